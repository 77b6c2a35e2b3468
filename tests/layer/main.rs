//! The layer as a whole, every feature off or as loaded: the OpenXR layer passing everything
//! through, the Vulkan half on its own, every manifest against both loaders, the built library's
//! symbols, and the warnings that keep it from being silent. One test binary: its tests run as
//! threads of one process, so every run folder and file they write is named for its test.

#[path = "../common/mod.rs"]
mod common;

mod manifests;
mod notices;
mod pass_through;
mod symbols;
mod vulkan_layer;
