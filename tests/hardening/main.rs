//! Hardening (issues 11 and 23): lifecycles and the layer's own Vulkan objects flat across
//! sessions, faults below the layer (OpenXR and Vulkan), re-entry from below, a multi-threaded app,
//! hostile configuration, the files the layer writes, and the layer under valgrind memcheck. One
//! test binary: its tests run as threads of one process, so every run folder and file they write
//! is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod faults_vk;
mod faults_xr;
mod files;
mod hostile_config;
mod lifecycle;
mod memcheck;
mod reentry;
mod threads;
mod vk_objects;
