//! The injection chassis: the hooks raise *triggers* (a pass began, a subpass began, the depth
//! attachment was cleared, the pass is ending); this module asks the eye-pass test
//! (`track::eye_pass`) whether the pass is an eye pass with a freshly cleared depth, and if so
//! calls every injecting feature in registry order at the injection point, then restores the app's
//! state (`plugin::vk::inject::restore`). Passes whose contents are secondary command buffers get
//! the draws in a secondary of the layer's, executed ahead of the app's (`plugin::vk::secondary`).
//! The pure decision (when a pass counts, deferral to a later clear, pending secondaries) is
//! `plugin::vk::inject::trigger::decide`.

use crate::plugin::vk::inject::*;
use crate::plugin::vk::feature::VkFeature;
use crate::plugin::vk::DeviceState;
use crate::core::pass::NotMasked;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::track::cmd::{AttachmentUse, PassInstance};
use crate::track::eye_pass::{self, MaskPlan};
use ash::vk::{self, Handle};
use std::sync::atomic::Ordering;

/// The features that draw at the injection point under one trigger's settings, asked once per
/// trigger: those that draw right after the depth clear (`now`) and those that wait for the pass's
/// first depth-tested draw (`at_depth_test`), as bits of their registry positions.
#[derive(Clone, Copy)]
struct Injectors {
    now: u32,
    at_depth_test: u32,
}

impl Injectors {
    fn of(d: &DeviceState, s: &Settings) -> Injectors {
        let (mut now, mut at_depth_test) = (0, 0);
        for (i, f) in d.features.all().iter().enumerate() {
            if f.injects(s) {
                if f.injects_before_depth_test() {
                    at_depth_test |= 1 << i;
                } else {
                    now |= 1 << i;
                }
            }
        }
        Injectors { now, at_depth_test }
    }
    fn any(self) -> bool {
        self.now | self.at_depth_test != 0
    }
    fn pick(d: &DeviceState, bits: u32) -> impl Iterator<Item = &dyn VkFeature> {
        d.features.all().iter().enumerate().filter(move |(i, _)| bits & (1 << i) != 0).map(|(_, f)| f.as_ref())
    }
    /// Every injecting feature.
    fn all(self, d: &DeviceState) -> impl Iterator<Item = &dyn VkFeature> {
        Injectors::pick(d, self.now | self.at_depth_test)
    }
    /// Those that draw right after the depth clear.
    fn now(self, d: &DeviceState) -> impl Iterator<Item = &dyn VkFeature> {
        Injectors::pick(d, self.now)
    }
    /// Those that wait for the pass's first depth-tested draw.
    fn at_depth_test(self, d: &DeviceState) -> impl Iterator<Item = &dyn VkFeature> {
        Injectors::pick(d, self.at_depth_test)
    }
}

/// Whether any feature draws at the injection point under these settings.
pub(crate) fn any_injects(d: &DeviceState, s: &Settings) -> bool {
    Injectors::of(d, s).any()
}

/// Entry from the hooks, after the triggering command went down successfully.
pub(crate) fn on_trigger(d: &DeviceState, cb: vk::CommandBuffer, trigger: Trigger) {
    let settings = d.settings();
    let inj = Injectors::of(d, &settings);
    if !inj.any() {
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
                    for f in inj.all(d).filter(|f| !f.fills_at_submission()) {
                        f.not_injected(d, &settings, why);
                    }
                }
            } else {
                count_not_injected(d, inj, &settings, decision.counts, why, &snap.pass);
            }
            let swapchain = || (awaits && why == NotMasked::EyeUnknown).then(|| eye_pass::awaiting_eyes(&snap.pass, &facts)).flatten().map(|f| (f, false));
            if let Some((fail_depth, walk)) = walk.or_else(swapchain) {
                if trigger.secondary_contents() && !snap.secondary_level {
                    let plan = shape_only(&snap.pass, fail_depth);
                    lock(&d.inject.books).pending.insert(key, Pending { snap, plan, counts: false, awaiting: Some(walk) });
                    return;
                }
                inject_awaiting(d, inj, cb, key, &snap, (fail_depth, walk), &settings, true);
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
        veto(d, inj, &settings, decision.counts, reason, &snap.pass);
        return;
    }
    if trigger.secondary_contents() && !snap.secondary_level {
        lock(&d.inject.books).pending.insert(key, Pending { snap, plan, counts: decision.counts, awaiting: None });
        return;
    }
    inject(d, inj, cb, key, &snap, &plan, &settings, decision.counts, true);
}

/// The app executes secondaries in `cb`: if its open eye pass awaits the layer's draws, they are
/// recorded into a secondary of the layer's, returned to be executed first.
pub(crate) fn on_execute_commands(d: &DeviceState, cb: vk::CommandBuffer) -> Option<vk::CommandBuffer> {
    let Pending { snap, plan, counts, awaiting } = lock(&d.inject.books).pending.remove(&cb.as_raw())?;
    let settings = d.settings();
    let inj = Injectors::of(d, &settings);
    let formats;
    let inherit = match (&snap.pass.rendering, &snap.pass.render_pass, &snap.pass.framebuffer) {
        (Some(r), _, _) => {
            let Some(pipeline::PassKey::Dynamic { colors, depth, stencil, samples, .. }) = pipeline::pass_key(d, &snap.pass, &plan) else {
                count_not_injected(d, inj, &settings, counts, NotMasked::Unsupported, &snap.pass);
                return None;
            };
            formats = colors;
            crate::plugin::vk::secondary::Inherit::Rendering { flags: r.flags, view_mask: r.view_mask, colors: &formats, depth, stencil, samples: vk::SampleCountFlags::from_raw(samples) }
        }
        (None, Some(rp), Some(fb)) => crate::plugin::vk::secondary::Inherit::RenderPass { render_pass: rp.handle, subpass: snap.pass.subpass, framebuffer: fb.handle },
        _ => {
            count_not_injected(d, inj, &settings, counts, NotMasked::Unsupported, &snap.pass);
            return None;
        }
    };
    let recorded = crate::plugin::vk::secondary::record(d, cb.as_raw(), &inherit, |ours| {
        if let Some(walk) = awaiting {
            inject_awaiting(d, inj, ours, cb.as_raw(), &snap, (plan.fail_depth, walk), &settings, false)
        } else {
            inject(d, inj, ours, cb.as_raw(), &snap, &plan, &settings, counts, false)
        }
    });
    match recorded {
        Ok(ours) => Some(ours),
        Err(e) => {
            d.warn_repeated("layer secondary command buffer", &e);
            count_not_injected(d, inj, &settings, counts, NotMasked::LayerError, &snap.pass);
            None
        }
    }
}

/// Counts (and logs once) a pass the injecting features leave alone.
fn count_not_injected(d: &DeviceState, inj: Injectors, settings: &Settings, counts: bool, why: NotMasked, pass: &PassInstance) {
    if !counts {
        return;
    }
    for f in inj.all(d) {
        f.not_injected(d, settings, why);
    }
    if why != NotMasked::NotEyePass && lock(&d.inject.books).logged_reasons.insert(why) {
        tracing::info!(kind = ?pass.kind, "pass not masked: {} (logged once per reason)", why.name());
    }
}

/// The command buffer uses state the layer cannot restore: no injection, never wrong output.
fn veto(d: &DeviceState, inj: Injectors, settings: &Settings, counts: bool, reason: &'static str, pass: &PassInstance) {
    let first = {
        let mut books = lock(&d.inject.books);
        *books.vetoed.entry(reason).or_insert(0) += 1;
        books.logged_vetoes.insert(reason)
    };
    if first {
        tracing::warn!(kind = ?pass.kind, "injection vetoed: the command buffer uses {reason}, state the layer cannot restore after its draws; such passes are left alone (logged once per reason)");
    }
    if counts {
        for f in inj.all(d) {
            f.not_injected(d, settings, NotMasked::Unsupported);
        }
    }
}

/// Records every injecting feature's draws for an eye pass into `cb`, then the app's state after
/// them when `cb` is the app's own (a secondary of the layer's needs no restore: the app's
/// secondaries set their own state). Features that wait for the first depth-tested draw are
/// armed instead (only in the app's own command buffer: the layer's secondary runs ahead of all
/// of the app's draws, so it cannot wait for one).
#[allow(clippy::too_many_arguments)]
fn inject(d: &DeviceState, inj: Injectors, cb: vk::CommandBuffer, owner: u64, snap: &Snapshot, plan: &MaskPlan, settings: &Settings, counts: bool, restore: bool) {
    let at = Injection { cb, pass: &snap.pass, plan, settings, counts, owner, bound_sets: Default::default() };
    {
        // Dropped here: the app's state goes back after every feature's draws.
        let _restore = restore.then(|| restore::Restore::new(d, cb, &snap.restore, &snap.sets, &at.bound_sets));
        for f in inj.now(d) {
            f.inject(d, &at);
        }
    }
    if inj.at_depth_test == 0 {
        return;
    }
    if !restore {
        if counts {
            for f in inj.at_depth_test(d) {
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
    for f in Injectors::of(d, settings).at_depth_test(d) {
        f.not_injected(d, settings, NotMasked::Unsupported);
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
    let waiting = Injectors::of(d, &settings);
    if let Some((fail_depth, walk)) = armed.awaiting {
        let at = Awaiting { cb, owner: key, pass: &armed.pass, fail_depth, settings: &settings, bound_sets: Default::default(), walk };
        let _restore = restore::Restore::new(d, cb, &restore, &sets, &at.bound_sets);
        for f in waiting.at_depth_test(d) {
            f.inject_awaiting(d, &at);
        }
        return;
    }
    let at = Injection { cb, pass: &armed.pass, plan: &armed.plan, settings: &settings, counts: armed.counts, owner: key, bound_sets: Default::default() };
    let _restore = restore::Restore::new(d, cb, &restore, &sets, &at.bound_sets);
    for f in waiting.at_depth_test(d) {
        f.inject(d, &at);
    }
}

/// Records every injecting feature's draws for a pass awaiting its eyes (`Awaiting`), then the
/// app's state when `cb` is the app's own.
#[allow(clippy::too_many_arguments)]
fn inject_awaiting(d: &DeviceState, inj: Injectors, cb: vk::CommandBuffer, owner: u64, snap: &Snapshot, (fail_depth, walk): (f32, bool), settings: &Settings, restore: bool) {
    let at = Awaiting { cb, owner, pass: &snap.pass, fail_depth, settings, bound_sets: Default::default(), walk };
    {
        let _restore = restore.then(|| restore::Restore::new(d, cb, &snap.restore, &snap.sets, &at.bound_sets));
        for f in inj.now(d) {
            f.inject_awaiting(d, &at);
        }
    }
    // Only the app's own command buffer can wait for a draw (see `inject`).
    if inj.at_depth_test != 0 && restore {
        arm(d, owner, Armed { pass: snap.pass.clone(), plan: shape_only(&snap.pass, fail_depth), counts: false, awaiting: Some((fail_depth, walk)) });
    }
}


/// The app submits `cbs`: their recorded data flow joins the window, and every swapchain image
/// they write is walked back to its eye passes (`track::traced`); what the walk learned or could
/// not trace is logged once.
pub(crate) fn walk_submitted(d: &DeviceState, cbs: &[u64]) {
    if !d.settings().eyes_walk {
        return;
    }
    let snaps: Vec<_> = cbs.iter().filter_map(|cb| d.track.with_cb(*cb, |s| s.flow_on.then(|| (*cb, s.flow.snapshot()))).flatten()).collect();
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

