//! What a feature is to the OpenXR chassis: the events the OpenXR hooks raise over the registry's
//! list of features (`XR_FEATURES`), each with a do-nothing default. Per-session state lives in
//! the session's `features` by type (made by the registry, read with `Session::feature`), so no
//! hook names a feature.
//!
//! Events: `wanted_extensions` (xrCreateInstance), `swapchain_usage` (xrCreateSwapchain, may add
//! usage), `action_sets` / `action_sets_attached` / `active_action_sets`
//! (xrAttachSessionActionSets, xrSyncActions: the feature's own actions next to the app's),
//! `amend_views` and `views_located` (xrLocateViews), `frame_begun` (xrBeginFrame: publish what the Vulkan half
//! needs for the frame the app is about to record), `amend_frame_end` (xrEndFrame: may submit
//! amended layers in place of the app's), `views_enumerated` (xrEnumerateViewConfigurationViews:
//! may change what the app is told), `event` (xrPollEvent), `config_reloaded` (between frames),
//! `frame_stats` (the frame's `stats.file` line).
//! Image release reaches the Vulkan features (`crate::plugin::vk::before_release`).

use super::{Instance, Session};
use crate::plugin::settings::Settings;
use openxr_sys as xr;
use std::any::Any;

/// The app's `XrFrameEndInfo` with a feature's changes: `info` points into `_keep`, which lives
/// while the call goes down.
pub(crate) struct AmendedFrameEnd {
    pub info: xr::FrameEndInfo,
    pub _keep: Box<dyn Any>,
}

pub(crate) trait XrFeature: Sync {
    /// The registry id.
    fn id(&self) -> &'static str;
    /// Instance extensions the feature uses for itself, enabled when the runtime has them (asked
    /// once, at instance creation: they cannot be enabled later, so a feature asks whenever it may
    /// be switched on while the app runs).
    fn wanted_extensions(&self, _s: &Settings) -> Vec<&'static str> {
        Vec::new()
    }
    /// Usage the feature adds to a swapchain the app creates with `usage`.
    fn swapchain_usage(&self, _s: &Settings, _usage: xr::SwapchainUsageFlags) -> xr::SwapchainUsageFlags {
        xr::SwapchainUsageFlags::EMPTY
    }
    /// Action sets of the feature's to attach along with the app's (`xrAttachSessionActionSets`).
    fn action_sets(&self, _s: &Session) -> Vec<xr::ActionSet> {
        Vec::new()
    }
    /// The attach with the feature's sets went down with result `r`.
    fn action_sets_attached(&self, _s: &Session, _r: xr::Result) {}
    /// Action sets of the feature's to sync along with the app's (`xrSyncActions`).
    fn active_action_sets(&self, _s: &Session) -> Vec<xr::ActiveActionSet> {
        Vec::new()
    }
    /// The app located its views.
    fn views_located(&self, _s: &Session, _info: &xr::ViewLocateInfo, _views: &[xr::View]) {}
    /// `xrBeginFrame` succeeded: the app records the frame's passes next.
    fn frame_begun(&self, _s: &Session) {}
    /// The runtime answered `xrEnumerateViewConfigurationViews` of `system` with `views`; the
    /// feature may change what the app is told (e.g. the recommended sizes). Before the upscale
    /// scales them.
    fn views_enumerated(&self, _inst: &Instance, _system: xr::SystemId, _config: xr::ViewConfigurationType, _s: &Settings, _views: &mut [xr::ViewConfigurationView]) {}
    /// The runtime located the app's views (`views`, what the app will get); the feature may
    /// change them (angles, orientations) before anything else sees them.
    fn amend_views(&self, _s: &Session, _info: &xr::ViewLocateInfo, _views: &mut [xr::View]) {}
    /// The app asks for view `view`'s visibility mask of type `ty`: a feature that changed the
    /// app's views answers with the mesh as those views see it (triangles, three points each;
    /// a line loop's points in order), which the app gets instead of the runtime's (the first
    /// feature that answers wins). Asked with no lock of the layer's held: it may call down.
    fn amend_visibility_mask(&self, _s: &Session, _view: u32, _ty: xr::VisibilityMaskTypeKHR) -> Option<Vec<[f32; 2]>> {
        None
    }
    /// The runtime lacks `XR_KHR_visibility_mask` and the layer offers it to the app: the mesh of
    /// type `ty` for `view` (points, indexed in order), from the feature that knows the lens.
    /// `s`: the session, when the layer tracks it (not while the config switches the layer off).
    fn offered_visibility_mask(&self, _inst: &Instance, _s: Option<&Session>, _view: u32, _ty: xr::VisibilityMaskTypeKHR) -> Option<Vec<[f32; 2]>> {
        None
    }
    /// `xrEndFrame` is about to go down with the app's `info`; an amended copy replaces it (the
    /// first feature that amends wins).
    fn amend_frame_end(&self, _s: &Session, _info: &xr::FrameEndInfo) -> Option<AmendedFrameEnd> {
        None
    }
    /// The runtime delivered `event`; true when it is the layer's own (the app does not see it).
    fn event(&self, _inst: &Instance, _event: &xr::EventDataBuffer) -> bool {
        false
    }
    /// The configuration was reloaded with `changed` keys.
    fn config_reloaded(&self, _s: &Session, _changed: &[&'static str]) {}
    /// Fields of the feature's for the frame's `stats.file` line (written after `xrEndFrame`).
    fn frame_stats(&self, _s: &Session) -> Vec<(&'static str, serde_json::Value)> {
        Vec::new()
    }
    /// A file the frame's stats line also goes to, besides `stats.file` (`stereoshim top`'s
    /// stream while it watches), capped at `core::live::STREAM_MAX_BYTES`.
    fn stats_stream(&self, _s: &Session) -> Option<std::path::PathBuf> {
        None
    }
}
