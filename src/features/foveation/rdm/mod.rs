//! Radial density masking (foveation method 2): `rules` is the pure skip/reconstruction rule;
//! `vk` draws the checkerboard at the chassis' injection point and hands skipped quads on through
//! the app's transfers; `reconstruct` fills them before the runtime sees the image (`compute`: over
//! periphery tiles only); behind a post chain, `pass_end` (pure) and `pass_end_vk` reconstruct
//! right after the eye pass, in the app's command buffer (`pass_end_compute`: the compute pass
//! over periphery tiles there, the fill where it cannot run).

mod compute;
mod fill;
pub mod pass_end;
mod pass_end_compute;
mod pass_end_vk;
pub(crate) mod reconstruct;
pub mod rules;
pub(crate) mod vk;
