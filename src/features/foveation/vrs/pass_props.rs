//! Property tests of the create infos VRS rewrites (issue 11: random but valid `pNext` chains):
//! render passes (v1 translated to v2, v2 copied) get the rate attachment, pipelines the
//! shading-rate state. For any chain the app may pass: the app's structs all stay in the
//! rewrite, in order and untouched (the rewrite links to them or to exact copies), the layer adds
//! only its own struct, no structure type appears twice in any chain (`VUID-…-sType-unique`,
//! what validation would report), and passes or pipelines that use shading rate or a density map
//! themselves are left alone. Validation itself needs a device with attachment shading rates
//! (the GPU machine); these are the structural checks it makes.

use super::*;
use crate::plugin::vk::test_chain::{has_duplicates, walk, Chain};
use proptest::prelude::*;
use vk::StructureType as S;

/// Structs an app may chain to a `VkSubpassDescription2`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum SubpassExt {
    DepthStencilResolve,
    RenderToSingleSampled,
    /// The app's own rate attachment: the pass is left alone.
    OwnRate,
}

/// Structs an app may chain to a `VkRenderPassCreateInfo2`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PassExt {
    CreationControl,
    CreationFeedback,
    /// A density map: the pass is left alone.
    DensityMap,
}

/// Structs an app may chain to a `VkGraphicsPipelineCreateInfo`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PipelineExt {
    Rendering,
    CreationFeedback,
    Robustness,
    /// The app's own shading-rate state: left alone.
    OwnRate,
    /// Pipeline libraries: left alone.
    LibraryPart,
    Libraries,
}

static RATE_REF: vk::AttachmentReference2<'static> = vk::AttachmentReference2 {
    s_type: S::ATTACHMENT_REFERENCE_2,
    p_next: std::ptr::null(),
    attachment: vk::ATTACHMENT_UNUSED,
    layout: vk::ImageLayout::UNDEFINED,
    aspect_mask: vk::ImageAspectFlags::empty(),
    _marker: std::marker::PhantomData,
};

fn subpass_chain(exts: &[SubpassExt]) -> Chain {
    let mut c = Chain::default();
    for e in exts {
        match e {
            SubpassExt::DepthStencilResolve => c.push(vk::SubpassDescriptionDepthStencilResolve::default().depth_resolve_mode(vk::ResolveModeFlags::SAMPLE_ZERO)),
            SubpassExt::RenderToSingleSampled => c.push(vk::MultisampledRenderToSingleSampledInfoEXT::default().rasterization_samples(vk::SampleCountFlags::TYPE_4)),
            SubpassExt::OwnRate => c.push(vk::FragmentShadingRateAttachmentInfoKHR { p_fragment_shading_rate_attachment: &RATE_REF, ..Default::default() }),
        }
    }
    c
}

fn pass_chain(exts: &[PassExt]) -> Chain {
    let mut c = Chain::default();
    for e in exts {
        match e {
            PassExt::CreationControl => c.push(vk::RenderPassCreationControlEXT::default().disallow_merging(true)),
            PassExt::CreationFeedback => c.push(vk::RenderPassCreationFeedbackCreateInfoEXT::default()),
            PassExt::DensityMap => c.push(vk::RenderPassFragmentDensityMapCreateInfoEXT::default()),
        }
    }
    c
}

fn pipeline_chain(exts: &[PipelineExt]) -> Chain {
    let mut c = Chain::default();
    for e in exts {
        match e {
            PipelineExt::Rendering => c.push(vk::PipelineRenderingCreateInfo::default().view_mask(0b11)),
            PipelineExt::CreationFeedback => c.push(vk::PipelineCreationFeedbackCreateInfo::default()),
            PipelineExt::Robustness => c.push(vk::PipelineRobustnessCreateInfoEXT::default()),
            PipelineExt::OwnRate => c.push(vk::PipelineFragmentShadingRateStateCreateInfoKHR::default()),
            PipelineExt::LibraryPart => c.push(vk::GraphicsPipelineLibraryCreateInfoEXT::default()),
            PipelineExt::Libraries => c.push(vk::PipelineLibraryCreateInfoKHR::default()),
        }
    }
    c
}

/// A subset of `all` in random order: a valid chain has each structure type at most once.
fn chain_of<T: Clone + std::fmt::Debug + 'static>(all: Vec<T>) -> impl Strategy<Value = Vec<T>> {
    let n = all.len();
    proptest::sample::subsequence(all, 0..=n).prop_shuffle()
}

fn types(p: *const c_void) -> Vec<vk::StructureType> {
    walk(p).into_iter().map(|(t, _)| t).collect()
}

fn texel() -> impl Strategy<Value = vk::Extent2D> {
    (0u32..3, 0u32..3).prop_map(|(w, h)| vk::Extent2D { width: 1 << (w + 2), height: 1 << (h + 2) })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// `vkCreateRenderPass2`: the rate attachment is appended and referenced from every graphics
    /// subpass by a struct put at the head of its chain; everything the app chained is kept.
    #[test]
    fn render_pass2_keeps_every_app_struct(
        subpasses in prop::collection::vec((any::<bool>(), chain_of(vec![SubpassExt::DepthStencilResolve, SubpassExt::RenderToSingleSampled, SubpassExt::OwnRate])), 1..4),
        top in chain_of(vec![PassExt::CreationControl, PassExt::CreationFeedback, PassExt::DensityMap]),
        attachments in 0usize..4,
        texel in texel(),
    ) {
        let sub_chains: Vec<Chain> = subpasses.iter().map(|(_, e)| subpass_chain(e)).collect();
        let top_chain = pass_chain(&top);
        let atts: Vec<vk::AttachmentDescription2<'_>> = (0..attachments)
            .map(|i| vk::AttachmentDescription2::default().format(vk::Format::R8G8B8A8_UNORM).samples(vk::SampleCountFlags::TYPE_1).load_op(if i % 2 == 0 { vk::AttachmentLoadOp::CLEAR } else { vk::AttachmentLoadOp::LOAD }))
            .collect();
        let subs: Vec<vk::SubpassDescription2<'_>> = subpasses
            .iter()
            .zip(&sub_chains)
            .map(|((graphics, _), c)| vk::SubpassDescription2 {
                p_next: c.head,
                pipeline_bind_point: if *graphics { vk::PipelineBindPoint::GRAPHICS } else { vk::PipelineBindPoint::COMPUTE },
                ..Default::default()
            })
            .collect();
        let ci = vk::RenderPassCreateInfo2 { p_next: top_chain.head, ..Default::default() }.attachments(&atts).subpasses(&subs);
        let app_sub_chains: Vec<Vec<vk::StructureType>> = subs.iter().map(|s| types(s.p_next)).collect();

        // SAFETY: a valid create info, alive while the copy is used.
        let owned = unsafe { owned_from_v2(&ci) };
        let expect_alone = top.contains(&PassExt::DensityMap) || subpasses.iter().any(|(_, e)| e.contains(&SubpassExt::OwnRate));
        // SAFETY: as above.
        prop_assert_eq!(unsafe { v2_leave_alone(&owned) }, expect_alone);
        if expect_alone {
            return Ok(());
        }
        let rp = with_rate(owned, texel);
        prop_assert_eq!(rp.info.p_next, ci.p_next, "the app's top chain is passed on as it is");
        prop_assert_eq!(rp.index as usize, attachments);
        prop_assert_eq!(rp.info.attachment_count as usize, attachments + 1);
        // SAFETY: the rewrite's arrays, alive with it.
        let (new_atts, new_subs) = unsafe { (crate::plugin::vk::convert::slice(rp.info.p_attachments, rp.info.attachment_count), crate::plugin::vk::convert::slice(rp.info.p_subpasses, rp.info.subpass_count)) };
        for (a, b) in atts.iter().zip(new_atts) {
            prop_assert_eq!((a.format, a.load_op, a.samples), (b.format, b.load_op, b.samples));
        }
        prop_assert_eq!(new_atts[attachments].format, vk::Format::R8_UINT);
        for (i, (s, app)) in new_subs.iter().zip(&subs).enumerate() {
            prop_assert!(!has_duplicates(s.p_next), "subpass {i}: {:?}", types(s.p_next));
            if app.pipeline_bind_point == vk::PipelineBindPoint::GRAPHICS {
                let chain = walk(s.p_next);
                prop_assert_eq!(chain[0].0, S::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR);
                // SAFETY: the layer's struct, alive with the rewrite.
                let f = unsafe { &*(chain[0].1 as *const vk::FragmentShadingRateAttachmentInfoKHR<'_>) };
                prop_assert_eq!(f.p_next, app.p_next, "the app's subpass chain follows, unchanged");
                // SAFETY: as above.
                let r = unsafe { &*f.p_fragment_shading_rate_attachment };
                prop_assert_eq!(r.attachment as usize, attachments);
                prop_assert_eq!(f.shading_rate_attachment_texel_size, texel);
            } else {
                prop_assert_eq!(s.p_next, app.p_next, "non-graphics subpasses are not touched");
            }
        }
        prop_assert!(!has_duplicates(rp.info.p_next));
        // The app's own structs are not modified.
        prop_assert_eq!(subs.iter().map(|s| types(s.p_next)).collect::<Vec<_>>(), app_sub_chains);
    }

    /// `vkCreateRenderPass`: translated to v2 only when its chain holds nothing but multiview and
    /// input aspects (which the translation carries over); the translation keeps every subpass's
    /// references and view mask.
    #[test]
    fn render_pass1_translation(
        subpasses in prop::collection::vec((0usize..3, any::<bool>(), any::<bool>()), 1..4),
        multiview in any::<bool>(),
        aspects in any::<bool>(),
        unknown in any::<bool>(),
        texel in texel(),
    ) {
        let atts = [
            vk::AttachmentDescription { format: vk::Format::R8G8B8A8_SRGB, samples: vk::SampleCountFlags::TYPE_1, ..Default::default() },
            vk::AttachmentDescription { format: vk::Format::D32_SFLOAT, samples: vk::SampleCountFlags::TYPE_1, ..Default::default() },
        ];
        let color = [vk::AttachmentReference { attachment: 0, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL }; 2];
        let depth = vk::AttachmentReference { attachment: 1, layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL };
        let input = [vk::AttachmentReference { attachment: 1, layout: vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL }];
        let subs: Vec<vk::SubpassDescription<'_>> = subpasses
            .iter()
            .map(|&(colors, with_depth, with_input)| {
                let mut s = vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color[..colors]);
                if with_depth {
                    s = s.depth_stencil_attachment(&depth);
                }
                if with_input {
                    s = s.input_attachments(&input);
                }
                s
            })
            .collect();
        let masks: Vec<u32> = (0..subs.len() as u32).map(|i| 0b11 >> (i % 2)).collect();
        let aspect_refs = [vk::InputAttachmentAspectReference { subpass: 0, input_attachment_index: 0, aspect_mask: vk::ImageAspectFlags::DEPTH }];
        let mut chain = Chain::default();
        if multiview {
            chain.push(vk::RenderPassMultiviewCreateInfo { subpass_count: masks.len() as u32, p_view_masks: masks.as_ptr(), ..Default::default() });
        }
        if aspects {
            chain.push(vk::RenderPassInputAttachmentAspectCreateInfo { aspect_reference_count: 1, p_aspect_references: aspect_refs.as_ptr(), ..Default::default() });
        }
        if unknown {
            chain.push(vk::RenderPassFragmentDensityMapCreateInfoEXT::default());
        }
        let ci = vk::RenderPassCreateInfo { p_next: chain.head, ..Default::default() }.attachments(&atts).subpasses(&subs);
        // SAFETY: a valid create info, alive while the translation is used.
        let owned = unsafe { owned_from_v1(&ci) };
        prop_assert_eq!(owned.is_none(), unknown, "a struct it cannot translate makes it decline");
        let Some(owned) = owned else { return Ok(()) };
        let rp = with_rate(owned, texel);
        prop_assert!(rp.info.p_next.is_null());
        // SAFETY: the rewrite's arrays, alive with it.
        let new_subs = unsafe { crate::plugin::vk::convert::slice(rp.info.p_subpasses, rp.info.subpass_count) };
        for (i, (s, app)) in new_subs.iter().zip(&subs).enumerate() {
            prop_assert_eq!(s.color_attachment_count, app.color_attachment_count);
            prop_assert_eq!(s.input_attachment_count, app.input_attachment_count);
            prop_assert_eq!(s.p_depth_stencil_attachment.is_null(), app.p_depth_stencil_attachment.is_null());
            prop_assert_eq!(s.view_mask, if multiview { masks[i] } else { 0 });
            prop_assert_eq!(types(s.p_next), vec![S::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR]);
            if app.input_attachment_count > 0 {
                // SAFETY: as above.
                let r = unsafe { &*s.p_input_attachments };
                // Without the aspect struct: all the depth format's aspects, which are DEPTH.
                prop_assert_eq!(r.aspect_mask, vk::ImageAspectFlags::DEPTH);
            }
        }
    }

    /// `vkCreateGraphicsPipelines`: each pipeline not using shading rate or libraries itself gets
    /// the state at the head of its chain, the app's chain after it as it was.
    #[test]
    fn pipelines_keep_every_app_struct(
        pipelines in prop::collection::vec((chain_of(vec![PipelineExt::Rendering, PipelineExt::CreationFeedback, PipelineExt::Robustness, PipelineExt::OwnRate, PipelineExt::LibraryPart, PipelineExt::Libraries]), any::<bool>(), any::<bool>(), any::<bool>()), 1..4),
    ) {
        let chains: Vec<Chain> = pipelines.iter().map(|(e, ..)| pipeline_chain(e)).collect();
        let dynamic_rate = [vk::DynamicState::VIEWPORT, vk::DynamicState::FRAGMENT_SHADING_RATE_KHR];
        let dynamic_plain = [vk::DynamicState::VIEWPORT];
        let (ds_rate, ds_plain) = (vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_rate), vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_plain));
        let infos: Vec<vk::GraphicsPipelineCreateInfo<'_>> = pipelines
            .iter()
            .zip(&chains)
            .map(|((_, render_pass, library, rate_dynamic), c)| vk::GraphicsPipelineCreateInfo {
                p_next: c.head,
                flags: if *library { vk::PipelineCreateFlags::LIBRARY_KHR } else { vk::PipelineCreateFlags::empty() },
                render_pass: if *render_pass { vk::RenderPass::from_raw(0x1234) } else { vk::RenderPass::null() },
                p_dynamic_state: if *rate_dynamic { &ds_rate } else { &ds_plain },
                subpass: 0,
                ..Default::default()
            })
            .collect();
        let before: Vec<Vec<vk::StructureType>> = infos.iter().map(|i| types(i.p_next)).collect();
        // SAFETY: valid create infos, alive while the copies are used.
        let out = unsafe { with_rate_state(&infos) };
        let mut changed = 0;
        for ((copy, app), (exts, _, library, rate_dynamic)) in out.infos.iter().zip(&infos).zip(&pipelines) {
            let alone = *library || *rate_dynamic || exts.iter().any(|e| matches!(e, PipelineExt::OwnRate | PipelineExt::LibraryPart | PipelineExt::Libraries));
            prop_assert!(!has_duplicates(copy.p_next), "{:?}", types(copy.p_next));
            prop_assert_eq!((copy.render_pass, copy.subpass, copy.layout, copy.stage_count), (app.render_pass, app.subpass, app.layout, app.stage_count));
            if alone {
                prop_assert_eq!(copy.p_next, app.p_next);
                prop_assert_eq!(copy.flags, app.flags);
                continue;
            }
            changed += 1;
            let chain = walk(copy.p_next);
            prop_assert_eq!(chain[0].0, S::PIPELINE_FRAGMENT_SHADING_RATE_STATE_CREATE_INFO_KHR);
            // SAFETY: the layer's struct, alive with `out`.
            let state = unsafe { &*(chain[0].1 as *const vk::PipelineFragmentShadingRateStateCreateInfoKHR<'_>) };
            prop_assert_eq!(state.p_next, app.p_next, "the app's chain follows, unchanged");
            prop_assert_eq!(state.fragment_size, vk::Extent2D { width: 1, height: 1 });
            let rendering_flag = copy.flags.contains(vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR);
            prop_assert_eq!(rendering_flag, app.render_pass == vk::RenderPass::null(), "the flag only for dynamic rendering");
            prop_assert_eq!(copy.flags & !vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR, app.flags);
        }
        prop_assert_eq!(out.changed, changed);
        prop_assert_eq!(infos.iter().map(|i| types(i.p_next)).collect::<Vec<_>>(), before, "the app's chains are not modified");
    }
}
