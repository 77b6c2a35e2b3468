//! The test ground's own checks, no layer: xr-scene through the mock runtime (deterministic, the
//! expected scene, equivalent code paths agree), its far-field scene options, the harness's
//! comparisons on synthetic data, and its crash reports. One test binary: its tests run as
//! threads of one process, so every run folder and file they write is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod crash_report;
mod helpers;
mod scene_options;
mod xr_scene;
