//! The OpenXR plug-in contract: what an OpenXR feature may see. The feature trait and its events
//! (`XrFeature`), the instance and session it is given (each feature's state in them by type,
//! never by name), the next layer's dispatch table (`Next`, from the one list of calls,
//! `xr_calls!`), the live settings, and the few OpenXR facts features share. The shell (`crate::xr`)
//! builds on this; nothing here names the shell, the registry or a feature.

mod feature;
mod instance;
mod next;
mod session;

pub(crate) use feature::{AmendedFrameEnd, XrFeature};
pub(crate) use instance::{Instance, Stats};
pub(crate) use next::{xr_calls, Next};
pub(crate) use session::{fov_tangents, sessions, LocatedView, Session, VulkanBinding};

use crate::plugin::settings::Settings;
use openxr_sys as xr;
use std::sync::Arc;

pub(crate) use crate::core::views::VISIBILITY_MASK_EXT;
pub(crate) const EYE_GAZE_EXT: &str = "XR_EXT_eye_gaze_interaction";

/// An `XrVisibilityMaskKHR` asking for the counts only (the two-call idiom's first call).
pub(crate) fn empty_visibility_mask() -> xr::VisibilityMaskKHR {
    xr::VisibilityMaskKHR {
        ty: xr::VisibilityMaskKHR::TYPE,
        next: std::ptr::null_mut(),
        vertex_capacity_input: 0,
        vertex_count_output: 0,
        vertices: std::ptr::null_mut(),
        index_capacity_input: 0,
        index_count_output: 0,
        indices: std::ptr::null_mut(),
    }
}

/// The live settings (published with the config at instance creation and on every reload), else
/// those of the instance's own config.
pub(crate) fn settings(inst: &Instance) -> Arc<Settings> {
    crate::plugin::settings::current().unwrap_or_else(|| Arc::new(Settings::from_config(&inst.config)))
}
