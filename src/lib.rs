//! stereoshim: an OpenXR API layer and a Vulkan layer in one library, making unmodified Vulkan VR
//! apps render less. The layer itself arrives with the layer-core issue; today the crate holds the
//! workspace root that the test harness (`tests/mock-runtime`, `tests/xr-scene`) builds against.
