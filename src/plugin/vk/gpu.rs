//! The GPU helpers every feature's own work is recorded with: the memory barriers and subresource
//! ranges of the layer's transfers, compute dispatches and draws. One builder each, so every
//! barrier the layer records says the same things the same way (no queue family transfer: the
//! layer's work runs on the queue of the app's work it follows).

use ash::vk;

/// The colour aspect of `layers` array layers from `base_layer`, `mips` mip levels from 0.
pub(crate) fn color_range(base_layer: u32, layers: u32, mips: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: mips, base_array_layer: base_layer, layer_count: layers }
}

/// A layout transition of `range` of `image` from `old` to `new`, making `src` accesses before it
/// visible to `dst` accesses after it.
pub(crate) fn image_barrier(image: vk::Image, range: vk::ImageSubresourceRange, (old, new): (vk::ImageLayout, vk::ImageLayout), (src, dst): (vk::AccessFlags, vk::AccessFlags)) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .src_access_mask(src)
        .dst_access_mask(dst)
        .old_layout(old)
        .new_layout(new)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(range)
}

/// A barrier on the whole of `buffer` between `src` and `dst` accesses.
pub(crate) fn buffer_barrier(buffer: vk::Buffer, src: vk::AccessFlags, dst: vk::AccessFlags) -> vk::BufferMemoryBarrier<'static> {
    vk::BufferMemoryBarrier::default().src_access_mask(src).dst_access_mask(dst).src_queue_family_index(vk::QUEUE_FAMILY_IGNORED).dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED).buffer(buffer).offset(0).size(vk::WHOLE_SIZE)
}

/// Where a pipeline of the layer's draws: a subpass of a render pass object, or dynamic rendering
/// with these attachment formats (and, when the pass may carry variable-rate shading's attachment,
/// the flag every pipeline bound in it must have).
pub(crate) enum Target<'a> {
    Subpass(vk::RenderPass, u32),
    Rendering { info: vk::PipelineRenderingCreateInfo<'a>, fsr_attachment: bool },
}

/// What differs between the layer's graphics pipelines (the injected depth and checkerboard
/// draws, RDM's fill, the upscale's fragment pass). Everything else they share: triangle lists,
/// no culling, one viewport and scissor set dynamically, and no fragment shading rate state (its
/// defaults, 1×1 with KEEP combiners, ignore a rate attachment, so the layer's draws are
/// pixel-exact also in passes that carry one).
pub(crate) struct Draw<'a> {
    pub vert: vk::ShaderModule,
    pub frag: Option<vk::ShaderModule>,
    /// Vertex buffer bindings and attributes (empty: vertices from the shader or push constants).
    pub bindings: &'a [vk::VertexInputBindingDescription],
    pub attributes: &'a [vk::VertexInputAttributeDescription],
    pub samples: vk::SampleCountFlags,
    /// Depth test and write with this compare op; None: no depth state.
    pub depth_compare: Option<vk::CompareOp>,
    /// Per colour attachment, what the draw writes.
    pub color_writes: &'a [vk::ColorComponentFlags],
    pub layout: vk::PipelineLayout,
    pub target: Target<'a>,
}

/// Creates `draw`'s pipeline on `device`.
///
/// # Safety
/// Every object `draw` names is a live object of `device` (a render pass may be the app's, in use
/// by the pass being recorded).
pub(crate) unsafe fn graphics_pipeline(device: &ash::Device, draw: Draw<'_>) -> Result<vk::Pipeline, vk::Result> {
    let mut stages = vec![vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(draw.vert).name(c"main")];
    if let Some(frag) = draw.frag {
        stages.push(vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(frag).name(c"main"));
    }
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default().vertex_binding_descriptions(draw.bindings).vertex_attribute_descriptions(draw.attributes);
    let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(draw.samples);
    let depth = draw.depth_compare.map(|op| vk::PipelineDepthStencilStateCreateInfo::default().depth_test_enable(true).depth_write_enable(true).depth_compare_op(op));
    let blend_atts: Vec<vk::PipelineColorBlendAttachmentState> = draw.color_writes.iter().map(|m| vk::PipelineColorBlendAttachmentState::default().color_write_mask(*m)).collect();
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_atts);
    let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let mut info = vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&input_assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .color_blend_state(&blend)
        .dynamic_state(&dynamic)
        .layout(draw.layout);
    if let Some(depth) = &depth {
        info = info.depth_stencil_state(depth);
    }
    let mut rendering;
    match draw.target {
        Target::Subpass(render_pass, subpass) => info = info.render_pass(render_pass).subpass(subpass),
        Target::Rendering { info: r, fsr_attachment } => {
            rendering = r;
            info = info.push_next(&mut rendering);
            if fsr_attachment {
                info = info.flags(vk::PipelineCreateFlags::RENDERING_FRAGMENT_SHADING_RATE_ATTACHMENT_KHR);
            }
        }
    }
    // SAFETY: a valid create info whose objects are live (the caller's contract).
    unsafe { device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }.map(|p| p[0]).map_err(|(_, e)| e)
}
