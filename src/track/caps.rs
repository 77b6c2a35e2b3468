//! What the app's device can legally be asked to do, read from its `VkDeviceCreateInfo` (plus what
//! the layer added there), and what each object the layer creates on that device needs. Everything
//! the layer creates must be valid for *that* device: a Vulkan 1.0 device without `multiview` must
//! never see a shader module declaring the `MultiView` capability (VUID-VkShaderModuleCreateInfo-
//! pCode-08740), a pipeline for dynamic rendering needs `dynamicRendering`, and so on. A feature
//! whose object needs more than the device has is not applied on that device (logged once,
//! counted), never created anyway.

use ash::vk;

/// The device as created: its usable API version and the relevant features that were enabled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceCaps {
    /// min(instance `apiVersion`, physical device `apiVersion`): the version the device is used at.
    pub api_version: u32,
    /// `multiview` enabled (`VkPhysicalDeviceMultiviewFeatures` or `Vulkan11Features`).
    pub multiview: bool,
    /// `dynamicRendering` enabled (`VkPhysicalDeviceDynamicRenderingFeatures` or `Vulkan13Features`).
    pub dynamic_rendering: bool,
    /// `vkCreateRenderPass2` is usable: Vulkan 1.2, or `VK_KHR_create_renderpass2` enabled (by the
    /// app or the layer).
    pub render_pass2: bool,
    /// `attachmentFragmentShadingRate` enabled (by the app or the layer).
    pub fsr_attachment: bool,
}

/// What one kind of layer object needs from the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    pub multiview: bool,
    pub dynamic_rendering: bool,
    pub render_pass2: bool,
    pub fsr_attachment: bool,
}

/// The first capability `needs` asks for that the device lacks, by its spec name.
pub fn missing(caps: &DeviceCaps, needs: &Needs) -> Option<&'static str> {
    [
        (needs.multiview && !caps.multiview, "multiview"),
        (needs.dynamic_rendering && !caps.dynamic_rendering, "dynamicRendering"),
        (needs.render_pass2 && !caps.render_pass2, "VK_KHR_create_renderpass2"),
        (needs.fsr_attachment && !caps.fsr_attachment, "attachmentFragmentShadingRate"),
    ]
    .into_iter()
    .find_map(|(lacks, name)| lacks.then_some(name))
}

/// The feature flags found in a `VkDeviceCreateInfo` chain, as plain booleans (the FFI shell reads
/// the structs; this keeps the rule testable).
#[derive(Clone, Copy, Debug, Default)]
pub struct ChainedFeatures {
    pub multiview: bool,
    pub dynamic_rendering: bool,
}

/// Capabilities of a device created at `api_version` with `extensions` enabled (the app's plus
/// the layer's additions) and `features` chained, with `fsr_attachment` when the layer (or the
/// app) enabled attachment rates.
pub fn from_create_info(api_version: u32, extensions: &[String], features: ChainedFeatures, fsr_attachment: bool) -> DeviceCaps {
    let has = |name: &str| extensions.iter().any(|e| e == name);
    DeviceCaps {
        api_version,
        // A feature of an extension or core version is only enabled through its features struct;
        // enabling the extension alone enables no feature.
        multiview: features.multiview && (api_version >= vk::API_VERSION_1_1 || has("VK_KHR_multiview")),
        dynamic_rendering: features.dynamic_rendering
            && (api_version >= vk::API_VERSION_1_3 || has("VK_KHR_dynamic_rendering")),
        render_pass2: api_version >= vk::API_VERSION_1_2 || has("VK_KHR_create_renderpass2"),
        fsr_attachment,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn vulkan_1_0_device_has_nothing_beyond_1_0() {
        let c = from_create_info(vk::API_VERSION_1_0, &[], ChainedFeatures::default(), false);
        assert_eq!(c, DeviceCaps { api_version: vk::API_VERSION_1_0, ..Default::default() });
        assert_eq!(missing(&c, &Needs::default()), None, "a per-eye draw needs nothing");
        assert_eq!(missing(&c, &Needs { multiview: true, ..Default::default() }), Some("multiview"));
        assert_eq!(missing(&c, &Needs { dynamic_rendering: true, ..Default::default() }), Some("dynamicRendering"));
    }

    #[test]
    fn features_need_their_struct_and_their_version_or_extension() {
        let both = ChainedFeatures { multiview: true, dynamic_rendering: true };
        // 1.0 with the features chained but no extension: not enabled (the struct is invalid there).
        let c = from_create_info(vk::API_VERSION_1_0, &[], both, false);
        assert!(!c.multiview && !c.dynamic_rendering);
        let c = from_create_info(vk::API_VERSION_1_0, &names(&["VK_KHR_multiview", "VK_KHR_create_renderpass2"]), both, false);
        assert!(c.multiview && !c.dynamic_rendering && c.render_pass2);
        let c = from_create_info(vk::API_VERSION_1_1, &[], both, false);
        assert!(c.multiview && !c.dynamic_rendering && !c.render_pass2);
        let c = from_create_info(vk::API_VERSION_1_3, &[], both, true);
        assert!(c.multiview && c.dynamic_rendering && c.render_pass2 && c.fsr_attachment);
        // 1.3 without the feature structs: extensions of the core version are there, features not.
        let c = from_create_info(vk::API_VERSION_1_3, &[], ChainedFeatures::default(), false);
        assert!(!c.multiview && !c.dynamic_rendering && c.render_pass2);
    }

    #[test]
    fn first_missing_capability_is_named() {
        let c = DeviceCaps { api_version: vk::API_VERSION_1_3, multiview: true, ..Default::default() };
        let n = Needs { multiview: true, dynamic_rendering: true, fsr_attachment: true, ..Default::default() };
        assert_eq!(missing(&c, &n), Some("dynamicRendering"));
        let full = DeviceCaps { api_version: vk::API_VERSION_1_3, multiview: true, dynamic_rendering: true, render_pass2: true, fsr_attachment: true };
        assert_eq!(missing(&full, &n), None);
    }
}

/// `VkPhysicalDeviceFragmentShadingRatePropertiesKHR`, the parts the map needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DeviceRates {
    /// `minFragmentShadingRateAttachmentTexelSize`: the finest map the device takes.
    pub texel_width: u32,
    pub texel_height: u32,
    /// `layeredShadingRateAttachments`: multiview passes can read one layer per view.
    pub layered: bool,
}
