//! Radial density masking's reconstruction as a compute pass over periphery tiles only: the eye
//! rects are copied into a storage temp image, `shaders/rdm_recon.comp` fills the skipped quads of
//! the tiles `rules::RdmParams::periphery_tiles` lists (a pooled host buffer), and the tiles are
//! copied back. The full-screen fragment fill (`reconstruct`) stays as the fallback for images
//! this cannot handle (`rules::compute_path`).
//!
//! Why compute and not an indirect draw of the skipped quads: the draw needs a primitive per quad
//! (hundreds of thousands per eye), which a software rasterizer pays for in setup and binning; a
//! workgroup per 8×8-quad tile evaluates the rule once per quad (shared memory) instead of 13 times
//! per pixel, and reads each neighbour once per quad. Writing through a storage image of the
//! layer's own temp copy needs no STORAGE usage on the app's images (and works for sRGB
//! swapchains, which no GPU can bind as storage); the copy back needs TRANSFER_DST, which the
//! foveation feature adds to colour swapchains.

use super::reconstruct::{layer_error, make_temp, Failure, Temp};
use super::rules::{ComputeStorage, NotApplied, Pending, RdmParams};
use super::vk::lock;
use crate::core::rect::PixelRect;
use crate::vk::lifetime::PooledBuffer;
use crate::vk::DeviceState;
use ash::vk;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

static RECON: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_recon.comp.spv"));
static RECON_HALF: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_recon_half.comp.spv"));

/// Push constants of shaders/rdm_recon.comp.
#[repr(C)]
#[derive(Clone, Copy)]
struct ReconParams {
    rect: [i32; 4],
    tan: [f32; 4],
    fovea: [f32; 4],
    /// Array layer, first tile of the eye in the tile buffer, sRGB, unused.
    misc: [i32; 4],
    /// Image width and height, unused × 2.
    size: [i32; 4],
}

/// The compute pass's shared objects of one device, made on first use.
pub(super) struct ComputeObjects {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    /// Per storage kind (rgba8, rgba16f): module and pipeline.
    pipelines: HashMap<bool, (vk::ShaderModule, vk::Pipeline)>,
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
    fn tiles_of(&self, p: &RdmParams, clip: PixelRect) -> Arc<Vec<u32>> {
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
        if let Some(o) = lock(&self.objects).take() {
            // SAFETY: our objects; the device is idle, nothing uses them.
            unsafe {
                for (module, pipeline) in o.pipelines.values() {
                    d.fns.destroy_pipeline(*pipeline, None);
                    d.fns.destroy_shader_module(*module, None);
                }
                d.fns.destroy_pipeline_layout(o.layout, None);
                d.fns.destroy_descriptor_set_layout(o.set_layout, None);
            }
        }
    }
}

/// What a reconstruction slot keeps for the compute pass between uses (reused after its fence).
#[derive(Default)]
pub(super) struct SlotData {
    set: vk::DescriptorSet,
    temp: Option<Temp>,
    tiles: Option<PooledBuffer>,
}

impl SlotData {
    /// The temp image, for the slot's destruction.
    pub(super) fn take_temp(&mut self) -> Option<Temp> {
        self.temp.take()
    }
}

/// (pipeline layout, descriptor set layout, pipeline) for `storage`.
fn objects(d: &DeviceState, storage: ComputeStorage) -> Result<(vk::PipelineLayout, vk::DescriptorSetLayout, vk::Pipeline), String> {
    let half = storage == ComputeStorage::Rgba16f;
    let mut guard = lock(&d.features.rdm.reconstruct.compute.objects);
    // Creating a few objects under this lock is fine: these calls never re-enter the layer.
    if guard.is_none() {
        let bindings = [
            vk::DescriptorSetLayoutBinding::default().binding(0).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
            vk::DescriptorSetLayoutBinding::default().binding(1).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE),
        ];
        // SAFETY: valid create infos on our device; on failure what was made is destroyed.
        unsafe {
            let set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(|e| e.to_string())?;
            let set_layouts = [set_layout];
            let ranges = [vk::PushConstantRange { stage_flags: vk::ShaderStageFlags::COMPUTE, offset: 0, size: std::mem::size_of::<ReconParams>() as u32 }];
            let layout = d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges), None);
            let layout = layout.inspect_err(|_| d.fns.destroy_descriptor_set_layout(set_layout, None)).map_err(|e| e.to_string())?;
            *guard = Some(ComputeObjects { set_layout, layout, pipelines: HashMap::new() });
        }
    }
    let o = guard.as_mut().expect("just set");
    if let Some(&(_, p)) = o.pipelines.get(&half) {
        return Ok((o.layout, o.set_layout, p));
    }
    let words = ash::util::read_spv(&mut std::io::Cursor::new(if half { RECON_HALF } else { RECON })).map_err(|e| e.to_string())?;
    // SAFETY: valid SPIR-V compiled at build time (SPIR-V 1.0, nothing beyond Vulkan 1.0 core:
    // storage images of rgba8 / rgba16f need no feature); valid create infos.
    unsafe {
        let module = d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None).map_err(|e| e.to_string())?;
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main");
        let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(o.layout);
        match d.fns.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) {
            Ok(p) => {
                o.pipelines.insert(half, (module, p[0]));
                Ok((o.layout, o.set_layout, p[0]))
            }
            Err((_, e)) => {
                d.fns.destroy_shader_module(module, None);
                Err(e.to_string())
            }
        }
    }
}

/// The slot's storage temp image of the swapchain image's shape (created or kept), its compute
/// descriptor set (allocated once from the slot's pool), and a tile buffer of `tile_bytes`;
/// points the set at both.
fn prepare(
    d: &DeviceState,
    data: &mut SlotData,
    descriptor_pool: vk::DescriptorPool,
    set_layout: vk::DescriptorSetLayout,
    storage: ComputeStorage,
    shape: (u32, u32, u32),
    tile_bytes: u64,
) -> Result<(), Failure> {
    let format = storage.temp_format();
    let usage = vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::STORAGE;
    if data.temp.as_ref().map_or(true, |t| t.key != (format, shape.0, shape.1, shape.2)) {
        if let Some(t) = data.temp.take() {
            // SAFETY: the slot's fence signalled: nothing uses it.
            unsafe { super::reconstruct::destroy_temp(d, t) };
        }
        data.temp = Some(make_temp(d, format, usage, shape)?);
    }
    if data.tiles.as_ref().map_or(true, |b| b.size < tile_bytes) {
        // The old buffer (if any) goes back to the pool: the slot's fence signalled.
        data.tiles = Some(PooledBuffer::take(d, tile_bytes, &d.features.rdm.reconstruct.memory).map_err(|e| (NotApplied::LayerError, format!("tile buffer: {e}")))?);
    }
    if data.set == vk::DescriptorSet::null() {
        let layouts = [set_layout];
        // SAFETY: the slot's pool has room for this one compute set (see `new_slot`).
        data.set = unsafe { d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(descriptor_pool).set_layouts(&layouts)) }
            .map_err(layer_error("compute descriptor set"))?[0];
    }
    let (temp, tiles) = (data.temp.as_ref().expect("just made"), data.tiles.as_ref().expect("just taken"));
    let images = [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: temp.view, image_layout: vk::ImageLayout::GENERAL }];
    let buffers = [vk::DescriptorBufferInfo { buffer: tiles.buffer, offset: 0, range: vk::WHOLE_SIZE }];
    let writes = [
        vk::WriteDescriptorSet::default().dst_set(data.set).dst_binding(0).descriptor_type(vk::DescriptorType::STORAGE_IMAGE).image_info(&images),
        vk::WriteDescriptorSet::default().dst_set(data.set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&buffers),
    ];
    // SAFETY: the set is not in use (the slot's fence signalled); valid handles.
    unsafe { d.fns.update_descriptor_sets(&writes, &[]) };
    Ok(())
}

/// Records into `cb` (begun, the slot's) the reconstruction of `eyes` of the swapchain image
/// `image` (in COLOR_ATTACHMENT_OPTIMAL, as the app released it; left so): copy in, one dispatch
/// per eye over its periphery tiles, copy the tiles back. Returns the tiles dispatched.
#[allow(clippy::too_many_arguments)]
pub(super) fn record(
    d: &DeviceState,
    data: &mut SlotData,
    descriptor_pool: vk::DescriptorPool,
    cb: vk::CommandBuffer,
    image: vk::Image,
    storage: ComputeStorage,
    shape: (u32, u32, u32),
    eyes: &[Pending],
) -> Result<u64, Failure> {
    let (layout, set_layout, pipeline) = objects(d, storage).map_err(|e| (NotApplied::LayerError, e))?;
    let (width, height, layers_total) = shape;
    let whole = PixelRect { x: 0, y: 0, width, height };
    let me = &d.features.rdm.reconstruct.compute;
    let lists: Vec<Arc<Vec<u32>>> = eyes.iter().map(|p| me.tiles_of(&p.params, whole)).collect();
    let total: usize = lists.iter().map(|l| l.len()).sum();
    prepare(d, data, descriptor_pool, set_layout, storage, shape, (total.max(1) * 4) as u64)?;
    let tiles_buf = data.tiles.as_ref().expect("prepared");
    let mut firsts = Vec::with_capacity(lists.len());
    let mut offset = 0u64;
    for l in &lists {
        firsts.push(offset as i32 / 4);
        tiles_buf.write(offset, l);
        offset += 4 * l.len() as u64;
    }
    let temp = data.temp.as_ref().expect("prepared").image;
    let mut layers: Vec<u32> = eyes.iter().map(|p| p.layer).collect();
    layers.sort_unstable();
    layers.dedup();
    let range = |layer: u32, count: u32| vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: count };
    let layer_of = |layer: u32| vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 };
    let barrier = |img: vk::Image, r: vk::ImageSubresourceRange, (from, src): (vk::ImageLayout, vk::AccessFlags), (to, dst): (vk::ImageLayout, vk::AccessFlags)| {
        vk::ImageMemoryBarrier::default()
            .src_access_mask(src)
            .dst_access_mask(dst)
            .old_layout(from)
            .new_layout(to)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(img)
            .subresource_range(r)
    };
    let swapchain_layers = |from, to| -> Vec<vk::ImageMemoryBarrier> { layers.iter().map(|&l| barrier(image, range(l, 1), from, to)).collect() };
    let copy = |r: PixelRect, layer: u32| vk::ImageCopy {
        src_subresource: layer_of(layer),
        src_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
        dst_subresource: layer_of(layer),
        dst_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
        extent: vk::Extent3D { width: r.width, height: r.height, depth: 1 },
    };
    let copy_in: Vec<vk::ImageCopy> = eyes.iter().map(|p| copy(p.params.rect.intersect(&whole), p.layer)).filter(|c| c.extent.width > 0 && c.extent.height > 0).collect();
    // Back: only the tiles' pixels can have changed; a run of neighbouring tiles in a row is one
    // region (regions of one eye never overlap; eyes' rects do not overlap either).
    let mut copy_back = Vec::new();
    for (p, l) in eyes.iter().zip(&lists) {
        for span in tile_spans(&p.params, l, whole) {
            copy_back.push(copy(span, p.layer));
        }
    }
    let cm = vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE;
    let fns = &d.fns;
    // SAFETY: `cb` is the slot's, begun; every handle is alive (the swapchain image is acquired
    // and not yet released; the temp image and tile buffer are the slot's, idle since its fence
    // signalled); arrays outlive the calls; push constants match the layout's range.
    unsafe {
        // The app's writes finish before the copy reads the image; the temp's previous uses are
        // complete (the slot's fence), so its old contents may be discarded.
        let mut first = swapchain_layers((vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, cm), (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ));
        first.push(barrier(temp, range(0, layers_total), (vk::ImageLayout::UNDEFINED, vk::AccessFlags::empty()), (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE)));
        let all_before = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::FRAGMENT_SHADER;
        fns.cmd_pipeline_barrier(cb, all_before, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &first);
        fns.cmd_copy_image(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, temp, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &copy_in);
        let rw = vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE;
        let to_general = [barrier(temp, range(0, layers_total), (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE), (vk::ImageLayout::GENERAL, rw))];
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COMPUTE_SHADER, vk::DependencyFlags::empty(), &[], &[], &to_general);
        fns.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
        fns.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &[data.set], &[]);
        let srgb = matches!(storage, ComputeStorage::Rgba8 { srgb: true }) as i32;
        for ((p, l), first) in eyes.iter().zip(&lists).zip(&firsts) {
            if l.is_empty() {
                continue;
            }
            let r = p.params.rect;
            let pc = ReconParams {
                rect: [r.x, r.y, r.width as i32, r.height as i32],
                tan: [p.params.tan_left, p.params.tan_up, p.params.step_x, p.params.step_y],
                fovea: [p.params.center[0], p.params.center[1], p.params.k_inner, p.params.k_middle],
                misc: [p.layer as i32, *first, srgb, 0],
                size: [width as i32, height as i32, 0, 0],
            };
            let bytes = std::slice::from_raw_parts(&pc as *const ReconParams as *const u8, std::mem::size_of::<ReconParams>());
            fns.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, bytes);
            fns.cmd_dispatch(cb, l.len() as u32, 1, 1);
        }
        // The shader's writes before the copy back; the copy-in's reads of the swapchain image
        // before the copy back overwrites it.
        let mut back = swapchain_layers((vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ), (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE));
        back.push(barrier(temp, range(0, layers_total), (vk::ImageLayout::GENERAL, vk::AccessFlags::SHADER_WRITE), (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ)));
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &back);
        if !copy_back.is_empty() {
            fns.cmd_copy_image(cb, temp, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &copy_back);
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
fn tile_spans(p: &RdmParams, tiles: &[u32], clip: PixelRect) -> Vec<PixelRect> {
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
        for s in [RECON, RECON_HALF] {
            assert_eq!(&s[..4], &0x0723_0203u32.to_le_bytes(), "SPIR-V magic");
        }
        assert_eq!(std::mem::size_of::<ReconParams>(), 80);
        let fov = crate::shared::ViewFov { tan_left: -1.0, tan_right: 1.0, tan_up: 1.0, tan_down: -1.0 };
        let fovea = crate::shared::FoveaView { view: 0, center: [0.0, 0.0], inner_deg: 20.0, middle_deg: 35.0 };
        let p = RdmParams::new(&fov, &fovea, PixelRect { x: 100, y: 0, width: 40, height: 20 }).unwrap();
        // Row 0: tiles 0, 1, 2 → one span (clipped to the rect: 40 px); row 1: tiles 0 and 2.
        let spans = tile_spans(&p, &[0, 1, 2, 1 << 16, 2 | 1 << 16], PixelRect { x: 0, y: 0, width: 1000, height: 1000 });
        assert_eq!(
            spans,
            vec![
                PixelRect { x: 100, y: 0, width: 40, height: 16 },
                PixelRect { x: 100, y: 16, width: 16, height: 4 },
                PixelRect { x: 132, y: 16, width: 8, height: 4 },
            ]
        );
    }
}
