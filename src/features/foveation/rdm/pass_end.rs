//! Where radial density masking reconstructs an eye pass whose target a post-process chain reads
//! (reached by the data-flow walk, or taken by the size fallback): right after the pass ends, in
//! the app's own command buffer, before any later pass can read the checkerboard. Pure: which
//! image that is (the resolve target of a multisampled eye; behind a tonemap subpass that reads
//! the eye as an input attachment, that subpass's output), the layout the app left it in, and why
//! a pass cannot be reconstructed there. `pass_end_vk` records it.
#![forbid(unsafe_code)]

use super::rules::NotApplied;
use crate::track::cmd::PassInstance;
use crate::track::resources::ImageView;
use ash::vk;
use std::sync::Arc;

/// The single-sampled image the pass leaves the eye in, read by what follows.
#[derive(Clone, Debug, PartialEq)]
pub struct PassEndTarget {
    pub view: Arc<ImageView>,
    /// The layout the pass leaves it in (its final layout, or the rendering's layout).
    pub layout: vk::ImageLayout,
    /// The target's layer of an eye in layer `l` of the eye's image is `l + layer_offset` (their
    /// views' base layers differ: a resolve or output view of another layer).
    pub layer_offset: i64,
    /// The target is a later subpass's output, not the eye's image: the holes are filled after
    /// that subpass's per-pixel pass over them (a tonemap), in its colour space.
    pub after_subpass: bool,
}

/// What the rule needs to know of the app's objects.
pub trait Objects {
    /// A view the app created (resolve views of dynamic rendering are handles only).
    fn view(&self, view: u64) -> Option<Arc<ImageView>>;
    /// The sample count of an image.
    fn samples(&self, image: u64) -> Option<vk::SampleCountFlags>;
}

/// The target reconstructed when `pass` ends, for an eye pass whose colour attachment shows
/// `eye_image`; why none otherwise.
pub fn target(pass: &PassInstance, eye_image: u64, objects: &dyn Objects) -> Result<PassEndTarget, NotApplied> {
    let usable = |layout: vk::ImageLayout| !matches!(layout, vk::ImageLayout::UNDEFINED | vk::ImageLayout::PREINITIALIZED);
    let single = |image: u64| objects.samples(image).is_some_and(|s| s == vk::SampleCountFlags::TYPE_1);
    if let Some(r) = &pass.rendering {
        // A suspended rendering goes on in a later command buffer: its end is not the pass's.
        if r.suspending() {
            return Err(NotApplied::SubpassChain);
        }
        let c = r.color.iter().find(|c| c.attachment.image_view.as_ref().is_some_and(|v| v.image == eye_image)).ok_or(NotApplied::PostChain)?;
        let view = c.attachment.image_view.clone().ok_or(NotApplied::PostChain)?;
        let (view, layout) = if single(view.image) {
            (view, c.attachment.layout)
        } else if c.resolve_mode != vk::ResolveModeFlags::NONE && c.resolve_view != 0 {
            (objects.view(c.resolve_view).ok_or(NotApplied::MsaaUnresolved)?, c.resolve_layout)
        } else {
            return Err(NotApplied::MsaaUnresolved);
        };
        if !usable(layout) || !single(view.image) {
            return Err(NotApplied::TargetUsage);
        }
        let eye_base = c.attachment.image_view.as_ref().map_or(0, |v| v.range.base_array_layer);
        return Ok(PassEndTarget { layer_offset: view.range.base_array_layer as i64 - eye_base as i64, view, layout, after_subpass: false });
    }
    let rp = pass.render_pass.as_ref().ok_or(NotApplied::PostChain)?;
    let eye_sub = pass.subpass as usize;
    let sub = rp.subpasses.get(eye_sub).ok_or(NotApplied::PostChain)?;
    let shows = |i: u32| pass.attachments.get(i as usize).and_then(|a| a.image_view.as_ref()).is_some_and(|v| v.image == eye_image);
    let (k, index) = sub.color.iter().enumerate().find_map(|(k, r)| r.used().filter(|&i| shows(i)).map(|i| (k, i))).ok_or(NotApplied::PostChain)?;
    let desc = |i: u32| rp.attachments.get(i as usize);
    // The single-sampled attachment subpass `s`'s colour `k` (attachment `i`) leaves.
    let single_of = |s: &crate::track::resources::Subpass, k: usize, i: u32| -> Result<u32, NotApplied> {
        if desc(i).is_some_and(|a| a.samples == vk::SampleCountFlags::TYPE_1) {
            Ok(i)
        } else {
            s.resolve.get(k).and_then(|r| r.used()).ok_or(NotApplied::MsaaUnresolved)
        }
    };
    let (chosen, after_subpass) = if eye_sub + 1 == rp.subpasses.len() {
        (single_of(sub, k, index)?, false)
    } else {
        // A later subpass runs before the pass ends, so the checkerboard reaches it. The one
        // structure that still works: exactly one later subpass that reads the eye as an input
        // attachment (a tonemap, as Godot's mobile renderer records it). Input attachments are
        // read at the fragment's own pixel, so that subpass's output holds the eye at the same
        // pixels, its holes where the eye's were: it is reconstructed when the render pass ends.
        let last = rp.subpasses.len() - 1;
        let out = &rp.subpasses[last];
        let eye_single = single_of(sub, k, index).ok();
        let reads_eye = out.input.iter().filter_map(|r| r.used()).any(|i| i == index || Some(i) == eye_single);
        if eye_sub + 2 != rp.subpasses.len() || !reads_eye {
            return Err(NotApplied::SubpassChain);
        }
        let (k2, index2) = out.color.iter().enumerate().find_map(|(k, r)| r.used().map(|i| (k, i))).ok_or(NotApplied::SubpassChain)?;
        (single_of(out, k2, index2)?, true)
    };
    let view = pass.attachments.get(chosen as usize).and_then(|a| a.image_view.clone()).ok_or(NotApplied::PostChain)?;
    let layout = desc(chosen).map_or(vk::ImageLayout::UNDEFINED, |a| a.final_layout);
    if !usable(layout) || !single(view.image) {
        return Err(NotApplied::TargetUsage);
    }
    let eye_base = pass.attachments.get(index as usize).and_then(|a| a.image_view.as_ref()).map_or(0, |v| v.range.base_array_layer);
    Ok(PassEndTarget { layer_offset: view.range.base_array_layer as i64 - eye_base as i64, view, layout, after_subpass })
}

/// The image of the pass's first colour attachment: the target a pass planned at submission
/// reconstructs (engines' eye passes render one colour).
pub fn first_color_image(pass: &PassInstance) -> Option<u64> {
    let att = match (&pass.rendering, &pass.render_pass) {
        (Some(r), _) => r.color.first().map(|c| &c.attachment),
        (None, Some(rp)) => rp.subpasses.get(pass.subpass as usize).and_then(|s| s.color.first()).and_then(|r| r.used()).and_then(|i| pass.attachments.get(i as usize)),
        _ => None,
    };
    att.and_then(|a| a.image_view.as_ref()).map(|v| v.image)
}

/// The colour image whose eye pixels the reconstruction at the pass's end fills, for eyes found
/// through `eye_image`: itself when it is one of the pass's colour attachments; else (the eyes
/// were found through the pass's depth image: an engine that swaps its colour targets between
/// frames, as Bevy does without MSAA, has its depth traced before the colour it renders into this
/// frame) the pass's first colour attachment, which shows the same eyes at the same pixels.
pub fn reconstructed_image(pass: &PassInstance, eye_image: u64) -> Option<u64> {
    let colors: Vec<u64> = match (&pass.rendering, &pass.render_pass) {
        (Some(r), _) => r.color.iter().filter_map(|c| c.attachment.image_view.as_ref()).map(|v| v.image).collect(),
        (None, Some(rp)) => rp
            .subpasses
            .get(pass.subpass as usize)
            .into_iter()
            .flat_map(|s| s.color.iter().filter_map(|r| r.used()))
            .filter_map(|i| pass.attachments.get(i as usize)?.image_view.as_ref().map(|v| v.image))
            .collect(),
        _ => Vec::new(),
    };
    if colors.contains(&eye_image) {
        Some(eye_image)
    } else {
        first_color_image(pass)
    }
}

/// Whether an image of `usage` can be reconstructed in place: copied out (TRANSFER_SRC) and
/// drawn into (COLOR_ATTACHMENT).
pub fn usage_ok(usage: vk::ImageUsageFlags) -> bool {
    usage.contains(vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::COLOR_ATTACHMENT)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::cmd::{AttachmentUse, DynamicRendering, PassKind, Rect, RenderingAttachment};
    use crate::track::resources::{AttachmentDesc, AttachmentRef, RenderPass, RenderPassVersion, SubresourceRange, Subpass};
    use std::collections::HashMap;

    struct World {
        views: HashMap<u64, Arc<ImageView>>,
        samples: HashMap<u64, vk::SampleCountFlags>,
    }
    impl Objects for World {
        fn view(&self, view: u64) -> Option<Arc<ImageView>> {
            self.views.get(&view).cloned()
        }
        fn samples(&self, image: u64) -> Option<vk::SampleCountFlags> {
            self.samples.get(&image).copied()
        }
    }

    /// Views 1001 (image 1, MSAA), 1002 (image 2, single), 1003 (image 3, depth).
    fn world() -> World {
        let range = SubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
        let v = |h: u64| Arc::new(ImageView { handle: 1000 + h, image: h, view_type: vk::ImageViewType::TYPE_2D, format: vk::Format::R16G16B16A16_SFLOAT, range });
        World {
            views: [1, 2, 3].into_iter().map(|h| (1000 + h, v(h))).collect(),
            samples: [(1, vk::SampleCountFlags::TYPE_4), (2, vk::SampleCountFlags::TYPE_1), (3, vk::SampleCountFlags::TYPE_4)].into_iter().collect(),
        }
    }

    fn att(w: &World, view: u64, layout: vk::ImageLayout) -> AttachmentUse {
        AttachmentUse { view, image_view: w.view(view), swapchain: None, layout, load_op: vk::AttachmentLoadOp::CLEAR, store_op: vk::AttachmentStoreOp::STORE, clear: None }
    }

    fn render_pass(w: &World, msaa: bool, resolve: bool, subpasses: usize) -> PassInstance {
        let desc = |samples, final_layout| AttachmentDesc {
            format: vk::Format::R16G16B16A16_SFLOAT,
            samples,
            load_op: vk::AttachmentLoadOp::CLEAR,
            store_op: vk::AttachmentStoreOp::STORE,
            stencil_load_op: vk::AttachmentLoadOp::DONT_CARE,
            stencil_store_op: vk::AttachmentStoreOp::DONT_CARE,
            initial_layout: vk::ImageLayout::UNDEFINED,
            final_layout,
        };
        let r = |attachment| AttachmentRef { attachment, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL };
        let color_view = if msaa { 1001 } else { 1002 };
        let samples = if msaa { vk::SampleCountFlags::TYPE_4 } else { vk::SampleCountFlags::TYPE_1 };
        let sub = Subpass { color: vec![r(0)], resolve: if resolve { vec![r(2)] } else { vec![] }, depth_stencil: Some(r(1)), input: vec![], view_mask: 0 };
        let rp = RenderPass {
            handle: 9,
            version: RenderPassVersion::V1,
            attachments: vec![desc(samples, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL), desc(samples, vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL), desc(vk::SampleCountFlags::TYPE_1, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)],
            subpasses: vec![sub; subpasses],
            correlation_masks: vec![],
            layer_rate_attachment: None,
        };
        PassInstance {
            kind: PassKind::RenderPass,
            render_area: Rect { x: 0, y: 0, width: 8, height: 8 },
            subpass: 0,
            render_pass: Some(Arc::new(rp)),
            framebuffer: None,
            attachments: vec![att(w, color_view, vk::ImageLayout::UNDEFINED), att(w, 1003, vk::ImageLayout::UNDEFINED), att(w, 1002, vk::ImageLayout::UNDEFINED)],
            clear_values: vec![],
            rendering: None,
            flow_at: None,
        }
    }

    #[test]
    fn a_single_sampled_eye_is_its_own_target_in_its_final_layout() {
        let w = world();
        let t = target(&render_pass(&w, false, false, 1), 2, &w).unwrap();
        assert_eq!((t.view.image, t.layout), (2, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL));
    }

    #[test]
    fn a_multisampled_eye_is_reconstructed_in_its_resolve_target() {
        let w = world();
        let t = target(&render_pass(&w, true, true, 1), 1, &w).unwrap();
        assert_eq!((t.view.image, t.layout), (2, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL));
        assert_eq!(target(&render_pass(&w, true, false, 1), 1, &w), Err(NotApplied::MsaaUnresolved), "resolved later by a transfer: not here");
    }

    #[test]
    fn a_later_subpass_or_another_image_is_refused() {
        let w = world();
        // The later subpass does not read the eye.
        assert_eq!(target(&render_pass(&w, false, false, 2), 2, &w), Err(NotApplied::SubpassChain));
        assert_eq!(target(&render_pass(&w, false, false, 1), 7, &w), Err(NotApplied::PostChain));
    }

    /// The eye (attachment 0, or its resolve 2) read as an input attachment by the one subpass
    /// after it, which writes attachment 3 (image 4, layer 1 of its view): that output is the
    /// target, its layer one above the eye's.
    fn tonemap_subpass(w: &mut World, msaa: bool, subpasses: usize) -> PassInstance {
        let range = SubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 1, layer_count: 1 };
        w.views.insert(1004, Arc::new(ImageView { handle: 1004, image: 4, view_type: vk::ImageViewType::TYPE_2D, format: vk::Format::R8G8B8A8_SRGB, range }));
        w.samples.insert(4, vk::SampleCountFlags::TYPE_1);
        let mut pass = render_pass(w, msaa, msaa, 1);
        let mut rp = (**pass.render_pass.as_ref().unwrap()).clone();
        let mut out_desc = rp.attachments[2];
        out_desc.final_layout = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
        rp.attachments.push(out_desc);
        let r = |attachment| AttachmentRef { attachment, layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL };
        let read = if msaa { 2 } else { 0 };
        let tonemap = Subpass { color: vec![r(3)], resolve: vec![], depth_stencil: None, input: vec![r(read)], view_mask: 0 };
        for _ in 1..subpasses {
            rp.subpasses.push(tonemap.clone());
        }
        pass.render_pass = Some(Arc::new(rp));
        pass.attachments.push(att(w, 1004, vk::ImageLayout::UNDEFINED));
        pass
    }

    #[test]
    fn behind_a_tonemap_subpass_its_output_is_the_target() {
        let mut w = world();
        for msaa in [false, true] {
            let eye = if msaa { 1 } else { 2 };
            let t = target(&tonemap_subpass(&mut w, msaa, 2), eye, &w).unwrap();
            assert_eq!((t.view.image, t.layout, t.layer_offset, t.after_subpass), (4, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, 1, true), "msaa {msaa}");
        }
        // Two subpasses after the eye: refused.
        assert_eq!(target(&tonemap_subpass(&mut w, false, 3), 2, &w), Err(NotApplied::SubpassChain));
        // In the last subpass, the eye is its own target (offset 0).
        let t = target(&render_pass(&w, false, false, 1), 2, &w).unwrap();
        assert_eq!((t.layer_offset, t.after_subpass), (0, false));
    }

    #[test]
    fn dynamic_rendering_uses_the_resolve_view_and_refuses_suspending() {
        let w = world();
        let color = |view, resolve_view| RenderingAttachment { attachment: att(&w, view, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL), resolve_mode: if resolve_view != 0 { vk::ResolveModeFlags::AVERAGE } else { vk::ResolveModeFlags::NONE }, resolve_view, resolve_layout: vk::ImageLayout::GENERAL };
        let pass = |c: RenderingAttachment, flags| PassInstance {
            kind: PassKind::Dynamic,
            render_area: Rect { x: 0, y: 0, width: 8, height: 8 },
            subpass: 0,
            render_pass: None,
            framebuffer: None,
            attachments: vec![],
            clear_values: vec![],
            rendering: Some(DynamicRendering { flags, layer_count: 1, view_mask: 0, color: vec![c], depth: None, stencil: None }),
            flow_at: None,
        };
        let t = target(&pass(color(1001, 1002), vk::RenderingFlags::empty()), 1, &w).unwrap();
        assert_eq!((t.view.image, t.layout), (2, vk::ImageLayout::GENERAL));
        let t = target(&pass(color(1002, 0), vk::RenderingFlags::empty()), 2, &w).unwrap();
        assert_eq!((t.view.image, t.layout), (2, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL));
        assert_eq!(target(&pass(color(1001, 0), vk::RenderingFlags::empty()), 1, &w), Err(NotApplied::MsaaUnresolved));
        assert_eq!(target(&pass(color(1002, 0), vk::RenderingFlags::SUSPENDING), 2, &w), Err(NotApplied::SubpassChain));
    }

    #[test]
    fn usage_needs_copy_out_and_draw_in() {
        assert!(usage_ok(vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED));
        assert!(!usage_ok(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED));
    }
}
