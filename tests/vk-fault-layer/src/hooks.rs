//! The intercepted commands (`spec::FUNCS`): the marker instance notes the app's call on its
//! thread and calls down; the lower instance counts the call, by origin, and either fails it
//! (null outputs, no call down) or calls down, noting the objects created with `VK_FAULT_COUNT`.

use crate::spec::{self, Origin};
use ash::vk::{self, Handle};
use std::cell::RefCell;

thread_local! {
    /// The app's intercepted calls in progress on this thread, as the marker saw them:
    /// (`spec::FUNCS` index, signature).
    static APP_CALLS: RefCell<Vec<(usize, Vec<u64>)>> = const { RefCell::new(Vec::new()) };
}

/// What identifies the app's own call of a command among the calls the layer in between makes
/// inside it. Only `vkQueueSubmit` needs one: stereoshim submits its own work (set-up work before,
/// a completion fence after) from inside the app's `vkQueueSubmit`, while it passes the app's
/// command buffers down. Those are dispatchable handles, which no layer wraps (validation wraps
/// the fence, so the fence cannot tell the calls apart). An empty signature matches any call: the
/// layer creates none of its own objects of a kind inside the app's creation of that kind.
///
/// # Safety
/// `submits` must point to `count` valid submit infos.
unsafe fn submit_signature(count: u32, submits: *const vk::SubmitInfo<'_>) -> Vec<u64> {
    let mut cbs = Vec::new();
    for i in 0..count as usize {
        // SAFETY: within the caller's `count` valid submit infos.
        let s = unsafe { &*submits.add(i) };
        for j in 0..s.command_buffer_count as usize {
            // SAFETY: each submit info's command buffer array has its count of handles.
            cbs.push(unsafe { *s.p_command_buffers.add(j) }.as_raw());
        }
    }
    if cbs.is_empty() {
        // A submission of no command buffer (a fence or semaphores only) is told apart by this
        // marker alone.
        cbs.push(u64::MAX);
    }
    cbs
}

/// Runs `down` (the call to the next layer) for the marker (`U`) or the lower instance; the
/// lower one first re-enters the chain when `VK_FAULT_REENTER` names the command (`reenter`),
/// and with `VK_FAULT_COUNT` notes the handles `created` reads once the call succeeded (`device`:
/// the dispatch key of the call's device).
fn intercept<const U: bool>(
    func: usize,
    signature: Vec<u64>,
    device: usize,
    down: impl FnOnce() -> vk::Result,
    clear: impl FnOnce(),
    reenter: impl FnOnce(),
    created: impl FnOnce() -> Vec<u64>,
) -> vk::Result {
    let name = spec::FUNCS[func][0];
    if U {
        APP_CALLS.with(|c| c.borrow_mut().push((func, signature)));
        // Popped by a guard, so a panic below cannot leave a stale marker on this thread.
        struct Pop;
        impl Drop for Pop {
            fn drop(&mut self) {
                APP_CALLS.with(|c| c.borrow_mut().pop());
            }
        }
        let _pop = Pop;
        return down();
    }
    let app = APP_CALLS.with(|c| c.borrow().iter().any(|(f, s)| *f == func && (s.is_empty() || s.iter().any(|x| signature.contains(x)))));
    let origin = if app { Origin::App } else { Origin::Layer };
    let rules = match crate::rules() {
        Ok(r) => r.as_slice(),
        Err(_) => &[],
    };
    let call = crate::counters().next(rules, func, origin);
    match call.fail {
        Some(code) => {
            let who = if app { "app" } else { "layer" };
            eprintln!(
                "vk-fault-layer: {name} call {} ({who} call {}) failed on purpose: {}",
                call.index,
                call.origin_index,
                spec::result_name(code)
            );
            clear();
            vk::Result::from_raw(code)
        }
        None => {
            reenter();
            let r = down();
            // Positive results (a pipeline compile required) are successes that may have
            // created some of the outputs; `created` skips the null ones.
            if crate::count::enabled() && r.as_raw() >= 0 {
                if let Some(kind) = crate::count::kind_of_creation(name) {
                    crate::count::created(device, kind, origin, created());
                }
            }
            r
        }
    }
}

/// The next layer's function `func` of the device `first` (a device or queue) belongs to.
fn next<const U: bool>(first: impl Handle, func: usize) -> Option<unsafe extern "system" fn()> {
    crate::device_state::<U>(crate::dispatch_key(first)).and_then(|d| d.fns[func])
}

/// Writes `n` null handles to `out`.
///
/// # Safety
/// `out` must be valid for writing `n` handles.
unsafe fn null_out<T: Handle>(out: *mut T, n: u32) {
    for i in 0..n as usize {
        // SAFETY: within the `n` handles the caller guarantees.
        unsafe { out.add(i).write(T::from_raw(0)) };
    }
}

/// The `n` handles at `out` (null ones included), as raw values.
///
/// # Safety
/// `out` must be valid for reading `n` handles.
unsafe fn handles<T: Handle + Copy>(out: *const T, n: u32) -> Vec<u64> {
    // SAFETY: within the `n` handles the caller guarantees.
    (0..n as usize).map(|i| unsafe { *out.add(i) }.as_raw()).collect()
}

/// No handles counted: a submission, or handles that go with their pool (`count`); `unsafe`
/// only to share the hooks' one shape.
unsafe fn no_handles() -> Vec<u64> {
    Vec::new()
}

/// `vkQueueSubmit` writes nothing to clear; `unsafe` only to share the hooks' one shape.
unsafe fn no_outputs() {}

/// One intercepted command: its hook (generic over the role), the signature of the app's call,
/// how its outputs are cleared when it fails, and the handles it created when it succeeded.
macro_rules! hooks {
    ($($hook:ident $name:literal $pfn:ty = ($first:ident : $ft:ty $(, $a:ident : $t:ty)*) sig $sig:expr; clear $clear:block keep $keep:block)*) => {
        $(
            unsafe extern "system" fn $hook<const U: bool>($first: $ft $(, $a: $t)*) -> vk::Result {
                crate::entry($name, vk::Result::ERROR_UNKNOWN, || {
                    let func = spec::func_index($name).expect("listed in spec::FUNCS");
                    let Some(f) = next::<U>($first, func) else {
                        eprintln!("vk-fault-layer: {} on a device this layer never saw created", $name);
                        return vk::Result::ERROR_INITIALIZATION_FAILED;
                    };
                    // SAFETY: the pointer the next layer returned for this command's name has
                    // this command's type.
                    let f: $pfn = unsafe { std::mem::transmute::<unsafe extern "system" fn(), $pfn>(f) };
                    // SAFETY: the caller's arguments, to the next layer unchanged.
                    let down = || unsafe { f($first $(, $a)*) };
                    // SAFETY: the output pointers are valid for writing as the command's valid
                    // usage requires (counts read from the caller's valid infos); on failure the
                    // spec leaves them undefined, and null handles are what a careful driver writes.
                    let clear = || unsafe { $clear };
                    // SAFETY: read only after the call succeeded, when the outputs hold the
                    // created handles (counts as for `clear`).
                    let created = || -> Vec<u64> { unsafe { $keep } };
                    let key = crate::dispatch_key($first);
                    intercept::<U>(func, $sig, key, down, clear, || crate::reenter::from($name, $first), created)
                })
            }
        )*

        /// The hook of an intercepted command name (aliases included), for the proc-addr
        /// functions; None for every other name.
        pub(crate) fn lookup<const U: bool>(name: &[u8]) -> Option<unsafe extern "system" fn()> {
            let func = spec::func_index(std::str::from_utf8(name).ok()?)?;
            let core = spec::FUNCS[func][0];
            $(
                if core == $name {
                    return crate::void($hook::<U> as $pfn);
                }
            )*
            None
        }
    };
}

type Alloc<'a> = *const vk::AllocationCallbacks<'a>;

hooks! {
    create_image "vkCreateImage" vk::PFN_vkCreateImage = (device: vk::Device, ci: *const vk::ImageCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Image) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    allocate_memory "vkAllocateMemory" vk::PFN_vkAllocateMemory = (device: vk::Device, info: *const vk::MemoryAllocateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::DeviceMemory) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_graphics_pipelines "vkCreateGraphicsPipelines" vk::PFN_vkCreateGraphicsPipelines = (device: vk::Device, cache: vk::PipelineCache, count: u32, infos: *const vk::GraphicsPipelineCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Pipeline) sig Vec::new();
        clear { null_out(out, count) }
        keep { handles(out, count) }
    create_compute_pipelines "vkCreateComputePipelines" vk::PFN_vkCreateComputePipelines = (device: vk::Device, cache: vk::PipelineCache, count: u32, infos: *const vk::ComputePipelineCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Pipeline) sig Vec::new();
        clear { null_out(out, count) }
        keep { handles(out, count) }
    create_shader_module "vkCreateShaderModule" vk::PFN_vkCreateShaderModule = (device: vk::Device, ci: *const vk::ShaderModuleCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::ShaderModule) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    queue_submit "vkQueueSubmit" vk::PFN_vkQueueSubmit = (queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo<'_>, fence: vk::Fence) sig {
            // SAFETY: the caller passes `count` valid submit infos.
            unsafe { submit_signature(count, submits) }
        };
        clear { no_outputs() }
        keep { no_handles() }
    create_render_pass "vkCreateRenderPass" vk::PFN_vkCreateRenderPass = (device: vk::Device, ci: *const vk::RenderPassCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::RenderPass) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_render_pass2 "vkCreateRenderPass2" vk::PFN_vkCreateRenderPass2 = (device: vk::Device, ci: *const vk::RenderPassCreateInfo2<'_>, alloc: Alloc<'_>, out: *mut vk::RenderPass) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_image_view "vkCreateImageView" vk::PFN_vkCreateImageView = (device: vk::Device, ci: *const vk::ImageViewCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::ImageView) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_buffer "vkCreateBuffer" vk::PFN_vkCreateBuffer = (device: vk::Device, ci: *const vk::BufferCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Buffer) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_descriptor_pool "vkCreateDescriptorPool" vk::PFN_vkCreateDescriptorPool = (device: vk::Device, ci: *const vk::DescriptorPoolCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::DescriptorPool) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    allocate_descriptor_sets "vkAllocateDescriptorSets" vk::PFN_vkAllocateDescriptorSets = (device: vk::Device, info: *const vk::DescriptorSetAllocateInfo<'_>, out: *mut vk::DescriptorSet) sig Vec::new();
        clear { null_out(out, (*info).descriptor_set_count) }
        keep { no_handles() }
    create_framebuffer "vkCreateFramebuffer" vk::PFN_vkCreateFramebuffer = (device: vk::Device, ci: *const vk::FramebufferCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Framebuffer) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_query_pool "vkCreateQueryPool" vk::PFN_vkCreateQueryPool = (device: vk::Device, ci: *const vk::QueryPoolCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::QueryPool) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    allocate_command_buffers "vkAllocateCommandBuffers" vk::PFN_vkAllocateCommandBuffers = (device: vk::Device, info: *const vk::CommandBufferAllocateInfo<'_>, out: *mut vk::CommandBuffer) sig Vec::new();
        clear { null_out(out, (*info).command_buffer_count) }
        keep { no_handles() }
    create_fence "vkCreateFence" vk::PFN_vkCreateFence = (device: vk::Device, ci: *const vk::FenceCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Fence) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_pipeline_layout "vkCreatePipelineLayout" vk::PFN_vkCreatePipelineLayout = (device: vk::Device, ci: *const vk::PipelineLayoutCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::PipelineLayout) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_descriptor_set_layout "vkCreateDescriptorSetLayout" vk::PFN_vkCreateDescriptorSetLayout = (device: vk::Device, ci: *const vk::DescriptorSetLayoutCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::DescriptorSetLayout) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_sampler "vkCreateSampler" vk::PFN_vkCreateSampler = (device: vk::Device, ci: *const vk::SamplerCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::Sampler) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
    create_command_pool "vkCreateCommandPool" vk::PFN_vkCreateCommandPool = (device: vk::Device, ci: *const vk::CommandPoolCreateInfo<'_>, alloc: Alloc<'_>, out: *mut vk::CommandPool) sig Vec::new();
        clear { null_out(out, 1) }
        keep { handles(out, 1) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_command_has_a_hook() {
        for names in spec::FUNCS {
            for n in *names {
                assert!(lookup::<false>(n.as_bytes()).is_some() && lookup::<true>(n.as_bytes()).is_some(), "{n}");
            }
        }
        assert!(lookup::<false>(b"vkDestroyImage").is_none());
    }
}
