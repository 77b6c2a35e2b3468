//! The eye decision: which eyes a pass's attachment shows, and which source of that knowledge
//! wins, in order. A swapchain image shows what `xrEndFrame` published (unless the walk saw it
//! written by a post pass). Any other image: a post pass's target as the walk last saw it; else a
//! 1:1 transfer into a swapchain image (an intermediate eye target); else, or when the transfer
//! does not qualify, what the data-flow walk traced (fresh at a submission, never a rect that
//! keeps changing); else `eyes.fallback = size` (by size and order in the frame). Every outcome
//! that teaches something is logged once per image.

use super::cmd::AttachmentUse;
use super::eye_pass::{self, EyeSource, Eyes, Learned};
use super::fallback::Order;
use super::flow::FlowAt;
use super::DeviceTracker;
use crate::bridge::Shared;
use ash::vk;
use std::collections::HashSet;
use std::sync::{Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// When a pass's eyes are asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum When {
    /// While the app records the pass: what the walk learned describes earlier frames.
    Recording,
    /// At a submission of its recording, after that submission's walk: what the walk found in it
    /// describes this very frame.
    Submission,
}

/// How a pass's eyes are asked for: when, and under which settings.
#[derive(Clone, Copy, Debug)]
pub struct Asked {
    /// `mask.intermediate`: only said in the log line of an intermediate target.
    pub intermediate: bool,
    pub when: When,
    /// `eyes.walk`: an image the walk has not seen yet is `Untraced`, not `Unknown`.
    pub walk: bool,
    /// `eyes.fallback = size` with its order; None when off.
    pub fallback: Option<Order>,
    /// Where the pass asked about is recorded (`PassInstance::flow_at`): at a submission, a
    /// target both eyes take turns in shows the eye of this use.
    pub at: Option<FlowAt>,
}

/// What the decision logged already, and the size fallback's order within the frame.
#[derive(Debug, Default)]
pub struct EyeBooks {
    logged_targets: HashSet<u64>,
    /// `eyes.fallback = size`: the eye-sized images of this frame in the order their passes
    /// came (the eye by order), and the decisions already logged.
    fallback_frame: Vec<u64>,
    logged_fallback: HashSet<String>,
}

impl DeviceTracker {
    /// The eyes attachment `a` shows, asked as `asked` says.
    pub fn eyes_at(&self, shared: &Shared, a: &AttachmentUse, asked: &Asked) -> Eyes {
        eyes_at(self, shared, a, asked)
    }
    /// A frame ended (`xrEndFrame`): the size fallback's order starts again.
    pub fn eyes_new_frame(&self) {
        lock(&self.eye_books).fallback_frame.clear();
    }
}

/// The eyes an attachment shows (`eyes_of`), asked at recording or at submission.
pub(crate) fn eyes_at(d: &DeviceTracker, shared: &Shared, a: &AttachmentUse, asked: &Asked) -> Eyes {
    let Asked { intermediate, when, walk, .. } = *asked;
    let image = a.image_view.as_ref().map(|v| v.image);
    if let Some(sc) = &a.swapchain {
        if image.is_some_and(|i| d.traced.is_post(i, Some(sc.swapchain.handle))) {
            return Eyes::Post;
        }
        return Eyes::Swapchain(sc.swapchain.uses().iter().map(EyeSource::from_use).collect());
    }
    let Some(image) = image else { return Eyes::Unknown };
    // One target the eyes take turns in: only this use's walk says which eye it shows.
    let this_use = || match asked.at.filter(|_| when == When::Submission).and_then(|at| d.traced.use_eyes(at)) {
        Some(eyes) => Eyes::Traced(eyes),
        None => Eyes::PerUse,
    };
    let traced = || match d.traced.eyes(image) {
        Some(t) if t.per_use => this_use(),
        // Confirmed by the walk of the submission being made: right for this frame, whatever
        // the rect did before.
        Some(t) if when == When::Submission && d.traced.fresh(&t) => Eyes::Traced(t.eyes),
        // A rect that has changed may change again at any frame: never applied from memory.
        Some(t) if t.dynamic => Eyes::Changing,
        Some(t) => Eyes::Traced(t.eyes),
        None if d.traced.is_post(image, None) => Eyes::Post,
        None if d.traced.has_eyes() => Eyes::NotEye,
        None => match fallback(d, shared, a, image, asked.fallback) {
            Eyes::Unknown if walk => Eyes::Untraced,
            e => e,
        },
    };
    // What the walk saw last wins over what transfers alone say (a 1:1 copy of a post target
    // does not make it an eye pass's).
    if d.traced.is_post(image, None) {
        return Eyes::Post;
    }
    // One target the eyes take turns in (each copied into its own eye's image or layer before
    // the other eye renders into it): transfers name every eye it was ever copied to, not the
    // one this use shows; only the walk of the submission that carries the pass can.
    if d.traced.eyes(image).is_some_and(|t| t.per_use) {
        return traced();
    }
    match d.intermediate_eyes(shared, image) {
        None => traced(),
        Some(learned) => {
            let first = lock(&d.eye_books).logged_targets.insert(image);
            match learned {
                // Copied 1:1 to different eyes from the same pixels (before the walk has seen
                // the frame: the eyes' uses are published at its end): the eyes take turns in it.
                Learned::Eyes(e) if eyes_share_pixels(&e) => this_use(),
                Learned::Eyes(e) => {
                    if first {
                        tracing::info!(
                            image = format_args!("{image:#x}"),
                            "intermediate eye target: image is transferred 1:1 into a swapchain image; eyes {:?}{}",
                            e,
                            if intermediate { "" } else { " (mask.intermediate = off: not masked)" }
                        );
                    }
                    Eyes::Intermediate(e)
                }
                Learned::Rejected(why) => {
                    let t = traced();
                    if first && matches!(t, Eyes::Unknown | Eyes::Untraced) {
                        tracing::info!(image = format_args!("{image:#x}"), "not an intermediate eye target: {why}");
                    }
                    t
                }
            }
        }
    }
}

/// Two different eyes at the same rect of the same layer: no one picture shows both, so the image
/// held each in turn (one target the eyes take turns in).
pub(crate) fn eyes_share_pixels(eyes: &[EyeSource]) -> bool {
    eyes.iter().any(|a| eyes.iter().any(|b| a.view != b.view && (a.layer, a.rect) == (b.layer, b.rect)))
}

/// `eyes.fallback = size`: an image nothing ties to an eye, taken as one by its size and the
/// order of such passes in the frame; every decision logged once (per image and outcome).
fn fallback(d: &DeviceTracker, shared: &Shared, a: &AttachmentUse, image: u64, order: Option<Order>) -> Eyes {
    let Some(order) = order else { return Eyes::Unknown };
    let Some(view) = a.image_view.as_ref() else { return Eyes::Unknown };
    if view.range.aspect_mask.intersects(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL) {
        return Eyes::Unknown;
    }
    let Some(img) = d.images.get(image) else { return Eyes::Unknown };
    let eye = shared.swapchains.values().into_iter().flat_map(|(_, s)| s.uses()).find(|u| !u.depth).map(|u| (u.image_rect.width.max(0) as u32, u.image_rect.height.max(0) as u32));
    let Some(eye) = eye else { return Eyes::Unknown };
    let layers = view.range.layers_of(img.array_layers);
    let nth = {
        let mut b = lock(&d.eye_books);
        match b.fallback_frame.iter().position(|i| *i == image) {
            Some(n) => n,
            None => {
                b.fallback_frame.push(image);
                b.fallback_frame.len() - 1
            }
        }
    };
    let decided = super::fallback::eyes_by_size((img.extent.width, img.extent.height), layers, layers >= 2, eye, nth, order);
    let key = match &decided {
        Ok(e) => format!("{image:#x} {:?}", e.iter().map(|s| s.view).collect::<Vec<_>>()),
        Err(_) => format!("{image:#x} refused"),
    };
    let first = {
        let mut b = lock(&d.eye_books);
        b.logged_fallback.len() < 256 && b.logged_fallback.insert(key)
    };
    match decided {
        Ok(eyes) => {
            if first {
                tracing::info!("eyes.fallback = size: an untraced pass's target {image:#x} taken as an eye target by size and order ({order:?}, pass {nth} of the frame): {}", eye_pass::describe(&eyes));
            }
            Eyes::Fallback(eyes)
        }
        Err(why) => {
            if first {
                tracing::info!("eyes.fallback = size: {image:#x} is not an eye target: {why}");
            }
            Eyes::Unknown
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bridge::Swapchain;
    use crate::core::rect::PixelRect;
    use crate::core::views::{EyeUse, ImageRect, SwapchainDesc};
    use crate::track::cmd::AttachmentUse;
    use crate::track::eye_pass::TransferRegion;
    use crate::track::flow::{DrawRecord, ImageUse, Op, PassRecord};
    use crate::track::resources::{Image, ImageView, SubresourceRange};
    use crate::track::traced::TrackerWorld;
    use std::sync::Arc;

    /// One intermediate (image 10, depth 12) copied into layer v of ONE 2-layer swapchain image
    /// (300; view v at layer v) right after eye v renders into it: the copies alone name both
    /// eyes at the same pixels, which no single picture shows; so before and after the walk saw
    /// the eyes take turns in it, each use gets its own eye at submission, and none at recording.
    #[test]
    fn a_target_the_eyes_take_turns_in_is_not_decided_by_its_copies() {
        let d = DeviceTracker::default();
        let shared = Shared::default();
        let desc = SwapchainDesc { usage_flags: 0, format: 43, sample_count: 1, width: 64, height: 32, array_size: 2 };
        let sc = Arc::new(Swapchain::new(79, desc, vec![300]));
        shared.add_swapchain(sc.clone());
        let whole = ImageRect { x: 0, y: 0, width: 64, height: 32 };
        sc.set_uses((0..2).map(|v| EyeUse { view: v, image_rect: whole, image_array_index: v, depth: false }).collect());
        let image = |h: u64, layers: u32| Image {
            handle: h,
            image_type: vk::ImageType::TYPE_2D,
            format: vk::Format::R8G8B8A8_UNORM,
            extent: vk::Extent3D { width: 64, height: 32, depth: 1 },
            mip_levels: 1,
            array_layers: layers,
            samples: vk::SampleCountFlags::TYPE_1,
            usage: vk::ImageUsageFlags::empty(),
            flags: vk::ImageCreateFlags::empty(),
        };
        d.images.insert(10, Arc::new(image(10, 1)));
        d.images.insert(300, Arc::new(image(300, 2)));
        let range = SubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
        let view = Arc::new(ImageView { handle: 1010, image: 10, view_type: vk::ImageViewType::TYPE_2D, format: vk::Format::UNDEFINED, range });
        d.views.insert(1010, view.clone());
        let rect = PixelRect { x: 0, y: 0, width: 64, height: 32 };
        let copy = |layer: u32| vec![TransferRegion { src_layer: 0, dst_layer: layer, layer_count: 1, src: rect, dst: rect }];
        let u = |image| ImageUse { image, base_layer: 0, layers: 1, mip: 0 };
        let scene = || {
            let mut p = PassRecord { colors: vec![u(10)], color_loads: vec![false], depth: Some(u(12)), depth_cleared: true, render_area: rect, ..Default::default() };
            p.draw(Some(true), DrawRecord { viewport: None, sets: vec![], pushed: vec![] });
            Op::Pass(p)
        };
        for layer in 0..2 {
            d.record_transfer(&shared, 10, 300, &copy(layer));
        }
        let att = AttachmentUse { view: 1010, image_view: Some(view), swapchain: None, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, load_op: vk::AttachmentLoadOp::CLEAR, store_op: vk::AttachmentStoreOp::STORE, clear: None };
        let asked = |when, at| Asked { intermediate: true, when, walk: true, fallback: None, at };
        let views = |e: Eyes| match e {
            Eyes::Intermediate(s) | Eyes::Traced(s) => Some(s.iter().map(|s| s.view).collect::<Vec<_>>()),
            _ => None,
        };
        assert_eq!(d.eyes_at(&shared, &att, &asked(When::Recording, None)), Eyes::PerUse, "the copies alone: both eyes at the same pixels, in turn");
        assert!(!eyes_share_pixels(&[EyeSource { view: 0, layer: 0, rect }, EyeSource { view: 1, layer: 1, rect }]), "multiview: a layer each");
        let half = PixelRect { width: 32, ..rect };
        assert!(!eyes_share_pixels(&[EyeSource { view: 0, layer: 0, rect: half }, EyeSource { view: 1, layer: 0, rect: PixelRect { x: 32, ..half } }]), "side by side");
        let world = TrackerWorld { descriptors: &d.descriptors, views: &d.views, images: &d.images, shared: &shared };
        let ops = vec![scene(), Op::Transfer { src: 10, dst: 300, regions: copy(0) }, scene(), Op::Transfer { src: 10, dst: 300, regions: copy(1) }];
        d.traced.submitted(&world, vec![(7, Arc::new(ops))]);
        assert_eq!(d.eyes_at(&shared, &att, &asked(When::Recording, None)), Eyes::PerUse, "recorded: the use is not known yet");
        let at = |op| Some(FlowAt { cb: 7, op });
        assert_eq!(views(d.eyes_at(&shared, &att, &asked(When::Submission, at(0)))), Some(vec![0]), "the first use is the left eye's");
        assert_eq!(views(d.eyes_at(&shared, &att, &asked(When::Submission, at(2)))), Some(vec![1]), "the second the right eye's");
    }
}
