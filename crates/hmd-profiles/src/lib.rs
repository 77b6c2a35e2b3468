//! Headset profiles as data, in one place: the mock runtime serves them to apps and layers under
//! test, and `stereoshim preview --hmd` shows what the layer would do on them. Pure and safe.
#![forbid(unsafe_code)]

pub mod mask;
pub mod profile;
