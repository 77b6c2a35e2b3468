//! The hidden-area mask on the Vulkan side: at the chassis' injection point (an eye pass's depth
//! just cleared) draw the view's hidden triangles at the depth that fails the app's test, so
//! early-Z rejects the app's own fragments there. Geometry comes from `rules`, the eye rects from
//! the chassis' plan; this module only turns them into commands.
//!
//! The draw reads its vertices and its indirect draw arguments from a buffer of the recording's
//! own (`MaskData`), held by the app's command buffer (`plugin::vk::lifetime`). A command buffer recorded
//! once and resubmitted keeps drawing the *current* mask: before each submission whose recording
//! is idle, a buffer filled for an older mask generation is refilled (`before_submit`).

use crate::features::mask::MaskSettings;
use crate::core::pass::NotMasked;
use crate::core::rect::PixelRect;
use crate::core::stats::FeatureStats;
use crate::features::mask::rules::{self, MaskFrameStats};
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::core::views::Views;
use crate::track::cmd::PassInstance;
use crate::track::eye_pass::{EyeDraw, EyeLayout, EyeSource, MaskPlan};
use crate::plugin::vk::feature::{DeviceInit, Plugin, VkFeature};
use crate::plugin::vk::inject::open_passes::OpenPasses;
use crate::plugin::vk::inject::{self, pipeline, Awaiting, Injection};
use crate::plugin::vk::lifetime::{self, PooledBuffer};
use crate::plugin::vk::DeviceState;
use ash::vk;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

static VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask.vert.spv"));
static VERT_MV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask_mv.vert.spv"));
static FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask.frag.spv"));

/// One vertex: NDC position and the view it belongs to.
#[repr(C)]
#[derive(Clone, Copy)]
struct Vertex {
    pos: [f32; 2],
    view: u32,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// One mask generation's geometry, built once per generation.
struct Geometry {
    generation: u64,
    /// view → NDC triangles.
    ndc: BTreeMap<u32, Vec<[f32; 2]>>,
}

impl Geometry {
    fn of(views: &Views) -> Geometry {
        let mut ndc = BTreeMap::new();
        for m in &views.masks {
            let Some(fov) = views.app_fovs.get(m.view as usize) else { continue };
            // In the view the app renders (turned or wider than the runtime's: docs/views.md),
            // with what lies outside the runtime's FOV hidden too.
            let runtime = views.runtime_fovs.get(m.view as usize).unwrap_or(fov);
            let turn = views.runtime_turns.get(m.view as usize).copied().flatten();
            let t = rules::triangles_to_ndc(&crate::core::reframe::in_app_view(&m.triangles, runtime, turn, fov), fov);
            if !t.is_empty() {
                ndc.insert(m.view, t);
            }
        }
        Geometry { generation: views.generation, ndc }
    }
}

/// What a recording's mask draws are for.
enum Target {
    /// A known eye pass: one indirect draw per eye (one in all for multiview), each recorded with
    /// its eye's viewport and scissor.
    /// `walked`: the target was tied to its eyes by the data-flow walk (checked at each
    /// submission, `inject::walk_still_holds`).
    Eyes { draws: Vec<EyeDraw>, multiview: bool, image: u64, walked: bool },
    /// A pass whose eyes were unknown when it was recorded: one indirect draw over the render
    /// area, into which the eyes' geometry is mapped once they are known. `walk`: it awaits the
    /// walk (counted at each submission, applied or not).
    Awaiting { pass: Box<PassInstance>, fail_depth: f32, area: PixelRect, walk: bool },
}

/// A recording's mask data: indirect arguments first, then the vertices.
struct MaskData {
    buffer: PooledBuffer,
    target: Target,
    /// How the pass's target was tied to the eyes (`Via::name`; `stats.file` `mask_by_source`).
    source: &'static str,
    /// What the buffer holds now.
    filled: Mutex<Filled>,
    /// The pass ended without one depth-tested draw (a post pass recorded before the walk knew
    /// it): the mask saved nothing there, so it draws nothing and counts as `post_pass`.
    saves_nothing: AtomicBool,
}

/// The content of a recording's buffer: for which mask generation and eyes, and the pixels each
/// view's draw covers (counted per submission).
#[derive(Default)]
struct Filled {
    key: Option<(u64, Vec<EyeDraw>)>,
    pixels: Vec<(u32, u64)>,
    /// How an awaiting target was tied to its eyes at the last fill (`Via::name`).
    source: Option<&'static str>,
}

/// Maps NDC of `from` (a viewport) into NDC of `to` (another viewport of the same framebuffer).
fn remap(p: [f32; 2], from: PixelRect, to: PixelRect) -> [f32; 2] {
    let px = from.x as f32 + (p[0] + 1.0) * 0.5 * from.width as f32;
    let py = from.y as f32 + (p[1] + 1.0) * 0.5 * from.height as f32;
    [(px - to.x as f32) / to.width as f32 * 2.0 - 1.0, (py - to.y as f32) / to.height as f32 * 2.0 - 1.0]
}

impl MaskData {
    fn draw_slots(&self) -> inject::DrawSlots {
        match &self.target {
            Target::Eyes { draws, multiview, .. } => inject::DrawSlots::for_eyes(draws.len(), *multiview),
            Target::Awaiting { .. } => inject::DrawSlots::AWAITING,
        }
    }
    fn vertex_offset(&self) -> u64 {
        self.draw_slots().vertex_offset()
    }
    fn clear(&self, f: &mut Filled) {
        self.draw_slots().clear(&self.buffer);
        *f = Filled::default();
    }
    /// Makes the buffer hold `g`'s mask for the target's eyes (`plan`: the eyes known now, for an
    /// awaiting target; `moved`: where this submission's walk found a walked target's eyes, when
    /// not where they were recorded), or nothing when `g` lacks a view's mask or it does not fit
    /// (no mask is always correct output). Only called while no submission of the recording
    /// executes.
    fn refresh(&self, me: &MaskDevice, g: &Geometry, plan: Option<&MaskPlan>, moved: Option<&[EyeSource]>) {
        let mut f = lock(&self.filled);
        // Each eye's draw: where its mask belongs (`viewport`) and the viewport the draw was
        // recorded with, into whose NDC the mask is mapped (the recorded scissor still clips).
        let (draws, recorded, multiview, area): (Vec<EyeDraw>, Vec<PixelRect>, bool, bool) = match (&self.target, plan) {
            (Target::Eyes { draws, multiview, .. }, _) => {
                let recorded: Vec<PixelRect> = draws.iter().map(|dr| if *multiview { draws[0].viewport } else { dr.viewport }).collect();
                let mut now = draws.clone();
                if let Some(eyes) = moved {
                    for dr in &mut now {
                        let Some(e) = eyes.iter().find(|e| e.view == dr.view && e.layer == dr.layer) else { return self.clear(&mut f) };
                        dr.viewport = e.rect;
                    }
                }
                (now, recorded, *multiview, false)
            }
            (Target::Awaiting { area, .. }, Some(p)) => (p.draws.clone(), vec![*area; p.draws.len()], p.layout == EyeLayout::Multiview, true),
            (Target::Awaiting { .. }, None) => return self.clear(&mut f),
        };
        let key = (g.generation, draws.clone());
        if f.key.as_ref() == Some(&key) {
            return;
        }
        let buf = &self.buffer;
        let mut vertices = Vec::new();
        let mut args = Vec::new();
        for (dr, to) in draws.iter().zip(&recorded) {
            let Some(t) = g.ndc.get(&dr.view) else { return self.clear(&mut f) };
            args.push(vk::DrawIndirectCommand { vertex_count: t.len() as u32, instance_count: 1, first_vertex: vertices.len() as u32, first_instance: 0 });
            if dr.viewport == *to {
                vertices.extend(t.iter().map(|&pos| Vertex { pos, view: dr.view }));
            } else {
                vertices.extend(t.iter().map(|&p| Vertex { pos: remap(p, dr.viewport, *to), view: dr.view }));
            }
        }
        if (multiview || area) && !args.is_empty() {
            args = vec![vk::DrawIndirectCommand { vertex_count: vertices.len() as u32, instance_count: 1, first_vertex: 0, first_instance: 0 }];
        }
        if args.is_empty() || !buf.write(self.vertex_offset(), &vertices) {
            tracing::debug!("a recorded mask draw does not fit the current mask: drawn empty");
            return self.clear(&mut f);
        }
        buf.write(0, &args);
        // What is drawn: the mask in the eye's rect, clipped by the recorded scissor (and the
        // recorded viewport, which holds the scissor).
        let pixels = draws.iter().map(|dr| (dr.view, me.coverage(g, dr.view, dr.viewport, dr.scissor))).collect();
        *f = Filled { key: Some(key), pixels, source: plan.map(|p| p.via.name()) };
    }
}

#[derive(Default)]
struct Books {
    frame: MaskFrameStats,
    total: MaskFrameStats,
    /// (generation, view, viewport, scissor) → pixels covered.
    coverage: HashMap<(u64, u32, PixelRect, PixelRect), u64>,
    logged_kinds: HashSet<(EyeLayout, bool)>,
    geometry: Option<Arc<Geometry>>,
}

/// The mask's per-device state. Locks guard bookkeeping only, never a call down.
pub(crate) struct MaskDevice {
    /// The master switch at device creation; `mask.*` settings are read live.
    layer_enabled: bool,
    used: AtomicBool,
    memory: vk::PhysicalDeviceMemoryProperties,
    books: Mutex<Books>,
    /// The mask data in each command buffer's open passes (judged when they end).
    open: OpenPasses<Arc<MaskData>>,
}

impl Plugin for MaskDevice {
    fn new(init: &DeviceInit<'_>) -> MaskDevice {
        MaskDevice { layer_enabled: init.settings.enabled, used: AtomicBool::new(false), memory: init.memory, books: Mutex::default(), open: OpenPasses::default() }
    }
    fn empty_stats() -> Box<dyn FeatureStats> {
        Box::new(MaskFrameStats::default())
    }
    fn enabled(s: &Settings, _frame: &crate::core::stats::FrameStats) -> bool {
        s.of::<MaskSettings>().enabled
    }
}

impl MaskDevice {
    fn count(&self, f: impl Fn(&mut MaskFrameStats)) {
        let mut b = lock(&self.books);
        f(&mut b.frame);
        f(&mut b.total);
    }

    /// The current generation's geometry (built once per generation).
    fn geometry(&self) -> Arc<Geometry> {
        let views = shared().views();
        let mut b = lock(&self.books);
        match &b.geometry {
            Some(g) if g.generation == views.generation => g.clone(),
            _ => {
                let g = Arc::new(Geometry::of(&views));
                tracing::info!(generation = views.generation, views = g.ndc.len(), vertices = g.ndc.values().map(Vec::len).sum::<usize>(), "mask geometry built");
                b.geometry = Some(g.clone());
                g
            }
        }
    }

    fn coverage(&self, g: &Geometry, view: u32, viewport: PixelRect, scissor: PixelRect) -> u64 {
        let k = (g.generation, view, viewport, scissor);
        if let Some(n) = lock(&self.books).coverage.get(&k) {
            return *n;
        }
        let n = g.ndc.get(&view).map_or(0, |t| rules::coverage(t, viewport.viewport(), scissor));
        let mut books = lock(&self.books);
        if books.coverage.len() > 256 {
            books.coverage.clear();
        }
        books.coverage.insert(k, n);
        n
    }

    /// The mask pipeline for a pass (made once per pass compatibility).
    fn pipeline(&self, d: &DeviceState, pass: &PassInstance, plan: &MaskPlan, debug: bool) -> Result<vk::Pipeline, NotMasked> {
        let pass = pipeline::pass_key(d, pass, plan).ok_or(NotMasked::Unsupported)?;
        let key = pipeline::PipelineKey { feature: self.id(), variant: debug as u32, pass };
        pipeline::get(d, &key, || pipeline::PipelineDesc {
            vert: VERT,
            vert_multiview: VERT_MV,
            // Without the debug tint the draw is depth-only: no fragment shader at all.
            frag: debug.then_some(FRAG),
            stride: std::mem::size_of::<Vertex>() as u32,
            attributes: vec![
                vk::VertexInputAttributeDescription { location: 0, binding: 0, format: vk::Format::R32G32_SFLOAT, offset: 0 },
                vk::VertexInputAttributeDescription { location: 1, binding: 0, format: vk::Format::R32_UINT, offset: 8 },
            ],
            write_first_color: debug,
            per_instance: false,
            layout: None,
            depth_compare_op: vk::CompareOp::ALWAYS,
        })
        .map_err(|e| match e {
            pipeline::PipelineError::DeviceLacks => NotMasked::DeviceLacks,
            pipeline::PipelineError::Vulkan(e) => {
                d.warn_repeated("mask pipeline", &e);
                NotMasked::LayerError
            }
        })
    }

    /// A recording's buffer, with room for masks up to twice the current one's size (a changed
    /// mask usually fits when refilled).
    fn data(&self, d: &DeviceState, g: &Geometry, target: Target, source: &'static str) -> Result<Arc<MaskData>, NotMasked> {
        let vertices: usize = g.ndc.values().map(Vec::len).sum();
        let size = inject::DRAW_ARGS * 4 + 2 * (vertices * std::mem::size_of::<Vertex>()) as u64;
        let buffer = PooledBuffer::take(d, size, &self.memory).map_err(|e| {
            d.warn_repeated("mask buffer", &e);
            NotMasked::LayerError
        })?;
        Ok(Arc::new(MaskData { buffer, target, source, filled: Mutex::default(), saves_nothing: AtomicBool::new(false) }))
    }

    /// Records the mask draw(s) of a known eye pass; returns the pixels they cover per view.
    fn record(&self, d: &DeviceState, at: &Injection<'_>) -> Result<Vec<(u32, u64)>, NotMasked> {
        let plan = at.plan;
        let g = self.geometry();
        if g.ndc.is_empty() || plan.draws.iter().any(|dr| !g.ndc.contains_key(&dr.view)) {
            return Err(NotMasked::NoMask);
        }
        let p = self.pipeline(d, at.pass, plan, at.settings.of::<MaskSettings>().debug)?;
        let multiview = plan.layout == EyeLayout::Multiview;
        let draws: Vec<EyeDraw> = if multiview { plan.draws.clone() } else { plan.draws.iter().filter(|dr| dr.scissor.area() > 0).copied().collect() };
        let recorded: Vec<EyeDraw> = if multiview { draws.iter().take(1).copied().collect() } else { draws.clone() };
        let walked = plan.via == crate::track::eye_pass::Via::Walk;
        let data = self.data(d, &g, Target::Eyes { draws, multiview, image: plan.image, walked }, plan.via.name())?;
        data.refresh(self, &g, None, None);
        let draws: Vec<inject::IndirectDraw> =
            recorded.iter().enumerate().map(|(i, dr)| inject::IndirectDraw { slot: i as u64, viewport: inject::fail_viewport(dr.viewport, plan.fail_depth), scissor: dr.scissor }).collect();
        // SAFETY: `at.cb` is recording inside the pass the plan was made for (the chassis just
        // recorded its begin / clear); the pipeline is compatible with it; the buffer is held by
        // the app's command buffer (below) until its recording is closed and its submissions
        // completed.
        unsafe { inject::record_indirect(d, at.cb, p, data.buffer.buffer, data.vertex_offset(), &draws) };
        let pixels = plan.draws.iter().map(|dr| (dr.view, self.coverage(&g, dr.view, dr.viewport, dr.scissor))).collect();
        self.open.opened(d, at.owner, data.clone());
        lifetime::hold(d, at.owner, data);
        Ok(pixels)
    }

    fn log_kind_once(&self, plan: &MaskPlan, pixels: &[(u32, u64)]) {
        if !lock(&self.books).logged_kinds.insert((plan.layout, plan.intermediate)) {
            return;
        }
        let target = if plan.intermediate { "intermediate image" } else { "swapchain image" };
        let eyes: Vec<String> = plan
            .draws
            .iter()
            .map(|dr| {
                let r = dr.viewport;
                let px = pixels.iter().find(|p| p.0 == dr.view).map_or(0, |p| p.1);
                format!("view {}, rect {}x{}+{}+{} ({px} pixels masked)", dr.view, r.width, r.height, r.x, r.y)
            })
            .collect();
        tracing::info!("masking {} pass on {target} {:#x}: {}; mask depth {}", plan.layout.name(), plan.image, eyes.join("; "), plan.fail_depth);
    }
}

impl VkFeature for MaskDevice {
    fn id(&self) -> &'static str {
        "mask"
    }
    fn take_frame(&self) -> Box<dyn FeatureStats> {
        Box::new(std::mem::take(&mut lock(&self.books).frame))
    }
    fn summary(&self) -> Option<String> {
        self.used.load(Ordering::Relaxed).then(|| lock(&self.books).total.summary())
    }
    fn injects(&self, s: &Settings) -> bool {
        let on = self.layer_enabled && s.of::<MaskSettings>().enabled;
        if on {
            self.used.store(true, Ordering::Relaxed);
        }
        on
    }
    /// Draws and counts go by submission (`before_submit`): a command buffer recorded once and
    /// resubmitted is masked and counted every time.
    fn inject(&self, d: &DeviceState, at: &Injection<'_>) {
        match self.record(d, at) {
            Ok(pixels) => self.log_kind_once(at.plan, &pixels),
            Err(why) => {
                if at.counts {
                    self.count(|s| s.count_not_masked(why));
                    if why != NotMasked::NotEyePass {
                        tracing::debug!("pass not masked: {}", why.name());
                    }
                }
            }
        }
    }
    fn not_injected(&self, _d: &DeviceState, _s: &Settings, why: NotMasked) {
        self.count(|s| s.count_not_masked(why));
    }
    fn recordings_closed(&self, _d: &DeviceState, cbs: &[u64]) {
        self.open.closed(cbs);
    }
    /// A pass the mask went into ends: without one depth-tested draw in it, the mask saved
    /// nothing (a post pass with a depth attachment, recorded before the walk knew it).
    fn pass_ending(&self, d: &DeviceState, cb: vk::CommandBuffer) {
        for data in self.open.ending(d, vk::Handle::as_raw(cb)) {
            data.saves_nothing.store(true, Ordering::Relaxed);
        }
    }
    /// A pass whose eyes are not known yet: one draw over the render area, empty until a
    /// submission finds its eyes.
    fn inject_awaiting(&self, d: &DeviceState, at: &Awaiting<'_>) {
        let g = self.geometry();
        if g.ndc.is_empty() {
            return;
        }
        let area = inject::render_area(at.pass);
        // Any plan with this pass's shape makes the same pipeline (render pass + subpass or
        // formats; multiview from the pass itself).
        let plan = inject::shape_only(at.pass, at.fail_depth);
        let Ok(p) = self.pipeline(d, at.pass, &plan, at.settings.of::<MaskSettings>().debug) else { return };
        let Ok(data) = self.data(d, &g, Target::Awaiting { pass: Box::new(at.pass.clone()), fail_depth: at.fail_depth, area, walk: at.walk }, "swapchain") else { return };
        data.refresh(self, &g, None, None);
        let draw = inject::IndirectDraw { slot: 0, viewport: inject::fail_viewport(area, at.fail_depth), scissor: area };
        // SAFETY: `at.cb` is recording inside the pass (the chassis just recorded its begin /
        // clear); the pipeline is compatible with it; the buffer (empty draw arguments until
        // filled) is held by the app's command buffer (below).
        unsafe { inject::record_indirect(d, at.cb, p, data.buffer.buffer, data.vertex_offset(), &[draw]) };
        self.open.opened(d, at.owner, data.clone());
        lifetime::hold(d, at.owner, data);
    }
    /// Refreshes idle recordings for the live mask and settings, then counts what each submitted
    /// recording draws.
    fn before_submit(&self, d: &DeviceState, cbs: &[u64]) {
        let settings = d.settings();
        let on = self.layer_enabled && settings.of::<MaskSettings>().enabled;
        let mut g: Option<Arc<Geometry>> = None;
        for &cb in cbs {
            let idle = !lifetime::in_flight(d, cb);
            lifetime::with_holds(d, cb, |holds| {
                for h in holds {
                    let Some(data) = h.downcast_ref::<MaskData>() else { continue };
                    // Why a recording awaiting the walk draws nothing this submission.
                    let mut not_now = None;
                    if idle {
                        if !on {
                            data.clear(&mut lock(&data.filled));
                        } else {
                            let g = g.get_or_insert_with(|| self.geometry());
                            let plan = match &data.target {
                                Target::Awaiting { pass, fail_depth, walk, .. } => {
                                    let plan = inject::plan_now(d, pass, *fail_depth, settings.intermediate);
                                    if *walk {
                                        not_now = plan.as_ref().err().copied();
                                    }
                                    plan.ok()
                                }
                                Target::Eyes { .. } => None,
                            };
                            let moved = match &data.target {
                                Target::Eyes { draws, image, walked: true, .. } => inject::walk_moved(d, *image, draws),
                                _ => Ok(None),
                            };
                            match moved {
                                Ok(moved) => data.refresh(self, g, plan.as_ref(), moved.as_deref()),
                                Err(why) => {
                                    // The eye rect changes from frame to frame and this
                                    // submission's walk did not confirm it, or the target is
                                    // shared by the eyes: no mask beats one beside the eye.
                                    data.clear(&mut lock(&data.filled));
                                    not_now = Some(why);
                                }
                            }
                            // A pass that awaited its eyes, filled now (the walk tied it to its
                            // eye at this submission): said once per kind, as recorded masks are.
                            if let Some(p) = &plan {
                                let px = lock(&data.filled).pixels.clone();
                                if !px.is_empty() {
                                    self.log_kind_once(p, &px);
                                }
                            }
                        }
                    }
                    if data.saves_nothing.load(Ordering::Relaxed) {
                        if idle {
                            data.clear(&mut lock(&data.filled));
                        }
                        self.count(|s| s.count_not_masked(NotMasked::PostPass));
                        continue;
                    }
                    let (pixels, source) = {
                        let f = lock(&data.filled);
                        (f.pixels.clone(), f.source.unwrap_or(data.source))
                    };
                    if !pixels.is_empty() {
                        self.count(|s| {
                            s.passes_masked += 1;
                            *s.by_source.entry(source).or_insert(0) += 1;
                            for (view, px) in &pixels {
                                *s.pixels_masked.entry(*view).or_insert(0) += px;
                            }
                        });
                    } else if let Some(why) = not_now {
                        self.count(|s| s.count_not_masked(why));
                    }
                }
            });
        }
    }
    fn fills_at_submission(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shaders_are_embedded_spirv() {
        for s in [VERT, VERT_MV, FRAG] {
            assert_eq!(&s[..4], &0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
        }
        assert_eq!(std::mem::size_of::<Vertex>(), 12);
        assert_eq!(inject::DRAW_ARGS, 16);
    }
}
