//! Upscaling: the app renders fewer pixels and the layer upscales them into the runtime's
//! swapchain. So far its filters, on the CPU (`filter`: EASU + RCAS and bilinear, and the
//! quality measures the upscale is judged by); the swapchain interposition and the GPU passes
//! come next, held to this reference.

pub mod filter;
