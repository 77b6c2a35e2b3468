//! The loader ↔ layer interface structs that `ash` does not define (they belong to the loader's
//! `vk_layer.h`, not to the Vulkan registry `ash` is generated from).
//!
//! Defined here from the loader's documented interface (LoaderLayerInterface.md, `vk_layer.h` of
//! Vulkan-Loader 1.3) rather than taken from a crate: the few crates that carry them
//! (`ash-layer`, `vulkan-layer`) bring their own dispatch machinery and pin other `ash` versions,
//! while we need six plain `#[repr(C)]` types that match `ash::vk` 0.38 exactly. Layouts are
//! checked by the tests below against the C layout rules on this target.

use ash::vk;
use std::ffi::{c_char, c_void};

/// `VK_STRUCTURE_TYPE_LOADER_INSTANCE_CREATE_INFO`: the loader's structs in the `pNext` chain of
/// `VkInstanceCreateInfo` given to a layer.
pub const LOADER_INSTANCE_CREATE_INFO: vk::StructureType = vk::StructureType::from_raw(47);
/// `VK_STRUCTURE_TYPE_LOADER_DEVICE_CREATE_INFO`, the same for `VkDeviceCreateInfo`.
pub const LOADER_DEVICE_CREATE_INFO: vk::StructureType = vk::StructureType::from_raw(48);

/// `VkNegotiateLayerStructType::LAYER_NEGOTIATE_INTERFACE_STRUCT`.
pub const LAYER_NEGOTIATE_INTERFACE_STRUCT: i32 = 1;
/// The loader–layer interface version this layer implements: 2 adds
/// `vkNegotiateLoaderLayerInterfaceVersion` and the optional `vk_layerGetPhysicalDeviceProcAddr`
/// (which we do not need: we intercept no physical-device extension commands).
pub const LAYER_INTERFACE_VERSION: u32 = 2;

/// `PFN_GetPhysicalDeviceProcAddr` (the loader's, not a Vulkan command).
pub type PfnGetPhysicalDeviceProcAddr =
    Option<unsafe extern "system" fn(vk::Instance, *const c_char) -> vk::PFN_vkVoidFunction>;

/// `VkNegotiateLayerInterface`.
#[repr(C)]
#[derive(Debug)]
pub struct NegotiateLayerInterface {
    pub s_type: i32,
    pub p_next: *mut c_void,
    pub loader_layer_interface_version: u32,
    pub pfn_get_instance_proc_addr: Option<vk::PFN_vkGetInstanceProcAddr>,
    pub pfn_get_device_proc_addr: Option<vk::PFN_vkGetDeviceProcAddr>,
    pub pfn_get_physical_device_proc_addr: PfnGetPhysicalDeviceProcAddr,
}

/// `VkLayerFunction`: which member of the create-info union is valid.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerFunction(pub i32);

impl LayerFunction {
    /// `VK_LAYER_LINK_INFO`: `u.pLayerInfo` is the chain of next layers.
    pub const LINK_INFO: LayerFunction = LayerFunction(0);
    /// `VK_LOADER_DATA_CALLBACK`: `u.pfnSet*LoaderData`.
    pub const LOADER_DATA_CALLBACK: LayerFunction = LayerFunction(1);
}

/// `VkLayerInstanceLink`: one element of the list of layers below us.
#[repr(C)]
#[derive(Debug)]
pub struct LayerInstanceLink {
    pub p_next: *mut LayerInstanceLink,
    pub pfn_next_get_instance_proc_addr: vk::PFN_vkGetInstanceProcAddr,
    pub pfn_next_get_physical_device_proc_addr: PfnGetPhysicalDeviceProcAddr,
}

/// `VkLayerInstanceCreateInfo`. The C union's other members (loader data callback, layer device
/// callbacks, loader feature flags) are at most two pointers wide; only `pLayerInfo` is read, the
/// padding keeps the size equal to C's.
#[repr(C)]
#[derive(Debug)]
pub struct LayerInstanceCreateInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub function: LayerFunction,
    pub p_layer_info: *mut LayerInstanceLink,
    _union_rest: *const c_void,
}

/// `VkLayerDeviceLink`.
#[repr(C)]
#[derive(Debug)]
pub struct LayerDeviceLink {
    pub p_next: *mut LayerDeviceLink,
    pub pfn_next_get_instance_proc_addr: vk::PFN_vkGetInstanceProcAddr,
    pub pfn_next_get_device_proc_addr: vk::PFN_vkGetDeviceProcAddr,
}

/// `VkLayerDeviceCreateInfo` (its union: `pLayerInfo` or `pfnSetDeviceLoaderData`, one pointer).
#[repr(C)]
#[derive(Debug)]
pub struct LayerDeviceCreateInfo {
    pub s_type: vk::StructureType,
    pub p_next: *const c_void,
    pub function: LayerFunction,
    pub p_layer_info: *mut LayerDeviceLink,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn layouts_match_c() {
        let p = size_of::<*const c_void>();
        assert_eq!(offset_of!(NegotiateLayerInterface, loader_layer_interface_version), 2 * p);
        assert_eq!(size_of::<NegotiateLayerInterface>(), 6 * p);
        // sType (4, padded to 8), pNext, function (4, padded), union.
        assert_eq!(offset_of!(LayerInstanceCreateInfo, p_layer_info), 3 * p);
        assert_eq!(size_of::<LayerInstanceCreateInfo>(), 5 * p);
        assert_eq!(offset_of!(LayerDeviceCreateInfo, p_layer_info), 3 * p);
        assert_eq!(size_of::<LayerDeviceLink>(), 3 * p);
        assert_eq!(size_of::<LayerInstanceLink>(), 3 * p);
    }
}
