//! Radial density masking's reconstruction by the full-screen fragment fill
//! (`shaders/rdm_fill.frag`): where the compute pass cannot run (`rules::compute_path`), the
//! released swapchain image is copied into a temp image of the slot's and the fill draws the
//! skipped quads back from it. Its objects are made once per device (per colour format for the
//! render pass and pipeline) with no lock held.

use super::reconstruct::{layer_error, submit, Failure, Slot};
use super::rules::{NotApplied, Pending};
use crate::core::rect::PixelRect;
use super::vk::lock;
use crate::plugin::vk::DeviceState;
use crate::plugin::vk::gpu;
use ash::vk::{self, Handle};
use std::collections::HashMap;

static FILL_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_fill.vert.spv"));
static FILL_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_fill.frag.spv"));
static FILL_BUFFER_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_fill_buffer.vert.spv"));
static FILL_BUFFER_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/rdm_fill_buffer.frag.spv"));

/// A vertex of the fill's buffer variant (`shaders/rdm_fill.vert` `FROM_BUFFER`): one of an eye's
/// full-target triangle, with the eye's rule parameters, written at each submission.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FillVertex {
    pub(super) pos: [f32; 2],
    pub(super) rect: [i32; 4],
    pub(super) tan: [f32; 4],
    pub(super) fovea: [f32; 4],
}

impl FillVertex {
    /// The three vertices of eye `p`'s triangle over the whole target.
    pub(super) fn triangle(p: &Pending) -> [FillVertex; 3] {
        let r = p.params.rect;
        let v = |pos| FillVertex {
            pos,
            rect: [r.x, r.y, r.width as i32, r.height as i32],
            tan: [p.params.tan_left, p.params.tan_up, p.params.step_x, p.params.step_y],
            fovea: [p.params.center[0], p.params.center[1], p.params.k_inner, p.params.k_middle],
        };
        [v([-1.0, -1.0]), v([3.0, -1.0]), v([-1.0, 3.0])]
    }
}

/// Which fill pipeline: parameters from push constants (recorded with the draw) or from the
/// recording's vertex buffer (filled at submission).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum FillSource {
    PushConstants,
    VertexBuffer,
}

pub(super) struct FillObjects {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    sampler: vk::Sampler,
    vert: vk::ShaderModule,
    frag: vk::ShaderModule,
    vert_buffer: vk::ShaderModule,
    frag_buffer: vk::ShaderModule,
    /// Per colour format and source: render pass (load, store, COLOR_ATTACHMENT_OPTIMAL) and
    /// pipeline.
    passes: HashMap<(vk::Format, FillSource), (vk::RenderPass, vk::Pipeline)>,
}

impl FillObjects {
    /// The shared objects without the per-format ones: copied out of the lock to make a
    /// format's pipeline with no lock held.
    fn shared(&self) -> FillObjects {
        FillObjects { passes: HashMap::new(), ..*self }
    }
}

/// A layer image of a swapchain image's shape (the fill's copy target, then sampled).
pub(super) struct Temp {
    pub(super) image: vk::Image,
    pub(super) memory: vk::DeviceMemory,
    pub(super) view: vk::ImageView,
    /// (format, width, height, layers).
    pub(super) key: (vk::Format, u32, u32, u32),
}

/// # Safety
/// No pending GPU work may use it.
pub(super) unsafe fn destroy_temp(d: &DeviceState, t: Temp) {
    // SAFETY: per the contract.
    unsafe {
        d.fns.destroy_image_view(t.view, None);
        d.fns.destroy_image(t.image, None);
        d.fns.free_memory(t.memory, None);
    }
}

/// The slot's temp image for the fill (a copy target of the swapchain image's shape, sampled),
/// recreated when the shape changes; the fill's descriptor set (allocated on first use) then
/// points at the new one.
pub(super) fn ensure_temp(d: &DeviceState, slot: &mut Slot, format: vk::Format, shape: (u32, u32, u32), set_layout: vk::DescriptorSetLayout, sampler: vk::Sampler) -> Result<vk::Image, Failure> {
    let key = (format, shape.0, shape.1, shape.2);
    if let Some(t) = slot.temp.as_ref().filter(|t| t.key == key) {
        return Ok(t.image);
    }
    if let Some(t) = slot.temp.take() {
        // SAFETY: the slot's fence signalled: nothing uses it.
        unsafe { destroy_temp(d, t) };
    }
    let t = make_temp(d, format, vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::SAMPLED, shape)?;
    // SAFETY: the slot's pool has room for this one fill set (see `new_slot`); the set is not in
    // use (the slot's fence signalled).
    unsafe {
        if slot.set == vk::DescriptorSet::null() {
            let layouts = [set_layout];
            match d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(slot.descriptor_pool).set_layouts(&layouts)) {
                Ok(sets) => slot.set = sets[0],
                Err(e) => {
                    destroy_temp(d, t);
                    return Err((NotApplied::LayerError, format!("descriptor set: {e}")));
                }
            }
        }
        let infos = [vk::DescriptorImageInfo { sampler, image_view: t.view, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
        let write = vk::WriteDescriptorSet::default().dst_set(slot.set).dst_binding(0).descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&infos);
        d.fns.update_descriptor_sets(&[write], &[]);
    }
    let image = t.image;
    slot.temp = Some(t);
    Ok(image)
}

/// A device-local image of `format` and `usage` with the swapchain image's shape
/// (width, height, layers) and a 2D-array view of it.
pub(super) fn make_temp(d: &DeviceState, format: vk::Format, usage: vk::ImageUsageFlags, (width, height, layers): (u32, u32, u32)) -> Result<Temp, Failure> {
    let key = (format, width, height, layers);
    let info = vk::ImageCreateInfo::default()
        .image_type(vk::ImageType::TYPE_2D)
        .format(format)
        .extent(vk::Extent3D { width, height, depth: 1 })
        .mip_levels(1)
        .array_layers(layers)
        .samples(vk::SampleCountFlags::TYPE_1)
        .tiling(vk::ImageTiling::OPTIMAL)
        .usage(usage)
        .sharing_mode(vk::SharingMode::EXCLUSIVE)
        .initial_layout(vk::ImageLayout::UNDEFINED);
    // SAFETY: valid create / allocate infos on our device; failures destroy what was made.
    unsafe {
        let image = d.fns.create_image(&info, None).map_err(layer_error("temp image"))?;
        let req = d.fns.get_image_memory_requirements(image);
        let mem = &super::vk::RdmDevice::of(d).reconstruct.memory;
        let index = crate::plugin::vk::lifetime::memory_type(mem, req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)
            .or_else(|| crate::plugin::vk::lifetime::memory_type(mem, req.memory_type_bits, vk::MemoryPropertyFlags::empty()));
        let Some(index) = index else {
            d.fns.destroy_image(image, None);
            return Err((NotApplied::LayerError, "no memory type for the temp image".into()));
        };
        let memory = match d.fns.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(index), None) {
            Ok(m) => m,
            Err(e) => {
                d.fns.destroy_image(image, None);
                return Err((NotApplied::LayerError, format!("temp memory: {e}")));
            }
        };
        let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers };
        let view = d.fns.bind_image_memory(image, memory, 0).and_then(|_| {
            d.fns.create_image_view(&vk::ImageViewCreateInfo::default().image(image).view_type(vk::ImageViewType::TYPE_2D_ARRAY).format(format).subresource_range(range), None)
        });
        match view {
            Ok(view) => Ok(Temp { image, memory, view, key }),
            Err(e) => {
                d.fns.destroy_image(image, None);
                d.fns.free_memory(memory, None);
                Err((NotApplied::LayerError, format!("temp view: {e}")))
            }
        }
    }
}

/// Push constants of shaders/rdm_fill.frag.
#[repr(C)]
#[derive(Clone, Copy)]
pub(super) struct FillParams {
    rect: [i32; 4],
    tan: [f32; 4],
    fovea: [f32; 4],
    layer: i32,
}

impl FillParams {
    /// The fill's parameters for one eye.
    pub(super) fn of(p: &Pending) -> FillParams {
        let r = p.params.rect;
        FillParams {
            rect: [r.x, r.y, r.width as i32, r.height as i32],
            tan: [p.params.tan_left, p.params.tan_up, p.params.step_x, p.params.step_y],
            fovea: [p.params.center[0], p.params.center[1], p.params.k_inner, p.params.k_middle],
            layer: p.layer as i32,
        }
    }
    /// As push-constant bytes.
    pub(super) fn bytes(&self) -> &[u8] {
        // SAFETY: a `repr(C)` struct of 4-byte scalars, without padding, read as its own bytes
        // for its lifetime.
        unsafe { std::slice::from_raw_parts(self as *const FillParams as *const u8, std::mem::size_of::<FillParams>()) }
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn record_and_submit(
    d: &DeviceState,
    slot: &mut Slot,
    image: u64,
    format: vk::Format,
    shape: (u32, u32, u32),
    eyes: &[Pending],
    family: u32,
    queue_index: u32,
    (layout, set_layout, render_pass, pipeline, sampler): (vk::PipelineLayout, vk::DescriptorSetLayout, vk::RenderPass, vk::Pipeline, vk::Sampler),
) -> Result<(), Failure> {
    let temp = ensure_temp(d, slot, format, shape, set_layout, sampler)?;
    let image = vk::Image::from_raw(image);
    let (width, height, layers) = shape;
    let mut eye_layers: Vec<u32> = eyes.iter().map(|p| p.layer).collect();
    eye_layers.sort_unstable();
    eye_layers.dedup();
    let cb = slot.cb;
    // SAFETY: our command buffer, reset and not in use (its fence signalled); every handle is
    // alive: the swapchain image is acquired by the app and not yet released; arrays outlive the
    // calls. The OpenXR Vulkan binding lets a call inside xrReleaseSwapchainImage use the session's
    // queue (the app synchronizes its queue use around these calls).
    unsafe {
        d.fns.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(layer_error("begin"))?;
        let mut framebuffers = Vec::new();
        for l in eye_layers {
            let view = d
                .fns
                .create_image_view(&vk::ImageViewCreateInfo::default().image(image).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(color_range(l, 1)), None)
                .map_err(layer_error("swapchain view"))?;
            let views = [view];
            let fb = match d.fns.create_framebuffer(&vk::FramebufferCreateInfo::default().render_pass(render_pass).attachments(&views).width(width).height(height).layers(1), None) {
                Ok(f) => f,
                Err(e) => {
                    d.fns.destroy_image_view(view, None);
                    return Err((NotApplied::LayerError, format!("framebuffer: {e}")));
                }
            };
            slot.transient.push((view, fb));
            framebuffers.push((l, fb));
        }
        let target = FillTarget { image, before: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, whole: PixelRect { x: 0, y: 0, width, height }, framebuffers: &framebuffers };
        record_fill(d, cb, &target, (temp, layers, slot.set), (layout, render_pass, pipeline), FillDraws::Pushed { eyes, args: None });
    }
    submit(d, slot, family, queue_index)
}

/// The image a fill reconstructs: the layout it is in, its extent, and a framebuffer of the
/// fill's render pass per layer drawn (in that order).
pub(super) struct FillTarget<'a> {
    pub(super) image: vk::Image,
    pub(super) before: vk::ImageLayout,
    pub(super) whole: PixelRect,
    pub(super) framebuffers: &'a [(u32, vk::Framebuffer)],
}

/// What the fill draws.
pub(super) enum FillDraws<'a> {
    /// The eyes known when recorded: each eye's rect copied, its parameters pushed with its draw;
    /// `args`: a buffer with one indirect draw per eye (in `eyes`' order), else direct draws.
    Pushed { eyes: &'a [Pending], args: Option<vk::Buffer> },
    /// Eyes known only at submission (`FillSource::VertexBuffer`): `area` copied and drawn in every
    /// layer; two indirect draws per layer in `buffer`, the vertices from `vertex_offset`.
    FromBuffer { area: PixelRect, buffer: vk::Buffer, vertex_offset: u64 },
}

/// Indirect draws per layer of `FillDraws::FromBuffer` (side by side: two eyes in one layer).
pub(super) const EYES_PER_LAYER: usize = 2;

pub(super) fn color_range(layer: u32, count: u32) -> vk::ImageSubresourceRange {
    gpu::color_range(layer, count, 1)
}


/// Records the reconstruction by the fill into `cb` (outside any pass): the eyes' pixels of
/// `target.image` copied into `temp` (image, layers, the fill's descriptor set over it), then per
/// framebuffer the fill drawn back from it. The image is left in COLOR_ATTACHMENT_OPTIMAL, behind
/// the fill render pass's external dependency.
///
/// # Safety
/// `cb` is recording outside any pass; `target.image` is in `target.before` and every handle
/// (the pipeline objects, `temp`, the framebuffers, the draw buffer) lives until `cb`'s
/// submissions complete.
pub(super) unsafe fn record_fill(
    d: &DeviceState,
    cb: vk::CommandBuffer,
    target: &FillTarget<'_>,
    (temp, temp_layers, set): (vk::Image, u32, vk::DescriptorSet),
    (layout, render_pass, pipeline): (vk::PipelineLayout, vk::RenderPass, vk::Pipeline),
    draws: FillDraws<'_>,
) {
    let (image, whole) = (target.image, target.whole);
    let layer_of = |layer: u32| vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: layer, layer_count: 1 };
    let copy = |layer: u32, r: PixelRect| vk::ImageCopy {
        src_subresource: layer_of(layer),
        src_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
        dst_subresource: layer_of(layer),
        dst_offset: vk::Offset3D { x: r.x, y: r.y, z: 0 },
        extent: vk::Extent3D { width: r.width, height: r.height, depth: 1 },
    };
    let regions: Vec<vk::ImageCopy> = match &draws {
        FillDraws::Pushed { eyes, .. } => eyes.iter().map(|e| copy(e.layer, e.params.rect.intersect(&whole))).collect(),
        FillDraws::FromBuffer { area, .. } => target.framebuffers.iter().map(|(l, _)| copy(*l, area.intersect(&whole))).collect(),
    };
    let regions: Vec<vk::ImageCopy> = regions.into_iter().filter(|c| c.extent.width > 0 && c.extent.height > 0).collect();
    let each_layer = |layouts, access| target.framebuffers.iter().map(move |(l, _)| gpu::image_barrier(image, color_range(*l, 1), layouts, access));
    // SAFETY: per the contract; arrays outlive the calls.
    unsafe {
        // The app's writes (rendering, a resolve, or a copy from an intermediate) finish before
        // the copy reads the image; the temp image's previous readers before it is overwritten.
        let mut first: Vec<vk::ImageMemoryBarrier> =
            each_layer((target.before, vk::ImageLayout::TRANSFER_SRC_OPTIMAL), (vk::AccessFlags::COLOR_ATTACHMENT_WRITE | vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::TRANSFER_READ)).collect();
        first.push(gpu::image_barrier(temp, color_range(0, temp_layers), (vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL), (vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE)));
        let waits = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::FRAGMENT_SHADER;
        d.fns.cmd_pipeline_barrier(cb, waits, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &first);
        d.fns.cmd_copy_image(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, temp, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &regions);
        let mut second: Vec<vk::ImageMemoryBarrier> = each_layer(
            (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL),
            (vk::AccessFlags::empty(), vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE),
        )
        .collect();
        second.push(gpu::image_barrier(temp, color_range(0, temp_layers), (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL), (vk::AccessFlags::TRANSFER_WRITE, vk::AccessFlags::SHADER_READ)));
        let fill_stages = vk::PipelineStageFlags::FRAGMENT_SHADER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT;
        d.fns.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, fill_stages, vk::DependencyFlags::empty(), &[], &[], &second);
        for (li, (layer, fb)) in target.framebuffers.iter().enumerate() {
            let area = match &draws {
                FillDraws::Pushed { eyes, .. } => eyes.iter().filter(|e| e.layer == *layer).map(|e| e.params.rect.intersect(&whole)).reduce(|a, b| crate::track::flow::union(&a, &b)),
                FillDraws::FromBuffer { area, .. } => Some(area.intersect(&whole)),
            };
            let Some(area) = area.filter(|a| a.area() > 0) else { continue };
            d.fns.cmd_begin_render_pass(cb, &vk::RenderPassBeginInfo::default().render_pass(render_pass).framebuffer(*fb).render_area(crate::plugin::vk::inject::rect2d(area)), vk::SubpassContents::INLINE);
            d.fns.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.fns.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::GRAPHICS, layout, 0, &[set], &[]);
            match &draws {
                FillDraws::Pushed { eyes, args } => {
                    for (i, e) in eyes.iter().enumerate().filter(|(_, e)| e.layer == *layer) {
                        let r = e.params.rect;
                        let vp = vk::Viewport { x: r.x as f32, y: r.y as f32, width: r.width as f32, height: r.height as f32, min_depth: 0.0, max_depth: 1.0 };
                        d.fns.cmd_set_viewport(cb, 0, &[vp]);
                        d.fns.cmd_set_scissor(cb, 0, &[crate::plugin::vk::inject::rect2d(r.intersect(&whole))]);
                        d.fns.cmd_push_constants(cb, layout, vk::ShaderStageFlags::FRAGMENT, 0, FillParams::of(e).bytes());
                        match args {
                            Some(buffer) => d.fns.cmd_draw_indirect(cb, *buffer, crate::plugin::vk::inject::DRAW_ARGS * i as u64, 1, crate::plugin::vk::inject::DRAW_ARGS as u32),
                            None => d.fns.cmd_draw(cb, 3, 1, 0, 0),
                        }
                    }
                }
                FillDraws::FromBuffer { buffer, vertex_offset, .. } => {
                    d.fns.cmd_bind_vertex_buffers(cb, 0, &[*buffer], &[*vertex_offset]);
                    let vp = vk::Viewport { x: 0.0, y: 0.0, width: whole.width as f32, height: whole.height as f32, min_depth: 0.0, max_depth: 1.0 };
                    d.fns.cmd_set_viewport(cb, 0, &[vp]);
                    d.fns.cmd_set_scissor(cb, 0, &[crate::plugin::vk::inject::rect2d(area)]);
                    d.fns.cmd_push_constants(cb, layout, vk::ShaderStageFlags::FRAGMENT, 0, &(*layer as i32).to_ne_bytes());
                    for slot in 0..EYES_PER_LAYER {
                        d.fns.cmd_draw_indirect(cb, *buffer, crate::plugin::vk::inject::DRAW_ARGS * (li * EYES_PER_LAYER + slot) as u64, 1, crate::plugin::vk::inject::DRAW_ARGS as u32);
                    }
                }
            }
            d.fns.cmd_end_render_pass(cb);
        }
    }
}

/// The fill pipeline's shared objects and the render pass + pipeline for `format`, made once.
pub(super) fn fill_objects(d: &DeviceState, format: vk::Format) -> Result<(vk::PipelineLayout, vk::DescriptorSetLayout, vk::RenderPass, vk::Pipeline, vk::Sampler), String> {
    fill_objects_for(d, (format, FillSource::PushConstants))
}

/// `fill_objects` for a colour format and parameter source.
pub(super) fn fill_objects_for(d: &DeviceState, key: (vk::Format, FillSource)) -> Result<(vk::PipelineLayout, vk::DescriptorSetLayout, vk::RenderPass, vk::Pipeline, vk::Sampler), String> {
    let format = key.0;
    // Objects are made with no lock held: the calls go down the chain, and what is below may
    // call back into the layer. A thread that loses a race to another destroys its own.
    let fill = &super::vk::RdmDevice::of(d).reconstruct.fill;
    let have = lock(fill).as_ref().map(|f| (f.shared(), f.passes.get(&key).copied()));
    let common = match have {
        Some((f, Some((rp, p)))) => return Ok((f.layout, f.set_layout, rp, p, f.sampler)),
        Some((f, None)) => f,
        None => {
            let new = create_fill_common(d)?;
            let mut guard = lock(fill);
            match guard.as_ref() {
                Some(f) => {
                    let existing = f.shared();
                    drop(guard);
                    // SAFETY: ours, never used.
                    unsafe { destroy_fill(d, new) };
                    existing
                }
                None => {
                    let made = new.shared();
                    *guard = Some(new);
                    made
                }
            }
        }
    };
    let (rp, p) = create_fill_pipeline(d, &common, format, key.1)?;
    let mut guard = lock(fill);
    let existing = match guard.as_mut() {
        Some(f) => match f.passes.get(&key) {
            Some(&existing) => Some(existing),
            None => {
                f.passes.insert(key, (rp, p));
                None
            }
        },
        // Gone meanwhile (the device is being destroyed): ours goes too.
        None => Some((vk::RenderPass::null(), vk::Pipeline::null())),
    };
    drop(guard);
    match existing {
        None => Ok((common.layout, common.set_layout, rp, p, common.sampler)),
        Some((erp, ep)) => {
            // SAFETY: ours, never used.
            unsafe {
                d.fns.destroy_pipeline(p, None);
                d.fns.destroy_render_pass(rp, None);
            }
            if ep == vk::Pipeline::null() {
                return Err("the device's RDM objects are being destroyed".into());
            }
            Ok((common.layout, common.set_layout, erp, ep, common.sampler))
        }
    }
}

pub(super) fn create_fill_common(d: &DeviceState) -> Result<FillObjects, String> {
    let module = |bytes: &[u8]| -> Result<vk::ShaderModule, String> {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes)).map_err(|e| e.to_string())?;
        // SAFETY: valid SPIR-V compiled at build time.
        unsafe { d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }.map_err(|e| e.to_string())
    };
    let bindings = [vk::DescriptorSetLayoutBinding::default()
        .binding(0)
        .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
        .descriptor_count(1)
        .stage_flags(vk::ShaderStageFlags::FRAGMENT)];
    // SAFETY: valid create infos on our device.
    unsafe {
        let set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(|e| e.to_string())?;
        let set_layouts = [set_layout];
        let ranges = [vk::PushConstantRange { stage_flags: vk::ShaderStageFlags::FRAGMENT, offset: 0, size: std::mem::size_of::<FillParams>() as u32 }];
        let layout = d
            .fns
            .create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges), None)
            .map_err(|e| e.to_string())?;
        let sampler = d
            .fns
            .create_sampler(
                &vk::SamplerCreateInfo::default()
                    .mag_filter(vk::Filter::NEAREST)
                    .min_filter(vk::Filter::NEAREST)
                    .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                    .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                    .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE),
                None,
            )
            .map_err(|e| e.to_string())?;
        Ok(FillObjects {
            set_layout,
            layout,
            sampler,
            vert: module(FILL_VERT)?,
            frag: module(FILL_FRAG)?,
            vert_buffer: module(FILL_BUFFER_VERT)?,
            frag_buffer: module(FILL_BUFFER_FRAG)?,
            passes: HashMap::new(),
        })
    }
}

pub(super) fn create_fill_pipeline(d: &DeviceState, f: &FillObjects, format: vk::Format, source: FillSource) -> Result<(vk::RenderPass, vk::Pipeline), String> {
    let attachments = [vk::AttachmentDescription::default()
        .format(format)
        .samples(vk::SampleCountFlags::TYPE_1)
        .load_op(vk::AttachmentLoadOp::LOAD)
        .store_op(vk::AttachmentStoreOp::STORE)
        .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
        .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
        .initial_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
        .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
    let color = [vk::AttachmentReference { attachment: 0, layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL }];
    let subpasses = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color)];
    // In: the barriers before the pass already order it after the copy. Out: whatever reads the
    // image next (the runtime's compositor or capture) sees the reconstructed pixels.
    let deps = [
        vk::SubpassDependency {
            src_subpass: vk::SUBPASS_EXTERNAL,
            dst_subpass: 0,
            src_stage_mask: vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            dst_stage_mask: vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            src_access_mask: vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            dst_access_mask: vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            dependency_flags: vk::DependencyFlags::empty(),
        },
        vk::SubpassDependency {
            src_subpass: 0,
            dst_subpass: vk::SUBPASS_EXTERNAL,
            src_stage_mask: vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            dst_stage_mask: vk::PipelineStageFlags::ALL_COMMANDS,
            src_access_mask: vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            dst_access_mask: vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE,
            dependency_flags: vk::DependencyFlags::empty(),
        },
    ];
    // SAFETY: valid create infos; arrays outlive the calls.
    unsafe {
        let rp = d
            .fns
            .create_render_pass(&vk::RenderPassCreateInfo::default().attachments(&attachments).subpasses(&subpasses).dependencies(&deps), None)
            .map_err(|e| e.to_string())?;
        let (vert, frag) = match source {
            FillSource::PushConstants => (f.vert, f.frag),
            FillSource::VertexBuffer => (f.vert_buffer, f.frag_buffer),
        };
        let bindings = [vk::VertexInputBindingDescription { binding: 0, stride: std::mem::size_of::<FillVertex>() as u32, input_rate: vk::VertexInputRate::VERTEX }];
        let attributes = [
            vk::VertexInputAttributeDescription { location: 0, binding: 0, format: vk::Format::R32G32_SFLOAT, offset: 0 },
            vk::VertexInputAttributeDescription { location: 1, binding: 0, format: vk::Format::R32G32B32A32_SINT, offset: 8 },
            vk::VertexInputAttributeDescription { location: 2, binding: 0, format: vk::Format::R32G32B32A32_SFLOAT, offset: 24 },
            vk::VertexInputAttributeDescription { location: 3, binding: 0, format: vk::Format::R32G32B32A32_SFLOAT, offset: 40 },
        ];
        let (bindings, attributes): (&[_], &[_]) = match source {
            FillSource::PushConstants => (&[], &[]),
            FillSource::VertexBuffer => (&bindings, &attributes),
        };
        let draw = gpu::Draw {
            vert,
            frag: Some(frag),
            bindings,
            attributes,
            samples: vk::SampleCountFlags::TYPE_1,
            depth_compare: None,
            color_writes: &[vk::ColorComponentFlags::RGBA],
            layout: f.layout,
            target: gpu::Target::Subpass(rp, 0),
        };
        match gpu::graphics_pipeline(&d.fns, draw) {
            Ok(p) => Ok((rp, p)),
            Err(e) => {
                d.fns.destroy_render_pass(rp, None);
                Err(e.to_string())
            }
        }
    }
}

/// # Safety
/// No submission using `f`'s objects may be pending.
pub(super) unsafe fn destroy_fill(d: &DeviceState, f: FillObjects) {
    // SAFETY: per the contract.
    unsafe {
        for (rp, p) in f.passes.values() {
            d.fns.destroy_pipeline(*p, None);
            d.fns.destroy_render_pass(*rp, None);
        }
        d.fns.destroy_pipeline_layout(f.layout, None);
        d.fns.destroy_descriptor_set_layout(f.set_layout, None);
        d.fns.destroy_sampler(f.sampler, None);
        for m in [f.vert, f.frag, f.vert_buffer, f.frag_buffer] {
            d.fns.destroy_shader_module(m, None);
        }
    }
}


