//! Radial density masking's reconstruction at the end of an eye pass whose target a post chain
//! reads (`pass_end` says which image and layout): recorded into the app's command buffer right
//! after the pass, so no tonemap, bloom or TAA ever samples the checkerboard: by the compute pass
//! over periphery tiles (`pass_end_compute`) where the target's format and usage allow, else the
//! eye rects are copied into a layer temp image and the full-screen fill (`fill`,
//! `shaders/rdm_fill.frag`) draws the skipped quads back from it. Then the image returns to the
//! layout the app left it in, behind a barrier every later command waits for.
//!
//! The checkerboard and the fill are one unit: both are indirect draws whose arguments the
//! recording's buffers hold, written for the rule's parameters the fill was recorded with
//! (`Link::frozen`). When the fovea or the views move on, or the fill could not be recorded,
//! both draw nothing — a pass is foveated and reconstructed, or left whole, never holed.

use crate::features::foveation::FoveationSettings;
use super::fill::{color_range, fill_objects_for, make_temp, record_fill, FillDraws, FillSource, FillTarget, FillVertex, Temp, EYES_PER_LAYER};
use super::pass_end::{self, PassEndTarget};
use super::pass_end_compute::{self, EyesAt, LinkCompute};
use super::rules::{NotApplied, Pending};
use super::vk::{lock, log_once, RdmDevice};
use crate::core::rect::PixelRect;
use crate::track::eye_pass::EyeDraw;
use crate::track::resources::ImageView;
use crate::plugin::vk::inject::{self, restore};
use crate::plugin::vk::lifetime::{Garbage, PooledBuffer};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// What ties a recording's checkerboard to its reconstruction at the pass's end.
pub(super) struct Link {
    /// The fill's indirect draws (`slots` of them), then — for a pass planned at submission — its
    /// vertices (`FillVertex`, three per eye); for the compute pass, its dispatch, eyes and tiles
    /// (`pass_end_compute`).
    pub(super) fill_args: PooledBuffer,
    pub(super) slots: usize,
    /// Recorded with the pass: (foveation generation, views generation) and the eyes the fill's
    /// push constants are for. None: the fill reads its eyes from the buffer, filled at each
    /// submission (`fill_submitted`).
    pub(super) frozen: Option<((u64, u64), Vec<EyeDraw>)>,
    /// The target's layers the fill draws into, in framebuffer order (two slots each).
    pub(super) layers: Vec<u32>,
    /// The fill was recorded after the pass (`record`): until then, and if it never is, the
    /// checkerboard draws nothing.
    pub(super) recorded: AtomicBool,
    /// The compute pass's side, where it reconstructs instead of the fill.
    compute: Option<LinkCompute>,
    /// The target's layer of an eye in layer `l` of the eye pass's image (`PassEndTarget`).
    layer_offset: i64,
}

impl Link {
    /// The link of `prepared`'s reconstruction of `eyes`; `frozen`: the generations and eyes the
    /// checkerboard is recorded for (eyes known at recording). Off until armed.
    pub(super) fn new(me: &RdmDevice, d: &DeviceState, prepared: &Prepared, eyes: &Eyes, frozen: Option<((u64, u64), Vec<EyeDraw>)>) -> Result<Arc<Link>, NotApplied> {
        let (slots, layers) = match eyes {
            Eyes::Recorded(list) => (list.len(), Vec::new()),
            Eyes::Submitted { layers, .. } => (layers.len() * EYES_PER_LAYER, layers.clone()),
        };
        let size = match &prepared.how {
            How::Compute(c) => pass_end_compute::link_size(c),
            How::Fill { .. } => Link::size(slots, matches!(eyes, Eyes::Submitted { .. })),
        };
        let fail = |what: &'static str, e: String| {
            d.warn_repeated(what, &e);
            NotApplied::LayerError
        };
        let fill_args = PooledBuffer::take(d, size, &me.memory).map_err(|e| fail("rdm pass-end arguments", e))?;
        let compute = match &prepared.how {
            How::Compute(c) => {
                let recorded = match eyes {
                    Eyes::Recorded(list) => Some(list.as_slice()),
                    Eyes::Submitted { .. } => None,
                };
                Some(pass_end_compute::link(me, d, c, &fill_args, recorded).map_err(|e| fail("rdm pass-end compute link", e))?)
            }
            How::Fill { .. } => None,
        };
        let link = Link { fill_args, slots, frozen, layers, recorded: AtomicBool::new(false), compute, layer_offset: prepared.target.layer_offset };
        link.arm(false);
        Ok(Arc::new(link))
    }
    /// Whether the compute pass reconstructs (else the fill).
    pub(super) fn is_compute(&self) -> bool {
        self.compute.is_some()
    }
    /// The buffer size a link of `slots` draws (and, planned at submission, two eyes' vertices)
    /// needs.
    fn size(slots: usize, submitted: bool) -> u64 {
        inject::DRAW_ARGS * slots as u64 + if submitted { (EYES_PER_LAYER * 3 * std::mem::size_of::<FillVertex>()) as u64 } else { 0 }
    }
    fn vertex_offset(&self) -> u64 {
        inject::DRAW_ARGS * self.slots as u64
    }
    /// The fill's draws (one full-screen triangle per eye) or the dispatch on (`on`) or off.
    pub(super) fn arm(&self, on: bool) {
        if let Some(c) = &self.compute {
            return c.arm(&self.fill_args, on && self.frozen.is_some());
        }
        let args = vk::DrawIndirectCommand { vertex_count: if on && self.frozen.is_some() { 3 } else { 0 }, instance_count: 1, first_vertex: 0, first_instance: 0 };
        self.fill_args.write(0, &vec![args; self.slots]);
    }
    /// Whether the checkerboard may draw under `key` now.
    pub(super) fn allows(&self, key: &((u64, u64), Vec<EyeDraw>)) -> bool {
        self.recorded.load(Ordering::Acquire) && self.frozen.as_ref().is_none_or(|f| f == key)
    }
    /// Planned at submission: the fill draws `eyes` (their triangles and parameters), each in its
    /// layer's framebuffer; false (nothing drawn) when an eye has no slot.
    pub(super) fn fill_submitted(&self, me: &RdmDevice, eyes: &[Pending]) -> bool {
        // In the target's layers.
        let mut moved = Vec::with_capacity(eyes.len());
        for p in eyes {
            let Ok(layer) = u32::try_from(p.layer as i64 + self.layer_offset) else { return false };
            moved.push(Pending { layer, ..*p });
        }
        let eyes = &moved;
        if let Some(c) = &self.compute {
            return c.fill_submitted(me, &self.fill_args, eyes);
        }
        let mut args = vec![vk::DrawIndirectCommand::default(); self.slots];
        let mut vertices = Vec::new();
        let mut used = vec![0usize; self.layers.len()];
        for p in eyes {
            let Some(li) = self.layers.iter().position(|&l| l == p.layer) else { return false };
            if used[li] >= EYES_PER_LAYER || vertices.len() >= EYES_PER_LAYER * 3 {
                return false;
            }
            args[li * EYES_PER_LAYER + used[li]] = vk::DrawIndirectCommand { vertex_count: 3, instance_count: 1, first_vertex: vertices.len() as u32, first_instance: 0 };
            used[li] += 1;
            vertices.extend(FillVertex::triangle(p));
        }
        self.fill_args.write(self.vertex_offset(), &vertices) && self.fill_args.write(0, &args)
    }
}

/// A layer temp image of one shape with the fill's descriptor set over it, shared by every
/// recording that reconstructs an image of that shape (each recording's copy into it waits for
/// earlier fills' reads: the first barrier of `record`). Destroyed through the device's trash
/// when the last recording holding it is done.
pub(super) struct SharedTemp {
    temp: Option<Temp>,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    trash: Arc<Mutex<Vec<Garbage>>>,
}

impl Drop for SharedTemp {
    fn drop(&mut self) {
        if let Some(t) = self.temp.take() {
            let mut trash = lock(&self.trash);
            trash.push(Garbage::Image(t.view, t.image, t.memory));
            trash.push(Garbage::DescriptorPool(self.pool));
        }
    }
}

/// The pass-end objects of a device: the compute pass's pixel buffer, the fill's temps by shape,
/// and views + framebuffers of the app's targets by (image, layer) — destroyed with the image
/// (the app waits for its work first).
#[derive(Default)]
pub(super) struct PassEndObjects {
    pub(super) pixels: Option<Arc<pass_end_compute::SharedPixels>>,
    temps: HashMap<(vk::Format, u32, u32, u32), Arc<SharedTemp>>,
    framebuffers: HashMap<(u64, u32), (vk::ImageView, vk::Framebuffer)>,
}

/// What a pass-end reconstruction needs, made while its pass is open (`prepare`).
pub(super) struct Prepared {
    target: PassEndTarget,
    extent: (u32, u32),
    how: How,
}

/// Which reconstruction, with its objects.
enum How {
    Compute(pass_end_compute::Prepared),
    Fill {
        temp: Arc<SharedTemp>,
        /// (layer, framebuffer of the target's layer for the fill's render pass).
        framebuffers: Vec<(u32, vk::Framebuffer)>,
        /// The fill's pipeline layout, render pass and pipeline for the target's format.
        fill: (vk::PipelineLayout, vk::RenderPass, vk::Pipeline),
    },
}

/// A reconstruction waiting for its pass's end in a command buffer.
pub(super) struct Job {
    prepared: Prepared,
    eyes: Eyes,
    link: Arc<Link>,
}

/// The eyes a job reconstructs.
pub(super) enum Eyes {
    /// Known at recording: each eye's rect is copied, and its parameters pushed with its draw.
    Recorded(Vec<Pending>),
    /// Known at each submission: the render area of every layer in `layers` is copied, and the
    /// reconstruction's eyes come from the link's buffer.
    Submitted { area: PixelRect, layers: Vec<u32> },
}

struct Views<'a>(&'a DeviceState);

impl pass_end::Objects for Views<'_> {
    fn view(&self, view: u64) -> Option<Arc<ImageView>> {
        self.0.track.views.get(view)
    }
    fn samples(&self, image: u64) -> Option<vk::SampleCountFlags> {
        self.0.track.images.get(image).map(|i| i.samples)
    }
}

/// The layers of `eye_image`'s colour attachment in `pass` whose pixels the pass-end target holds
/// (its view's range): where a pass whose eyes are known only at submission may show them.
pub(super) fn pass_layers(d: &DeviceState, pass: &crate::track::cmd::PassInstance, eye_image: u64) -> Vec<u32> {
    let Ok(t) = pass_end::target(pass, eye_image, &Views(d)) else { return Vec::new() };
    let total = d.track.images.get(t.view.image).map_or(1, |i| i.array_layers);
    let n = t.view.range.layers_of(total).min(pass.view_mask().count_ones().max(1));
    // In the eye's image (`prepare` moves them to the target's).
    (t.view.range.base_array_layer..t.view.range.base_array_layer + n).filter_map(|l| u32::try_from(l as i64 - t.layer_offset).ok()).collect()
}

/// Everything a pass-end reconstruction of `eyes` (in `eye_image`'s pass `pass`) needs, made now,
/// while the pass is open: the checkerboard goes in only if this succeeds.
/// `eyes` are moved to the target's layers (`PassEndTarget::layer_offset`).
pub(super) fn prepare(me: &RdmDevice, d: &DeviceState, pass: &crate::track::cmd::PassInstance, eye_image: u64, eyes: &mut Eyes) -> Result<Prepared, NotApplied> {
    let target = pass_end::target(pass, eye_image, &Views(d))?;
    let shift = |l: u32| u32::try_from(l as i64 + target.layer_offset).map_err(|_| NotApplied::TargetUsage);
    match eyes {
        Eyes::Recorded(list) => {
            for p in list.iter_mut() {
                p.layer = shift(p.layer)?;
            }
        }
        Eyes::Submitted { layers, .. } => {
            for l in layers.iter_mut() {
                *l = shift(*l)?;
            }
        }
    }
    if target.after_subpass {
        log_once(me, format!("after subpass {:#x}", target.view.image), || {
            tracing::info!("radial density masking: an eye pass into {eye_image:#x} is read by a later subpass of its render pass (a tonemap); its holes are filled in that subpass's output {:#x} when the render pass ends", target.view.image)
        });
    }
    let image = d.track.images.get(target.view.image).ok_or(NotApplied::TargetUsage)?;
    if !pass_end::usage_ok(image.usage) || target.view.range.base_mip_level != 0 || image.extent.depth > 1 {
        return Err(NotApplied::TargetUsage);
    }
    let (width, height, layers) = (image.extent.width, image.extent.height, image.array_layers.max(1));
    let format = image.format;
    let (mut layer_list, source, at) = match eyes {
        Eyes::Recorded(list) => (list.iter().map(|p| p.layer).collect::<Vec<u32>>(), FillSource::PushConstants, EyesAt::Recorded(list)),
        Eyes::Submitted { area, layers } => (layers.clone(), FillSource::VertexBuffer, EyesAt::Submitted { area: *area, layers }),
    };
    layer_list.sort_unstable();
    layer_list.dedup();
    if layer_list.is_empty() || layer_list.iter().any(|&l| l >= layers) {
        return Err(NotApplied::TargetUsage);
    }
    let compute = if d.settings().of::<FoveationSettings>().rdm_reconstruction == crate::features::foveation::Reconstruction::Fill {
        Err("foveation.rdm_reconstruction = fill".to_string())
    } else {
        pass_end_compute::prepare(me, d, (format, image.usage, (width, height)), at)
    };
    match compute {
        Ok(c) => return Ok(Prepared { target, extent: (width, height), how: How::Compute(c) }),
        // The fill at a pass's end costs more than the checkerboard saves at moderate loads on
        // the GPUs measured (docs/benchmarks.md, "RDM behind post chains": 11.5 → 14.7 ms where
        // the compute pass gives 8.8), so `foveation.method = auto` leaves such passes whole.
        Err(why) if d.settings().of::<FoveationSettings>().method != crate::features::foveation::Method::Rdm => {
            log_once(me, format!("pass end auto {why}"), || {
                tracing::info!("radial density masking leaves eye passes into {:#x} (behind a post chain) whole with foveation.method = auto: only the fragment fill could reconstruct them ({why}), which costs more than it saves at moderate loads; foveation.method = \"rdm\" applies it", image.handle)
            });
            return Err(NotApplied::PostChain);
        }
        Err(why) => log_once(me, format!("pass end fill {why}"), || tracing::info!("radial density masking: the fragment fill reconstructs eye passes into {:#x} at their end, not the compute pass ({why})", image.handle)),
    }
    let fail = |what: String| {
        log_once(me, format!("pass end {what}"), || tracing::warn!("radial density masking: no reconstruction at the pass's end for {:#x} ({what}): such passes are left whole", image.handle));
        NotApplied::TargetUsage
    };
    let (layout, set_layout, render_pass, pipeline, sampler) = fill_objects_for(d, (format, source)).map_err(fail)?;
    let temp = shared_temp(me, d, format, (width, height, layers), set_layout, sampler).map_err(|(_, e)| fail(e))?;
    let mut framebuffers = Vec::new();
    for layer in layer_list {
        framebuffers.push((layer, framebuffer(me, d, image.handle, format, layer, (width, height), render_pass).map_err(fail)?));
    }
    Ok(Prepared { target, extent: (width, height), how: How::Fill { temp, framebuffers, fill: (layout, render_pass, pipeline) } })
}

impl Job {
    pub(super) fn new(prepared: Prepared, eyes: Eyes, link: Arc<Link>) -> Job {
        Job { prepared, eyes, link }
    }
}

fn shared_temp(me: &RdmDevice, d: &DeviceState, format: vk::Format, shape: (u32, u32, u32), set_layout: vk::DescriptorSetLayout, sampler: vk::Sampler) -> Result<Arc<SharedTemp>, (NotApplied, String)> {
    let key = (format, shape.0, shape.1, shape.2);
    if let Some(t) = lock(&me.pass_end).temps.get(&key) {
        return Ok(t.clone());
    }
    let t = make_temp(d, format, vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::SAMPLED, shape)?;
    let sizes = [vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 1 }];
    let mut shared = SharedTemp { temp: Some(t), pool: vk::DescriptorPool::null(), set: vk::DescriptorSet::null(), trash: d.lifetime.trash.clone() };
    // SAFETY: valid create / allocate infos on the app's device; on failure `shared` drops and
    // hands what was made to the trash (nothing uses it yet).
    unsafe {
        shared.pool = d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None).map_err(super::reconstruct::layer_error("descriptor pool"))?;
        let layouts = [set_layout];
        shared.set = d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(shared.pool).set_layouts(&layouts)).map_err(super::reconstruct::layer_error("descriptor set"))?[0];
        let view = shared.temp.as_ref().map_or(vk::ImageView::null(), |t| t.view);
        let infos = [vk::DescriptorImageInfo { sampler, image_view: view, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
        let write = vk::WriteDescriptorSet::default().dst_set(shared.set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&infos);
        d.fns.update_descriptor_sets(&[write], &[]);
    }
    let shared = Arc::new(shared);
    let mut o = lock(&me.pass_end);
    // Another thread may have made one meanwhile: keep the first, ours goes to the trash.
    Ok(o.temps.entry(key).or_insert(shared).clone())
}

fn framebuffer(me: &RdmDevice, d: &DeviceState, image: u64, format: vk::Format, layer: u32, (width, height): (u32, u32), render_pass: vk::RenderPass) -> Result<vk::Framebuffer, String> {
    if let Some((_, fb)) = lock(&me.pass_end).framebuffers.get(&(image, layer)) {
        return Ok(*fb);
    }
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 };
    // SAFETY: the app's live image (its pass is being recorded); our view and framebuffer,
    // destroyed with the image (`destroyed`).
    unsafe {
        let view = d
            .fns
            .create_image_view(&vk::ImageViewCreateInfo::default().image(vk::Image::from_raw(image)).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(range), None)
            .map_err(|e| format!("view: {e}"))?;
        let views = [view];
        let fb = match d.fns.create_framebuffer(&vk::FramebufferCreateInfo::default().render_pass(render_pass).attachments(&views).width(width).height(height).layers(1), None) {
            Ok(f) => f,
            Err(e) => {
                d.fns.destroy_image_view(view, None);
                return Err(format!("framebuffer: {e}"));
            }
        };
        let mut o = lock(&me.pass_end);
        if let Some((_, existing)) = o.framebuffers.get(&(image, layer)) {
            let existing = *existing;
            drop(o);
            d.fns.destroy_framebuffer(fb, None);
            d.fns.destroy_image_view(view, None);
            return Ok(existing);
        }
        o.framebuffers.insert((image, layer), (view, fb));
        Ok(fb)
    }
}

/// The app destroyed `image`: its views and framebuffers of ours go (its work is complete).
pub(super) fn image_destroyed(me: &RdmDevice, d: &DeviceState, image: u64) {
    let gone: Vec<(vk::ImageView, vk::Framebuffer)> = {
        let mut o = lock(&me.pass_end);
        let keys: Vec<(u64, u32)> = o.framebuffers.keys().filter(|k| k.0 == image).copied().collect();
        keys.into_iter().filter_map(|k| o.framebuffers.remove(&k)).collect()
    };
    for (view, fb) in gone {
        // SAFETY: the app may destroy an image only once no pending work uses it, ours included.
        unsafe {
            d.fns.destroy_framebuffer(fb, None);
            d.fns.destroy_image_view(view, None);
        }
    }
}

/// At vkDestroyDevice (idle): everything of ours.
pub(super) fn destroy(me: &RdmDevice, d: &DeviceState) {
    let o = std::mem::take(&mut *lock(&me.pass_end));
    for (_, (view, fb)) in o.framebuffers {
        // SAFETY: the device is idle.
        unsafe {
            d.fns.destroy_framebuffer(fb, None);
            d.fns.destroy_image_view(view, None);
        }
    }
    drop(o.temps);
}

/// Records `job` into `cb`, just after the eye pass ended: copy, fill (`fill::record_fill`), back
/// to the app's layout; then the app's bound state. Returns false when the app's state could not
/// be restored (the fill is then not recorded, and the checkerboard stays off).
pub(super) fn record(d: &DeviceState, cb: vk::CommandBuffer, job: &Job) -> bool {
    let key = cb.as_raw();
    if d.settings().of::<FoveationSettings>().rdm_reconstruction == crate::features::foveation::Reconstruction::Off {
        // `foveation.rdm_reconstruction = off` (a measurement setting): the holes stay, as at
        // the release.
        job.link.recorded.store(true, Ordering::Release);
        return true;
    }
    let p = &job.prepared;
    let image = vk::Image::from_raw(p.target.view.image);
    let (temp, framebuffers, fill) = match &p.how {
        How::Compute(c) => {
            let Some(link) = job.link.compute.as_ref() else { return false };
            if !pass_end_compute::record(d, cb, c, image, p.target.layout, (&job.link.fill_args, link)) {
                return false;
            }
            job.link.recorded.store(true, Ordering::Release);
            return true;
        }
        How::Fill { temp, framebuffers, fill } => (temp, framebuffers, *fill),
    };
    let Some((restore_cmds, sets, veto)) = d.track.with_cb(key, |s| (s.restore_commands(), s.descriptor_set_commands(), s.veto)) else { return false };
    if veto.is_some() {
        return false;
    }
    let Some(temp_image) = temp.temp.as_ref() else { return false };
    let (width, height) = p.extent;
    let target = FillTarget { image, before: p.target.layout, whole: PixelRect { x: 0, y: 0, width, height }, framebuffers };
    let draws = match &job.eyes {
        Eyes::Recorded(eyes) => FillDraws::Pushed { eyes, args: Some(job.link.fill_args.buffer) },
        Eyes::Submitted { area, .. } => FillDraws::FromBuffer { area: *area, buffer: job.link.fill_args.buffer, vertex_offset: job.link.vertex_offset() },
    };
    let bound_sets = std::cell::Cell::new(true);
    {
        let _restore = restore::Restore::new(d, cb, &restore_cmds, &sets, &bound_sets);
        // SAFETY: `cb` is the app's command buffer, recording outside any pass (its eye pass just
        // ended); the target is the pass's attachment in `p.target.layout`; every object of ours
        // is held by the recording (the checkerboard data with the link's buffer, the temp's Arc
        // below) or lives until the image dies (the framebuffers).
        unsafe {
            record_fill(d, cb, &target, (temp_image.image, temp_image.key.3, temp.set), fill, draws);
            // Back to the app's layout; every later command (whatever the app synchronizes with
            // next, even only its pass's external dependency) waits for the fill.
            let last: Vec<vk::ImageMemoryBarrier> = framebuffers
                .iter()
                .map(|(l, _)| {
                    crate::plugin::vk::gpu::image_barrier(target.image, color_range(*l, 1), (vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, p.target.layout), (vk::AccessFlags::COLOR_ATTACHMENT_WRITE, vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE))
                })
                .collect();
            d.fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &last);
        }
    }
    crate::plugin::vk::lifetime::hold(d, key, temp.clone());
    job.link.recorded.store(true, Ordering::Release);
    true
}
