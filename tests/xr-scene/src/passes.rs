//! The three ways the app opens a render pass instance (`--rendering`): a classic render pass,
//! a render pass made with vkCreateRenderPass2, or dynamic rendering. Each shape matters to the
//! layer under test, which has to find and modify the app's eye passes in all of them. With
//! `--post` the eye pass may also resolve its multisampled colour into a resolve attachment
//! (`resolveImageView` with dynamic rendering), and with `--post-subpass` its render pass has a
//! second subpass that reads the scene as an input attachment and writes the swapchain image.

use crate::cli::Rendering;
use crate::error::{Ctx, Result};
use crate::gpu::{DynamicRendering, Gpu, RenderPass2};
use ash::vk;
use std::collections::HashMap;

/// Formats and sample count shared by every pass of the app.
#[derive(Debug, Clone, Copy)]
pub struct PassFormat {
    pub color: vk::Format,
    pub depth: vk::Format,
    pub samples: vk::SampleCountFlags,
    /// `Some(0b11)` for the multiview layout.
    pub view_mask: Option<u32>,
    /// Depth is submitted to the runtime, so it must be stored.
    pub store_depth: bool,
    pub has_stencil: bool,
    /// `--depth-clear attachments|image`: the depth (and stencil) attachment is loaded, not
    /// cleared by the pass; the app clears it itself (inside the pass or before it).
    pub load_depth: bool,
    /// `--post --samples N>1`: the multisampled colour resolves into a single-sampled attachment
    /// of the same format at the end of the pass (attachment 2), as Bevy's main pass does.
    pub resolve: bool,
    /// `--post-subpass`: the format of subpass 1's colour attachment (attachment 2: the swapchain
    /// image, or the double-wide texture), which reads attachment 0 as an input attachment.
    pub subpass_color: Option<vk::Format>,
}

/// The layout attachment 0 ends the pass in: read by subpass 1 with `--post-subpass` (and left
/// so; the next frame discards it), else still a colour attachment.
const SUBPASS_INPUT_LAYOUT: vk::ImageLayout = vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL;

pub struct Passes {
    device: ash::Device,
    mode: Rendering,
    pub format: PassFormat,
    /// Null for dynamic rendering.
    pub render_pass: vk::RenderPass,
    /// By attachment views: colour, depth, and the resolve or subpass-1 attachment (or null).
    framebuffers: HashMap<[vk::ImageView; 3], vk::Framebuffer>,
    /// How the scene's pipelines are built (`--dynamic-state`, `--pipeline-library`).
    pub style: PipelineStyle,
    /// `--pipeline-library`: the libraries of the linked pipelines, kept while those live (the
    /// spec's rule) and destroyed with the passes.
    libraries: std::sync::Mutex<Vec<vk::Pipeline>>,
}

/// `--dynamic-state` and `--pipeline-library`: the scene's pipelines built as DXVK builds its own.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PipelineStyle {
    /// Nearly every state dynamic (`SceneDraw::set_state` sets them after each bind).
    pub dynamic: bool,
    /// Linked from four graphics pipeline libraries, one per state subset.
    pub library: bool,
}

/// The states `--dynamic-state` leaves to commands: extended dynamic state 1 and 2 (core in 1.3),
/// 3 (those every device with the extension's features has) and vertex input.
pub const DYNAMIC_STATES: [vk::DynamicState; 23] = [
    vk::DynamicState::VIEWPORT,
    vk::DynamicState::SCISSOR,
    vk::DynamicState::CULL_MODE,
    vk::DynamicState::FRONT_FACE,
    vk::DynamicState::PRIMITIVE_TOPOLOGY,
    vk::DynamicState::DEPTH_TEST_ENABLE,
    vk::DynamicState::DEPTH_WRITE_ENABLE,
    vk::DynamicState::DEPTH_COMPARE_OP,
    vk::DynamicState::DEPTH_BOUNDS_TEST_ENABLE,
    vk::DynamicState::STENCIL_TEST_ENABLE,
    vk::DynamicState::STENCIL_OP,
    vk::DynamicState::DEPTH_BIAS_ENABLE,
    vk::DynamicState::PRIMITIVE_RESTART_ENABLE,
    vk::DynamicState::RASTERIZER_DISCARD_ENABLE,
    vk::DynamicState::VERTEX_INPUT_EXT,
    vk::DynamicState::POLYGON_MODE_EXT,
    vk::DynamicState::RASTERIZATION_SAMPLES_EXT,
    vk::DynamicState::SAMPLE_MASK_EXT,
    vk::DynamicState::ALPHA_TO_COVERAGE_ENABLE_EXT,
    vk::DynamicState::DEPTH_CLAMP_ENABLE_EXT,
    vk::DynamicState::COLOR_BLEND_ENABLE_EXT,
    vk::DynamicState::COLOR_BLEND_EQUATION_EXT,
    vk::DynamicState::COLOR_WRITE_MASK_EXT,
];

const COLOR_LAYOUT: vk::ImageLayout = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
const DEPTH_LAYOUT: vk::ImageLayout = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL;

impl Passes {
    pub fn new(gpu: &Gpu, mode: Rendering, format: PassFormat) -> Result<Passes> {
        let mut p = Passes {
            device: gpu.device.clone(),
            mode,
            format,
            render_pass: vk::RenderPass::null(),
            framebuffers: HashMap::new(),
            style: PipelineStyle::default(),
            libraries: std::sync::Mutex::new(Vec::new()),
        };
        let depth_store = if format.store_depth { vk::AttachmentStoreOp::STORE } else { vk::AttachmentStoreOp::DONT_CARE };
        let depth_load = if format.load_depth { vk::AttachmentLoadOp::LOAD } else { vk::AttachmentLoadOp::CLEAR };
        // Images arrive in their attachment layouts (barriers outside the pass put them there),
        // so the passes themselves do no layout transitions.
        // A multisampled colour that is resolved is not kept; a scene read by subpass 1 is not
        // kept either (Godot Mobile's transient HDR buffer).
        let color_store = if format.resolve || format.subpass_color.is_some() { vk::AttachmentStoreOp::DONT_CARE } else { vk::AttachmentStoreOp::STORE };
        let color_final = if format.subpass_color.is_some() { SUBPASS_INPUT_LAYOUT } else { COLOR_LAYOUT };
        // Attachment 2: the resolve target (same format, one sample) or subpass 1's colour.
        let third = match (format.resolve, format.subpass_color) {
            (true, _) => Some((format.color, vk::AttachmentLoadOp::DONT_CARE)),
            (false, Some(f)) => Some((f, vk::AttachmentLoadOp::CLEAR)),
            (false, None) => None,
        };
        let view_mask = format.view_mask.unwrap_or(0);
        match mode {
            Rendering::RenderPass => {
                let mut attachments = vec![
                    vk::AttachmentDescription::default()
                        .format(format.color)
                        .samples(format.samples)
                        .load_op(vk::AttachmentLoadOp::CLEAR)
                        .store_op(color_store)
                        .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                        .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                        .initial_layout(COLOR_LAYOUT)
                        .final_layout(color_final),
                    vk::AttachmentDescription::default()
                        .format(format.depth)
                        .samples(format.samples)
                        .load_op(depth_load)
                        .store_op(depth_store)
                        .stencil_load_op(depth_load)
                        .stencil_store_op(depth_store)
                        .initial_layout(DEPTH_LAYOUT)
                        .final_layout(DEPTH_LAYOUT),
                ];
                if let Some((f, load)) = third {
                    attachments.push(
                        vk::AttachmentDescription::default()
                            .format(f)
                            .samples(vk::SampleCountFlags::TYPE_1)
                            .load_op(load)
                            .store_op(vk::AttachmentStoreOp::STORE)
                            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                            .initial_layout(COLOR_LAYOUT)
                            .final_layout(COLOR_LAYOUT),
                    );
                }
                let color_ref = [vk::AttachmentReference { attachment: 0, layout: COLOR_LAYOUT }];
                let depth_ref = vk::AttachmentReference { attachment: 1, layout: DEPTH_LAYOUT };
                let third_ref = [vk::AttachmentReference { attachment: 2, layout: COLOR_LAYOUT }];
                let input_ref = [vk::AttachmentReference { attachment: 0, layout: SUBPASS_INPUT_LAYOUT }];
                let mut subpasses = vec![vk::SubpassDescription::default()
                    .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                    .color_attachments(&color_ref)
                    .depth_stencil_attachment(&depth_ref)];
                if format.resolve {
                    subpasses[0] = subpasses[0].resolve_attachments(&third_ref);
                }
                let dependencies = [subpass_dependency(view_mask)];
                if format.subpass_color.is_some() {
                    subpasses.push(
                        vk::SubpassDescription::default()
                            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                            .input_attachments(&input_ref)
                            .color_attachments(&third_ref),
                    );
                }
                let masks = vec![view_mask; subpasses.len()];
                let correlation = [view_mask];
                let mut multiview = vk::RenderPassMultiviewCreateInfo::default()
                    .view_masks(&masks)
                    .correlation_masks(&correlation);
                let mut info = vk::RenderPassCreateInfo::default().attachments(&attachments).subpasses(&subpasses);
                if subpasses.len() > 1 {
                    info = info.dependencies(&dependencies);
                }
                if format.view_mask.is_some() {
                    info = info.push_next(&mut multiview);
                }
                // SAFETY: valid create info.
                p.render_pass = unsafe { gpu.device.create_render_pass(&info, None) }.ctx("vkCreateRenderPass")?;
            }
            Rendering::RenderPass2 => {
                let mut attachments = vec![
                    vk::AttachmentDescription2::default()
                        .format(format.color)
                        .samples(format.samples)
                        .load_op(vk::AttachmentLoadOp::CLEAR)
                        .store_op(color_store)
                        .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                        .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                        .initial_layout(COLOR_LAYOUT)
                        .final_layout(color_final),
                    vk::AttachmentDescription2::default()
                        .format(format.depth)
                        .samples(format.samples)
                        .load_op(depth_load)
                        .store_op(depth_store)
                        .stencil_load_op(depth_load)
                        .stencil_store_op(depth_store)
                        .initial_layout(DEPTH_LAYOUT)
                        .final_layout(DEPTH_LAYOUT),
                ];
                if let Some((f, load)) = third {
                    attachments.push(
                        vk::AttachmentDescription2::default()
                            .format(f)
                            .samples(vk::SampleCountFlags::TYPE_1)
                            .load_op(load)
                            .store_op(vk::AttachmentStoreOp::STORE)
                            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                            .initial_layout(COLOR_LAYOUT)
                            .final_layout(COLOR_LAYOUT),
                    );
                }
                let color_ref = [vk::AttachmentReference2::default()
                    .attachment(0)
                    .layout(COLOR_LAYOUT)
                    .aspect_mask(vk::ImageAspectFlags::COLOR)];
                let depth_ref = vk::AttachmentReference2::default()
                    .attachment(1)
                    .layout(DEPTH_LAYOUT)
                    .aspect_mask(crate::targets::depth_aspect(format.depth));
                let third_ref = [vk::AttachmentReference2::default().attachment(2).layout(COLOR_LAYOUT).aspect_mask(vk::ImageAspectFlags::COLOR)];
                let input_ref = [vk::AttachmentReference2::default()
                    .attachment(0)
                    .layout(SUBPASS_INPUT_LAYOUT)
                    .aspect_mask(vk::ImageAspectFlags::COLOR)];
                let mut subpasses = vec![vk::SubpassDescription2::default()
                    .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                    .view_mask(view_mask)
                    .color_attachments(&color_ref)
                    .depth_stencil_attachment(&depth_ref)];
                if format.resolve {
                    subpasses[0] = subpasses[0].resolve_attachments(&third_ref);
                }
                if format.subpass_color.is_some() {
                    subpasses.push(
                        vk::SubpassDescription2::default()
                            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                            .view_mask(view_mask)
                            .input_attachments(&input_ref)
                            .color_attachments(&third_ref),
                    );
                }
                let d = subpass_dependency(view_mask);
                let dependencies = [vk::SubpassDependency2::default()
                    .src_subpass(d.src_subpass)
                    .dst_subpass(d.dst_subpass)
                    .src_stage_mask(d.src_stage_mask)
                    .dst_stage_mask(d.dst_stage_mask)
                    .src_access_mask(d.src_access_mask)
                    .dst_access_mask(d.dst_access_mask)
                    .dependency_flags(d.dependency_flags)];
                let correlated = [view_mask];
                let mut info = vk::RenderPassCreateInfo2::default().attachments(&attachments).subpasses(&subpasses);
                if subpasses.len() > 1 {
                    info = info.dependencies(&dependencies);
                }
                if format.view_mask.is_some() {
                    info = info.correlated_view_masks(&correlated);
                }
                // SAFETY: valid create info; the 2-variant entry point matches the device version.
                p.render_pass = unsafe {
                    match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                        RenderPass2::Core => gpu.device.create_render_pass2(&info, None),
                        RenderPass2::Khr(k) => k.create_render_pass2(&info, None),
                    }
                }
                .ctx("vkCreateRenderPass2")?;
            }
            Rendering::Dynamic => {}
        }
        Ok(p)
    }

    /// The framebuffer of a pass on `views` (colour, depth, and the resolve or subpass-1
    /// attachment or null; made the first time; render pass objects), or null (dynamic
    /// rendering, which has none).
    pub fn framebuffer(&mut self, views: [vk::ImageView; 3], extent: vk::Extent2D) -> Result<vk::Framebuffer> {
        if self.mode == Rendering::Dynamic {
            return Ok(vk::Framebuffer::null());
        }
        if let Some(fb) = self.framebuffers.get(&views) {
            return Ok(*fb);
        }
        let count = if views[2] == vk::ImageView::null() { 2 } else { 3 };
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(self.render_pass)
            .attachments(&views[..count])
            .width(extent.width)
            .height(extent.height)
            .layers(1);
        // SAFETY: views of live images compatible with the render pass.
        let fb = unsafe { self.device.create_framebuffer(&info, None) }.ctx("vkCreateFramebuffer")?;
        self.framebuffers.insert(views, fb);
        Ok(fb)
    }

    /// `--secondary`: begins `secondary` (a secondary command buffer) for the contents of the pass
    /// that `begin` will open on `framebuffer`'s attachments ([`Passes::framebuffer`]; null with
    /// dynamic rendering): it continues that render pass instance, inheriting render pass,
    /// subpass 0 and framebuffer (render pass objects) or the attachment formats, view mask and
    /// sample count (dynamic rendering). `usage`: the primary's usage flags (ONE_TIME_SUBMIT or
    /// not), to which RENDER_PASS_CONTINUE is added. Takes `&self` so that worker threads can
    /// begin secondaries at once (`--threads`).
    pub fn begin_secondary(&self, gpu: &Gpu, secondary: vk::CommandBuffer, framebuffer: vk::Framebuffer, usage: vk::CommandBufferUsageFlags) -> Result<()> {
        let color_formats = [self.format.color];
        let mut rendering = vk::CommandBufferInheritanceRenderingInfo::default()
            .view_mask(self.format.view_mask.unwrap_or(0))
            .color_attachment_formats(&color_formats)
            .depth_attachment_format(self.format.depth)
            .stencil_attachment_format(if self.format.has_stencil { self.format.depth } else { vk::Format::UNDEFINED })
            .rasterization_samples(self.format.samples);
        let mut inheritance = vk::CommandBufferInheritanceInfo::default();
        match self.mode {
            Rendering::RenderPass | Rendering::RenderPass2 => {
                inheritance = inheritance.render_pass(self.render_pass).subpass(0).framebuffer(framebuffer);
            }
            Rendering::Dynamic => inheritance = inheritance.push_next(&mut rendering),
        }
        let info = vk::CommandBufferBeginInfo::default()
            .flags(usage | vk::CommandBufferUsageFlags::RENDER_PASS_CONTINUE)
            .inheritance_info(&inheritance);
        // SAFETY: the buffer is a secondary of a pool with RESET_COMMAND_BUFFER, not pending (the
        // submission of the primary that executed it was waited on); the inheritance matches the
        // pass `begin` opens.
        unsafe { gpu.device.begin_command_buffer(secondary, &info) }.ctx("vkBeginCommandBuffer(secondary)")
    }

    /// Opens the pass on `color`/`depth`: colour cleared, depth cleared by the load op (or loaded,
    /// with `load_depth`). With `secondary` its contents are secondary command buffers (render
    /// pass: `VK_SUBPASS_CONTENTS_SECONDARY_COMMAND_BUFFERS`; dynamic rendering:
    /// `VK_RENDERING_CONTENTS_SECONDARY_COMMAND_BUFFERS_BIT`).
    pub fn begin(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, target: &crate::renderer::PassTarget, clear_depth: f32, secondary: bool) -> Result<()> {
        let (color, depth, extent) = (target.color_view, target.depth_view, target.extent);
        let contents = if secondary { vk::SubpassContents::SECONDARY_COMMAND_BUFFERS } else { vk::SubpassContents::INLINE };
        let area = vk::Rect2D { offset: vk::Offset2D::default(), extent };
        let clears = [
            vk::ClearValue { color: vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] } },
            vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: clear_depth, stencil: 0 } },
            vk::ClearValue { color: vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] } },
        ];
        match self.mode {
            Rendering::RenderPass | Rendering::RenderPass2 => {
                let fb = self.framebuffer(target.attachments(), extent)?;
                let info = vk::RenderPassBeginInfo::default()
                    .render_pass(self.render_pass)
                    .framebuffer(fb)
                    .render_area(area)
                    .clear_values(&clears);
                // SAFETY: recording state; the images are in the layouts the pass expects.
                unsafe {
                    if self.mode == Rendering::RenderPass {
                        gpu.device.cmd_begin_render_pass(cmd, &info, contents);
                    } else {
                        let sb = vk::SubpassBeginInfo::default().contents(contents);
                        match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                            RenderPass2::Core => gpu.device.cmd_begin_render_pass2(cmd, &info, &sb),
                            RenderPass2::Khr(k) => k.cmd_begin_render_pass2(cmd, &info, &sb),
                        }
                    }
                }
            }
            Rendering::Dynamic => {
                let mut color_att = [vk::RenderingAttachmentInfo::default()
                    .image_view(color)
                    .image_layout(COLOR_LAYOUT)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::STORE)
                    .clear_value(clears[0])];
                if let Some(resolve) = target.resolve_view {
                    // Averaged into the single-sampled target at the end of the pass; the
                    // multisampled colour itself is not kept.
                    color_att[0] = color_att[0]
                        .store_op(vk::AttachmentStoreOp::DONT_CARE)
                        .resolve_mode(vk::ResolveModeFlags::AVERAGE)
                        .resolve_image_view(resolve)
                        .resolve_image_layout(COLOR_LAYOUT);
                }
                let depth_att = vk::RenderingAttachmentInfo::default()
                    .image_view(depth)
                    .image_layout(DEPTH_LAYOUT)
                    .load_op(if self.format.load_depth { vk::AttachmentLoadOp::LOAD } else { vk::AttachmentLoadOp::CLEAR })
                    .store_op(if self.format.store_depth {
                        vk::AttachmentStoreOp::STORE
                    } else {
                        vk::AttachmentStoreOp::DONT_CARE
                    })
                    .clear_value(clears[1]);
                let flags = if secondary { vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS } else { vk::RenderingFlags::empty() };
                let info = vk::RenderingInfo::default()
                    .flags(flags)
                    .render_area(area)
                    .layer_count(1)
                    .view_mask(self.format.view_mask.unwrap_or(0))
                    .color_attachments(&color_att)
                    .depth_attachment(&depth_att);
                let info = if self.format.has_stencil { info.stencil_attachment(&depth_att) } else { info };
                // SAFETY: recording state; images were transitioned by explicit barriers.
                unsafe {
                    match gpu.dynamic_rendering.as_ref().expect("dynamic rendering loader") {
                        DynamicRendering::Core => gpu.device.cmd_begin_rendering(cmd, &info),
                        DynamicRendering::Khr(k) => k.cmd_begin_rendering(cmd, &info),
                    }
                }
            }
        }
        Ok(())
    }

    /// `--depth-clear attachments`: clears the depth (and stencil) attachment of the open pass with
    /// `vkCmdClearAttachments` over the whole render area (`extent` from the origin: for
    /// side-by-side one rect covering both eyes). Multiview: layer 0, count 1 clears every view.
    pub fn clear_depth_attachment(&self, gpu: &Gpu, cmd: vk::CommandBuffer, extent: vk::Extent2D, clear_depth: f32) {
        let aspect = if self.format.has_stencil {
            vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
        } else {
            vk::ImageAspectFlags::DEPTH
        };
        let attachment = [vk::ClearAttachment {
            aspect_mask: aspect,
            color_attachment: 0,
            clear_value: vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: clear_depth, stencil: 0 } },
        }];
        let rect = [vk::ClearRect {
            rect: vk::Rect2D { offset: vk::Offset2D::default(), extent },
            base_array_layer: 0,
            layer_count: 1,
        }];
        // SAFETY: a pass with a depth attachment is open on `cmd`; the rect lies in its render area.
        unsafe { gpu.device.cmd_clear_attachments(cmd, &attachment, &rect) };
    }

    /// `--post-subpass`: from the scene's subpass to the tonemap's, whose commands are recorded
    /// inline (also when the scene's were in a secondary command buffer).
    pub fn next_subpass(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        // SAFETY: a render pass with two subpasses is open on `cmd`, in its first subpass.
        unsafe {
            match self.mode {
                Rendering::RenderPass => gpu.device.cmd_next_subpass(cmd, vk::SubpassContents::INLINE),
                Rendering::RenderPass2 => {
                    let begin = vk::SubpassBeginInfo::default().contents(vk::SubpassContents::INLINE);
                    let end = vk::SubpassEndInfo::default();
                    match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                        RenderPass2::Core => gpu.device.cmd_next_subpass2(cmd, &begin, &end),
                        RenderPass2::Khr(k) => k.cmd_next_subpass2(cmd, &begin, &end),
                    }
                }
                Rendering::Dynamic => unreachable!("--post-subpass is refused with dynamic rendering"),
            }
        }
    }

    pub fn end(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        // SAFETY: a pass of the same kind is open on `cmd`.
        unsafe {
            match self.mode {
                Rendering::RenderPass => gpu.device.cmd_end_render_pass(cmd),
                Rendering::RenderPass2 => {
                    let info = vk::SubpassEndInfo::default();
                    match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                        RenderPass2::Core => gpu.device.cmd_end_render_pass2(cmd, &info),
                        RenderPass2::Khr(k) => k.cmd_end_render_pass2(cmd, &info),
                    }
                }
                Rendering::Dynamic => match gpu.dynamic_rendering.as_ref().expect("dynamic rendering loader") {
                    DynamicRendering::Core => gpu.device.cmd_end_rendering(cmd),
                    DynamicRendering::Khr(k) => k.cmd_end_rendering(cmd),
                },
            }
        }
    }

    /// Builds the scene pipeline for this pass shape.
    pub fn create_pipeline(
        &self,
        layout: vk::PipelineLayout,
        vert: vk::ShaderModule,
        frag: vk::ShaderModule,
        depth_compare: vk::CompareOp,
        kind: PipelineKind,
    ) -> Result<vk::Pipeline> {
        let stages = [
            vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(vert).name(c"main"),
            vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"),
        ];
        let bindings = [vk::VertexInputBindingDescription {
            binding: 0,
            stride: std::mem::size_of::<crate::scene::Vertex>() as u32,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attr = |location, format, offset| vk::VertexInputAttributeDescription { location, binding: 0, format, offset };
        let attributes = [
            attr(0, vk::Format::R32G32B32_SFLOAT, 0),
            attr(1, vk::Format::R32G32B32_SFLOAT, 12),
            attr(2, vk::Format::R32G32B32_SFLOAT, 24),
            attr(3, vk::Format::R32_UINT, 36),
        ];
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(&bindings)
            .vertex_attribute_descriptions(&attributes);
        let input_assembly =
            vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
        // No culling: the sky is seen from inside and correctness of winding is not the point here.
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(vk::CullModeFlags::NONE)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(self.format.samples);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(kind != PipelineKind::Sky)
            .depth_write_enable(kind == PipelineKind::Opaque)
            .depth_compare_op(depth_compare);
        let mut blend_att = vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA);
        if kind == PipelineKind::Translucent {
            // The vertex format has no alpha: the pane's opacity is the blend constant's.
            blend_att = blend_att
                .blend_enable(true)
                .src_color_blend_factor(vk::BlendFactor::CONSTANT_ALPHA)
                .dst_color_blend_factor(vk::BlendFactor::ONE_MINUS_CONSTANT_ALPHA)
                .color_blend_op(vk::BlendOp::ADD)
                .src_alpha_blend_factor(vk::BlendFactor::ZERO)
                .dst_alpha_blend_factor(vk::BlendFactor::ONE)
                .alpha_blend_op(vk::BlendOp::ADD);
        }
        let blend_atts = [blend_att];
        let blend = vk::PipelineColorBlendStateCreateInfo::default()
            .attachments(&blend_atts)
            .blend_constants([0.0, 0.0, 0.0, crate::scene::PANE_ALPHA]);
        let dynamic_states: &[vk::DynamicState] = if self.style.dynamic { &DYNAMIC_STATES } else { &DYNAMIC_STATES[..2] };
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(dynamic_states);
        let color_formats = [self.format.color];
        let rendering_info = || {
            vk::PipelineRenderingCreateInfo::default()
                .view_mask(self.format.view_mask.unwrap_or(0))
                .color_attachment_formats(&color_formats)
                .depth_attachment_format(self.format.depth)
                .stencil_attachment_format(if self.format.has_stencil { self.format.depth } else { vk::Format::UNDEFINED })
        };
        let whole = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&input_assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(layout);
        if self.style.library {
            return self.link_libraries(whole, rendering_info);
        }
        let mut rendering = rendering_info();
        let mut info = whole;
        if self.mode == Rendering::Dynamic {
            info = info.push_next(&mut rendering);
        } else {
            info = info.render_pass(self.render_pass).subpass(0);
        }
        // SAFETY: valid create info; all referenced objects are alive.
        let pipelines = unsafe { self.device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }
            .map_err(|(_, e)| e)
            .ctx("vkCreateGraphicsPipelines")?;
        Ok(pipelines[0])
    }
}

impl Passes {
    /// `--pipeline-library`: `whole`'s state split into the four libraries of graphics pipeline
    /// libraries (vertex input, pre-rasterization, fragment shader, fragment output), each made
    /// on its own, then linked (the libraries live as long as the passes).
    fn link_libraries<'a>(&self, whole: vk::GraphicsPipelineCreateInfo<'a>, rendering: impl Fn() -> vk::PipelineRenderingCreateInfo<'a>) -> Result<vk::Pipeline> {
        use vk::GraphicsPipelineLibraryFlagsEXT as P;
        let stages = whole.p_stages;
        let parts = [P::VERTEX_INPUT_INTERFACE, P::PRE_RASTERIZATION_SHADERS, P::FRAGMENT_SHADER, P::FRAGMENT_OUTPUT_INTERFACE];
        let mut libraries = Vec::new();
        let mut made = Ok(());
        for part in parts {
            let mut library = vk::GraphicsPipelineLibraryCreateInfoEXT::default().flags(part);
            let mut r = rendering();
            // Each library gets the whole create info's pointers: a subset reads its own and
            // ignores the others (the spec's rule); the stages only where they belong.
            let mut info = whole;
            info.p_next = std::ptr::null();
            info.flags = vk::PipelineCreateFlags::LIBRARY_KHR;
            info.stage_count = 0;
            info.p_stages = std::ptr::null();
            if part == P::PRE_RASTERIZATION_SHADERS || part == P::FRAGMENT_SHADER {
                info.stage_count = 1;
                // SAFETY: `whole` has two stages: vertex, then fragment.
                info.p_stages = if part == P::PRE_RASTERIZATION_SHADERS { stages } else { unsafe { stages.add(1) } };
            }
            info = info.push_next(&mut library);
            if self.mode == Rendering::Dynamic {
                info = info.push_next(&mut r);
            } else if part != P::VERTEX_INPUT_INTERFACE {
                info = info.render_pass(self.render_pass).subpass(0);
            }
            // SAFETY: valid create info; all referenced objects are alive.
            match unsafe { self.device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) } {
                Ok(p) => libraries.push(p[0]),
                Err((_, e)) => {
                    made = Err(e);
                    break;
                }
            }
        }
        let linked = made.and_then(|()| {
            let mut link = vk::PipelineLibraryCreateInfoKHR::default().libraries(&libraries);
            // A fast link, as DXVK makes first (no link-time optimisation).
            let info = vk::GraphicsPipelineCreateInfo::default().layout(whole.layout).push_next(&mut link);
            // SAFETY: valid libraries of compatible state and layout.
            unsafe { self.device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }.map(|p| p[0]).map_err(|(_, e)| e)
        });
        self.libraries.lock().unwrap_or_else(|e| e.into_inner()).extend(libraries);
        linked.ctx("vkCreateGraphicsPipelines(--pipeline-library)")
    }
}

/// `--post-subpass`: subpass 1 reads what subpass 0 wrote at the same pixel (and view).
fn subpass_dependency(view_mask: u32) -> vk::SubpassDependency {
    let mut flags = vk::DependencyFlags::BY_REGION;
    if view_mask != 0 {
        flags |= vk::DependencyFlags::VIEW_LOCAL;
    }
    vk::SubpassDependency {
        src_subpass: 0,
        dst_subpass: 1,
        src_stage_mask: vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
        dst_stage_mask: vk::PipelineStageFlags::FRAGMENT_SHADER,
        src_access_mask: vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
        dst_access_mask: vk::AccessFlags::INPUT_ATTACHMENT_READ,
        dependency_flags: flags,
    }
}

/// The scene's pipelines differ only in depth and blend state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PipelineKind {
    /// Depth test and write on, no blending: everything of the default scene.
    Opaque,
    /// `--sky-first`: depth test and write off, as engines draw a skybox before the scene.
    Sky,
    /// `--translucent`: depth test on, write off, blended with the blend constant's alpha.
    Translucent,
}

impl Drop for Passes {
    fn drop(&mut self) {
        // SAFETY: the owner waited for the device to go idle; these objects are ours.
        unsafe {
            for fb in self.framebuffers.values() {
                self.device.destroy_framebuffer(*fb, None);
            }
            if self.render_pass != vk::RenderPass::null() {
                self.device.destroy_render_pass(self.render_pass, None);
            }
            // The pipelines linked from them were destroyed by the renderer first.
            for l in self.libraries.get_mut().unwrap_or_else(|e| e.into_inner()).drain(..) {
                self.device.destroy_pipeline(l, None);
            }
        }
    }
}
