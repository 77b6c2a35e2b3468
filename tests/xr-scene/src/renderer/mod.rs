//! Per-frame GPU work: scene buffers, descriptors, the pipeline, and recording a frame's command
//! buffer with every barrier the frame needs (the tests run under synchronization validation).
//! Normal mode records one command buffer anew every frame and waits for it; `--record-once`
//! records one per combination of acquired swapchain images the first time it is needed and then
//! only resubmits it, as simple engines do, with the per-frame data in memory it reads.
//! `--threads` records the passes' secondaries on worker threads and submits on a submit thread
//! (`crate::threads`). What is drawn inside a pass is `draw`, the barriers around the passes
//! `barriers`. With `--post` the eye passes render the chain's HDR target and `crate::post`
//! records the rest; with `--submit-texture double-wide` the frame ends with the blits.

mod barriers;
mod compositor;
mod draw;

use crate::cli::{DepthClear, DepthMode, Layout, Options};
use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use crate::passes::{PassFormat, Passes, PipelineKind};
use crate::stats::{GpuCounters, PixelCounters, BINDING_RANGE};
use crate::targets::{depth_aspect, Targets};
use crate::threads::{Submission, Submitter, Workers};
use ash::vk;
pub(crate) use barriers::{image_barrier, range};
pub(crate) use draw::shader_module;
pub use draw::PassTarget;
use draw::{Buffer, PushConstants, SceneDraw, SetBinding, PC_MANUAL_SRGB, PC_PIXEL_STATS};
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
    /// Each view's projection alone (`--draw-hidden-area`).
    pub proj: [Mat4; 2],
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
    /// CPU time of the frame's `vkQueueSubmit(2)` call, µs.
    pub submit_us: f64,
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
    pending: Option<(u64, f64, f64)>,
}

pub struct Renderer {
    device: ash::Device,
    intermediate: bool,
    /// `--one-target`: both eyes through one offscreen target, each copied right after its pass.
    one_target: bool,
    /// `--submit-via openvr`: the copy into the swapchain is the compositor's, not the app's.
    compositor: Option<compositor::Compositor>,
    samples: vk::SampleCountFlags,
    passes: Passes,
    /// Pipelines, scene buffers, push constants: what a pass's contents are recorded with.
    draw: SceneDraw,
    /// Which optional parts the scene has (`--sky`, `--translucent`, `--far-movers`).
    parts: crate::scene::Parts,
    /// `--draw-hidden-area`: each view's hidden-area mesh, drawn first in its eye's pass.
    hidden_area: Vec<crate::scene::HiddenAreaMesh>,
    /// The depth nothing can be nearer than (0 with standard depth, 1 reversed).
    near_depth: f32,
    /// `--sync-hazard`: leave out the counters' fill → fragment shader barrier.
    sync_hazard: bool,
    /// `--thread-hazard`: the workers' secondaries come from one pool.
    thread_hazard: bool,
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
    /// `--threads`: one recording worker (with its own command pool) per pass.
    workers: Option<Workers>,
    /// Every queue submission goes through it (`--threads`: on the submit thread).
    submitter: Submitter,
    /// Normal mode: one set, re-recorded and waited for every frame. `--record-once`: one per
    /// entry of `sets_by_images`, each in flight until the frame that needs it again.
    sets: Vec<FrameSet>,
    sets_by_images: HashMap<Vec<Acquired>, usize>,
    /// `--post`: the chain after the eye passes.
    post: Option<crate::post::PostChain>,
    /// `--dynamic-resolution`; and the scale of the frame being recorded.
    dynamic_resolution: bool,
    frame_scale: f32,
}

impl Renderer {
    pub fn new(opts: &Options, gpu: &Gpu, targets: &Targets, hidden_area: &[crate::scene::HiddenAreaMesh]) -> Result<Renderer> {
        let d = &gpu.device;
        let multiview = opts.layout == Layout::Multiview;
        let post = opts.post.is_some();
        let passes = Passes::new(
            gpu,
            opts.rendering,
            PassFormat {
                // `--post`: the eye pass renders HDR, tonemapped later.
                color: if post { crate::post::HDR_FORMAT } else { targets.color_format },
                depth: targets.depth_format,
                samples: targets.samples,
                view_mask: multiview.then_some(0b11),
                store_depth: opts.submit_depth,
                has_stencil: depth_aspect(targets.depth_format).contains(vk::ImageAspectFlags::STENCIL),
                load_depth: opts.depth_clear != DepthClear::LoadOp,
                resolve: post && targets.samples != vk::SampleCountFlags::TYPE_1,
                subpass_color: opts.post_subpass.then_some(targets.color_format),
            },
        )?;
        let view_sizes = targets.views.map(|v| (v.extent.width, v.extent.height));
        // The HDR target holds linear colour: only the tonemap encodes.
        let mut flags = if opts.color_format == crate::cli::ColorFamily::Unorm && !post { PC_MANUAL_SRGB } else { 0 };
        if opts.pixel_stats.is_some() {
            flags |= PC_PIXEL_STATS;
        }
        let mut r = Renderer {
            device: d.clone(),
            intermediate: opts.intermediate,
            compositor: None,
            one_target: opts.one_target,
            samples: targets.samples,
            passes,
            draw: SceneDraw {
                device: d.clone(),
                layout: opts.layout,
                multiview,
                bind_before_pass: opts.bind_before_pass,
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
                hidden_area_count: 0,
                sky_first: opts.sky_first,
                empty: opts.empty,
                dynamic: None,
                shaders: None,
            },
            parts: crate::scene::Parts {
                sky: opts.sky == crate::cli::Sky::Geometry,
                translucent: opts.translucent,
                far_mover: opts.far_movers,
            },
            hidden_area: hidden_area.to_vec(),
            near_depth: if opts.depth == crate::cli::DepthMode::Reverse { 1.0 } else { 0.0 },
            sync_hazard: opts.sync_hazard,
            thread_hazard: opts.thread_hazard,
            record_once: opts.record_once,
            rerecord_every: opts.rerecord_every,
            pixel_stats: opts.pixel_stats.clone(),
            view_sizes,
            secondary: opts.secondary,
            pass_count: targets.slots.len() as u32,
            command_pool: vk::CommandPool::null(),
            workers: None,
            submitter: Submitter::new(gpu, opts.threads)?,
            sets: Vec::new(),
            sets_by_images: HashMap::new(),
            post: None,
            dynamic_resolution: opts.dynamic_resolution,
            frame_scale: 1.0,
        };
        if opts.threads {
            r.workers = Some(Workers::new(gpu, targets.slots.len())?);
        }
        r.init(opts, gpu, targets)?;
        Ok(r)
    }

    fn init(&mut self, opts: &Options, gpu: &Gpu, targets: &Targets) -> Result<()> {
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
            self.draw.set_layout = d
                .create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
                .ctx("vkCreateDescriptorSetLayout")?;
            let ranges = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: std::mem::size_of::<PushConstants>() as u32,
            }];
            let set_layouts = [self.draw.set_layout];
            self.draw.pipeline_layout = d
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges),
                    None,
                )
                .ctx("vkCreatePipelineLayout")?;

            let (vs, fs) = match (self.draw.multiview, opts.vulkan_api) {
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
            self.passes.style = crate::passes::PipelineStyle { dynamic: opts.dynamic_state, library: opts.pipeline_library };
            if opts.dynamic_state {
                self.draw.dynamic = Some(draw::DynamicState {
                    eds3: ash::ext::extended_dynamic_state3::Device::new(&gpu.instance, d),
                    vertex_input: ash::ext::vertex_input_dynamic_state::Device::new(&gpu.instance, d),
                    depth_compare: compare,
                    samples: self.passes.format.samples,
                });
            }
            if opts.shader_object {
                // Shader objects instead of the scene's pipelines: no pipeline is made.
                kinds.clear();
                let device = ash::ext::shader_object::Device::new(&gpu.instance, d);
                match draw::ShaderObjects::new(device, vs, fs, &set_layouts, &ranges) {
                    Ok(s) => self.draw.shaders = Some(s),
                    Err(e) => {
                        d.destroy_shader_module(vert, None);
                        d.destroy_shader_module(frag, None);
                        return Err(e);
                    }
                }
            }
            let mut created = Ok(());
            for kind in kinds {
                match self.passes.create_pipeline(self.draw.pipeline_layout, vert, frag, compare, kind) {
                    Ok(p) => match kind {
                        PipelineKind::Opaque => self.draw.pipeline = p,
                        PipelineKind::Sky => self.draw.sky_pipeline = p,
                        PipelineKind::Translucent => self.draw.translucent_pipeline = p,
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
        if opts.post.is_some() {
            self.post = Some(crate::post::PostChain::new(gpu, opts, targets, self.passes.render_pass)?);
        }
        if opts.submit_via == crate::cli::SubmitVia::Openvr {
            self.compositor = Some(compositor::Compositor::new(gpu)?);
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
            match (&self.workers, self.secondary) {
                // `--threads`: pass i's secondary from worker i's pool, which only worker i
                // records into (allocated here while no worker runs). `--thread-hazard`: all of
                // them from the render thread's pool, which the workers then use at once.
                (Some(workers), _) => {
                    for i in 0..self.pass_count as usize {
                        let info = vk::CommandBufferAllocateInfo::default()
                            .command_pool(if self.thread_hazard { self.command_pool } else { workers.pool(i) })
                            .level(vk::CommandBufferLevel::SECONDARY)
                            .command_buffer_count(1);
                        set.secondaries.push(d.allocate_command_buffers(&info).ctx("vkAllocateCommandBuffers(secondary)")?[0]);
                    }
                }
                (None, true) => {
                    set.secondaries = d
                        .allocate_command_buffers(
                            &vk::CommandBufferAllocateInfo::default()
                                .command_pool(self.command_pool)
                                .level(vk::CommandBufferLevel::SECONDARY)
                                .command_buffer_count(self.pass_count),
                        )
                        .ctx("vkAllocateCommandBuffers(secondary)")?;
                }
                (None, false) => {}
            }
            set.fence = d.create_fence(&vk::FenceCreateInfo::default(), None).ctx("vkCreateFence")?;

            let pool_sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: 1 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER_DYNAMIC, descriptor_count: 2 },
            ];
            set.descriptor_pool = d
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&pool_sizes), None)
                .ctx("vkCreateDescriptorPool")?;
            let set_layouts = [self.draw.set_layout];
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
                Some(p) => vk::DescriptorBufferInfo { buffer: p.buffer, offset: 0, range: p.binding_range(self.draw.multiview) },
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
        let scene = crate::scene::build_parts(self.parts, &self.hidden_area, self.near_depth);
        let mesh = scene.mesh;
        self.draw.hidden_area_count = scene.hidden_area;
        self.draw.opaque_count = scene.opaque;
        self.draw.sky_count = scene.sky;
        self.draw.translucent_count = scene.translucent;
        // SAFETY: Vertex is repr(C) plain data.
        let vbytes = unsafe {
            std::slice::from_raw_parts(mesh.vertices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.vertices[..]))
        };
        // SAFETY: u32 slice viewed as bytes.
        let ibytes = unsafe {
            std::slice::from_raw_parts(mesh.indices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.indices[..]))
        };
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        self.draw.vertices = Buffer::new(gpu, vbytes.len() as u64, dst | vk::BufferUsageFlags::VERTEX_BUFFER, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
        self.draw.indices = Buffer::new(gpu, ibytes.len() as u64, dst | vk::BufferUsageFlags::INDEX_BUFFER, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
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
                d.cmd_copy_buffer(cmd, staging.buffer, self.draw.vertices.buffer, &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size: vbytes.len() as u64 }]);
                d.cmd_copy_buffer(cmd, staging.buffer, self.draw.indices.buffer, &[vk::BufferCopy { src_offset: vbytes.len() as u64, dst_offset: 0, size: ibytes.len() as u64 }]);
                let mb = [vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::VERTEX_ATTRIBUTE_READ | vk::AccessFlags::INDEX_READ)];
                d.cmd_pipeline_barrier(cmd, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::VERTEX_INPUT, vk::DependencyFlags::empty(), &mb, &[], &[]);
                if let Some(post) = &self.post {
                    post.record_init(cmd);
                }
                d.end_command_buffer(cmd).ctx("vkEndCommandBuffer")?;
                self.submitter.submit(Submission { cmd, fence, submit2: false })?;
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
        self.frame_scale = if self.dynamic_resolution { crate::post::dynamic_scale(frame) } else { 1.0 };
        let record_us = if self.record_once && set.recorded && !rerecord {
            0.0
        } else {
            self.record(gpu, index, targets, acquired)?;
            self.sets[index].recorded = true;
            record_start.elapsed().as_secs_f64() * 1e6
        };
        let set = &mut self.sets[index];
        // The command buffer is fully recorded and not pending (its fence was waited for); the
        // fence is unsignalled (reset after every wait).
        let submit_us = self.submitter.submit(Submission { cmd: set.cmd, fence: set.fence, submit2: gpu.submit2 })?;
        set.pending = Some((frame, record_us, submit_us));
        if !self.record_once {
            // One frame at a time: measured before the next one is recorded.
            done.extend(self.complete(index)?);
        }
        if let Some(c) = &self.compositor {
            c.submit(gpu, |cb| self.copy_to_swapchains(cb, targets, acquired))?;
        }
        Ok(done)
    }

    /// Waits for every frame still in flight and returns their measurements, in frame order.
    pub fn finish(&mut self) -> Result<Vec<FrameResult>> {
        let mut order: Vec<(u64, usize)> = self.sets.iter().enumerate().filter_map(|(i, s)| s.pending.map(|(f, ..)| (f, i))).collect();
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
        let Some((frame, record_us, submit_us)) = set.pending.take() else { return Ok(None) };
        let d = &self.device;
        // SAFETY: the fence was submitted with the set's command buffer.
        unsafe {
            d.wait_for_fences(&[set.fence], true, u64::MAX).ctx("vkWaitForFences")?;
            d.reset_fences(&[set.fence]).ctx("vkResetFences")?;
        }
        let (gpu_time_ms, counts) = set.counters.read(self.draw.multiview)?;
        if let (Some(p), Some(dir)) = (&set.pixels, &self.pixel_stats) {
            p.write(dir, frame)?;
        }
        Ok(Some(FrameResult { frame, gpu_time_ms, counts, record_us, submit_us }))
    }

    /// Records frame set `index`'s command buffers for the images in `acquired`. `--threads`: the
    /// passes' secondaries first, each on its worker, then the primary here.
    fn record(&mut self, gpu: &Gpu, index: usize, targets: &Targets, acquired: &[Acquired]) -> Result<()> {
        let d = gpu.device.clone();
        // Every pass's framebuffer exists before any recording starts (workers cannot make one).
        let mut passes = Vec::new();
        for (slot_index, a) in acquired.iter().enumerate() {
            let slot = &targets.slots[slot_index];
            let (_, final_view, _, _) = slot.final_image(a.color);
            // The eye pass's colour: the post chain's HDR target (multisampled, resolved into the
            // HDR target), `--intermediate`'s offscreen target, or the final image itself.
            // `--one-target`: every eye renders into the first slot's scene target.
            let post_slot = if self.one_target { &targets.slots[0] } else { slot };
            let (color_view, resolve_view) = match (&post_slot.post, targets.offscreen_of(slot_index)) {
                (Some(p), _) => match &p.scene_msaa {
                    Some(ms) => (ms.view, Some(p.scene.view)),
                    None => (p.scene.view, None),
                },
                (None, Some(o)) => (o.view, None),
                (None, None) => (final_view, None),
            };
            let subpass_view = self.passes.format.subpass_color.map(|_| final_view);
            let depth_view = match (&slot.depth, a.depth, targets.own_depth_of(slot_index)) {
                (Some(chain), Some(i), _) => chain.views[i as usize],
                (_, _, Some(own)) => own.view,
                _ => return Err(Error("internal: slot without depth".into())),
            };
            let mut pass = PassTarget { slot: slot_index, color_view, depth_view, resolve_view, subpass_view, extent: slot.scene_extent, framebuffer: vk::Framebuffer::null() };
            pass.framebuffer = self.passes.framebuffer(pass.attachments(), slot.scene_extent)?;
            passes.push(pass);
        }
        let set = &self.sets[index];
        let cmd = set.cmd;
        let multiview = self.draw.multiview;
        let offsets = [0u32, 1].map(|eye| {
            let counters = set.counters.dynamic_offset(eye, multiview);
            [counters, set.pixels.as_ref().map_or(counters, |p| p.dynamic_offset(eye, multiview))]
        });
        let views = targets.scene_views.map(|v| v.scaled(self.frame_scale));
        let binding = SetBinding { descriptor_set: set.descriptor_set, offsets, views };
        // A command buffer recorded once is submitted many times (and so are the secondaries it
        // executes): ONE_TIME_SUBMIT only where it is re-recorded for every submission.
        let usage = if self.record_once { vk::CommandBufferUsageFlags::empty() } else { vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT };
        if let Some(workers) = &mut self.workers {
            // Secondary i comes from worker i's pool (`new_set`), and worker i alone records it.
            let (draw, pass_objects, secondaries) = (&self.draw, &self.passes, &set.secondaries);
            workers.record(passes.len(), |i, meet| draw.record_secondary(gpu, pass_objects, secondaries[i], &passes[i], &binding, usage, &|| meet.arrive()))?;
        }
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
            for pass in &passes {
                match set.secondaries.get(pass.slot).copied() {
                    // `--secondary`: the pass's contents (its clear, binds and draws) go into its
                    // own secondary command buffer (recorded now unless a worker did), executed
                    // inside the pass.
                    Some(sec) => {
                        if self.workers.is_none() {
                            self.draw.record_secondary(gpu, &self.passes, sec, pass, &binding, usage, &|| {})?;
                        }
                        self.passes.begin(gpu, cmd, pass, self.draw.clear_depth, true)?;
                        d.cmd_execute_commands(cmd, &[sec]);
                    }
                    None => {
                        if self.draw.bind_before_pass {
                            self.draw.bind_before_pass(cmd, pass, &binding);
                        }
                        self.passes.begin(gpu, cmd, pass, self.draw.clear_depth, false)?;
                        self.draw.record_contents(gpu, &self.passes, cmd, pass, &binding);
                    }
                }
                if let (Some(post), Some(_)) = (&self.post, pass.subpass_view) {
                    post.record_subpass(gpu, &self.passes, cmd, pass);
                }
                self.passes.end(gpu, cmd);
                if self.one_target {
                    // This eye's picture leaves the shared target before the other eye renders:
                    // through its post chain, or copied.
                    match &mut self.post {
                        Some(post) => post.record_eye(gpu, cmd, targets, pass.slot, acquired[pass.slot].color, self.frame_scale)?,
                        None => self.resolve_to_swapchains(cmd, targets, acquired, Some(pass.slot)),
                    }
                    if pass.slot + 1 < passes.len() {
                        self.shared_depth_barrier(cmd, targets);
                    }
                }
            }
            if let (Some(post), false) = (&mut self.post, self.one_target) {
                post.record(gpu, cmd, targets, acquired, self.frame_scale)?;
            }
            if self.compositor.is_none() {
                self.copy_to_swapchains(cmd, targets, acquired);
            }
            set.counters.record_end(cmd);
            if let Some(p) = &set.pixels {
                p.record_end(cmd);
            }
            d.end_command_buffer(cmd).ctx("vkEndCommandBuffer")?;
        }
        Ok(())
    }

    /// `--intermediate`'s resolve or copy, `--submit-texture`'s blit: the app's textures into the
    /// swapchain images, recorded into `cmd` (the app's, or the compositor's).
    fn copy_to_swapchains(&self, cmd: vk::CommandBuffer, targets: &Targets, acquired: &[Acquired]) {
        if self.intermediate && !self.one_target {
            self.resolve_to_swapchains(cmd, targets, acquired, None);
        }
        if targets.slots.iter().any(|s| s.double_wide.is_some()) {
            self.blit_double_wide(cmd, targets, acquired);
        }
    }

    /// `--threads`: (frames recorded on workers, of which with two passes' recordings
    /// overlapping in time); None without workers.
    pub fn worker_frames(&self) -> Option<(u64, u64)> {
        self.workers.as_ref().map(|w| (w.recorded, w.overlapped))
    }
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
            d.destroy_pipeline(self.draw.pipeline, None);
            d.destroy_pipeline(self.draw.sky_pipeline, None);
            d.destroy_pipeline(self.draw.translucent_pipeline, None);
            if let Some(s) = &self.draw.shaders {
                s.destroy();
            }
            d.destroy_pipeline_layout(self.draw.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.draw.set_layout, None);
            d.destroy_command_pool(self.command_pool, None);
        }
        self.draw.vertices.destroy(d);
        self.draw.indices.destroy(d);
    }
}
