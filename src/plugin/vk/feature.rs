//! What a feature is to the Vulkan chassis: a `Plugin` (how it is made per device, its config keys
//! and statistics) and a `VkFeature` (the events it handles). Hooks track state and raise these
//! events over `DeviceFeatures::all()` in registry order; a feature implements only the events it
//! needs (every method has a do-nothing default).
//!
//! Events, in the order a frame meets them:
//! - creation: `image_usage`, `amend_render_pass`, `amend_framebuffer` / `framebuffer_created`,
//!   `amend_pipelines` (may return an amended copy of the app's create info; the first feature
//!   that amends wins, and the app's own info is retried if the driver refuses the amended one);
//! - destruction: `destroyed` (images, render passes, framebuffers);
//! - recording: `amend_render_pass_begin` / `amend_rendering` (before the pass goes down; the
//!   point before begin), `pass_begun` (after), `inject` / `inject_awaiting` at the chassis'
//!   injection point (`vk::chassis`: right after the depth clear), `not_injected`, `pass_ending`
//!   (before the end goes down), `pass_ended` (after it), `transfer` (copies, resolves, blits);
//! - `injects_before_depth_test` features get `inject` at the pass's first depth-tested draw
//!   (`vk::chassis::before_draw`) instead of right after the clear;
//! - submission: `queue_submitting` (set-up work of the layer's that goes at the head of the
//!   app's submission) and `set_up_submitted`, `before_submit` (refresh what a recorded command
//!   buffer reads; apply what it recorded, in recording order);
//! - OpenXR side: `before_release` (`xrReleaseSwapchainImage`, before it goes down),
//!   `display_ready` (the upscale's display-size image written, at `xrEndFrame`);
//! - `take_frame` at every `xrEndFrame`, `destroy` at `vkDestroyDevice`.

use super::inject::{Awaiting, Injection};
use super::DeviceState;
use crate::core::pass::NotMasked;
use crate::core::stats::FeatureStats;
use crate::plugin::settings::Settings;
use crate::track::cmd::PassKind;
use crate::track::eye_pass::TransferRegion;
use ash::vk;
use std::any::Any;

/// What a feature may use when it is made for a new device.
pub(crate) struct DeviceInit<'a> {
    pub settings: &'a Settings,
    pub memory: vk::PhysicalDeviceMemoryProperties,
    /// The device's attachment shading rates, when the layer enabled them.
    pub rates: Option<crate::track::caps::DeviceRates>,
    pub set_loader_data: Option<super::PfnSetDeviceLoaderData>,
    /// The device is a CPU implementation (`VK_PHYSICAL_DEVICE_TYPE_CPU`: lavapipe, SwiftShader),
    /// where `foveation.method = auto` does not pick RDM (`Method::resolve`).
    pub software: bool,
}

/// One device's feature objects, in registry order: the chassis dispatches events over `all`, and
/// a feature finds its own object (from code that is handed only the device) with `get`.
pub(crate) struct DeviceFeatures(Vec<Box<dyn VkFeature>>);

impl DeviceFeatures {
    /// The registry's objects for a new device, in dispatch order.
    pub(crate) fn new(all: Vec<Box<dyn VkFeature>>) -> DeviceFeatures {
        DeviceFeatures(all)
    }
    /// Every feature, in registry order.
    pub(crate) fn all(&self) -> &[Box<dyn VkFeature>] {
        &self.0
    }
    /// The object of feature type `T`. Every registered feature has one on every device, so a
    /// missing one is a registry error.
    pub(crate) fn get<T: VkFeature + 'static>(&self) -> &T {
        self.0
            .iter()
            // `as_ref` first: `AsAny` is implemented for the `Box` too, whose `Any` is the box's.
            .find_map(|f| f.as_ref().as_any().downcast_ref::<T>())
            .unwrap_or_else(|| panic!("no {} on the device: the feature is not registered", std::any::type_name::<T>()))
    }
}

/// `Any` for every feature object, so `DeviceFeatures::get` can find one by type.
pub(crate) trait AsAny {
    fn as_any(&self) -> &dyn Any;
}

impl<T: Any> AsAny for T {
    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// How a feature is registered.
pub(crate) trait Plugin: VkFeature + Sized {
    fn new(init: &DeviceInit<'_>) -> Self;
    /// A frame's empty statistics of this feature.
    fn empty_stats() -> Box<dyn FeatureStats>;
    /// Whether the user has the feature on in a frame recorded under `s` (`frame`: what every
    /// feature counted in it, for choices resolved per device such as `foveation.method = auto`).
    /// Never-silent notices warn about features that are on but apply to nothing.
    fn enabled(s: &Settings, frame: &crate::core::stats::FrameStats) -> bool;
}

/// An app's create or begin info with the feature's additions: `info` points into `keep`, which
/// lives while the call goes down.
pub(crate) struct Amended<T> {
    pub info: T,
    /// What `info` points into; only kept alive.
    pub _keep: Box<dyn Any>,
}

/// The render pass amendment also says which attachment the feature appended.
pub(crate) struct AmendedRenderPass {
    pub amended: Amended<vk::RenderPassCreateInfo2<'static>>,
    pub appended_attachment: u32,
}

/// Where a render pass create info comes from.
#[derive(Clone, Copy)]
pub(crate) enum RenderPassInfo {
    V1(*const vk::RenderPassCreateInfo<'static>),
    V2(*const vk::RenderPassCreateInfo2<'static>),
}

/// A destroyed app object the feature may have derived state from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Destroyed {
    Image(u64),
    Framebuffer(u64),
}

/// The events a feature handles on one device.
///
/// The `unsafe fn`s receive the app's create / begin infos: they must be valid for the duration
/// of the call (the app's contract with the hook that raises the event).
pub(crate) trait VkFeature: AsAny + Send + Sync {
    /// The registry id (`stats.file`, logs, pipeline cache keys).
    fn id(&self) -> &'static str;
    /// This feature's statistics of the frame that just ended; resets them.
    fn take_frame(&self) -> Box<dyn FeatureStats>;
    /// The session's totals for the device's stats line, when the feature ever acted.
    fn summary(&self) -> Option<String> {
        None
    }

    /// # Safety
    /// `ci` is the app's valid create info.
    unsafe fn amend_render_pass(&self, _d: &DeviceState, _ci: RenderPassInfo) -> Option<AmendedRenderPass> {
        None
    }
    /// # Safety
    /// `ci` is the app's valid create info. `pending` receives what `framebuffer_created` needs.
    unsafe fn amend_framebuffer(&self, _d: &DeviceState, _ci: *const vk::FramebufferCreateInfo<'_>, _pending: &mut Option<Box<dyn Any>>) -> Option<Amended<vk::FramebufferCreateInfo<'static>>> {
        None
    }
    /// The framebuffer an amendment was made for was created (Some) or failed (None).
    fn framebuffer_created(&self, _d: &DeviceState, _fb: Option<vk::Framebuffer>, _pending: Box<dyn Any>) {}
    /// # Safety
    /// `infos` are `count` valid create infos.
    unsafe fn amend_pipelines(&self, _d: &DeviceState, _infos: *const vk::GraphicsPipelineCreateInfo<'_>, _count: u32) -> Option<Amended<Vec<vk::GraphicsPipelineCreateInfo<'static>>>> {
        None
    }
    fn destroyed(&self, _d: &DeviceState, _what: Destroyed) {}

    /// # Safety
    /// `info` is the app's valid begin info; `cb` is recording outside a pass.
    unsafe fn amend_render_pass_begin(&self, _d: &DeviceState, _cb: vk::CommandBuffer, _kind: PassKind, _info: *const vk::RenderPassBeginInfo<'_>) -> Option<Amended<vk::RenderPassBeginInfo<'static>>> {
        None
    }
    /// # Safety
    /// `info` is the app's valid rendering info; `cb` is recording outside a pass.
    unsafe fn amend_rendering(&self, _d: &DeviceState, _cb: vk::CommandBuffer, _info: *const vk::RenderingInfo<'_>) -> Option<Amended<vk::RenderingInfo<'static>>> {
        None
    }
    /// A render pass instance began (after the call went down and the pass is tracked).
    fn pass_begun(&self, _d: &DeviceState, _cb: vk::CommandBuffer, _secondary: bool) {}
    /// The open pass (still tracked) is about to end: the last point to record into it.
    fn pass_ending(&self, _d: &DeviceState, _cb: vk::CommandBuffer) {}
    /// The pass ended (outside any pass again, before the app's next command).
    fn pass_ended(&self, _d: &DeviceState, _cb: vk::CommandBuffer) {}
    /// The current recordings of `cbs` are over (begun again, reset, freed): a pass left open in
    /// one of them never ends, so nothing kept for it may reach a later recording.
    fn recordings_closed(&self, _d: &DeviceState, _cbs: &[u64]) {}

    /// Whether the feature draws at the injection point under these settings on this device.
    fn injects(&self, _s: &Settings) -> bool {
        false
    }
    /// Whether the feature's draws wait for the pass's first depth-tested draw instead of going in
    /// right after the depth clear: draws without depth test that come first (a sky) would
    /// otherwise paint over what the feature wrote.
    fn injects_before_depth_test(&self) -> bool {
        false
    }
    /// Records the feature's draws into `at.cb` inside the app's pass (the chassis restores the
    /// app's state afterwards). Counts its own success and failure (`at.counts`).
    fn inject(&self, _d: &DeviceState, _at: &Injection<'_>) {}
    /// Whether the feature's draws for a pass awaiting the walk (`Awaiting` from
    /// `eye_pass::awaiting_walk`) are counted at each submission (applied, or why not) rather than
    /// when the pass is recorded.
    fn fills_at_submission(&self) -> bool {
        false
    }
    /// Like `inject`, for a pass whose eyes are not known yet: record draws that do nothing until
    /// `before_submit` fills them for the eyes known then.
    fn inject_awaiting(&self, _d: &DeviceState, _at: &Awaiting<'_>) {}
    /// An eye-pass candidate got no injection for `why` (counted when the feature injects).
    fn not_injected(&self, _d: &DeviceState, _s: &Settings, _why: NotMasked) {}
    /// The app transferred `src` into `dst` in `cb`.
    fn transfer(&self, _d: &DeviceState, _cb: vk::CommandBuffer, _src: u64, _dst: u64, _regions: &[TransferRegion]) {}

    /// Command buffers are about to be submitted: refresh what their recordings read (only where
    /// no earlier submission of a recording may still execute) and act on what they recorded.
    fn before_submit(&self, _d: &DeviceState, _cbs: &[u64]) {}
    /// A queue submission of command buffers of `family` is about to go down: the feature's
    /// one-time set-up work for them (command buffers made by `plugin::vk::secondary::prepare_once`:
    /// first image layouts, query pool resets). The chassis puts them at the head of the app's
    /// first batch, so they run first and share the app's fate: a submission that fails runs
    /// neither the set-up nor the app work that needs it (a separate submission of the layer's
    /// could fail alone and leave the app's command buffers using objects never set up).
    fn queue_submitting(&self, _d: &DeviceState, _family: u32) -> Vec<vk::CommandBuffer> {
        Vec::new()
    }
    /// The submission that carried `set_up` (what `queue_submitting` returned, non-empty) went
    /// down (`ok`) or not: set-up that did not go down is handed out again next time.
    fn set_up_submitted(&self, _d: &DeviceState, _family: u32, _set_up: &[vk::CommandBuffer], _ok: bool) {}
    /// Whether the feature reads the depth attachment after an eye pass ends: the chassis then
    /// makes passes store their depth (`plugin::vk::keep_depth`).
    fn keeps_depth(&self, _s: &Settings) -> bool {
        false
    }
    /// Image usage the feature adds to an image the app creates with `usage` (e.g. TRANSFER_SRC
    /// to copy an attachment): the app's own usage stays, so nothing it can see changes.
    fn image_usage(&self, _s: &Settings, _usage: vk::ImageUsageFlags) -> vk::ImageUsageFlags {
        vk::ImageUsageFlags::empty()
    }
    /// `xrReleaseSwapchainImage` of `image` (index of `swapchain`) is about to go down; the
    /// session's queue is (`family`, `queue_index`).
    fn before_release(&self, _d: &DeviceState, _family: u32, _queue_index: u32, _swapchain: u64, _image_index: u32) {}
    /// The upscale wrote `views` (view, rect, layer) of `image`, an image of the runtime's
    /// display-size swapchain behind `display` (its description: the runtime's size), on the
    /// session's queue, before the runtime gets it back (`xrEndFrame`).
    fn display_ready(&self, _d: &DeviceState, _family: u32, _queue_index: u32, _display: &crate::bridge::Swapchain, _image: u64, _views: &[(u32, crate::core::views::ImageRect, u32)]) {}

    /// `vkDestroyDevice`, before it goes down (the device is idle).
    fn destroy(&self, _d: &DeviceState) {}
}
