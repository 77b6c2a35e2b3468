//! The features, one folder each: its keys and settings, its pure rules, its Vulkan and OpenXR
//! halves. A feature depends on the base, the trackers and the plug-in contracts only, never on
//! another feature; `crate::registry` is the one place that lists them in dispatch order.

pub mod far_field;
pub mod foveation;
pub mod mask;
/// Not a registry plug-in: the overlay draws nothing into the app's passes (its shell is
/// `crate::xr::overlay`).
pub mod overlay;
pub mod screenshot;
/// Not a registry plug-in: the upscale changes no app pass (its shell is `crate::xr::upscale`).
pub mod upscale;
pub mod views;

