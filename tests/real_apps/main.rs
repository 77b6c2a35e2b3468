//! A real engine through the layer, not the test ground's own: Bevy on the mock runtime and on
//! Monado in the trixie root (`hello_xr`, the real app, is its own binary). Its tests run as
//! threads of one process, so every run folder and file they write is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod engine_bevy;
