//! The plug-in contracts: what a feature may see and do. The typed settings (the chassis' own and,
//! by type, each feature's), the Vulkan and OpenXR feature traits with the context they are
//! given (`xr`: the OpenXR side), and the shared GPU helpers. Nothing here names a feature or a
//! shell: the registry (`src/registry.rs`) names the features.

pub mod settings;
pub mod vk;
pub mod xr;
