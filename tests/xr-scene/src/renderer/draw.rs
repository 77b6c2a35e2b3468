//! What is drawn inside an eye pass: the scene's pipelines, buffers and push constants, and the
//! recording of one pass's contents (its `--depth-clear attachments` clear, binds and draws) into a
//! command buffer. Everything here is read-only while frames are recorded and holds no per-frame
//! state, so `--threads` can record two passes' contents on two threads at once
//! ([`crate::threads::Workers`]).

use crate::cli::{DepthClear, Layout};
use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use crate::passes::{Passes, PipelineKind};
use crate::targets::ViewRect;
use ash::vk;

/// Per draw and constant for the whole run (eye index, options, pixel-stats geometry).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub(super) struct PushConstants {
    pub eye: u32,
    pub shading_cost: u32,
    pub flags: u32,
    /// `--pixel-stats`: the eye rect's origin x in the framebuffer, its size, and the element
    /// distance between the views' regions in the bound range (multiview only).
    pub pix_origin_x: i32,
    pub pix_width: u32,
    pub pix_height: u32,
    pub pix_view_stride: u32,
}

pub(super) const PC_MANUAL_SRGB: u32 = 1;
pub(super) const PC_PIXEL_STATS: u32 = 2;

pub(super) struct Buffer {
    pub buffer: vk::Buffer,
    pub memory: vk::DeviceMemory,
}

impl Buffer {
    pub fn null() -> Buffer {
        Buffer { buffer: vk::Buffer::null(), memory: vk::DeviceMemory::null() }
    }

    pub fn new(gpu: &Gpu, size: u64, usage: vk::BufferUsageFlags, props: vk::MemoryPropertyFlags) -> Result<Buffer> {
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

    pub fn destroy(&mut self, d: &ash::Device) {
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

/// One pass of a frame as its contents are recorded: the slot it renders, its attachments'
/// views, its size and (render pass objects) its framebuffer.
#[derive(Debug, Clone, Copy)]
pub struct PassTarget {
    pub slot: usize,
    pub color_view: vk::ImageView,
    pub depth_view: vk::ImageView,
    /// `--post --samples N>1`: the single-sampled target the colour resolves into.
    pub resolve_view: Option<vk::ImageView>,
    /// `--post-subpass`: subpass 1's colour attachment (the swapchain image or the double-wide
    /// texture).
    pub subpass_view: Option<vk::ImageView>,
    pub extent: vk::Extent2D,
    /// Null for dynamic rendering.
    pub framebuffer: vk::Framebuffer,
}

impl PassTarget {
    /// The framebuffer's attachments: colour, depth, and the resolve or subpass-1 attachment (at
    /// most one of them: the command line refuses MSAA with `--post-subpass`), or null.
    pub fn attachments(&self) -> [vk::ImageView; 3] {
        [self.color_view, self.depth_view, self.resolve_view.or(self.subpass_view).unwrap_or(vk::ImageView::null())]
    }
}

/// What a pass's draws bind of their frame set: plain values, so that a worker thread needs
/// nothing of the set itself (its mapped memory stays with the render thread).
#[derive(Debug, Clone, Copy)]
pub struct SetBinding {
    pub descriptor_set: vk::DescriptorSet,
    /// Per eye: the dynamic offsets of binding 1 (the per-view counters) and binding 2 (the
    /// per-pixel counters, or the per-view counters again without `--pixel-stats`).
    pub offsets: [[u32; 2]; 2],
    /// Each view's rect in the eye pass's target (its viewport).
    pub views: [ViewRect; 2],
}

/// The scene's draw state: created by [`super::Renderer`] (which destroys it), read by every
/// recording.
pub(super) struct SceneDraw {
    pub device: ash::Device,
    pub layout: Layout,
    pub multiview: bool,
    pub bind_before_pass: bool,
    pub clear_depth: f32,
    pub depth_clear: DepthClear,
    pub push: PushConstants,
    pub set_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
    pub pipeline: vk::Pipeline,
    /// `--sky-first`: the sky's own pipeline (depth test and write off); null without it.
    pub sky_pipeline: vk::Pipeline,
    /// `--translucent`: the pane's pipeline (blended, depth write off); null without it.
    pub translucent_pipeline: vk::Pipeline,
    pub vertices: Buffer,
    pub indices: Buffer,
    /// The scene's index ranges ([`crate::scene::Scene`]): opaque, sky, translucent counts.
    pub opaque_count: u32,
    pub sky_count: u32,
    pub translucent_count: u32,
    /// `--draw-hidden-area`: the hidden-area triangles, the last indices.
    pub hidden_area_count: u32,
    /// `--sky-first`: the sky is drawn first in each pass, by its own draw.
    pub sky_first: bool,
    /// `--empty`: record the passes without their draws.
    pub empty: bool,
    /// `--dynamic-state`: the state `set_state` records after each bind of a scene pipeline.
    pub dynamic: Option<DynamicState>,
    /// `--shader-object`: the scene's shaders, bound instead of its pipelines.
    pub shaders: Option<ShaderObjects>,
}

/// `--shader-object`: the scene's vertex and fragment shader objects.
pub(super) struct ShaderObjects {
    pub device: ash::ext::shader_object::Device,
    pub vert: vk::ShaderEXT,
    pub frag: vk::ShaderEXT,
}

impl ShaderObjects {
    /// Unlinked shader objects from the pipelines' SPIR-V, with their layout's sets and push
    /// constants.
    pub fn new(device: ash::ext::shader_object::Device, vs: &[u8], fs: &[u8], set_layouts: &[vk::DescriptorSetLayout], ranges: &[vk::PushConstantRange]) -> Result<ShaderObjects> {
        let words = |b: &[u8]| ash::util::read_spv(&mut std::io::Cursor::new(b)).ctx("reading SPIR-V");
        let (v, f) = (words(vs)?, words(fs)?);
        let info = |stage, next, code: &[u32]| {
            // SAFETY: the words' own memory, viewed as its bytes (u8 has no alignment needs).
            let bytes = unsafe { std::slice::from_raw_parts(code.as_ptr().cast::<u8>(), code.len() * 4) };
            vk::ShaderCreateInfoEXT::default()
                .stage(stage)
                .next_stage(next)
                .code_type(vk::ShaderCodeTypeEXT::SPIRV)
                .code(bytes)
                .name(c"main")
                .set_layouts(set_layouts)
                .push_constant_ranges(ranges)
        };
        let infos = [info(vk::ShaderStageFlags::VERTEX, vk::ShaderStageFlags::FRAGMENT, &v), info(vk::ShaderStageFlags::FRAGMENT, vk::ShaderStageFlags::empty(), &f)];
        // SAFETY: valid create infos whose arrays outlive the call.
        let shaders = unsafe { device.create_shaders(&infos, None) }.map_err(|(_, e)| e).ctx("vkCreateShadersEXT")?;
        Ok(ShaderObjects { device, vert: shaders[0], frag: shaders[1] })
    }

    /// Binds the scene's shaders, every other graphics stage bound to none (as a draw with
    /// shader objects needs).
    fn bind(&self, rec: vk::CommandBuffer) {
        use vk::ShaderStageFlags as S;
        let stages = [S::VERTEX, S::TESSELLATION_CONTROL, S::TESSELLATION_EVALUATION, S::GEOMETRY, S::FRAGMENT];
        let shaders = [self.vert, vk::ShaderEXT::null(), vk::ShaderEXT::null(), vk::ShaderEXT::null(), self.frag];
        // SAFETY: `rec` is recording; the shaders are alive.
        unsafe { self.device.cmd_bind_shaders(rec, &stages, &shaders) };
    }

    /// # Safety
    /// No recording that uses them may still execute.
    pub unsafe fn destroy(&self) {
        // SAFETY: per the contract.
        unsafe {
            self.device.destroy_shader(self.vert, None);
            self.device.destroy_shader(self.frag, None);
        }
    }
}

/// `--dynamic-state`: the extensions' commands and the values the pipelines leave to them.
pub(super) struct DynamicState {
    pub eds3: ash::ext::extended_dynamic_state3::Device,
    pub vertex_input: ash::ext::vertex_input_dynamic_state::Device,
    pub depth_compare: vk::CompareOp,
    pub samples: vk::SampleCountFlags,
}

impl SceneDraw {
    /// Which views a pass of `slot` draws, one draw each (multiview: one draw for both).
    pub fn draws(&self, slot: usize) -> Vec<u32> {
        match self.layout {
            Layout::PerEye => vec![slot as u32],
            Layout::SideBySide => vec![0, 1],
            Layout::Multiview => vec![0],
        }
    }

    /// Viewport and scissor (with `viewport`), descriptor set and push constants of view `eye`.
    fn bind(&self, rec: vk::CommandBuffer, _pass: &PassTarget, set: &SetBinding, eye: u32, viewport: bool) {
        let d = &self.device;
        // Multiview's rects start at 0 in both layers; `--viewport-scale` makes every rect smaller
        // than its target.
        let rect = set.views[eye as usize];
        let (x, w) = (rect.offset_x, rect.extent.width);
        let h = rect.extent.height;
        let pc = PushConstants { eye, pix_origin_x: x, pix_width: rect.extent.width, pix_height: h, ..self.push };
        // SAFETY: `rec` is recording (inside the pass, or before it with `--bind-before-pass`);
        // every handle is alive. PushConstants is repr(C) plain data, viewed as its bytes.
        unsafe {
            let vp = [vk::Viewport { x: x as f32, y: 0.0, width: w as f32, height: h as f32, min_depth: 0.0, max_depth: 1.0 }];
            let sc = [vk::Rect2D { offset: vk::Offset2D { x, y: 0 }, extent: vk::Extent2D { width: w, height: h } }];
            if viewport && self.shaders.is_some() {
                // Shader objects take the viewport count from the command buffer too.
                d.cmd_set_viewport_with_count(rec, &vp);
                d.cmd_set_scissor_with_count(rec, &sc);
            } else if viewport {
                d.cmd_set_viewport(rec, 0, &vp);
                d.cmd_set_scissor(rec, 0, &sc);
            }
            d.cmd_bind_descriptor_sets(rec, vk::PipelineBindPoint::GRAPHICS, self.pipeline_layout, 0, &[set.descriptor_set], &set.offsets[eye as usize]);
            let bytes = std::slice::from_raw_parts(&pc as *const PushConstants as *const u8, std::mem::size_of::<PushConstants>());
            d.cmd_push_constants(rec, self.pipeline_layout, vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT, 0, bytes);
        }
    }

    fn bind_buffers(&self, rec: vk::CommandBuffer) {
        let d = &self.device;
        match &self.shaders {
            Some(s) => s.bind(rec),
            // SAFETY: `rec` is recording; the pipeline is alive.
            None => unsafe { d.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, self.pipeline) },
        }
        // SAFETY: `rec` is recording; the buffers are alive.
        unsafe {
            d.cmd_bind_vertex_buffers(rec, 0, &[self.vertices.buffer], &[0]);
            d.cmd_bind_index_buffer(rec, self.indices.buffer, 0, vk::IndexType::UINT32);
        }
        self.set_state(rec, PipelineKind::Opaque);
    }

    /// Binds the pipeline of `kind` and, with `--dynamic-state`, sets its state.
    fn bind_kind(&self, rec: vk::CommandBuffer, kind: PipelineKind) {
        if let Some(s) = &self.shaders {
            // The kinds differ only in state: the same shaders, rebound as an app switching
            // materials would.
            s.bind(rec);
            self.set_state(rec, kind);
            return;
        }
        let p = match kind {
            PipelineKind::Opaque => self.pipeline,
            PipelineKind::Sky => self.sky_pipeline,
            PipelineKind::Translucent => self.translucent_pipeline,
        };
        // SAFETY: `rec` is recording; the pipeline is alive.
        unsafe { self.device.cmd_bind_pipeline(rec, vk::PipelineBindPoint::GRAPHICS, p) };
        self.set_state(rec, kind);
    }

    /// `--dynamic-state`: every state the pipelines leave dynamic but viewport and scissor (set
    /// per view by `bind`), with the values `--dynamic-state` off builds into the pipeline of
    /// `kind`: the same pictures, drawn with state from commands, as DXVK draws.
    fn set_state(&self, rec: vk::CommandBuffer, kind: PipelineKind) {
        let Some(s) = &self.dynamic else { return };
        let d = &self.device;
        let bindings = [vk::VertexInputBindingDescription2EXT::default()
            .binding(0)
            .stride(std::mem::size_of::<crate::scene::Vertex>() as u32)
            .input_rate(vk::VertexInputRate::VERTEX)
            .divisor(1)];
        let attr = |location, format, offset| vk::VertexInputAttributeDescription2EXT::default().location(location).binding(0).format(format).offset(offset);
        let attributes = [
            attr(0, vk::Format::R32G32B32_SFLOAT, 0),
            attr(1, vk::Format::R32G32B32_SFLOAT, 12),
            attr(2, vk::Format::R32G32B32_SFLOAT, 24),
            attr(3, vk::Format::R32_UINT, 36),
        ];
        // The pane's blend (`PipelineKind::Translucent`), as the static pipeline has it.
        let equation = vk::ColorBlendEquationEXT {
            src_color_blend_factor: vk::BlendFactor::CONSTANT_ALPHA,
            dst_color_blend_factor: vk::BlendFactor::ONE_MINUS_CONSTANT_ALPHA,
            color_blend_op: vk::BlendOp::ADD,
            src_alpha_blend_factor: vk::BlendFactor::ZERO,
            dst_alpha_blend_factor: vk::BlendFactor::ONE,
            alpha_blend_op: vk::BlendOp::ADD,
        };
        // SAFETY: `rec` is recording with a scene pipeline bound that has these states dynamic;
        // the device has the extensions and features (`Gpu::create_device`).
        unsafe {
            d.cmd_set_cull_mode(rec, vk::CullModeFlags::NONE);
            d.cmd_set_front_face(rec, vk::FrontFace::COUNTER_CLOCKWISE);
            d.cmd_set_primitive_topology(rec, vk::PrimitiveTopology::TRIANGLE_LIST);
            d.cmd_set_depth_test_enable(rec, kind != PipelineKind::Sky);
            d.cmd_set_depth_write_enable(rec, kind == PipelineKind::Opaque);
            d.cmd_set_depth_compare_op(rec, s.depth_compare);
            d.cmd_set_depth_bounds_test_enable(rec, false);
            d.cmd_set_stencil_test_enable(rec, false);
            d.cmd_set_stencil_op(rec, vk::StencilFaceFlags::FRONT_AND_BACK, vk::StencilOp::KEEP, vk::StencilOp::KEEP, vk::StencilOp::KEEP, vk::CompareOp::ALWAYS);
            d.cmd_set_depth_bias_enable(rec, false);
            d.cmd_set_primitive_restart_enable(rec, false);
            d.cmd_set_rasterizer_discard_enable(rec, false);
            if self.shaders.is_some() {
                // Static in every pipeline; shader objects take them from the command buffer.
                d.cmd_set_blend_constants(rec, &[0.0, 0.0, 0.0, crate::scene::PANE_ALPHA]);
                d.cmd_set_depth_bias(rec, 0.0, 0.0, 0.0);
            }
            s.vertex_input.cmd_set_vertex_input(rec, &bindings, &attributes);
            s.eds3.cmd_set_polygon_mode(rec, vk::PolygonMode::FILL);
            s.eds3.cmd_set_rasterization_samples(rec, s.samples);
            s.eds3.cmd_set_sample_mask(rec, s.samples, &[u32::MAX]);
            s.eds3.cmd_set_alpha_to_coverage_enable(rec, false);
            s.eds3.cmd_set_depth_clamp_enable(rec, false);
            s.eds3.cmd_set_color_blend_enable(rec, 0, &[(kind == PipelineKind::Translucent).into()]);
            s.eds3.cmd_set_color_blend_equation(rec, 0, &[equation]);
            s.eds3.cmd_set_color_write_mask(rec, 0, &[vk::ColorComponentFlags::RGBA]);
        }
    }

    /// `--bind-before-pass`: all draw state of a one-draw pass (pipeline and buffers of any pass)
    /// is set on the primary before the pass begins — legal, and what a layer that injects draws
    /// into the pass must preserve.
    pub fn bind_before_pass(&self, cmd: vk::CommandBuffer, pass: &PassTarget, set: &SetBinding) {
        self.bind_buffers(cmd);
        if let [eye] = self.draws(pass.slot)[..] {
            self.bind(cmd, pass, set, eye, true);
        }
    }

    /// Records the contents of `pass` into `rec` (the primary inside the open pass, or the pass's
    /// secondary): the depth clear of `--depth-clear attachments`, binds, and the draws.
    pub fn record_contents(&self, gpu: &Gpu, passes: &Passes, rec: vk::CommandBuffer, pass: &PassTarget, set: &SetBinding) {
        let d = &self.device;
        let draws = self.draws(pass.slot);
        let early = self.bind_before_pass;
        let one_draw = draws.len() == 1;
        // `--depth-clear attachments`: the pass loaded depth; clearing it is its first command.
        if self.depth_clear == DepthClear::Attachments {
            passes.clear_depth_attachment(gpu, rec, pass.extent, self.clear_depth);
        }
        if !early {
            self.bind_buffers(rec);
        }
        for eye in draws.iter().copied() {
            if !(early && one_draw) {
                self.bind(rec, pass, set, eye, true);
            }
            if self.empty {
                continue;
            }
            // SAFETY: `rec` is recording inside the pass with pipeline, buffers and set bound.
            unsafe {
                if self.hidden_area_count > 0 {
                    // First in the pass, as games draw the runtime's mask: at the near depth,
                    // so the depth test rejects the scene's fragments behind it.
                    d.cmd_draw_indexed(rec, self.hidden_area_count, 1, self.opaque_count + self.sky_count + self.translucent_count, 0, 0);
                }
                // Pipelines share one layout, so switching keeps the bound set and push
                // constants. Default scene: one draw, the sky last in it.
                if self.sky_first {
                    self.bind_kind(rec, PipelineKind::Sky);
                    d.cmd_draw_indexed(rec, self.sky_count, 1, self.opaque_count, 0, 0);
                    self.bind_kind(rec, PipelineKind::Opaque);
                    d.cmd_draw_indexed(rec, self.opaque_count, 1, 0, 0, 0);
                } else {
                    d.cmd_draw_indexed(rec, self.opaque_count + self.sky_count, 1, 0, 0, 0);
                }
                if self.translucent_count > 0 {
                    // After everything opaque, as translucent geometry must be.
                    self.bind_kind(rec, PipelineKind::Translucent);
                    d.cmd_draw_indexed(rec, self.translucent_count, 1, self.opaque_count + self.sky_count, 0, 0);
                    self.bind_kind(rec, PipelineKind::Opaque);
                }
            }
        }
    }

    /// `--secondary`: begins `secondary` continuing `pass`, records the pass's contents into it,
    /// calls `before_end` and ends it. Touches no state but `secondary` (and its pool), so passes
    /// may be recorded on different threads when their secondaries come from different pools.
    #[allow(clippy::too_many_arguments)]
    pub fn record_secondary(
        &self,
        gpu: &Gpu,
        passes: &Passes,
        secondary: vk::CommandBuffer,
        pass: &PassTarget,
        set: &SetBinding,
        usage: vk::CommandBufferUsageFlags,
        before_end: &dyn Fn(),
    ) -> Result<()> {
        passes.begin_secondary(gpu, secondary, pass.framebuffer, usage)?;
        self.record_contents(gpu, passes, secondary, pass, set);
        before_end();
        // SAFETY: begun above, no pass of its own open (it continues the primary's).
        unsafe { self.device.end_command_buffer(secondary) }.ctx("vkEndCommandBuffer(secondary)")
    }
}

/// The newest SPIR-V a device of this API version accepts (Vulkan 1.0: 1.0, 1.1: 1.3, 1.3: 1.6),
/// as the header's version word.
pub(super) fn max_spirv(api: crate::cli::VulkanApi) -> u32 {
    match api {
        crate::cli::VulkanApi::V1_0 => 0x0001_0000,
        crate::cli::VulkanApi::V1_1 => 0x0001_0300,
        crate::cli::VulkanApi::V1_3 => 0x0001_0600,
    }
}
pub(crate) fn shader_module(d: &ash::Device, bytes: &[u8], api: crate::cli::VulkanApi) -> Result<vk::ShaderModule> {
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
