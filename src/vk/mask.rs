//! The hidden-area mask on the Vulkan side: right where an eye pass's depth buffer starts out
//! cleared, draw the view's hidden triangles at the depth that fails the app's test, so early-Z
//! rejects the app's own fragments there. Owns the layer's Vulkan objects for it (pipelines per
//! compatibility key, a vertex buffer per mask generation) and records the draw plus everything it
//! disturbed (`CmdState::restore_commands`). Decisions come from `track::eye_pass` and geometry from
//! `crate::mask`; this module only turns them into commands.

use super::DeviceState;
use crate::config::Config;
use crate::mask::{self, MaskFrameStats, NotMasked, PixelRect};
use crate::shared::{shared, Views};
use crate::track::caps;
use crate::track::cmd::{AttachmentUse, PassInstance, StateCmd};
use crate::track::eye_pass::{self, EyeLayout, EyeSource, Eyes, Learned, MaskPlan};
use ash::vk::{self, Handle};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

static VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask.vert.spv"));
static VERT_MV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask_mv.vert.spv"));
static FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mask.frag.spv"));

/// Frames ended (`take_frame_stats` calls): a retired vertex buffer is destroyed only this many
/// frames after it stopped being used for new draws. OpenXR apps keep at most a few frames in
/// flight (xrWaitFrame throttles them), so command buffers recorded with it have completed by then.
pub(super) const RETIRE_AFTER_FRAMES: u64 = 16;
pub(super) static FRAMES_ENDED: AtomicU64 = AtomicU64::new(0);

/// One vertex: NDC position and the view it belongs to.
#[repr(C)]
#[derive(Clone, Copy)]
struct Vertex {
    pos: [f32; 2],
    view: u32,
}

/// What makes a layer pipeline usable inside an app's pass.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) enum PipelineKey {
    /// Compatible with the app's render pass + subpass (the subpass carries its view mask).
    RenderPass { render_pass: u64, subpass: u32, samples: u32, colors: u32, multiview: bool, debug: bool, rdm: bool },
    /// `VkPipelineRenderingCreateInfo` for dynamic rendering.
    Dynamic { colors: Vec<vk::Format>, depth: vk::Format, stencil: vk::Format, samples: u32, view_mask: u32, debug: bool, rdm: bool },
}

/// The vertex buffer of one mask generation.
struct MaskBuffer {
    generation: u64,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    /// view → (first vertex, vertex count).
    ranges: BTreeMap<u32, (u32, u32)>,
    /// view → NDC triangles (pixel statistics).
    ndc: BTreeMap<u32, Vec<[f32; 2]>>,
    total: u32,
    /// Frame count at which a newer generation replaced it.
    retired_at: Option<u64>,
}

#[derive(Default)]
struct Objects {
    layout: vk::PipelineLayout,
    modules: Modules,
    pipelines: HashMap<PipelineKey, vk::Pipeline>,
    buffers: Vec<MaskBuffer>,
}

#[derive(Default)]
struct Books {
    frame: MaskFrameStats,
    total: MaskFrameStats,
    /// (generation, view, viewport, scissor) → pixels covered.
    coverage: HashMap<(u64, u32, PixelRect, PixelRect), u64>,
    logged_kinds: HashSet<(EyeLayout, bool)>,
    logged_targets: HashSet<u64>,
    logged_reasons: HashSet<NotMasked>,
    /// Device capabilities already reported missing (`log_device_lacks_once`).
    logged_lacks: HashSet<&'static str>,
    /// Command buffers whose open pass loads its depth and was not masked at its beginning: it
    /// counts (masked or not) at its first depth clear (vkCmdClearAttachments), or as
    /// `depth_not_cleared` when it ends, so it is counted once either way.
    deferred: HashSet<u64>,
    /// Primaries whose open eye pass has its contents in secondary command buffers: the draws go
    /// into a secondary of the layer's, executed ahead of the app's at its next
    /// vkCmdExecuteCommands (`on_execute_commands`).
    pending: HashMap<u64, Pending>,
}

/// An injection waiting for the app's vkCmdExecuteCommands.
struct Pending {
    snap: Snapshot,
    plan: MaskPlan,
    counts: bool,
}

/// Per-device mask state. Locks are held only around bookkeeping, never while calling down.
pub(crate) struct MaskDevice {
    /// The master switch (`enabled`) at device creation; `mask.*` keys are read live.
    layer_enabled: bool,
    /// Whether the mask ever did anything on this device (adds its counters to the stats line).
    used: std::sync::atomic::AtomicBool,
    memory: vk::PhysicalDeviceMemoryProperties,
    /// The device offers `attachmentFragmentShadingRate` (foveation.method = auto then means vrs).
    fsr_attachment: bool,
    objects: Mutex<Objects>,
    books: Mutex<Books>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Settings {
    pub enabled: bool,
    /// Radial density masking: `foveation.enabled` and the method resolves to rdm on this device.
    pub rdm: bool,
    pub debug: bool,
    pub intermediate: bool,
}

/// Why a mask draw is recorded.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Trigger {
    /// A render pass instance / rendering just began (`secondary`: its contents are recorded in
    /// secondary command buffers).
    Begin { secondary: bool },
    /// vkCmdNextSubpass: a later subpass may be the first to use (and clear) the depth attachment.
    NextSubpass { secondary: bool },
    /// vkCmdClearAttachments cleared the depth attachment to this value over these rects.
    Clear { depth: f32, rects: Vec<PixelRect> },
    /// The pass is about to end (nothing is drawn): a deferred pass that was never cleared counts.
    End,
}

impl Settings {
    /// Whether anything injects at eye passes (the mask, radial density masking, or both).
    pub fn any(&self) -> bool {
        self.enabled || self.rdm
    }
}

impl MaskDevice {
    pub fn new(config: &Config, memory: vk::PhysicalDeviceMemoryProperties, fsr_attachment: bool) -> MaskDevice {
        MaskDevice {
            layer_enabled: config.enabled(),
            used: std::sync::atomic::AtomicBool::new(false),
            memory,
            fsr_attachment,
            objects: Mutex::new(Objects::default()),
            books: Mutex::new(Books::default()),
        }
    }

    /// The `mask.*` settings in effect now: the OpenXR half re-reads a changed config file between
    /// frames (`shared().config`), falling back to the device's own configuration.
    pub fn settings(&self, device_config: &Arc<Config>) -> Settings {
        let c = shared().config().unwrap_or_else(|| device_config.clone());
        let enabled = self.layer_enabled && c.bool("mask.enabled");
        let rdm = self.layer_enabled && c.bool("foveation.enabled") && crate::rdm::method_is_rdm(c.choice("foveation.method"), self.fsr_attachment);
        if enabled || rdm {
            self.used.store(true, Ordering::Relaxed);
        }
        Settings { enabled, rdm, debug: c.bool("mask.debug"), intermediate: c.choice("mask.intermediate") != "off" }
    }

    /// Another injecting feature (variable-rate shading) counted here: the stats line includes it.
    pub(super) fn mark_used(&self) {
        self.used.store(true, Ordering::Relaxed);
    }

    pub fn used(&self) -> bool {
        self.used.load(Ordering::Relaxed)
    }

    pub fn take_frame(&self) -> MaskFrameStats {
        std::mem::take(&mut lock(&self.books).frame)
    }

    pub fn summary(&self) -> String {
        lock(&self.books).total.summary()
    }

    pub(super) fn count(&self, f: impl Fn(&mut MaskFrameStats)) {
        let mut b = lock(&self.books);
        f(&mut b.frame);
        f(&mut b.total);
    }
}

/// Sums and resets every device's statistics of the frame that just ended.
pub(crate) fn take_frame_stats() -> MaskFrameStats {
    FRAMES_ENDED.fetch_add(1, Ordering::Relaxed);
    let mut all = MaskFrameStats::default();
    for (_, d) in super::layer().devices.values() {
        all.add(&d.mask.take_frame());
    }
    all
}

/// What the pass looked like when the trigger fired, copied out of the command buffer's lock.
struct Snapshot {
    pass: PassInstance,
    restore: Vec<StateCmd>,
    secondary_level: bool,
    explicit_clear: Option<f32>,
}

/// Entry from the hooks, after the triggering command went down successfully.
pub(crate) fn on_trigger(d: &DeviceState, cb: vk::CommandBuffer, trigger: Trigger) {
    let settings = d.mask.settings(&d.config);
    if !settings.enabled && !settings.rdm {
        return;
    }
    let key = cb.as_raw();
    if trigger == Trigger::End && !lock(&d.mask.books).deferred.contains(&key) {
        return;
    }
    let secondary_level = d.track.command_buffers.get(key).is_some_and(|c| c.level == vk::CommandBufferLevel::SECONDARY);
    let snap = d.track.with_cb(key, |s| {
        let pass = s.pass.clone()?;
        // A pass that loads an image cleared by vkCmdClearDepthStencilImage starts from that clear.
        let mut explicit_clear = None;
        if matches!(trigger, Trigger::Begin { .. }) {
            let images: Vec<u64> = attachments(&pass).iter().filter_map(|a| a.image_view.as_ref().map(|v| v.image)).collect();
            // Only a loaded depth attachment keeps that clear (a load op CLEAR replaces it).
            if let Some(depth_image) = depth_image(&pass).filter(|_| eye_pass::depth_loads(&pass)) {
                explicit_clear = s.depth_image_clears.iter().rev().find(|(i, _)| *i == depth_image).map(|(_, v)| *v);
            }
            s.depth_image_clears.retain(|(i, _)| !images.contains(i));
        }
        if let Trigger::Clear { depth, .. } = &trigger {
            explicit_clear = Some(*depth);
        }
        Some(Snapshot { pass, restore: s.restore_commands(), secondary_level, explicit_clear })
    });
    let Some(Some(snap)) = snap else { return };
    let resuming = snap.pass.rendering.as_ref().is_some_and(|r| r.resuming());
    // A primary whose pass has its contents in secondaries gets the draws in a secondary of the
    // layer's at the app's vkCmdExecuteCommands; the app's own secondary-level buffers are left
    // alone (counted as `secondary`).
    let secondary_contents = match &trigger {
        Trigger::Begin { secondary } | Trigger::NextSubpass { secondary } => *secondary,
        Trigger::Clear { .. } | Trigger::End => false,
    };
    if !matches!(trigger, Trigger::Clear { .. }) {
        // A new subpass or the end: whatever was pending for the previous one was never executed.
        lock(&d.mask.books).pending.remove(&key);
    }
    let eyes = |a: &AttachmentUse| eyes_of(d, a, settings.intermediate);
    let facts = eye_pass::Facts {
        secondary_contents: snap.secondary_level,
        intermediate_enabled: settings.intermediate,
        eyes: &eyes,
        explicit_clear: snap.explicit_clear,
    };
    let plan = eye_pass::classify(&snap.pass, &facts);
    // Only a pass's beginning counts as a pass; later subpasses and clears count when they mask.
    // A pass that loads its depth may still clear it (vkCmdClearAttachments) before it draws: it
    // counts at that clear, or when it ends uncleared (a suspended rendering counts at its end).
    let counts = {
        let mut books = lock(&d.mask.books);
        match &trigger {
            Trigger::Begin { .. } if resuming => false,
            Trigger::Begin { .. } => {
                let defer = matches!(plan, Err(NotMasked::DepthNotCleared)) && eye_pass::depth_loads(&snap.pass);
                if defer {
                    books.deferred.insert(key);
                } else {
                    books.deferred.remove(&key);
                }
                !defer
            }
            Trigger::NextSubpass { .. } => false,
            Trigger::Clear { .. } => books.deferred.remove(&key),
            Trigger::End => !snap.pass.rendering.as_ref().is_some_and(|r| r.suspending()) && books.deferred.remove(&key),
        }
    };
    let mut plan = match plan {
        Ok(p) => p,
        Err(why) => {
            count_not_applied(d, settings, counts, why, &snap.pass);
            return;
        }
    };
    if trigger == Trigger::End {
        return;
    }
    if let Trigger::Clear { rects, .. } = &trigger {
        // A clear of part of the attachment: mask only eyes it fully re-cleared.
        plan.draws.retain(|dr| rects.iter().any(|r| r.contains(&dr.scissor)));
        if plan.draws.is_empty() {
            if counts {
                // Still uncleared where the eyes are: a later clear or the pass's end counts it.
                lock(&d.mask.books).deferred.insert(key);
            }
            return;
        }
    }
    if secondary_contents && !snap.secondary_level {
        lock(&d.mask.books).pending.insert(key, Pending { snap, plan, counts });
        return;
    }
    inject(d, cb, &snap, &plan, settings, counts, true);
}

/// The app executes secondaries in `cb`: if its open eye pass awaits the layer's draws, they are
/// recorded into a secondary of the layer's, returned to be executed first.
pub(crate) fn on_execute_commands(d: &DeviceState, cb: vk::CommandBuffer) -> Option<vk::CommandBuffer> {
    let Pending { snap, plan, counts } = lock(&d.mask.books).pending.remove(&cb.as_raw())?;
    let settings = d.mask.settings(&d.config);
    let formats;
    let inherit = match (&snap.pass.rendering, &snap.pass.render_pass, &snap.pass.framebuffer) {
        (Some(r), _, _) => {
            let Some(PipelineKey::Dynamic { colors, depth, stencil, samples, .. }) = pipeline_key(d, &snap.pass, &plan, false, false) else {
                count_not_applied(d, settings, counts, NotMasked::Unsupported, &snap.pass);
                return None;
            };
            formats = colors;
            super::secondary::Inherit::Rendering {
                flags: r.flags,
                view_mask: r.view_mask,
                colors: &formats,
                depth,
                stencil,
                samples: vk::SampleCountFlags::from_raw(samples),
            }
        }
        (None, Some(rp), Some(fb)) => super::secondary::Inherit::RenderPass { render_pass: rp.handle, subpass: snap.pass.subpass, framebuffer: fb.handle },
        _ => {
            count_not_applied(d, settings, counts, NotMasked::Unsupported, &snap.pass);
            return None;
        }
    };
    let recorded = super::secondary::record(d, cb.as_raw(), &inherit, |ours| inject(d, ours, &snap, &plan, settings, counts, false));
    match recorded {
        Ok(ours) => Some(ours),
        Err(e) => {
            tracing::warn!("layer secondary command buffer: {e}");
            count_not_applied(d, settings, counts, NotMasked::LayerError, &snap.pass);
            None
        }
    }
}

/// Counts (and logs once) a pass the enabled features leave alone.
fn count_not_applied(d: &DeviceState, settings: Settings, counts: bool, why: NotMasked, pass: &PassInstance) {
    if !counts {
        return;
    }
    if settings.enabled {
        d.mask.count(|s| s.count_not_masked(why));
    }
    if settings.rdm && why != NotMasked::NotEyePass {
        d.mask.count(|s| *s.rdm.not_applied.entry(why.name()).or_insert(0) += 1);
    }
    log_reason_once(d, why, pass);
}

/// Records the enabled features' draws for an eye pass into `cb` — the app's command buffer right
/// after the depth clear (then the app's state is restored after them), or a secondary of the
/// layer's inheriting the pass (nothing to restore: the app's secondaries set their own state).
fn inject(d: &DeviceState, cb: vk::CommandBuffer, snap: &Snapshot, plan: &MaskPlan, settings: Settings, counts: bool, restore: bool) {
    if settings.enabled {
        match record(d, cb, snap, plan, settings.debug) {
            Ok(pixels) => {
                d.mask.count(|s| {
                    s.passes_masked += 1;
                    for (view, px) in &pixels {
                        *s.pixels_masked.entry(*view).or_insert(0) += px;
                    }
                });
                log_kind_once(d, plan, &pixels);
            }
            Err(why) => {
                if counts {
                    d.mask.count(|s| s.count_not_masked(why));
                    log_reason_once(d, why, &snap.pass);
                }
            }
        }
    }
    if settings.rdm {
        // After the mask (if any): the checkerboard goes over the same cleared depth.
        let key = pipeline_key(d, &snap.pass, plan, false, true);
        match key.ok_or(crate::rdm::NotApplied::LayerError).and_then(|k| super::rdm::record_draw(d, cb, &k, plan)) {
            Ok(()) => {}
            Err(why) => {
                if counts {
                    d.mask.count(|s| s.rdm.count_not_applied(why));
                }
            }
        }
    }
    if restore && (settings.enabled || settings.rdm) {
        // SAFETY: `cb` is recording inside the pass; the commands replay the app's state, whose
        // handles are alive while it records.
        unsafe {
            for c in &snap.restore {
                replay(d, cb, c);
            }
        }
    }
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

pub(super) fn eyes_of(d: &DeviceState, a: &AttachmentUse, intermediate: bool) -> Eyes {
    if let Some(sc) = &a.swapchain {
        return Eyes::Swapchain(sc.swapchain.uses().iter().map(EyeSource::from_use).collect());
    }
    let Some(image) = a.image_view.as_ref().map(|v| v.image) else { return Eyes::Unknown };
    match d.track.intermediate_eyes(shared(), image) {
        None => Eyes::Unknown,
        Some(learned) => {
            let first = lock(&d.mask.books).logged_targets.insert(image);
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
                    if first {
                        tracing::info!(image = format_args!("{image:#x}"), "not an intermediate eye target: {why}");
                    }
                    Eyes::Unknown
                }
            }
        }
    }
}

fn log_reason_once(d: &DeviceState, why: NotMasked, pass: &PassInstance) {
    if why == NotMasked::NotEyePass {
        return;
    }
    if lock(&d.mask.books).logged_reasons.insert(why) {
        tracing::info!(kind = ?pass.kind, "pass not masked: {} (logged once per reason)", why.name());
    }
}

fn log_kind_once(d: &DeviceState, plan: &MaskPlan, pixels: &[(u32, u64)]) {
    if !lock(&d.mask.books).logged_kinds.insert((plan.layout, plan.intermediate)) {
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
    tracing::info!(
        "masking {} pass on {target} {:#x}: {}; mask depth {}",
        plan.layout.name(),
        plan.image,
        eyes.join("; "),
        plan.fail_depth
    );
}

/// Records the mask draw(s) and the app's state after them; returns pixels masked per view.
fn record(d: &DeviceState, cb: vk::CommandBuffer, snap: &Snapshot, plan: &MaskPlan, debug: bool) -> Result<Vec<(u32, u64)>, NotMasked> {
    let views = shared().views();
    let buffer = vertex_buffer(d, &views).map_err(|e| {
        tracing::warn!("mask vertex buffer: {e}");
        NotMasked::LayerError
    })?;
    let Some(buffer) = buffer else { return Err(NotMasked::NoMask) };
    let (vk_buffer, generation, ranges, total) = buffer;
    if plan.draws.iter().any(|dr| !ranges.contains_key(&dr.view)) {
        return Err(NotMasked::NoMask);
    }
    let key = pipeline_key(d, &snap.pass, plan, debug, false).ok_or(NotMasked::Unsupported)?;
    let pipeline = pipeline(d, &key).map_err(|e| match e {
        PipelineError::DeviceLacks => NotMasked::DeviceLacks,
        PipelineError::Vulkan(e) => {
            tracing::warn!(?key, "mask pipeline: {e}");
            NotMasked::LayerError
        }
    })?;
    let fns = d.fns.fp_v1_0();
    let viewport = |r: PixelRect| fail_viewport(r, plan.fail_depth);
    let scissor = rect2d;
    // SAFETY: `cb` is recording inside the pass the plan was made for (the hook just recorded its
    // begin / clear); the pipeline is compatible with it; the buffer lives until retired frames
    // after this command buffer completed; all arrays outlive the calls.
    unsafe {
        (fns.cmd_bind_pipeline)(cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
        (fns.cmd_bind_vertex_buffers)(cb, 0, 1, &vk_buffer, &0);
        if plan.layout == EyeLayout::Multiview {
            let dr = plan.draws[0];
            (fns.cmd_set_viewport)(cb, 0, 1, &viewport(dr.viewport));
            (fns.cmd_set_scissor)(cb, 0, 1, &scissor(dr.scissor));
            (fns.cmd_draw)(cb, total, 1, 0, 0);
        } else {
            for dr in plan.draws.iter().filter(|dr| dr.scissor.area() > 0) {
                let (first, count) = ranges[&dr.view];
                (fns.cmd_set_viewport)(cb, 0, 1, &viewport(dr.viewport));
                (fns.cmd_set_scissor)(cb, 0, 1, &scissor(dr.scissor));
                (fns.cmd_draw)(cb, count, 1, first, 0);
            }
        }
    }
    let mut pixels = Vec::new();
    for dr in &plan.draws {
        pixels.push((dr.view, coverage(d, generation, dr.view, dr.viewport, dr.scissor)));
    }
    Ok(pixels)
}

fn coverage(d: &DeviceState, generation: u64, view: u32, viewport: PixelRect, scissor: PixelRect) -> u64 {
    let k = (generation, view, viewport, scissor);
    if let Some(n) = lock(&d.mask.books).coverage.get(&k) {
        return *n;
    }
    let ndc = lock(&d.mask.objects).buffers.iter().find(|b| b.generation == generation).and_then(|b| b.ndc.get(&view).cloned());
    let n = ndc.map_or(0, |t| mask::coverage(&t, viewport.viewport(), scissor));
    let mut books = lock(&d.mask.books);
    if books.coverage.len() > 256 {
        books.coverage.clear();
    }
    books.coverage.insert(k, n);
    n
}

fn pipeline_key(d: &DeviceState, pass: &PassInstance, plan: &MaskPlan, debug: bool, rdm: bool) -> Option<PipelineKey> {
    let samples_of_view = |a: &AttachmentUse| {
        let v = a.image_view.as_ref()?;
        d.track.images.get(v.image).map(|i| i.samples.as_raw())
    };
    if let Some(r) = &pass.rendering {
        let fmt = |a: &AttachmentUse| a.image_view.as_ref().map_or(vk::Format::UNDEFINED, |v| v.format);
        let depth = r.depth.as_ref()?;
        let colors = r.color.iter().map(|c| if c.attachment.view == 0 { vk::Format::UNDEFINED } else { fmt(&c.attachment) }).collect();
        let stencil = r.stencil.as_ref().filter(|s| s.attachment.view != 0).map_or(vk::Format::UNDEFINED, |s| fmt(&s.attachment));
        return Some(PipelineKey::Dynamic {
            colors,
            depth: fmt(&depth.attachment),
            stencil,
            samples: samples_of_view(&depth.attachment)?,
            view_mask: r.view_mask,
            debug,
            rdm,
        });
    }
    let rp = pass.render_pass.as_ref()?;
    let sub = rp.subpasses.get(pass.subpass as usize)?;
    let depth = rp.attachments.get(sub.depth_stencil?.used()? as usize)?;
    let multiview = sub.view_mask != 0;
    if multiview != (plan.layout == EyeLayout::Multiview) {
        return None;
    }
    Some(PipelineKey::RenderPass {
        render_pass: rp.handle,
        subpass: pass.subpass,
        samples: depth.samples.as_raw(),
        colors: sub.color.len() as u32,
        multiview,
        debug,
        rdm,
    })
}

/// The shader modules of the layer's injected draws.
#[derive(Clone, Copy, Default)]
struct Modules {
    vert: vk::ShaderModule,
    vert_mv: vk::ShaderModule,
    frag: vk::ShaderModule,
    rdm_vert: vk::ShaderModule,
    rdm_vert_mv: vk::ShaderModule,
    rdm_frag: vk::ShaderModule,
}

impl Modules {
    fn all(&self) -> [vk::ShaderModule; 6] {
        [self.vert, self.vert_mv, self.frag, self.rdm_vert, self.rdm_vert_mv, self.rdm_frag]
    }
}

/// Layout and shader modules, made once per device.
fn common(d: &DeviceState) -> Result<(vk::PipelineLayout, Modules), String> {
    {
        let o = lock(&d.mask.objects);
        if o.layout != vk::PipelineLayout::null() {
            return Ok((o.layout, o.modules));
        }
    }
    let module = |bytes: &[u8]| -> Result<vk::ShaderModule, String> {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes)).map_err(|e| e.to_string())?;
        // SAFETY: valid SPIR-V compiled at build time; a valid create info.
        unsafe { d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }.map_err(|e| e.to_string())
    };
    // No descriptor sets, no push constants: the draws need nothing but their vertices.
    // SAFETY: a valid, empty create info.
    let layout = unsafe { d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default(), None) }.map_err(|e| e.to_string())?;
    let (rv, rvm, rf) = super::rdm::draw_shaders();
    // The multiview variants declare the MultiView capability: only a device that enabled
    // `multiview` may see them (VUID-VkShaderModuleCreateInfo-pCode-08740). Elsewhere they stay
    // null, and `pipeline` never asks for them (`PipelineKey::needs`).
    let multiview_module = |bytes: &[u8]| if d.caps.multiview { module(bytes) } else { Ok(vk::ShaderModule::null()) };
    let modules = Modules {
        vert: module(VERT)?,
        vert_mv: multiview_module(VERT_MV)?,
        frag: module(FRAG)?,
        rdm_vert: module(rv)?,
        rdm_vert_mv: multiview_module(rvm)?,
        rdm_frag: module(rf)?,
    };
    let mut o = lock(&d.mask.objects);
    if o.layout != vk::PipelineLayout::null() {
        drop(o);
        // Another thread won the race: ours are unused.
        // SAFETY: objects this function just created, never used.
        unsafe {
            d.fns.destroy_pipeline_layout(layout, None);
            for m in modules.all() {
                d.fns.destroy_shader_module(m, None);
            }
        }
        return common(d);
    }
    (o.layout, o.modules) = (layout, modules);
    Ok((layout, modules))
}

impl PipelineKey {
    /// What the device must have been created with for this pipeline (and its shader modules).
    pub(super) fn needs(&self) -> caps::Needs {
        match self {
            PipelineKey::RenderPass { multiview, .. } => caps::Needs { multiview: *multiview, ..Default::default() },
            PipelineKey::Dynamic { view_mask, .. } => {
                caps::Needs { multiview: *view_mask != 0, dynamic_rendering: true, ..Default::default() }
            }
        }
    }
}

/// Why the layer has no pipeline for a key.
#[derive(Debug)]
pub(super) enum PipelineError {
    /// The device was created without a capability the pipeline needs (logged once, by name).
    DeviceLacks,
    /// A Vulkan call failed.
    Vulkan(String),
}

impl From<String> for PipelineError {
    fn from(e: String) -> PipelineError {
        PipelineError::Vulkan(e)
    }
}

/// Logs, once per device and capability, that a feature is not applied because the device lacks
/// what its draw needs.
pub(super) fn log_device_lacks_once(d: &DeviceState, what: &'static str) {
    if lock(&d.mask.books).logged_lacks.insert(what) {
        tracing::warn!(
            "the app's device was created without {what}, which the layer's draw for this pass needs: \
             the mask / foveation is not applied to such passes on this device (logged once)"
        );
    }
}

/// The cached pipeline for `key`, created on first use (never per draw) and only when the device
/// has what it needs.
pub(super) fn pipeline(d: &DeviceState, key: &PipelineKey) -> Result<vk::Pipeline, PipelineError> {
    if let Some(lacking) = caps::missing(&d.caps, &key.needs()) {
        log_device_lacks_once(d, lacking);
        return Err(PipelineError::DeviceLacks);
    }
    if let Some(p) = lock(&d.mask.objects).pipelines.get(key) {
        return Ok(*p);
    }
    let (layout, m) = common(d)?;
    let (multiview, samples, colors, debug, rdm) = match key {
        PipelineKey::RenderPass { samples, colors, multiview, debug, rdm, .. } => (*multiview, *samples, *colors as usize, *debug, *rdm),
        PipelineKey::Dynamic { colors, samples, view_mask, debug, rdm, .. } => (*view_mask != 0, *samples, colors.len(), *debug, *rdm),
    };
    // Radial density masking: its own vertex layout and a fragment shader that discards kept
    // quads; colour writes stay off.
    let (vert, vert_mv, frag) = if rdm { (m.rdm_vert, m.rdm_vert_mv, m.rdm_frag) } else { (m.vert, m.vert_mv, m.frag) };
    // Without the debug tint the draw is depth-only: no fragment shader at all, so the GPU runs
    // its depth-only fast path (colour writes are masked off, so no output is undefined).
    let all_stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(if multiview { vert_mv } else { vert })
            .name(c"main"),
        vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"),
    ];
    let stages = if debug || rdm { &all_stages[..] } else { &all_stages[..1] };
    let (stride, attributes) = if rdm {
        super::rdm::vertex_layout()
    } else {
        (
            std::mem::size_of::<Vertex>() as u32,
            vec![
                vk::VertexInputAttributeDescription { location: 0, binding: 0, format: vk::Format::R32G32_SFLOAT, offset: 0 },
                vk::VertexInputAttributeDescription { location: 1, binding: 0, format: vk::Format::R32_UINT, offset: 8 },
            ],
        )
    };
    let bindings = [vk::VertexInputBindingDescription { binding: 0, stride, input_rate: vk::VertexInputRate::VERTEX }];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default().vertex_binding_descriptions(&bindings).vertex_attribute_descriptions(&attributes);
    let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::from_raw(samples));
    // ALWAYS + write: the mask replaces the cleared depth with the failing value, whatever the
    // app's compare op is.
    let depth = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(true)
        .depth_compare_op(vk::CompareOp::ALWAYS);
    let blend_atts: Vec<vk::PipelineColorBlendAttachmentState> = (0..colors)
        .map(|i| {
            let mask = if debug && !rdm && i == 0 { vk::ColorComponentFlags::RGBA } else { vk::ColorComponentFlags::empty() };
            vk::PipelineColorBlendAttachmentState::default().color_write_mask(mask)
        })
        .collect();
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_atts);
    let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let mut info = vk::GraphicsPipelineCreateInfo::default()
        .stages(stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&input_assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth)
        .color_blend_state(&blend)
        .dynamic_state(&dynamic)
        .layout(layout);
    let color_formats: Vec<vk::Format>;
    let mut rendering;
    match key {
        PipelineKey::RenderPass { render_pass, subpass, .. } => {
            info = info.render_pass(vk::RenderPass::from_raw(*render_pass)).subpass(*subpass);
        }
        PipelineKey::Dynamic { colors, depth, stencil, view_mask, .. } => {
            color_formats = colors.clone();
            rendering = vk::PipelineRenderingCreateInfo::default()
                .view_mask(*view_mask)
                .color_attachment_formats(&color_formats)
                .depth_attachment_format(*depth)
                .stencil_attachment_format(*stencil);
            info = info.push_next(&mut rendering);
            // The pass may carry variable-rate shading's attachment, which every pipeline bound
            // in it must be made for.
            if d.vrs.enabled() {
                info = info.flags(vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR);
            }
        }
    }
    // No VkPipelineFragmentShadingRateStateCreateInfoKHR: the defaults (1×1, [KEEP, KEEP]) ignore
    // a rate attachment, so mask and RDM depth is written at full rate, pixel-exact, in render
    // pass objects that carry the layer's rate attachment too (same render pass: compatible).
    // SAFETY: a valid create info; every object it names is alive (the app's render pass is in use
    // by the pass being recorded).
    let created = unsafe { d.fns.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }.map_err(|(_, e)| e.to_string())?;
    let p = created[0];
    let mut o = lock(&d.mask.objects);
    if let Some(existing) = o.pipelines.get(key) {
        let existing = *existing;
        drop(o);
        // SAFETY: ours was just created and never used.
        unsafe { d.fns.destroy_pipeline(p, None) };
        return Ok(existing);
    }
    o.pipelines.insert(key.clone(), p);
    drop(o);
    tracing::debug!(?key, "mask pipeline created");
    Ok(p)
}

/// The app destroyed a render pass: pipelines made against it go too (its handle may be reused).
/// Every command buffer that used them also used the render pass, and the app must have waited
/// for those before destroying it.
pub(crate) fn forget_render_pass(d: &DeviceState, render_pass: u64) {
    let gone: Vec<vk::Pipeline> = {
        let mut o = lock(&d.mask.objects);
        let keys: Vec<PipelineKey> = o.pipelines.keys().filter(|k| matches!(k, PipelineKey::RenderPass { render_pass: r, .. } if *r == render_pass)).cloned().collect();
        keys.iter().filter_map(|k| o.pipelines.remove(k)).collect()
    };
    for p in gone {
        // SAFETY: our pipeline; its command buffers completed (see above).
        unsafe { d.fns.destroy_pipeline(p, None) };
    }
}

type BufferInfo = (vk::Buffer, u64, BTreeMap<u32, (u32, u32)>, u32);

/// The vertex buffer of the current mask generation, built when the generation first appears;
/// None when no view has a mask.
fn vertex_buffer(d: &DeviceState, views: &Arc<Views>) -> Result<Option<BufferInfo>, String> {
    let now = FRAMES_ENDED.load(Ordering::Relaxed);
    let mut retired = Vec::new();
    {
        let mut o = lock(&d.mask.objects);
        if let Some(b) = o.buffers.iter().find(|b| b.generation == views.generation && b.retired_at.is_none()) {
            return Ok((b.total > 0).then(|| (b.buffer, b.generation, b.ranges.clone(), b.total)));
        }
        for b in o.buffers.iter_mut() {
            b.retired_at.get_or_insert(now);
        }
        o.buffers.retain(|b| {
            let old = b.retired_at.is_some_and(|r| now >= r + RETIRE_AFTER_FRAMES);
            if old {
                retired.push((b.buffer, b.memory));
            }
            !old
        });
    }
    for (buffer, memory) in retired {
        // SAFETY: retired RETIRE_AFTER_FRAMES frames ago; no command buffer still uses it.
        unsafe {
            d.fns.destroy_buffer(buffer, None);
            d.fns.free_memory(memory, None);
        }
    }
    let mut vertices = Vec::new();
    let mut ranges = BTreeMap::new();
    let mut ndc_of = BTreeMap::new();
    for m in &views.masks {
        let Some(fov) = views.fovs.get(m.view as usize) else { continue };
        let ndc = mask::triangles_to_ndc(&m.triangles, fov);
        if ndc.is_empty() {
            continue;
        }
        ranges.insert(m.view, (vertices.len() as u32, ndc.len() as u32));
        vertices.extend(ndc.iter().map(|&pos| Vertex { pos, view: m.view }));
        ndc_of.insert(m.view, ndc);
    }
    let total = vertices.len() as u32;
    let (buffer, memory) = if vertices.is_empty() { (vk::Buffer::null(), vk::DeviceMemory::null()) } else { create_buffer(d, &vertices)? };
    let mut o = lock(&d.mask.objects);
    o.buffers.push(MaskBuffer { generation: views.generation, buffer, memory, ranges: ranges.clone(), ndc: ndc_of, total, retired_at: None });
    drop(o);
    tracing::info!(generation = views.generation, views = ranges.len(), vertices = total, "mask vertex buffer built");
    Ok((total > 0).then_some((buffer, views.generation, ranges, total)))
}

pub(super) fn create_buffer<T: Copy>(d: &DeviceState, vertices: &[T]) -> Result<(vk::Buffer, vk::DeviceMemory), String> {
    let size = std::mem::size_of_val(vertices) as u64;
    let info = vk::BufferCreateInfo::default().size(size).usage(vk::BufferUsageFlags::VERTEX_BUFFER).sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: a valid create info.
    let buffer = unsafe { d.fns.create_buffer(&info, None) }.map_err(|e| e.to_string())?;
    // SAFETY: our buffer.
    let req = unsafe { d.fns.get_buffer_memory_requirements(buffer) };
    let wanted = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
    let mem = &d.mask.memory;
    let Some(type_index) = (0..mem.memory_type_count).find(|&i| req.memory_type_bits & (1 << i) != 0 && mem.memory_types[i as usize].property_flags.contains(wanted)) else {
        // SAFETY: our unused buffer.
        unsafe { d.fns.destroy_buffer(buffer, None) };
        return Err("no host-visible coherent memory type".into());
    };
    let alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(type_index);
    // SAFETY: a valid allocate info; on failure our buffer is destroyed.
    let memory = match unsafe { d.fns.allocate_memory(&alloc, None) } {
        Ok(m) => m,
        Err(e) => {
            // SAFETY: our unused buffer.
            unsafe { d.fns.destroy_buffer(buffer, None) };
            return Err(e.to_string());
        }
    };
    // SAFETY: fresh memory of the right type and size, mapped once, written, unmapped; coherent,
    // so the writes are visible to the queue submissions that follow.
    let r = unsafe {
        d.fns.bind_buffer_memory(buffer, memory, 0).and_then(|_| {
            let p = d.fns.map_memory(memory, 0, size, vk::MemoryMapFlags::empty())? as *mut T;
            std::ptr::copy_nonoverlapping(vertices.as_ptr(), p, vertices.len());
            d.fns.unmap_memory(memory);
            Ok(())
        })
    };
    if let Err(e) = r {
        // SAFETY: ours, never used by the GPU.
        unsafe {
            d.fns.destroy_buffer(buffer, None);
            d.fns.free_memory(memory, None);
        }
        return Err(e.to_string());
    }
    Ok((buffer, memory))
}

/// Destroys every layer object of the device (at vkDestroyDevice, before calling down; the app has
/// waited for the device to go idle).
pub(crate) fn destroy(d: &DeviceState) {
    let o = std::mem::take(&mut *lock(&d.mask.objects));
    // SAFETY: our objects; the device is idle.
    unsafe {
        for p in o.pipelines.values() {
            d.fns.destroy_pipeline(*p, None);
        }
        for b in &o.buffers {
            d.fns.destroy_buffer(b.buffer, None);
            d.fns.free_memory(b.memory, None);
        }
        d.fns.destroy_pipeline_layout(o.layout, None);
        for m in o.modules.all() {
            d.fns.destroy_shader_module(m, None);
        }
    }
}

/// Records one state command the app had in effect.
///
/// # Safety
/// `cb` must be recording; the command's handles are the app's, still valid.
pub(super) unsafe fn replay(d: &DeviceState, cb: vk::CommandBuffer, c: &StateCmd) {
    let v0 = d.fns.fp_v1_0();
    let v3 = d.fns.fp_v1_3();
    let vp = |v: &crate::track::cmd::Viewport| vk::Viewport { x: v.x, y: v.y, width: v.width, height: v.height, min_depth: v.min_depth, max_depth: v.max_depth };
    let rc = |r: &crate::track::cmd::Rect| vk::Rect2D { offset: vk::Offset2D { x: r.x, y: r.y }, extent: vk::Extent2D { width: r.width, height: r.height } };
    // SAFETY: per this function's contract; arrays live across each call.
    unsafe {
        match c {
            StateCmd::BindPipeline(p) => (v0.cmd_bind_pipeline)(cb, vk::PipelineBindPoint::GRAPHICS, vk::Pipeline::from_raw(*p)),
            StateCmd::SetViewport { first, viewports } => {
                let v: Vec<_> = viewports.iter().map(vp).collect();
                (v0.cmd_set_viewport)(cb, *first, v.len() as u32, v.as_ptr())
            }
            StateCmd::SetViewportWithCount(viewports) => {
                let v: Vec<_> = viewports.iter().map(vp).collect();
                (v3.cmd_set_viewport_with_count)(cb, v.len() as u32, v.as_ptr())
            }
            StateCmd::SetScissor { first, scissors } => {
                let s: Vec<_> = scissors.iter().map(rc).collect();
                (v0.cmd_set_scissor)(cb, *first, s.len() as u32, s.as_ptr())
            }
            StateCmd::SetScissorWithCount(scissors) => {
                let s: Vec<_> = scissors.iter().map(rc).collect();
                (v3.cmd_set_scissor_with_count)(cb, s.len() as u32, s.as_ptr())
            }
            StateCmd::LineWidth(w) => (v0.cmd_set_line_width)(cb, *w),
            StateCmd::DepthBias { constant_factor, clamp, slope_factor } => (v0.cmd_set_depth_bias)(cb, *constant_factor, *clamp, *slope_factor),
            StateCmd::BlendConstants(c) => (v0.cmd_set_blend_constants)(cb, c),
            StateCmd::DepthBounds { min, max } => (v0.cmd_set_depth_bounds)(cb, *min, *max),
            StateCmd::StencilCompareMask { face, mask } => (v0.cmd_set_stencil_compare_mask)(cb, *face, *mask),
            StateCmd::StencilWriteMask { face, mask } => (v0.cmd_set_stencil_write_mask)(cb, *face, *mask),
            StateCmd::StencilReference { face, reference } => (v0.cmd_set_stencil_reference)(cb, *face, *reference),
            StateCmd::CullMode(m) => (v3.cmd_set_cull_mode)(cb, *m),
            StateCmd::FrontFace(f) => (v3.cmd_set_front_face)(cb, *f),
            StateCmd::PrimitiveTopology(t) => (v3.cmd_set_primitive_topology)(cb, *t),
            StateCmd::DepthTestEnable(e) => (v3.cmd_set_depth_test_enable)(cb, (*e).into()),
            StateCmd::DepthWriteEnable(e) => (v3.cmd_set_depth_write_enable)(cb, (*e).into()),
            StateCmd::DepthCompareOp(op) => (v3.cmd_set_depth_compare_op)(cb, *op),
            StateCmd::DepthBoundsTestEnable(e) => (v3.cmd_set_depth_bounds_test_enable)(cb, (*e).into()),
            StateCmd::StencilTestEnable(e) => (v3.cmd_set_stencil_test_enable)(cb, (*e).into()),
            StateCmd::StencilOp { face, fail_op, pass_op, depth_fail_op, compare_op } => {
                (v3.cmd_set_stencil_op)(cb, *face, *fail_op, *pass_op, *depth_fail_op, *compare_op)
            }
            StateCmd::RasterizerDiscardEnable(e) => (v3.cmd_set_rasterizer_discard_enable)(cb, (*e).into()),
            StateCmd::DepthBiasEnable(e) => (v3.cmd_set_depth_bias_enable)(cb, (*e).into()),
            StateCmd::PrimitiveRestartEnable(e) => (v3.cmd_set_primitive_restart_enable)(cb, (*e).into()),
            StateCmd::LineStipple { factor, pattern } => {
                if let Some(f) = d.ext.cmd_set_line_stipple {
                    f(cb, *factor, *pattern)
                }
            }
            StateCmd::ColorWriteEnable(v) => {
                if let Some(f) = d.ext.cmd_set_color_write_enable {
                    let b: Vec<vk::Bool32> = v.iter().map(|&x| x.into()).collect();
                    f(cb, b.len() as u32, b.as_ptr())
                }
            }
            StateCmd::LogicOp(op) => {
                if let Some(f) = d.ext.cmd_set_logic_op {
                    f(cb, *op)
                }
            }
            StateCmd::PatchControlPoints(n) => {
                if let Some(f) = d.ext.cmd_set_patch_control_points {
                    f(cb, *n)
                }
            }
            StateCmd::PushConstants { layout, stages, offset, data } => {
                (v0.cmd_push_constants)(cb, vk::PipelineLayout::from_raw(*layout), *stages, *offset, data.len() as u32, data.as_ptr().cast())
            }
            StateCmd::BindVertexBuffers { first, bindings } => {
                let buffers: Vec<vk::Buffer> = bindings.iter().map(|b| vk::Buffer::from_raw(b.buffer)).collect();
                let offsets: Vec<u64> = bindings.iter().map(|b| b.offset).collect();
                let n = buffers.len() as u32;
                if bindings.iter().any(|b| b.v2) {
                    let sizes: Vec<u64> = bindings.iter().map(|b| b.size.unwrap_or(vk::WHOLE_SIZE)).collect();
                    let strides: Option<Vec<u64>> = bindings.iter().map(|b| b.stride).collect();
                    let has_sizes = bindings.iter().any(|b| b.size.is_some());
                    (v3.cmd_bind_vertex_buffers2)(
                        cb,
                        *first,
                        n,
                        buffers.as_ptr(),
                        offsets.as_ptr(),
                        if has_sizes { sizes.as_ptr() } else { std::ptr::null() },
                        strides.as_ref().map_or(std::ptr::null(), |s| s.as_ptr()),
                    )
                } else {
                    (v0.cmd_bind_vertex_buffers)(cb, *first, n, buffers.as_ptr(), offsets.as_ptr())
                }
            }
        }
    }
}

/// The viewport of an injected depth draw: the eye's rect, with the depth range pinned to the fail
/// depth so one pipeline serves both depth conventions.
pub(super) fn fail_viewport(r: PixelRect, fail_depth: f32) -> vk::Viewport {
    vk::Viewport {
        x: r.x as f32,
        y: r.y as f32,
        width: r.width as f32,
        height: r.height as f32,
        min_depth: fail_depth,
        max_depth: fail_depth,
    }
}

pub(super) fn rect2d(r: PixelRect) -> vk::Rect2D {
    vk::Rect2D { offset: vk::Offset2D { x: r.x, y: r.y }, extent: vk::Extent2D { width: r.width, height: r.height } }
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
    }
}
