//! The pure core every feature and both shells build on: rectangles, fovea geometry, the eye-pass
//! vocabulary, the per-feature statistics registry, a lens's hidden pixels and their reframing
//! into another view, the lifetime rules of layer objects and the bookkeeping of the layer's GPU
//! frame timer. Nothing here touches Vulkan or OpenXR, and nothing
//! here knows a feature.
#![forbid(unsafe_code)]

pub mod config;
pub mod fovea;
pub mod gpu_time;
pub mod guard;
pub mod handles;
pub mod hmd;
pub mod lens;
pub mod lifetime;
pub mod live;
pub mod log;
pub mod parts;
pub mod pass;
pub mod rect;
pub mod reframe;
pub mod stats;
pub mod views;
