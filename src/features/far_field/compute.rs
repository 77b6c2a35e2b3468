//! The far field's compute copy: at the end of a single-sampled source pass, one compute pass per
//! source view reads the app's colour and depth (sampled, in SHADER_READ_ONLY_OPTIMAL for the
//! duration), writes them into the view's slot (RGBA16F linear colour, R32F depth) and reduces the
//! depth to a range per 16×16 tile (`shaders/far_field_copy.comp`).
//!
//! Why not `vkCmdCopyImage`: measured on the H100 (docs/benchmarks.md), each image copy of a
//! 2016×2240 view cost ~0.33 ms — as much as the app's cheapest full-screen shading — while a
//! compute pass runs on every unit of the GPU. The tiles come for free in the same pass.
//!
//! Per recording the copy makes views of the app's images and a descriptor set; they are held by
//! the recording (`lifetime::hold`) and destroyed after its last submission completed.

use super::copy::{copy_barriers, source_layers, PendingCopy};
use crate::track::eye_pass::EyeDraw;
use crate::plugin::vk::lifetime::{self, Garbage, PooledBuffer};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::sync::{Arc, Mutex};

static COPY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/far_field_copy.comp.spv"));

/// The single-sampled slots' formats: linear colour with headroom for any app format the far
/// field reuses (8-bit values survive the round trip), and depth as plain floats (storage images
/// of depth formats are not generally supported).
pub(super) const SLOT_COLOR: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
pub(super) const SLOT_DEPTH: vk::Format = vk::Format::R32_SFLOAT;

/// Bytes between two sources' parameters (`minStorageBufferOffsetAlignment` is at most 256).
const PARAMS_STRIDE: u64 = 256;

/// The compute copy's device objects (made once with the far field's other objects).
#[derive(Clone, Copy)]
pub(super) struct Copier {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    sampler: vk::Sampler,
    memory: vk::PhysicalDeviceMemoryProperties,
}

impl Copier {
    /// `sampler` (nearest) stays owned by the caller.
    pub(super) fn new(d: &DeviceState, sampler: vk::Sampler, memory: vk::PhysicalDeviceMemoryProperties) -> Result<Copier, String> {
        let binding = |b: u32, ty: vk::DescriptorType| vk::DescriptorSetLayoutBinding::default().binding(b).descriptor_type(ty).descriptor_count(1).stage_flags(vk::ShaderStageFlags::COMPUTE);
        let bindings = [
            binding(0, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
            binding(1, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
            binding(2, vk::DescriptorType::STORAGE_IMAGE),
            binding(3, vk::DescriptorType::STORAGE_IMAGE),
            binding(4, vk::DescriptorType::STORAGE_BUFFER),
            binding(5, vk::DescriptorType::STORAGE_BUFFER),
        ];
        let code = ash::util::read_spv(&mut std::io::Cursor::new(COPY)).map_err(|e| e.to_string())?;
        // SAFETY: valid create infos and SPIR-V (compiled for Vulkan 1.0 by build.rs); whatever
        // was made is destroyed on failure, the rest by `destroy`.
        unsafe {
            let set_layout = d.fns.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None).map_err(|e| e.to_string())?;
            let layouts = [set_layout];
            let layout = match d.fns.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts), None) {
                Ok(l) => l,
                Err(e) => {
                    d.fns.destroy_descriptor_set_layout(set_layout, None);
                    return Err(e.to_string());
                }
            };
            let pipeline = d.fns.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None).map_err(|e| e.to_string()).and_then(|module| {
                let info = vk::ComputePipelineCreateInfo::default()
                    .stage(vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module).name(c"main"))
                    .layout(layout);
                let made = d.fns.create_compute_pipelines(vk::PipelineCache::null(), &[info], None);
                d.fns.destroy_shader_module(module, None);
                made.map(|p| p[0]).map_err(|(_, e)| e.to_string())
            });
            match pipeline {
                Ok(pipeline) => Ok(Copier { set_layout, layout, pipeline, sampler, memory }),
                Err(e) => {
                    d.fns.destroy_pipeline_layout(layout, None);
                    d.fns.destroy_descriptor_set_layout(set_layout, None);
                    Err(e)
                }
            }
        }
    }

    /// # Safety
    /// The device is idle (no recording that used the copier may still execute).
    pub(super) unsafe fn destroy(&self, d: &DeviceState) {
        // SAFETY: ours; per this function's contract nothing uses them any more.
        unsafe {
            d.fns.destroy_pipeline(self.pipeline, None);
            d.fns.destroy_pipeline_layout(self.layout, None);
            d.fns.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// What one recording's copies made: views of the app's images, the descriptor pool, the
/// parameters. Destroyed (through the device's trash) when the recording is done with them.
struct CopyObjects {
    views: Vec<vk::ImageView>,
    pool: vk::DescriptorPool,
    _params: PooledBuffer,
    trash: Arc<Mutex<Vec<Garbage>>>,
}

impl Drop for CopyObjects {
    fn drop(&mut self) {
        let mut t = self.trash.lock().unwrap_or_else(|e| e.into_inner());
        t.extend(self.views.drain(..).map(|v| Garbage::Image(v, vk::Image::null(), vk::DeviceMemory::null())));
        t.push(Garbage::DescriptorPool(std::mem::take(&mut self.pool)));
    }
}

/// One source's parameters (`Copy` in the shader).
#[repr(C)]
#[derive(Clone, Copy)]
struct Params {
    rect: [i32; 4],
    grid: [u32; 4],
}

/// Records the compute copies of `sources` (views of the pass that just ended in `cb`).
pub(super) fn record(d: &DeviceState, cb: vk::CommandBuffer, p: &PendingCopy, sources: &[EyeDraw], c: &Copier) -> Result<(), &'static str> {
    // The app's compute bindings (pipeline or shader object, sets) are restored afterwards; a
    // command buffer with state the layer does not restore (`CmdState::veto`) is left alone.
    let compute = match d.track.with_cb(cb.as_raw(), |s| (s.veto, s.compute.clone())) {
        Some((None, compute)) => compute,
        Some((Some(_), _)) => return Err("vetoed"),
        None => return Err("unsupported"),
    };
    let objects = make_objects(d, p, sources, c).map_err(|e| {
        d.warn_repeated("far field copy", &e);
        "layer_error"
    })?;
    let (before, after) = copy_barriers(p, sources, (vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL, vk::AccessFlags::SHADER_READ), vk::AccessFlags::SHADER_WRITE);
    // The tiles: a global barrier (the reuse draws read the whole buffer through their descriptor).
    let tiles = vk::MemoryBarrier::default().src_access_mask(vk::AccessFlags::SHADER_WRITE).dst_access_mask(vk::AccessFlags::SHADER_READ);
    let attachment_stages = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
    // Earlier reuse draws read the slots (fragment) and the tiles (vertex): write after read.
    let readers = vk::PipelineStageFlags::VERTEX_SHADER | vk::PipelineStageFlags::FRAGMENT_SHADER;
    let fns = d.fns.fp_v1_0();
    // SAFETY: `cb` is the app's command buffer outside any pass (its pass just ended); the
    // barriers move the app's attachments from the layouts the pass left them in to a sampled
    // layout and back; the views, sets and parameters are held by the recording (below) and the
    // slots with it; `RestoreCompute` rebinds the app's compute state before anything else is
    // recorded.
    unsafe {
        (fns.cmd_pipeline_barrier)(cb, attachment_stages | readers, vk::PipelineStageFlags::COMPUTE_SHADER, vk::DependencyFlags::empty(), 0, std::ptr::null(), 0, std::ptr::null(), before.len() as u32, before.as_ptr());
        {
            let _restore = crate::plugin::vk::inject::restore::RestoreCompute::new(d, cb, compute);
            (fns.cmd_bind_pipeline)(cb, vk::PipelineBindPoint::COMPUTE, c.pipeline);
            for (dr, set) in sources.iter().zip(&objects.1) {
                (fns.cmd_bind_descriptor_sets)(cb, vk::PipelineBindPoint::COMPUTE, c.layout, 0, 1, set, 0, std::ptr::null());
                let (x, y) = super::rules::tile_grid(dr.viewport.width, dr.viewport.height);
                (fns.cmd_dispatch)(cb, x, y, 1);
            }
        }
        (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::COMPUTE_SHADER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), 1, &tiles, 0, std::ptr::null(), after.len() as u32, after.as_ptr());
    }
    lifetime::hold(d, cb.as_raw(), Arc::new(objects.0));
    Ok(())
}

/// The views, descriptor sets and parameters of one recording's copies (sets in `sources` order).
fn make_objects(d: &DeviceState, p: &PendingCopy, sources: &[EyeDraw], c: &Copier) -> Result<(CopyObjects, Vec<vk::DescriptorSet>), String> {
    let n = sources.len() as u32;
    let params = PooledBuffer::take(d, PARAMS_STRIDE * n as u64, &c.memory)?;
    let mut objects = CopyObjects { views: Vec::new(), pool: vk::DescriptorPool::null(), _params: params, trash: d.lifetime.trash.clone() };
    let view = |image: vk::Image, format: vk::Format, aspect: vk::ImageAspectFlags, layer: u32| {
        let range = vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: layer, layer_count: 1 };
        // SAFETY: the app's image, alive while its pass is recorded; a valid create info.
        unsafe { d.fns.create_image_view(&vk::ImageViewCreateInfo::default().image(image).view_type(vk::ImageViewType::TYPE_2D).format(format).subresource_range(range), None) }
            .map_err(|e| format!("view of the app's image: {e}"))
    };
    for dr in sources {
        let (cl, dl) = source_layers(p, dr);
        // Pushed as made, so a failure still hands every view made so far to the trash.
        objects.views.push(view(p.color.image, p.color.format, vk::ImageAspectFlags::COLOR, cl)?);
        objects.views.push(view(p.depth.image, p.depth.format, vk::ImageAspectFlags::DEPTH, dl)?);
    }
    let sizes = [
        vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 2 * n },
        vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_IMAGE, descriptor_count: 2 * n },
        vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 2 * n },
    ];
    // SAFETY: valid create / allocate infos on our own objects.
    objects.pool = unsafe { d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(n).pool_sizes(&sizes), None) }.map_err(|e| e.to_string())?;
    let layouts = vec![c.set_layout; n as usize];
    // SAFETY: as above.
    let sets = unsafe { d.fns.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(objects.pool).set_layouts(&layouts)) }.map_err(|e| e.to_string())?;
    let slots = &p.slots;
    for (i, (dr, set)) in sources.iter().zip(&sets).enumerate() {
        let r = dr.viewport;
        let (gx, gy) = slots.grid;
        objects._params.write(i as u64 * PARAMS_STRIDE, &[Params { rect: [r.x, r.y, r.width as i32, r.height as i32], grid: [gx, gy, dr.view & 1, 0] }]);
        let slot = &slots.images[dr.view as usize & 1];
        let sampled = |v: vk::ImageView| [vk::DescriptorImageInfo { sampler: c.sampler, image_view: v, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }];
        let storage = |v: vk::ImageView| [vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: v, image_layout: vk::ImageLayout::GENERAL }];
        let (src_color, src_depth) = (sampled(objects.views[2 * i]), sampled(objects.views[2 * i + 1]));
        let (slot_color, slot_depth) = (storage(slot[0].view), storage(slot[1].view));
        let tiles = [vk::DescriptorBufferInfo { buffer: slots.tiles, offset: 0, range: vk::WHOLE_SIZE }];
        let params = [vk::DescriptorBufferInfo { buffer: objects._params.buffer, offset: i as u64 * PARAMS_STRIDE, range: std::mem::size_of::<Params>() as u64 }];
        let w = |b: u32, ty: vk::DescriptorType| vk::WriteDescriptorSet::default().dst_set(*set).dst_binding(b).descriptor_type(ty);
        let writes = [
            w(0, vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&src_color),
            w(1, vk::DescriptorType::COMBINED_IMAGE_SAMPLER).image_info(&src_depth),
            w(2, vk::DescriptorType::STORAGE_IMAGE).image_info(&slot_color),
            w(3, vk::DescriptorType::STORAGE_IMAGE).image_info(&slot_depth),
            w(4, vk::DescriptorType::STORAGE_BUFFER).buffer_info(&tiles),
            w(5, vk::DescriptorType::STORAGE_BUFFER).buffer_info(&params),
        ];
        // SAFETY: our set, not yet used by any command buffer; every object it names is alive.
        unsafe { d.fns.update_descriptor_sets(&writes, &[]) };
    }
    Ok((objects, sets))
}
