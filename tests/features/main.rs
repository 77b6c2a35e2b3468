//! The features end to end on xr-scene and the mock runtime (lavapipe): the hidden-area mask,
//! foveation (RDM, VRS, eye tracking), the far field, behind post-processing chains, with command
//! buffers recorded once, the GPU timer, the overlay, screenshots, the upscale (and its GPU passes
//! against their CPU reference), and the views (FOV cut, symmetric and parallel). One test
//! binary: its tests run as threads of one process, so every run folder and file they write is
//! named for its test.

#[path = "../common/mod.rs"]
mod common;
#[path = "../upscale_gpu/mod.rs"]
mod upscale_gpu;

mod eye_tracking;
mod far_field;
mod foveation;
mod gpu_time;
mod mask;
mod mask_app_drawn;
mod mask_geometry;
mod mask_source;
mod overlay;
mod post_chain;
mod post_chain_far_field;
mod post_chain_layer;
mod post_chain_rdm;
mod record_once;
mod screenshot;
mod top;
mod upscale;
mod upscale_filters;
mod views;
mod views_widened;
mod vrs;
