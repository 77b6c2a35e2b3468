//! Which device extensions and features stereoshim adds to the app's `vkCreateDevice`. Adding
//! anything to someone else's device can make that device fail to create, so the decision is a
//! pure function of what the device offers, what the app asked for and the configuration, and it
//! declines whenever a dependency or conflict is in doubt.

pub const FRAGMENT_SHADING_RATE: &str = "VK_KHR_fragment_shading_rate";
pub const CREATE_RENDERPASS_2: &str = "VK_KHR_create_renderpass2";
/// `VK_KHR_create_renderpass2`'s own dependencies on a Vulkan 1.0 device (core in 1.1).
pub const RENDERPASS_2_DEPENDENCIES_1_0: &[&str] = &["VK_KHR_multiview", "VK_KHR_maintenance2"];
/// Extensions whose features must not be enabled together with `pipelineFragmentShadingRate` /
/// `attachmentFragmentShadingRate` (VUIDs of `VkDeviceCreateInfo`: shadingRateImage-04478..,
/// fragmentDensityMap-04481..): if the app uses one, we never add shading rate.
pub const CONFLICTING: &[&str] = &["VK_NV_shading_rate_image", "VK_EXT_fragment_density_map"];

/// `VkPhysicalDeviceFragmentShadingRateFeaturesKHR` as the device reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FsrSupport {
    pub pipeline: bool,
    pub primitive: bool,
    pub attachment: bool,
}

#[derive(Clone, Debug)]
pub struct Inputs<'a> {
    /// `vkEnumerateDeviceExtensionProperties` of the physical device.
    pub available: &'a [String],
    /// `ppEnabledExtensionNames` of the app's create info.
    pub requested: &'a [String],
    /// min(physical device apiVersion, instance apiVersion): the version the device can be used at.
    pub api_version: u32,
    /// The instance can query `vkGetPhysicalDeviceFeatures2` (1.1 or
    /// VK_KHR_get_physical_device_properties2).
    pub instance_has_properties2: bool,
    /// `vulkan.fragment_shading_rate`: auto | on | off.
    pub fsr_mode: &'a str,
    /// Some feature may need shading rate (`foveation_wants_fsr`).
    pub feature_wants_fsr: bool,
    /// None when it could not be queried.
    pub fsr_support: Option<FsrSupport>,
}

/// What to change in the app's `VkDeviceCreateInfo`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Decision {
    /// Extension names to append (never one the app already asked for).
    pub add_extensions: Vec<&'static str>,
    /// Enable these members of `VkPhysicalDeviceFragmentShadingRateFeaturesKHR` (in a copy of the
    /// app's struct when it chained one).
    pub enable_fsr: Option<FsrSupport>,
    /// Why, for the log.
    pub reason: String,
}

/// Whether foveation asks for shading rate at device creation: `foveation.method` auto or vrs,
/// whether or not `foveation.enabled` is on yet — it can be switched on live, but extensions and
/// features can only be enabled when the device is created. (The device must still have
/// attachment rates: `decide` checks that.)
pub fn foveation_wants_fsr(method: &str) -> bool {
    matches!(method, "auto" | "vrs")
}

pub const PROPERTIES_2: &str = "VK_KHR_get_physical_device_properties2";

/// The instance extensions the layer adds to an app's `VkInstanceCreateInfo` (`XR_KHR_vulkan_enable2`
/// passes it through the OpenXR half): `VK_KHR_get_physical_device_properties2` on a Vulkan 1.0
/// instance when shading rate may be wanted, since `VK_KHR_fragment_shading_rate` needs it (or
/// 1.1) and the layer can only query the rate features through it. Only what the loader lists.
pub fn instance_additions(api_version: u32, requested: &[String], available: &[String], fsr_wanted: bool) -> Vec<&'static str> {
    let needed = fsr_wanted && api_version < ash::vk::API_VERSION_1_1 && !has(requested, PROPERTIES_2);
    if needed && has(available, PROPERTIES_2) {
        vec![PROPERTIES_2]
    } else {
        Vec::new()
    }
}

/// `XR_KHR_vulkan_enable`: the runtime's space-separated instance-extension list with `ext`
/// appended (the app enables what that call lists before creating its own instance), or None when
/// it is already there.
pub fn with_listed_extension(list: &str, ext: &str) -> Option<String> {
    if list.split(' ').any(|e| e == ext) {
        return None;
    }
    let list = list.trim_end_matches(' ');
    Some(if list.is_empty() { ext.to_string() } else { format!("{list} {ext}") })
}

/// Whether the configuration may want fragment shading rate on the app's devices
/// (`vulkan.fragment_shading_rate` on, or auto with foveation method auto/vrs).
pub fn config_wants_fsr(fsr_mode: &str, foveation_method: &str) -> bool {
    match fsr_mode {
        "off" => false,
        "on" => true,
        _ => foveation_wants_fsr(foveation_method),
    }
}

fn has(list: &[String], name: &str) -> bool {
    list.iter().any(|e| e == name)
}

pub fn decide(i: &Inputs<'_>) -> Decision {
    let no = |reason: String| Decision { reason, ..Decision::default() };
    let wanted = match i.fsr_mode {
        "off" => return no("fragment shading rate: off by configuration".into()),
        "on" => true,
        _ => i.feature_wants_fsr,
    };
    if !wanted {
        return no("fragment shading rate: auto, no enabled feature uses it".into());
    }
    if !has(i.available, FRAGMENT_SHADING_RATE) {
        return no(format!("fragment shading rate: device lacks {FRAGMENT_SHADING_RATE}"));
    }
    if let Some(c) = CONFLICTING.iter().find(|c| has(i.requested, c)) {
        return no(format!("fragment shading rate: app enables {c}, which conflicts"));
    }
    if i.api_version < ash::vk::API_VERSION_1_1 && !i.instance_has_properties2 {
        return no("fragment shading rate: instance lacks VK_KHR_get_physical_device_properties2".into());
    }
    // VK_KHR_fragment_shading_rate requires VK_KHR_create_renderpass2 (core in 1.2), which on a
    // 1.0 device requires VK_KHR_multiview and VK_KHR_maintenance2 (core in 1.1). A Vulkan 1.0 or
    // 1.1 app rarely enables them itself, so the layer adds whichever the device offers.
    let mut deps: Vec<&'static str> = Vec::new();
    if i.api_version < ash::vk::API_VERSION_1_2 {
        deps.push(CREATE_RENDERPASS_2);
        if i.api_version < ash::vk::API_VERSION_1_1 {
            deps.extend_from_slice(RENDERPASS_2_DEPENDENCIES_1_0);
        }
    }
    if let Some(lacking) = deps.iter().find(|e| !has(i.requested, e) && !has(i.available, e)) {
        return no(format!("fragment shading rate: device lacks {lacking}, which {FRAGMENT_SHADING_RATE} needs below Vulkan 1.2"));
    }
    deps.retain(|e| !has(i.requested, e));
    let Some(support) = i.fsr_support else {
        return no("fragment shading rate: features could not be queried".into());
    };
    if !support.attachment {
        return no("fragment shading rate: device lacks attachmentFragmentShadingRate".into());
    }
    let enable = FsrSupport { pipeline: support.pipeline, primitive: false, attachment: true };
    let already = has(i.requested, FRAGMENT_SHADING_RATE);
    let mut add_extensions = deps;
    if !already {
        add_extensions.push(FRAGMENT_SHADING_RATE);
    }
    Decision {
        add_extensions,
        enable_fsr: Some(enable),
        reason: format!(
            "fragment shading rate: {} {FRAGMENT_SHADING_RATE}, enabling attachment{} rates",
            if already { "app already enables" } else { "adding" },
            if enable.pipeline { " and pipeline" } else { "" }
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ash::vk;

    fn strings(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    fn inputs<'a>(available: &'a [String], requested: &'a [String], mode: &'a str) -> Inputs<'a> {
        Inputs {
            available,
            requested,
            api_version: vk::API_VERSION_1_3,
            instance_has_properties2: true,
            fsr_mode: mode,
            feature_wants_fsr: false,
            fsr_support: Some(FsrSupport { pipeline: true, primitive: true, attachment: true }),
        }
    }

    #[test]
    fn instance_gets_properties2_only_when_needed_and_listed() {
        let avail = strings(&[PROPERTIES_2]);
        let none = strings(&[]);
        assert_eq!(instance_additions(vk::API_VERSION_1_0, &none, &avail, true), vec![PROPERTIES_2]);
        assert!(instance_additions(vk::API_VERSION_1_1, &none, &avail, true).is_empty(), "core in 1.1");
        assert!(instance_additions(vk::API_VERSION_1_0, &avail, &avail, true).is_empty(), "app enables it");
        assert!(instance_additions(vk::API_VERSION_1_0, &none, &none, true).is_empty(), "loader lacks it");
        assert!(instance_additions(vk::API_VERSION_1_0, &none, &avail, false).is_empty(), "no shading rate wanted");
        assert!(config_wants_fsr("auto", "auto") && config_wants_fsr("on", "rdm") && !config_wants_fsr("off", "vrs"));
        assert!(!config_wants_fsr("auto", "rdm"));
    }

    #[test]
    fn listed_extension_is_appended_once() {
        assert_eq!(with_listed_extension("VK_KHR_a VK_KHR_b", PROPERTIES_2).as_deref(), Some("VK_KHR_a VK_KHR_b VK_KHR_get_physical_device_properties2"));
        assert_eq!(with_listed_extension("", PROPERTIES_2).as_deref(), Some(PROPERTIES_2));
        assert_eq!(with_listed_extension("VK_KHR_a ", PROPERTIES_2).as_deref(), Some("VK_KHR_a VK_KHR_get_physical_device_properties2"));
        assert_eq!(with_listed_extension("VK_KHR_get_physical_device_properties2 VK_KHR_a", PROPERTIES_2), None);
        assert!(with_listed_extension("VK_KHR_get_physical_device_properties2x", PROPERTIES_2).is_some());
    }

    #[test]
    fn off_and_auto_add_nothing() {
        let avail = strings(&[FRAGMENT_SHADING_RATE]);
        let req = strings(&[]);
        for mode in ["off", "auto"] {
            let d = decide(&inputs(&avail, &req, mode));
            assert!(d.add_extensions.is_empty() && d.enable_fsr.is_none(), "{mode}: {d:?}");
        }
        let d = decide(&Inputs { feature_wants_fsr: true, ..inputs(&avail, &req, "off") });
        assert!(d.enable_fsr.is_none());
    }

    #[test]
    fn on_adds_extension_and_features_when_available() {
        let avail = strings(&[FRAGMENT_SHADING_RATE, CREATE_RENDERPASS_2]);
        let req = strings(&["VK_KHR_multiview"]);
        let d = decide(&inputs(&avail, &req, "on"));
        assert_eq!(d.add_extensions, vec![FRAGMENT_SHADING_RATE]);
        assert_eq!(d.enable_fsr, Some(FsrSupport { pipeline: true, primitive: false, attachment: true }));
        // auto with a feature asking behaves like on.
        let d = decide(&Inputs { feature_wants_fsr: true, ..inputs(&avail, &req, "auto") });
        assert_eq!(d.add_extensions, vec![FRAGMENT_SHADING_RATE]);
    }

    #[test]
    fn foveation_asks_for_shading_rate_unless_it_is_rdm() {
        assert!(foveation_wants_fsr("auto") && foveation_wants_fsr("vrs") && !foveation_wants_fsr("rdm"));
        let avail = strings(&[FRAGMENT_SHADING_RATE]);
        let req = strings(&[]);
        let d = decide(&Inputs { feature_wants_fsr: foveation_wants_fsr("auto"), ..inputs(&avail, &req, "auto") });
        assert_eq!(d.enable_fsr, Some(FsrSupport { pipeline: true, primitive: false, attachment: true }));
        // ... but not on a device without attachment rates (lavapipe), nor with rdm.
        let no_att = FsrSupport { pipeline: true, primitive: true, attachment: false };
        let d = decide(&Inputs { feature_wants_fsr: true, fsr_support: Some(no_att), ..inputs(&avail, &req, "auto") });
        assert!(d.enable_fsr.is_none() && d.add_extensions.is_empty());
        let none = strings(&[]);
        assert!(decide(&Inputs { feature_wants_fsr: true, ..inputs(&none, &req, "auto") }).enable_fsr.is_none());
        let d = decide(&Inputs { feature_wants_fsr: foveation_wants_fsr("rdm"), ..inputs(&avail, &req, "auto") });
        assert!(d.enable_fsr.is_none());
    }

    #[test]
    fn never_adds_twice_or_to_a_device_without_it() {
        let avail = strings(&[FRAGMENT_SHADING_RATE]);
        let req = strings(&[FRAGMENT_SHADING_RATE]);
        let d = decide(&inputs(&avail, &req, "on"));
        assert!(d.add_extensions.is_empty() && d.enable_fsr.is_some(), "{d:?}");
        let none = strings(&["VK_KHR_swapchain"]);
        let d = decide(&inputs(&none, &req, "on"));
        assert!(d.add_extensions.is_empty() && d.enable_fsr.is_none(), "{d:?}");
        assert!(d.reason.contains("lacks"), "{}", d.reason);
    }

    #[test]
    fn dependencies_and_conflicts_decline() {
        let avail = strings(&[FRAGMENT_SHADING_RATE, CREATE_RENDERPASS_2]);
        let req = strings(&[]);
        // 1.1 device without the app's create_renderpass2: the layer adds it.
        let d = decide(&Inputs { api_version: vk::API_VERSION_1_1, ..inputs(&avail, &req, "on") });
        assert!(d.enable_fsr.is_some(), "{d:?}");
        assert_eq!(d.add_extensions, vec![CREATE_RENDERPASS_2, FRAGMENT_SHADING_RATE]);
        // ... with it, only shading rate is added.
        let req2 = strings(&[CREATE_RENDERPASS_2]);
        let d = decide(&Inputs { api_version: vk::API_VERSION_1_1, ..inputs(&avail, &req2, "on") });
        assert_eq!(d.add_extensions, vec![FRAGMENT_SHADING_RATE]);
        // A device that does not offer create_renderpass2 below 1.2: declined.
        let only_fsr = strings(&[FRAGMENT_SHADING_RATE]);
        let d = decide(&Inputs { api_version: vk::API_VERSION_1_1, ..inputs(&only_fsr, &req, "on") });
        assert!(d.enable_fsr.is_none() && d.add_extensions.is_empty(), "{d:?}");
        assert!(d.reason.contains(CREATE_RENDERPASS_2), "{}", d.reason);
        // Vulkan 1.0 (a 1.0 app on any GPU): create_renderpass2 and its 1.1 dependencies too.
        let all = strings(&[FRAGMENT_SHADING_RATE, CREATE_RENDERPASS_2, "VK_KHR_multiview", "VK_KHR_maintenance2"]);
        let d = decide(&Inputs { api_version: vk::API_VERSION_1_0, ..inputs(&all, &req, "on") });
        assert_eq!(d.add_extensions, vec![CREATE_RENDERPASS_2, "VK_KHR_multiview", "VK_KHR_maintenance2", FRAGMENT_SHADING_RATE]);
        let d = decide(&Inputs { api_version: vk::API_VERSION_1_0, ..inputs(&avail, &req, "on") });
        assert!(d.enable_fsr.is_none(), "1.0 device without VK_KHR_multiview: {d:?}");
        // 1.0 instance without properties2.
        let d = decide(&Inputs {
            api_version: vk::API_VERSION_1_0,
            instance_has_properties2: false,
            ..inputs(&avail, &req2, "on")
        });
        assert!(d.enable_fsr.is_none());
        let req3 = strings(&["VK_EXT_fragment_density_map"]);
        assert!(decide(&inputs(&avail, &req3, "on")).enable_fsr.is_none());
        // Feature not supported / not queryable.
        let d = decide(&Inputs { fsr_support: Some(FsrSupport::default()), ..inputs(&avail, &req, "on") });
        assert!(d.enable_fsr.is_none());
        assert!(decide(&Inputs { fsr_support: None, ..inputs(&avail, &req, "on") }).enable_fsr.is_none());
    }
}
