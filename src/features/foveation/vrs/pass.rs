//! What the app's objects need so that variable-rate shading's attachment can be chained into
//! their passes at all.
//!
//! - Pipelines: when the layer enabled `attachmentFragmentShadingRate` on the device, every
//!   graphics pipeline that does not use shading rate itself gets
//!   `VkPipelineFragmentShadingRateStateCreateInfoKHR { 1×1, [KEEP, REPLACE] }` (without it the
//!   attachment is ignored: the default combiner ops are KEEP, KEEP), and dynamic-rendering ones
//!   `VK_PIPELINE_CREATE_RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_BIT_KHR` (required of every
//!   pipeline bound in a rendering with a rate attachment). Both are inert in passes without one
//!   (the attachment rate is then 1×1), so foveation can be switched on live.
//! - Render pass objects: render pass compatibility compares subpass descriptions (and so a
//!   subpass's `VkFragmentShadingRateAttachmentInfoKHR`), so a variant pass with the attachment
//!   would need pipeline variants. Instead the app's own pass gets it: `vkCreateRenderPass(2)`
//!   goes down as `vkCreateRenderPass2` with one more attachment (R8_UINT, LOAD / DONT_CARE,
//!   `FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL` throughout; index = the app's attachment count,
//!   recorded as `RenderPass::layer_rate_attachment`; the tracked description stays the app's)
//!   referenced from every graphics subpass, so the app's pipelines are made against it.
//!   Passes with their own rate attachment or a density map are left alone. Each framebuffer of
//!   such a pass gets a layer rate image (`ceil(extent / texel)`, one layer per view when
//!   multiview and layered, else 1) appended — imageless: its image info at creation, its view
//!   at each begin — destroyed with the framebuffer. Limit: an imageless framebuffer's chain must
//!   start with its attachments struct (create and begin).

use super::rules as rule;
use super::vk::{image_objects, lock, MapKey, RateImage};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::ffi::c_void;

/// A framebuffer's rate image (destroyed with the framebuffer: the app must have waited for
/// every command buffer that used it).
#[derive(Clone, Debug)]
pub(super) struct FbRate {
    pub image: vk::Image,
    pub memory: vk::DeviceMemory,
    pub view: vk::ImageView,
    pub width: u32,
    pub height: u32,
    pub layers: u32,
    /// The rate attachment's index in the render pass (the app's attachment count).
    pub index: u32,
}

/// `vkCreateGraphicsPipelines`: copies of the create infos with the shading-rate state, kept
/// alive while the call goes down.
pub(super) struct PipelineInfos {
    pub infos: Vec<vk::GraphicsPipelineCreateInfo<'static>>,
    // Boxed: the copies point at them, so they must not move when the vector grows.
    #[allow(clippy::vec_box)]
    _states: Vec<Box<vk::PipelineFragmentShadingRateStateCreateInfoKHR<'static>>>,
    pub changed: usize,
}

/// Whether the app's pipeline uses shading rate itself, or is a library (left alone).
///
/// # Safety
/// `ci` must be a valid create info.
unsafe fn leave_alone(ci: &vk::GraphicsPipelineCreateInfo<'_>) -> bool {
    use vk::StructureType as S;
    let in_chain = |t: S| {
        // SAFETY: a valid chain (the caller's contract).
        unsafe { crate::plugin::vk::convert::find_in_chain::<vk::BaseInStructure<'_>>(ci.p_next, t) }.is_some()
    };
    if in_chain(S::PIPELINE_FRAGMENT_SHADING_RATE_STATE_CREATE_INFO_KHR)
        || in_chain(S::GRAPHICS_PIPELINE_LIBRARY_CREATE_INFO_EXT)
        || in_chain(S::PIPELINE_LIBRARY_CREATE_INFO_KHR)
        || ci.flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR)
    {
        return true;
    }
    // SAFETY: null or a valid dynamic state info with its array.
    let dynamic = unsafe { ci.p_dynamic_state.as_ref() }.map_or(&[][..], |ds| unsafe { crate::plugin::vk::convert::slice(ds.p_dynamic_states, ds.dynamic_state_count) });
    dynamic.contains(&vk::DynamicState::FRAGMENT_SHADING_RATE_KHR)
}

/// The app's pipeline create infos with the shading-rate state added where it applies; None when
/// the device has no layer-enabled attachment rates (the app's infos go down untouched).
///
/// # Safety
/// `infos` must be `count` valid create infos, alive while the result is used.
pub(super) unsafe fn pipeline_infos(d: &DeviceState, infos: *const vk::GraphicsPipelineCreateInfo<'_>, count: u32) -> Option<PipelineInfos> {
    if !super::vk::VrsDevice::of(d).enabled() {
        return None;
    }
    // SAFETY: the caller's contract.
    Some(unsafe { with_rate_state(crate::plugin::vk::convert::slice(infos, count)) })
}

/// Copies of `app` with the shading-rate state at the head of each chain (and the rendering flag
/// for dynamic-rendering pipelines) where `leave_alone` does not hold.
///
/// # Safety
/// `app` must be valid create infos, alive while the result is used.
unsafe fn with_rate_state(app: &[vk::GraphicsPipelineCreateInfo<'_>]) -> PipelineInfos {
    let mut out = PipelineInfos { infos: Vec::with_capacity(app.len()), _states: Vec::new(), changed: 0 };
    for ci in app {
        // SAFETY: lifetimes erased: the copies live only during the app's call.
        let mut copy: vk::GraphicsPipelineCreateInfo<'static> = unsafe { std::mem::transmute(*ci) };
        // SAFETY: a valid create info.
        if !unsafe { leave_alone(ci) } {
            let mut state = Box::new(vk::PipelineFragmentShadingRateStateCreateInfoKHR {
                fragment_size: vk::Extent2D { width: 1, height: 1 },
                combiner_ops: [vk::FragmentShadingRateCombinerOpKHR::KEEP, vk::FragmentShadingRateCombinerOpKHR::REPLACE],
                ..Default::default()
            });
            state.p_next = ci.p_next;
            copy.p_next = &*state as *const _ as *const c_void;
            if ci.render_pass == vk::RenderPass::null() {
                copy.flags |= vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR;
            }
            out._states.push(state);
            out.changed += 1;
        }
        out.infos.push(copy);
    }
    out
}

/// The parts of a `VkRenderPassCreateInfo2`, owned (the arrays the pointers lead to live here).
struct Owned2 {
    flags: vk::RenderPassCreateFlags,
    p_next: *const c_void,
    attachments: Vec<vk::AttachmentDescription2<'static>>,
    subpasses: Vec<vk::SubpassDescription2<'static>>,
    /// What the subpasses' pointers lead to (v1 translations).
    _refs: Vec<Vec<vk::AttachmentReference2<'static>>>,
    dependencies: Vec<vk::SubpassDependency2<'static>>,
    correlation: Vec<u32>,
}

/// `vkCreateRenderPass(2)` with the rate attachment: a `VkRenderPassCreateInfo2` whose arrays
/// live here while the call goes down.
pub(super) struct RatePass {
    pub info: vk::RenderPassCreateInfo2<'static>,
    /// The rate attachment's index (the app's attachment count).
    pub index: u32,
    _owned: Owned2,
    #[allow(clippy::vec_box)]
    _fsr: Vec<Box<vk::FragmentShadingRateAttachmentInfoKHR<'static>>>,
    _fsr_ref: Box<vk::AttachmentReference2<'static>>,
}

fn ptr_or_null<T>(v: &[T]) -> *const T {
    if v.is_empty() {
        std::ptr::null()
    } else {
        v.as_ptr()
    }
}


/// A `VkRenderPassCreateInfo` as the equivalent `VkRenderPassCreateInfo2` (multiview and input
/// aspects translated); None when its chain holds anything else.
///
/// # Safety
/// `ci` and everything it points to must be valid; the result is used while they are.
unsafe fn owned_from_v1(ci: &vk::RenderPassCreateInfo<'_>) -> Option<Owned2> {
    let mut multiview: Option<&vk::RenderPassMultiviewCreateInfo<'_>> = None;
    let mut aspects: &[vk::InputAttachmentAspectReference] = &[];
    let mut p = ci.p_next as *const vk::BaseInStructure<'_>;
    // SAFETY: a valid chain; each struct is read as the type its sType names.
    unsafe {
        while let Some(b) = p.as_ref() {
            match b.s_type {
                vk::StructureType::RENDER_PASS_MULTIVIEW_CREATE_INFO => multiview = Some(&*(p as *const vk::RenderPassMultiviewCreateInfo<'_>)),
                vk::StructureType::RENDER_PASS_INPUT_ATTACHMENT_ASPECT_CREATE_INFO => {
                    let a = &*(p as *const vk::RenderPassInputAttachmentAspectCreateInfo<'_>);
                    aspects = crate::plugin::vk::convert::slice(a.p_aspect_references, a.aspect_reference_count);
                }
                _ => return None,
            }
            p = b.p_next;
        }
    }
    // SAFETY: arrays valid with their counts (the caller's contract).
    let (atts, subs, deps) = unsafe {
        (
            crate::plugin::vk::convert::slice(ci.p_attachments, ci.attachment_count),
            crate::plugin::vk::convert::slice(ci.p_subpasses, ci.subpass_count),
            crate::plugin::vk::convert::slice(ci.p_dependencies, ci.dependency_count),
        )
    };
    // SAFETY: the multiview struct's arrays, valid with their counts.
    let (view_masks, view_offsets, correlation) = multiview.map_or((&[][..], &[][..], &[][..]), |m| unsafe {
        (
            crate::plugin::vk::convert::slice(m.p_view_masks, m.subpass_count),
            crate::plugin::vk::convert::slice(m.p_view_offsets, m.dependency_count),
            crate::plugin::vk::convert::slice(m.p_correlation_masks, m.correlation_mask_count),
        )
    });
    let attachments: Vec<vk::AttachmentDescription2<'static>> = atts
        .iter()
        .map(|a| vk::AttachmentDescription2 {
            flags: a.flags,
            format: a.format,
            samples: a.samples,
            load_op: a.load_op,
            store_op: a.store_op,
            stencil_load_op: a.stencil_load_op,
            stencil_store_op: a.stencil_store_op,
            initial_layout: a.initial_layout,
            final_layout: a.final_layout,
            ..Default::default()
        })
        .collect();
    let r2 = |r: &vk::AttachmentReference, aspect: vk::ImageAspectFlags| vk::AttachmentReference2 { attachment: r.attachment, layout: r.layout, aspect_mask: aspect, ..Default::default() };
    let mut refs = Vec::new();
    // Per subpass: indices into `refs` of (input, color, resolve, depth).
    let mut at = Vec::new();
    for (i, s) in subs.iter().enumerate() {
        // SAFETY: the subpass's arrays are valid with its counts; resolve has color_count entries.
        let (input, color, resolve, depth) = unsafe {
            (
                crate::plugin::vk::convert::slice(s.p_input_attachments, s.input_attachment_count),
                crate::plugin::vk::convert::slice(s.p_color_attachments, s.color_attachment_count),
                crate::plugin::vk::convert::slice(s.p_resolve_attachments, s.color_attachment_count),
                s.p_depth_stencil_attachment.as_ref(),
            )
        };
        let input: Vec<_> = input
            .iter()
            .enumerate()
            .map(|(j, r)| {
                let aspect = if r.attachment == vk::ATTACHMENT_UNUSED {
                    vk::ImageAspectFlags::empty()
                } else {
                    aspects
                        .iter()
                        .find(|a| a.subpass as usize == i && a.input_attachment_index as usize == j)
                        .map(|a| a.aspect_mask)
                        .unwrap_or_else(|| atts.get(r.attachment as usize).map_or(vk::ImageAspectFlags::COLOR, |a| crate::plugin::vk::convert::format_aspects(a.format)))
                };
                r2(r, aspect)
            })
            .collect();
        let none = vk::ImageAspectFlags::empty();
        at.push(refs.len());
        refs.push(input);
        refs.push(color.iter().map(|r| r2(r, none)).collect());
        refs.push(resolve.iter().map(|r| r2(r, none)).collect());
        refs.push(depth.iter().map(|r| r2(r, none)).collect());
    }
    let subpasses = subs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let k = at[i];
            vk::SubpassDescription2 {
                flags: s.flags,
                pipeline_bind_point: s.pipeline_bind_point,
                view_mask: view_masks.get(i).copied().unwrap_or(0),
                input_attachment_count: refs[k].len() as u32,
                p_input_attachments: ptr_or_null(&refs[k]),
                color_attachment_count: refs[k + 1].len() as u32,
                p_color_attachments: ptr_or_null(&refs[k + 1]),
                p_resolve_attachments: ptr_or_null(&refs[k + 2]),
                p_depth_stencil_attachment: ptr_or_null(&refs[k + 3]),
                preserve_attachment_count: s.preserve_attachment_count,
                p_preserve_attachments: s.p_preserve_attachments,
                ..Default::default()
            }
        })
        .collect();
    let dependencies = deps
        .iter()
        .enumerate()
        .map(|(i, d)| vk::SubpassDependency2 {
            src_subpass: d.src_subpass,
            dst_subpass: d.dst_subpass,
            src_stage_mask: d.src_stage_mask,
            dst_stage_mask: d.dst_stage_mask,
            src_access_mask: d.src_access_mask,
            dst_access_mask: d.dst_access_mask,
            dependency_flags: d.dependency_flags,
            view_offset: view_offsets.get(i).copied().unwrap_or(0),
            ..Default::default()
        })
        .collect();
    Some(Owned2 { flags: ci.flags, p_next: std::ptr::null(), attachments, subpasses, _refs: refs, dependencies, correlation: correlation.to_vec() })
}

/// A `VkRenderPassCreateInfo2`'s arrays, copied (its chains are kept as the app wrote them).
///
/// # Safety
/// `ci` and everything it points to must be valid; the result is used while they are.
unsafe fn owned_from_v2(ci: &vk::RenderPassCreateInfo2<'_>) -> Owned2 {
    // SAFETY: arrays valid with their counts; lifetimes erased: used only during the app's call.
    unsafe {
        Owned2 {
            flags: ci.flags,
            p_next: ci.p_next,
            attachments: crate::plugin::vk::convert::slice(ci.p_attachments, ci.attachment_count).iter().map(|a| std::mem::transmute_copy(a)).collect(),
            subpasses: crate::plugin::vk::convert::slice(ci.p_subpasses, ci.subpass_count).iter().map(|s| std::mem::transmute_copy(s)).collect(),
            _refs: Vec::new(),
            dependencies: crate::plugin::vk::convert::slice(ci.p_dependencies, ci.dependency_count).iter().map(|d| std::mem::transmute_copy(d)).collect(),
            correlation: crate::plugin::vk::convert::slice(ci.p_correlated_view_masks, ci.correlated_view_mask_count).to_vec(),
        }
    }
}

/// Whether the app's pass has its own rate attachment or a density map (left alone).
///
/// # Safety
/// As `owned_from_v2`.
unsafe fn v2_leave_alone(o: &Owned2) -> bool {
    use vk::StructureType as S;
    // SAFETY: valid chains.
    let in_chain = |p: *const c_void, t: S| unsafe { crate::plugin::vk::convert::find_in_chain::<vk::BaseInStructure<'_>>(p, t) }.is_some();
    in_chain(o.p_next, S::RENDER_PASS_FRAGMENT_DENSITY_MAP_CREATE_INFO_EXT) || o.subpasses.iter().any(|s| in_chain(s.p_next, S::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR))
}

/// Appends the rate attachment (index = the app's count) and references it from every graphics
/// subpass with the device's finest texel.
fn with_rate(mut o: Owned2, texel: vk::Extent2D) -> RatePass {
    let index = o.attachments.len() as u32;
    let layout = vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR;
    o.attachments.push(vk::AttachmentDescription2 {
        format: vk::Format::R8_UINT,
        samples: vk::SampleCountFlags::TYPE_1,
        load_op: vk::AttachmentLoadOp::LOAD,
        store_op: vk::AttachmentStoreOp::DONT_CARE,
        stencil_load_op: vk::AttachmentLoadOp::DONT_CARE,
        stencil_store_op: vk::AttachmentStoreOp::DONT_CARE,
        initial_layout: layout,
        final_layout: layout,
        ..Default::default()
    });
    let fsr_ref = Box::new(vk::AttachmentReference2 { attachment: index, layout, ..Default::default() });
    let mut fsr = Vec::new();
    for s in o.subpasses.iter_mut().filter(|s| s.pipeline_bind_point == vk::PipelineBindPoint::GRAPHICS) {
        let f = Box::new(vk::FragmentShadingRateAttachmentInfoKHR {
            p_next: s.p_next,
            p_fragment_shading_rate_attachment: &*fsr_ref,
            shading_rate_attachment_texel_size: texel,
            ..Default::default()
        });
        s.p_next = &*f as *const _ as *const c_void;
        fsr.push(f);
    }
    let info = vk::RenderPassCreateInfo2 {
        p_next: o.p_next,
        flags: o.flags,
        attachment_count: o.attachments.len() as u32,
        p_attachments: ptr_or_null(&o.attachments),
        subpass_count: o.subpasses.len() as u32,
        p_subpasses: ptr_or_null(&o.subpasses),
        dependency_count: o.dependencies.len() as u32,
        p_dependencies: ptr_or_null(&o.dependencies),
        correlated_view_mask_count: o.correlation.len() as u32,
        p_correlated_view_masks: ptr_or_null(&o.correlation),
        ..Default::default()
    };
    RatePass { info, index, _owned: o, _fsr: fsr, _fsr_ref: fsr_ref }
}

fn texel(d: &DeviceState) -> Option<vk::Extent2D> {
    super::vk::VrsDevice::of(d).rates.filter(|_| super::vk::VrsDevice::of(d).enabled()).map(|r| vk::Extent2D { width: r.texel_width, height: r.texel_height })
}

fn adds(d: &DeviceState, o: &Owned2, app_fsr_or_fdm: bool) -> bool {
    let graphics = o.subpasses.iter().filter(|s| s.pipeline_bind_point == vk::PipelineBindPoint::GRAPHICS).count();
    rule::adds_rate_attachment(super::vk::VrsDevice::of(d).enabled(), app_fsr_or_fdm, false, graphics)
}

/// `vkCreateRenderPass`: the app's pass as `vkCreateRenderPass2` info with the rate attachment;
/// None where the layer leaves it alone.
///
/// # Safety
/// `ci` must be the app's valid create info, alive while the result is used.
pub(super) unsafe fn render_pass_v1(d: &DeviceState, ci: *const vk::RenderPassCreateInfo<'_>) -> Option<RatePass> {
    let texel = texel(d)?;
    // SAFETY: the caller's contract.
    let o = unsafe { owned_from_v1(&*ci) }?;
    adds(d, &o, false).then(|| with_rate(o, texel))
}

/// `vkCreateRenderPass2`: as `render_pass_v1`.
///
/// # Safety
/// As `render_pass_v1`.
pub(super) unsafe fn render_pass_v2(d: &DeviceState, ci: *const vk::RenderPassCreateInfo2<'_>) -> Option<RatePass> {
    let texel = texel(d)?;
    // SAFETY: the caller's contract.
    let o = unsafe { owned_from_v2(&*ci) };
    // SAFETY: as above.
    let alone = unsafe { v2_leave_alone(&o) };
    adds(d, &o, alone).then(|| with_rate(o, texel))
}

/// `vkCreateFramebuffer` for a pass with the layer's rate attachment: the app's info with the
/// rate image's view (or, imageless, its image info) appended.
pub(super) struct RateFramebuffer {
    pub info: vk::FramebufferCreateInfo<'static>,
    _views: Vec<vk::ImageView>,
    _image_infos: Vec<vk::FramebufferAttachmentImageInfo<'static>>,
    _attachments: Option<Box<vk::FramebufferAttachmentsCreateInfo<'static>>>,
    _format: Box<vk::Format>,
}

/// The rate image objects made for a framebuffer being created (registered once it exists).
pub(super) struct PendingRate(FbRate);

/// Builds the rate image for a framebuffer of a pass with the layer's rate attachment; None for
/// other passes. Err: the framebuffer cannot be given its rate image.
///
/// # Safety
/// `ci` must be the app's valid create info, alive while the result is used.
pub(super) unsafe fn framebuffer_info(d: &DeviceState, ci: *const vk::FramebufferCreateInfo<'_>) -> Result<Option<(RateFramebuffer, PendingRate)>, String> {
    // SAFETY: the caller's contract.
    let app = unsafe { &*ci };
    let Some(rp) = d.track.render_passes.get(app.render_pass.as_raw()) else { return Ok(None) };
    let (Some(index), Some(rates)) = (rp.layer_rate_attachment, super::vk::VrsDevice::of(d).rates) else { return Ok(None) };
    let masks: Vec<u32> = rp.subpasses.iter().map(|s| s.view_mask).collect();
    let (width, height, layers) = rule::pass_rate_extent(app.width, app.height, &masks, rates);
    let imageless = app.flags.contains(vk::FramebufferCreateFlags::IMAGELESS);
    // SAFETY: lifetimes erased: the copy lives only during the app's call.
    let mut info: vk::FramebufferCreateInfo<'static> = unsafe { std::mem::transmute(*app) };
    let format = Box::new(vk::Format::R8_UINT);
    let mut out = RateFramebuffer { info, _views: Vec::new(), _image_infos: Vec::new(), _attachments: None, _format: format };
    let key = MapKey { width, height, layers, eyes: vec![], foveation_generation: 0, views_generation: 0 };
    // On any error below, `img` goes to the device's trash unused.
    let mut img = RateImage::empty(d);
    image_objects(d, &key, &mut img)?;
    if imageless {
        // SAFETY: a valid chain: the attachments info must come first (we replace it by a copy).
        let first = unsafe { (app.p_next as *const vk::BaseInStructure<'_>).as_ref() };
        if first.map(|b| b.s_type) != Some(vk::StructureType::FRAMEBUFFER_ATTACHMENTS_CREATE_INFO) {
            return Err("imageless framebuffer whose chain does not start with VkFramebufferAttachmentsCreateInfo".into());
        }
        // SAFETY: the sType names this struct; its array is valid with its count.
        let a = unsafe { &*(app.p_next as *const vk::FramebufferAttachmentsCreateInfo<'static>) };
        // SAFETY: as above; lifetimes erased (used only during the app's call).
        out._image_infos = unsafe { crate::plugin::vk::convert::slice(a.p_attachment_image_infos, a.attachment_image_info_count) }.iter().map(|i| unsafe { std::mem::transmute_copy(i) }).collect();
        out._image_infos.push(vk::FramebufferAttachmentImageInfo {
            usage: vk::ImageUsageFlags::FRAGMENT_SHADING_RATE_ATTACHMENT_KHR | vk::ImageUsageFlags::TRANSFER_DST,
            width,
            height,
            layer_count: layers,
            view_format_count: 1,
            p_view_formats: &*out._format,
            ..Default::default()
        });
        let mut copy = Box::new(*a);
        copy.attachment_image_info_count = out._image_infos.len() as u32;
        copy.p_attachment_image_infos = out._image_infos.as_ptr();
        info.p_next = &*copy as *const _ as *const c_void;
        info.attachment_count = out._image_infos.len() as u32;
        out._attachments = Some(copy);
    } else {
        // SAFETY: valid with its count.
        out._views = unsafe { crate::plugin::vk::convert::slice(app.p_attachments, app.attachment_count) }.to_vec();
        out._views.push(img.view);
        info.p_attachments = out._views.as_ptr();
        info.attachment_count = out._views.len() as u32;
    }
    out.info = info;
    let (image, memory, view) = img.take_image();
    let rate = FbRate { image, memory, view, width, height, layers, index };
    Ok(Some((out, PendingRate(rate))))
}

/// After `vkCreateFramebuffer`: keeps the rate image with the framebuffer, or destroys it when
/// the call failed.
pub(super) fn framebuffer_created(d: &DeviceState, fb: Option<vk::Framebuffer>, pending: PendingRate) {
    match fb {
        Some(fb) => {
            lock(&super::vk::VrsDevice::of(d).framebuffers).insert(fb.as_raw(), pending.0);
        }
        None => destroy_fb_rate(d, &pending.0),
    }
}

pub(super) fn destroy_fb_rate(d: &DeviceState, r: &FbRate) {
    // SAFETY: our objects; the framebuffer (and so every command buffer using them) is done.
    unsafe {
        d.fns.destroy_image_view(r.view, None);
        d.fns.destroy_image(r.image, None);
        d.fns.free_memory(r.memory, None);
    }
}

/// `vkDestroyFramebuffer` (after it went down).
pub(super) fn forget_framebuffer(d: &DeviceState, fb: u64) {
    let r = lock(&super::vk::VrsDevice::of(d).framebuffers).remove(&fb);
    if let Some(r) = r {
        destroy_fb_rate(d, &r);
    }
}

#[cfg(test)]
#[path = "pass_props.rs"]
mod props;

#[cfg(test)]
mod tests {
    use super::*;

    fn reference(attachment: u32, layout: vk::ImageLayout) -> vk::AttachmentReference {
        vk::AttachmentReference { attachment, layout }
    }

    /// Reads a v2 subpass's array (test helper over the rewrite's own pointers).
    fn refs(p: *const vk::AttachmentReference2<'_>, n: u32) -> Vec<(u32, vk::ImageLayout, vk::ImageAspectFlags)> {
        // SAFETY: the rewrite's arrays, alive with it.
        unsafe { crate::plugin::vk::convert::slice(p, n) }.iter().map(|r| (r.attachment, r.layout, r.aspect_mask)).collect()
    }

    #[test]
    fn v1_pass_is_translated_and_gets_the_rate_attachment_last() {
        use vk::ImageLayout as L;
        let atts = [
            vk::AttachmentDescription { format: vk::Format::R8G8B8A8_SRGB, samples: vk::SampleCountFlags::TYPE_1, load_op: vk::AttachmentLoadOp::CLEAR, ..Default::default() },
            vk::AttachmentDescription { format: vk::Format::D24_UNORM_S8_UINT, samples: vk::SampleCountFlags::TYPE_1, ..Default::default() },
        ];
        let color = [reference(0, L::COLOR_ATTACHMENT_OPTIMAL)];
        let depth = reference(1, L::DEPTH_STENCIL_ATTACHMENT_OPTIMAL);
        let input = [reference(1, L::DEPTH_STENCIL_READ_ONLY_OPTIMAL)];
        let subs = [
            vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color).depth_stencil_attachment(&depth),
            vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).input_attachments(&input).color_attachments(&color),
        ];
        let deps = [vk::SubpassDependency { src_subpass: 0, dst_subpass: 1, dependency_flags: vk::DependencyFlags::VIEW_LOCAL, ..Default::default() }];
        let masks = [0b11u32, 0b11];
        let offsets = [0i32];
        let corr = [0b11u32];
        let mut mv = vk::RenderPassMultiviewCreateInfo::default().view_masks(&masks).view_offsets(&offsets).correlation_masks(&corr);
        let ci = vk::RenderPassCreateInfo::default().attachments(&atts).subpasses(&subs).dependencies(&deps).push_next(&mut mv);
        // SAFETY: a valid create info built above.
        let o = unsafe { owned_from_v1(&ci) }.expect("multiview is translated");
        let rp = with_rate(o, vk::Extent2D { width: 16, height: 16 });
        assert_eq!(rp.index, 2, "appended after the app's attachments");
        let i = &rp.info;
        assert_eq!(i.attachment_count, 3);
        assert!(i.p_next.is_null(), "v1 chain translated, not forwarded");
        // SAFETY: the rewrite's arrays.
        let (a, s, dep, c) = unsafe {
            (
                crate::plugin::vk::convert::slice(i.p_attachments, i.attachment_count),
                crate::plugin::vk::convert::slice(i.p_subpasses, i.subpass_count),
                crate::plugin::vk::convert::slice(i.p_dependencies, i.dependency_count),
                crate::plugin::vk::convert::slice(i.p_correlated_view_masks, i.correlated_view_mask_count),
            )
        };
        assert_eq!(a[0].format, vk::Format::R8G8B8A8_SRGB);
        assert_eq!(a[0].load_op, vk::AttachmentLoadOp::CLEAR);
        assert_eq!((a[2].format, a[2].load_op, a[2].samples), (vk::Format::R8_UINT, vk::AttachmentLoadOp::LOAD, vk::SampleCountFlags::TYPE_1));
        assert_eq!((a[2].initial_layout, a[2].final_layout), (L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR, L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR));
        assert_eq!((s[0].view_mask, s[1].view_mask), (0b11, 0b11));
        assert_eq!(refs(s[0].p_color_attachments, s[0].color_attachment_count)[0].0, 0);
        assert!(s[0].p_resolve_attachments.is_null());
        // SAFETY: as above.
        assert_eq!(unsafe { (*s[0].p_depth_stencil_attachment).attachment }, 1);
        assert!(s[1].p_depth_stencil_attachment.is_null());
        // A v1 input attachment reads all of its format's aspects.
        assert_eq!(refs(s[1].p_input_attachments, 1)[0].2, vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL);
        assert_eq!((dep[0].view_offset, dep[0].dependency_flags), (0, vk::DependencyFlags::VIEW_LOCAL));
        assert_eq!(c, &[0b11]);
        for sub in s {
            // SAFETY: the chain the rewrite built.
            let f = unsafe { crate::plugin::vk::convert::find_in_chain::<vk::FragmentShadingRateAttachmentInfoKHR<'_>>(sub.p_next, vk::StructureType::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR) }.expect("every graphics subpass");
            // SAFETY: as above.
            let f = unsafe { &*f };
            assert_eq!(f.shading_rate_attachment_texel_size, vk::Extent2D { width: 16, height: 16 });
            // SAFETY: as above.
            let r = unsafe { &*f.p_fragment_shading_rate_attachment };
            assert_eq!((r.attachment, r.layout), (2, L::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR));
        }
    }

    #[test]
    fn v1_chains_with_unknown_structs_are_left_alone() {
        let mut fdm = vk::RenderPassFragmentDensityMapCreateInfoEXT::default();
        let ci = vk::RenderPassCreateInfo::default().push_next(&mut fdm);
        // SAFETY: a valid create info built above.
        assert!(unsafe { owned_from_v1(&ci) }.is_none());
    }

    #[test]
    fn v2_pass_keeps_its_chains_and_own_rate_attachments_are_left_alone() {
        let atts = [vk::AttachmentDescription2::default().format(vk::Format::B8G8R8A8_SRGB).samples(vk::SampleCountFlags::TYPE_4)];
        let color = [vk::AttachmentReference2::default().attachment(0).layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let mut dsr = vk::SubpassDescriptionDepthStencilResolve::default();
        let subs = [
            vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color).push_next(&mut dsr),
            vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::COMPUTE),
        ];
        let ci = vk::RenderPassCreateInfo2::default().attachments(&atts).subpasses(&subs);
        // SAFETY: a valid create info built above.
        let o = unsafe { owned_from_v2(&ci) };
        // SAFETY: as above.
        assert!(!unsafe { v2_leave_alone(&o) });
        let rp = with_rate(o, vk::Extent2D { width: 8, height: 8 });
        assert_eq!(rp.index, 1);
        // SAFETY: the rewrite's arrays.
        let s = unsafe { crate::plugin::vk::convert::slice(rp.info.p_subpasses, rp.info.subpass_count) };
        // SAFETY: the chain the rewrite built: ours first, then the app's.
        let first = unsafe { &*(s[0].p_next as *const vk::BaseInStructure<'_>) };
        assert_eq!(first.s_type, vk::StructureType::FRAGMENT_SHADING_RATE_ATTACHMENT_INFO_KHR);
        // SAFETY: as above.
        assert_eq!(unsafe { (*first.p_next).s_type }, vk::StructureType::SUBPASS_DESCRIPTION_DEPTH_STENCIL_RESOLVE);
        assert!(s[1].p_next.is_null(), "compute subpasses get none");

        let fsr_ref = vk::AttachmentReference2::default().attachment(0).layout(vk::ImageLayout::FRAGMENT_SHADING_RATE_ATTACHMENT_OPTIMAL_KHR);
        let mut own = vk::FragmentShadingRateAttachmentInfoKHR::default().fragment_shading_rate_attachment(&fsr_ref);
        let subs = [vk::SubpassDescription2::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).push_next(&mut own)];
        let ci = vk::RenderPassCreateInfo2::default().attachments(&atts).subpasses(&subs);
        // SAFETY: as above.
        assert!(unsafe { v2_leave_alone(&owned_from_v2(&ci)) });
    }

    #[test]
    fn input_aspects_by_format() {
        use crate::plugin::vk::convert::format_aspects;
        assert_eq!(format_aspects(vk::Format::D32_SFLOAT), vk::ImageAspectFlags::DEPTH);
        assert_eq!(format_aspects(vk::Format::S8_UINT), vk::ImageAspectFlags::STENCIL);
        assert_eq!(format_aspects(vk::Format::R16G16B16A16_SFLOAT), vk::ImageAspectFlags::COLOR);
    }
}
