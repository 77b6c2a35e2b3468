//! `VK_FAULT_COUNT=1`: the lower instance keeps, per device, the set of live handles of every
//! object kind whose creation it hooks (`spec::FUNCS`), by origin (`spec::Origin`): the app's (or
//! the runtime's) and those the layer above it (stereoshim) creates for itself. A creation adds
//! the handles it returned to its origin's set; a destruction removes the handle from whichever
//! set holds it (the app may destroy what the runtime made, and the handle says nothing about who
//! made it). Command buffers and descriptor sets go with their pools and are not counted.
//!
//! The counts are printed on stderr — one `vk-fault-layer: live objects: …` line — at each of the
//! app's `vkDeviceWaitIdle` calls (seen by the marker instance, above stereoshim, after the call
//! has gone down) and at `vkDestroyDevice` in the lower instance before it calls down, when the
//! layer above has destroyed everything it is going to destroy. `tests/vk_objects.rs` reads them
//! to prove that what stereoshim creates for itself does not pile up across sessions.

use crate::spec::Origin;
use ash::vk::{self, Handle};
use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::sync::{Mutex, OnceLock};

/// The counted kinds: (name in the printed line, its destruction command). A kind's index is its
/// position here.
pub const KINDS: &[(&str, &str)] = &[
    ("image", "vkDestroyImage"),
    ("memory", "vkFreeMemory"),
    ("image_view", "vkDestroyImageView"),
    ("buffer", "vkDestroyBuffer"),
    ("shader_module", "vkDestroyShaderModule"),
    ("pipeline_layout", "vkDestroyPipelineLayout"),
    ("set_layout", "vkDestroyDescriptorSetLayout"),
    ("pipeline", "vkDestroyPipeline"),
    ("render_pass", "vkDestroyRenderPass"),
    ("framebuffer", "vkDestroyFramebuffer"),
    ("sampler", "vkDestroySampler"),
    ("descriptor_pool", "vkDestroyDescriptorPool"),
    ("query_pool", "vkDestroyQueryPool"),
    ("command_pool", "vkDestroyCommandPool"),
    ("fence", "vkDestroyFence"),
];

/// The next layer's commands a device resolves for counting: the [`KINDS`]' destructions in
/// order, then `vkDeviceWaitIdle` (index [`WAIT_IDLE`]).
pub fn next_names() -> Vec<&'static [&'static str]> {
    static NAMES: OnceLock<Vec<[&'static str; 1]>> = OnceLock::new();
    NAMES.get_or_init(|| KINDS.iter().map(|k| [k.1]).chain([["vkDeviceWaitIdle"]]).collect()).iter().map(|n| &n[..]).collect()
}

pub const WAIT_IDLE: usize = KINDS.len();

/// The kind created by a `spec::FUNCS` command, by its core name; None for those that create
/// nothing counted (submission, pool allocations).
pub fn kind_of_creation(name: &str) -> Option<usize> {
    let kind = match name {
        "vkCreateImage" => "image",
        "vkAllocateMemory" => "memory",
        "vkCreateImageView" => "image_view",
        "vkCreateBuffer" => "buffer",
        "vkCreateShaderModule" => "shader_module",
        "vkCreatePipelineLayout" => "pipeline_layout",
        "vkCreateDescriptorSetLayout" => "set_layout",
        "vkCreateGraphicsPipelines" | "vkCreateComputePipelines" => "pipeline",
        "vkCreateRenderPass" | "vkCreateRenderPass2" => "render_pass",
        "vkCreateFramebuffer" => "framebuffer",
        "vkCreateSampler" => "sampler",
        "vkCreateDescriptorPool" => "descriptor_pool",
        "vkCreateQueryPool" => "query_pool",
        "vkCreateCommandPool" => "command_pool",
        "vkCreateFence" => "fence",
        _ => return None,
    };
    KINDS.iter().position(|k| k.0 == kind)
}

/// Whether `VK_FAULT_COUNT=1` asked for counting (read once).
pub(crate) fn enabled() -> bool {
    static ON: OnceLock<bool> = OnceLock::new();
    *ON.get_or_init(|| std::env::var("VK_FAULT_COUNT").is_ok_and(|v| v == "1"))
}

/// One device's live handles: `[origin][kind]` (origin 0 the app's, 1 the layer's).
#[derive(Default)]
struct Live {
    sets: [Vec<HashSet<u64>>; 2],
}

impl Live {
    fn set(&mut self, origin: usize, kind: usize) -> &mut HashSet<u64> {
        let sets = &mut self.sets[origin];
        if sets.is_empty() {
            sets.resize_with(KINDS.len(), HashSet::new);
        }
        &mut sets[kind]
    }
}

/// Live handles per device (its dispatch key). Handles are only unique per device.
fn devices() -> &'static Mutex<HashMap<usize, Live>> {
    static DEVICES: OnceLock<Mutex<HashMap<usize, Live>>> = OnceLock::new();
    DEVICES.get_or_init(Default::default)
}

/// Notes the handles a successful creation of `kind` on device `key` returned.
pub(crate) fn created(key: usize, kind: usize, origin: Origin, handles: impl IntoIterator<Item = u64>) {
    let mut d = crate::lock(devices());
    let set = d.entry(key).or_default().set(matches!(origin, Origin::Layer) as usize, kind);
    set.extend(handles.into_iter().filter(|h| *h != 0));
}

/// Notes the destruction of `handle` of `kind` on device `key`, before the call goes down (after
/// it, another thread may get the same handle from a new creation).
pub(crate) fn destroyed(key: usize, kind: usize, handle: u64) {
    let mut d = crate::lock(devices());
    let live = d.entry(key).or_default();
    for origin in 0..2 {
        if live.set(origin, kind).remove(&handle) {
            return;
        }
    }
}

/// Prints the device's live counts (`when` says at which call), and forgets the device when it is
/// being destroyed.
pub(crate) fn report(key: usize, when: &str, forget: bool) {
    let mut d = crate::lock(devices());
    let live = d.entry(key).or_default();
    let mut line = format!("vk-fault-layer: live objects at {when}:");
    for (origin, name) in [(1, "layer"), (0, "app")] {
        line.push(' ');
        line.push_str(name);
        for (kind, k) in KINDS.iter().enumerate() {
            let _ = write!(line, " {}={}", k.0, live.set(origin, kind).len());
        }
    }
    if forget {
        d.remove(&key);
    }
    drop(d);
    eprintln!("{line}");
}

/// The next layer's counting command `i` ([`next_names`]) of the device `device`.
fn next<const U: bool>(device: vk::Device, i: usize) -> Option<unsafe extern "system" fn()> {
    crate::device_state::<U>(crate::dispatch_key(device)).and_then(|d| d.count_fns[i])
}

/// The destruction hooks (lower instance): note the destruction, then call down unchanged.
macro_rules! destroy_hooks {
    ($($hook:ident $name:literal $pfn:ty = $t:ty;)*) => {
        $(
            unsafe extern "system" fn $hook(device: vk::Device, handle: $t, alloc: *const vk::AllocationCallbacks<'_>) {
                crate::entry($name, (), || {
                    let kind = KINDS.iter().position(|k| k.1 == $name).expect("listed in KINDS");
                    let Some(f) = next::<false>(device, kind) else {
                        eprintln!("vk-fault-layer: {} on a device this layer never saw created", $name);
                        return;
                    };
                    // SAFETY: the pointer the next layer returned for this command's name has
                    // this command's type.
                    let f: $pfn = unsafe { std::mem::transmute::<unsafe extern "system" fn(), $pfn>(f) };
                    if handle.as_raw() != 0 {
                        destroyed(crate::dispatch_key(device), kind, handle.as_raw());
                    }
                    // `VK_FAULT_REENTER=vkDestroyImage` still re-enters from here (this hook
                    // replaces `reenter`'s when counting).
                    crate::reenter::from($name, device);
                    // SAFETY: the caller's arguments, to the next layer unchanged.
                    unsafe { f(device, handle, alloc) }
                })
            }
        )*

        /// The destruction hook of a counted kind's command for the lower instance.
        fn destroy_hook(name: &str) -> Option<unsafe extern "system" fn()> {
            $(
                if name == $name {
                    return crate::void($hook as $pfn);
                }
            )*
            None
        }
    };
}

destroy_hooks! {
    destroy_image "vkDestroyImage" vk::PFN_vkDestroyImage = vk::Image;
    free_memory "vkFreeMemory" vk::PFN_vkFreeMemory = vk::DeviceMemory;
    destroy_image_view "vkDestroyImageView" vk::PFN_vkDestroyImageView = vk::ImageView;
    destroy_buffer "vkDestroyBuffer" vk::PFN_vkDestroyBuffer = vk::Buffer;
    destroy_shader_module "vkDestroyShaderModule" vk::PFN_vkDestroyShaderModule = vk::ShaderModule;
    destroy_pipeline_layout "vkDestroyPipelineLayout" vk::PFN_vkDestroyPipelineLayout = vk::PipelineLayout;
    destroy_set_layout "vkDestroyDescriptorSetLayout" vk::PFN_vkDestroyDescriptorSetLayout = vk::DescriptorSetLayout;
    destroy_pipeline "vkDestroyPipeline" vk::PFN_vkDestroyPipeline = vk::Pipeline;
    destroy_render_pass "vkDestroyRenderPass" vk::PFN_vkDestroyRenderPass = vk::RenderPass;
    destroy_framebuffer "vkDestroyFramebuffer" vk::PFN_vkDestroyFramebuffer = vk::Framebuffer;
    destroy_sampler "vkDestroySampler" vk::PFN_vkDestroySampler = vk::Sampler;
    destroy_descriptor_pool "vkDestroyDescriptorPool" vk::PFN_vkDestroyDescriptorPool = vk::DescriptorPool;
    destroy_query_pool "vkDestroyQueryPool" vk::PFN_vkDestroyQueryPool = vk::QueryPool;
    destroy_command_pool "vkDestroyCommandPool" vk::PFN_vkDestroyCommandPool = vk::CommandPool;
    destroy_fence "vkDestroyFence" vk::PFN_vkDestroyFence = vk::Fence;
}

/// The app's `vkDeviceWaitIdle` (marker instance only: every call it sees is the app's or the
/// runtime's): goes down, then the device's counts are printed — stereoshim makes no objects of
/// its own inside the call, so the line shows what lives between the app's calls.
unsafe extern "system" fn device_wait_idle(device: vk::Device) -> vk::Result {
    crate::entry("vkDeviceWaitIdle", vk::Result::ERROR_UNKNOWN, || {
        let Some(f) = next::<true>(device, WAIT_IDLE) else {
            eprintln!("vk-fault-layer: vkDeviceWaitIdle on a device this layer never saw created");
            return vk::Result::ERROR_INITIALIZATION_FAILED;
        };
        // SAFETY: the pointer the next layer returned for "vkDeviceWaitIdle".
        let f: vk::PFN_vkDeviceWaitIdle = unsafe { std::mem::transmute::<unsafe extern "system" fn(), vk::PFN_vkDeviceWaitIdle>(f) };
        // SAFETY: the caller's device, to the next layer unchanged.
        let r = unsafe { f(device) };
        report(crate::dispatch_key(device), "vkDeviceWaitIdle", false);
        r
    })
}

/// The counting hook of a command name when `VK_FAULT_COUNT=1`: the destructions for the lower
/// instance, `vkDeviceWaitIdle` for the marker; None otherwise.
pub(crate) fn lookup<const U: bool>(name: &[u8]) -> Option<unsafe extern "system" fn()> {
    if !enabled() {
        return None;
    }
    let name = std::str::from_utf8(name).ok()?;
    match (U, name) {
        (true, "vkDeviceWaitIdle") => crate::void(device_wait_idle as vk::PFN_vkDeviceWaitIdle),
        (false, _) => destroy_hook(name),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_has_a_creation_and_a_destruction() {
        for (kind, (_, destroy)) in KINDS.iter().enumerate() {
            assert!(destroy_hook(destroy).is_some(), "{destroy} has no hook");
            assert!(crate::spec::FUNCS.iter().any(|n| kind_of_creation(n[0]) == Some(kind)), "kind {kind} is never created");
        }
        assert_eq!(next_names()[WAIT_IDLE], ["vkDeviceWaitIdle"]);
    }

    #[test]
    fn a_destruction_removes_from_either_origin() {
        let key = 0x5eed;
        created(key, 0, Origin::App, [1, 2]);
        created(key, 0, Origin::Layer, [3, 0]);
        destroyed(key, 0, 3);
        destroyed(key, 0, 1);
        destroyed(key, 0, 99);
        let mut d = crate::lock(devices());
        let live = d.get_mut(&key).unwrap();
        assert_eq!((live.set(0, 0).len(), live.set(1, 0).len()), (1, 0));
    }
}
