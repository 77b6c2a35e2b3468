//! VRS for eye passes whose eyes are known only at each submission: passes recorded before the
//! data-flow walk knew their target (the first frames, command buffers recorded once), and passes
//! into a target whose eye rect changes from frame to frame (dynamic resolution). Such a pass gets
//! its rate attachment when it is recorded, but the upload of its map reads a staging buffer of
//! the recording's own; every submission writes into it the map for the eyes that submission's
//! walk found — or 1×1 everywhere when it found none, so a pass is shaded in full rather than
//! foveated in the wrong place. With dynamic rendering the rate image is the recording's own too
//! (a shared one could be uploaded with another submission's rect in between); a render pass
//! object's framebuffer rate image is written by each begin anyway.

use super::rules::{self as rule, NotApplied};
use super::vk::{count, not_applied, plan, Mode};
use crate::track::cmd::{PassInstance, PassKind};
use crate::track::eye_pass::{self, Facts};
use crate::plugin::vk::inject::When;
use crate::plugin::vk::lifetime::{self, PooledBuffer};
use crate::plugin::vk::DeviceState;
use super::vk::RateImage;
use std::sync::{Arc, Mutex};

/// Rate images no recording uses any more, by (texels wide, high, layers).
pub(crate) type RatePool = Arc<Mutex<Vec<((u32, u32, u32), RateImage)>>>;

/// The most images the pool keeps (the rest go to the trash).
const POOLED: usize = 16;

/// A pooled rate image of `shape`, if any.
pub(super) fn take_pooled(d: &DeviceState, shape: (u32, u32, u32)) -> Option<RateImage> {
    let mut pool = super::vk::lock(&super::vk::VrsDevice::of(d).rate_pool);
    let i = pool.iter().position(|(s, _)| *s == shape)?;
    Some(pool.swap_remove(i).1)
}

impl Drop for SubmissionMap {
    /// The recording is done (its submissions completed: `plugin::vk::lifetime`): its image can serve
    /// another.
    fn drop(&mut self) {
        if let Some(img) = self.image.take() {
            let mut pool = super::vk::lock(&self.pool);
            if pool.len() < POOLED {
                pool.push((self.shape, img));
            }
        }
    }
}

/// A pass's rate map filled at each submission: held by the recording.
pub(super) struct SubmissionMap {
    pub(super) pass: PassInstance,
    pub(super) kind: PassKind,
    /// The rate image's texels and layers.
    pub(super) shape: (u32, u32, u32),
    /// What the recorded upload copies into the rate image.
    pub(super) staging: PooledBuffer,
    /// Dynamic rendering: the recording's own rate image, back to the pool with the recording.
    image: Option<RateImage>,
    pool: RatePool,
    /// What the staging buffer holds now, and what it counts as (applied, or why not).
    last: Mutex<Last>,
}

/// Whether `pass`, which `plan` could not tie to its eyes now, awaits them from the walk of each
/// submission (`eye_pass::awaiting_walk`).
pub(super) fn awaits_walk(d: &DeviceState, pass: &PassInstance, secondary: bool) -> bool {
    let intermediate = d.settings().intermediate;
    let eyes = |a: &crate::track::cmd::AttachmentUse| crate::plugin::vk::inject::eyes_of(d, a, intermediate);
    let facts = Facts { secondary_contents: secondary, intermediate_enabled: intermediate, eyes: &eyes, explicit_clear: None };
    eye_pass::awaiting_walk(pass, &facts).is_some()
}

/// The rate image's layers for `pass` when its eyes are not known: one per view of a multiview
/// pass, else one (`rules::pass_eyes`); why not (a layered pass without multiview, a device
/// without layered rates).
pub(super) fn layers(d: &DeviceState, pass: &PassInstance) -> Result<u32, NotApplied> {
    let mask = pass.view_mask();
    if mask != 0 {
        let rates = super::vk::VrsDevice::of(d).rates.ok_or(NotApplied::Unsupported)?;
        return if rates.layered { Ok(32 - mask.leading_zeros()) } else { Err(NotApplied::MultiviewNotLayered) };
    }
    let layered = pass.rendering.as_ref().is_some_and(|r| r.layer_count > 1) || pass.framebuffer.as_ref().is_some_and(|f| f.layers > 1);
    if layered {
        return Err(NotApplied::Layered);
    }
    Ok(1)
}

/// What a map's staging buffer holds: a submission whose eyes and generations are those of the
/// last one rewrites nothing.
#[derive(Default)]
struct Last {
    /// The map written (None: full rate everywhere).
    held: Option<super::vk::MapKey>,
    counted: Option<Result<(), NotApplied>>,
}

impl SubmissionMap {
    /// A map of `shape` (texels, layers), full rate until a submission fills it.
    pub(super) fn new(d: &DeviceState, pass: PassInstance, kind: PassKind, shape: (u32, u32, u32), image: Option<RateImage>) -> Result<SubmissionMap, String> {
        let bytes = shape.0 as u64 * shape.1 as u64 * shape.2 as u64;
        // On failure `image` drops into the device's trash.
        let staging = PooledBuffer::take(d, bytes.max(4), &super::vk::VrsDevice::of(d).memory)?;
        let map = SubmissionMap { pass, kind, shape, staging, image, pool: super::vk::VrsDevice::of(d).rate_pool.clone(), last: Mutex::default() };
        map.write(d, &[]);
        Ok(map)
    }

    fn write(&self, d: &DeviceState, eyes: &[rule::EyeRates]) -> bool {
        let Some(rates) = super::vk::VrsDevice::of(d).rates else { return false };
        let (w, h, layers) = self.shape;
        let data: Vec<u8> = (0..layers).flat_map(|l| rule::rate_layer(w, h, rates.texel_width, rates.texel_height, l, eyes)).collect();
        self.staging.write(0, &data)
    }

    /// At a submission of the recording (`idle`: none of its earlier submissions still runs):
    /// the map for the eyes this submission's walk found, counted as applied or not.
    pub(super) fn submit(&self, d: &DeviceState, idle: bool) {
        let mode = super::vk::VrsDevice::of(d).mode(&d.settings());
        let mut last = super::vk::lock(&self.last);
        if idle {
            let now = if mode != Mode::On {
                Err(None)
            } else {
                match plan(d, mode, &self.pass, false, || false, When::Submission) {
                    Ok(Some((key, eyes, _, _))) => {
                        let eyes: Vec<rule::EyeRates> = eyes.into_iter().filter(|e| e.layer < self.shape.2).collect();
                        if eyes.is_empty() {
                            Err(Some(NotApplied::EyeUnknown))
                        } else if last.held.as_ref() == Some(&key) || self.write(d, &eyes) {
                            last.held = Some(key);
                            Ok(())
                        } else {
                            Err(Some(NotApplied::EyeUnknown))
                        }
                    }
                    Ok(None) => Err(None),
                    Err(why) => Err(Some(why)),
                }
            };
            last.counted = match now {
                Ok(()) => Some(Ok(())),
                Err(why) => {
                    if last.held.take().is_some() {
                        self.write(d, &[]);
                    }
                    why.map(Err)
                }
            };
        }
        // Counted at every submission, with what the staging buffer holds for it.
        match last.counted {
            Some(Ok(())) => count(d, |s| s.passes += 1),
            Some(Err(why)) => not_applied(d, why, self.kind),
            None => {}
        }
    }
}

/// Before a submission: every map of the submitted recordings gets this submission's eyes.
pub(super) fn before_submit(d: &DeviceState, cbs: &[u64]) {
    for &cb in cbs {
        let idle = !lifetime::in_flight(d, cb);
        lifetime::with_holds(d, cb, |holds| {
            for h in holds {
                if let Some(m) = h.downcast_ref::<SubmissionMap>() {
                    m.submit(d, idle);
                }
            }
        });
    }
}
