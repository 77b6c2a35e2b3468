//! The one injection mechanism: where a feature's draws go into an app's pass, and how the app's
//! state comes back afterwards. The hooks raise *triggers* (a pass began, a subpass began, the
//! depth attachment was cleared, the pass is ending); this module asks the eye-pass test
//! (`track::eye_pass`) whether the pass is an eye pass with a freshly cleared depth, and if so
//! calls every injecting feature in registry order at the injection point, then restores the app's
//! state (`restore`). Passes whose contents are secondary command buffers get the draws in a
//! secondary of the layer's, executed ahead of the app's (`vk::secondary`).
//!
//! Injection points: right after the depth clear (the pass's begin with a CLEAR load op, a
//! `vkCmdClearAttachments` of the depth, or a begin that loads an image cleared by
//! `vkCmdClearDepthStencilImage`). The pure decision (when a pass counts, deferral to a later
//! clear, pending secondaries) is `trigger::decide`.

pub(crate) mod open_passes;
pub(crate) mod pipeline;
pub(crate) mod restore;
pub(crate) mod trigger;

use super::DeviceState;
use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::track::cmd::{AttachmentUse, PassInstance, StateCmd};
use crate::track::eye_pass::{self, EyeDraw, EyeSource, Eyes, Learned, MaskPlan};
use ash::vk::{self, Handle};
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};
pub(crate) use trigger::Trigger;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The size of one `VkDrawIndirectCommand`: injected draws read their arguments from the
/// recording's own buffer (`vk::lifetime::PooledBuffer`), so resubmissions draw current data.
pub(crate) const DRAW_ARGS: u64 = std::mem::size_of::<vk::DrawIndirectCommand>() as u64;

/// What a feature gets at the injection point.
pub(crate) struct Injection<'a> {
    /// The command buffer to record into: the app's, inside its pass, or a secondary of the
    /// layer's inheriting it.
    pub cb: vk::CommandBuffer,
    pub pass: &'a PassInstance,
    pub plan: &'a MaskPlan,
    pub settings: &'a Settings,
    /// Whether this injection counts as the pass's (a pass counts once, at its first chance).
    pub counts: bool,
    /// The app's command buffer the draws end up in (holds are taken on it).
    pub owner: u64,
    /// Set by a feature that bound descriptor sets: the app's are rebound afterwards.
    pub bound_sets: std::cell::Cell<bool>,
}

/// A pass that renders into a swapchain image whose eye uses are not known yet (the session's
/// first frame), with its depth freshly cleared: features record draws whose data they fill at
/// submission, once the eyes are known (`plan_now`), so a command buffer recorded that early and
/// resubmitted later is still masked / foveated.
pub(crate) struct Awaiting<'a> {
    pub cb: vk::CommandBuffer,
    pub owner: u64,
    pub pass: &'a PassInstance,
    pub fail_depth: f32,
    pub settings: &'a Settings,
    /// Set by a feature that bound descriptor sets: the app's are rebound afterwards.
    pub bound_sets: std::cell::Cell<bool>,
    /// It awaits the walk (`eye_pass::awaiting_walk`), not the OpenXR half's eye uses: features
    /// that fill at submission count it there (`VkFeature::fills_at_submission`).
    pub walk: bool,
}

/// The plan for a pass recorded earlier, with the eyes known now (at a submission of its
/// recording: after that submission's walk).
pub(crate) fn plan_now(d: &DeviceState, pass: &PassInstance, fail_depth: f32, intermediate: bool) -> Result<MaskPlan, NotMasked> {
    let eyes = |a: &AttachmentUse| eyes_at(d, a, intermediate, When::Submission);
    // The clear that makes `fail_depth` fail.
    let clear = 1.0 - fail_depth;
    let facts = eye_pass::Facts { secondary_contents: false, intermediate_enabled: intermediate, eyes: &eyes, explicit_clear: Some(clear) };
    eye_pass::classify(pass, &facts)
}

/// Where the eyes a recording's draws for `image` were planned with (from what the walk had
/// learned when it was recorded) are at this submission:
/// - `Ok(None)`: where they were — the walk of this submission found the same rects, or did not
///   reach the image and its rects are not known to change;
/// - `Ok(Some(eyes))`: this submission's walk found them elsewhere (dynamic resolution moved the
///   rect since the recording): these rects are this frame's;
/// - `Err(())`: unknown now (the rects change from frame to frame and this submission's walk did
///   not confirm them): the draws must do nothing, or they could land beside the eye.
pub(crate) fn walk_moved(d: &DeviceState, image: u64, draws: &[EyeDraw]) -> Result<Option<Vec<EyeSource>>, ()> {
    let Some(t) = d.track.traced.eyes(image) else { return Ok(None) };
    if !d.track.traced.fresh(&t) {
        return if t.dynamic { Err(()) } else { Ok(None) };
    }
    let same = draws.iter().all(|dr| t.eyes.iter().any(|e| e.view == dr.view && e.layer == dr.layer && e.rect == dr.viewport));
    Ok((!same).then_some(t.eyes))
}

/// The render area of a pass as a rect.
pub(crate) fn render_area(pass: &PassInstance) -> PixelRect {
    let a = pass.render_area;
    PixelRect { x: a.x, y: a.y, width: a.width, height: a.height }
}

/// An injection waiting for the app's vkCmdExecuteCommands.
struct Pending {
    snap: Snapshot,
    plan: MaskPlan,
    counts: bool,
    /// The pass awaits its eyes (`Awaiting`, from the walk when `Some(true)`); `plan` only
    /// carries its shape.
    awaiting: Option<bool>,
}

/// Per-device injection state. The lock guards bookkeeping only, never a call down.
#[derive(Default)]
pub(crate) struct InjectDevice {
    books: Mutex<Books>,
    pub(crate) pipelines: pipeline::Cache,
    /// Passes armed for an injection at their first depth-tested draw: while zero, a draw costs
    /// the layer one atomic load.
    armed_count: AtomicUsize,
}

/// An eye pass whose `injects_before_depth_test` features wait for its first depth-tested draw.
struct Armed {
    pass: PassInstance,
    plan: MaskPlan,
    counts: bool,
    /// The pass awaits its eyes (`Awaiting`, with this fail depth, from the walk when true);
    /// `plan` only has its shape.
    awaiting: Option<(f32, bool)>,
}

#[derive(Default)]
struct Books {
    /// Command buffers whose open pass loads its depth and was not injected at its beginning: it
    /// counts at its first depth clear, or as `depth_not_cleared` when it ends.
    deferred: HashSet<u64>,
    /// Primaries whose open eye pass has its contents in secondaries.
    pending: HashMap<u64, Pending>,
    logged_targets: HashSet<u64>,
    logged_reasons: HashSet<NotMasked>,
    logged_vetoes: HashSet<&'static str>,
    /// Injections vetoed, by reason (the command the layer cannot restore after).
    vetoed: HashMap<&'static str, u64>,
    /// Command buffer → its armed open pass.
    armed: HashMap<u64, Armed>,
    /// `eyes.fallback = size`: the eye-sized images of this frame in the order their passes
    /// came (the eye by order), and the decisions already logged.
    fallback_frame: Vec<u64>,
    logged_fallback: HashSet<String>,
}

impl InjectDevice {
    /// A frame ended (`xrEndFrame`): the size fallback's order starts again.
    pub(crate) fn new_frame(&self) {
        lock(&self.books).fallback_frame.clear();
    }

    /// Injections vetoed so far, by reason (for the device's stats line).
    pub(crate) fn vetoed(&self) -> Vec<(&'static str, u64)> {
        let mut v: Vec<_> = lock(&self.books).vetoed.iter().map(|(k, v)| (*k, *v)).collect();
        v.sort();
        v
    }
}

/// What the pass looked like when the trigger fired, copied out of the command buffer's lock.
struct Snapshot {
    pass: PassInstance,
    restore: Vec<StateCmd>,
    sets: Vec<StateCmd>,
    secondary_level: bool,
    explicit_clear: Option<f32>,
    veto: Option<&'static str>,
}

/// Whether any feature draws at the injection point under these settings.
pub(crate) fn any_injects(d: &DeviceState, s: &Settings) -> bool {
    d.features.all().iter().any(|f| f.injects(s))
}

/// Entry from the hooks, after the triggering command went down successfully.
pub(crate) fn on_trigger(d: &DeviceState, cb: vk::CommandBuffer, trigger: Trigger) {
    let settings = d.settings();
    if !any_injects(d, &settings) {
        return;
    }
    let key = cb.as_raw();
    if !matches!(trigger, Trigger::Clear { .. }) {
        // A new pass or subpass, or the end: an armed injection that met no depth-tested draw
        // had nothing to save.
        disarm(d, key);
    }
    if trigger == Trigger::End && !lock(&d.inject.books).deferred.contains(&key) {
        return;
    }
    let secondary_level = d.track.command_buffers.get(key).is_some_and(|c| c.level == vk::CommandBufferLevel::SECONDARY);
    let snap = d.track.with_cb(key, |s| {
        let pass = s.pass.clone()?;
        // A pass that loads an image cleared by vkCmdClearDepthStencilImage starts from that clear.
        let mut explicit_clear = None;
        if matches!(trigger, Trigger::Begin { .. }) {
            let images: Vec<u64> = attachments(&pass).iter().filter_map(|a| a.image_view.as_ref().map(|v| v.image)).collect();
            if let Some(depth_image) = depth_image(&pass).filter(|_| eye_pass::depth_loads(&pass)) {
                explicit_clear = s.depth_image_clears.iter().rev().find(|(i, _)| *i == depth_image).map(|(_, v)| *v);
            }
            s.depth_image_clears.retain(|(i, _)| !images.contains(i));
        }
        if let Trigger::Clear { depth, .. } = &trigger {
            explicit_clear = Some(*depth);
        }
        Some(Snapshot { pass, restore: s.restore_commands(), sets: s.descriptor_set_commands(), secondary_level, explicit_clear, veto: s.veto })
    });
    let Some(Some(snap)) = snap else { return };
    if !matches!(trigger, Trigger::Clear { .. }) {
        // A new subpass or the end: whatever was pending for the previous one was never executed.
        lock(&d.inject.books).pending.remove(&key);
    }
    let eyes = |a: &AttachmentUse| eyes_of(d, a, settings.intermediate);
    let facts = eye_pass::Facts { secondary_contents: snap.secondary_level, intermediate_enabled: settings.intermediate, eyes: &eyes, explicit_clear: snap.explicit_clear };
    let plan = eye_pass::classify(&snap.pass, &facts);
    let decision = {
        let mut books = lock(&d.inject.books);
        let deferred = books.deferred.contains(&key);
        let dec = trigger::decide(&trigger, &snap.pass, plan.as_ref().map(|_| ()).map_err(|e| *e), deferred);
        if dec.defer {
            books.deferred.insert(key);
        } else if dec.undefer {
            books.deferred.remove(&key);
        }
        dec
    };
    let mut plan = match plan {
        Ok(p) => p,
        Err(why) => {
            // A clear of part of the attachment may leave an eye uncleared: only whole clears.
            let whole = match &trigger {
                Trigger::Clear { rects, .. } => rects.iter().any(|r| r.contains(&render_area(&snap.pass))),
                Trigger::End => false,
                _ => true,
            };
            // A pass whose eyes a later moment may tell: the walk of its submission, or the
            // OpenXR half's first `xrEndFrame` for a swapchain image.
            let awaits = whole && snap.veto.is_none();
            let walk = awaits.then(|| eye_pass::awaiting_walk(&snap.pass, &facts)).flatten().map(|f| (f, true));
            if walk.is_some() {
                // Features that fill their draws at submission count the pass there (applied, or
                // why not); the others count it now.
                if decision.counts {
                    for f in d.features.all() {
                        if f.injects(&settings) && !f.fills_at_submission() {
                            f.not_injected(d, &settings, why);
                        }
                    }
                }
            } else {
                count_not_injected(d, &settings, decision.counts, why, &snap.pass);
            }
            let swapchain = || (awaits && why == NotMasked::EyeUnknown).then(|| eye_pass::awaiting_eyes(&snap.pass, &facts)).flatten().map(|f| (f, false));
            if let Some((fail_depth, walk)) = walk.or_else(swapchain) {
                if trigger.secondary_contents() && !snap.secondary_level {
                    let plan = shape_only(&snap.pass, fail_depth);
                    lock(&d.inject.books).pending.insert(key, Pending { snap, plan, counts: false, awaiting: Some(walk) });
                    return;
                }
                inject_awaiting(d, cb, key, &snap, (fail_depth, walk), &settings, true);
            }
            return;
        }
    };
    if trigger == Trigger::End {
        return;
    }
    if let Trigger::Clear { rects, .. } = &trigger {
        // A clear of part of the attachment: inject only into eyes it fully re-cleared.
        plan.draws.retain(|dr| rects.iter().any(|r| r.contains(&dr.scissor)));
        if plan.draws.is_empty() {
            if decision.counts {
                // Still uncleared where the eyes are: a later clear or the pass's end counts it.
                lock(&d.inject.books).deferred.insert(key);
            }
            return;
        }
    }
    if let Some(reason) = snap.veto {
        veto(d, &settings, decision.counts, reason, &snap.pass);
        return;
    }
    if trigger.secondary_contents() && !snap.secondary_level {
        lock(&d.inject.books).pending.insert(key, Pending { snap, plan, counts: decision.counts, awaiting: None });
        return;
    }
    inject(d, cb, key, &snap, &plan, &settings, decision.counts, true);
}

/// The app executes secondaries in `cb`: if its open eye pass awaits the layer's draws, they are
/// recorded into a secondary of the layer's, returned to be executed first.
pub(crate) fn on_execute_commands(d: &DeviceState, cb: vk::CommandBuffer) -> Option<vk::CommandBuffer> {
    let Pending { snap, plan, counts, awaiting } = lock(&d.inject.books).pending.remove(&cb.as_raw())?;
    let settings = d.settings();
    let formats;
    let inherit = match (&snap.pass.rendering, &snap.pass.render_pass, &snap.pass.framebuffer) {
        (Some(r), _, _) => {
            let Some(pipeline::PassKey::Dynamic { colors, depth, stencil, samples, .. }) = pipeline::pass_key(d, &snap.pass, &plan) else {
                count_not_injected(d, &settings, counts, NotMasked::Unsupported, &snap.pass);
                return None;
            };
            formats = colors;
            super::secondary::Inherit::Rendering { flags: r.flags, view_mask: r.view_mask, colors: &formats, depth, stencil, samples: vk::SampleCountFlags::from_raw(samples) }
        }
        (None, Some(rp), Some(fb)) => super::secondary::Inherit::RenderPass { render_pass: rp.handle, subpass: snap.pass.subpass, framebuffer: fb.handle },
        _ => {
            count_not_injected(d, &settings, counts, NotMasked::Unsupported, &snap.pass);
            return None;
        }
    };
    let recorded = super::secondary::record(d, cb.as_raw(), &inherit, |ours| {
        if let Some(walk) = awaiting {
            inject_awaiting(d, ours, cb.as_raw(), &snap, (plan.fail_depth, walk), &settings, false)
        } else {
            inject(d, ours, cb.as_raw(), &snap, &plan, &settings, counts, false)
        }
    });
    match recorded {
        Ok(ours) => Some(ours),
        Err(e) => {
            d.warn_repeated("layer secondary command buffer", &e);
            count_not_injected(d, &settings, counts, NotMasked::LayerError, &snap.pass);
            None
        }
    }
}

/// Counts (and logs once) a pass the injecting features leave alone.
fn count_not_injected(d: &DeviceState, settings: &Settings, counts: bool, why: NotMasked, pass: &PassInstance) {
    if !counts {
        return;
    }
    for f in d.features.all() {
        if f.injects(settings) {
            f.not_injected(d, settings, why);
        }
    }
    if why != NotMasked::NotEyePass && lock(&d.inject.books).logged_reasons.insert(why) {
        tracing::info!(kind = ?pass.kind, "pass not masked: {} (logged once per reason)", why.name());
    }
}

/// The command buffer uses state the layer cannot restore: no injection, never wrong output.
fn veto(d: &DeviceState, settings: &Settings, counts: bool, reason: &'static str, pass: &PassInstance) {
    let first = {
        let mut books = lock(&d.inject.books);
        *books.vetoed.entry(reason).or_insert(0) += 1;
        books.logged_vetoes.insert(reason)
    };
    if first {
        tracing::warn!(kind = ?pass.kind, "injection vetoed: the command buffer uses {reason}, state the layer cannot restore after its draws; such passes are left alone (logged once per reason)");
    }
    if counts {
        for f in d.features.all() {
            if f.injects(settings) {
                f.not_injected(d, settings, NotMasked::Unsupported);
            }
        }
    }
}

/// Records every injecting feature's draws for an eye pass into `cb`, then the app's state after
/// them when `cb` is the app's own (a secondary of the layer's needs no restore: the app's
/// secondaries set their own state). Features that wait for the first depth-tested draw are
/// armed instead (only in the app's own command buffer: the layer's secondary runs ahead of all
/// of the app's draws, so it cannot wait for one).
#[allow(clippy::too_many_arguments)]
fn inject(d: &DeviceState, cb: vk::CommandBuffer, owner: u64, snap: &Snapshot, plan: &MaskPlan, settings: &Settings, counts: bool, restore: bool) {
    let at = Injection { cb, pass: &snap.pass, plan, settings, counts, owner, bound_sets: Default::default() };
    {
        // Dropped here: the app's state goes back after every feature's draws.
        let _restore = restore.then(|| restore::Restore::new(d, cb, &snap.restore, &snap.sets, &at.bound_sets));
        for f in d.features.all() {
            if f.injects(settings) && !f.injects_before_depth_test() {
                f.inject(d, &at);
            }
        }
    }
    let waiting: Vec<_> = d.features.all().into_iter().filter(|f| f.injects(settings) && f.injects_before_depth_test()).collect();
    if waiting.is_empty() {
        return;
    }
    if !restore {
        for f in waiting {
            if counts {
                f.not_injected(d, settings, NotMasked::Secondary);
            }
        }
        return;
    }
    arm(d, owner, Armed { pass: snap.pass.clone(), plan: plan.clone(), counts, awaiting: None });
}

fn arm(d: &DeviceState, owner: u64, armed: Armed) {
    if lock(&d.inject.books).armed.insert(owner, armed).is_none() {
        d.inject.armed_count.fetch_add(1, Ordering::AcqRel);
    }
}

/// Counts a veto met by an armed pass for the waiting features only.
fn veto_waiting(d: &DeviceState, settings: &Settings, reason: &'static str) {
    *lock(&d.inject.books).vetoed.entry(reason).or_insert(0) += 1;
    for f in d.features.all() {
        if f.injects(settings) && f.injects_before_depth_test() {
            f.not_injected(d, settings, NotMasked::Unsupported);
        }
    }
}

fn disarm(d: &DeviceState, cb: u64) {
    if d.inject.armed_count.load(Ordering::Acquire) == 0 {
        return;
    }
    if lock(&d.inject.books).armed.remove(&cb).is_some() {
        d.inject.armed_count.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Entry from the draw hooks, before the app's draw goes down: the first depth-tested draw of an
/// armed pass gets the waiting features' draws in front of it, with the app's state as it is now
/// restored afterwards.
pub(crate) fn before_draw(d: &DeviceState, cb: vk::CommandBuffer) {
    if d.inject.armed_count.load(Ordering::Acquire) == 0 {
        return;
    }
    let key = cb.as_raw();
    if !lock(&d.inject.books).armed.contains_key(&key) {
        return;
    }
    let Some((tested, restore, sets, veto)) = d.track.with_cb(key, |s| (s.depth_tested(), s.restore_commands(), s.descriptor_set_commands(), s.veto)) else { return };
    if let Some(reason) = veto {
        // State the layer cannot restore was set after the pass was armed.
        disarm(d, key);
        let settings = d.settings();
        veto_waiting(d, &settings, reason);
        return;
    }
    // An untracked pipeline counts as depth-tested: injecting before it is the safe side only
    // if it tests depth, which every pipeline drawing scenery does.
    if tested == Some(false) {
        return;
    }
    let Some(armed) = lock(&d.inject.books).armed.remove(&key) else { return };
    d.inject.armed_count.fetch_sub(1, Ordering::AcqRel);
    let settings = d.settings();
    if let Some((fail_depth, walk)) = armed.awaiting {
        let at = Awaiting { cb, owner: key, pass: &armed.pass, fail_depth, settings: &settings, bound_sets: Default::default(), walk };
        let _restore = restore::Restore::new(d, cb, &restore, &sets, &at.bound_sets);
        for f in d.features.all() {
            if f.injects(&settings) && f.injects_before_depth_test() {
                f.inject_awaiting(d, &at);
            }
        }
        return;
    }
    let at = Injection { cb, pass: &armed.pass, plan: &armed.plan, settings: &settings, counts: armed.counts, owner: key, bound_sets: Default::default() };
    let _restore = restore::Restore::new(d, cb, &restore, &sets, &at.bound_sets);
    for f in d.features.all() {
        if f.injects(&settings) && f.injects_before_depth_test() {
            f.inject(d, &at);
        }
    }
}

/// Records every injecting feature's draws for a pass awaiting its eyes (`Awaiting`), then the
/// app's state when `cb` is the app's own.
#[allow(clippy::too_many_arguments)]
fn inject_awaiting(d: &DeviceState, cb: vk::CommandBuffer, owner: u64, snap: &Snapshot, (fail_depth, walk): (f32, bool), settings: &Settings, restore: bool) {
    let at = Awaiting { cb, owner, pass: &snap.pass, fail_depth, settings, bound_sets: Default::default(), walk };
    {
        let _restore = restore.then(|| restore::Restore::new(d, cb, &snap.restore, &snap.sets, &at.bound_sets));
        for f in d.features.all() {
            if f.injects(settings) && !f.injects_before_depth_test() {
                f.inject_awaiting(d, &at);
            }
        }
    }
    let waiting = d.features.all().into_iter().any(|f| f.injects(settings) && f.injects_before_depth_test());
    // Only the app's own command buffer can wait for a draw (see `inject`).
    if waiting && restore {
        arm(d, owner, Armed { pass: snap.pass.clone(), plan: shape_only(&snap.pass, fail_depth), counts: false, awaiting: Some((fail_depth, walk)) });
    }
}

/// A plan carrying only a pass's shape (its layout by view mask): what pipelines and inherited
/// secondaries need before the eyes are known.
pub(crate) fn shape_only(pass: &PassInstance, fail_depth: f32) -> MaskPlan {
    let layout = if pass.view_mask() != 0 { eye_pass::EyeLayout::Multiview } else { eye_pass::EyeLayout::PerEye };
    MaskPlan { fail_depth, layout, intermediate: false, via: eye_pass::Via::Swapchain, image: 0, view_mask: pass.view_mask(), draws: Vec::new() }
}

fn attachments(pass: &PassInstance) -> Vec<&AttachmentUse> {
    match &pass.rendering {
        Some(r) => r.color.iter().chain(&r.depth).chain(&r.stencil).map(|a| &a.attachment).collect(),
        None => pass.attachments.iter().collect(),
    }
}

fn depth_image(pass: &PassInstance) -> Option<u64> {
    let att = match &pass.rendering {
        Some(r) => r.depth.as_ref().map(|d| &d.attachment),
        None => {
            let rp = pass.render_pass.as_ref()?;
            let i = rp.subpasses.get(pass.subpass as usize)?.depth_stencil?.used()?;
            pass.attachments.get(i as usize)
        }
    }?;
    att.image_view.as_ref().map(|v| v.image)
}

/// Which eyes an attachment shows: a swapchain image's published uses, or an intermediate
/// target's learned ones (logged once per image).
pub(crate) fn eyes_of(d: &DeviceState, a: &AttachmentUse, intermediate: bool) -> Eyes {
    eyes_at(d, a, intermediate, When::Recording)
}

/// When a pass's eyes are asked for.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum When {
    /// While the app records the pass: what the walk learned describes earlier frames.
    Recording,
    /// At a submission of its recording, after that submission's walk: what the walk found in it
    /// describes this very frame.
    Submission,
}

/// The eyes an attachment shows (`eyes_of`), asked at recording or at submission.
pub(crate) fn eyes_at(d: &DeviceState, a: &AttachmentUse, intermediate: bool, when: When) -> Eyes {
    let image = a.image_view.as_ref().map(|v| v.image);
    if let Some(sc) = &a.swapchain {
        if image.is_some_and(|i| d.track.traced.is_post(i, Some(sc.swapchain.handle))) {
            return Eyes::Post;
        }
        return Eyes::Swapchain(sc.swapchain.uses().iter().map(EyeSource::from_use).collect());
    }
    let Some(image) = image else { return Eyes::Unknown };
    let traced = || match d.track.traced.eyes(image) {
        // Confirmed by the walk of the submission being made: right for this frame, whatever
        // the rect did before.
        Some(t) if when == When::Submission && d.track.traced.fresh(&t) => Eyes::Traced(t.eyes),
        // A rect that has changed may change again at any frame: never applied from memory.
        Some(t) if t.dynamic => Eyes::Changing,
        Some(t) => Eyes::Traced(t.eyes),
        None if d.track.traced.is_post(image, None) => Eyes::Post,
        None if d.track.traced.has_eyes() => Eyes::NotEye,
        None => match fallback(d, a, image) {
            Eyes::Unknown if d.settings().eyes_walk => Eyes::Untraced,
            e => e,
        },
    };
    // What the walk saw last wins over what transfers alone say (a 1:1 copy of a post target
    // does not make it an eye pass's).
    if d.track.traced.is_post(image, None) {
        return Eyes::Post;
    }
    match d.track.intermediate_eyes(shared(), image) {
        None => traced(),
        Some(learned) => {
            let first = lock(&d.inject.books).logged_targets.insert(image);
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
fn fallback(d: &DeviceState, a: &AttachmentUse, image: u64) -> Eyes {
    let Some(order) = d.settings().eyes_fallback else { return Eyes::Unknown };
    let Some(view) = a.image_view.as_ref() else { return Eyes::Unknown };
    if view.range.aspect_mask.intersects(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL) {
        return Eyes::Unknown;
    }
    let Some(img) = d.track.images.get(image) else { return Eyes::Unknown };
    let eye = shared().swapchains.values().into_iter().flat_map(|(_, s)| s.uses()).find(|u| !u.depth).map(|u| (u.image_rect.width.max(0) as u32, u.image_rect.height.max(0) as u32));
    let Some(eye) = eye else { return Eyes::Unknown };
    let layers = view.range.layers_of(img.array_layers);
    let nth = {
        let mut b = lock(&d.inject.books);
        match b.fallback_frame.iter().position(|i| *i == image) {
            Some(n) => n,
            None => {
                b.fallback_frame.push(image);
                b.fallback_frame.len() - 1
            }
        }
    };
    let decided = crate::track::fallback::eyes_by_size((img.extent.width, img.extent.height), layers, layers >= 2, eye, nth, order);
    let key = match &decided {
        Ok(e) => format!("{image:#x} {:?}", e.iter().map(|s| s.view).collect::<Vec<_>>()),
        Err(_) => format!("{image:#x} refused"),
    };
    let first = {
        let mut b = lock(&d.inject.books);
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

/// The app submits `cbs`: their recorded data flow joins the window, and every swapchain image
/// they write is walked back to its eye passes (`track::traced`); what the walk learned or could
/// not trace is logged once.
pub(crate) fn walk_submitted(d: &DeviceState, cbs: &[u64]) {
    if !d.settings().eyes_walk {
        return;
    }
    let snaps: Vec<_> = cbs.iter().filter_map(|cb| d.track.with_cb(*cb, |s| s.flow_on.then(|| s.flow.snapshot())).flatten()).collect();
    if snaps.is_empty() {
        return;
    }
    let world = crate::track::traced::TrackerWorld { descriptors: &d.track.descriptors, views: &d.track.views, images: &d.track.images, shared: shared() };
    for note in d.track.traced.submitted(&world, snaps) {
        match note {
            crate::track::traced::Note::Traced { image, eyes, chain, depth } => tracing::info!(
                "data-flow walk: {} {image:#x} of an eye pass, reached from the swapchain through {chain}: {}",
                if depth { "depth image" } else { "colour target" },
                eye_pass::describe(&eyes)
            ),
            crate::track::traced::Note::Untraced(why) => tracing::info!("data-flow walk: {why} (logged once)"),
        }
    }
}

/// One indirect draw of a feature's: its arguments' slot in the recording's buffer, and where.
pub(crate) struct IndirectDraw {
    pub slot: u64,
    pub viewport: vk::Viewport,
    pub scissor: PixelRect,
}

/// Records a feature's indirect draws from its recording's buffer (arguments at the start, one
/// `DRAW_ARGS` per slot; vertices from `vertex_offset`), each with its viewport and scissor.
///
/// # Safety
/// `cb` is recording inside a pass `pipeline` is compatible with, and `buffer` is held by the
/// recording that owns `cb` (`lifetime::hold`) until its submissions complete.
pub(crate) unsafe fn record_indirect(d: &DeviceState, cb: vk::CommandBuffer, pipeline: vk::Pipeline, buffer: vk::Buffer, vertex_offset: u64, draws: &[IndirectDraw]) {
    let fns = d.fns.fp_v1_0();
    // SAFETY: per the contract; every pointer is to a local that outlives its call.
    unsafe {
        (fns.cmd_bind_pipeline)(cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
        (fns.cmd_bind_vertex_buffers)(cb, 0, 1, &buffer, &vertex_offset);
        for dr in draws {
            (fns.cmd_set_viewport)(cb, 0, 1, &dr.viewport);
            (fns.cmd_set_scissor)(cb, 0, 1, &rect2d(dr.scissor));
            (fns.cmd_draw_indirect)(cb, buffer, DRAW_ARGS * dr.slot, 1, DRAW_ARGS as u32);
        }
    }
}

/// The viewport of an injected depth draw: the eye's rect, with the depth range pinned to the fail
/// depth so one pipeline serves both depth conventions.
pub(crate) fn fail_viewport(r: PixelRect, fail_depth: f32) -> vk::Viewport {
    vk::Viewport { x: r.x as f32, y: r.y as f32, width: r.width as f32, height: r.height as f32, min_depth: fail_depth, max_depth: fail_depth }
}

pub(crate) fn rect2d(r: PixelRect) -> vk::Rect2D {
    vk::Rect2D { offset: vk::Offset2D { x: r.x, y: r.y }, extent: vk::Extent2D { width: r.width, height: r.height } }
}
