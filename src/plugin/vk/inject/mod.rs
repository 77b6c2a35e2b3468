//! What a feature gets at the injection point and the helpers it draws with: the injection's
//! context (`Injection`, `Awaiting`), the eye-pass plan, indirect draws from the recording's own
//! buffer, the pipeline cache (`pipeline`) and the state restore (`restore`). The chassis that
//! raises injections from the hooks' triggers is `crate::vk::chassis`.
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
use crate::track::eye_pass::{self, EyeDraw, EyeSource, Eyes, MaskPlan};
pub(crate) use crate::track::eyes::When;
use crate::track::eyes::Asked;
use crate::track::flow::FlowAt;
use ash::vk;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::AtomicUsize;
use std::sync::{Mutex, MutexGuard};
pub(crate) use trigger::Trigger;

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The size of one `VkDrawIndirectCommand`: injected draws read their arguments from the
/// recording's own buffer (`plugin::vk::lifetime::PooledBuffer`), so resubmissions draw current data.
pub(crate) const DRAW_ARGS: u64 = std::mem::size_of::<vk::DrawIndirectCommand>() as u64;

/// The indirect draws a feature's recording keeps at the head of its own buffer, ahead of its
/// vertices (the mask, RDM): one slot per eye for per-eye draws, one for a multiview pass or a
/// pass awaiting its eyes (one draw over the render area).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DrawSlots(usize);

impl DrawSlots {
    /// For a known eye pass of `eyes` eyes.
    pub(crate) fn for_eyes(eyes: usize, multiview: bool) -> DrawSlots {
        DrawSlots(if multiview { 1 } else { eyes.max(1) })
    }
    /// For a pass awaiting its eyes.
    pub(crate) const AWAITING: DrawSlots = DrawSlots(1);
    /// Where the vertices start in the buffer.
    pub(crate) fn vertex_offset(self) -> u64 {
        DRAW_ARGS * self.0 as u64
    }
    /// Makes every slot draw nothing (only while no submission of the recording executes).
    pub(crate) fn clear(self, buffer: &crate::plugin::vk::lifetime::PooledBuffer) {
        buffer.write(0, &vec![vk::DrawIndirectCommand::default(); self.0]);
    }
}

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
    let eyes = |a: &AttachmentUse| eyes_at(d, a, intermediate, When::Submission, pass.flow_at);
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
/// - `Err(why)`: unknown now (the rects change from frame to frame and this submission's walk
///   did not confirm them, `RectChanging`; or the image turned out to be one target both eyes
///   take turns in, whose eye only a pass's own use tells, `SharedTarget`): the draws must do
///   nothing, or they could land beside the eye, or in the other one.
pub(crate) fn walk_moved(d: &DeviceState, image: u64, draws: &[EyeDraw]) -> Result<Option<Vec<EyeSource>>, NotMasked> {
    let Some(t) = d.track.traced.eyes(image) else { return Ok(None) };
    if t.per_use {
        return Err(NotMasked::SharedTarget);
    }
    if !d.track.traced.fresh(&t) {
        return if t.dynamic { Err(NotMasked::RectChanging) } else { Ok(None) };
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
pub(crate) struct Pending {
    pub(crate) snap: Snapshot,
    pub(crate) plan: MaskPlan,
    pub(crate) counts: bool,
    /// The pass awaits its eyes (`Awaiting`, from the walk when `Some(true)`); `plan` only
    /// carries its shape.
    pub(crate) awaiting: Option<bool>,
}

/// Per-device injection state. The lock guards bookkeeping only, never a call down.
#[derive(Default)]
pub(crate) struct InjectDevice {
    pub(crate) books: Mutex<Books>,
    pub(crate) pipelines: pipeline::Cache,
    /// Passes armed for an injection at their first depth-tested draw: while zero, a draw costs
    /// the layer one atomic load.
    pub(crate) armed_count: AtomicUsize,
}

/// An eye pass whose `injects_before_depth_test` features wait for its first depth-tested draw.
pub(crate) struct Armed {
    pub(crate) pass: PassInstance,
    pub(crate) plan: MaskPlan,
    pub(crate) counts: bool,
    /// The pass awaits its eyes (`Awaiting`, with this fail depth, from the walk when true);
    /// `plan` only has its shape.
    pub(crate) awaiting: Option<(f32, bool)>,
}

#[derive(Default)]
pub(crate) struct Books {
    /// Command buffers whose open pass loads its depth and was not injected at its beginning: it
    /// counts at its first depth clear, or as `depth_not_cleared` when it ends.
    pub(crate) deferred: HashSet<u64>,
    /// Primaries whose open eye pass has its contents in secondaries.
    pub(crate) pending: HashMap<u64, Pending>,
    pub(crate) logged_reasons: HashSet<NotMasked>,
    pub(crate) logged_vetoes: HashSet<&'static str>,
    /// Injections vetoed, by reason (the command the layer cannot restore after).
    pub(crate) vetoed: HashMap<&'static str, u64>,
    /// Command buffer → its armed open pass.
    pub(crate) armed: HashMap<u64, Armed>,
}

impl InjectDevice {
    /// Injections vetoed so far, by reason (for the device's stats line).
    pub(crate) fn vetoed(&self) -> Vec<(&'static str, u64)> {
        let mut v: Vec<_> = lock(&self.books).vetoed.iter().map(|(k, v)| (*k, *v)).collect();
        v.sort();
        v
    }
}

/// What the pass looked like when the trigger fired, copied out of the command buffer's lock.
pub(crate) struct Snapshot {
    pub(crate) pass: PassInstance,
    pub(crate) restore: Vec<StateCmd>,
    pub(crate) sets: Vec<StateCmd>,
    pub(crate) secondary_level: bool,
    pub(crate) explicit_clear: Option<f32>,
    pub(crate) veto: Option<&'static str>,
}

/// A plan carrying only a pass's shape (its layout by view mask): what pipelines and inherited
/// secondaries need before the eyes are known.
pub(crate) fn shape_only(pass: &PassInstance, fail_depth: f32) -> MaskPlan {
    let layout = if pass.view_mask() != 0 { eye_pass::EyeLayout::Multiview } else { eye_pass::EyeLayout::PerEye };
    MaskPlan { fail_depth, layout, intermediate: false, via: eye_pass::Via::Swapchain, image: 0, view_mask: pass.view_mask(), draws: Vec::new() }
}

pub(crate) fn attachments(pass: &PassInstance) -> Vec<&AttachmentUse> {
    match &pass.rendering {
        Some(r) => r.color.iter().chain(&r.depth).chain(&r.stencil).map(|a| &a.attachment).collect(),
        None => pass.attachments.iter().collect(),
    }
}

pub(crate) fn depth_image(pass: &PassInstance) -> Option<u64> {
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
    eyes_at(d, a, intermediate, When::Recording, None)
}

/// The eyes an attachment shows (`eyes_of`), asked at recording or at submission: the trackers'
/// decision (`track::eyes`) under the live settings.
pub(crate) fn eyes_at(d: &DeviceState, a: &AttachmentUse, intermediate: bool, when: When, at: Option<FlowAt>) -> Eyes {
    let s = d.settings();
    d.track.eyes_at(shared(), a, &Asked { intermediate, when, walk: s.eyes_walk, fallback: s.eyes_fallback, at })
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
