//! Per-frame GPU work: scene buffers, descriptors, the pipeline, and recording one frame's
//! command buffer with every barrier the frame needs (the tests run under synchronization validation).

use crate::cli::{DepthClear, DepthMode, Layout, Options};
use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use crate::passes::{PassFormat, Passes};
use crate::stats::{GpuCounters, PixelCounters, BINDING_RANGE};
use crate::targets::{depth_aspect, Targets};
use ash::vk;
use glam::{Mat4, Vec4};

// SPIR-V from build.rs; read_spv copies into u32-aligned storage.
const SCENE_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene.vert.spv"));
const SCENE_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene.frag.spv"));
const SCENE_MV_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_mv.vert.spv"));
const SCENE_MV_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_mv.frag.spv"));
const SCENE_VK10_VERT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_vk10.vert.spv"));
const SCENE_VK10_FRAG: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/scene_vk10.frag.spv"));

/// Uniform block `Frame` of the shaders (std140: mat4s and vec4s only, no padding surprises).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct FrameUniforms {
    pub view_proj: [Mat4; 2],
    pub cube_model: Mat4,
    pub eye_pos: [Vec4; 2],
}

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
        // SAFETY: device idle; our handles (null is ignored).
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
#[derive(Debug, Clone, Copy)]
pub struct Acquired {
    pub color: u32,
    pub depth: Option<u32>,
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
    descriptor_pool: vk::DescriptorPool,
    descriptor_set: vk::DescriptorSet,
    vertices: Buffer,
    indices: Buffer,
    index_count: u32,
    /// `--empty`: record the passes without their draws.
    empty: bool,
    uniforms: Buffer,
    uniforms_mapped: *mut FrameUniforms,
    pub counters: GpuCounters,
    /// `--pixel-stats`: per-pixel counters. Without it, binding 2 aliases the per-view counters
    /// (same ranges, same offsets) and the shader never touches it.
    pub pixels: Option<PixelCounters>,
    command_pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    /// `--secondary`: one secondary command buffer per pass of a frame (per slot), recorded anew
    /// every frame with the pass's contents; empty without the flag.
    secondaries: Vec<vk::CommandBuffer>,
    fence: vk::Fence,
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
        let counters = GpuCounters::new(gpu)?;
        let pixels = match opts.pixel_stats {
            Some(_) => Some(PixelCounters::new(gpu, targets.views.map(|v| (v.extent.width, v.extent.height)))?),
            None => None,
        };
        let mut flags = if opts.color_format == crate::cli::ColorFamily::Unorm { PC_MANUAL_SRGB } else { 0 };
        if pixels.is_some() {
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
                pix_view_stride: pixels.as_ref().map_or(0, |p| p.view_stride(multiview)),
            },
            passes,
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            descriptor_pool: vk::DescriptorPool::null(),
            descriptor_set: vk::DescriptorSet::null(),
            vertices: Buffer { buffer: vk::Buffer::null(), memory: vk::DeviceMemory::null() },
            indices: Buffer { buffer: vk::Buffer::null(), memory: vk::DeviceMemory::null() },
            index_count: 0,
            empty: opts.empty,
            uniforms: Buffer { buffer: vk::Buffer::null(), memory: vk::DeviceMemory::null() },
            uniforms_mapped: std::ptr::null_mut(),
            counters,
            pixels,
            command_pool: vk::CommandPool::null(),
            cmd: vk::CommandBuffer::null(),
            secondaries: Vec::new(),
            fence: vk::Fence::null(),
        };
        r.init(opts, gpu, targets.slots.len() as u32)?;
        Ok(r)
    }

    /// `passes`: how many passes a frame has (the number of secondaries `--secondary` needs).
    fn init(&mut self, opts: &Options, gpu: &Gpu, passes: u32) -> Result<()> {
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
            self.cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(self.command_pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .ctx("vkAllocateCommandBuffers")?[0];
            if opts.secondary {
                self.secondaries = d
                    .allocate_command_buffers(
                        &vk::CommandBufferAllocateInfo::default()
                            .command_pool(self.command_pool)
                            .level(vk::CommandBufferLevel::SECONDARY)
                            .command_buffer_count(passes),
                    )
                    .ctx("vkAllocateCommandBuffers(secondary)")?;
            }
            self.fence = d.create_fence(&vk::FenceCreateInfo::default(), None).ctx("vkCreateFence")?;

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
            let pipeline = self.passes.create_pipeline(self.pipeline_layout, vert, frag, compare);
            d.destroy_shader_module(vert, None);
            d.destroy_shader_module(frag, None);
            self.pipeline = pipeline?;

            let pool_sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: 1 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER_DYNAMIC, descriptor_count: 2 },
            ];
            self.descriptor_pool = d
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&pool_sizes), None)
                .ctx("vkCreateDescriptorPool")?;
            self.descriptor_set = d
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(self.descriptor_pool)
                        .set_layouts(&set_layouts),
                )
                .ctx("vkAllocateDescriptorSets")?[0];

            let ubo_size = std::mem::size_of::<FrameUniforms>() as u64;
            self.uniforms = Buffer::new(
                gpu,
                ubo_size,
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT,
            )?;
            self.uniforms_mapped = d
                .map_memory(self.uniforms.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                .ctx("vkMapMemory(uniforms)")? as *mut FrameUniforms;

            let ubo_info = [vk::DescriptorBufferInfo { buffer: self.uniforms.buffer, offset: 0, range: ubo_size }];
            let ssbo_info = [vk::DescriptorBufferInfo { buffer: self.counters.buffer, offset: 0, range: BINDING_RANGE }];
            let pixel_info = [match &self.pixels {
                Some(p) => vk::DescriptorBufferInfo { buffer: p.buffer, offset: 0, range: p.binding_range(self.multiview) },
                None => ssbo_info[0],
            }];
            let writes = [
                vk::WriteDescriptorSet::default()
                    .dst_set(self.descriptor_set)
                    .dst_binding(0)
                    .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
                    .buffer_info(&ubo_info),
                vk::WriteDescriptorSet::default()
                    .dst_set(self.descriptor_set)
                    .dst_binding(1)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .buffer_info(&ssbo_info),
                vk::WriteDescriptorSet::default()
                    .dst_set(self.descriptor_set)
                    .dst_binding(2)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER_DYNAMIC)
                    .buffer_info(&pixel_info),
            ];
            d.update_descriptor_sets(&writes, &[]);
        }
        self.upload_scene(gpu)
    }

    /// Puts the scene into device-local buffers through a staging buffer and a fenced copy.
    fn upload_scene(&mut self, gpu: &Gpu) -> Result<()> {
        let d = &gpu.device;
        let mesh = crate::scene::build();
        // SAFETY: Vertex is repr(C) plain data.
        let vbytes = unsafe {
            std::slice::from_raw_parts(mesh.vertices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.vertices[..]))
        };
        // SAFETY: u32 slice viewed as bytes.
        let ibytes = unsafe {
            std::slice::from_raw_parts(mesh.indices.as_ptr() as *const u8, std::mem::size_of_val(&mesh.indices[..]))
        };
        self.index_count = mesh.indices.len() as u32;
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
        // SAFETY: the staging memory is host-visible and `total` bytes long; the copy is fenced
        // and waited for before the staging buffer is destroyed.
        let result = unsafe {
            (|| -> Result<()> {
                let p = d.map_memory(staging.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).ctx("vkMapMemory")? as *mut u8;
                std::ptr::copy_nonoverlapping(vbytes.as_ptr(), p, vbytes.len());
                std::ptr::copy_nonoverlapping(ibytes.as_ptr(), p.add(vbytes.len()), ibytes.len());
                d.unmap_memory(staging.memory);
                d.begin_command_buffer(self.cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                    .ctx("vkBeginCommandBuffer")?;
                d.cmd_copy_buffer(self.cmd, staging.buffer, self.vertices.buffer, &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size: vbytes.len() as u64 }]);
                d.cmd_copy_buffer(self.cmd, staging.buffer, self.indices.buffer, &[vk::BufferCopy { src_offset: vbytes.len() as u64, dst_offset: 0, size: ibytes.len() as u64 }]);
                let mb = [vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::VERTEX_ATTRIBUTE_READ | vk::AccessFlags::INDEX_READ)];
                d.cmd_pipeline_barrier(self.cmd, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::VERTEX_INPUT, vk::DependencyFlags::empty(), &mb, &[], &[]);
                d.end_command_buffer(self.cmd).ctx("vkEndCommandBuffer")?;
                self.submit_and_wait(gpu)
            })()
        };
        staging.destroy(d);
        result
    }

    fn submit_and_wait(&self, gpu: &Gpu) -> Result<()> {
        let d = &gpu.device;
        let cmds = [self.cmd];
        // SAFETY: the command buffer is fully recorded; the fence is unsignalled.
        unsafe {
            d.queue_submit(gpu.queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], self.fence)
                .ctx("vkQueueSubmit")?;
            d.wait_for_fences(&[self.fence], true, u64::MAX).ctx("vkWaitForFences")?;
            d.reset_fences(&[self.fence]).ctx("vkResetFences")?;
        }
        Ok(())
    }

    /// Records, submits and waits for one frame; returns (GPU ms, shaded fragments per view).
    /// Records, submits and waits for one frame. Returns the GPU time in ms, the shaded fragments
    /// per view, and the CPU time spent recording the command buffer in µs (what a Vulkan layer's
    /// per-command overhead adds to).
    pub fn render(&mut self, gpu: &Gpu, targets: &Targets, acquired: &[Acquired], uniforms: &FrameUniforms) -> Result<(f64, [u64; 2], f64)> {
        let d = gpu.device.clone();
        let cmd = self.cmd;
        let record_start = std::time::Instant::now();
        // SAFETY: one frame in flight: the previous submit was waited on, so the uniform buffer
        // and the command buffer are free to reuse. All recorded handles are alive.
        unsafe {
            self.uniforms_mapped.write(*uniforms);
            d.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty()).ctx("vkResetCommandBuffer")?;
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                .ctx("vkBeginCommandBuffer")?;
            self.counters.record_start(cmd);
            if let Some(p) = &self.pixels {
                p.record_start(cmd);
            }
            self.pre_pass_barriers(targets, acquired);

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
                let rec = self.secondaries.get(slot_index).copied().unwrap_or(cmd);
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
                        &[self.descriptor_set],
                        &[
                            self.counters.dynamic_offset(eye, self.multiview),
                            match &self.pixels {
                                Some(p) => p.dynamic_offset(eye, self.multiview),
                                None => self.counters.dynamic_offset(eye, self.multiview),
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
                if let Some(&sec) = self.secondaries.get(slot_index) {
                    self.passes.begin_secondary(gpu, sec, color_view, depth_view, extent)?;
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
                    if !self.empty {
                        d.cmd_draw_indexed(rec, self.index_count, 1, 0, 0, 0);
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
                self.resolve_to_swapchains(targets, acquired);
            }
            self.counters.record_end(cmd);
            if let Some(p) = &self.pixels {
                p.record_end(cmd);
            }
            d.end_command_buffer(cmd).ctx("vkEndCommandBuffer")?;
        }
        let record_us = record_start.elapsed().as_secs_f64() * 1e6;
        self.submit_and_wait(gpu)?;
        let (gpu_ms, counts) = self.counters.read(self.multiview)?;
        Ok((gpu_ms, counts, record_us))
    }

    /// Everything the passes write, ordered after its previous use and put in attachment layout.
    fn pre_pass_barriers(&self, targets: &Targets, acquired: &[Acquired]) {
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
        let mut buffers = vec![self.counters.after_fill_barrier()];
        buffers.extend(self.pixels.as_ref().map(|p| p.after_fill_barrier()));
        let fragment_tests = vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
        let mut dst_stages = vk::PipelineStageFlags::FRAGMENT_SHADER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests;
        if self.depth_clear == DepthClear::Image {
            dst_stages |= vk::PipelineStageFlags::TRANSFER;
        }
        // SAFETY: recording state, outside any render pass.
        unsafe {
            self.device.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT | fragment_tests,
                dst_stages,
                vk::DependencyFlags::empty(),
                &[],
                &buffers,
                &images,
            );
        }
        if self.depth_clear == DepthClear::Image {
            self.clear_depth_images(targets, acquired);
        }
    }

    /// `--depth-clear image`: `vkCmdClearDepthStencilImage` on every depth image of the frame (in
    /// TRANSFER_DST_OPTIMAL), then the clear made visible to the passes that load it, in
    /// DEPTH_STENCIL_ATTACHMENT_OPTIMAL.
    fn clear_depth_images(&self, targets: &Targets, acquired: &[Acquired]) {
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
            unsafe { self.device.cmd_clear_depth_stencil_image(self.cmd, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &value, &[r]) };
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
                self.cmd,
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
    fn resolve_to_swapchains(&self, targets: &Targets, acquired: &[Acquired]) {
        let d = &self.device;
        let cmd = self.cmd;
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
        // SAFETY: wait for the GPU, then destroy our objects (null handles are ignored).
        unsafe {
            let _ = d.device_wait_idle();
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_pool(self.descriptor_pool, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_fence(self.fence, None);
            d.destroy_command_pool(self.command_pool, None);
        }
        self.vertices.destroy(d);
        self.indices.destroy(d);
        self.uniforms.destroy(d);
    }
}
