//! Radial density masking's reconstruction at an eye pass's end as the compute pass over periphery
//! tiles (`shaders/rdm_recon.comp`, `FROM_LINK`), as the release path reconstructs: the eye rects
//! are copied into a device-local pixel buffer, one indirect dispatch fills the skipped quads of
//! every eye's periphery tiles, and the tiles' rows (or, for eyes known only at submission, the
//! render area) are copied back. Used where the target's format has a compute storage
//! (`rules::ComputeStorage`: 8-bit RGBA/BGRA, 16-bit float) and the layer gave it TRANSFER_SRC and
//! TRANSFER_DST (`RdmDevice::image_usage`); `pass_end_vk` falls back to the fragment fill
//! elsewhere.
//!
//! Why not the fill everywhere: the fill evaluates the rule 52 times per skipped quad in a
//! fragment shader over the whole eye, the compute pass 9 times per quad over periphery tiles
//! only (docs/benchmarks.md, "RDM behind post chains": about 5 ms per eye on an H100).
//!
//! The eyes' parameters, their tiles and the dispatch's size live in the recording's link buffer
//! (host-visible, written when the recording is made or, for a pass planned at submission, at
//! each submission), so the dispatch needs no push constants and leaves the app's alone.

use super::compute::{self, ReconParams, Shader};
use super::rules::{ComputeStorage, Pending};
use super::vk::{lock, RdmDevice};
use crate::core::rect::PixelRect;
use crate::plugin::vk::inject::restore::RestoreCompute;
use crate::plugin::vk::lifetime::{Garbage, PooledBuffer};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::sync::{Arc, Mutex};

/// Eyes a link holds at most (`shaders/rdm_recon.comp` `eyes[8]`).
pub(super) const EYES_MAX: usize = 8;
/// The link buffer: the dispatch's arguments (16 bytes), `EYES_MAX` eyes, then the tiles (a word
/// each: x | y << 12 | eye << 24, in tiles of the eye's rect).
const EYES_AT: u64 = 16;
const TILES_AT: u64 = EYES_AT + EYES_MAX as u64 * std::mem::size_of::<ReconParams>() as u64;
/// Tile coordinates a link word holds.
const TILE_COORD_MAX: u32 = 1 << 12;

/// The device-local pixel buffer every pass-end reconstruction of a device shares (each
/// recording's copy into it waits for earlier recordings' uses: the first barrier of `record`).
/// Replaced by a larger one when a target needs more; destroyed through the device's trash when
/// the last recording holding it is done.
pub(super) struct SharedPixels {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    size: u64,
    trash: Arc<Mutex<Vec<Garbage>>>,
}

impl Drop for SharedPixels {
    fn drop(&mut self) {
        lock(&self.trash).push(Garbage::Buffer(self.buffer, self.memory));
    }
}

/// Where a pass's eyes sit in the pixel buffer.
#[derive(Clone, Debug, PartialEq)]
enum Placement {
    /// Known at recording: eye `i`'s clip (its rect within the image) from texel `bases[i]`.
    Eyes { clips: Vec<PixelRect>, bases: Vec<u64> },
    /// Known at each submission: layer `layers[k]`'s `area` (the render area within the image)
    /// from texel `k × area`.
    Layers { area: PixelRect, layers: Vec<u32> },
}

/// What a pass-end compute reconstruction needs, made while its pass is open.
pub(super) struct Prepared {
    storage: ComputeStorage,
    pixels: Arc<SharedPixels>,
    /// (pipeline layout, set layout, pipeline) of `Shader::Link(storage)`.
    objects: (vk::PipelineLayout, vk::DescriptorSetLayout, vk::Pipeline),
    placement: Placement,
    /// The layers reconstructed (each gets the layout barriers).
    layers: Vec<u32>,
    copy_in: Vec<vk::BufferImageCopy>,
    /// What the dispatch can change: the eyes' tile rows (eyes known at recording) or the render
    /// area of each layer (known at submission).
    copy_back: Vec<vk::BufferImageCopy>,
    /// Tiles the link buffer has room for.
    tiles_max: usize,
}

/// The eyes of a pass-end reconstruction, as `prepare` needs them.
pub(super) enum EyesAt<'a> {
    Recorded(&'a [Pending]),
    Submitted { area: PixelRect, layers: &'a [u32] },
}

/// The compute pass for a target of `format`, `usage` and `extent` (its mip 0), or why not (the
/// fill runs instead).
pub(super) fn prepare(me: &RdmDevice, d: &DeviceState, (format, usage, extent): (vk::Format, vk::ImageUsageFlags, (u32, u32)), eyes: EyesAt<'_>) -> Result<Prepared, String> {
    let storage = ComputeStorage::for_format(format).ok_or_else(|| format!("format {format:?}"))?;
    if !usage.contains(vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST) {
        return Err("no TRANSFER_SRC | TRANSFER_DST usage (made before the layer was on)".into());
    }
    let whole = PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 };
    let texel = storage.texel_bytes();
    let region = |layer: u32, clip: PixelRect, base: u64, r: PixelRect| vk::BufferImageCopy {
        buffer_offset: texel * (base + (r.y - clip.y) as u64 * clip.width as u64 + (r.x - clip.x) as u64),
        buffer_row_length: clip.width,
        buffer_image_height: 0,
        image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 },
        image_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
        image_extent: vk::Extent3D { width: r.width, height: r.height, depth: 1 },
    };
    let (placement, layers, texels, copy_in, copy_back, tiles_max) = match eyes {
        EyesAt::Recorded(eyes) => {
            if eyes.len() > EYES_MAX {
                return Err(format!("{} eyes in one pass", eyes.len()));
            }
            let clips: Vec<PixelRect> = eyes.iter().map(|p| p.params.rect.intersect(&whole)).collect();
            let mut bases = Vec::new();
            let mut texels = 0u64;
            for c in &clips {
                bases.push(texels);
                texels += c.area();
            }
            let copy_in = eyes.iter().zip(clips.iter().zip(&bases)).filter(|(_, (c, _))| c.area() > 0).map(|(p, (c, b))| region(p.layer, *c, *b, *c)).collect();
            // Back: only the tiles' pixels can have changed (a run of tiles in a row is one region).
            let mut back = Vec::new();
            let mut tiles = 0;
            for (i, p) in eyes.iter().enumerate() {
                let list = me.reconstruct.compute.tiles_of(&p.params, clips[i]);
                tiles += list.len();
                back.extend(compute::tile_spans(&p.params, &list, clips[i]).into_iter().map(|r| region(p.layer, clips[i], bases[i], r)));
            }
            let mut layers: Vec<u32> = eyes.iter().map(|p| p.layer).collect();
            layers.sort_unstable();
            layers.dedup();
            (Placement::Eyes { clips, bases }, layers, texels, copy_in, back, tiles)
        }
        EyesAt::Submitted { area, layers } => {
            let area = area.intersect(&whole);
            if area.area() == 0 || layers.len() * 2 > EYES_MAX {
                return Err(format!("render area {area:?} in {} layers", layers.len()));
            }
            let regions: Vec<vk::BufferImageCopy> = layers.iter().enumerate().map(|(k, &l)| region(l, area, k as u64 * area.area(), area)).collect();
            // Eyes are in the area; their tile grids start at their own rects, so a rect's tiles
            // over the area are at most one more per row and column than the area's.
            let tile_px = 2 * super::rules::TILE_QUADS;
            let per_eye = (area.width.div_ceil(tile_px) + 1) as usize * (area.height.div_ceil(tile_px) + 1) as usize;
            (Placement::Layers { area, layers: layers.to_vec() }, layers.to_vec(), layers.len() as u64 * area.area(), regions.clone(), regions, 2 * layers.len() * per_eye)
        }
    };
    if texels == 0 {
        return Err("nothing of the eyes inside the image".into());
    }
    let objects = compute::objects(d, Shader::Link(storage))?;
    let pixels = shared_pixels(me, d, texels * texel)?;
    Ok(Prepared { storage, pixels, objects, placement, layers, copy_in, copy_back, tiles_max })
}

fn shared_pixels(me: &RdmDevice, d: &DeviceState, size: u64) -> Result<Arc<SharedPixels>, String> {
    if let Some(p) = lock(&me.pass_end).pixels.as_ref().filter(|p| p.size >= size) {
        return Ok(p.clone());
    }
    // Rounded up, so a target that grows a little (dynamic resolution) does not make one per
    // frame.
    let size = size.next_multiple_of(1 << 20);
    let (buffer, memory, size) = compute::pixel_buffer(d, size).map_err(|(_, e)| e)?;
    let made = Arc::new(SharedPixels { buffer, memory, size, trash: d.lifetime.trash.clone() });
    let mut o = lock(&me.pass_end);
    // Another thread may have made one meanwhile: the larger stays (the other goes to the trash
    // when its last holder is done).
    match o.pixels.as_ref() {
        Some(p) if p.size >= size => Ok(p.clone()),
        _ => {
            o.pixels = Some(made.clone());
            Ok(made)
        }
    }
}

/// A link's compute side: its descriptor set over the shared pixels and the link buffer, in a
/// pool of its own that goes to the trash with it; where its eyes go.
pub(super) struct LinkCompute {
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    trash: Arc<Mutex<Vec<Garbage>>>,
    storage: ComputeStorage,
    placement: Placement,
    tiles_max: usize,
    /// Eyes known at recording: the dispatch's size, fixed at link time.
    frozen: Option<u32>,
}

impl Drop for LinkCompute {
    fn drop(&mut self) {
        lock(&self.trash).push(Garbage::DescriptorPool(self.pool));
    }
}

/// The link buffer's size for `p`.
pub(super) fn link_size(p: &Prepared) -> u64 {
    TILES_AT + 4 * p.tiles_max.max(1) as u64
}

/// The link's compute side over `buffer` (`link_size` bytes); for eyes known at recording, their
/// parameters and tiles are written now.
pub(super) fn link(me: &RdmDevice, d: &DeviceState, p: &Prepared, buffer: &PooledBuffer, recorded: Option<&[Pending]>) -> Result<LinkCompute, String> {
    let sizes = [vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 2 }];
    // SAFETY: valid create / allocate infos on the app's device; the set points at live buffers
    // (the shared pixels and the link buffer, both held by the recording with the link).
    let (pool, set) = unsafe {
        let pool = d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None).map_err(|e| format!("descriptor pool: {e}"))?;
        let layouts = [p.objects.1];
        let set = match d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts)) {
            Ok(s) => s[0],
            Err(e) => {
                d.fns.destroy_descriptor_pool(pool, None);
                return Err(format!("descriptor set: {e}"));
            }
        };
        let infos = [vk::DescriptorBufferInfo { buffer: p.pixels.buffer, offset: 0, range: vk::WHOLE_SIZE }, vk::DescriptorBufferInfo { buffer: buffer.buffer, offset: 0, range: link_size(p) }];
        let writes = [
            vk::WriteDescriptorSet::default().dst_set(set).dst_binding(0).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&infos[..1]),
            vk::WriteDescriptorSet::default().dst_set(set).dst_binding(1).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&infos[1..]),
        ];
        d.fns.update_descriptor_sets(&writes, &[]);
        (pool, set)
    };
    let mut c = LinkCompute { pool, set, trash: d.lifetime.trash.clone(), storage: p.storage, placement: p.placement.clone(), tiles_max: p.tiles_max, frozen: None };
    if let Some(eyes) = recorded {
        let groups = c.write_eyes(me, buffer, eyes).ok_or("the eyes' tiles do not fit the link")?;
        c.frozen = Some(groups);
    }
    Ok(c)
}

impl LinkCompute {
    /// Writes `eyes`' parameters and tiles into `buffer`; the dispatch's size, or None when they
    /// do not fit (too many eyes, an eye's layer not reconstructed, too many tiles).
    fn write_eyes(&self, me: &RdmDevice, buffer: &PooledBuffer, eyes: &[Pending]) -> Option<u32> {
        if eyes.len() > EYES_MAX {
            return None;
        }
        let mut params = Vec::with_capacity(eyes.len());
        let mut words: Vec<u32> = Vec::new();
        for (slot, p) in eyes.iter().enumerate() {
            let (clip, base) = match &self.placement {
                Placement::Eyes { clips, bases } => (*clips.get(slot)?, *bases.get(slot)?),
                Placement::Layers { area, layers } => (*area, layers.iter().position(|&l| l == p.layer)? as u64 * area.area()),
            };
            params.push(ReconParams::of(p, self.storage, clip, base, 0));
            for t in me.reconstruct.compute.tiles_of(&p.params, clip).iter() {
                let (x, y) = (t & 0xffff, t >> 16);
                if x >= TILE_COORD_MAX || y >= TILE_COORD_MAX {
                    return None;
                }
                words.push(x | y << 12 | (slot as u32) << 24);
            }
        }
        if words.len() > self.tiles_max {
            return None;
        }
        (buffer.write(EYES_AT, &params) && buffer.write(TILES_AT, &words)).then_some(words.len() as u32)
    }

    /// The dispatch on (`on`: the eyes known at recording) or off.
    pub(super) fn arm(&self, buffer: &PooledBuffer, on: bool) {
        let groups = self.frozen.filter(|_| on).unwrap_or(0);
        buffer.write(0, &[groups, 1, 1, 0]);
    }

    /// Eyes known at submission: written with the dispatch's size; false (nothing dispatched)
    /// when they do not fit.
    pub(super) fn fill_submitted(&self, me: &RdmDevice, buffer: &PooledBuffer, eyes: &[Pending]) -> bool {
        match self.write_eyes(me, buffer, eyes) {
            Some(groups) => buffer.write(0, &[groups, 1, 1, 0]),
            None => {
                buffer.write(0, &[0u32, 1, 1, 0]);
                false
            }
        }
    }
}

/// Records the reconstruction into `cb` right after the eye pass ended: the target's layers
/// (`image`, left by the pass in `before`) to the pixel buffer, the dispatch, the changed pixels
/// back, the layers back to `before` behind a barrier every later command waits for; then the
/// app's compute bindings. False when the app's compute state cannot be restored (nothing is
/// recorded then).
pub(super) fn record(d: &DeviceState, cb: vk::CommandBuffer, p: &Prepared, image: vk::Image, before: vk::ImageLayout, (buffer, c): (&PooledBuffer, &LinkCompute)) -> bool {
    let compute = match d.track.with_cb(cb.as_raw(), |s| (s.veto, s.compute.clone())) {
        Some((None, compute)) => compute,
        _ => return false,
    };
    let (layout, _, pipeline) = p.objects;
    let pixels = p.pixels.buffer;
    let barrier = |(old, new): (vk::ImageLayout, vk::ImageLayout), (src, dst): (vk::AccessFlags, vk::AccessFlags)| -> Vec<vk::ImageMemoryBarrier> {
        p.layers.iter().map(|&l| crate::plugin::vk::gpu::image_barrier(image, super::fill::color_range(l, 1), (old, new), (src, dst))).collect()
    };
    let pixel_barrier = |src, dst| compute::buffer_barrier(pixels, src, dst);
    let fns = &d.fns;
    // SAFETY: `cb` is the app's command buffer, recording outside any pass (its eye pass just
    // ended); the target is the pass's attachment in `before`; the pixel buffer is held by the
    // recording (below), the link buffer and set with the link; `RestoreCompute` rebinds the
    // app's compute state before anything else is recorded; arrays outlive the calls.
    unsafe {
        // The pass's writes (and its resolve) before the copy reads the target; earlier
        // recordings' uses of the shared pixel buffer (their dispatch and copy back) before this
        // copy overwrites it.
        let first = barrier((before, vk::ImageLayout::TRANSFER_SRC_OPTIMAL), (vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::TRANSFER_READ));
        let earlier = pixel_barrier(vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_WRITE);
        let waits = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COMPUTE_SHADER;
        fns.cmd_pipeline_barrier(cb, waits, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[earlier], &first);
        fns.cmd_copy_image_to_buffer(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, pixels, &p.copy_in);
        let rw = vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE;
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::COMPUTE_SHADER, vk::DependencyFlags::empty(), &[], &[pixel_barrier(vk::AccessFlags::TRANSFER_WRITE, rw)], &[]);
        {
            let _restore = RestoreCompute::new(d, cb, compute);
            fns.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
            fns.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &[c.set], &[]);
            fns.cmd_dispatch_indirect(cb, buffer.buffer, 0);
        }
        // The shader's writes before the copy back; the copy-in's reads of the target before the
        // copy back overwrites it.
        let back = barrier((vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (vk::AccessFlags::TRANSFER_READ, vk::AccessFlags::TRANSFER_WRITE));
        let src = vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER;
        fns.cmd_pipeline_barrier(cb, src, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[pixel_barrier(vk::AccessFlags::SHADER_WRITE, vk::AccessFlags::TRANSFER_READ)], &back);
        if !p.copy_back.is_empty() {
            fns.cmd_copy_buffer_to_image(cb, pixels, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &p.copy_back);
        }
        // Back to the app's layout; every later command (whatever the app synchronizes with
        // next, even only its pass's external dependency) waits for the copy.
        let last = barrier((vk::ImageLayout::TRANSFER_DST_OPTIMAL, before), (vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE));
        fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &last);
    }
    crate::plugin::vk::lifetime::hold(d, cb.as_raw(), p.pixels.clone());
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_layout_matches_the_shader() {
        // std430: uvec4 dispatch_args; Params eyes[8] (5 × 16 bytes each); uint tiles[].
        assert_eq!(EYES_AT, 16);
        assert_eq!(TILES_AT, 16 + 8 * 80);
    }
}
