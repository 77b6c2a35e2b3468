//! Per-frame GPU work: scene buffers, descriptors, the pipeline, and recording a frame's command
//! buffer with every barrier the frame needs (the tests run under synchronization validation).
//! Normal mode records one command buffer anew every frame and waits for it; `--record-once`
//! records one per combination of acquired swapchain images the first time it is needed and then
//! only resubmits it, as simple engines do, with the per-frame data in memory it reads.

use crate::cli::{DepthClear, DepthMode, Layout, Options};
use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use crate::passes::{PassFormat, Passes, PipelineKind};
use crate::stats::{GpuCounters, PixelCounters, BINDING_RANGE};
use crate::targets::{depth_aspect, Targets};
use ash::vk;
use glam::{Mat4, Vec4};
use std::collections::HashMap;
use std::path::PathBuf;

// SPIR-V from build.rs; read_spv copies into u32-aligned storage.
const SCENE_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene.vert.spv"));
const SCENE_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene.frag.spv"));
const SCENE_MV_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_mv.vert.spv"));
const SCENE_MV_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_mv.frag.spv"));
const SCENE_VK10_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_vk10.vert.spv"));
const SCENE_VK10_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_vk10.frag.spv"));

/// Uniform block `Frame` of the shaders (std140: mat4s and vec4s only, no padding surprises).
/// Everything that changes from frame to frame is here, never in push constants, so that a
/// command buffer recorded once (`--record-once`) still draws each frame's view.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct FrameUniforms {
    pub view_proj: [Mat4; 2],
    pub cube_model: Mat4,
    pub eye_pos: [Vec4; 2],
    /// `--far-movers`: the far mover's model matrix (identity without it).
    pub mover_model: Mat4,
}

/// Per draw and constant for the whole run (eye index, options, pixel-stats geometry).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct PushConstants {
    eye: u32,
    shading_cost: u32,
    flags: u32,
    /// `--pixel-stats`: the eye rect's origin x in the framebuffer, its size, and the element
    /// distance between the views' regions in the bound range (multiview only).
    pix_origin_x: i32,
    pix_width: u32,
    pix_height: u32,
    pix_view_stride: u32,
}

const PC_MANUAL_SRGB: u32 = 1;
const PC_PIXEL_STATS: u32 = 2;

struct Buffer {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
}

impl Buffer {
    fn null() -> Buffer {
        Buffer { buffer: vk::Buffer::null(), memory: vk::DeviceMemory::null() }
    }

    fn new(gpu: &Gpu, size: u64, usage: vk::BufferUsageFlags, props: vk::MemoryPropertyFlags) -> Result<Buffer> {
        let d = &gpu.device;
        // SAFETY: valid create infos; on failure the partial object is destroyed.
        unsafe {
            let buffer = d
                .create_buffer(&vk::BufferCreateInfo::default().size(size).usage(usage), None)
                .ctx("vkCreateBuffer")?;
            let mut b = Buffer { buffer, memory: vk::DeviceMemory::null() };
            let req = d.get_buffer_memory_requirements(buffer);
            let r = gpu.memory_type(req.memory_type_bits, props).and_then(|ty| {
                d.allocate_memory(&vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty), None)
                    .ctx("vkAllocateMemory")
            });
            match r {
                Ok(m) => b.memory = m,
                Err(e) => {
                    b.destroy(d);
                    return Err(e);
                }
            }
            if let Err(e) = d.bind_buffer_memory(buffer, b.memory, 0) {
                b.destroy(d);
                return Err(e).ctx("vkBindBufferMemory");
            }
            Ok(b)
        }
    }

    fn destroy(&mut self, d: &ash::Device) {
        // SAFETY: no pending GPU work uses it (callers wait); our handles (null is ignored).
        unsafe {
            d.destroy_buffer(self.buffer, None);
            if self.memory != vk::DeviceMemory::null() {
                d.free_memory(self.memory, None);
            }
        }
        self.buffer = vk::Buffer::null();
        self.memory = vk::DeviceMemory::null();
    }
}

/// Indices of the swapchain images acquired for this frame, per slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Acquired {
    pub color: u32,
    pub depth: Option<u32>,
}

/// What the app measured of one frame once its GPU work finished.
#[derive(Debug, Clone, Copy)]
pub struct FrameResult {
    pub frame: u64,
    pub gpu_time_ms: f64,
    /// Shaded fragments per view.
    pub counts: [u64; 2],
    /// CPU time spent recording the frame's command buffers, µs (0 when `--record-once`
    /// resubmitted buffers recorded for an earlier frame).
    pub record_us: f64,
}

/// Everything one submission reads or writes that the host also touches: its command buffers, the
/// uniform buffer the host fills before the submission, the counters it reads after, and the
/// fence in between. The host waits for the fence before it writes the uniforms or reads or
/// re-zeroes the counters again, so no submission's data is overwritten while the GPU reads it.
struct FrameSet {
    cmd: vk::CommandBuffer,
    /// `--secondary`: one secondary command buffer per pass (per slot); empty without the flag.
    secondaries: Vec<vk::CommandBuffer>,
    fence: vk::Fence,
    descriptor_pool: vk::DescriptorPool,
    descriptor_set: vk::DescriptorSet,
    uniforms: Buffer,
    uniforms_mapped: *mut FrameUniforms,
    counters: GpuCounters,
    /// `--pixel-stats`: per-pixel counters. Without it, binding 2 aliases the per-view counters
    /// (same ranges, same offsets) and the shader never touches it.
    pixels: Option<PixelCounters>,
    /// `--record-once`: the command buffers hold this set's frame (they are never re-recorded).
    recorded: bool,
    /// Submitted and not yet waited for: (frame number, recording time in µs).
    pending: Option<(u64, f64)>,
}

pub struct Renderer {
    device: ash::Device,
    layout: Layout,
    multiview: bool,
    intermediate: bool,
    bind_before_pass: bool,
    samples: vk::SampleCountFlags,
    clear_depth: f32,
    depth_clear: DepthClear,
    push: PushConstants,
    passes: Passes,
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    /// `--sky-first`: the sky's own pipeline (depth test and write off); null without it.
    sky_pipeline: vk::Pipeline,
    /// `--translucent`: the pane's pipeline (blended, depth write off); null without it.
    translucent_pipeline: vk::Pipeline,
    vertices: Buffer,
    indices: Buffer,
    /// The scene's index ranges ([`crate::scene::Scene`]): opaque, sky, translucent counts.
    opaque_count: u32,
    sky_count: u32,
    translucent_count: u32,
    /// Which optional parts the scene has (`--sky`, `--translucent`, `--far-movers`).
    parts: crate::scene::Parts,
    /// `--sky-first`: the sky is drawn first in each pass, by its own draw.
    sky_first: bool,
    /// `--empty`: record the passes without their draws.
    empty: bool,
    /// `--sync-hazard`: leave out the counters' fill → fragment shader barrier.
    sync_hazard: bool,
    /// `--record-once`: one frame set per combination of acquired images, never re-recorded...
    record_once: bool,
    /// ... except every N-th frame's (`--rerecord-every N`).
    rerecord_every: Option<u64>,
    /// `--pixel-stats DIR`: where a finished frame's per-pixel counts go.
    pixel_stats: Option<PathBuf>,
    /// Each view's image rect size (the per-pixel counters' regions).
    view_sizes: [(u32, u32); 2],
    /// `--secondary`: each pass's contents go into a secondary command buffer of its own.
    secondary: bool,
    /// How many passes a frame has (the number of secondaries `--secondary` needs per set).
    pass_count: u32,
    command_pool: vk::CommandPool,
    /// Normal mode: one set, re-recorded and waited for every frame. `--record-once`: one per
    /// entry of `sets_by_images`, each in flight until the frame that needs it again.
    sets: Vec<FrameSet>,
    sets_by_images: HashMap<Vec<Acquired>, usize>,
}

impl Renderer {
    pub fn new(opts: &Options, gpu: &Gpu, targets: &Targets) -> Result<Renderer> {
        let d = &gpu.device;
        let multiview = opts.layout == Layout::Multiview;
        let passes = Passes::new(
            gpu,
            opts.rendering,
            PassFormat {
                color: targets.color_format,
                depth: targets.depth_format,
                samples: targets.samples,
                view_mask: multiview.then_some(0b11),
                store_depth: opts.submit_depth,
                has_stencil: depth_aspect(targets.depth_format).contains(vk::ImageAspectFlags::STENCIL),
                load_depth: opts.depth_clear != DepthClear::LoadOp,
            },
        )?;
        let view_sizes = targets.views.map(|v| (v.extent.width, v.extent.height));
        let mut flags = if opts.color_format == crate::cli::ColorFamily::Unorm { PC_MANUAL_SRGB } else { 0 };
        if opts.pixel_stats.is_some() {
            flags |= PC_PIXEL_STATS;
        }
        let mut r = Renderer {
            device: d.clone(),
            layout: opts.layout,
            multiview,
            intermediate: opts.intermediate,
            bind_before_pass: opts.bind_before_pass,
            samples: targets.samples,
            clear_depth: if opts.depth == DepthMode::Reverse { 0.0 } else { 1.0 },
            depth_clear: opts.depth_clear,
            push: PushConstants {
                eye: 0,
                shading_cost: opts.shading_cost,
                flags,
                pix_origin_x: 0,
                pix_width: 0,
                pix_height: 0,
                pix_view_stride: if opts.pixel_stats.is_some() { PixelCounters::stride_for(gpu, view_sizes, multiview) } else { 0 },
            },
            passes,
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            sky_pipeline: vk::Pipeline::null(),
            translucent_pipeline: vk::Pipeline::null(),
            vertices: Buffer::null(),
            indices: Buffer::null(),
            opaque_count: 0,
            sky_count: 0,
            translucent_count: 0,
            parts: crate::scene::Parts {
                sky: opts.sky == crate::cli::Sky::Geometry,
                translucent: opts.translucent,
                far_mover: opts.far_movers,
            },
            sky_first: opts.sky_first,
            empty: opts.empty,
            sync_hazard: opts.sync_hazard,
            record_once: opts.record_once,
            rerecord_every: opts.rerecord_every,
            pixel_stats: opts.pixel_stats.clone(),
            view_sizes,
            secondary: opts.secondary,
            pass_count: targets.slots.len() as u32,
            command_pool: vk::CommandPool::null(),
            sets: Vec::new(),
            sets_by_images: HashMap::new(),
        };
        r.init(opts, gpu)?;
        Ok(r)
    }

    fn init(&mut self, opts: &Options, gpu: &Gpu) -> Result<()> {
        let d = &gpu.device;
        // SAFETY: plain object creation on a live device; everything is destroyed in Drop.
        unsafe {
            self.command_pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(gpu.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .ctx("vkCreateCommandPool")?;

            let bindings = [
                vk::DescriptorSetLayoutBinding::default()
                    .binding(0)
                    .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT),
                vk::DescriptorSetLayoutBinding::default()
                    .binding(1)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::FRAGMENT),
                vk::DescriptorSetLayoutBinding::default()
                    .binding(2)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::FRAGMENT),
            ];
            self.set_layout = d
                .create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
                .ctx("vkCreateDescriptorSetLayout")?;
            let ranges = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: std::mem::size_of::<PushConstants>() as u32,
            }];
            let set_layouts = [self.set_layout];
            self.pipeline_layout = d
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges),
                    None,
                )
                .ctx("vkCreatePipelineLayout")?;

            let (vs, fs) = match (self.multiview, opts.vulkan_api) {
                (true, _) => (SCENE_MV_VERT, SCENE_MV_FRAG),
                (false, crate::cli::VulkanApi::V1_0) => (SCENE_VK10_VERT, SCENE_VK10_FRAG),
                (false, _) => (SCENE_VERT, SCENE_FRAG),
            };
            let vert = shader_module(d, vs, opts.vulkan_api)?;
            let frag = match shader_module(d, fs, opts.vulkan_api) {
                Ok(f) => f,
                Err(e) => {
                    d.destroy_shader_module(vert, None);
                    return Err(e);
                }
            };
            let compare = if opts.depth == DepthMode::Reverse { vk::CompareOp::GREATER } else { vk::CompareOp::LESS };
            // Extra pipelines only for the options that draw with them, so that the default run
            // creates exactly what it always did.
            let mut kinds = vec![PipelineKind::Opaque];
            if opts.sky_first {
                kinds.push(PipelineKind::Sky);
            }
            if opts.translucent {
                kinds.push(PipelineKind::Translucent);
            }
            let mut created = Ok(());
            for kind in kinds {
                match self.passes.create_pipeline(self.pipeline_layout, vert, frag, compare, kind) {
                    Ok(p) => match kind {
                        PipelineKind::Opaque => self.pipeline = p,
                        PipelineKind::Sky => self.sky_pipeline = p,
                        PipelineKind::Translucent => self.translucent_pipeline = p,
                    },
                    Err(e) => {
                        created = Err(e);
                        break;
                    }
                }
            }
            d.destroy_shader_module(vert, None);
            d.destroy_shader_module(frag, None);
            created?;
        }
        self.upload_scene(gpu)
    }

    /// A new frame set: command buffers, fence, and the uniforms, counters and descriptor set that
    /// its command buffers read and write. Pushed onto `sets` as soon as it holds anything, so
    /// Drop frees what a failure left behind.
    fn new_set(&mut self, gpu: &Gpu) -> Result<usize> {
        let d = &gpu.device;
        let counters = GpuCounters::new(gpu)?;
        let pixels = match self.pixel_stats {
            Some(_) => Some(PixelCounters::new(gpu, self.view_sizes)?),
            None => None,
        };
        self.sets.push(FrameSet {
            cmd: vk::CommandBuffer::null(),
            secondaries: Vec::new(),
            fence: vk::Fence::null(),
            descriptor_pool: vk::DescriptorPool::null(),
            descriptor_set: vk::DescriptorSet::null(),
            uniforms: Buffer::null(),
            uniforms_mapped: std::ptr::null_mut(),
            counters,
            pixels,
            recorded: false,
            pending: None,
        });
        let index = self.sets.len() - 1;
        let set = &mut self.sets[index];
        // SAFETY: plain object creation on a live device; everything is destroyed in Drop.
        unsafe {
            set.cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(self.command_pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .ctx("vkAllocateCommandBuffers")?[0];
            if self.secondary {
                set.secondaries = d
                    .allocate_command_buffers(
                        &vk::CommandBufferAllocateInfo::default()
                            .command_pool(self.command_pool)
                            .level(vk::CommandBufferLevel::SECONDARY)
                            .command_buffer_count(self.pass_count),
                    )
                    .ctx("vkAllocateCommandBuffers(secondary)")?;
            }
            set.fence = d.create_fence(&vk::FenceCreateInfo::default(), None).ctx("vkCreateFence")?;

            let pool_sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: 1 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER_DYNAMIC, descriptor_count: 2 },
            ];
            set.descriptor_pool = d
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&pool_sizes), None)
                .ctx("vkCreateDescriptorPool")?;
            let set_layouts = [self.set_layout];
            set.descriptor_set = d
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default().descriptor_pool(set.descriptor_pool).set_layouts(&set_layouts),
                )
                .ctx("vkAllocateDescriptorSets")?[0];

            let ubo_size = std::mem::size_of::<FrameUniforms>() as u64;
            set.uniforms = Buffer::new(
                gpu,
                ubo_size,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT,
            )?;
            set.uniforms_mapped = d
                .map_memory(set.uniforms.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                .ctx("vkMapMemory(uniforms)")? as *mut FrameUniforms;

            let ubo_info = [vk::DescriptorBufferInfo { buffer: set.uniforms.buffer, offset: 0, range: ubo_size }];
            let ssbo_info = [vk::DescriptorBufferInfo { buffer: set.counters.buffer, offset: 0, range: BINDING_RANGE }];
            let pixel_info = [match &set.pixels {
                Some(p) => vk::DescriptorBufferInfo { buffer: p.buffer, offset: 0, range: p.binding_range(self.multiview) },
                None => ssbo_info[0],
            }];
            let writes = [
                vk::WriteDescriptorSet::default()
                    .dst_set(set.descriptor_set)
                    .dst_binding(0)
                    .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
                    .buffer_info(&ubo_info),
                vk::WriteDescriptorSet::default()
                    .dst_set(set.descriptor_set)
                    .dst_binding(1)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .buffer_info(&ssbo_info),
                vk::WriteDescriptorSet::default()
                    .dst_set(set.descriptor_set)
                    .dst_binding(2)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .buffer_info(&pixel_info),
            ];
            d.update_descriptor_sets(&writes, &[]);
        }
        Ok(index)
    }

    /// Puts the scene into device-local buffers through a staging buffer and a fenced copy.
    fn upload_scene(&mut self, gpu: &Gpu) -> Result<()> {
        let d = &gpu.device;
        let scene = crate::scene::build_parts(self.parts);
        let mesh = scene.mesh;
        self.opaque_count = scene.opaque;
        self.sky_count = scene.sky;
        self.translucent_count = scene.translucent;
        // SAFETY: Vertex is repr(C) plain data.
        let vbytes = unsafe {
            std::slice::from_raw_parts(mesh.vertices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.vertices[..]))
        };
        // SAFETY: u32 slice viewed as bytes.
        let ibytes = unsafe {
            std::slice::from_raw_parts(mesh.indices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.indices[..]))
        };
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        self.vertices = Buffer::new(gpu, vbytes.len() as u64, dst | vk::BufferUsageFlags::VERTEX_BUFFER, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
        self.indices = Buffer::new(gpu, ibytes.len() as u64, dst | vk::BufferUsageFlags::INDEX_BUFFER, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
        let total = (vbytes.len() + ibytes.len()) as u64;
        let mut staging = Buffer::new(
            gpu,
            total,
            vk::BufferUsageFlags::TRANSFER_SRC,
            vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT,
        )?;
        let (mut cmd, mut fence) = (vk::CommandBuffer::null(), vk::Fence::null());
        // SAFETY: the staging memory is host-visible and `total` bytes long; the copy is fenced
        // and waited for before the staging buffer, the command buffer and the fence go.
        let result = unsafe {
            (|| -> Result<()> {
                let p = d.map_memory(staging.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).ctx("vkMapMemory")? as *mut u8;
                std::ptr::copy_nonoverlapping(vbytes.as_ptr(), p, vbytes.len());
                std::ptr::copy_nonoverlapping(ibytes.as_ptr(), p.add(vbytes.len()), ibytes.len());
                d.unmap_memory(staging.memory);
                cmd = d
                    .allocate_command_buffers(
                        &vk::CommandBufferAllocateInfo::default()
                            .command_pool(self.command_pool)
                            .level(vk::CommandBufferLevel::PRIMARY)
                            .command_buffer_count(1),
                    )
                    .ctx("vkAllocateCommandBuffers")?[0];
                fence = d.create_fence(&vk::FenceCreateInfo::default(), None).ctx("vkCreateFence")?;
                d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                    .ctx("vkBeginCommandBuffer")?;
                d.cmd_copy_buffer(cmd, staging.buffer, self.vertices.buffer, &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size: vbytes.len() as u64 }]);
                d.cmd_copy_buffer(cmd, staging.buffer, self.indices.buffer, &[vk::BufferCopy { src_offset: vbytes.len() as u64, dst_offset: 0, size: ibytes.len() as u64 }]);
                let mb = [vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::VERTEX_ATTRIBUTE_READ | vk::AccessFlags::INDEX_READ)];
                d.cmd_pipeline_barrier(cmd, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::VERTEX_INPUT, vk::DependencyFlags::empty(), &mb, &[], &[]);
                d.end_command_buffer(cmd).ctx("vkEndCommandBuffer")?;
                let cmds = [cmd];
                d.queue_submit(gpu.queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], fence).ctx("vkQueueSubmit")?;
                d.wait_for_fences(&[fence], true, u64::MAX).ctx("vkWaitForFences")
            })()
        };
        if result.is_err() {
            // SAFETY: nothing may still run on a failed path (a submitted copy is waited for).
            unsafe {
                let _ = d.device_wait_idle();
            }
        }
        // SAFETY: the copy finished (waited above); null handles are ignored.
        unsafe {
            d.destroy_fence(fence, None);
            if cmd != vk::CommandBuffer::null() {
                d.free_command_buffers(self.command_pool, &[cmd]);
            }
        }
        staging.destroy(d);
        result
    }

    /// Renders one frame: writes `uniforms` for the GPU, records (normal mode: anew every frame;
    /// `--record-once`: only the first time this combination of acquired images occurs, and in
    /// every N-th frame with `--rerecord-every N`) and
    /// submits. Returns the measurements of every frame whose GPU work is known to be finished
    /// now: normal mode waits for this frame; `--record-once` waits only when it reuses a set, for
    /// the frame that set held before (the others stay in flight; [`Renderer::finish`] collects them).
    pub fn render(&mut self, gpu: &Gpu, targets: &Targets, acquired: &[Acquired], uniforms: &FrameUniforms, frame: u64) -> Result<Vec<FrameResult>> {
        let index = match (self.record_once, self.sets_by_images.get(acquired)) {
            (true, Some(&i)) => i,
            (true, None) => {
                let i = self.new_set(gpu)?;
                self.sets_by_images.insert(acquired.to_vec(), i);
                i
            }
            (false, _) if self.sets.is_empty() => self.new_set(gpu)?,
            (false, _) => 0,
        };
        let mut done = Vec::new();
        // The set's previous submission must be finished before its uniforms are written and its
        // counters zeroed again.
        done.extend(self.complete(index)?);
        let record_start = std::time::Instant::now();
        let set = &self.sets[index];
        // SAFETY: the set's previous submission is complete (above), so the GPU reads nothing of
        // its uniform buffer, which is host-coherent and mapped for the set's lifetime.
        unsafe { set.uniforms_mapped.write(*uniforms) };
        let rerecord = self.rerecord_every.is_some_and(|n| frame > 0 && frame.is_multiple_of(n));
        let record_us = if self.record_once && set.recorded && !rerecord {
            0.0
        } else {
            self.record(gpu, index, targets, acquired)?;
            self.sets[index].recorded = true;
            record_start.elapsed().as_secs_f64() * 1e6
        };
        let set = &mut self.sets[index];
        let cmds = [set.cmd];
        // Both submissions below: the command buffer is fully recorded and not pending (its fence
        // was waited for); the fence is unsignalled (reset after every wait).
        if gpu.submit2 {
            let infos = [vk::CommandBufferSubmitInfo::default().command_buffer(set.cmd)];
            // SAFETY: see above; synchronization2 is enabled with --submit2.
            unsafe { gpu.device.queue_submit2(gpu.queue, &[vk::SubmitInfo2::default().command_buffer_infos(&infos)], set.fence) }.ctx("vkQueueSubmit2")?;
        } else {
            // SAFETY: see above.
            unsafe { gpu.device.queue_submit(gpu.queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], set.fence) }.ctx("vkQueueSubmit")?;
        }
        set.pending = Some((frame, record_us));
        if !self.record_once {
            // One frame at a time: measured before the next one is recorded.
            done.extend(self.complete(index)?);
        }
        Ok(done)
    }

    /// Waits for every frame still in flight and returns their measurements, in frame order.
    pub fn finish(&mut self) -> Result<Vec<FrameResult>> {
        let mut order: Vec<(u64, usize)> = self.sets.iter().enumerate().filter_map(|(i, s)| s.pending.map(|(f, _)| (f, i))).collect();
        order.sort_unstable();
        let mut done = Vec::new();
        for (_, i) in order {
            done.extend(self.complete(i)?);
        }
        Ok(done)
    }

    /// If set `index` has a submission in flight: waits for it, reads its counters (and writes
    /// its per-pixel counts) and makes the set reusable.
    fn complete(&mut self, index: usize) -> Result<Option<FrameResult>> {
        let set = &mut self.sets[index];
        let Some((frame, record_us)) = set.pending.take() else { return Ok(None) };
        let d = &self.device;
        // SAFETY: the fence was submitted with the set's command buffer.
        unsafe {
            d.wait_for_fences(&[set.fence], true, u64::MAX).ctx("vkWaitForFences")?;
            d.reset_fences(&[set.fence]).ctx("vkResetFences")?;
        }
        let (gpu_time_ms, counts) = set.counters.read(self.multiview)?;
        if let (Some(p), Some(dir)) = (&set.pixels, &self.pixel_stats) {
            p.write(dir, frame)?;
        }
        Ok(Some(FrameResult { frame, gpu_time_ms, counts, record_us }))
    }

    /// Records frame set `index`'s command buffers for the images in `acquired`.
    fn record(&mut self, gpu: &Gpu, index: usize, targets: &Targets, acquired: &[Acquired]) -> Result<()> {
        let d = gpu.device.clone();
        let set = &self.sets[index];
        let cmd = set.cmd;
        // A command buffer recorded once is submitted many times (and so are the secondaries it
        // executes): ONE_TIME_SUBMIT only where it is re-recorded for every submission.
        let usage = if self.record_once { vk::CommandBufferUsageFlags::empty() } else { vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT };
        // SAFETY: the set's previous submission was waited for, so its command buffers are not
        // pending and may be reset. All recorded handles are alive.
        unsafe {
            d.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty()).ctx("vkResetCommandBuffer")?;
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default().flags(usage)).ctx("vkBeginCommandBuffer")?;
            set.counters.record_start(cmd);
            if let Some(p) = &set.pixels {
                p.record_start(cmd);
            }
            self.pre_pass_barriers(cmd, set, targets, acquired);

            for (slot_index, a) in acquired.iter().enumerate() {
                let slot = &targets.slots[slot_index];
                let color_view = match &slot.offscreen {
                    Some(o) => o.view,
                    None => slot.color.views[a.color as usize],
                };
                let depth_view = match (&slot.depth, a.depth, &slot.own_depth) {
                    (Some(chain), Some(i), _) => chain.views[i as usize],
                    (_, _, Some(own)) => own.view,
                    _ => return Err(Error("internal: slot without depth".into())),
                };
                let extent = slot.extent;
                // Which views this pass draws, one draw each (multiview: one draw for both).
                let draws: Vec<u32> = match self.layout {
                    Layout::PerEye => vec![slot_index as u32],
                    Layout::SideBySide => vec![0, 1],
                    Layout::Multiview => vec![0],
                };
                // Where the pass's contents are recorded: its secondary, or the primary itself.
                let rec = set.secondaries.get(slot_index).copied().unwrap_or(cmd);
                let bind = |eye: u32, viewport: bool| {
                    let rect = targets.views[eye as usize];
                    let (x, w) = if self.multiview { (0, extent.width) } else { (rect.offset_x, rect.extent.width) };
                    let h = rect.extent.height;
                    if viewport {
                        d.cmd_set_viewport(rec, 0, &[vk::Viewport { x: x as f32, y: 0.0, width: w as f32, height: h as f32, min_depth: 0.0, max_depth: 1.0 }]);
                        d.cmd_set_scissor(rec, 0, &[vk::Rect2D { offset: vk::Offset2D { x, y: 0 }, extent: vk::Extent2D { width: w, height: h } }]);
                    }
                    d.cmd_bind_descriptor_sets(
                        rec,
                        vk::PipelineBindPoint::GRAPHICS,
                        self.pipeline_layout,
                        0,
                        &[set.descriptor_set],
                        &[
                            set.counters.dynamic_offset(eye, self.multiview),
                            match &set.pixels {
                                Some(p) => p.dynamic_offset(eye, self.multiview),
                                None => set.counters.dynamic_offset(eye, self.multiview),
                            },
                        ],
                    );
                    let pc = PushConstants { eye, pix_origin_x: x, pix_width: rect.extent.width, pix_height: h, ..self.push };
                    let bytes = std::slice::from_raw_parts(&pc as *const PushConstants as *const u8, std::mem::size_of::<PushConstants>());
                    d.cmd_push_constants(rec, self.pipeline_layout, vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT, 0, bytes);
                };
                let bind_buffers = || {
                    d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
                    d.cmd_bind_vertex_buffers(rec, 0, &[self.vertices.buffer], &[0]);
                    d.cmd_bind_index_buffer(rec, self.indices.buffer, 0, vk::IndexType::UINT32);
                };
                // `--bind-before-pass`: all draw state of a one-draw pass (pipeline and buffers of
                // any pass) is set before the pass begins — legal, and what a layer that injects
                // draws into the pass must preserve.
                let early = self.bind_before_pass;
                let one_draw = draws.len() == 1;
                if early {
                    bind_buffers();
                    if one_draw {
                        bind(draws[0], true);
                    }
                }
                // `--secondary`: the pass's contents (its clear, binds and draws) go into its own
                // secondary command buffer, recorded first and executed inside the pass.
                if let Some(&sec) = set.secondaries.get(slot_index) {
                    self.passes.begin_secondary(gpu, sec, color_view, depth_view, extent, usage)?;
                } else {
                    self.passes.begin(gpu, cmd, color_view, depth_view, extent, self.clear_depth, false)?;
                }
                // `--depth-clear attachments`: the pass loaded depth; clearing it is its first command.
                if self.depth_clear == DepthClear::Attachments {
                    self.passes.clear_depth_attachment(gpu, rec, extent, self.clear_depth);
                }
                if !early {
                    bind_buffers();
                }
                for eye in draws.iter().copied() {
                    if !(early && one_draw) {
                        bind(eye, true);
                    }
                    if self.empty {
                        continue;
                    }
                    // Pipelines share one layout, so switching keeps the bound set and push
                    // constants. Default scene: one draw, the sky last in it.
                    if self.sky_first {
                        d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.sky_pipeline);
                        d.cmd_draw_indexed(rec, self.sky_count, 1, self.opaque_count, 0, 0);
                        d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
                        d.cmd_draw_indexed(rec, self.opaque_count, 1, 0, 0, 0);
                    } else {
                        d.cmd_draw_indexed(rec, self.opaque_count + self.sky_count, 1, 0, 0, 0);
                    }
                    if self.translucent_count > 0 {
                        // After everything opaque, as translucent geometry must be.
                        d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.translucent_pipeline);
                        d.cmd_draw_indexed(rec, self.translucent_count, 1, self.opaque_count + self.sky_count, 0, 0);
                        d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
                    }
                }
                if rec != cmd {
                    d.end_command_buffer(rec).ctx("vkEndCommandBuffer(secondary)")?;
                    self.passes.begin(gpu, cmd, color_view, depth_view, extent, self.clear_depth, true)?;
                    d.cmd_execute_commands(cmd, &[rec]);
                }
                self.passes.end(gpu, cmd);
            }

            if self.intermediate {
                self.resolve_to_swapchains(cmd, targets, acquired);
            }
            set.counters.record_end(cmd);
            if let Some(p) = &set.pixels {
                p.record_end(cmd);
            }
            d.end_command_buffer(cmd).ctx("vkEndCommandBuffer")?;
        }
        Ok(())
    }
    /// Everything the passes write, ordered after its previous use and put in attachment layout.
    fn pre_pass_barriers(&self, cmd: vk::CommandBuffer, set: &FrameSet, targets: &Targets, acquired: &[Acquired]) {
        let mut images = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let color_range = range(vk::ImageAspectFlags::COLOR, slot.layers);
            let depth_range = range(depth_aspect(targets.depth_format), slot.layers);
            let color_rw = vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE;
            let depth_rw = vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
            match &slot.offscreen {
                // Last frame's resolve/copy read it; its contents are cleared anyway.
                Some(o) => images.push(image_barrier(
                    o.image,
                    color_range,
                    vk::ImageLayout::UNDEFINED,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::empty(),
                    color_rw,
                )),
                // The runtime hands swapchain images out in COLOR_ATTACHMENT_OPTIMAL.
                None => images.push(image_barrier(
                    slot.color.images[a.color as usize],
                    color_range,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                    color_rw,
                )),
            }
            // `--depth-clear image`: depth goes to TRANSFER_DST_OPTIMAL for its clear first.
            let (depth_layout, depth_access) = if self.depth_clear == DepthClear::Image {
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE)
            } else {
                (vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL, depth_rw)
            };
            match (&slot.depth, a.depth, &slot.own_depth) {
                (Some(chain), Some(di), _) => images.push(image_barrier(
                    chain.images[di as usize],
                    depth_range,
                    vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                    depth_layout,
                    vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                    depth_access,
                )),
                (_, _, Some(own)) => images.push(image_barrier(
                    own.image,
                    depth_range,
                    vk::ImageLayout::UNDEFINED,
                    depth_layout,
                    vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                    depth_access,
                )),
                _ => {}
            }
        }
        let mut buffers = vec![set.counters.after_fill_barrier()];
        buffers.extend(set.pixels.as_ref().map(|p| p.after_fill_barrier()));
        if self.sync_hazard {
            // `--sync-hazard`: the fragment shader's atomics then race the fill (write after
            // write), which only synchronization validation notices.
            buffers.clear();
        }
        let fragment_tests = vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
        let mut dst_stages = vk::PipelineStageFlags::FRAGMENT_SHADER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests;
        if self.depth_clear == DepthClear::Image {
            dst_stages |= vk::PipelineStageFlags::TRANSFER;
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests,
                dst_stages,
                vk::DependencyFlags::empty(),
                &[],
                &buffers,
                &images,
            );
        }
        if self.depth_clear == DepthClear::Image {
            self.clear_depth_images(cmd, targets, acquired);
        }
    }

    /// `--depth-clear image`: `vkCmdClearDepthStencilImage` on every depth image of the frame (in
    /// TRANSFER_DST_OPTIMAL), then the clear made visible to the passes that load it, in
    /// DEPTH_STENCIL_ATTACHMENT_OPTIMAL.
    fn clear_depth_images(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        let value = vk::ClearDepthStencilValue { depth: self.clear_depth, stencil: 0 };
        let mut to_attachment = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let image = match (&slot.depth, a.depth, &slot.own_depth) {
                (Some(chain), Some(di), _) => chain.images[di as usize],
                (_, _, Some(own)) => own.image,
                _ => continue,
            };
            let r = range(depth_aspect(targets.depth_format), slot.layers);
            // SAFETY: recording, outside any pass; the image was just put in TRANSFER_DST_OPTIMAL.
            unsafe { self.device.cmd_clear_depth_stencil_image(cmd, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &value, &[r]) };
            to_attachment.push(image_barrier(
                image,
                r,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ));
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &to_attachment,
            );
        }
    }

    /// `--intermediate`: resolve (N > 1) or copy (N = 1) each offscreen target into its swapchain
    /// image, then hand the swapchain image back in COLOR_ATTACHMENT_OPTIMAL as the binding requires.
    fn resolve_to_swapchains(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        let d = &self.device;
        let mut to_transfer = Vec::new();
        let mut back = Vec::new();
        for (i, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[i];
            let Some(off) = &slot.offscreen else { continue };
            let r = range(vk::ImageAspectFlags::COLOR, slot.layers);
            let sc = slot.color.images[a.color as usize];
            to_transfer.push(image_barrier(
                off.image,
                r,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::TRANSFER_READ,
            ));
            to_transfer.push(image_barrier(
                sc,
                r,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::TRANSFER_WRITE,
            ));
            back.push(image_barrier(
                sc,
                r,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::AccessFlags::TRANSFER_WRITE,
                vk::AccessFlags::COLOR_ATTACHMENT_READ | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            ));
        }
        // SAFETY: recording state, outside any render pass; images are in the layouts named.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &to_transfer,
            );
            for (i, a) in acquired.iter().enumerate() {
                let slot = &targets.slots[i];
                let Some(off) = &slot.offscreen else { continue };
                let layers = vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: slot.layers,
                };
                let extent = vk::Extent3D { width: slot.extent.width, height: slot.extent.height, depth: 1 };
                let sc = slot.color.images[a.color as usize];
                if self.samples == vk::SampleCountFlags::TYPE_1 {
                    let region = vk::ImageCopy {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: layers,
                        dst_offset: vk::Offset3D::default(),
                        extent,
                    };
                    d.cmd_copy_image(cmd, off.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, sc, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
                } else {
                    let region = vk::ImageResolve {
                        src_subresource: layers,
                        src_offset: vk::Offset3D::default(),
                        dst_subresource: layers,
                        dst_offset: vk::Offset3D::default(),
                        extent,
                    };
                    d.cmd_resolve_image(cmd, off.image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, sc, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
                }
            }
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &back,
            );
        }
    }
}

fn range(aspect: vk::ImageAspectFlags, layers: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers }
}

fn image_barrier(
    image: vk::Image,
    range: vk::ImageSubresourceRange,
    old: vk::ImageLayout,
    new: vk::ImageLayout,
    src: vk::AccessFlags,
    dst: vk::AccessFlags,
) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .image(image)
        .subresource_range(range)
        .old_layout(old)
        .new_layout(new)
        .src_access_mask(src)
        .dst_access_mask(dst)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
}

/// The newest SPIR-V a device of this API version accepts (Vulkan 1.0: 1.0, 1.1: 1.3, 1.3: 1.6),
/// as the header's version word.
fn max_spirv(api: crate::cli::VulkanApi) -> u32 {
    match api {
        crate::cli::VulkanApi::V1_0 => 0x0001_0000,
        crate::cli::VulkanApi::V1_1 => 0x0001_0300,
        crate::cli::VulkanApi::V1_3 => 0x0001_0600,
    }
}

fn shader_module(d: &ash::Device, bytes: &[u8], api: crate::cli::VulkanApi) -> Result<vk::ShaderModule> {
    let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes)).ctx("reading SPIR-V")?;
    // Checked here too, so that a run without `--validation` fails as well (the validation layer
    // reports it as UNASSIGNED-CoreValidation-Shader-InconsistentSpirv).
    let version = words.get(1).copied().unwrap_or(u32::MAX);
    if version > max_spirv(api) {
        return Err(Error(format!("internal: a shader's SPIR-V version {version:#x} is too new for Vulkan 1.{}", api.minor())));
    }
    // SAFETY: valid SPIR-V produced by glslangValidator at build time.
    unsafe { d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }.ctx("vkCreateShaderModule")
}

impl Drop for Renderer {
    fn drop(&mut self) {
        let d = &self.device;
        // SAFETY: wait for the GPU (frames still in flight included), then destroy our objects
        // (null handles are ignored; command buffers go with their pool).
        unsafe {
            let _ = d.device_wait_idle();
            for set in &mut self.sets {
                d.destroy_fence(set.fence, None);
                d.destroy_descriptor_pool(set.descriptor_pool, None);
                set.uniforms.destroy(d);
            }
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline(self.sky_pipeline, None);
            d.destroy_pipeline(self.translucent_pipeline, None);
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_command_pool(self.command_pool, None);
        }
        self.vertices.destroy(d);
        self.indices.destroy(d);
    }
}
