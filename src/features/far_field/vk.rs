//! The far field on the Vulkan side. At the end of an eye pass whose view may be a source, the
//! layer copies the view's colour and depth into a *slot* of its own (one per view). In a
//! destination view's pass, in front of its first depth-tested draw (`injects_before_depth_test`),
//! it draws one grid of 16×16-pixel tiles per view that writes the slot's far pixels at the split
//! plane's depth (`shaders/far_field.*`); tiles whose source holds nothing far are culled in the
//! vertex shader, from the depth ranges reduced with the copy (`super::compute`). Which slot, frame and pose each draw uses is decided at
//! every submission (`before_submit`, `rules::check_source`) and written into the recording's own
//! buffer, so command buffers recorded once follow the head and the alternation.
//!
//! Slots stay in the GENERAL layout for their whole life (set once by a one-time submission ahead
//! of the first app submission that uses them); copies and reads are ordered by barriers the
//! layer records next to them. The app's images go to TRANSFER_SRC for the copy and back to the
//! layout the pass left them in.

use crate::features::far_field::FarFieldSettings;
use super::count::Counter;
use super::compute::Copier;
use super::copy::{attachments, make_slots, AwaitPass, CopyOp, PendingCopy, Slots, NOT_REDUCED};
use super::rules::{self, InverseDepth, Stamp};
use super::stats::FarFieldStats;
use crate::core::rect::PixelRect;
use crate::core::stats::FeatureStats;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::core::views::{FarFieldViews, ViewPose};
use crate::track::cmd::{AttachmentUse, PassInstance};
use crate::track::eye_pass::{EyeDraw, EyeLayout};
use crate::plugin::vk::feature::{DeviceInit, Plugin, VkFeature};
use crate::plugin::vk::inject::{self, pipeline, Injection};
use crate::plugin::vk::lifetime::{self, PooledBuffer};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

static VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/far_field.vert.spv"));
static VERT_MV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/far_field_mv.vert.spv"));
static FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/far_field.frag.spv"));
static FRAG_MSAA: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/far_field_msaa.frag.spv"));

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

mod reuse;
use reuse::Instance;

const INSTANCE: u64 = std::mem::size_of::<Instance>() as u64;

/// A recording's reuse draw(s): one indirect draw per destination view, arguments and instance
/// data in `buffer`.
struct ReuseOp {
    /// The pass's depth convention (its pipeline's compare op).
    reversed: bool,
    buffer: PooledBuffer,
    slots: Arc<Slots>,
    views: Vec<ReuseView>,
    multiview: bool,
    awaiting: Option<Arc<AwaitPass>>,
    /// Counts the reused pixels (None where the layer could not make its queries).
    counter: Option<Arc<Counter>>,
    /// The pass's target and eyes, when the data-flow walk tied it to them: a rect that moved
    /// since the recording (dynamic resolution) reuses nothing (`inject::walk_moved`).
    walked: Option<(u64, Vec<EyeDraw>)>,
}

#[derive(Clone, Copy, Debug)]
struct ReuseView {
    view: u32,
    /// Which slot the draw reads (decided at recording: `rules::slot_to_read`).
    slot: u32,
    /// The view's pixels in the destination image, and its layer.
    rect: PixelRect,
    layer: u32,
}

/// Where a pass's reuse draws and copies go: a known eye pass, or one awaiting its eyes with
/// guessed draws.
struct Target<'a> {
    cb: vk::CommandBuffer,
    owner: u64,
    pass: &'a PassInstance,
    /// The plan the pipeline is made for (its shape for an awaiting pass).
    plan: &'a crate::track::eye_pass::MaskPlan,
    draws: Vec<EyeDraw>,
    settings: &'a Settings,
    bound_sets: &'a std::cell::Cell<bool>,
    awaiting: Option<Arc<AwaitPass>>,
}

#[derive(Default)]
struct Objects {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    linear: vk::Sampler,
    nearest: vk::Sampler,
    /// The compute copy (None where it could not be made: single-sampled passes are then not
    /// applied, `layer_error`).
    copier: Option<Copier>,
    slots: Option<Arc<Slots>>,
    /// The slots' one-time layout set-up, recorded when they were made in a command buffer of
    /// this queue family, until a submission there takes it (`queue_submitting`).
    slots_init: Option<(u32, vk::CommandBuffer)>,
}

/// The layouts and samplers `objects` has made so far: destroyed if it returns before all are
/// made (null handles are ignored by vkDestroy*).
struct Made<'a> {
    d: &'a DeviceState,
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    linear: vk::Sampler,
    nearest: vk::Sampler,
}

impl Drop for Made<'_> {
    fn drop(&mut self) {
        let f = &self.d.fns;
        // SAFETY: our objects, not yet published nor used by anything.
        unsafe {
            f.destroy_sampler(self.nearest, None);
            f.destroy_sampler(self.linear, None);
            f.destroy_pipeline_layout(self.layout, None);
            f.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

#[derive(Default)]
struct Books {
    frame: FarFieldStats,
    total: FarFieldStats,
    pending: HashMap<u64, PendingCopy>,
    logged: HashSet<&'static str>,
    /// (frame, views that reused pixels in it so far): a copy of such a view is not a source.
    reused: (u64, [bool; 2]),
    /// Counters whose results are copied out when their pass ends in a command buffer.
    readbacks: HashMap<u64, Vec<Arc<Counter>>>,
    /// The resets of query pools made since the last submission, recorded in command buffers
    /// of a queue family (`count::Counter::new`): submitted ahead of the next submission there.
    pending_resets: Vec<(u32, vk::CommandBuffer)>,
    /// The reused-pixel total at the last `take_frame`.
    pixels_taken: u64,
    /// The slots' layout set-up handed to a submission (`queue_submitting`), until it is known
    /// whether that submission went down.
    slots_init_taken: Option<(vk::CommandBuffer, Arc<Slots>)>,
}

/// The far field's per-device state. Locks guard bookkeeping only, never a call down.
pub(crate) struct FarFieldDevice {
    /// Reused pixels counted so far (occlusion queries, collected after completion).
    pixels_reused: Arc<std::sync::atomic::AtomicU64>,
    query_pools: super::count::FreePools,
    layer_enabled: bool,
    used: AtomicBool,
    memory: vk::PhysicalDeviceMemoryProperties,
    books: Mutex<Books>,
    objects: Mutex<Objects>,
}

impl Plugin for FarFieldDevice {
    fn new(init: &DeviceInit<'_>) -> FarFieldDevice {
        FarFieldDevice { pixels_reused: Arc::default(), query_pools: Arc::default(), layer_enabled: init.settings.enabled, used: AtomicBool::new(false), memory: init.memory, books: Mutex::default(), objects: Mutex::default() }
    }
    fn empty_stats() -> Box<dyn FeatureStats> {
        Box::new(FarFieldStats::default())
    }
    fn enabled(s: &Settings, _frame: &crate::core::stats::FrameStats) -> bool {
        s.of::<FarFieldSettings>().enabled
    }
}

/// The pose of `view` located for `frame`, if the layer still has it.
fn pose_of(v: &FarFieldViews, frame: u64, view: u32) -> Option<ViewPose> {
    [&v.current, &v.previous].into_iter().flatten().find(|(f, _)| *f == frame).and_then(|(_, views)| views.get(view as usize).copied())
}

impl FarFieldDevice {
    fn count(&self, f: impl Fn(&mut FarFieldStats)) {
        let mut b = lock(&self.books);
        f(&mut b.frame);
        f(&mut b.total);
    }

    /// Says once which source the depth range came from (the app's depth info, the config, or
    /// the engine's documented default).
    fn log_range_source(&self, source: rules::RangeSource) {
        let key = match source {
            rules::RangeSource::DepthInfo => "range:depth_info",
            rules::RangeSource::Config => "range:config",
            rules::RangeSource::Engine(_) => "range:engine",
        };
        if lock(&self.books).logged.insert(key) {
            match source {
                rules::RangeSource::DepthInfo => tracing::info!("far field depth range: from the app's XrCompositionLayerDepthInfoKHR"),
                rules::RangeSource::Config => tracing::info!("far field depth range: from far_field.near_z / far_z"),
                rules::RangeSource::Engine(e) => tracing::info!("far field depth range: the engine's documented default, {e} (the app submits no depth info; far_field.near_z / far_z override it)"),
            }
        }
    }

    fn not_applied(&self, why: &'static str) {
        let first = {
            let mut b = lock(&self.books);
            b.frame.count_not_applied(why);
            b.total.count_not_applied(why);
            b.logged.insert(why)
        };
        if first {
            tracing::warn!("far field not applied to an eye pass: {why}: {} (logged once per reason)", FarFieldStats::default().hint(why));
        }
    }

    /// The descriptor set layout, pipeline layout and samplers (made once per device).
    fn objects(&self, d: &DeviceState) -> Result<(vk::DescriptorSetLayout, vk::PipelineLayout, vk::Sampler, vk::Sampler), String> {
        let made = {
            let o = lock(&self.objects);
            (o.layout != vk::PipelineLayout::null()).then_some((o.set_layout, o.layout, o.linear, o.nearest))
        };
        if let Some(made) = made {
            return Ok(made);
        }
        let mut bindings: Vec<_> = (0..4)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::FRAGMENT)
            })
            .collect();
        bindings.push(
            vk::DescriptorSetLayoutBinding::default()
                .binding(4)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::VERTEX),
        );
        let sampler = |filter: vk::Filter| {
            vk::SamplerCreateInfo::default()
                .mag_filter(filter)
                .min_filter(filter)
                .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .max_lod(0.0)
        };
        // Made with no lock held: the calls go down the chain, and what is below may call back into
        // the layer. A thread that loses the race to another destroys its own below.
        // SAFETY: valid create infos; the objects are ours until `destroy`.
        let (set_layout, layout, linear, nearest, copier) = unsafe {
            // What was made before a creation fails is destroyed again (issue 11: a failed sampler
            // leaked the layouts until the device went, which validation reports there).
            let mut made = Made { d, set_layout: vk::DescriptorSetLayout::null(), layout: vk::PipelineLayout::null(), linear: vk::Sampler::null(), nearest: vk::Sampler::null() };
            made.set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(|e| e.to_string())?;
            let layouts = [made.set_layout];
            made.layout = d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts), None).map_err(|e| e.to_string())?;
            made.linear = d.fns.create_sampler(&sampler(vk::Filter::LINEAR), None).map_err(|e| e.to_string())?;
            made.nearest = d.fns.create_sampler(&sampler(vk::Filter::NEAREST), None).map_err(|e| e.to_string())?;
            let (set_layout, layout, linear, nearest) = (made.set_layout, made.layout, made.linear, made.nearest);
            // All made: the guard lets go of them.
            std::mem::forget(made);
            let copier = match Copier::new(d, nearest, self.memory) {
                Ok(c) => Some(c),
                Err(e) => {
                    tracing::warn!("far field: no compute copy ({e}): single-sampled passes are not applied");
                    None
                }
            };
            (set_layout, layout, linear, nearest, copier)
        };
        let mut o = lock(&self.objects);
        if o.layout != vk::PipelineLayout::null() {
            let existing = (o.set_layout, o.layout, o.linear, o.nearest);
            drop(o);
            // SAFETY: ours, never used.
            unsafe {
                if let Some(c) = &copier {
                    c.destroy(d);
                }
                drop(Made { d, set_layout, layout, linear, nearest });
            }
            return Ok(existing);
        }
        *o = Objects { set_layout, layout, linear, nearest, copier, slots: o.slots.take(), slots_init: o.slots_init.take() };
        Ok((set_layout, layout, linear, nearest))
    }

    /// The slots, made (again) when they are missing, too small or of other formats, for a pass
    /// recorded in a command buffer of queue family `family`. Their layout set-up is recorded
    /// here too, not when it is submitted: the app's command buffer is about to copy into them,
    /// and a set-up that could not be made at submission would leave that copy writing images in
    /// an undefined layout (issue 11, tests/hardening/faults_vk.rs). Failing now, the pass goes without.
    fn slots(&self, d: &DeviceState, family: Option<u32>, extent: vk::Extent2D, color_format: vk::Format, depth_format: vk::Format, samples: vk::SampleCountFlags) -> Result<Arc<Slots>, String> {
        if let Some(s) = &lock(&self.objects).slots {
            if s.color_format == color_format && s.depth_format == depth_format && s.samples == samples && s.extent.width >= extent.width && s.extent.height >= extent.height {
                return Ok(s.clone());
            }
        }
        let (set_layout, _, linear, nearest) = self.objects(d)?;
        let family = family.ok_or("the command buffer's queue family is unknown: the slots' layouts cannot be set up")?;
        let slots = Arc::new(make_slots(d, &self.memory, extent, (color_format, depth_format, samples), set_layout, linear, nearest)?);
        // On failure the new slots are dropped, which hands their objects to the trash.
        let init = crate::plugin::vk::secondary::prepare_once(d, family, |cb| record_slot_init(d, cb, &slots)).map_err(|e| format!("slot layouts: {e}"))?;
        tracing::info!(width = extent.width, height = extent.height, ?color_format, ?depth_format, samples = samples.as_raw(), "far field source slots created");
        let mut o = lock(&self.objects);
        o.slots = Some(slots.clone());
        o.slots_init = Some((family, init));
        Ok(slots)
    }

    fn pipeline(&self, d: &DeviceState, t: &Target<'_>, reversed: bool, debug: bool, msaa: bool) -> Result<vk::Pipeline, &'static str> {
        let pass = pipeline::pass_key(d, t.pass, t.plan).ok_or("unsupported")?;
        let (_, layout, _, _) = self.objects(d).map_err(|e| {
            d.warn_repeated("far field objects", &e);
            "layer_error"
        })?;
        let key = pipeline::PipelineKey { feature: self.id(), variant: debug as u32 | (reversed as u32) << 1 | (msaa as u32) << 2, pass };
        let attr = |location: u32, format: vk::Format, offset: u32| vk::VertexInputAttributeDescription { location, binding: 0, format, offset };
        let f4 = vk::Format::R32G32B32A32_SFLOAT;
        pipeline::get(d, &key, || pipeline::PipelineDesc {
            vert: VERT,
            vert_multiview: VERT_MV,
            frag: Some(if msaa { FRAG_MSAA } else { FRAG }),
            stride: INSTANCE as u32,
            attributes: vec![
                attr(0, f4, 0),
                attr(1, f4, 16),
                attr(2, f4, 32),
                attr(3, f4, 48),
                attr(4, f4, 64),
                attr(5, f4, 80),
                attr(6, vk::Format::R32G32B32A32_UINT, 96),
                attr(7, f4, 112),
                attr(8, vk::Format::R32G32B32A32_UINT, 128),
                attr(9, f4, 144),
            ],
            write_first_color: true,
            per_instance: true,
            layout: Some(layout),
            // Only where nothing nearer than the split was drawn yet (the mask's depth included).
            depth_compare_op: if reversed { vk::CompareOp::GREATER } else { vk::CompareOp::LESS },
        })
        .map_err(|e| match e {
            pipeline::PipelineError::DeviceLacks => "device_lacks",
            pipeline::PipelineError::Vulkan(e) => {
                d.warn_repeated("far field pipeline", &e);
                "layer_error"
            }
        })
    }

    /// Records the reuse draws of an eye pass and notes its copy for the pass's end.
    fn record(&self, d: &DeviceState, at: Target<'_>) -> Result<(), &'static str> {
        let s = &at.settings.of::<FarFieldSettings>();
        // The depth convention from the clear (the depth range itself is only needed at
        // submission, when a pass recorded before the app's first frame end has it too).
        let reversed = at.plan.fail_depth == 1.0;
        if at.pass.rendering.as_ref().is_some_and(|r| r.suspending()) {
            return Err("unsupported");
        }
        let (color, depth, color_info, depth_info) = attachments(d, at.pass)?;
        let multiview = at.plan.layout == EyeLayout::Multiview;
        let draws: Vec<EyeDraw> = at.draws.iter().filter(|dr| dr.view < 2 && dr.viewport.area() > 0).copied().collect();
        let extent = draws.iter().fold(vk::Extent2D::default(), |e, dr| vk::Extent2D { width: e.width.max(dr.viewport.width), height: e.height.max(dr.viewport.height) });
        let samples = color_info.1;
        let family = d.track.command_buffers.get(at.cb.as_raw()).and_then(|c| d.track.pools.get(c.pool)).map(|p| p.queue_family_index);
        let slots = self.slots(d, family, extent, color_info.0, depth_info.0, samples).map_err(|e| {
            d.warn_repeated("far field slots", &e);
            "layer_error"
        })?;
        let dests: Vec<EyeDraw> = draws.iter().filter(|dr| s.alternate || dr.view != s.source_view).copied().collect();
        if !dests.is_empty() {
            let mut copied = [false; 2];
            lifetime::with_holds(d, at.owner, |holds| {
                for c in holds.iter().filter_map(|h| h.downcast_ref::<CopyOp>()) {
                    copied[c.view as usize] = true;
                }
            });
            let reuse: Vec<ReuseView> = dests
                .iter()
                .map(|dr| ReuseView { view: dr.view, slot: rules::slot_to_read(dr.view, copied[1 - dr.view as usize], s.source, s.source_view, s.alternate), rect: dr.viewport, layer: dr.layer })
                .collect();
            let p = self.pipeline(d, &at, reversed, s.debug, samples != vk::SampleCountFlags::TYPE_1)?;
            let n = reuse.len() as u64;
            let buffer = PooledBuffer::take(d, inject::DRAW_ARGS * n + INSTANCE * n, &self.memory).map_err(|e| {
                d.warn_repeated("far field buffer", &e);
                "layer_error"
            })?;
            // Nothing is drawn until a submission finds a fresh source.
            buffer.write(0, &vec![vk::DrawIndirectCommand::default(); n as usize]);
            let recorded_count = if multiview { 1 } else { dests.len() };
            // In a multiview pass one query takes as many consecutive indices as the pass has views.
            let queries = if multiview { at.pass.view_mask().count_ones().max(1) } else { recorded_count as u32 };
            let family = d.track.command_buffers.get(at.cb.as_raw()).and_then(|c| d.track.pools.get(c.pool)).map(|p| p.queue_family_index);
            let counter = match Counter::new(d, &self.memory, queries, samples.as_raw(), self.pixels_reused.clone(), &self.query_pools, family) {
                Ok((c, reset)) => {
                    lock(&self.books).pending_resets.extend(reset);
                    Some(Arc::new(c))
                }
                Err(e) => {
                    d.warn_repeated("far field: reused pixels are not counted for a pass", &e);
                    None
                }
            };
            let walked = (at.plan.via == crate::track::eye_pass::Via::Walk && at.awaiting.is_none()).then(|| (at.plan.image, at.draws.clone()));
            let op = Arc::new(ReuseOp { reversed, buffer, slots: slots.clone(), views: reuse, multiview, awaiting: at.awaiting.clone(), counter, walked });
            let (_, layout, _, _) = self.objects(d).map_err(|_| "layer_error")?;
            let fns = d.fns.fp_v1_0();
            let recorded = if multiview { &dests[..1] } else { &dests[..] };
            // SAFETY: `at.cb` is the app's command buffer inside the pass the plan was made for,
            // in front of its first depth-tested draw; the pipeline is compatible with the pass;
            // the descriptor set, buffer and slots are held by the recording (`lifetime::hold`)
            // until its submissions completed. The chassis restores the app's state afterwards
            // (`bound_sets` asks for its descriptor sets too).
            unsafe {
                (fns.cmd_bind_pipeline)(at.cb, vk::PipelineBindPoint::GRAPHICS, p);
                (fns.cmd_bind_descriptor_sets)(at.cb, vk::PipelineBindPoint::GRAPHICS, layout, 0, 1, &slots.set, 0, std::ptr::null());
                (fns.cmd_bind_vertex_buffers)(at.cb, 0, 1, &op.buffer.buffer, &(inject::DRAW_ARGS * n));
                for (i, dr) in recorded.iter().enumerate() {
                    let r = dr.viewport;
                    let viewport = vk::Viewport { x: r.x as f32, y: r.y as f32, width: r.width as f32, height: r.height as f32, min_depth: 0.0, max_depth: 1.0 };
                    (fns.cmd_set_viewport)(at.cb, 0, 1, &viewport);
                    (fns.cmd_set_scissor)(at.cb, 0, 1, &inject::rect2d(dr.scissor));
                    // Multiview: one query spans the pass's views (consecutive indices).
                    if let Some(c) = &op.counter {
                        (fns.cmd_begin_query)(at.cb, c.pool, i as u32, vk::QueryControlFlags::empty());
                    }
                    (fns.cmd_draw_indirect)(at.cb, op.buffer.buffer, inject::DRAW_ARGS * i as u64, 1, inject::DRAW_ARGS as u32);
                    if let Some(c) = &op.counter {
                        (fns.cmd_end_query)(at.cb, c.pool, i as u32);
                    }
                }
            }
            if let Some(c) = &op.counter {
                lock(&self.books).readbacks.entry(at.owner).or_default().push(c.clone());
            }
            at.bound_sets.set(true);
            lifetime::hold(d, at.owner, op);
        }
        let walked = (at.plan.via == crate::track::eye_pass::Via::Walk && at.awaiting.is_none()).then_some(at.plan.image);
        let pending = PendingCopy { slots, color, depth, draws, multiview, awaiting: at.awaiting, walked };
        lock(&self.books).pending.insert(at.owner, pending);
        Ok(())
    }

    fn mark_reused(&self, frame: u64, view: u32) {
        let mut b = lock(&self.books);
        if b.reused.0 != frame {
            b.reused = (frame, [false; 2]);
        }
        b.reused.1[view as usize & 1] = true;
    }

    fn reused_in(&self, frame: u64, view: u32) -> bool {
        let b = lock(&self.books);
        b.reused.0 == frame && b.reused.1[view as usize & 1]
    }
}

impl VkFeature for FarFieldDevice {
    fn id(&self) -> &'static str {
        "far_field"
    }
    /// Reused pixels are counted as their submissions complete: a frame's count is what
    /// completed since the last frame end (frames in flight shift it by a frame or two; totals are
    /// exact).
    fn take_frame(&self) -> Box<dyn FeatureStats> {
        let now = self.pixels_reused.load(Ordering::Relaxed);
        let mut b = lock(&self.books);
        let pixels = now - std::mem::replace(&mut b.pixels_taken, now);
        b.frame.pixels_reused += pixels;
        b.total.pixels_reused += pixels;
        Box::new(std::mem::take(&mut b.frame))
    }
    fn summary(&self) -> Option<String> {
        self.used.load(Ordering::Relaxed).then(|| {
            let mut total = lock(&self.books).total.clone();
            total.pixels_reused = self.pixels_reused.load(Ordering::Relaxed);
            total.summary()
        })
    }
    fn injects(&self, s: &Settings) -> bool {
        let on = self.layer_enabled && s.of::<FarFieldSettings>().enabled;
        if on {
            self.used.store(true, Ordering::Relaxed);
        }
        on
    }
    fn injects_before_depth_test(&self) -> bool {
        true
    }
    /// Passes awaiting the walk get their reuse (or their reason) at each submission
    /// (`refresh`, `AwaitPass::resolve_or_why`).
    fn fills_at_submission(&self) -> bool {
        true
    }
    /// The source eye's depth is copied when its pass ends.
    fn keeps_depth(&self, s: &Settings) -> bool {
        self.layer_enabled && s.of::<FarFieldSettings>().enabled
    }
    fn inject(&self, d: &DeviceState, at: &Injection<'_>) {
        let t = Target { cb: at.cb, owner: at.owner, pass: at.pass, plan: at.plan, draws: at.plan.draws.clone(), settings: at.settings, bound_sets: &at.bound_sets, awaiting: None };
        if let Err(why) = self.record(d, t) {
            if at.counts {
                self.not_applied(why);
            }
        }
    }
    /// A pass whose eyes are not known yet (recorded before the walk or the OpenXR half knew its
    /// target, or into one whose eye rect changes every frame): a copy and a reuse draw are
    /// recorded for each view over the render area, and each submission ties them to the eyes
    /// known then (`AwaitPass::resolve_or_why`): a guess that is not this pass's reuses nothing
    /// and leaves its slot invalid.
    fn inject_awaiting(&self, d: &DeviceState, at: &inject::Awaiting<'_>) {
        let area = inject::render_area(at.pass);
        let layer = |a: &AttachmentUse| a.image_view.as_ref().map_or(0, |v| v.range.base_array_layer);
        let color = match (&at.pass.rendering, &at.pass.render_pass) {
            (Some(r), _) => r.color.first().map(|c| &c.attachment),
            (None, Some(rp)) => rp.subpasses.get(at.pass.subpass as usize).and_then(|s| s.color.first()).and_then(|r| r.used()).and_then(|i| at.pass.attachments.get(i as usize)),
            _ => None,
        };
        let Some(base) = color.map(layer) else { return };
        // One guess per view over the whole render area; each submission ties each to the eye of
        // its view, wherever in the area it is (`rules::resolve_guess`): a multiview pass's views
        // in their layers, a per-eye pass's one eye, two eyes side by side.
        let mask = at.pass.view_mask();
        let draws: Vec<EyeDraw> = (0..2u32).filter(|v| mask == 0 || mask & (1 << v) != 0).map(|v| EyeDraw { view: v, layer: base + if mask != 0 { v } else { 0 }, viewport: area, scissor: area }).collect();
        let plan = inject::shape_only(at.pass, at.fail_depth);
        let awaiting = Some(Arc::new(AwaitPass { pass: at.pass.clone(), fail_depth: at.fail_depth, walk: at.walk }));
        let t = Target { cb: at.cb, owner: at.owner, pass: at.pass, plan: &plan, draws, settings: at.settings, bound_sets: &at.bound_sets, awaiting };
        if let Err(why) = self.record(d, t) {
            tracing::debug!("far field: a pass awaiting its eyes got no reuse draw: {why}");
        }
    }
    fn not_injected(&self, _d: &DeviceState, _s: &Settings, why: crate::core::pass::NotMasked) {
        if why != crate::core::pass::NotMasked::NotEyePass {
            self.count(|st| st.count_not_applied(why.name()));
        }
    }
    fn pass_ended(&self, d: &DeviceState, cb: vk::CommandBuffer) {
        let (pending, readbacks) = {
            let mut b = lock(&self.books);
            (b.pending.remove(&cb.as_raw()), b.readbacks.remove(&cb.as_raw()))
        };
        for c in readbacks.into_iter().flatten() {
            c.record_readback(d, cb);
        }
        let Some(p) = pending else { return };
        let s = d.settings();
        let copier = lock(&self.objects).copier;
        if let Err(why) = super::copy::record(d, cb, p, &s, copier.as_ref()) {
            self.not_applied(why);
        }
    }
    /// Attachments can be read: SAMPLED (the compute copy) and TRANSFER_SRC (multisampled copies)
    /// whenever the layer is on (the far field can be switched on live). Transient attachments
    /// never hold anything to copy.
    fn image_usage(&self, _s: &Settings, usage: vk::ImageUsageFlags) -> vk::ImageUsageFlags {
        let attachment = usage.intersects(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT);
        if self.layer_enabled && attachment && !usage.contains(vk::ImageUsageFlags::TRANSIENT_ATTACHMENT) {
            vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::SAMPLED
        } else {
            vk::ImageUsageFlags::empty()
        }
    }
    fn queue_submitting(&self, _d: &DeviceState, family: u32) -> Vec<vk::CommandBuffer> {
        let mut set_up: Vec<vk::CommandBuffer> = {
            let mut b = lock(&self.books);
            let (here, elsewhere) = std::mem::take(&mut b.pending_resets).into_iter().partition(|(f, _)| *f == family);
            b.pending_resets = elsewhere;
            here.into_iter().map(|(_, cb)| cb).collect()
        };
        let init = {
            let mut o = lock(&self.objects);
            match (&o.slots, o.slots_init) {
                (Some(slots), Some((f, cb))) if f == family && !slots.initialized.load(Ordering::Acquire) => {
                    let slots = slots.clone();
                    o.slots_init = None;
                    Some((cb, slots))
                }
                _ => None,
            }
        };
        if let Some((cb, slots)) = init {
            lock(&self.books).slots_init_taken = Some((cb, slots));
            set_up.push(cb);
        }
        set_up
    }
    fn set_up_submitted(&self, _d: &DeviceState, family: u32, set_up: &[vk::CommandBuffer], ok: bool) {
        let mut b = lock(&self.books);
        let init = b.slots_init_taken.take_if(|(cb, _)| set_up.contains(cb));
        if ok {
            if let Some((_, slots)) = init {
                slots.initialized.store(true, Ordering::Release);
            }
            return;
        }
        // The submission failed as a whole: neither the set-up nor the app's command buffers
        // that need it ran. The set-up goes with the next submission there.
        b.pending_resets.extend(set_up.iter().filter(|cb| !matches!(&init, Some((i, _)) if i == *cb)).map(|&cb| (family, cb)));
        drop(b);
        if let Some((cb, slots)) = init {
            let mut o = lock(&self.objects);
            // Slots replaced meanwhile have their own set-up.
            if o.slots.as_ref().is_some_and(|s| Arc::ptr_eq(s, &slots)) {
                o.slots_init = Some((family, cb));
            }
        }
    }
    fn before_submit(&self, d: &DeviceState, cbs: &[u64]) {
        let s = d.settings();
        let views = shared().far_field();
        let frame = views.current.as_ref().map_or(0, |c| c.0);
        let engine = d.engine.as_deref().and_then(rules::engine_depth);
        let inverse = |reversed| {
            let (r, source) = rules::depth_range_with_engine(views.depth, s.of::<FarFieldSettings>().configured_range, engine, reversed)?;
            self.log_range_source(source);
            InverseDepth::of(&r)
        };
        let on = self.layer_enabled && s.of::<FarFieldSettings>().enabled;
        for &cb in cbs {
            let idle = !lifetime::in_flight(d, cb);
            lifetime::with_holds(d, cb, |holds| {
                for h in holds {
                    if let Some(c) = h.downcast_ref::<CopyOp>() {
                        // A guessed copy holds the view it turns out to be, or nothing usable.
                        // The eye's rect may be smaller than the guess (the render area, copied
                        // whole), at its origin (dynamic resolution): the slot holds it there.
                        let view = match &c.awaiting {
                            None => Some((c.view, c.rect)),
                            // A copy of the render area serves the eye found at its origin.
                            Some(a) => a.resolve_or_why(d, s.intermediate, (c.view, c.layer, c.rect), true).ok(),
                        };
                        // A walked source whose rect moved since the recording copied the wrong
                        // pixels: no fresh source.
                        let view = view.filter(|_| c.walked.as_ref().is_none_or(|(image, dr)| matches!(inject::walk_moved(d, *image, std::slice::from_ref(dr)), Ok(None))));
                        let stamp = view.map(|(v, rect)| (Stamp { view: v, frame, rendered: !self.reused_in(frame, v) }, rect));
                        lock(&c.slots.copied)[c.view as usize & 1] = stamp;
                        self.count(|st| st.copies += 1);
                    } else if let Some(r) = h.downcast_ref::<ReuseOp>() {
                        if !idle {
                            continue;
                        }
                        // The recording's previous submission completed: its count is in.
                        if let Some(c) = &r.counter {
                            c.collect();
                        }
                        let moved = r.walked.as_ref().is_some_and(|(image, draws)| !matches!(inject::walk_moved(d, *image, draws), Ok(None)));
                        if moved {
                            r.buffer.write(0, &vec![vk::DrawIndirectCommand::default(); r.views.len()]);
                            self.not_applied(crate::core::pass::NotMasked::RectChanging.name());
                        } else if on && r.slots.initialized.load(Ordering::Acquire) {
                            self.refresh(d, r, &s, &views, inverse(r.reversed));
                        } else {
                            r.buffer.write(0, &vec![vk::DrawIndirectCommand::default(); r.views.len()]);
                        }
                    }
                }
            });
        }
    }
    fn destroy(&self, d: &DeviceState) {
        super::count::destroy(d, &self.query_pools);
        let o = std::mem::take(&mut *lock(&self.objects));
        drop(o.slots);
        // SAFETY: our objects; the device is idle.
        unsafe {
            if let Some(c) = &o.copier {
                c.destroy(d);
            }
            if o.layout != vk::PipelineLayout::null() {
                d.fns.destroy_pipeline_layout(o.layout, None);
                d.fns.destroy_descriptor_set_layout(o.set_layout, None);
                d.fns.destroy_sampler(o.linear, None);
                d.fns.destroy_sampler(o.nearest, None);
            }
        }
    }
}

/// Records the slots' one-time set-up: every slot image from UNDEFINED to GENERAL, the tile
/// buffer marked not reduced.
fn record_slot_init(d: &DeviceState, cb: vk::CommandBuffer, slots: &Slots) {
    let barriers: Vec<vk::ImageMemoryBarrier> = slots
        .images
        .iter()
        .flat_map(|s| [(&s[0], vk::ImageAspectFlags::COLOR), (&s[1], if slots.compute { vk::ImageAspectFlags::COLOR } else { vk::ImageAspectFlags::DEPTH })])
        .map(|(o, aspect)| {
            crate::plugin::vk::gpu::image_barrier(o.image, vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 }, (vk::ImageLayout::UNDEFINED, vk::ImageLayout::GENERAL), (vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::SHADER_READ))
        })
        .collect();
    let tiles = [vk::BufferMemoryBarrier::default()
        .buffer(slots.tiles)
        .offset(0)
        .size(vk::WHOLE_SIZE)
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)];
    let fns = d.fns.fp_v1_0();
    // SAFETY: our one-time command buffer, recording; the slots and their tile buffer are
    // ours and unused so far (no tile is known until a reduction fills it).
    unsafe {
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), barriers.len() as u32, barriers.as_ptr());
        (fns.cmd_fill_buffer)(cb, slots.tiles, 0, vk::WHOLE_SIZE, NOT_REDUCED);
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), 0, std::ptr::null(), tiles.len() as u32, tiles.as_ptr(), 0, std::ptr::null())
    };
}
