//! stereoshim: an OpenXR API layer and a Vulkan layer in one library, making unmodified Vulkan VR
//! apps render less. `xr` and `vk` are the thin FFI shells; everything else is safe core logic
//! that needs no GPU and is unit-tested.

pub mod bridge;
pub mod core;
pub mod doctor;
pub mod features;
pub mod frame_stats;
pub mod guard;
pub mod log;
pub mod manifest;
pub mod notices;
pub mod plugin;
pub mod private_fs;
pub mod registry;
pub mod stats_summary;
pub mod track;
pub mod vk;
pub mod vk_manifest;
pub mod xr;
pub mod install;
pub mod preview;
