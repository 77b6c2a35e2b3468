//! Depth and colour kept past the pass for features that read them afterwards (the far field
//! copies the source eye's colour and depth when its pass ends): an app that never reads its depth
//! back usually stores it with `DONT_CARE`, and one that resolves a multisampled colour in the pass
//! (or reads it as a transient input attachment) discards the colour too, which leaves the contents
//! undefined after the pass. The chassis then creates render passes and begins renderings with
//! `STORE` for the depth aspect of the depth attachment, and for the colour attachments of every
//! subpass / rendering that has a depth attachment (the only ones that can be eye passes), instead
//! — a change the app cannot see (undefined contents become defined ones), made only while such a
//! feature is on. Stencil store ops and resolve targets are left as the app chose.

use ash::vk;

/// Whether any feature reads depth after the pass under the device's live settings.
pub(crate) fn wanted(d: &super::DeviceState) -> bool {
    let s = d.settings();
    d.features.all().iter().any(|f| f.keeps_depth(&s))
}

/// Makes the attachments the subpasses use as depth (`depth_refs`) store; `store_op` picks an
/// attachment description's store op. Whether anything changed.
fn store_depth<A>(attachments: &mut [A], depth_refs: impl IntoIterator<Item = u32>, store_op: impl Fn(&mut A) -> &mut vk::AttachmentStoreOp) -> bool {
    let mut changed = false;
    for r in depth_refs {
        if let Some(op) = attachments.get_mut(r as usize).map(&store_op) {
            changed |= *op != vk::AttachmentStoreOp::STORE;
            *op = vk::AttachmentStoreOp::STORE;
        }
    }
    changed
}

/// A `VkRenderPassCreateInfo` whose depth attachments store; `info` points into `_attachments`.
pub(crate) struct RenderPassV1 {
    _attachments: Vec<vk::AttachmentDescription>,
    pub info: vk::RenderPassCreateInfo<'static>,
}

/// The app's render pass with depth stored, or None when every depth attachment already stores.
///
/// # Safety
/// `ci` is the app's valid create info (valid for the duration of the app's call, which outlives
/// the returned copy's use).
pub(crate) unsafe fn render_pass(ci: *const vk::RenderPassCreateInfo<'_>) -> Option<Box<RenderPassV1>> {
    // SAFETY: per the contract, the arrays are valid with their counts.
    unsafe {
        let ci = &*ci;
        let subpasses = super::convert::slice(ci.p_subpasses, ci.subpass_count);
        let mut attachments = super::convert::slice(ci.p_attachments, ci.attachment_count).to_vec();
        let kept = subpasses.iter().filter_map(|s| s.p_depth_stencil_attachment.as_ref().map(|r| (s, r.attachment))).flat_map(|(s, depth)| {
            let colors = super::convert::slice(s.p_color_attachments, s.color_attachment_count).iter().map(|r| r.attachment);
            std::iter::once(depth).chain(colors).collect::<Vec<_>>()
        });
        if !store_depth(&mut attachments, kept.filter(|&i| i != vk::ATTACHMENT_UNUSED), |a| &mut a.store_op) {
            return None;
        }
        let mut out = Box::new(RenderPassV1 { _attachments: attachments, info: std::mem::transmute::<vk::RenderPassCreateInfo<'_>, vk::RenderPassCreateInfo<'static>>(*ci) });
        out.info.p_attachments = out._attachments.as_ptr();
        Some(out)
    }
}

/// A `VkRenderPassCreateInfo2` whose depth attachments store.
pub(crate) struct RenderPassV2 {
    _attachments: Vec<vk::AttachmentDescription2<'static>>,
    pub info: vk::RenderPassCreateInfo2<'static>,
}

/// # Safety
/// As for [`render_pass`].
pub(crate) unsafe fn render_pass2(ci: *const vk::RenderPassCreateInfo2<'_>) -> Option<Box<RenderPassV2>> {
    // SAFETY: per the contract, the arrays are valid with their counts; the copied attachment
    // descriptions keep their `pNext` chains, which live as long as the app's call.
    unsafe {
        let ci = &*ci;
        let subpasses = super::convert::slice(ci.p_subpasses, ci.subpass_count);
        let mut attachments: Vec<vk::AttachmentDescription2<'static>> =
            super::convert::slice(ci.p_attachments, ci.attachment_count).iter().map(|a| std::mem::transmute::<vk::AttachmentDescription2<'_>, vk::AttachmentDescription2<'static>>(*a)).collect();
        let kept = subpasses.iter().filter_map(|s| s.p_depth_stencil_attachment.as_ref().map(|r| (s, r.attachment))).flat_map(|(s, depth)| {
            let colors = super::convert::slice(s.p_color_attachments, s.color_attachment_count).iter().map(|r| r.attachment);
            std::iter::once(depth).chain(colors).collect::<Vec<_>>()
        });
        if !store_depth(&mut attachments, kept.filter(|&i| i != vk::ATTACHMENT_UNUSED), |a| &mut a.store_op) {
            return None;
        }
        let mut out = Box::new(RenderPassV2 { _attachments: attachments, info: std::mem::transmute::<vk::RenderPassCreateInfo2<'_>, vk::RenderPassCreateInfo2<'static>>(*ci) });
        out.info.p_attachments = out._attachments.as_ptr();
        Some(out)
    }
}

/// A `VkRenderingInfo` whose depth and colour attachments store.
pub(crate) struct Rendering {
    _depth: Box<vk::RenderingAttachmentInfo<'static>>,
    _colors: Vec<vk::RenderingAttachmentInfo<'static>>,
    pub info: vk::RenderingInfo<'static>,
}

/// # Safety
/// `info` is the app's valid rendering info (valid for the duration of its call).
pub(crate) unsafe fn rendering(info: *const vk::RenderingInfo<'_>) -> Option<Box<Rendering>> {
    // SAFETY: per the contract; the copy keeps the app's other pointers, valid during its call.
    unsafe {
        let info = &*info;
        let depth = info.p_depth_attachment.as_ref()?;
        if depth.image_view == vk::ImageView::null() {
            return None;
        }
        let colors = super::convert::slice(info.p_color_attachments, info.color_attachment_count);
        let discards = |a: &vk::RenderingAttachmentInfo<'_>| a.image_view != vk::ImageView::null() && a.store_op != vk::AttachmentStoreOp::STORE;
        if !discards(depth) && !colors.iter().any(discards) {
            return None;
        }
        let keep = |a: &vk::RenderingAttachmentInfo<'_>| {
            let mut k = std::mem::transmute::<vk::RenderingAttachmentInfo<'_>, vk::RenderingAttachmentInfo<'static>>(*a);
            if k.image_view != vk::ImageView::null() {
                k.store_op = vk::AttachmentStoreOp::STORE;
            }
            k
        };
        let mut out = Box::new(Rendering { info: std::mem::transmute::<vk::RenderingInfo<'_>, vk::RenderingInfo<'static>>(*info), _depth: Box::new(keep(depth)), _colors: colors.iter().map(keep).collect() });
        out.info.p_depth_attachment = &*out._depth;
        if !out._colors.is_empty() {
            out.info.p_color_attachments = out._colors.as_ptr();
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_depth_attachments_that_discard_change() {
        let att = |op| vk::AttachmentDescription { store_op: op, ..Default::default() };
        let mut a = vec![att(vk::AttachmentStoreOp::DONT_CARE), att(vk::AttachmentStoreOp::DONT_CARE), att(vk::AttachmentStoreOp::STORE)];
        // Attachment 1 is the depth of a subpass; 2 already stores; 7 is out of range (ignored).
        assert!(store_depth(&mut a, [1, 2, 7], |a| &mut a.store_op));
        assert_eq!(a.iter().map(|a| a.store_op).collect::<Vec<_>>(), [vk::AttachmentStoreOp::DONT_CARE, vk::AttachmentStoreOp::STORE, vk::AttachmentStoreOp::STORE]);
        assert!(!store_depth(&mut a, [1, 2], |a| &mut a.store_op), "nothing left to change");
        let mut none = vec![att(vk::AttachmentStoreOp::NONE)];
        assert!(store_depth(&mut none, [0], |a| &mut a.store_op));
        assert_eq!(none[0].store_op, vk::AttachmentStoreOp::STORE);
    }
}
