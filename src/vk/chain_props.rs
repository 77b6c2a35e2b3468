//! Property tests of the `VkDeviceCreateInfo` rewrite (issue 11: random but valid `pNext`
//! chains). For any chain of feature structs the app may pass: the rewrite keeps every app struct
//! in its order with its contents (linking to the app's own or to exact copies), enables the
//! shading-rate features it decided on in the one struct of that type (the app's choices kept),
//! never chains a structure type twice (`VUID-VkDeviceCreateInfo-sType-unique`), appends only the
//! extensions it decided on, leaves the app's create info untouched, and declines (the app's
//! info goes down as it came) exactly when a struct it cannot copy precedes the app's own
//! shading-rate features.

use super::*;
use crate::plugin::vk::test_chain::{has_duplicates, walk, Chain};
use proptest::prelude::*;
use vk::StructureType as S;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Ext {
    Features2,
    V11,
    V12,
    V13,
    Multiview,
    DynamicRendering,
    Sync2,
    Imageless,
    Timeline,
    /// The app's own shading-rate features, with its choices.
    Rate { pipeline: bool, primitive: bool, attachment: bool },
    /// Structs the rewrite has no size for.
    MeshShader,
    DeviceGroup,
}

fn push(c: &mut Chain, e: Ext) {
    match e {
        Ext::Features2 => c.push(vk::PhysicalDeviceFeatures2 { features: vk::PhysicalDeviceFeatures { sample_rate_shading: 1, ..Default::default() }, ..Default::default() }),
        Ext::V11 => c.push(vk::PhysicalDeviceVulkan11Features { multiview: 1, ..Default::default() }),
        Ext::V12 => c.push(vk::PhysicalDeviceVulkan12Features { timeline_semaphore: 1, ..Default::default() }),
        Ext::V13 => c.push(vk::PhysicalDeviceVulkan13Features { dynamic_rendering: 1, ..Default::default() }),
        Ext::Multiview => c.push(vk::PhysicalDeviceMultiviewFeatures { multiview: 1, ..Default::default() }),
        Ext::DynamicRendering => c.push(vk::PhysicalDeviceDynamicRenderingFeatures { dynamic_rendering: 1, ..Default::default() }),
        Ext::Sync2 => c.push(vk::PhysicalDeviceSynchronization2Features { synchronization2: 1, ..Default::default() }),
        Ext::Imageless => c.push(vk::PhysicalDeviceImagelessFramebufferFeatures { imageless_framebuffer: 1, ..Default::default() }),
        Ext::Timeline => c.push(vk::PhysicalDeviceTimelineSemaphoreFeatures { timeline_semaphore: 1, ..Default::default() }),
        Ext::Rate { pipeline, primitive, attachment } => c.push(vk::PhysicalDeviceFragmentShadingRateFeaturesKHR {
            pipeline_fragment_shading_rate: pipeline.into(),
            primitive_fragment_shading_rate: primitive.into(),
            attachment_fragment_shading_rate: attachment.into(),
            ..Default::default()
        }),
        Ext::MeshShader => c.push(vk::PhysicalDeviceMeshShaderFeaturesEXT { mesh_shader: 1, ..Default::default() }),
        Ext::DeviceGroup => c.push(vk::DeviceGroupDeviceCreateInfo::default()),
    }
}

/// Size of each struct a test chain holds, to compare contents byte for byte.
fn size_of_type(t: vk::StructureType) -> usize {
    use std::mem::size_of;
    match t {
        S::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR => size_of::<vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>>(),
        S::PHYSICAL_DEVICE_MESH_SHADER_FEATURES_EXT => size_of::<vk::PhysicalDeviceMeshShaderFeaturesEXT<'_>>(),
        S::DEVICE_GROUP_DEVICE_CREATE_INFO => size_of::<vk::DeviceGroupDeviceCreateInfo<'_>>(),
        t => chained_struct_size(t).expect("a struct of the test's list"),
    }
}

/// A struct's bytes after its sType and pNext (the contents).
fn contents(t: vk::StructureType, p: *const c_void) -> Vec<u8> {
    let header = std::mem::size_of::<vk::BaseInStructure<'_>>();
    // SAFETY: a valid struct of type `t`, `size_of_type(t)` bytes long.
    let bytes = unsafe { std::slice::from_raw_parts(p as *const u8, size_of_type(t)) };
    bytes[header..].to_vec()
}

fn rate_ext() -> impl Strategy<Value = Ext> {
    (any::<bool>(), any::<bool>(), any::<bool>()).prop_map(|(pipeline, primitive, attachment)| Ext::Rate { pipeline, primitive, attachment })
}

fn chain() -> impl Strategy<Value = Vec<Ext>> {
    (rate_ext(), any::<bool>()).prop_flat_map(|(rate, with_unknown)| {
        let mut all = vec![Ext::Features2, Ext::V11, Ext::V12, Ext::V13, Ext::Multiview, Ext::DynamicRendering, Ext::Sync2, Ext::Imageless, Ext::Timeline, rate];
        if with_unknown {
            all.extend([Ext::MeshShader, Ext::DeviceGroup]);
        }
        let n = all.len();
        proptest::sample::subsequence(all, 0..=n).prop_shuffle()
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn device_create_info_keeps_every_app_struct(exts in chain(), enable in (any::<bool>(), any::<bool>()), app_names in 0usize..3) {
        let mut c = Chain::default();
        for &e in &exts {
            push(&mut c, e);
        }
        let all_names = [c"VK_KHR_swapchain".as_ptr(), c"VK_KHR_multiview".as_ptr(), c"VK_KHR_maintenance2".as_ptr()];
        let ci = vk::DeviceCreateInfo { p_next: c.head, enabled_extension_count: app_names as u32, pp_enabled_extension_names: all_names.as_ptr(), ..Default::default() };
        let app = walk(ci.p_next);
        let app_contents: Vec<Vec<u8>> = app.iter().map(|&(t, p)| contents(t, p)).collect();
        let d = device_ext::Decision {
            add_extensions: vec![device_ext::FRAGMENT_SHADING_RATE],
            enable_fsr: Some(device_ext::FsrSupport { pipeline: enable.0, primitive: false, attachment: enable.1 }),
            reason: String::new(),
        };
        // SAFETY: a valid create info, alive while the rewrite is used.
        let m = unsafe { modify_device_create_info(&ci, &d) };

        let rate_at = exts.iter().position(|e| matches!(e, Ext::Rate { .. }));
        let unknown_before = rate_at.is_some_and(|r| exts[..r].iter().any(|e| matches!(e, Ext::MeshShader | Ext::DeviceGroup)));
        prop_assert_eq!(m.is_err(), unknown_before, "declines exactly when it cannot copy what precedes the app's struct: {:?}", exts);
        let Ok(m) = m else { return Ok(()) };

        let new = walk(m.ci.p_next);
        prop_assert!(!has_duplicates(m.ci.p_next), "{:?}", new.iter().map(|t| t.0).collect::<Vec<_>>());
        let (app_rate, rest) = match rate_at {
            // Ours first, then the app's chain itself.
            None => {
                prop_assert_eq!(new[0].0, S::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR);
                prop_assert_eq!(new.get(1).map(|t| t.1), app.first().map(|t| t.1), "the app's chain follows unchanged");
                ((false, false, false), &new[1..])
            }
            Some(r) => {
                let Ext::Rate { pipeline, primitive, attachment } = exts[r] else { unreachable!() };
                prop_assert_eq!(new.len(), app.len(), "no struct added or lost");
                // Copies up to and including the rate struct, the app's own after it.
                for (i, (n, a)) in new.iter().zip(&app).enumerate() {
                    prop_assert_eq!(n.0, a.0);
                    prop_assert_eq!(n.1 == a.1, i > r, "struct {} ({:?}): a copy up to the app's rate struct, the app's own after", i, n.0);
                }
                ((pipeline, primitive, attachment), &new[..])
            }
        };
        // Contents: every struct but the rate one as the app wrote it.
        for (n, (a, bytes)) in rest.iter().zip(app.iter().zip(&app_contents)) {
            prop_assert_eq!(n.0, a.0);
            if n.0 != S::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR {
                prop_assert_eq!(&contents(n.0, n.1), bytes, "{:?} changed", n.0);
            }
        }
        let ours = new.iter().find(|t| t.0 == S::PHYSICAL_DEVICE_FRAGMENT_SHADING_RATE_FEATURES_KHR).unwrap();
        // SAFETY: the rewrite's rate struct, alive with `m`.
        let f = unsafe { &*(ours.1 as *const vk::PhysicalDeviceFragmentShadingRateFeaturesKHR<'_>) };
        prop_assert_eq!(
            (f.pipeline_fragment_shading_rate, f.primitive_fragment_shading_rate, f.attachment_fragment_shading_rate),
            (u32::from(app_rate.0 || enable.0), u32::from(app_rate.1), u32::from(app_rate.2 || enable.1)),
            "the layer's features added to the app's choices"
        );
        // The app's create info and chain are untouched.
        prop_assert_eq!(walk(ci.p_next), app.clone());
        prop_assert_eq!(app.iter().map(|&(t, p)| contents(t, p)).collect::<Vec<_>>(), app_contents);
        prop_assert_eq!(ci.enabled_extension_count as usize, app_names);
        // SAFETY: the rewrite's names, alive with `m`.
        let names = unsafe { convert::names(m.ci.pp_enabled_extension_names, m.ci.enabled_extension_count) };
        let want: Vec<&str> = ["VK_KHR_swapchain", "VK_KHR_multiview", "VK_KHR_maintenance2"][..app_names].iter().copied().chain([device_ext::FRAGMENT_SHADING_RATE]).collect();
        prop_assert_eq!(names, want);
    }
}
