//! Real apps through the layer, not the test ground's own: Debian bookworm's Khronos `hello_xr`
//! on the mock runtime, and a real engine (Bevy) on the mock runtime and on Monado in the trixie
//! root. One test binary: its tests run as threads of one process, so every run folder and file
//! they write is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod engine_bevy;
mod hello_xr;
