//! The Vulkan plug-in contract: what a feature's Vulkan half is (`feature`), the device it is
//! given (`DeviceState`: the layer's view of one `VkDevice`, without the feature list's types),
//! and the shared GPU helpers every feature draws with (injection context, pipeline cache, state
//! restore, lifetimes of the layer's objects, secondary command buffers, the GPU frame timer).
//! The entry points and hooks that raise these events are the shell, `crate::vk`.

pub(crate) mod convert;
pub(crate) mod feature;
pub(crate) mod gpu;
pub(crate) mod gpu_time;
pub(crate) mod inject;
pub(crate) mod keep_depth;
pub(crate) mod lifetime;
pub(crate) mod own;
pub(crate) mod secondary;
#[cfg(test)]
pub(crate) mod test_chain;

use crate::core::guard::{self, PassThrough};
use crate::core::handles::HandleMap;
use crate::track::device_ext::Decision;
use crate::track::DeviceTracker;
use ash::vk::{self, Handle};
use std::ffi::{c_void, CStr};
use std::sync::{Arc, OnceLock};

/// Every live device's state, by dispatch key: the Vulkan shell inserts at `vkCreateDevice` and
/// removes at `vkDestroyDevice`; the OpenXR half finds a session's device here by its key.
pub(crate) fn devices() -> &'static HandleMap<usize, DeviceState> {
    static DEVICES: OnceLock<HandleMap<usize, DeviceState>> = OnceLock::new();
    DEVICES.get_or_init(HandleMap::default)
}

/// Extension commands that are not core in any version, loaded by name (None when the device
/// does not offer them; we then never hand out our hook for them either).
#[derive(Default)]
pub(crate) struct ExtFns {
    pub cmd_set_line_stipple: Option<vk::PFN_vkCmdSetLineStippleKHR>,
    pub cmd_set_color_write_enable: Option<vk::PFN_vkCmdSetColorWriteEnableEXT>,
    pub cmd_set_logic_op: Option<vk::PFN_vkCmdSetLogicOpEXT>,
    pub cmd_set_patch_control_points: Option<vk::PFN_vkCmdSetPatchControlPointsEXT>,
    /// Extended dynamic state 3's commands (from that extension or `VK_EXT_shader_object`),
    /// when the device has them: the app's are tracked and replayed (`hooks::dyn_state`). A
    /// table loaded by name; the layer calls only commands the app itself called through it.
    pub eds3: Option<ash::ext::extended_dynamic_state3::DeviceFn>,
    pub cmd_set_vertex_input: Option<vk::PFN_vkCmdSetVertexInputEXT>,
    pub cmd_bind_shaders: Option<vk::PFN_vkCmdBindShadersEXT>,
    // Commands that veto injections (`hooks::dyn_state`).
    pub cmd_set_fragment_shading_rate: Option<vk::PFN_vkCmdSetFragmentShadingRateKHR>,
    pub cmd_set_rendering_attachment_locations: Option<vk::PFN_vkCmdSetRenderingAttachmentLocationsKHR>,
    pub cmd_set_rendering_input_attachment_indices: Option<vk::PFN_vkCmdSetRenderingInputAttachmentIndicesKHR>,
    pub cmd_push_descriptor_set: Option<vk::PFN_vkCmdPushDescriptorSetKHR>,
    pub cmd_push_descriptor_set_with_template: Option<vk::PFN_vkCmdPushDescriptorSetWithTemplateKHR>,
    pub cmd_bind_descriptor_buffers: Option<vk::PFN_vkCmdBindDescriptorBuffersEXT>,
}

/// What the layer keeps per `VkDevice`.
pub(crate) struct DeviceState {
    pub handle: vk::Device,
    /// `handle`'s dispatch key, read at creation: the key of this state in `Layer::devices`.
    pub key: usize,
    /// What the device was created with: every layer object is checked against it.
    pub caps: crate::track::caps::DeviceCaps,
    /// The instance's `VkApplicationInfo::pEngineName`.
    pub engine: Option<String>,
    pub next_gdpa: vk::PFN_vkGetDeviceProcAddr,
    /// The device functions for everything the layer does itself: the next layer's (core names
    /// falling back to their KHR/EXT aliases, so the table works on devices that offer a command
    /// only as an extension), with the creation and destruction of its own objects counted
    /// (`own`).
    pub fns: ash::Device,
    /// The next layer's functions as they are: where the app's own create and destroy calls go
    /// down, uncounted.
    pub next: ash::Device,
    /// The layer's own live Vulkan objects, by kind (`own.*` in the device stats line).
    pub own: Arc<own::Counted>,
    pub ext: ExtFns,
    pub pass_through: Arc<PassThrough>,
    pub track: DeviceTracker,
    pub extension_decision: Decision,
    /// The settings resolved when the device was created (used until the OpenXR half publishes
    /// live ones).
    pub settings: Arc<crate::plugin::settings::Settings>,
    /// The loader's callback for dispatchable objects the layer creates itself.
    pub set_loader_data: Option<PfnSetDeviceLoaderData>,
    /// The physical device's memory types (for the layer's own allocations).
    pub memory: vk::PhysicalDeviceMemoryProperties,
    /// Every registered feature's per-device object, in registry order (`crate::registry`).
    pub features: feature::DeviceFeatures,
    /// The injection chassis: triggers, pipeline cache.
    pub inject: inject::InjectDevice,
    /// Holds of recorded command buffers and their submissions.
    pub lifetime: lifetime::LifetimeDevice,
    /// The layer's secondary command buffers for eye passes with secondary contents.
    pub secondary: secondary::SecondaryDevice,
    /// The GPU frame timer (`stats.gpu_time`).
    pub gpu_time: gpu_time::GpuTimeDevice,
    /// Failures of the layer's own objects that repeat: logged once per kind, counted
    /// (`DeviceState::warn_repeated`).
    pub repeats: crate::core::log::Repeats,
}

/// The loader's `PFN_vkSetDeviceLoaderData`: a layer must call it on dispatchable objects it
/// creates itself (our command buffers) so the layers below find their dispatch tables.
pub(crate) type PfnSetDeviceLoaderData = unsafe extern "system" fn(vk::Device, *mut c_void) -> vk::Result;

impl DeviceState {
    /// A failure of the layer's own object of `kind` (`what` says what failed): WARN the first
    /// time on this device, then only counted (the feature tries again at its next use, which
    /// under a persistent failure is every pass).
    pub fn warn_repeated(&self, kind: &'static str, what: impl std::fmt::Display) {
        if self.repeats.first(kind) {
            tracing::warn!("{kind}: {what} (repeats are counted, not logged)");
        }
    }
    /// The live settings (the OpenXR half re-reads a changed config file between frames), else
    /// the device's own.
    pub fn settings(&self) -> Arc<crate::plugin::settings::Settings> {
        crate::plugin::settings::current().unwrap_or_else(|| self.settings.clone())
    }

    /// `debug.fail_in`: the layer logic of `call` fails on purpose (fault-injection tests).
    pub fn check(&self, call: &'static str) -> Result<(), guard::Fault> {
        if self.settings.fails_in(call) {
            return Err(guard::Fault(format!("{call}: failing on purpose (debug.fail_in)")));
        }
        Ok(())
    }
}

/// The loader's dispatch key of a dispatchable handle; 0 for a null handle.
pub(crate) fn dispatch_key<H: Handle>(handle: H) -> usize {
    let raw = handle.as_raw();
    if raw == 0 {
        return 0;
    }
    // SAFETY: every dispatchable Vulkan handle the loader hands to a layer points to an object
    // whose first word is the loader's dispatch table pointer (LoaderLayerInterface.md, "Dispatch
    // table"); the app guarantees the handle is valid for the call it passed it to.
    unsafe { *(raw as usize as *const usize) }
}

/// A `VkDevice` as the OpenXR half holds it: its dispatch key, read once at `xrCreateSession`,
/// when the runtime has just accepted the device in the session's graphics binding. Every later
/// lookup from the OpenXR half (each `xrBeginFrame`, `xrReleaseSwapchainImage`) goes by this key
/// and never reads the app's handle again, so a device the app destroyed out of order (before its
/// session) is a missed lookup, not a read of freed memory (issue 23).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DeviceKey(usize);

impl DeviceKey {
    /// Reads the key of `device`, which must be a live `VkDevice` (the runtime validated it).
    pub(crate) fn of_live(device: u64) -> DeviceKey {
        DeviceKey(dispatch_key(vk::Device::from_raw(device)))
    }
    /// The device's state, while the Vulkan half tracks it.
    pub(crate) fn state(self) -> Option<Arc<DeviceState>> {
        devices().get(self.0)
    }
}

/// Whether the Vulkan half created the state of this device (the OpenXR half asks, to log
/// whether the session's device is one the layer can act on).
pub(crate) fn device_is_tracked(device: DeviceKey) -> bool {
    device.state().is_some()
}

/// Whether `state` is still the state of a live device: the app has not destroyed the device
/// since (which removes the state; a later device under the same key has a new one). Whoever
/// holds a device's state past a call of the app's (the OpenXR half's overlay) checks it before
/// touching the device again, never the app's handle.
pub(crate) fn device_is_live(state: &Arc<DeviceState>) -> bool {
    devices().get(state.key).is_some_and(|d| Arc::ptr_eq(&d, state))
}

/// Looks a command up through `gdpa`, falling back to the KHR and EXT aliases of a core name, so
/// ash's core-named tables resolve on devices that offer the command only as an extension.
///
/// # Safety
/// `gdpa` must be a valid `vkGetDeviceProcAddr` for `device`.
pub(crate) unsafe fn device_proc(gdpa: vk::PFN_vkGetDeviceProcAddr, device: vk::Device, name: &CStr) -> *const c_void {
    let mut candidates = vec![name.to_owned()];
    for suffix in ["KHR", "EXT"] {
        let mut n = name.to_bytes().to_vec();
        n.extend_from_slice(suffix.as_bytes());
        candidates.extend(std::ffi::CString::new(n).ok());
    }
    for c in candidates {
        // SAFETY: per this function's contract.
        if let Some(f) = unsafe { gdpa(device, c.as_ptr()) } {
            return f as *const c_void;
        }
    }
    std::ptr::null()
}

/// `xrReleaseSwapchainImage` of `index` of `swapchain` is about to go down: the features act on
/// the released image (`binding`: the session's device, queue family and queue index).
pub(crate) fn before_release(binding: Option<(DeviceKey, u32, u32)>, swapchain: u64, index: Option<u32>) {
    let (Some((device, family, queue)), Some(index)) = (binding, index) else { return };
    let Some(d) = device.state() else { return };
    if d.pass_through.is_on() {
        return;
    }
    for f in d.features.all() {
        f.before_release(&d, family, queue, swapchain, index);
    }
}

/// The upscale wrote `views` (view, rect, layer) of the runtime's image `image` behind `display`
/// (described at the runtime's size): the features act on it before the runtime gets it back.
pub(crate) fn display_ready(binding: Option<(DeviceKey, u32, u32)>, display: &crate::bridge::Swapchain, image: u64, views: &[(u32, crate::core::views::ImageRect, u32)]) {
    let Some((device, family, queue)) = binding else { return };
    let Some(d) = device.state() else { return };
    if d.pass_through.is_on() || views.is_empty() {
        return;
    }
    for f in d.features.all() {
        f.display_ready(&d, family, queue, display, image, views);
    }
}

