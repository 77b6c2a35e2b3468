//! Which render pass instances are eye passes, and where each eye sits in them: the decision the
//! hidden-area mask depends on, kept pure so every shape (per-eye, side-by-side, multiview,
//! intermediate targets copied into swapchain images) is unit-tested without a GPU. The FFI shell
//! feeds it the tracked pass and draws what it plans; nothing here touches Vulkan.
#![forbid(unsafe_code)]

use super::cmd::{AttachmentUse, PassInstance};
use super::resources::RenderPass;
use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::core::views::{EyeUse, ImageRect};
use ash::vk;

/// One eye as an image holds it: which view, in which array layer, in which rect (image pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EyeSource {
    pub view: u32,
    pub layer: u32,
    pub rect: PixelRect,
}

impl EyeSource {
    pub fn from_use(u: &EyeUse) -> EyeSource {
        EyeSource { view: u.view, layer: u.image_array_index, rect: rect(u.image_rect) }
    }
}

/// Eyes as the log shows them: `view 0 layer 0 256x256+0+0, view 1 …`.
pub fn describe(eyes: &[EyeSource]) -> String {
    eyes.iter().map(|e| format!("view {} layer {} {}x{}+{}+{}", e.view, e.layer, e.rect.width, e.rect.height, e.rect.x, e.rect.y)).collect::<Vec<_>>().join(", ")
}

pub fn rect(r: ImageRect) -> PixelRect {
    PixelRect { x: r.x, y: r.y, width: r.width.max(0) as u32, height: r.height.max(0) as u32 }
}

/// What is known about the eyes an attachment's image shows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Eyes {
    /// A swapchain image; empty until the OpenXR half saw it submitted.
    Swapchain(Vec<EyeSource>),
    /// An image the app copies / resolves / blits into a swapchain image, 1:1.
    Intermediate(Vec<EyeSource>),
    /// An eye pass's target the data-flow walk reached from a swapchain image through
    /// post-processing (draws, compute, scaled blits): what the runtime gets is derived from it.
    Traced(Vec<EyeSource>),
    /// Taken as an eye target by size and order (`eyes.fallback = size`).
    Fallback(Vec<EyeSource>),
    /// Traced, but its eye rect changed at the last walk (dynamic resolution).
    Changing,
    /// Traced as one target both eyes take turns in: which eye this pass shows is asked per use,
    /// at its submission (`Traced::use_eyes`), and was not known here.
    PerUse,
    /// Only post-process passes (draws that never test depth) were seen writing it.
    Post,
    /// Unknown, while the data-flow walk has traced the frame's eyes elsewhere: not an eye
    /// target (a bloom mip, a shadow or reflection target).
    NotEye,
    /// Unknown because the walk has not traced a frame yet: the submission of this very
    /// recording may tell (`awaiting_eyes`).
    Untraced,
    /// Neither (yet).
    Unknown,
}

/// How the eyes are laid out in the pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EyeLayout {
    PerEye,
    SideBySide,
    Multiview,
}

impl EyeLayout {
    pub fn name(&self) -> &'static str {
        match self {
            EyeLayout::PerEye => "per-eye",
            EyeLayout::SideBySide => "side-by-side",
            EyeLayout::Multiview => "multiview",
        }
    }
}

/// One mask draw: a view's mask mapped into `viewport` (the eye's rect), clipped to `scissor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EyeDraw {
    pub view: u32,
    /// The array layer of the target image that shows the view.
    pub layer: u32,
    pub viewport: PixelRect,
    pub scissor: PixelRect,
}

/// What to draw into an eye pass.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskPlan {
    /// The depth that fails the app's test: 0 after a clear to 1 (LESS), 1 after a clear to 0
    /// (reversed Z).
    pub fail_depth: f32,
    pub layout: EyeLayout,
    pub intermediate: bool,
    /// How the target was tied to the eyes: by the data-flow walk or the size fallback, a
    /// post-process chain may read it before the runtime does (nothing may leave holes in it).
    pub via: Via,
    /// The image whose eyes were found (for the log).
    pub image: u64,
    /// Multiview: the pass's view mask (one draw; view `i` of the mask is gl_ViewIndex `i`).
    pub view_mask: u32,
    /// Multiview: one per view, all with the same viewport.
    pub draws: Vec<EyeDraw>,
}

/// Inputs beyond the pass itself.
pub struct Facts<'a> {
    /// `VK_SUBPASS_CONTENTS_SECONDARY_COMMAND_BUFFERS` / `VK_RENDERING_CONTENTS_SECONDARY_…`.
    pub secondary_contents: bool,
    /// `mask.intermediate = auto`.
    pub intermediate_enabled: bool,
    /// The eyes an attachment's image shows.
    pub eyes: &'a dyn Fn(&AttachmentUse) -> Eyes,
    /// The depth value an explicit clear just wrote (vkCmdClearAttachments inside the pass, or
    /// vkCmdClearDepthStencilImage before a pass that loads it): replaces the load-op check.
    pub explicit_clear: Option<f32>,
}

/// The depth attachment of the pass's current subpass / rendering, and whether this is where its
/// contents start (cleared by the load op: first subpass using it, or a non-resuming rendering).
pub fn depth_attachment(pass: &PassInstance) -> Option<(&AttachmentUse, bool, vk::ImageLayout)> {
    if let Some(r) = &pass.rendering {
        let d = r.depth.as_ref().filter(|d| d.attachment.view != 0)?;
        let starts = d.attachment.load_op == vk::AttachmentLoadOp::CLEAR && !r.resuming();
        return Some((&d.attachment, starts, d.attachment.layout));
    }
    let rp = pass.render_pass.as_ref()?;
    let sub = rp.subpasses.get(pass.subpass as usize)?;
    let dref = sub.depth_stencil?;
    let index = dref.used()?;
    let att = pass.attachments.get(index as usize)?;
    let desc = rp.attachments.get(index as usize)?;
    let starts = first_use(rp, pass.subpass, index) && desc.load_op == vk::AttachmentLoadOp::CLEAR;
    Some((att, starts, dref.layout))
}

/// Attachments of the current subpass / rendering that could show eyes: colour first, then depth.
fn eye_candidates(pass: &PassInstance) -> Vec<&AttachmentUse> {
    if let Some(r) = &pass.rendering {
        return r.color.iter().chain(&r.depth).map(|a| &a.attachment).filter(|a| a.view != 0).collect();
    }
    let Some(sub) = pass.render_pass.as_ref().and_then(|rp| rp.subpasses.get(pass.subpass as usize)) else {
        return Vec::new();
    };
    sub.color
        .iter()
        .chain(sub.depth_stencil.iter())
        .filter_map(|r| r.used())
        .filter_map(|i| pass.attachments.get(i as usize))
        .collect()
}

fn read_only(layout: vk::ImageLayout) -> bool {
    matches!(
        layout,
        vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL
            | vk::ImageLayout::DEPTH_READ_ONLY_OPTIMAL
            | vk::ImageLayout::DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL
            | vk::ImageLayout::READ_ONLY_OPTIMAL
            | vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL
    )
}

/// The depth a cleared value makes fail: 1 → 0 (LESS / LESS_OR_EQUAL apps), 0 → 1 (reversed Z).
pub fn fail_depth(clear: f32) -> Option<f32> {
    if clear == 1.0 {
        Some(0.0)
    } else if clear == 0.0 {
        Some(1.0)
    } else {
        None
    }
}

/// Whether `subpass` is the first subpass of `rp` to use attachment `index`: where its load op
/// decides its contents.
pub fn first_use(rp: &RenderPass, subpass: u32, index: u32) -> bool {
    !rp.subpasses[..(subpass as usize).min(rp.subpasses.len())]
        .iter()
        .any(|s| s.color.iter().chain(&s.resolve).chain(&s.input).chain(s.depth_stencil.iter()).any(|r| r.used() == Some(index)))
}

/// Whether the depth attachment of the pass's current subpass / rendering starts from the image's
/// earlier contents: load op LOAD where its contents start in this pass (its first subpass, a
/// rendering that does not resume). Only then does a `vkCmdClearDepthStencilImage` recorded before
/// the pass decide its depth; a load op CLEAR overwrites that clear.
pub fn depth_loads(pass: &PassInstance) -> bool {
    if let Some(r) = &pass.rendering {
        return !r.resuming() && r.depth.as_ref().is_some_and(|d| d.attachment.view != 0 && d.attachment.load_op == vk::AttachmentLoadOp::LOAD);
    }
    let Some(rp) = pass.render_pass.as_ref() else { return false };
    let Some(index) = rp.subpasses.get(pass.subpass as usize).and_then(|s| s.depth_stencil).and_then(|r| r.used()) else {
        return false;
    };
    first_use(rp, pass.subpass, index) && rp.attachments.get(index as usize).is_some_and(|a| a.load_op == vk::AttachmentLoadOp::LOAD)
}

/// The attachment of the open pass that shows eyes, which eyes its image holds, and whether it
/// is an intermediate target: the eye-pass test shared by the mask, radial density masking and
/// variable-rate shading (which needs no depth).
pub fn find_eyes<'p>(pass: &'p PassInstance, facts: &Facts<'_>) -> Result<(&'p AttachmentUse, Vec<EyeSource>, Via), NotMasked> {
    let mut found: Option<(&AttachmentUse, Vec<EyeSource>, Via)> = None;
    let mut unknown_swapchain = false;
    let mut has_color = false;
    let mut post = false;
    let mut changing = false;
    let mut per_use = false;
    for att in eye_candidates(pass) {
        let is_depth = att.image_view.as_ref().is_some_and(|v| {
            v.range.aspect_mask.intersects(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL)
        });
        let eyes = (facts.eyes)(att);
        has_color |= !is_depth && eyes != Eyes::NotEye;
        match eyes {
            Eyes::Swapchain(s) if s.is_empty() => unknown_swapchain = true,
            Eyes::Swapchain(s) => {
                found = Some((att, s, Via::Swapchain));
                break;
            }
            Eyes::Intermediate(s) if !s.is_empty() && found.is_none() => found = Some((att, s, Via::Transfer)),
            Eyes::Traced(s) if !s.is_empty() && found.is_none() => found = Some((att, s, Via::Walk)),
            Eyes::Fallback(s) if !s.is_empty() && found.is_none() => found = Some((att, s, Via::Fallback)),
            Eyes::Post => post = true,
            Eyes::Changing => changing = true,
            Eyes::PerUse => per_use = true,
            _ => {}
        }
    }
    let Some((att, sources, via)) = found else {
        return Err(if changing {
            NotMasked::RectChanging
        } else if per_use {
            NotMasked::SharedTarget
        } else if post {
            NotMasked::PostPass
        } else if unknown_swapchain || has_color {
            NotMasked::EyeUnknown
        } else {
            NotMasked::NotEyePass
        });
    };
    if via != Via::Swapchain && !facts.intermediate_enabled {
        return Err(NotMasked::IntermediateOff);
    }
    Ok((att, sources, via))
}

/// How an eye pass's target was tied to the eyes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Via {
    /// It is a swapchain image.
    Swapchain,
    /// It is transferred 1:1 into one.
    Transfer,
    /// The data-flow walk reached it through post-processing.
    Walk,
    /// The size fallback took it (`eyes.fallback = size`).
    Fallback,
}

impl Via {
    /// The name in logs and `stats.file` (`mask.by_source`).
    pub fn name(self) -> &'static str {
        match self {
            Via::Swapchain => "swapchain",
            Via::Transfer => "transfer",
            Via::Walk => "walk",
            Via::Fallback => "fallback",
        }
    }
    /// A post chain may read the target before the runtime does.
    pub fn behind_post(self) -> bool {
        matches!(self, Via::Walk | Via::Fallback)
    }
}

/// The fail depth of a pass whose depth starts cleared to 0 or 1 here, else why not.
fn cleared_depth(pass: &PassInstance, facts: &Facts<'_>) -> Result<f32, NotMasked> {
    let Some((depth, starts, layout)) = depth_attachment(pass) else {
        return Err(NotMasked::NoDepthAttachment);
    };
    if let Some(v) = &depth.image_view {
        if !v.range.aspect_mask.is_empty() && !v.range.aspect_mask.contains(vk::ImageAspectFlags::DEPTH) {
            return Err(NotMasked::NoDepthAttachment);
        }
    }
    if read_only(layout) {
        return Err(NotMasked::Unsupported);
    }
    let clear = match facts.explicit_clear {
        Some(c) => c,
        None if starts => match depth.clear {
            Some(c) => c.depth(),
            None => return Err(NotMasked::DepthNotCleared),
        },
        None => return Err(NotMasked::DepthNotCleared),
    };
    fail_depth(clear).ok_or(NotMasked::DepthClearNot01)
}

/// A pass that renders into a swapchain image whose eye uses the OpenXR half has not seen yet
/// (they are learned at the first `xrEndFrame`), with its depth freshly cleared: it may become an
/// eye pass by the time the command buffer is submitted. Some(fail depth) for such a pass.
pub fn awaiting_eyes(pass: &PassInstance, facts: &Facts<'_>) -> Option<f32> {
    if facts.secondary_contents || find_eyes(pass, facts) != Err(NotMasked::EyeUnknown) {
        return None;
    }
    let swapchain_unknown = eye_candidates(pass).iter().any(|a| matches!((facts.eyes)(a), Eyes::Swapchain(s) if s.is_empty()));
    if !swapchain_unknown {
        return None;
    }
    cleared_depth(pass, facts).ok()
}

/// Whether a pass the walk may still tie to its eyes at submission — one recorded before any
/// walk (`Untraced`), or into a target whose eye rect changes from frame to frame (`Changing`) —
/// has a freshly cleared depth; its fail depth then. Features record draws for it that are filled
/// at each submission, from what that submission's walk found (`plugin::vk::inject::plan_now`).
pub fn awaiting_walk(pass: &PassInstance, facts: &Facts<'_>) -> Option<f32> {
    if facts.secondary_contents || !facts.intermediate_enabled {
        return None;
    }
    match find_eyes(pass, facts) {
        Err(NotMasked::EyeUnknown | NotMasked::RectChanging | NotMasked::SharedTarget) => {}
        _ => return None,
    }
    // A colour target only the walk can tie to an eye (a depth image says nothing alone); a
    // swapchain image's pass awaits the OpenXR half instead (`awaiting_eyes`).
    let mut walkable = false;
    for a in eye_candidates(pass) {
        let depth = a.image_view.as_ref().is_some_and(|v| v.range.aspect_mask.intersects(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL));
        match (facts.eyes)(a) {
            Eyes::Swapchain(_) => return None,
            Eyes::Untraced | Eyes::Changing | Eyes::PerUse if !depth => walkable = true,
            _ => {}
        }
    }
    if !walkable {
        return None;
    }
    cleared_depth(pass, facts).ok()
}

/// Decides whether the open pass gets a mask, and where.
pub fn classify(pass: &PassInstance, facts: &Facts<'_>) -> Result<MaskPlan, NotMasked> {
    // Eyes first: a pass that shows no eye is not an eye pass, whatever its depth does.
    let (att, sources, via) = find_eyes(pass, facts)?;
    let intermediate = via != Via::Swapchain;
    if facts.secondary_contents {
        return Err(NotMasked::Secondary);
    }
    let fail_depth = cleared_depth(pass, facts)?;

    let base_layer = att.image_view.as_ref().map_or(0, |v| v.range.base_array_layer);
    let area = PixelRect { x: pass.render_area.x, y: pass.render_area.y, width: pass.render_area.width, height: pass.render_area.height };
    let draw = |s: &EyeSource| EyeDraw { view: s.view, layer: s.layer, viewport: s.rect, scissor: s.rect.intersect(&area) };
    let view_mask = pass.view_mask();
    let mut sources = sources;
    sources.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
    sources.dedup();
    let plan = |layout, view_mask, draws: Vec<EyeDraw>| MaskPlan { fail_depth, layout, intermediate, via, image: att.image_view.as_ref().map_or(0, |v| v.image), view_mask, draws };
    if view_mask != 0 {
        let mut draws = Vec::new();
        for i in (0..32).filter(|i| view_mask & (1 << i) != 0) {
            let Some(s) = sources.iter().find(|s| s.layer == base_layer + i) else {
                return Err(NotMasked::EyeUnknown);
            };
            // The vertex shader keeps a triangle when its view equals gl_ViewIndex.
            if s.view != i {
                return Err(NotMasked::Unsupported);
            }
            draws.push(draw(s));
        }
        if draws.iter().any(|d| d.viewport != draws[0].viewport) {
            return Err(NotMasked::Unsupported);
        }
        return Ok(plan(EyeLayout::Multiview, view_mask, draws));
    }
    let here: Vec<&EyeSource> = sources.iter().filter(|s| s.layer == base_layer).collect();
    match here.len() {
        0 => Err(NotMasked::EyeUnknown),
        1 => Ok(plan(EyeLayout::PerEye, 0, vec![draw(here[0])])),
        _ => Ok(plan(EyeLayout::SideBySide, 0, here.into_iter().map(draw).collect())),
    }
}

/// One region of a transfer into a swapchain image (vkCmdCopyImage / ResolveImage / BlitImage).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TransferRegion {
    pub src_layer: u32,
    pub dst_layer: u32,
    pub layer_count: u32,
    pub src: PixelRect,
    pub dst: PixelRect,
}

/// Why a transfer source is (not) an intermediate target of an eye; logged once per target.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Learned {
    Eyes(Vec<EyeSource>),
    /// Sizes or scaling do not match any eye 1:1.
    Rejected(String),
}

/// The eyes a transfer source shows, from transfers into swapchain images whose eye uses are
/// `uses`: an eye counts when its image rect lies inside a region's destination and the region
/// maps pixels 1:1 (same extent on both sides, so no scaling), and the source image (of extent
/// `src_extent`) holds the whole translated rect.
pub fn learn_intermediate(regions: &[TransferRegion], uses: &[EyeUse], src_extent: (u32, u32), dst_samples: u32) -> Learned {
    if dst_samples > 1 {
        // xrizer resolves a multisampled game texture into a swapchain of the texture's sample
        // count. Vulkan resolves only into single-sampled images; what a driver makes of it
        // cannot be followed pixel by pixel (a feature's holes would not be where it put them).
        return Learned::Rejected(format!("transferred into a {dst_samples}-sample swapchain image: a pixel of the source is not a pixel of the destination"));
    }
    let mut eyes = Vec::new();
    let mut why = Vec::new();
    let src_image = PixelRect { x: 0, y: 0, width: src_extent.0, height: src_extent.1 };
    for r in regions {
        if (r.src.width, r.src.height) != (r.dst.width, r.dst.height) {
            why.push(format!("scaled region {}x{} → {}x{}", r.src.width, r.src.height, r.dst.width, r.dst.height));
            continue;
        }
        for u in uses {
            let layer = u.image_array_index;
            if layer < r.dst_layer || layer >= r.dst_layer + r.layer_count {
                continue;
            }
            let e = rect(u.image_rect);
            if !r.dst.contains(&e) {
                why.push(format!("view {} rect {}x{}+{}+{} not inside the copied region", u.view, e.width, e.height, e.x, e.y));
                continue;
            }
            let src = PixelRect { x: e.x - r.dst.x + r.src.x, y: e.y - r.dst.y + r.src.y, width: e.width, height: e.height };
            if !src_image.contains(&src) {
                why.push(format!("source image {}x{} smaller than view {}'s rect", src_extent.0, src_extent.1, u.view));
                continue;
            }
            eyes.push(EyeSource { view: u.view, layer: layer - r.dst_layer + r.src_layer, rect: src });
        }
    }
    eyes.sort_by_key(|s| (s.layer, s.rect.x, s.rect.y, s.view));
    eyes.dedup();
    if eyes.is_empty() {
        Learned::Rejected(if why.is_empty() { "no eye use of the destination".into() } else { why.join("; ") })
    } else {
        Learned::Eyes(eyes)
    }
}

#[cfg(test)]
mod tests {
    use super::super::cmd::{ClearValue, DynamicRendering, PassKind, Rect, RenderingAttachment};
    use super::super::resources::*;
    use super::*;
    use std::sync::Arc;

    fn view(handle: u64, image: u64, base_layer: u32, aspect: vk::ImageAspectFlags) -> Arc<ImageView> {
        Arc::new(ImageView {
            handle,
            image,
            view_type: vk::ImageViewType::TYPE_2D,
            format: vk::Format::UNDEFINED,
            range: SubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: base_layer, layer_count: 1 },
        })
    }

    fn att(v: u64, image: u64, load: vk::AttachmentLoadOp, clear: Option<f32>, aspect: vk::ImageAspectFlags) -> AttachmentUse {
        AttachmentUse {
            view: v,
            image_view: Some(view(v, image, 0, aspect)),
            swapchain: None,
            layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
            load_op: load,
            store_op: vk::AttachmentStoreOp::STORE,
            clear: clear.map(|d| ClearValue([d.to_bits(), 0, 0, 0])),
        }
    }

    const R: vk::AttachmentLoadOp = vk::AttachmentLoadOp::CLEAR;
    const COLOR: vk::ImageAspectFlags = vk::ImageAspectFlags::COLOR;
    const DEPTH: vk::ImageAspectFlags = vk::ImageAspectFlags::DEPTH;

    fn dynamic(depth: Option<AttachmentUse>, view_mask: u32, flags: vk::RenderingFlags) -> PassInstance {
        let ra = |a: AttachmentUse| RenderingAttachment {
            attachment: a,
            resolve_mode: vk::ResolveModeFlags::NONE,
            resolve_view: 0,
            resolve_layout: vk::ImageLayout::UNDEFINED,
        };
        PassInstance {
            kind: PassKind::Dynamic,
            render_area: Rect { x: 0, y: 0, width: 200, height: 100 },
            subpass: 0,
            render_pass: None,
            framebuffer: None,
            attachments: vec![],
            clear_values: vec![],
            rendering: Some(DynamicRendering {
                flags,
                layer_count: 1,
                view_mask,
                color: vec![ra(att(1, 10, R, None, COLOR))],
                depth: depth.map(ra),
                stencil: None,
            }),
            flow_at: None,
        }
    }

    fn src(view: u32, layer: u32, x: i32, w: u32) -> EyeSource {
        EyeSource { view, layer, rect: PixelRect { x, y: 0, width: w, height: 100 } }
    }

    fn facts<'a>(eyes: &'a dyn Fn(&AttachmentUse) -> Eyes) -> Facts<'a> {
        Facts { secondary_contents: false, intermediate_enabled: true, eyes, explicit_clear: None }
    }

    fn swapchain_eyes(sources: Vec<EyeSource>) -> impl Fn(&AttachmentUse) -> Eyes {
        move |a: &AttachmentUse| if a.view == 1 { Eyes::Swapchain(sources.clone()) } else { Eyes::Unknown }
    }

    #[test]
    fn per_eye_pass_masks_its_view_with_the_convention_of_its_clear() {
        let eyes = swapchain_eyes(vec![src(1, 0, 0, 200)]);
        let p = classify(&dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::empty()), &facts(&eyes)).unwrap();
        assert_eq!((p.fail_depth, p.layout, p.draws.len(), p.draws[0].view), (0.0, EyeLayout::PerEye, 1, 1));
        let p = classify(&dynamic(Some(att(2, 20, R, Some(0.0), DEPTH)), 0, vk::RenderingFlags::empty()), &facts(&eyes)).unwrap();
        assert_eq!(p.fail_depth, 1.0);
        assert_eq!(
            classify(&dynamic(Some(att(2, 20, R, Some(0.5), DEPTH)), 0, vk::RenderingFlags::empty()), &facts(&eyes)),
            Err(NotMasked::DepthClearNot01)
        );
    }

    #[test]
    fn depth_must_be_cleared_at_the_start() {
        let eyes = swapchain_eyes(vec![src(0, 0, 0, 200)]);
        let load = att(2, 20, vk::AttachmentLoadOp::LOAD, None, DEPTH);
        assert_eq!(classify(&dynamic(Some(load.clone()), 0, vk::RenderingFlags::empty()), &facts(&eyes)), Err(NotMasked::DepthNotCleared));
        // An explicit clear makes a loaded depth buffer maskable.
        let f = Facts { explicit_clear: Some(1.0), ..facts(&eyes) };
        assert!(classify(&dynamic(Some(load), 0, vk::RenderingFlags::empty()), &f).is_ok());
        assert_eq!(
            classify(&dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::RESUMING), &facts(&eyes)),
            Err(NotMasked::DepthNotCleared)
        );
        assert_eq!(classify(&dynamic(None, 0, vk::RenderingFlags::empty()), &facts(&eyes)), Err(NotMasked::NoDepthAttachment));
        let f = Facts { secondary_contents: true, ..facts(&eyes) };
        assert_eq!(classify(&dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::empty()), &f), Err(NotMasked::Secondary));
    }

    #[test]
    fn side_by_side_draws_each_half_clipped_to_the_render_area() {
        let eyes = swapchain_eyes(vec![src(1, 0, 100, 100), src(0, 0, 0, 100)]);
        let mut pass = dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::empty());
        pass.render_area = Rect { x: 0, y: 0, width: 150, height: 100 };
        let p = classify(&pass, &facts(&eyes)).unwrap();
        assert_eq!(p.layout, EyeLayout::SideBySide);
        assert_eq!(p.draws.iter().map(|d| d.view).collect::<Vec<_>>(), vec![0, 1]);
        assert_eq!(p.draws[1].scissor, PixelRect { x: 100, y: 0, width: 50, height: 100 });
        assert_eq!(p.draws[1].viewport, PixelRect { x: 100, y: 0, width: 100, height: 100 });
    }

    #[test]
    fn multiview_needs_every_layer_in_view_order() {
        let depth = Some(att(2, 20, R, Some(1.0), DEPTH));
        let eyes = swapchain_eyes(vec![src(0, 0, 0, 200), src(1, 1, 0, 200)]);
        let p = classify(&dynamic(depth.clone(), 0b11, vk::RenderingFlags::empty()), &facts(&eyes)).unwrap();
        assert_eq!((p.layout, p.view_mask, p.draws.len()), (EyeLayout::Multiview, 0b11, 2));
        let swapped = swapchain_eyes(vec![src(1, 0, 0, 200), src(0, 1, 0, 200)]);
        assert_eq!(classify(&dynamic(depth.clone(), 0b11, vk::RenderingFlags::empty()), &facts(&swapped)), Err(NotMasked::Unsupported));
        let one = swapchain_eyes(vec![src(0, 0, 0, 200)]);
        assert_eq!(classify(&dynamic(depth, 0b11, vk::RenderingFlags::empty()), &facts(&one)), Err(NotMasked::EyeUnknown));
    }

    #[test]
    fn unknown_targets_and_intermediates() {
        let depth = Some(att(2, 20, R, Some(1.0), DEPTH));
        let none = |_: &AttachmentUse| Eyes::Unknown;
        assert_eq!(classify(&dynamic(depth.clone(), 0, vk::RenderingFlags::empty()), &facts(&none)), Err(NotMasked::EyeUnknown));
        let unseen = swapchain_eyes(vec![]);
        assert_eq!(classify(&dynamic(depth.clone(), 0, vk::RenderingFlags::empty()), &facts(&unseen)), Err(NotMasked::EyeUnknown));
        let inter = |a: &AttachmentUse| if a.view == 1 { Eyes::Intermediate(vec![src(0, 0, 0, 200)]) } else { Eyes::Unknown };
        let p = classify(&dynamic(depth.clone(), 0, vk::RenderingFlags::empty()), &facts(&inter)).unwrap();
        assert!(p.intermediate && p.image == 10);
        let off = Facts { intermediate_enabled: false, ..facts(&inter) };
        assert_eq!(classify(&dynamic(depth, 0, vk::RenderingFlags::empty()), &off), Err(NotMasked::IntermediateOff));
        // A depth-only pass into an unknown image (a shadow map) is simply not an eye pass.
        let mut shadow = dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::empty());
        shadow.rendering.as_mut().unwrap().color.clear();
        assert_eq!(classify(&shadow, &facts(&none)), Err(NotMasked::NotEyePass));
    }

    #[test]
    fn render_pass_depth_cleared_only_in_its_first_subpass() {
        let desc = |load| AttachmentDesc {
            format: vk::Format::D32_SFLOAT,
            samples: vk::SampleCountFlags::TYPE_1,
            load_op: load,
            store_op: vk::AttachmentStoreOp::STORE,
            stencil_load_op: vk::AttachmentLoadOp::DONT_CARE,
            stencil_store_op: vk::AttachmentStoreOp::DONT_CARE,
            initial_layout: vk::ImageLayout::UNDEFINED,
            final_layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
        };
        let r = |i| AttachmentRef { attachment: i, layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL };
        let sub = Subpass { color: vec![r(0)], depth_stencil: Some(r(1)), ..Subpass::default() };
        let rp = Arc::new(RenderPass {
            handle: 1,
            version: RenderPassVersion::V1,
            attachments: vec![desc(R), desc(R)],
            subpasses: vec![sub.clone(), sub],
            correlation_masks: vec![],
            layer_rate_attachment: None,
        });
        let mut pass = PassInstance {
            kind: PassKind::RenderPass,
            render_area: Rect { x: 0, y: 0, width: 200, height: 100 },
            subpass: 0,
            render_pass: Some(rp),
            framebuffer: None,
            attachments: vec![att(1, 10, R, None, COLOR), att(2, 20, R, Some(1.0), DEPTH)],
            clear_values: vec![],
            rendering: None,
            flow_at: None,
        };
        let eyes = swapchain_eyes(vec![src(0, 0, 0, 200)]);
        assert!(classify(&pass, &facts(&eyes)).is_ok());
        pass.subpass = 1;
        assert_eq!(classify(&pass, &facts(&eyes)), Err(NotMasked::DepthNotCleared));
        // Loaded depth: only where its contents start (an image clear before the pass counts).
        assert!(!depth_loads(&pass));
        let rp = pass.render_pass.as_ref().unwrap();
        pass.render_pass = Some(Arc::new(RenderPass { attachments: vec![desc(R), desc(vk::AttachmentLoadOp::LOAD)], ..(**rp).clone() }));
        assert!(!depth_loads(&pass));
        pass.subpass = 0;
        assert!(depth_loads(&pass));
    }

    #[test]
    fn depth_loads_only_with_load_op_load() {
        let load = att(2, 20, vk::AttachmentLoadOp::LOAD, None, DEPTH);
        assert!(depth_loads(&dynamic(Some(load.clone()), 0, vk::RenderingFlags::empty())));
        assert!(!depth_loads(&dynamic(Some(load), 0, vk::RenderingFlags::RESUMING)));
        assert!(!depth_loads(&dynamic(Some(att(2, 20, R, Some(1.0), DEPTH)), 0, vk::RenderingFlags::empty())));
        let dont_care = att(2, 20, vk::AttachmentLoadOp::DONT_CARE, None, DEPTH);
        assert!(!depth_loads(&dynamic(Some(dont_care), 0, vk::RenderingFlags::empty())));
        assert!(!depth_loads(&dynamic(None, 0, vk::RenderingFlags::empty())));
    }

    fn eye_use(view: u32, layer: u32, x: i32, w: i32) -> EyeUse {
        EyeUse { view, image_rect: ImageRect { x, y: 0, width: w, height: 100 }, image_array_index: layer, depth: false }
    }

    #[test]
    fn intermediates_are_learned_only_from_one_to_one_transfers() {
        let whole = PixelRect { x: 0, y: 0, width: 200, height: 100 };
        let region = TransferRegion { src_layer: 0, dst_layer: 0, layer_count: 1, src: whole, dst: whole };
        // Side-by-side: one region covers both eyes.
        let uses = [eye_use(0, 0, 0, 100), eye_use(1, 0, 100, 100)];
        assert_eq!(learn_intermediate(&[region], &uses, (200, 100), 1), Learned::Eyes(vec![src(0, 0, 0, 100), src(1, 0, 100, 100)]));
        // Multiview array: layers map through.
        let mv = TransferRegion { layer_count: 2, ..region };
        let uses = [eye_use(0, 0, 0, 200), eye_use(1, 1, 0, 200)];
        assert_eq!(learn_intermediate(&[mv], &uses, (200, 100), 1), Learned::Eyes(vec![src(0, 0, 0, 200), src(1, 1, 0, 200)]));
        // A scaled blit and a source too small are rejected with a reason.
        let scaled = TransferRegion { src: PixelRect { width: 100, height: 50, ..whole }, ..region };
        assert!(matches!(learn_intermediate(&[scaled], &uses, (100, 50), 1), Learned::Rejected(w) if w.contains("scaled")));
        assert!(matches!(learn_intermediate(&[region], &uses, (100, 100), 1), Learned::Rejected(w) if w.contains("smaller")));
        // An offset source region moves the eye rect with it.
        let shifted = TransferRegion { src: PixelRect { x: 50, y: 0, width: 200, height: 100 }, ..region };
        assert_eq!(learn_intermediate(&[shifted], &uses[..1], (300, 100), 1), Learned::Eyes(vec![src(0, 0, 50, 200)]));
        // A resolve into a multisampled swapchain image (as xrizer does for an MSAA game texture)
        // is no pixel-for-pixel transfer: the data-flow walk decides instead.
        assert!(matches!(learn_intermediate(&[region], &uses[..1], (200, 100), 4), Learned::Rejected(w) if w.contains("4-sample")));
    }
}
