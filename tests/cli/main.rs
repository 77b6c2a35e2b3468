//! The `stereoshim` command end to end: install, status, run, manifest and stats; `doctor`;
//! `preview`. One test binary: its tests run as threads of one process, so every run folder and
//! file they write is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod commands;
mod doctor;
mod preview;
