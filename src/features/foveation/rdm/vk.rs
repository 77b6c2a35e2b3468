//! Radial density masking on the Vulkan side, the draw half: at the chassis' injection point (an
//! eye pass's depth just cleared, after the mask) a full-viewport draw writes the failing depth on
//! the quads `rules` skips, so early-Z rejects the app's fragments there. Which eyes of which image
//! await reconstruction is decided when the command buffer is *submitted* (not recorded), in
//! recording order together with the app's 1:1 transfers that carry them from an intermediate
//! target into the swapchain image, so a command buffer recorded once and resubmitted hands its
//! skipped quads to `reconstruct` every frame.

use crate::features::foveation::FoveationSettings;
use super::rules::{hand_off, HandOff, NotApplied, Pending, RdmFrameStats, RdmParams, SkipCount};
use crate::core::rect::PixelRect;
use crate::core::stats::FeatureStats;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::track::eye_pass::{EyeDraw, EyeLayout, MaskPlan, TransferRegion, Via};
use crate::plugin::vk::feature::{Destroyed, DeviceInit, Plugin, VkFeature};
use crate::plugin::vk::inject::open_passes::OpenPasses;
use crate::plugin::vk::inject::{self, pipeline, Awaiting, Injection};
use crate::plugin::vk::lifetime::{self, PooledBuffer};
use crate::plugin::vk::DeviceState;
use crate::core::pass::NotMasked;
use ash::vk;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

static VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm.vert.spv"));
static VERT_MV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_mv.vert.spv"));
static FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm.frag.spv"));

/// One vertex of the depth draw: position, view, and the eye's rule parameters (flat).
#[repr(C)]
#[derive(Clone, Copy)]
struct Vertex {
    pos: [f32; 2],
    view: u32,
    origin: [i32; 2],
    /// tan_left, tan_up, step_x, step_y.
    tan: [f32; 4],
    /// cx, cy, k_inner, k_middle.
    fovea: [f32; 4],
}

/// Stride and attributes of `Vertex` (shaders/rdm.vert).
fn vertex_layout() -> (u32, Vec<vk::VertexInputAttributeDescription>) {
    let a = |location, format, offset| vk::VertexInputAttributeDescription { location, binding: 0, format, offset };
    (
        std::mem::size_of::<Vertex>() as u32,
        vec![
            a(0, vk::Format::R32G32_SFLOAT, 0),
            a(1, vk::Format::R32_UINT, 8),
            a(2, vk::Format::R32G32_SINT, 12),
            a(3, vk::Format::R32G32B32A32_SFLOAT, 20),
            a(4, vk::Format::R32G32B32A32_SFLOAT, 36),
        ],
    )
}



#[derive(Default)]
pub(super) struct Books {
    frame: RdmFrameStats,
    total: RdmFrameStats,
    /// Image (swapchain or intermediate) → eyes drawn with RDM since it was last released / copied.
    pub(super) pending: HashMap<u64, Vec<Pending>>,
    counts: HashMap<(u64, u64, u32, PixelRect, PixelRect), SkipCount>,
    pub(super) logged: HashSet<String>,
    /// Command buffer → reconstructions waiting for its open pass's end (`pass_end_vk`).
    jobs: HashMap<u64, Vec<super::pass_end_vk::Job>>,
}

/// Per-device RDM state. Locks guard bookkeeping only, never a call down.
pub(crate) struct RdmDevice {
    layer_enabled: bool,
    /// The device has layer-enabled attachment rates (`foveation.method = auto` is VRS there).
    fsr_attachment: bool,
    /// A CPU implementation (`foveation.method = auto` is no foveation there).
    software: bool,
    used: AtomicBool,
    pub(super) memory: vk::PhysicalDeviceMemoryProperties,
    pub(super) books: Mutex<Books>,
    pub(super) reconstruct: super::reconstruct::Reconstruct,
    pub(super) pass_end: Mutex<super::pass_end_vk::PassEndObjects>,
    /// The checkerboards in each command buffer's open passes (judged when they end).
    open: OpenPasses<Arc<Drawn>>,
}

impl RdmDevice {
    /// The device's object of this feature (the registry made one for every device).
    pub(crate) fn of(d: &DeviceState) -> &RdmDevice {
        d.features.get::<RdmDevice>()
    }
}

pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Plugin for RdmDevice {
    /// `foveation.*`, shared with VRS (the registry lists a key once).
    fn new(init: &DeviceInit<'_>) -> RdmDevice {
        RdmDevice {
            layer_enabled: init.settings.enabled,
            fsr_attachment: init.rates.is_some(),
            software: init.software,
            used: AtomicBool::new(false),
            memory: init.memory,
            books: Mutex::default(),
            reconstruct: super::reconstruct::Reconstruct::new(init.memory, init.set_loader_data),
            pass_end: Mutex::default(),
            open: OpenPasses::default(),
        }
    }
    fn empty_stats() -> Box<dyn FeatureStats> {
        Box::new(RdmFrameStats::default())
    }
    /// On with RDM as the method in effect: `rdm`, or `auto` where no other foveation method
    /// acted this frame.
    fn enabled(s: &Settings, frame: &crate::core::stats::FrameStats) -> bool {
        let vrs_active = frame.iter().any(|f| f.group() == Some("foveation") && f.id() != "rdm" && !f.is_empty());
        s.of::<FoveationSettings>().enabled && (s.of::<FoveationSettings>().method == crate::features::foveation::Method::Rdm || (s.of::<FoveationSettings>().method == crate::features::foveation::Method::Auto && !vrs_active))
    }
}

impl RdmDevice {
    pub(super) fn count(&self, f: impl Fn(&mut RdmFrameStats)) {
        let mut b = lock(&self.books);
        f(&mut b.frame);
        f(&mut b.total);
    }
}

/// The app transferred `src` into `dst` in a recording: applied to the pending books when the
/// command buffer is submitted, in recording order with the draws.
struct Transfer {
    src: u64,
    dst: u64,
    regions: Vec<TransferRegion>,
}

/// What a recording's checkerboard draws are for.
enum Target {
    /// A known eye pass: one indirect draw per eye (one in all for multiview), recorded with the
    /// eye's viewport and scissor; a full-viewport triangle per eye.
    Eyes { draws: Vec<EyeDraw>, multiview: bool, image: u64 },
    /// A pass whose eyes were unknown when recorded: one indirect draw over the render area, a
    /// quad per eye (its scissor rect) once the eyes are known. `walk`: only the walk can tie it
    /// to its eyes (counted at each submission).
    Awaiting { pass: Box<crate::track::cmd::PassInstance>, fail_depth: f32, area: PixelRect, walk: bool },
}

/// One recorded checkerboard injection: its buffer (indirect arguments, then the vertices with
/// the rule's parameters per eye) and what it holds. Refilled for the current fovea before a
/// submission when the recording is idle, so a command buffer recorded once follows the gaze.
struct Drawn {
    buffer: PooledBuffer,
    target: Target,
    filled: Mutex<Filled>,
    /// Behind a post chain: the reconstruction at the pass's end this checkerboard depends on.
    link: Option<Arc<super::pass_end_vk::Link>>,
    /// The pass ended without one depth-tested draw (a post pass recorded before the walk knew
    /// it): the checkerboard skipped nothing there, so it draws nothing and nothing is
    /// reconstructed (counted `post_pass`).
    saves_nothing: AtomicBool,
}

/// What a recording's buffer holds: for which generations and eyes, the eyes of which image it
/// leaves to reconstruct, and what it skips per view.
#[derive(Default)]
struct Filled {
    key: Option<((u64, u64), Vec<EyeDraw>)>,
    image: u64,
    pending: Vec<Pending>,
    skipped: Vec<(u32, SkipCount)>,
}

/// (foveation generation, views generation) and every eye's rule parameters under them.
type EyeParams = ((u64, u64), Vec<(EyeDraw, RdmParams)>);

/// The rule's parameters of `eyes` under the current fovea and FOVs.
fn params_now(eyes: &[EyeDraw]) -> Result<EyeParams, NotApplied> {
    let fovea = shared().foveation();
    let views = shared().views();
    let mut out = Vec::new();
    for dr in eyes {
        let f = fovea.views.iter().find(|f| f.view == dr.view).ok_or(NotApplied::NoFovea)?;
        let fov = views.app_fovs.get(dr.view as usize).ok_or(NotApplied::NoFovea)?;
        out.push((*dr, RdmParams::new(fov, f, dr.viewport).ok_or(NotApplied::NoFovea)?));
    }
    if out.is_empty() {
        return Err(NotApplied::NoFovea);
    }
    Ok(((fovea.generation, views.generation), out))
}

fn vertex(pos: [f32; 2], dr: &EyeDraw, p: &RdmParams) -> Vertex {
    Vertex { pos, view: dr.view, origin: [p.rect.x, p.rect.y], tan: [p.tan_left, p.tan_up, p.step_x, p.step_y], fovea: [p.center[0], p.center[1], p.k_inner, p.k_middle] }
}

/// A full-viewport triangle per eye (drawn with the eye's viewport), or, over `area`, a quad per
/// eye covering its scissor rect.
fn vertices(eyes: &[(EyeDraw, RdmParams)], area: Option<PixelRect>) -> Vec<Vertex> {
    let mut out = Vec::new();
    for (dr, p) in eyes {
        match area {
            None => out.extend([[-1.0f32, -1.0], [3.0, -1.0], [-1.0, 3.0]].iter().map(|&pos| vertex(pos, dr, p))),
            Some(a) => {
                let r = dr.scissor;
                let x = |px: i32| (px - a.x) as f32 / a.width as f32 * 2.0 - 1.0;
                let y = |py: i32| (py - a.y) as f32 / a.height as f32 * 2.0 - 1.0;
                let (x0, x1, y0, y1) = (x(r.x), x(r.x + r.width as i32), y(r.y), y(r.y + r.height as i32));
                out.extend([[x0, y0], [x1, y0], [x0, y1], [x1, y0], [x1, y1], [x0, y1]].iter().map(|&pos| vertex(pos, dr, p)));
            }
        }
    }
    out
}

impl Drawn {
    fn draw_slots(&self) -> inject::DrawSlots {
        match &self.target {
            Target::Eyes { draws, multiview, .. } => inject::DrawSlots::for_eyes(draws.len(), *multiview),
            Target::Awaiting { .. } => inject::DrawSlots::AWAITING,
        }
    }
    fn vertex_offset(&self) -> u64 {
        self.draw_slots().vertex_offset()
    }
    /// Draws nothing, leaves nothing to reconstruct.
    fn clear(&self, f: &mut Filled) {
        self.draw_slots().clear(&self.buffer);
        *f = Filled::default();
    }
    /// Makes the buffer hold the rule for the current fovea (`plan`: the eyes known now, for an
    /// awaiting target). Keeps what it has when the fovea is momentarily unknown. Only called while
    /// no submission of the recording executes.
    fn refresh(&self, me: &RdmDevice, plan: Option<&MaskPlan>) {
        let mut f = lock(&self.filled);
        let (draws, multiview, area, image) = match (&self.target, plan) {
            (Target::Eyes { draws, multiview, image }, _) => (draws.clone(), *multiview, None, *image),
            // Reached through a post chain: no reconstruction at release would come in time; only
            // the fill at the pass's end (the link's) can follow.
            (Target::Awaiting { .. }, Some(p)) if p.via.behind_post() != self.link.is_some() => {
                if let Some(link) = &self.link {
                    link.arm(false);
                }
                return self.clear(&mut f);
            }
            (Target::Awaiting { area, .. }, Some(p)) => (p.draws.clone(), p.layout == EyeLayout::Multiview, Some(*area), p.image),
            (Target::Awaiting { .. }, None) => return self.clear(&mut f),
        };
        let Ok((generations, eyes)) = params_now(&draws) else { return };
        let key = (generations, draws);
        if let Some(link) = &self.link {
            // The fill at the pass's end was recorded for one fovea and these eyes: under any
            // other, or without it, no checkerboard.
            if !link.allows(&key) {
                link.arm(false);
                return self.clear(&mut f);
            }
        }
        if f.key.as_ref() == Some(&key) {
            return;
        }
        let buf = &self.buffer;
        let vertices = vertices(&eyes, area);
        let per = if area.is_some() { 6 } else { 3 };
        let args: Vec<vk::DrawIndirectCommand> = if multiview || area.is_some() {
            vec![vk::DrawIndirectCommand { vertex_count: vertices.len() as u32, instance_count: 1, first_vertex: 0, first_instance: 0 }]
        } else {
            (0..eyes.len()).map(|i| vk::DrawIndirectCommand { vertex_count: per, instance_count: 1, first_vertex: per * i as u32, first_instance: 0 }).collect()
        };
        if !buf.write(self.vertex_offset(), &vertices) {
            return self.clear(&mut f);
        }
        buf.write(0, &args);
        let skipped = eyes.iter().map(|(dr, p)| (dr.view, count(me, generations.0, generations.1, dr, p))).collect();
        let pending: Vec<Pending> = eyes.iter().map(|(dr, p)| Pending { view: dr.view, layer: dr.layer, params: *p }).collect();
        if let Some(link) = &self.link {
            let filled = if link.frozen.is_some() {
                link.arm(true);
                true
            } else {
                link.fill_submitted(me, &pending)
            };
            if !filled {
                link.arm(false);
                return self.clear(&mut f);
            }
        }
        *f = Filled { key: Some(key), image, pending, skipped };
    }
}

impl VkFeature for RdmDevice {
    fn id(&self) -> &'static str {
        "rdm"
    }
    fn take_frame(&self) -> Box<dyn FeatureStats> {
        Box::new(std::mem::take(&mut lock(&self.books).frame))
    }
    fn summary(&self) -> Option<String> {
        self.used.load(Ordering::Relaxed).then(|| {
            let waits = self.reconstruct.release_waits.load(Ordering::Relaxed);
            format!("{} release_waits={waits}", lock(&self.books).total.summary())
        })
    }
    fn injects(&self, s: &Settings) -> bool {
        let method = s.of::<FoveationSettings>().method.resolve(self.fsr_attachment, self.software);
        let on = self.layer_enabled && s.of::<FoveationSettings>().enabled && method == Some(crate::features::foveation::Method::Rdm);
        if on {
            self.used.store(true, Ordering::Relaxed);
        } else if self.layer_enabled && s.of::<FoveationSettings>().enabled && method.is_none() {
            log_once(self, "auto declined".into(), || {
                tracing::warn!("foveation.method = auto: no foveation on this CPU Vulkan implementation (RDM's own passes cost more than they save for most apps here: docs/benchmarks.md); set foveation.method = \"rdm\" to force it")
            });
        }
        on
    }
    fn inject(&self, d: &DeviceState, at: &Injection<'_>) {
        super::compute::warm(d);
        if let Err(why) = record_draw(self, d, at) {
            if at.counts {
                self.count(|s| s.count_not_applied(why));
            }
        }
    }
    fn inject_awaiting(&self, d: &DeviceState, at: &Awaiting<'_>) {
        super::compute::warm(d);
        if let Err(why) = record_awaiting(self, d, at) {
            tracing::debug!("radial density masking: no draw for a pass awaiting its eyes: {}", why.name());
            // A pass awaiting the walk is counted here, once, when it gets nothing at all.
            if at.walk {
                self.count(|s| s.count_not_applied(why));
            }
        }
    }
    /// Passes awaiting the walk are counted at each submission (`before_submit`).
    fn fills_at_submission(&self) -> bool {
        true
    }
    fn not_injected(&self, _d: &DeviceState, _s: &Settings, why: NotMasked) {
        if why != NotMasked::NotEyePass {
            self.count(|s| *s.not_applied.entry(why.name()).or_insert(0) += 1);
        }
    }
    fn transfer(&self, d: &DeviceState, cb: vk::CommandBuffer, src: u64, dst: u64, regions: &[TransferRegion]) {
        if self.injects(&d.settings()) {
            lifetime::hold(d, ash::vk::Handle::as_raw(cb), Arc::new(Transfer { src, dst, regions: regions.to_vec() }));
        }
    }
    /// Colour attachments can be reconstructed in place at an eye pass's end by the compute pass
    /// (`pass_end_compute`: copied out and back) whenever the layer is on (RDM can be switched on
    /// live). Transient attachments never hold an eye a later pass reads.
    fn image_usage(&self, _s: &Settings, usage: vk::ImageUsageFlags) -> vk::ImageUsageFlags {
        if self.layer_enabled && usage.contains(vk::ImageUsageFlags::COLOR_ATTACHMENT) && !usage.contains(vk::ImageUsageFlags::TRANSIENT_ATTACHMENT) {
            vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST
        } else {
            vk::ImageUsageFlags::empty()
        }
    }
    fn destroyed(&self, d: &DeviceState, what: Destroyed) {
        if let Destroyed::Image(image) = what {
            lock(&self.books).pending.remove(&image);
            super::pass_end_vk::image_destroyed(self, d, image);
        }
    }
    /// A recording abandoned inside an eye pass (reset while recording): its pass-end
    /// reconstructions are never recorded, and its checkerboards never submitted.
    fn recordings_closed(&self, _d: &DeviceState, cbs: &[u64]) {
        let mut b = lock(&self.books);
        for cb in cbs {
            b.jobs.remove(cb);
        }
        drop(b);
        self.open.closed(cbs);
    }
    /// A pass with checkerboards ends: without one depth-tested draw they skipped nothing.
    fn pass_ending(&self, d: &DeviceState, cb: vk::CommandBuffer) {
        for drawn in self.open.ending(d, ash::vk::Handle::as_raw(cb)) {
            drawn.saves_nothing.store(true, Ordering::Relaxed);
        }
    }
    /// The eye passes behind a post chain that ended in `cb` get their reconstruction now.
    fn pass_ended(&self, d: &DeviceState, cb: vk::CommandBuffer) {
        let Some(jobs) = lock(&self.books).jobs.remove(&ash::vk::Handle::as_raw(cb)) else { return };
        for job in jobs {
            if !super::pass_end_vk::record(d, cb, &job) {
                // The checkerboard stays off (`Link::recorded`): the pass is left whole.
                self.count(|s| s.count_not_applied(NotApplied::TargetUsage));
                log_once(self, "pass end not recorded".into(), || tracing::warn!("radial density masking: the reconstruction could not follow an eye pass (the command buffer holds state the layer cannot restore): such passes are left whole"));
            }
        }
    }
    /// Refreshes idle recordings for the live fovea and settings, then applies what each
    /// submitted recording does, in recording order: its eyes await reconstruction (counted as
    /// this submission's), the app's transfers carry them on.
    fn before_submit(&self, d: &DeviceState, cbs: &[u64]) {
        let settings = d.settings();
        let on = self.injects(&settings);
        for &cb in cbs {
            let idle = !lifetime::in_flight(d, cb);
            lifetime::with_holds(d, cb, |holds| {
                for h in holds {
                    if let Some(drawn) = h.downcast_ref::<Drawn>() {
                        if drawn.saves_nothing.load(Ordering::Relaxed) {
                            if idle {
                                drawn.clear(&mut lock(&drawn.filled));
                                if let Some(link) = &drawn.link {
                                    link.arm(false);
                                }
                            }
                            self.count(|s| *s.not_applied.entry(crate::core::pass::NotMasked::PostPass.name()).or_insert(0) += 1);
                            continue;
                        }
                        // Why a pass awaiting the walk is left whole this submission.
                        let mut not_now = None;
                        if idle && !on {
                            drawn.clear(&mut lock(&drawn.filled));
                        } else if idle {
                            let plan = match &drawn.target {
                                Target::Awaiting { pass, fail_depth, walk, .. } => {
                                    let plan = inject::plan_now(d, pass, *fail_depth, settings.intermediate);
                                    if *walk {
                                        not_now = plan.as_ref().err().map(|why| why.name()).filter(|n| *n != crate::core::pass::NotMasked::NotEyePass.name());
                                    }
                                    plan.ok()
                                }
                                Target::Eyes { .. } => None,
                            };
                            drawn.refresh(self, plan.as_ref());
                            if let (Some(link), Target::Eyes { draws, image, .. }) = (&drawn.link, &drawn.target) {
                                // Behind a post chain the rect may have moved since the recording
                                // (dynamic resolution): no checkerboard where the eye is not.
                                let why = match inject::walk_moved(d, *image, draws) {
                                    Ok(None) => None,
                                    Ok(Some(_)) => Some(crate::core::pass::NotMasked::RectChanging),
                                    Err(why) => Some(why),
                                };
                                if let Some(why) = why {
                                    link.arm(false);
                                    drawn.clear(&mut lock(&drawn.filled));
                                    self.count(|s| *s.not_applied.entry(why.name()).or_insert(0) += 1);
                                }
                            }
                        }
                        let f = lock(&drawn.filled);
                        if f.pending.is_empty() {
                            if let Some(why) = not_now {
                                self.count(|s| *s.not_applied.entry(why).or_insert(0) += 1);
                            }
                            continue;
                        }
                        self.count(|s| {
                            s.passes += 1;
                            for (view, c) in &f.skipped {
                                *s.quads_skipped.entry(*view).or_insert(0) += c.quads_skipped;
                                *s.pixels_skipped.entry(*view).or_insert(0) += c.pixels_skipped;
                            }
                        });
                        if let Some(link) = &drawn.link {
                            // Reconstructed when its pass ended, in the recording itself.
                            self.count(|s| {
                                for p in &f.pending {
                                    *s.reconstructed.entry(p.view).or_insert(0) += 1;
                                }
                                let n = f.pending.len() as u64;
                                if link.is_compute() {
                                    s.compute += n;
                                } else {
                                    *s.fill_fallback.entry(super::rules::FillFallback::PassEnd.name()).or_insert(0) += n;
                                }
                            });
                            continue;
                        }
                        let mut books = lock(&self.books);
                        let list = books.pending.entry(f.image).or_default();
                        for p in &f.pending {
                            list.retain(|x| !(x.layer == p.layer && x.params.rect == p.params.rect));
                            list.push(*p);
                        }
                    } else if let Some(t) = h.downcast_ref::<Transfer>() {
                        on_transfer(self, d, t.src, t.dst, &t.regions);
                    }
                }
            });
        }
    }
    fn before_release(&self, d: &DeviceState, family: u32, queue_index: u32, swapchain: u64, image_index: u32) {
        super::reconstruct::before_release(self, d, family, queue_index, swapchain, image_index);
    }
    fn destroy(&self, d: &DeviceState) {
        lock(&self.books).jobs.clear();
        super::pass_end_vk::destroy(self, d);
        self.reconstruct.destroy(d);
    }
}

pub(super) fn log_once(me: &RdmDevice, key: String, f: impl FnOnce()) {
    if lock(&me.books).logged.insert(key) {
        f();
    }
}

/// The checkerboard pipeline for a pass.
fn pipeline(me: &RdmDevice, d: &DeviceState, pass: &crate::track::cmd::PassInstance, plan: &MaskPlan) -> Result<vk::Pipeline, NotApplied> {
    let pass = pipeline::pass_key(d, pass, plan).ok_or(NotApplied::LayerError)?;
    let key = pipeline::PipelineKey { feature: me.id(), variant: 0, pass };
    pipeline::get(d, &key, || {
        let (stride, attributes) = vertex_layout();
        // A fragment shader that discards kept quads; colour writes stay off.
        pipeline::PipelineDesc { vert: VERT, vert_multiview: VERT_MV, frag: Some(FRAG), stride, attributes, write_first_color: false, per_instance: false, layout: None, depth_compare_op: vk::CompareOp::ALWAYS }
    })
    .map_err(|e| match e {
        pipeline::PipelineError::DeviceLacks => NotApplied::DeviceLacks,
        pipeline::PipelineError::Vulkan(e) => {
            d.warn_repeated("rdm pipeline", &e);
            NotApplied::LayerError
        }
    })
}

/// A recording's buffer: room for a quad per eye of two eyes.
fn drawn(me: &RdmDevice, d: &DeviceState, target: Target) -> Result<Arc<Drawn>, NotApplied> {
    let size = inject::DRAW_ARGS * 2 + 12 * std::mem::size_of::<Vertex>() as u64;
    let buffer = PooledBuffer::take(d, size, &me.memory).map_err(|e| {
        d.warn_repeated("rdm vertex buffer", &e);
        NotApplied::LayerError
    })?;
    Ok(Arc::new(Drawn { buffer, target, filled: Mutex::default(), link: None, saves_nothing: AtomicBool::new(false) }))
}

/// Records the checkerboard depth draw into the open pass (after the mask, before the chassis
/// restores the app's state); what it skips and leaves to reconstruct goes by submission.
/// Before any checkerboard goes into a pass: the reconstruction that will fill its holes at the
/// image's release must be able to run (`reconstruct::ready`). If it cannot, the pass is left
/// whole (counted `layer_error`, logged once) rather than handed to the runtime with holes.
fn reconstruction_ready(me: &RdmDevice, d: &DeviceState, cb: vk::CommandBuffer, s: &Settings) -> Result<(), NotApplied> {
    use crate::features::foveation::Reconstruction;
    if s.of::<FoveationSettings>().rdm_reconstruction == Reconstruction::Off {
        return Ok(());
    }
    let family = d.track.command_buffers.get(ash::vk::Handle::as_raw(cb)).and_then(|c| d.track.pools.get(c.pool)).map(|p| p.queue_family_index);
    let Some(family) = family else { return Ok(()) };
    super::reconstruct::ready(d, family, s.of::<FoveationSettings>().rdm_reconstruction != Reconstruction::Fill).map_err(|(why, e)| {
        log_once(me, format!("not ready {e}"), || tracing::warn!("radial density masking skipped for a pass: its reconstruction could not be prepared ({e})"));
        why
    })
}

/// The reconstruction at `at`'s pass's end, for `eyes` at the fovea and views of `generations`.
fn pass_end_link(me: &RdmDevice, d: &DeviceState, at: &Injection<'_>, eyes: &[(EyeDraw, RdmParams)], generations: (u64, u64)) -> Result<(super::pass_end_vk::Prepared, super::pass_end_vk::Eyes, Arc<super::pass_end_vk::Link>), NotApplied> {
    let plan = at.plan;
    let pending: Vec<Pending> = eyes.iter().map(|(dr, p)| Pending { view: dr.view, layer: dr.layer, params: *p }).collect();
    let mut eyes_at = super::pass_end_vk::Eyes::Recorded(pending);
    let image = super::pass_end::reconstructed_image(at.pass, plan.image).ok_or(NotApplied::PostChain)?;
    let prepared = super::pass_end_vk::prepare(me, d, at.pass, image, &mut eyes_at)?;
    let link = super::pass_end_vk::Link::new(me, d, &prepared, &eyes_at, Some((generations, plan.draws.clone())))?;
    Ok((prepared, eyes_at, link))
}

fn record_draw(me: &RdmDevice, d: &DeviceState, at: &Injection<'_>) -> Result<(), NotApplied> {
    let plan = at.plan;
    let ((fovea_generation, views_generation), eyes) = params_now(&plan.draws)?;
    // Behind a post chain a tonemapper, bloom or TAA reads the target before any release: the
    // holes are filled when the pass ends (`pass_end_vk`), or the pass is left whole. An app's own
    // target copied 1:1 into the swapchain is filled there too where the pass's end can: other
    // readers of it then see it whole (an OpenVR game's desktop mirror draws its eye textures);
    // where it cannot (a multisampled target resolved by the copy), the skipped quads follow the
    // copy and are filled at the release, as before.
    let pass_end = match plan.via {
        Via::Walk | Via::Fallback => Some(pass_end_link(me, d, at, &eyes, (fovea_generation, views_generation)).inspect_err(|why| {
            log_once(me, format!("pass end {}", why.name()), || tracing::info!("radial density masking left an eye pass behind a post chain alone ({:#x}): {}", plan.image, why.name()))
        })?),
        Via::Transfer => match pass_end_link(me, d, at, &eyes, (fovea_generation, views_generation)) {
            Ok(link) => Some(link),
            Err(why) => {
                log_once(me, format!("transfer at release {}", why.name()), || {
                    tracing::info!("radial density masking: eye passes into {:#x}, copied into the swapchain, are reconstructed in the swapchain image at the release ({}: not at the pass's end)", plan.image, why.name())
                });
                reconstruction_ready(me, d, at.cb, at.settings)?;
                None
            }
        },
        Via::Swapchain => {
            reconstruction_ready(me, d, at.cb, at.settings)?;
            None
        }
    };
    let p = pipeline(me, d, at.pass, plan)?;
    let multiview = plan.layout == EyeLayout::Multiview;
    let mut data = drawn(me, d, Target::Eyes { draws: plan.draws.clone(), multiview, image: plan.image })?;
    if let Some((_, _, link)) = &pass_end {
        if let Some(dr) = Arc::get_mut(&mut data) {
            dr.link = Some(link.clone());
        }
    }
    data.refresh(me, None);
    let cb = at.cb;
    let vk_buffer = data.buffer.buffer;
    let viewport = |r: PixelRect| inject::fail_viewport(r, plan.fail_depth);
    let draws: Vec<inject::IndirectDraw> = if multiview {
        let dr = plan.draws[0];
        vec![inject::IndirectDraw { slot: 0, viewport: viewport(dr.viewport), scissor: dr.scissor }]
    } else {
        plan.draws.iter().enumerate().filter(|(_, dr)| dr.scissor.area() > 0).map(|(i, dr)| inject::IndirectDraw { slot: i as u64, viewport: viewport(dr.viewport), scissor: dr.scissor }).collect()
    };
    // SAFETY: `cb` is recording inside the pass the plan was made for; the pipeline is compatible
    // with it; the buffer is held by the app's command buffer (below) until its recording closes
    // and its submissions complete.
    unsafe { inject::record_indirect(d, cb, p, vk_buffer, data.vertex_offset(), &draws) };
    if let Some((prepared, eyes_at, link)) = pass_end {
        let job = super::pass_end_vk::Job::new(prepared, eyes_at, link);
        lock(&me.books).jobs.entry(at.owner).or_default().push(job);
    }
    me.open.opened(d, at.owner, data.clone());
    lifetime::hold(d, at.owner, data);
    let counts: Vec<(u32, SkipCount)> = eyes.iter().map(|(dr, p)| (dr.view, count(me, fovea_generation, views_generation, dr, p))).collect();
    log_once(me, format!("draw {:?} {}", plan.layout, plan.intermediate), || {
        let what: Vec<String> = eyes
            .iter()
            .zip(&counts)
            .map(|((dr, p), (_, c))| {
                let r = p.rect;
                format!("view {} layer {} rect {}x{}+{}+{}: {} of {} quads skipped", dr.view, dr.layer, r.width, r.height, r.x, r.y, c.quads_skipped, c.quads)
            })
            .collect();
        let target = if plan.intermediate { "intermediate image" } else { "swapchain image" };
        tracing::info!("radial density masking {} pass on {target} {:#x}: {}", plan.layout.name(), plan.image, what.join("; "));
    });
    Ok(())
}

/// A pass whose eyes are not known yet: one draw over the render area, empty until a submission
/// finds its eyes.
fn record_awaiting(me: &RdmDevice, d: &DeviceState, at: &Awaiting<'_>) -> Result<(), NotApplied> {
    let area = inject::render_area(at.pass);
    let plan = inject::shape_only(at.pass, at.fail_depth);
    // Only the walk can tie it to its eyes, so a post chain reads its target: the fill at the
    // pass's end reads its eyes from the recording's buffer, filled at each submission.
    let pass_end = if at.walk {
        let image = super::pass_end::first_color_image(at.pass).ok_or(NotApplied::PostChain)?;
        let layers = super::pass_end_vk::pass_layers(d, at.pass, image);
        let mut eyes_at = super::pass_end_vk::Eyes::Submitted { area, layers };
        let prepared = super::pass_end_vk::prepare(me, d, at.pass, image, &mut eyes_at)?;
        let link = super::pass_end_vk::Link::new(me, d, &prepared, &eyes_at, None)?;
        Some((prepared, eyes_at, link))
    } else {
        reconstruction_ready(me, d, at.cb, at.settings)?;
        None
    };
    let p = pipeline(me, d, at.pass, &plan)?;
    let mut data = drawn(me, d, Target::Awaiting { pass: Box::new(at.pass.clone()), fail_depth: at.fail_depth, area, walk: at.walk })?;
    if let Some((_, _, link)) = &pass_end {
        if let Some(dr) = Arc::get_mut(&mut data) {
            dr.link = Some(link.clone());
        }
    }
    data.refresh(me, None);
    let draw = inject::IndirectDraw { slot: 0, viewport: inject::fail_viewport(area, at.fail_depth), scissor: area };
    // SAFETY: `at.cb` is recording inside the pass; the pipeline is compatible with it; the
    // buffer (empty draw arguments until filled) is held by the app's command buffer (below).
    unsafe { inject::record_indirect(d, at.cb, p, data.buffer.buffer, data.vertex_offset(), &[draw]) };
    if let Some((prepared, eyes_at, link)) = pass_end {
        let job = super::pass_end_vk::Job::new(prepared, eyes_at, link);
        lock(&me.books).jobs.entry(at.owner).or_default().push(job);
    }
    me.open.opened(d, at.owner, data.clone());
    lifetime::hold(d, at.owner, data);
    Ok(())
}

fn count(me: &RdmDevice, fovea_gen: u64, views_gen: u64, dr: &EyeDraw, p: &RdmParams) -> SkipCount {
    let k = (fovea_gen, views_gen, dr.view, dr.viewport, dr.scissor);
    if let Some(c) = lock(&me.books).counts.get(&k) {
        return *c;
    }
    let c = p.count(dr.scissor);
    let mut books = lock(&me.books);
    if books.counts.len() > 256 {
        books.counts.clear();
    }
    books.counts.insert(k, c);
    c
}

/// The app transfers `src` into `dst`: eyes of `src` awaiting reconstruction move to `dst` when a
/// region carries them 1:1 into a swapchain image; a scaled region is counted (its skipped quads
/// cannot be reconstructed there).
fn on_transfer(me: &RdmDevice, _d: &DeviceState, src: u64, dst: u64, regions: &[TransferRegion]) {
    if shared().images.get(dst).is_none() {
        return;
    }
    let mut books = lock(&me.books);
    let Some(list) = books.pending.remove(&src) else { return };
    let HandOff { moved, kept, scaled } = hand_off(list, regions);
    if !kept.is_empty() {
        books.pending.insert(src, kept);
    }
    let list = books.pending.entry(dst).or_default();
    for q in moved {
        list.retain(|x| !(x.layer == q.layer && x.params.rect == q.params.rect));
        list.push(q);
    }
    drop(books);
    if scaled > 0 {
        me.count(|s| *s.not_applied.entry(NotApplied::NotOneToOne.name()).or_insert(0) += scaled);
        log_once(me, format!("scaled {src:#x}"), || {
            tracing::warn!(src = format_args!("{src:#x}"), "radial density masking: target is not copied 1:1 into the swapchain image; its skipped quads cannot be reconstructed there")
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shaders_are_embedded_spirv_and_the_vertex_matches_its_layout() {
        for s in [VERT, VERT_MV, FRAG] {
            assert_eq!(&s[..4], &0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
        }
        let (stride, attrs) = vertex_layout();
        assert_eq!(stride, 52);
        assert_eq!(attrs.last().unwrap().offset, std::mem::offset_of!(Vertex, fovea) as u32);
        assert_eq!(attrs[3].offset, std::mem::offset_of!(Vertex, tan) as u32);
        assert_eq!(attrs[2].offset, std::mem::offset_of!(Vertex, origin) as u32);
    }
}
