//! Radial density masking (foveation method 2): `rules` is the pure skip/reconstruction rule;
//! `vk` draws the checkerboard at the chassis' injection point and hands skipped quads on through
//! the app's transfers; `reconstruct` fills them before the runtime sees the image (`compute`: over
//! periphery tiles only).

mod compute;
mod fill;
pub(crate) mod reconstruct;
pub mod rules;
pub(crate) mod vk;
