//! Upscaling: the app renders fewer pixels and the layer upscales them into the runtime's
//! swapchain. So far its filters: on the CPU (`filter`: EASU + RCAS and bilinear, and the quality
//! measures the upscale is judged by) and as the GPU passes held to them (`gpu`); and its
//! geometry (`rules`: the sizes the app is told, the runtime's rects, the LOD bias). The
//! swapchain interposition that runs them at `xrEndFrame` comes with the plug-in.

pub mod filter;
pub mod gpu;
pub mod rules;
