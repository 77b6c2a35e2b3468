//! stereoshim: an OpenXR API layer and a Vulkan layer in one library, making unmodified Vulkan VR
//! apps render less. The FFI shells (`xr`, `vk`) arrive with the layer core; the safe core modules
//! below need no GPU and are unit-tested.

pub mod config;
