//! Reads the app's create infos and begin infos (raw pointers, `pNext` chains) into the owned,
//! safe descriptions of `crate::track`, while the call that passed them is still running. Every
//! function here requires that the pointers it is given are valid as the Vulkan spec demands of
//! the app for the call in progress.

use crate::track::cmd::{ClearValue, Rect, RenderingAttachment, StateCmd, Viewport};
use crate::track::resources::*;
use crate::track::DeviceTracker;
use ash::vk::{self, Handle};
use std::ffi::c_void;

/// A slice from an array pointer and count; empty for null or zero.
///
/// # Safety
/// `p` must point to `n` valid `T`s when non-null.
pub unsafe fn slice<'a, T>(p: *const T, n: u32) -> &'a [T] {
    if p.is_null() || n == 0 {
        &[]
    } else {
        // SAFETY: per the contract.
        unsafe { std::slice::from_raw_parts(p, n as usize) }
    }
}

/// The first struct of type `s_type` in a `pNext` chain.
///
/// # Safety
/// `p_next` must be a valid Vulkan structure chain, and `T` the struct that `s_type` denotes.
pub unsafe fn find_in_chain<T>(mut p_next: *const c_void, s_type: vk::StructureType) -> Option<*const T> {
    while !p_next.is_null() {
        let base = p_next as *const vk::BaseInStructure<'_>;
        // SAFETY: every structure in a valid chain starts with sType and pNext.
        let (ty, next) = unsafe { ((*base).s_type, (*base).p_next) };
        if ty == s_type {
            return Some(p_next as *const T);
        }
        p_next = next as *const c_void;
    }
    None
}

pub fn viewport(v: &vk::Viewport) -> Viewport {
    Viewport { x: v.x, y: v.y, width: v.width, height: v.height, min_depth: v.min_depth, max_depth: v.max_depth }
}

pub fn rect(r: &vk::Rect2D) -> Rect {
    Rect { x: r.offset.x, y: r.offset.y, width: r.extent.width, height: r.extent.height }
}

/// Vertex buffer bindings of `vkCmdBindVertexBuffers(2)`.
///
/// # Safety
/// `buffers` and `offsets` must hold `n` values; `sizes` and `strides` null or `n` values.
pub unsafe fn vertex_bindings(
    n: u32,
    buffers: *const vk::Buffer,
    offsets: *const vk::DeviceSize,
    sizes: *const vk::DeviceSize,
    strides: *const vk::DeviceSize,
    v2: bool,
) -> Vec<crate::track::cmd::VertexBinding> {
    // SAFETY: per the contract (slice returns empty for null).
    let (b, o, s, t) = unsafe { (slice(buffers, n), slice(offsets, n), slice(sizes, n), slice(strides, n)) };
    (0..n as usize)
        .map(|i| crate::track::cmd::VertexBinding {
            buffer: b.get(i).map_or(0, |x| x.as_raw()),
            offset: o.get(i).copied().unwrap_or(0),
            size: s.get(i).copied().filter(|&x| x != vk::WHOLE_SIZE),
            stride: t.get(i).copied(),
            v2,
        })
        .collect()
}

/// A copy / resolve region (same extent on both sides) as a transfer region.
pub fn copy_region(r: &vk::ImageCopy) -> crate::track::eye_pass::TransferRegion {
    let rect = |o: vk::Offset3D| crate::core::rect::PixelRect { x: o.x, y: o.y, width: r.extent.width, height: r.extent.height };
    crate::track::eye_pass::TransferRegion {
        src_layer: r.src_subresource.base_array_layer,
        dst_layer: r.dst_subresource.base_array_layer,
        layer_count: r.src_subresource.layer_count.min(r.dst_subresource.layer_count),
        src: rect(r.src_offset),
        dst: rect(r.dst_offset),
    }
}

/// A blit region; None when it mirrors (a flip never maps an eye 1:1).
pub fn blit_region(
    src_sub: vk::ImageSubresourceLayers,
    src: [vk::Offset3D; 2],
    dst_sub: vk::ImageSubresourceLayers,
    dst: [vk::Offset3D; 2],
) -> Option<crate::track::eye_pass::TransferRegion> {
    let rect = |o: [vk::Offset3D; 2]| {
        (o[1].x >= o[0].x && o[1].y >= o[0].y).then(|| crate::core::rect::PixelRect {
            x: o[0].x,
            y: o[0].y,
            width: (o[1].x - o[0].x) as u32,
            height: (o[1].y - o[0].y) as u32,
        })
    };
    Some(crate::track::eye_pass::TransferRegion {
        src_layer: src_sub.base_array_layer,
        dst_layer: dst_sub.base_array_layer,
        layer_count: src_sub.layer_count.min(dst_sub.layer_count),
        src: rect(src)?,
        dst: rect(dst)?,
    })
}

pub fn clear_value(c: &vk::ClearValue) -> ClearValue {
    // SAFETY: all members of the union are 16 bytes of plain data; reading the uint32 view of
    // either member is defined.
    ClearValue(unsafe { c.color.uint32 })
}

/// All the aspects of `f`: depth and/or stencil for depth-stencil formats, else colour (a v1 input
/// attachment's aspects when the app chains none; whether a swapchain format is a depth one).
pub fn format_aspects(f: vk::Format) -> vk::ImageAspectFlags {
    use vk::{Format as F, ImageAspectFlags as A};
    match f {
        F::D16_UNORM | F::X8_D24_UNORM_PACK32 | F::D32_SFLOAT => A::DEPTH,
        F::S8_UINT => A::STENCIL,
        F::D16_UNORM_S8_UINT | F::D24_UNORM_S8_UINT | F::D32_SFLOAT_S8_UINT => A::DEPTH | A::STENCIL,
        _ => A::COLOR,
    }
}

pub fn image(handle: vk::Image, ci: &vk::ImageCreateInfo<'_>) -> Image {
    Image {
        handle: handle.as_raw(),
        image_type: ci.image_type,
        format: ci.format,
        extent: ci.extent,
        mip_levels: ci.mip_levels,
        array_layers: ci.array_layers,
        samples: ci.samples,
        usage: ci.usage,
        flags: ci.flags,
    }
}

pub fn image_view(handle: vk::ImageView, ci: &vk::ImageViewCreateInfo<'_>) -> ImageView {
    let r = ci.subresource_range;
    ImageView {
        handle: handle.as_raw(),
        image: ci.image.as_raw(),
        view_type: ci.view_type,
        format: ci.format,
        range: SubresourceRange {
            aspect_mask: r.aspect_mask,
            base_mip_level: r.base_mip_level,
            level_count: r.level_count,
            base_array_layer: r.base_array_layer,
            layer_count: r.layer_count,
        },
    }
}

fn att_ref(r: &vk::AttachmentReference) -> AttachmentRef {
    AttachmentRef { attachment: r.attachment, layout: r.layout }
}

fn att_ref2(r: &vk::AttachmentReference2<'_>) -> AttachmentRef {
    AttachmentRef { attachment: r.attachment, layout: r.layout }
}

/// # Safety
/// `ci` and everything it points to must be valid (`vkCreateRenderPass`).
pub unsafe fn render_pass(handle: vk::RenderPass, ci: &vk::RenderPassCreateInfo<'_>) -> RenderPass {
    // SAFETY: the arrays are valid with their counts (caller's contract).
    let (atts, subs) = unsafe { (slice(ci.p_attachments, ci.attachment_count), slice(ci.p_subpasses, ci.subpass_count)) };
    // SAFETY: a valid chain; the sType names this struct.
    let multiview = unsafe {
        find_in_chain::<vk::RenderPassMultiviewCreateInfo<'_>>(ci.p_next, vk::StructureType::RENDER_PASS_MULTIVIEW_CREATE_INFO)
            .map(|m| &*m)
    };
    let (view_masks, correlation) = match multiview {
        // SAFETY: arrays of the multiview struct, valid with their counts.
        Some(m) => unsafe {
            (slice(m.p_view_masks, m.subpass_count).to_vec(), slice(m.p_correlation_masks, m.correlation_mask_count).to_vec())
        },
        None => (vec![], vec![]),
    };
    let subpasses = subs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            // SAFETY: the subpass's arrays are valid with its counts; resolve has color_count entries.
            unsafe {
                Subpass {
                    color: slice(s.p_color_attachments, s.color_attachment_count).iter().map(att_ref).collect(),
                    resolve: slice(s.p_resolve_attachments, s.color_attachment_count).iter().map(att_ref).collect(),
                    depth_stencil: s.p_depth_stencil_attachment.as_ref().map(att_ref),
                    input: slice(s.p_input_attachments, s.input_attachment_count).iter().map(att_ref).collect(),
                    view_mask: view_masks.get(i).copied().unwrap_or(0),
                }
            }
        })
        .collect();
    RenderPass {
        handle: handle.as_raw(),
        version: RenderPassVersion::V1,
        attachments: atts
            .iter()
            .map(|a| AttachmentDesc {
                format: a.format,
                samples: a.samples,
                load_op: a.load_op,
                store_op: a.store_op,
                stencil_load_op: a.stencil_load_op,
                stencil_store_op: a.stencil_store_op,
                initial_layout: a.initial_layout,
                final_layout: a.final_layout,
            })
            .collect(),
        subpasses,
        correlation_masks: correlation,
        layer_rate_attachment: None,
    }
}

/// # Safety
/// `ci` and everything it points to must be valid (`vkCreateRenderPass2`).
pub unsafe fn render_pass2(handle: vk::RenderPass, ci: &vk::RenderPassCreateInfo2<'_>) -> RenderPass {
    // SAFETY: the arrays are valid with their counts (caller's contract).
    let (atts, subs, corr) = unsafe {
        (
            slice(ci.p_attachments, ci.attachment_count),
            slice(ci.p_subpasses, ci.subpass_count),
            slice(ci.p_correlated_view_masks, ci.correlated_view_mask_count),
        )
    };
    let subpasses = subs
        .iter()
        .map(|s| {
            // SAFETY: the subpass's arrays are valid with its counts; resolve has color_count entries.
            unsafe {
                Subpass {
                    color: slice(s.p_color_attachments, s.color_attachment_count).iter().map(att_ref2).collect(),
                    resolve: slice(s.p_resolve_attachments, s.color_attachment_count).iter().map(att_ref2).collect(),
                    depth_stencil: s.p_depth_stencil_attachment.as_ref().map(att_ref2),
                    input: slice(s.p_input_attachments, s.input_attachment_count).iter().map(att_ref2).collect(),
                    view_mask: s.view_mask,
                }
            }
        })
        .collect();
    RenderPass {
        handle: handle.as_raw(),
        version: RenderPassVersion::V2,
        attachments: atts
            .iter()
            .map(|a| AttachmentDesc {
                format: a.format,
                samples: a.samples,
                load_op: a.load_op,
                store_op: a.store_op,
                stencil_load_op: a.stencil_load_op,
                stencil_store_op: a.stencil_store_op,
                initial_layout: a.initial_layout,
                final_layout: a.final_layout,
            })
            .collect(),
        subpasses,
        correlation_masks: corr.to_vec(),
        layer_rate_attachment: None,
    }
}

/// # Safety
/// `ci` and everything it points to must be valid (`vkCreateFramebuffer`).
pub unsafe fn framebuffer(handle: vk::Framebuffer, ci: &vk::FramebufferCreateInfo<'_>) -> Framebuffer {
    let attachments = if ci.flags.contains(vk::FramebufferCreateFlags::IMAGELESS) {
        // SAFETY: a valid chain; the sType names this struct; its arrays are valid.
        let infos = unsafe {
            find_in_chain::<vk::FramebufferAttachmentsCreateInfo<'_>>(ci.p_next, vk::StructureType::FRAMEBUFFER_ATTACHMENTS_CREATE_INFO)
                .map(|a| slice((*a).p_attachment_image_infos, (*a).attachment_image_info_count))
                .unwrap_or(&[])
        };
        FramebufferAttachments::Imageless(
            infos
                .iter()
                .map(|i| ImagelessAttachment {
                    usage: i.usage,
                    flags: i.flags,
                    width: i.width,
                    height: i.height,
                    layer_count: i.layer_count,
                    // SAFETY: valid with its count.
                    view_formats: unsafe { slice(i.p_view_formats, i.view_format_count) }.to_vec(),
                })
                .collect(),
        )
    } else {
        // SAFETY: valid with its count.
        FramebufferAttachments::Views(unsafe { slice(ci.p_attachments, ci.attachment_count) }.iter().map(|v| v.as_raw()).collect())
    };
    Framebuffer {
        handle: handle.as_raw(),
        render_pass: ci.render_pass.as_raw(),
        attachments,
        width: ci.width,
        height: ci.height,
        layers: ci.layers,
    }
}

/// # Safety
/// `ci` and everything it points to must be valid (`vkCreateGraphicsPipelines`): the pointers of
/// the state subsets it defines; those of other subsets are never read (the spec lets them dangle).
pub unsafe fn graphics_pipeline(handle: vk::Pipeline, ci: &vk::GraphicsPipelineCreateInfo<'_>) -> GraphicsPipeline {
    use vk::GraphicsPipelineLibraryFlagsEXT as P;
    // SAFETY: a valid chain (caller's contract); the sTypes name these structs.
    let (library_info, linked) = unsafe {
        (
            find_in_chain::<vk::GraphicsPipelineLibraryCreateInfoEXT<'_>>(ci.p_next, vk::StructureType::GRAPHICS_PIPELINE_LIBRARY_CREATE_INFO_EXT).map(|g| (*g).flags),
            find_in_chain::<vk::PipelineLibraryCreateInfoKHR<'_>>(ci.p_next, vk::StructureType::PIPELINE_LIBRARY_CREATE_INFO_KHR)
                .map(|l| slice((*l).p_libraries, (*l).library_count).iter().map(|p| p.as_raw()).collect::<Vec<u64>>())
                .unwrap_or_default(),
        )
    };
    // The subsets this create info defines (the spec's rule when the struct is absent: none for
    // a library or a link of libraries, all for a whole pipeline).
    let parts = match library_info {
        Some(flags) => flags,
        None if ci.flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR) || !linked.is_empty() => P::empty(),
        None => P::VERTEX_INPUT_INTERFACE | P::PRE_RASTERIZATION_SHADERS | P::FRAGMENT_SHADER | P::FRAGMENT_OUTPUT_INTERFACE,
    };
    let defines_any = !parts.is_empty();
    // SAFETY: pDepthStencilState belongs to the fragment shader subset, read only when this info
    // defines it. It is ignored by the spec when the pass has no depth attachment; reading it
    // then is still fine when non-null, but it means "no depth test", which the eye-pass code
    // resolves later.
    let ds = if parts.contains(P::FRAGMENT_SHADER) { unsafe { ci.p_depth_stencil_state.as_ref() } } else { None };
    let dynamic_states = if defines_any {
        // SAFETY: every subset reads pDynamicState; the array is valid with its count.
        unsafe { ci.p_dynamic_state.as_ref().map(|d| slice(d.p_dynamic_states, d.dynamic_state_count).to_vec()).unwrap_or_default() }
    } else {
        Vec::new()
    };
    let rendering = if defines_any && ci.render_pass == vk::RenderPass::null() {
        // SAFETY: a valid chain; the sType names this struct; its array is valid.
        unsafe {
            find_in_chain::<vk::PipelineRenderingCreateInfo<'_>>(ci.p_next, vk::StructureType::PIPELINE_RENDERING_CREATE_INFO).map(|r| {
                let r = &*r;
                RenderingFormats {
                    view_mask: r.view_mask,
                    color: slice(r.p_color_attachment_formats, r.color_attachment_count).to_vec(),
                    depth: r.depth_attachment_format,
                    stencil: r.stencil_attachment_format,
                }
            })
        }
    } else {
        None
    };
    GraphicsPipeline {
        handle: handle.as_raw(),
        render_pass: if defines_any { ci.render_pass.as_raw() } else { 0 },
        subpass: ci.subpass,
        rendering,
        depth_test_enable: ds.is_some_and(|d| d.depth_test_enable != 0),
        depth_write_enable: ds.is_some_and(|d| d.depth_write_enable != 0),
        depth_compare_op: ds.map_or(vk::CompareOp::ALWAYS, |d| d.depth_compare_op),
        dynamic_states,
        parts,
        libraries: linked,
    }
}

/// # Safety
/// `info` and everything it points to must be valid (`vkCmdBeginRenderPass(2)`).
pub unsafe fn render_pass_begin(info: &vk::RenderPassBeginInfo<'_>) -> crate::track::RenderPassBegin {
    // SAFETY: a valid chain; the sType names this struct; arrays valid with their counts.
    let attachment_views = unsafe {
        find_in_chain::<vk::RenderPassAttachmentBeginInfo<'_>>(info.p_next, vk::StructureType::RENDER_PASS_ATTACHMENT_BEGIN_INFO)
            .map(|a| slice((*a).p_attachments, (*a).attachment_count).iter().map(|v| v.as_raw()).collect())
    };
    crate::track::RenderPassBegin {
        render_pass: info.render_pass.as_raw(),
        framebuffer: info.framebuffer.as_raw(),
        render_area: rect(&info.render_area),
        // SAFETY: valid with its count.
        clear_values: unsafe { slice(info.p_clear_values, info.clear_value_count) }.iter().map(clear_value).collect(),
        attachment_views,
    }
}

/// # Safety
/// `info` and everything it points to must be valid (`vkCmdBeginRendering`).
pub unsafe fn rendering(
    tracker: &DeviceTracker,
    info: &vk::RenderingInfo<'_>,
) -> (Rect, crate::track::cmd::DynamicRendering) {
    let shared = crate::bridge::shared();
    let att = |a: &vk::RenderingAttachmentInfo<'_>| RenderingAttachment {
        attachment: tracker.attachment(
            shared,
            a.image_view.as_raw(),
            a.image_layout,
            a.load_op,
            a.store_op,
            (a.load_op == vk::AttachmentLoadOp::CLEAR).then(|| clear_value(&a.clear_value)),
        ),
        resolve_mode: a.resolve_mode,
        resolve_view: a.resolve_image_view.as_raw(),
        resolve_layout: a.resolve_image_layout,
    };
    // SAFETY: arrays valid with their counts; optional pointers null or valid.
    let (color, depth, stencil) = unsafe {
        (
            slice(info.p_color_attachments, info.color_attachment_count).iter().map(att).collect(),
            info.p_depth_attachment.as_ref().map(att),
            info.p_stencil_attachment.as_ref().map(att),
        )
    };
    (
        rect(&info.render_area),
        crate::track::cmd::DynamicRendering {
            flags: info.flags,
            layer_count: info.layer_count,
            view_mask: info.view_mask,
            color,
            depth,
            stencil,
        },
    )
}

/// `vkCmdPushConstants`' bytes.
///
/// # Safety
/// `values` must point to `size` bytes.
pub unsafe fn push_constants(layout: vk::PipelineLayout, stages: vk::ShaderStageFlags, offset: u32, size: u32, values: *const c_void) -> StateCmd {
    // SAFETY: per the contract.
    let data = unsafe { slice(values as *const u8, size) }.to_vec();
    StateCmd::PushConstants { layout: layout.as_raw(), stages, offset, data }
}

/// Extension names of a create info.
///
/// # Safety
/// `names` must hold `n` NUL-terminated strings.
pub unsafe fn names(names: *const *const std::ffi::c_char, n: u32) -> Vec<String> {
    // SAFETY: per the contract.
    unsafe { slice(names, n) }
        .iter()
        .filter(|p| !p.is_null())
        // SAFETY: per the contract.
        .map(|&p| unsafe { std::ffi::CStr::from_ptr(p) }.to_string_lossy().into_owned())
        .collect()
}

/// The features of `VkDeviceCreateInfo::pNext` that decide which layer objects the device may see.
///
/// # Safety
/// `p_next` must be a valid `VkDeviceCreateInfo` structure chain.
pub unsafe fn device_features(p_next: *const c_void) -> crate::track::caps::ChainedFeatures {
    let mut f = crate::track::caps::ChainedFeatures::default();
    // SAFETY: a valid chain per the contract; each sType names the struct it is read as.
    unsafe {
        if let Some(s) = find_in_chain::<vk::PhysicalDeviceMultiviewFeatures<'_>>(p_next, vk::StructureType::PHYSICAL_DEVICE_MULTIVIEW_FEATURES) {
            f.multiview |= (*s).multiview != 0;
        }
        if let Some(s) = find_in_chain::<vk::PhysicalDeviceVulkan11Features<'_>>(p_next, vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_1_FEATURES) {
            f.multiview |= (*s).multiview != 0;
        }
        if let Some(s) = find_in_chain::<vk::PhysicalDeviceDynamicRenderingFeatures<'_>>(p_next, vk::StructureType::PHYSICAL_DEVICE_DYNAMIC_RENDERING_FEATURES) {
            f.dynamic_rendering |= (*s).dynamic_rendering != 0;
        }
        if let Some(s) = find_in_chain::<vk::PhysicalDeviceVulkan13Features<'_>>(p_next, vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_3_FEATURES) {
            f.dynamic_rendering |= (*s).dynamic_rendering != 0;
        }
    }
    f
}
