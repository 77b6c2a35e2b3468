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
    let traced = || match d.traced.eyes(image) {
        // One target the eyes take turns in: only this use's walk says which eye it shows.
        Some(t) if t.per_use => match asked.at.filter(|_| when == When::Submission).and_then(|at| d.traced.use_eyes(at)) {
            Some(eyes) => Eyes::Traced(eyes),
            None => Eyes::PerUse,
        },
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
    match d.intermediate_eyes(shared, image) {
        None => traced(),
        Some(learned) => {
            let first = lock(&d.eye_books).logged_targets.insert(image);
            match learned {
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

