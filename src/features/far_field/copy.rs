//! The far field's source side: the slots (one colour + one depth image per view, read by the
//! reuse draws through one descriptor set) and the copies of a source eye's attachments into them
//! when its pass ends — the app's images go to TRANSFER_SRC for the copy and back to the layout
//! the pass left them in; the slots stay GENERAL for their whole life. Single-sampled slots are
//! filled by a compute pass (`super::compute`), which also reduces the depth to a range per tile
//! for the reuse draw's culling; multisampled ones by image copies (their tiles stay unknown).

use crate::features::far_field::FarFieldSettings;
use crate::core::rect::PixelRect;
use crate::plugin::settings::Settings;
use crate::track::cmd::{AttachmentUse, PassInstance};
use crate::track::eye_pass::EyeDraw;
use crate::plugin::vk::inject;
use crate::plugin::vk::lifetime::{self, Garbage};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, MutexGuard};

use super::rules::Stamp;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A layer image with its memory and view.
pub(super) struct Owned {
    pub(super) image: vk::Image,
    pub(super) memory: vk::DeviceMemory,
    pub(super) view: vk::ImageView,
}

/// The copies of both views: colour and depth per view, one descriptor set reading all four.
pub(super) struct Slots {
    pub(super) images: [[Owned; 2]; 2],
    pub(super) pool: vk::DescriptorPool,
    pub(super) set: vk::DescriptorSet,
    pub(super) extent: vk::Extent2D,
    /// The app's formats the slots were made for.
    pub(super) color_format: vk::Format,
    pub(super) depth_format: vk::Format,
    pub(super) samples: vk::SampleCountFlags,
    /// Filled by the compute copy (single-sampled: RGBA16F colour, R32F depth, STORAGE usage);
    /// else by image copies in the app's formats.
    pub(super) compute: bool,
    pub(super) initialized: AtomicBool,
    /// What each slot holds, as of the submissions seen so far: the copy's stamp and its extent.
    pub(super) copied: Mutex<[Option<(Stamp, PixelRect)>; 2]>,
    /// Both slots' per-tile depth ranges (`rules::tile_grid` of `extent`, slot 0's rows first),
    /// NaN where not reduced.
    pub(super) tiles: vk::Buffer,
    tiles_memory: vk::DeviceMemory,
    pub(super) grid: (u32, u32),
    pub(super) trash: Arc<Mutex<Vec<Garbage>>>,
}

/// The tile entries' fill where a slot was not reduced: NaN, which the reuse draw reads as unknown.
pub(super) const NOT_REDUCED: u32 = 0x7fc0_0000;

impl Slots {
    /// The bytes of one slot's tile ranges.
    pub(super) fn tile_bytes(&self) -> u64 {
        self.grid.0 as u64 * self.grid.1 as u64 * 8
    }
}


impl Drop for Slots {
    fn drop(&mut self) {
        let mut t = lock(&self.trash);
        for slot in &mut self.images {
            for o in slot.iter_mut() {
                t.push(Garbage::Image(std::mem::take(&mut o.view), std::mem::take(&mut o.image), std::mem::take(&mut o.memory)));
            }
        }
        t.push(Garbage::DescriptorPool(std::mem::take(&mut self.pool)));
        t.push(Garbage::Buffer(std::mem::take(&mut self.tiles), std::mem::take(&mut self.tiles_memory)));
    }
}

/// A pass recorded before its eyes were known (`inject::Awaiting`): which view a guessed draw
/// really is, and its rect, get decided at submission, from the eyes known then.
pub(super) struct AwaitPass {
    pub(super) pass: PassInstance,
    pub(super) fail_depth: f32,
    /// Tied to its eyes by the data-flow walk (counted at each submission), not by the OpenXR
    /// half's first frame.
    pub(super) walk: bool,
}

impl AwaitPass {
    /// The rect of the guessed view's eye (guessed over `rect`, in `layer`) of this pass
    /// (`rules::resolve_guess`; `at_origin` for a copy); otherwise why, to count (None: the pass
    /// is no eye pass after all, or has no eye of that view).
    pub(super) fn resolve_or_why(&self, d: &DeviceState, intermediate: bool, (view, layer, rect): (u32, u32, PixelRect), at_origin: bool) -> Result<(u32, PixelRect), Option<&'static str>> {
        let plan = match inject::plan_now(d, &self.pass, self.fail_depth, intermediate) {
            Ok(p) => p,
            Err(crate::core::pass::NotMasked::NotEyePass) => return Err(None),
            Err(why) => return Err(Some(why.name())),
        };
        let eyes: Vec<(u32, u32, PixelRect)> = plan.draws.iter().map(|dr| (dr.view, dr.layer, dr.viewport)).collect();
        super::rules::resolve_guess(&eyes, (view, layer, rect), at_origin)
    }
}

/// A recording copies `view`'s pixels (`rect` of layer `layer` of its image) into slot `view`.
pub(super) struct CopyOp {
    pub(super) view: u32,
    pub(super) rect: PixelRect,
    pub(super) layer: u32,
    pub(super) slots: Arc<Slots>,
    pub(super) awaiting: Option<Arc<AwaitPass>>,
    /// The walked target and the eye it copies (`PendingCopy::walked`).
    pub(super) walked: Option<(u64, EyeDraw)>,
}

/// An attachment to copy at the pass's end.
#[derive(Clone, Copy)]
pub(super) struct Source {
    pub(super) image: vk::Image,
    pub(super) format: vk::Format,
    pub(super) layout: vk::ImageLayout,
    pub(super) aspect: vk::ImageAspectFlags,
    pub(super) base_layer: u32,
}

/// What the end of an injected pass copies.
pub(super) struct PendingCopy {
    pub(super) slots: Arc<Slots>,
    pub(super) color: Source,
    pub(super) depth: Source,
    pub(super) draws: Vec<EyeDraw>,
    pub(super) multiview: bool,
    pub(super) awaiting: Option<Arc<AwaitPass>>,
    /// The pass's target, when the data-flow walk tied it to its eyes (checked at submission:
    /// `inject::walk_moved`).
    pub(super) walked: Option<u64>,
}

/// Records the copies of the source views of the pass that just ended in `cb`.
///
/// Returns why it could not, if so (then the slots keep what they had: no copy is noted).
pub(super) fn record(d: &DeviceState, cb: vk::CommandBuffer, p: PendingCopy, s: &Settings, copier: Option<&super::compute::Copier>) -> Result<(), &'static str> {
    let sources: Vec<EyeDraw> = p.draws.iter().filter(|dr| s.of::<FarFieldSettings>().alternate || dr.view == s.of::<FarFieldSettings>().source_view).copied().collect();
    if sources.is_empty() {
        return Ok(());
    }
    if p.slots.compute {
        let copier = copier.ok_or("layer_error")?;
        super::compute::record(d, cb, &p, &sources, copier)?;
    } else {
        record_transfer(d, cb, &p, &sources);
    }
    for dr in sources {
        lifetime::hold(d, cb.as_raw(), Arc::new(CopyOp { view: dr.view, rect: dr.viewport, layer: dr.layer, slots: p.slots.clone(), awaiting: p.awaiting.clone(), walked: p.walked.map(|i| (i, dr)) }));
    }
    Ok(())
}

/// The layers of the pass's colour and depth images that hold view `dr`.
pub(super) fn source_layers(p: &PendingCopy, dr: &EyeDraw) -> (u32, u32) {
    (dr.layer, p.depth.base_layer + if p.multiview { dr.view } else { 0 })
}

/// The barriers around reading `sources` out of the pass that just ended, for either copy:
/// before, the app's colour and depth go from the layouts the pass left them in to `read`
/// (layout, access) and the sources' slots from their readers (the reuse draws) to `slot_write`;
/// after, the app's images go back and the slots become readable again. The slots stay GENERAL.
pub(super) fn copy_barriers(
    p: &PendingCopy,
    sources: &[EyeDraw],
    read: (vk::ImageLayout, vk::AccessFlags),
    slot_write: vk::AccessFlags,
) -> (Vec<vk::ImageMemoryBarrier<'static>>, Vec<vk::ImageMemoryBarrier<'static>>) {
    let span = |f: fn((u32, u32)) -> u32| sources.iter().map(|dr| f(source_layers(p, dr))).fold((u32::MAX, 0), |(lo, hi), l| (lo.min(l), hi.max(l)));
    let layers = [(&p.color, span(|l| l.0)), (&p.depth, span(|l| l.1))];
    let barrier = |image: vk::Image, layouts: (vk::ImageLayout, vk::ImageLayout), access: (vk::AccessFlags, vk::AccessFlags), range: vk::ImageSubresourceRange| crate::plugin::vk::gpu::image_barrier(image, range, layouts, access);
    let app = |to_read: bool| {
        layers.map(|(src, (lo, hi))| {
            let range = vk::ImageSubresourceRange { aspect_mask: src.aspect, base_mip_level: 0, level_count: 1, base_array_layer: lo, layer_count: hi - lo + 1 };
            if to_read {
                let written = vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
                barrier(src.image, (src.layout, read.0), (written, read.1), range)
            } else {
                barrier(src.image, (read.0, src.layout), (vk::AccessFlags::empty(), vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE), range)
            }
        })
    };
    // Compute-filled slots hold depth as a colour format.
    let depth_aspect = if p.slots.compute { vk::ImageAspectFlags::COLOR } else { vk::ImageAspectFlags::DEPTH };
    let slots = |before: bool| {
        let access = if before { (vk::AccessFlags::SHADER_READ, slot_write) } else { (slot_write, vk::AccessFlags::SHADER_READ) };
        sources.iter().flat_map(move |dr| {
            let slot = &p.slots.images[dr.view as usize & 1];
            [(&slot[0], vk::ImageAspectFlags::COLOR), (&slot[1], depth_aspect)].map(|(o, aspect)| {
                let range = vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
                barrier(o.image, (vk::ImageLayout::GENERAL, vk::ImageLayout::GENERAL), access, range)
            })
        })
    };
    (app(true).into_iter().chain(slots(true)).collect(), app(false).into_iter().chain(slots(false)).collect())
}

/// Image copies into multisampled slots (their tiles are marked unknown).
fn record_transfer(d: &DeviceState, cb: vk::CommandBuffer, p: &PendingCopy, sources: &[EyeDraw]) {
    let (before, after) = copy_barriers(p, sources, (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::AccessFlags::TRANSFER_READ), vk::AccessFlags::TRANSFER_WRITE);
    let fns = d.fns.fp_v1_0();
    let attachment_stages = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
    // SAFETY: `cb` is the app's command buffer outside any pass (the pass just ended); the
    // barriers name the app's attachments in the layouts its pass left them in (and put them
    // back) and the layer's slots, which stay GENERAL; the slots are held by the recording.
    unsafe {
        (fns.cmd_pipeline_barrier)(cb, attachment_stages | vk::PipelineStageFlags::FRAGMENT_SHADER, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), before.len() as u32, before.as_ptr());
        for dr in sources {
            let r = dr.viewport;
            let slot = &p.slots.images[dr.view as usize];
            let region = |aspect, layer| vk::ImageCopy {
                src_subresource: vk::ImageSubresourceLayers { aspect_mask: aspect, mip_level: 0, base_array_layer: layer, layer_count: 1 },
                src_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
                dst_subresource: vk::ImageSubresourceLayers { aspect_mask: aspect, mip_level: 0, base_array_layer: 0, layer_count: 1 },
                dst_offset: vk::Offset3D::default(),
                extent: vk::Extent3D { width: r.width, height: r.height, depth: 1 },
            };
            let (color_layer, depth_layer) = source_layers(p, dr);
            (fns.cmd_copy_image)(cb, p.color.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, slot[0].image, vk::ImageLayout::GENERAL, 1, &region(vk::ImageAspectFlags::COLOR, color_layer));
            (fns.cmd_copy_image)(cb, p.depth.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, slot[1].image, vk::ImageLayout::GENERAL, 1, &region(vk::ImageAspectFlags::DEPTH, depth_layer));
        }
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), after.len() as u32, after.as_ptr());
    }
    let views: Vec<u32> = sources.iter().map(|dr| dr.view).collect();
    mark_unknown(d, cb, &p.slots, &views);
}

/// Marks `views`' tiles unknown (NaN): the reuse draw then tests every pixel.
fn mark_unknown(d: &DeviceState, cb: vk::CommandBuffer, slots: &Slots, views: &[u32]) {
    let fns = d.fns.fp_v1_0();
    // A global barrier: the draws read the whole tile buffer through their descriptor.
    let written = vk::MemoryBarrier::default().src_access_mask(vk::AccessFlags::TRANSFER_WRITE).dst_access_mask(vk::AccessFlags::SHADER_READ);
    // SAFETY: `cb` is the app's command buffer, recording outside any pass; the buffer is the
    // layer's, held by the recording with the slots.
    unsafe {
        // The reuse draws of earlier frames read these tiles in their vertex shaders (WAR).
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::VERTEX_SHADER, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), 0, std::ptr::null());
        for &v in views {
            (fns.cmd_fill_buffer)(cb, slots.tiles, v as u64 * slots.tile_bytes(), slots.tile_bytes(), NOT_REDUCED);
        }
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::VERTEX_SHADER, vk::DependencyFlags::empty(), 1, &written, 0, std::ptr::null(), 0, std::ptr::null());
    }
}

/// The pass's colour and depth sources and their (format, samples).
#[allow(clippy::type_complexity)]
pub(super) fn attachments(d: &DeviceState, pass: &PassInstance) -> Result<(Source, Source, (vk::Format, vk::SampleCountFlags), (vk::Format, vk::SampleCountFlags)), &'static str> {
    let (color, depth, color_layout, depth_layout): (&AttachmentUse, &AttachmentUse, vk::ImageLayout, vk::ImageLayout) = match (&pass.rendering, &pass.render_pass) {
        (Some(r), _) => {
            if r.color.len() != 1 {
                return Err("several_colour_attachments");
            }
            let depth = r.depth.as_ref().ok_or("no_depth_attachment")?;
            (&r.color[0].attachment, &depth.attachment, r.color[0].attachment.layout, depth.attachment.layout)
        }
        (None, Some(rp)) => {
            let sub = rp.subpasses.get(pass.subpass as usize).ok_or("unsupported")?;
            if sub.color.len() != 1 {
                return Err("several_colour_attachments");
            }
            let ci = sub.color[0].used().ok_or("unsupported")? as usize;
            let di = sub.depth_stencil.and_then(|r| r.used()).ok_or("no_depth_attachment")? as usize;
            let (c, dd) = (pass.attachments.get(ci).ok_or("unsupported")?, pass.attachments.get(di).ok_or("unsupported")?);
            (c, dd, rp.attachments[ci].final_layout, rp.attachments[di].final_layout)
        }
        _ => return Err("unsupported"),
    };
    if color.store_op != vk::AttachmentStoreOp::STORE || depth.store_op != vk::AttachmentStoreOp::STORE {
        return Err("not_stored");
    }
    let info = |a: &AttachmentUse| {
        let v = a.image_view.as_ref()?;
        let i = d.track.images.get(v.image)?;
        Some((v.image, v.range.base_array_layer, i.format, i.samples, i.usage))
    };
    let (ci, cl, cf, cs, cu) = info(color).ok_or("unsupported")?;
    let (di, dl, df, ds, du) = info(depth).ok_or("unsupported")?;
    if cs != ds {
        // Mixed-sample passes (VK_AMD_mixed_attachment_samples and the like).
        return Err("unsupported");
    }
    // Single-sampled sources are read by the compute copy, multisampled ones copied.
    let needed = if cs == vk::SampleCountFlags::TYPE_1 { vk::ImageUsageFlags::SAMPLED } else { vk::ImageUsageFlags::TRANSFER_SRC };
    if !cu.contains(needed) || !du.contains(needed) {
        return Err(if needed == vk::ImageUsageFlags::SAMPLED { "no_sampled_usage" } else { "no_transfer_src" });
    }
    let stencil = matches!(df, vk::Format::D16_UNORM_S8_UINT | vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT);
    let depth_aspect = if stencil { vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL } else { vk::ImageAspectFlags::DEPTH };
    Ok((
        Source { image: vk::Image::from_raw(ci), format: cf, layout: color_layout, aspect: vk::ImageAspectFlags::COLOR, base_layer: cl },
        Source { image: vk::Image::from_raw(di), format: df, layout: depth_layout, aspect: depth_aspect, base_layer: dl },
        (cf, cs),
        (df, ds),
    ))
}

/// Creates both views' slot images and the descriptor set reading them.
#[allow(clippy::too_many_arguments)]
pub(super) fn make_slots(
    d: &DeviceState,
    memory: &vk::PhysicalDeviceMemoryProperties,
    extent: vk::Extent2D,
    (color_format, depth_format, samples): (vk::Format, vk::Format, vk::SampleCountFlags),
    set_layout: vk::DescriptorSetLayout,
    linear: vk::Sampler,
    nearest: vk::Sampler,
) -> Result<Slots, String> {
    let trash = d.lifetime.trash.clone();
    let compute = samples == vk::SampleCountFlags::TYPE_1;
    let usage = if compute { vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::STORAGE } else { vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST };
    let image = |format: vk::Format, aspect: vk::ImageAspectFlags| -> Result<Owned, String> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width: extent.width, height: extent.height, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(samples)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid create infos; every object made here is destroyed on failure or handed to
        // `Slots`, whose drop puts it in the device's trash.
        unsafe {
            let image = d.fns.create_image(&info, None).map_err(|e| e.to_string())?;
            let req = d.fns.get_image_memory_requirements(image);
            let t = lifetime::memory_type(memory, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)
                .or_else(|| lifetime::memory_type(memory, req.memory_type_bits, vk::MemoryPropertyFlags::empty()))
                .ok_or("no memory type for the far field's images")?;
            let mem = match d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t), None) {
                Ok(m) => m,
                Err(e) => {
                    d.fns.destroy_image(image, None);
                    return Err(e.to_string());
                }
            };
            let view = d.fns.bind_image_memory(image, mem, 0).and_then(|_| {
                let range = vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
                d.fns.create_image_view(&vk::ImageViewCreateInfo::default().image(image).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(range), None)
            });
            match view {
                Ok(view) => Ok(Owned { image, memory: mem, view }),
                Err(e) => {
                    d.fns.destroy_image(image, None);
                    d.fns.free_memory(mem, None);
                    Err(e.to_string())
                }
            }
        }
    };
    let mut made: Vec<Owned> = Vec::new();
    let result = (|| {
        for _ in 0..2 {
            if compute {
                made.push(image(super::compute::SLOT_COLOR, vk::ImageAspectFlags::COLOR)?);
                made.push(image(super::compute::SLOT_DEPTH, vk::ImageAspectFlags::COLOR)?);
            } else {
                made.push(image(color_format, vk::ImageAspectFlags::COLOR)?);
                made.push(image(depth_format, vk::ImageAspectFlags::DEPTH)?);
            }
        }
        let sizes = [vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 4 }, vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 1 }];
        // SAFETY: valid create / allocate infos on our own objects.
        let pool = unsafe { d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None) }.map_err(|e| e.to_string())?;
        let layouts = [set_layout];
        // SAFETY: as above.
        let set = match unsafe { d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts)) } {
            Ok(s) => s[0],
            Err(e) => {
                // SAFETY: ours, unused.
                unsafe { d.fns.destroy_descriptor_pool(pool, None) };
                return Err(e.to_string());
            }
        };
        Ok((pool, set))
    })();
    let grid = super::rules::tile_grid(extent.width, extent.height);
    let tiles = result.and_then(|(pool, set)| match tile_buffer(d, memory, 2 * grid.0 as u64 * grid.1 as u64 * 8) {
        Ok(b) => Ok((pool, set, b)),
        Err(e) => {
            lock(&trash).push(Garbage::DescriptorPool(pool));
            Err(e)
        }
    });
    let (pool, set, (tiles, tiles_memory)) = match tiles {
        Ok(x) => x,
        Err(e) => {
            let mut t = lock(&trash);
            t.extend(made.into_iter().map(|o| Garbage::Image(o.view, o.image, o.memory)));
            return Err(e);
        }
    };
    let infos: Vec<[vk::DescriptorImageInfo; 1]> = made
        .iter()
        .enumerate()
        .map(|(i, o)| [vk::DescriptorImageInfo { sampler: if i % 2 == 0 { linear } else { nearest }, image_view: o.view, image_layout: vk::ImageLayout::GENERAL }])
        .collect();
    let mut writes: Vec<vk::WriteDescriptorSet> =
        infos.iter().enumerate().map(|(i, info)| vk::WriteDescriptorSet::default().dst_set(set).dst_binding(i as u32).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(info)).collect();
    let tile_info = [vk::DescriptorBufferInfo { buffer: tiles, offset: 0, range: vk::WHOLE_SIZE }];
    writes.push(vk::WriteDescriptorSet::default().dst_set(set).dst_binding(4).descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(&tile_info));
    // SAFETY: our set, not in use by any command buffer yet.
    unsafe { d.fns.update_descriptor_sets(&writes, &[]) };
    let mut it = made.into_iter();
    let mut next = || it.next().expect("four images");
    let images = [[next(), next()], [next(), next()]];
    Ok(Slots { images, pool, set, extent, color_format, depth_format, samples, compute, initialized: AtomicBool::new(false), copied: Mutex::new([None, None]), tiles, tiles_memory, grid, trash })
}

/// The tiles' storage buffer (device-local; filled by the layer's commands only).
fn tile_buffer(d: &DeviceState, memory: &vk::PhysicalDeviceMemoryProperties, size: u64) -> Result<(vk::Buffer, vk::DeviceMemory), String> {
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST;
    // The caller hands both to `Slots`, whose drop puts them in the device's trash.
    let (buffer, mem, _) = lifetime::bound_buffer(&d.fns, memory, size.max(8), usage, &[vk::MemoryPropertyFlags::DEVICE_LOCAL, vk::MemoryPropertyFlags::empty()])?;
    Ok((buffer, mem))
}
