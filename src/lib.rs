//! stereoshim: an OpenXR API layer and a Vulkan layer in one library, making unmodified Vulkan VR
//! apps render less. `xr` and `vk` are the thin FFI shells; everything else is safe core logic
//! that needs no GPU and is unit-tested.

pub mod bridge;
pub mod core;
pub mod doctor;
pub mod features;
pub mod manifests;
pub mod plugin;
pub mod registry;
pub mod report;
pub mod track;
pub mod vk;
pub mod xr;
pub mod preview;
pub mod top;
