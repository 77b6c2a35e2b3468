//! Radial density masking's reconstruction as a compute pass over periphery tiles only: the eye
//! rects are copied into a storage buffer of the layer's, `shaders/rdm_recon.comp` fills the
//! skipped quads of the tiles `rules::RdmParams::periphery_tiles` lists (a pooled host buffer),
//! and the tiles' rows are copied back. The full-screen fragment fill (`reconstruct`) stays as the
//! fallback for images this cannot handle (`rules::compute_path`).
//!
//! Why compute and not an indirect draw of the skipped quads: the draw needs a primitive per quad
//! (hundreds of thousands per eye), which a software rasterizer pays for in setup and binning; a
//! workgroup per 8×8-quad tile evaluates the rule once per quad (shared memory) instead of 13 times
//! per pixel, and reads each neighbour once per quad. Why a buffer and not a storage image: the
//! app's images need no STORAGE usage (sRGB swapchains cannot have it on most GPUs), and on
//! lavapipe a word load is far cheaper than an image load (measured: docs/benchmarks.md). The copy
//! back needs TRANSFER_DST, which the foveation feature adds to colour swapchains.

use super::reconstruct::{layer_error, Failure};
use super::rules::{ComputeStorage, NotApplied, Pending, RdmParams};
use super::vk::lock;
use crate::core::rect::PixelRect;
use crate::plugin::vk::lifetime::PooledBuffer;
use crate::plugin::vk::DeviceState;
use ash::vk;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

static RECON: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_recon.comp.spv"));
static RECON_LINK: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_recon_link.comp.spv"));
static RECON_LINK_HALF: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_recon_link_half.comp.spv"));

/// Which variant of `shaders/rdm_recon.comp`: at a swapchain image's release (8-bit texels,
/// parameters pushed per eye; `rules::compute_path`) or at an eye pass's end (`FROM_LINK`:
/// parameters and tiles in the recording's link buffer, one indirect dispatch, no push
/// constants), for 8-bit or 16-bit float texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Shader {
    Release,
    Link(ComputeStorage),
}

impl Shader {
    fn spirv(self) -> &'static [u8] {
        match self {
            Shader::Release => RECON,
            Shader::Link(ComputeStorage::Rgba8 { .. }) => RECON_LINK,
            Shader::Link(ComputeStorage::Rgba16F) => RECON_LINK_HALF,
        }
    }
    /// sRGB or not is a parameter of the shader, not a variant.
    fn key(self) -> Shader {
        match self {
            Shader::Link(ComputeStorage::Rgba8 { .. }) => Shader::Link(ComputeStorage::Rgba8 { srgb: false }),
            other => other,
        }
    }
}

/// Push constants of shaders/rdm_recon.comp; at a pass's end, an eye of the link buffer.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct ReconParams {
    rect: [i32; 4],
    tan: [f32; 4],
    fovea: [f32; 4],
    /// First word of the eye in the pixel buffer, first tile of the eye in the tile buffer, sRGB,
    /// unused.
    misc: [i32; 4],
    /// The eye's rect within the image: what the pixel buffer holds of it.
    clip: [i32; 4],
}

impl ReconParams {
    /// Eye `p`, whose pixels are `clip` of the image from texel `first_texel` of the pixel
    /// buffer and whose tiles start at `first_tile` (release path; the link's tiles name their eye).
    pub(super) fn of(p: &Pending, storage: ComputeStorage, clip: PixelRect, first_texel: u64, first_tile: i32) -> ReconParams {
        let (r, q) = (p.params.rect, &p.params);
        ReconParams {
            rect: [r.x, r.y, r.width as i32, r.height as i32],
            tan: [q.tan_left, q.tan_up, q.step_x, q.step_y],
            fovea: [q.center[0], q.center[1], q.k_inner, q.k_middle],
            misc: [first_texel as i32, first_tile, storage.srgb() as i32, 0],
            clip: [clip.x, clip.y, clip.width as i32, clip.height as i32],
        }
    }
    /// The push constants' bytes, field by field (no padding between 4-byte fields).
    pub(super) fn bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(std::mem::size_of::<ReconParams>());
        out.extend(self.rect.iter().flat_map(|v| v.to_ne_bytes()));
        out.extend(self.tan.iter().chain(&self.fovea).flat_map(|v| v.to_ne_bytes()));
        out.extend(self.misc.iter().chain(&self.clip).flat_map(|v| v.to_ne_bytes()));
        out
    }
}

pub(super) use crate::plugin::vk::gpu::buffer_barrier;

/// The compute pass's shared objects of one device, made on first use: one set layout (pixels,
/// tiles or link), a pipeline layout with the release's push constants and one without, and a
/// pipeline per shader variant.
pub(super) struct ComputeObjects {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    plain_layout: vk::PipelineLayout,
    pipelines: HashMap<Shader, (vk::ShaderModule, vk::Pipeline)>,
}

/// Per device: the objects and the tile lists of recent eyes (the rule's parameters change with
/// the fovea; a fixed fovea reuses its list every frame).
#[derive(Default)]
pub(super) struct Compute {
    objects: Mutex<Option<ComputeObjects>>,
    tiles: Mutex<HashMap<TileKey, Arc<Vec<u32>>>>,
}

/// An eye's rule parameters and clip, bit for bit.
type TileKey = [u32; 16];

fn tile_key(p: &RdmParams, clip: PixelRect) -> TileKey {
    let r = p.rect;
    [
        r.x as u32,
        r.y as u32,
        r.width,
        r.height,
        p.tan_left.to_bits(),
        p.tan_up.to_bits(),
        p.step_x.to_bits(),
        p.step_y.to_bits(),
        p.center[0].to_bits(),
        p.center[1].to_bits(),
        p.k_inner.to_bits(),
        p.k_middle.to_bits(),
        clip.x as u32,
        clip.y as u32,
        clip.width,
        clip.height,
    ]
}

impl Compute {
    pub(super) fn tiles_of(&self, p: &RdmParams, clip: PixelRect) -> Arc<Vec<u32>> {
        let key = tile_key(p, clip);
        if let Some(t) = lock(&self.tiles).get(&key) {
            return t.clone();
        }
        let t = Arc::new(p.periphery_tiles(clip));
        let mut cache = lock(&self.tiles);
        if cache.len() >= 16 {
            cache.clear();
        }
        cache.insert(key, t.clone());
        t
    }

    /// At vkDestroyDevice (the device is idle).
    pub(super) fn destroy(&self, d: &DeviceState) {
        // Taken in a statement of its own: a guard in the `if let` scrutinee lives through the
        // block, which calls down.
        let objects = lock(&self.objects).take();
        if let Some(o) = objects {
            // SAFETY: our objects; the device is idle, nothing uses them.
            unsafe { destroy_objects(d, o) };
        }
    }
}

/// # Safety
/// No submission using `o` may be pending.
unsafe fn destroy_objects(d: &DeviceState, o: ComputeObjects) {
    // SAFETY: per the contract.
    unsafe {
        for (module, pipeline) in o.pipelines.into_values() {
            d.fns.destroy_pipeline(pipeline, None);
            d.fns.destroy_shader_module(module, None);
        }
        d.fns.destroy_pipeline_layout(o.layout, None);
        d.fns.destroy_pipeline_layout(o.plain_layout, None);
        d.fns.destroy_descriptor_set_layout(o.set_layout, None);
    }
}

/// What a reconstruction slot keeps for the compute pass between uses (reused after its fence).
#[derive(Default)]
pub(super) struct SlotData {
    pub(super) set: vk::DescriptorSet,
    /// Device-local storage buffer of the eyes' pixels, with its size.
    pixels: Option<(vk::Buffer, vk::DeviceMemory, u64)>,
    tiles: Option<PooledBuffer>,
}

impl SlotData {
    /// # Safety
    /// No pending GPU work may use the slot's objects (its fence signalled).
    pub(super) unsafe fn destroy(&mut self, d: &DeviceState) {
        if let Some((b, m, _)) = self.pixels.take() {
            // SAFETY: per the contract.
            unsafe {
                d.fns.destroy_buffer(b, None);
                d.fns.free_memory(m, None);
            }
        }
        self.tiles = None;
    }
}

/// Makes the reconstruction's pipeline now, at the first RDM draw a command buffer records, so
/// its compilation (over a second on a CPU implementation) falls on the session's first frame,
/// not on a later image release in the middle of the app's frame pacing.
pub(super) fn warm(d: &DeviceState) {
    if let Err(e) = objects(d, Shader::Release) {
        // A failure of the layer's own objects is never silent (issue 11: tests/hardening/faults_vk.rs
        // found this one logged only at DEBUG): WARN once, DEBUG after; the reconstruction tries
        // again when it needs the pipeline, and a failure there turns it off for that image
        // (`NotApplied::LayerError`).
        static WARNED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
        if !WARNED.swap(true, std::sync::atomic::Ordering::Relaxed) {
            tracing::warn!("RDM compute pipeline not made ahead of use: {e}; tried again at first use");
        } else {
            tracing::debug!("RDM compute pipeline not made ahead of use: {e}");
        }
    }
}

/// The compute pass's pipeline and set layout, and `data`'s descriptor set from `descriptor_pool`:
/// made ahead of the checkerboard (`reconstruct::ready`), so a failure skips RDM for the pass
/// instead of leaving its holes unreconstructed at the image's release.
pub(super) fn ready(d: &DeviceState, data: &mut SlotData, descriptor_pool: vk::DescriptorPool) -> Result<(), Failure> {
    let (_, set_layout, _) = objects(d, Shader::Release).map_err(|e| (NotApplied::LayerError, format!("compute pipeline: {e}")))?;
    if data.set == vk::DescriptorSet::null() {
        let layouts = [set_layout];
        // SAFETY: the slot's pool has room for this one compute set (see `new_slot`).
        data.set = unsafe { d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(descriptor_pool).set_layouts(&layouts)) }
            .map_err(layer_error("compute descriptor set"))?[0];
    }
    Ok(())
}

/// (pipeline layout, set layout, pipeline) of `shader`, made on first use.
pub(super) fn objects(d: &DeviceState, shader: Shader) -> Result<(vk::PipelineLayout, vk::DescriptorSetLayout, vk::Pipeline), String> {
    let shader = shader.key();
    let objects = &super::vk::RdmDevice::of(d).reconstruct.compute.objects;
    let layout_of = |o: &ComputeObjects| if shader == Shader::Release { o.layout } else { o.plain_layout };
    let made = lock(objects).as_ref().map(|o| (layout_of(o), o.set_layout, o.pipelines.get(&shader).map(|p| p.1)));
    // Made with no lock held: the calls go down the chain, and what is below may call back into
    // the layer. A thread that loses the race to another destroys its own.
    let (layout, set_layout) = match made {
        Some((layout, set_layout, Some(pipeline))) => return Ok((layout, set_layout, pipeline)),
        Some((layout, set_layout, None)) => (layout, set_layout),
        None => {
            let new = create_layouts(d)?;
            let mut guard = lock(objects);
            match guard.as_ref() {
                Some(existing) => {
                    let kept = (layout_of(existing), existing.set_layout);
                    drop(guard);
                    // SAFETY: ours, never used.
                    unsafe { destroy_objects(d, new) };
                    kept
                }
                None => {
                    let kept = (layout_of(&new), new.set_layout);
                    *guard = Some(new);
                    kept
                }
            }
        }
    };
    let (module, pipeline) = create_pipeline(d, shader.spirv(), layout)?;
    let mut guard = lock(objects);
    let Some(o) = guard.as_mut() else {
        drop(guard);
        // SAFETY: ours, never used; the device's objects went meanwhile (vkDestroyDevice).
        unsafe {
            d.fns.destroy_pipeline(pipeline, None);
            d.fns.destroy_shader_module(module, None);
        }
        return Err("the device is being destroyed".into());
    };
    if let Some(&(_, existing)) = o.pipelines.get(&shader) {
        drop(guard);
        // SAFETY: ours, never used.
        unsafe {
            d.fns.destroy_pipeline(pipeline, None);
            d.fns.destroy_shader_module(module, None);
        }
        return Ok((layout, set_layout, existing));
    }
    o.pipelines.insert(shader, (module, pipeline));
    Ok((layout, set_layout, pipeline))
}

/// The set layout and both pipeline layouts.
fn create_layouts(d: &DeviceState) -> Result<ComputeObjects, String> {
    let binding = |b: u32| vk::DescriptorSetLayoutBinding::default().binding(b).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE);
    let bindings = [binding(0), binding(1)];
    // SAFETY: valid create infos on our device; on failure what was made is destroyed.
    unsafe {
        let set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(|e| e.to_string())?;
        let set_layouts = [set_layout];
        let ranges = [vk::PushConstantRange { stage_flags: vk::ShaderStageFlags::COMPUTE, offset: 0, size: std::mem::size_of::<ReconParams>() as u32 }];
        let layout = match d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges), None) {
            Ok(l) => l,
            Err(e) => {
                d.fns.destroy_descriptor_set_layout(set_layout, None);
                return Err(e.to_string());
            }
        };
        match d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts), None) {
            Ok(plain_layout) => Ok(ComputeObjects { set_layout, layout, plain_layout, pipelines: HashMap::new() }),
            Err(e) => {
                d.fns.destroy_pipeline_layout(layout, None);
                d.fns.destroy_descriptor_set_layout(set_layout, None);
                Err(e.to_string())
            }
        }
    }
}

fn create_pipeline(d: &DeviceState, spirv: &[u8], layout: vk::PipelineLayout) -> Result<(vk::ShaderModule, vk::Pipeline), String> {
    let words = ash::util::read_spv(&mut std::io::Cursor::new(spirv)).map_err(|e| e.to_string())?;
    // SAFETY: valid create infos on our device (SPIR-V 1.0 compiled at build time, nothing beyond
    // Vulkan 1.0 core); on failure the module is destroyed.
    unsafe {
        let module = d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None).map_err(|e| e.to_string())?;
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
        let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout);
        match d.fns.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) {
            Ok(p) => Ok((module, p[0])),
            Err((_, e)) => {
                d.fns.destroy_shader_module(module, None);
                Err(e.to_string())
            }
        }
    }
}

/// A device-local buffer for `size` bytes of pixels (copy target and source, storage).
pub(super) fn pixel_buffer(d: &DeviceState, size: u64) -> Result<(vk::Buffer, vk::DeviceMemory, u64), Failure> {
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
    let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: valid create / allocate infos on our device; failures destroy what was made.
    unsafe {
        let buffer = d.fns.create_buffer(&info, None).map_err(layer_error("pixel buffer"))?;
        let req = d.fns.get_buffer_memory_requirements(buffer);
        let mem = &super::vk::RdmDevice::of(d).reconstruct.memory;
        let index = crate::plugin::vk::lifetime::memory_type(mem, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)
            .or_else(|| crate::plugin::vk::lifetime::memory_type(mem, req.memory_type_bits, vk::MemoryPropertyFlags::empty()));
        let Some(index) = index else {
            d.fns.destroy_buffer(buffer, None);
            return Err((NotApplied::LayerError, "no memory type for the pixel buffer".into()));
        };
        let memory = d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(index), None);
        let bound = memory.and_then(|m| d.fns.bind_buffer_memory(buffer, m, 0).map(|_| m).inspect_err(|_| d.fns.free_memory(m, None)));
        match bound {
            Ok(m) => Ok((buffer, m, size)),
            Err(e) => {
                d.fns.destroy_buffer(buffer, None);
                Err((NotApplied::LayerError, format!("pixel memory: {e}")))
            }
        }
    }
}

/// The slot's pixel buffer (at least `pixel_bytes`), tile buffer (at least `tile_bytes`) and
/// compute descriptor set (allocated once from the slot's pool), the set pointed at both.
fn prepare(d: &DeviceState, data: &mut SlotData, descriptor_pool: vk::DescriptorPool, set_layout: vk::DescriptorSetLayout, pixel_bytes: u64, tile_bytes: u64) -> Result<(), Failure> {
    if data.pixels.is_none_or(|(_, _, size)| size < pixel_bytes) {
        if let Some((b, m, _)) = data.pixels.take() {
            // SAFETY: the slot's fence signalled: nothing uses them.
            unsafe {
                d.fns.destroy_buffer(b, None);
                d.fns.free_memory(m, None);
            }
        }
        data.pixels = Some(pixel_buffer(d, pixel_bytes)?);
    }
    if data.tiles.as_ref().is_none_or(|b| b.size < tile_bytes) {
        // The old buffer (if any) goes back to the pool: the slot's fence signalled.
        data.tiles = Some(PooledBuffer::take(d, tile_bytes, &super::vk::RdmDevice::of(d).reconstruct.memory).map_err(|e| (NotApplied::LayerError, format!("tile buffer: {e}")))?);
    }
    if data.set == vk::DescriptorSet::null() {
        let layouts = [set_layout];
        // SAFETY: the slot's pool has room for this one compute set (see `new_slot`).
        data.set = unsafe { d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(descriptor_pool).set_layouts(&layouts)) }
            .map_err(layer_error("compute descriptor set"))?[0];
    }
    let (pixels, tiles) = (data.pixels.expect("just made").0, data.tiles.as_ref().expect("just taken").buffer);
    let infos = [vk::DescriptorBufferInfo { buffer: pixels, offset: 0, range: vk::WHOLE_SIZE }, vk::DescriptorBufferInfo { buffer: tiles, offset: 0, range: vk::WHOLE_SIZE }];
    let writes = [
        vk::WriteDescriptorSet::default().dst_set(data.set).dst_binding(0).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&infos[..1]),
        vk::WriteDescriptorSet::default().dst_set(data.set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&infos[1..]),
    ];
    // SAFETY: the set is not in use (the slot's fence signalled); valid handles.
    unsafe { d.fns.update_descriptor_sets(&writes, &[]) };
    Ok(())
}

/// Records into `cb` (begun, the slot's) the reconstruction of `eyes` of the swapchain image
/// `image` (in COLOR_ATTACHMENT_OPTIMAL, as the app released it; left so): copy the eyes' rects
/// into the pixel buffer, one dispatch per eye over its periphery tiles, copy the tiles' rows
/// back. Returns the tiles dispatched.
#[allow(clippy::too_many_arguments)]
pub(super) fn record(
    d: &DeviceState,
    data: &mut SlotData,
    descriptor_pool: vk::DescriptorPool,
    cb: vk::CommandBuffer,
    image: vk::Image,
    storage: ComputeStorage,
    (width, height): (u32, u32),
    eyes: &[Pending],
) -> Result<u64, Failure> {
    if storage.texel_bytes() != 4 {
        // `rules::compute_path` sends only 8-bit swapchains here.
        return Err((NotApplied::LayerError, format!("{storage:?} texels at the release")));
    }
    let (layout, set_layout, pipeline) = objects(d, Shader::Release).map_err(|e| (NotApplied::LayerError, e))?;
    let texel = storage.texel_bytes();
    let whole = PixelRect { x: 0, y: 0, width, height };
    let me = &super::vk::RdmDevice::of(d).reconstruct.compute;
    let lists: Vec<Arc<Vec<u32>>> = eyes.iter().map(|p| me.tiles_of(&p.params, whole)).collect();
    let clips: Vec<PixelRect> = eyes.iter().map(|p| p.params.rect.intersect(&whole)).collect();
    // Each eye's pixels from word `bases[i]`, rows of its clip's width.
    let mut bases = Vec::with_capacity(eyes.len());
    let mut words = 0u64;
    for c in &clips {
        bases.push(words);
        words += c.area();
    }
    let total: usize = lists.iter().map(|l| l.len()).sum();
    prepare(d, data, descriptor_pool, set_layout, words.max(1) * texel, (total.max(1) * 4) as u64)?;
    let tiles_buf = data.tiles.as_ref().expect("prepared");
    let mut firsts = Vec::with_capacity(lists.len());
    let mut offset = 0u64;
    for l in &lists {
        firsts.push((offset / 4) as i32);
        tiles_buf.write(offset, l);
        offset += 4 * l.len() as u64;
    }
    let pixels = data.pixels.expect("prepared").0;
    let mut layers: Vec<u32> = eyes.iter().map(|p| p.layer).collect();
    layers.sort_unstable();
    layers.dedup();
    let range = |layer: u32| vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 };
    let swapchain_layers = |(from, src): (vk::ImageLayout, vk::AccessFlags), (to, dst): (vk::ImageLayout, vk::AccessFlags)| -> Vec<vk::ImageMemoryBarrier> {
        layers
            .iter()
            .map(|&l| crate::plugin::vk::gpu::image_barrier(image, range(l), (from, to), (src, dst)))
            .collect()
    };
    // A rect `r` of eye `i` (inside its clip) ↔ its words in the pixel buffer.
    let region = |i: usize, r: PixelRect| {
        let c = clips[i];
        vk::BufferImageCopy {
            buffer_offset: texel * (bases[i] + (r.y - c.y) as u64 * c.width as u64 + (r.x - c.x) as u64),
            buffer_row_length: c.width,
            buffer_image_height: 0,
            image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: eyes[i].layer, layer_count: 1 },
            image_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
            image_extent: vk::Extent3D { width: r.width, height: r.height, depth: 1 },
        }
    };
    let copy_in: Vec<vk::BufferImageCopy> = clips.iter().enumerate().filter(|(_, c)| c.area() > 0).map(|(i, c)| region(i, *c)).collect();
    // Back: only the tiles' pixels can have changed; a run of neighbouring tiles in a row is one
    // region (regions never overlap: tiles of one eye are disjoint, eyes' rects too).
    let copy_back: Vec<vk::BufferImageCopy> = eyes.iter().zip(&lists).enumerate().flat_map(|(i, (p, l))| tile_spans(&p.params, l, clips[i]).into_iter().map(move |r| (i, r))).map(|(i, r)| region(i, r)).collect();
    let buffer_barrier = |src, dst| buffer_barrier(pixels, src, dst);
    let fns = &d.fns;
    // SAFETY: `cb` is the slot's, begun; every handle is alive (the swapchain image is acquired
    // and not yet released; the pixel and tile buffers are the slot's, idle since its fence
    // signalled); arrays outlive the calls; push constants match the layout's range.
    unsafe {
        // The app's writes (rendering, or its resolve / copy into the image) finish before the
        // copy reads the image. The pixel buffer's earlier uses completed (the slot's fence).
        let first = swapchain_layers(
            (vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE),
            (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ),
        );
        let all_before = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::FRAGMENT_SHADER;
        fns.cmd_pipeline_barrier(cb, all_before, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &first);
        fns.cmd_copy_image_to_buffer(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, pixels, &copy_in);
        let rw = vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE;
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COMPUTE_SHADER, vk::DependencyFlags::empty(), &[], &[buffer_barrier(vk::AccessFlags::TRANSFER_WRITE, rw)], &[]);
        fns.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
        fns.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &[data.set], &[]);
        for (i, (p, l)) in eyes.iter().zip(&lists).enumerate() {
            if l.is_empty() || clips[i].area() == 0 {
                continue;
            }
            let pc = ReconParams::of(p, storage, clips[i], bases[i], firsts[i]);
            fns.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, &pc.bytes());
            fns.cmd_dispatch(cb, l.len() as u32, 1, 1);
        }
        // The shader's writes before the copy back; the copy-in's reads of the image before the
        // copy back overwrites it.
        let back = swapchain_layers((vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ), (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE));
        let src = vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER;
        fns.cmd_pipeline_barrier(cb, src, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[buffer_barrier(vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_READ)], &back);
        if !copy_back.is_empty() {
            fns.cmd_copy_buffer_to_image(cb, pixels, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &copy_back);
        }
        // As OpenXR requires at release: COLOR_ATTACHMENT_OPTIMAL; whatever reads the image next
        // (the runtime's compositor or capture) sees the reconstructed pixels.
        let last = swapchain_layers(
            (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE),
            (vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE),
        );
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &last);
    }
    Ok(total as u64)
}

/// The pixel rects the tiles of one eye cover within `clip`, a run of neighbouring tiles of a
/// row merged into one (the list is in row order).
pub(super) fn tile_spans(p: &RdmParams, tiles: &[u32], clip: PixelRect) -> Vec<PixelRect> {
    let tile_px = 2 * super::rules::TILE_QUADS as i32;
    let mut out = Vec::new();
    let mut run: Option<(u32, u32, u32)> = None;
    let mut flush = |(x0, x1, y): (u32, u32, u32)| {
        let r = PixelRect { x: p.rect.x + x0 as i32 * tile_px, y: p.rect.y + y as i32 * tile_px, width: (x1 - x0 + 1) * tile_px as u32, height: tile_px as u32 };
        let r = r.intersect(&p.rect).intersect(&clip);
        if r.area() > 0 {
            out.push(r);
        }
    };
    for &t in tiles {
        let (x, y) = (t & 0xffff, t >> 16);
        run = match run {
            Some((x0, x1, ry)) if ry == y && x1 + 1 == x => Some((x0, x, y)),
            Some(r) => {
                flush(r);
                Some((x, x, y))
            }
            None => Some((x, x, y)),
        };
    }
    if let Some(r) = run {
        flush(r);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shaders_are_spirv_and_spans_merge_rows() {
        assert_eq!(&RECON[..4], &0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
        assert_eq!(std::mem::size_of::<ReconParams>(), 80);
        let pc = ReconParams { rect: [1, 2, 3, 4], tan: [5.0; 4], fovea: [6.0; 4], misc: [7, 8, 9, 10], clip: [11, 12, 13, 14] };
        let b = pc.bytes();
        assert_eq!(b.len(), 80);
        assert_eq!((&b[0..4], &b[16..20], &b[32..36], &b[48..52], &b[64..68]), (&1i32.to_ne_bytes()[..], &5f32.to_ne_bytes()[..], &6f32.to_ne_bytes()[..], &7i32.to_ne_bytes()[..], &11i32.to_ne_bytes()[..]));
        let fov = crate::core::views::ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let fovea = crate::core::views::FoveaView { view: 0, center: [0.0, 0.0], inner_deg: 20.0, middle_deg: 35.0 };
        // Tiles of 32 px: row 0 tiles 0, 1, 2 → one span, clipped to the rect's 80 px; row 1
        // (8 px left of the rect): tiles 0 and 2, apart.
        assert_eq!(super::super::rules::TILE_QUADS, 16);
        let p = RdmParams::new(&fov, &fovea, PixelRect { x: 100, y: 0, width: 80, height: 40 }).unwrap();
        let spans = tile_spans(&p, &[0, 1, 2, 1 << 16, 2 | 1 << 16], PixelRect { x: 0, y: 0, width: 1000, height: 1000 });
        assert_eq!(
            spans,
            vec![
                PixelRect { x: 100, y: 0, width: 80, height: 32 },
                PixelRect { x: 100, y: 32, width: 32, height: 8 },
                PixelRect { x: 164, y: 32, width: 16, height: 8 },
            ]
        );
    }
}
