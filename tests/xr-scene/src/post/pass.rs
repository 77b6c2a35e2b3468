//! The post chain's own passes: one colour attachment (and, for `--post-depth-attachment`'s
//! tonemap pass, a depth attachment that no draw tests), in the app's `--rendering` shape (render
//! pass, render pass 2, dynamic rendering), multiview where the eye pass is; and the full-screen
//! pipelines drawn in them (one triangle, no vertex buffer, no depth test).

use crate::cli::Rendering;
use crate::error::{Ctx, Result};
use crate::gpu::{DynamicRendering, Gpu, RenderPass2};
use ash::vk;
use std::collections::HashMap;

const COLOR_LAYOUT: vk::ImageLayout = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
const DEPTH_LAYOUT: vk::ImageLayout = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL;

/// A single-subpass colour pass; its images arrive in attachment layout (barriers outside).
pub struct ColorPass {
    device: ash::Device,
    mode: Rendering,
    color: vk::Format,
    /// `--post-depth-attachment`: the depth format (cleared to `clear_depth`, not stored).
    depth: Option<vk::Format>,
    clear_depth: f32,
    view_mask: u32,
    /// Null for dynamic rendering.
    render_pass: vk::RenderPass,
    framebuffers: HashMap<(vk::ImageView, vk::ImageView), vk::Framebuffer>,
}

impl ColorPass {
    pub fn new(gpu: &Gpu, mode: Rendering, color: vk::Format, depth: Option<vk::Format>, clear_depth: f32, view_mask: u32) -> Result<ColorPass> {
        let mut p = ColorPass { device: gpu.device.clone(), mode, color, depth, clear_depth, view_mask, render_pass: vk::RenderPass::null(), framebuffers: HashMap::new() };
        let depth_aspect = depth.map(crate::targets::depth_aspect).unwrap_or(vk::ImageAspectFlags::DEPTH);
        match mode {
            Rendering::Dynamic => {}
            Rendering::RenderPass | Rendering::RenderPass2 => {
                // Render pass 2 describes everything the classic one does; the classic one is made
                // from the same description, so both paths stay one shape.
                let mut attachments = vec![vk::AttachmentDescription2::default()
                    .format(color)
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::STORE)
                    .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                    .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                    .initial_layout(COLOR_LAYOUT)
                    .final_layout(COLOR_LAYOUT)];
                if let Some(f) = depth {
                    attachments.push(
                        vk::AttachmentDescription2::default()
                            .format(f)
                            .samples(vk::SampleCountFlags::TYPE_1)
                            .load_op(vk::AttachmentLoadOp::CLEAR)
                            .store_op(vk::AttachmentStoreOp::DONT_CARE)
                            .stencil_load_op(vk::AttachmentLoadOp::CLEAR)
                            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                            .initial_layout(DEPTH_LAYOUT)
                            .final_layout(DEPTH_LAYOUT),
                    );
                }
                // SAFETY: valid create infos on a live device.
                p.render_pass = unsafe {
                    if mode == Rendering::RenderPass {
                        let a1: Vec<vk::AttachmentDescription> = attachments
                            .iter()
                            .map(|a| vk::AttachmentDescription {
                                flags: a.flags,
                                format: a.format,
                                samples: a.samples,
                                load_op: a.load_op,
                                store_op: a.store_op,
                                stencil_load_op: a.stencil_load_op,
                                stencil_store_op: a.stencil_store_op,
                                initial_layout: a.initial_layout,
                                final_layout: a.final_layout,
                            })
                            .collect();
                        let color_ref = [vk::AttachmentReference { attachment: 0, layout: COLOR_LAYOUT }];
                        let depth_ref = vk::AttachmentReference { attachment: 1, layout: DEPTH_LAYOUT };
                        let mut subpass = vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS).color_attachments(&color_ref);
                        if depth.is_some() {
                            subpass = subpass.depth_stencil_attachment(&depth_ref);
                        }
                        let subpasses = [subpass];
                        let masks = [view_mask];
                        let mut multiview = vk::RenderPassMultiviewCreateInfo::default().view_masks(&masks).correlation_masks(&masks);
                        let mut info = vk::RenderPassCreateInfo::default().attachments(&a1).subpasses(&subpasses);
                        if view_mask != 0 {
                            info = info.push_next(&mut multiview);
                        }
                        gpu.device.create_render_pass(&info, None).ctx("vkCreateRenderPass(post)")?
                    } else {
                        let color_ref = [vk::AttachmentReference2::default().attachment(0).layout(COLOR_LAYOUT).aspect_mask(vk::ImageAspectFlags::COLOR)];
                        let depth_ref = vk::AttachmentReference2::default().attachment(1).layout(DEPTH_LAYOUT).aspect_mask(depth_aspect);
                        let mut subpass = vk::SubpassDescription2::default()
                            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
                            .view_mask(view_mask)
                            .color_attachments(&color_ref);
                        if depth.is_some() {
                            subpass = subpass.depth_stencil_attachment(&depth_ref);
                        }
                        let subpasses = [subpass];
                        let correlated = [view_mask];
                        let mut info = vk::RenderPassCreateInfo2::default().attachments(&attachments).subpasses(&subpasses);
                        if view_mask != 0 {
                            info = info.correlated_view_masks(&correlated);
                        }
                        match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                            RenderPass2::Core => gpu.device.create_render_pass2(&info, None),
                            RenderPass2::Khr(k) => k.create_render_pass2(&info, None),
                        }
                        .ctx("vkCreateRenderPass2(post)")?
                    }
                };
            }
        }
        Ok(p)
    }

    fn framebuffer(&mut self, color: vk::ImageView, depth: vk::ImageView, extent: vk::Extent2D) -> Result<vk::Framebuffer> {
        if let Some(fb) = self.framebuffers.get(&(color, depth)) {
            return Ok(*fb);
        }
        let views = [color, depth];
        let count = if self.depth.is_some() { 2 } else { 1 };
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(self.render_pass)
            .attachments(&views[..count])
            .width(extent.width)
            .height(extent.height)
            .layers(1);
        // SAFETY: views of live images compatible with the render pass.
        let fb = unsafe { self.device.create_framebuffer(&info, None) }.ctx("vkCreateFramebuffer(post)")?;
        self.framebuffers.insert((color, depth), fb);
        Ok(fb)
    }

    /// Opens the pass on `color` (cleared to black) and, with a depth format, `depth` (cleared to
    /// the app's depth convention's far value, never tested) over all of `extent`.
    pub fn begin(&mut self, gpu: &Gpu, cmd: vk::CommandBuffer, color: vk::ImageView, depth: vk::ImageView, extent: vk::Extent2D) -> Result<()> {
        let area = vk::Rect2D { offset: vk::Offset2D::default(), extent };
        let clears = [
            vk::ClearValue { color: vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] } },
            vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: self.clear_depth, stencil: 0 } },
        ];
        match self.mode {
            Rendering::RenderPass | Rendering::RenderPass2 => {
                let fb = self.framebuffer(color, depth, extent)?;
                let n = if self.depth.is_some() { 2 } else { 1 };
                let info = vk::RenderPassBeginInfo::default().render_pass(self.render_pass).framebuffer(fb).render_area(area).clear_values(&clears[..n]);
                // SAFETY: recording, outside any pass; the images are in the layouts the pass expects.
                unsafe {
                    if self.mode == Rendering::RenderPass {
                        gpu.device.cmd_begin_render_pass(cmd, &info, vk::SubpassContents::INLINE);
                    } else {
                        let sb = vk::SubpassBeginInfo::default().contents(vk::SubpassContents::INLINE);
                        match gpu.render_pass2.as_ref().expect("render-pass2 loader") {
                            RenderPass2::Core => gpu.device.cmd_begin_render_pass2(cmd, &info, &sb),
                            RenderPass2::Khr(k) => k.cmd_begin_render_pass2(cmd, &info, &sb),
                        }
                    }
                }
            }
            Rendering::Dynamic => {
                let color_att = [vk::RenderingAttachmentInfo::default()
                    .image_view(color)
                    .image_layout(COLOR_LAYOUT)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::STORE)
                    .clear_value(clears[0])];
                let depth_att = vk::RenderingAttachmentInfo::default()
                    .image_view(depth)
                    .image_layout(DEPTH_LAYOUT)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::DONT_CARE)
                    .clear_value(clears[1]);
                let mut info = vk::RenderingInfo::default().render_area(area).layer_count(1).view_mask(self.view_mask).color_attachments(&color_att);
                if self.depth.is_some() {
                    info = info.depth_attachment(&depth_att);
                }
                // SAFETY: recording, outside any pass; the images were put in attachment layout.
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

    pub fn end(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        // SAFETY: this pass is open on `cmd`.
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

    /// The full-screen pipeline for this pass.
    pub fn pipeline(&self, layout: vk::PipelineLayout, vert: vk::ShaderModule, frag: vk::ShaderModule) -> Result<vk::Pipeline> {
        let target = PipelineTarget {
            render_pass: self.render_pass,
            subpass: 0,
            color: self.color,
            depth: self.depth,
            view_mask: self.view_mask,
        };
        fullscreen_pipeline(&self.device, layout, vert, frag, &target)
    }
}

impl Drop for ColorPass {
    fn drop(&mut self) {
        // SAFETY: the owner waited for the device to go idle; these objects are ours.
        unsafe {
            for fb in self.framebuffers.values() {
                self.device.destroy_framebuffer(*fb, None);
            }
            self.device.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// Where a full-screen pipeline draws: a render pass's subpass, or (null render pass) dynamic
/// rendering with these formats and view mask.
pub struct PipelineTarget {
    pub render_pass: vk::RenderPass,
    pub subpass: u32,
    pub color: vk::Format,
    pub depth: Option<vk::Format>,
    pub view_mask: u32,
}

/// One triangle over the viewport: no vertex input, no culling, no depth test or write (a depth
/// attachment, if the pass has one, is left as cleared), no blending.
pub fn fullscreen_pipeline(d: &ash::Device, layout: vk::PipelineLayout, vert: vk::ShaderModule, frag: vk::ShaderModule, target: &PipelineTarget) -> Result<vk::Pipeline> {
    let stages = [
        vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(vert).name(c"main"),
        vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"),
    ];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
    let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let depth = vk::PipelineDepthStencilStateCreateInfo::default().depth_test_enable(false).depth_write_enable(false);
    let blend_atts = [vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA)];
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_atts);
    let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let color_formats = [target.color];
    let mut rendering = vk::PipelineRenderingCreateInfo::default()
        .view_mask(target.view_mask)
        .color_attachment_formats(&color_formats)
        .depth_attachment_format(target.depth.unwrap_or(vk::Format::UNDEFINED));
    let mut info = vk::GraphicsPipelineCreateInfo::default()
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
    if target.render_pass == vk::RenderPass::null() {
        info = info.push_next(&mut rendering);
    } else {
        info = info.render_pass(target.render_pass).subpass(target.subpass);
    }
    // SAFETY: valid create info; all referenced objects are alive.
    let pipelines = unsafe { d.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }
        .map_err(|(_, e)| e)
        .ctx("vkCreateGraphicsPipelines(post)")?;
    Ok(pipelines[0])
}
