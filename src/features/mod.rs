//! The features, one folder each: its keys and settings, its pure rules, its Vulkan and OpenXR
//! halves. A feature depends on the base, the trackers and the plug-in contracts only, never on
//! another feature or on a shell; the registry (`src/registry.rs`) is the one place that lists them
//! in dispatch order.

pub mod far_field;
pub mod foveation;
pub mod live;
pub mod mask;
/// Not a registry plug-in: the overlay draws nothing into the app's passes (the OpenXR shell
/// calls its `xr` half).
pub mod overlay;
pub mod screenshot;
/// Not a registry plug-in: the upscale changes no app pass (the OpenXR shell calls its `xr` half).
pub mod upscale;
pub mod views;

