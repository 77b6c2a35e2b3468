//! Owned, immutable descriptions of the Vulkan objects an injected pass must know about (images,
//! views, render passes, framebuffers, pipelines): recorded once at creation by the FFI shell, so
//! every later decision is a safe lookup that needs neither the app's pointers nor a GPU.

use crate::bridge::{Shared, SwapchainImage};
use ash::vk;
use std::sync::Arc;

/// `VkImageCreateInfo`, the parts that matter for attaching to or reasoning about an image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub handle: u64,
    pub image_type: vk::ImageType,
    pub format: vk::Format,
    pub extent: vk::Extent3D,
    pub mip_levels: u32,
    pub array_layers: u32,
    pub samples: vk::SampleCountFlags,
    pub usage: vk::ImageUsageFlags,
    pub flags: vk::ImageCreateFlags,
}

impl Image {
    /// The OpenXR swapchain image this is, if any. Asked lazily: the runtime creates the image
    /// before the OpenXR half learns (from `xrEnumerateSwapchainImages`) that it is one.
    pub fn swapchain(&self, shared: &Shared) -> Option<Arc<SwapchainImage>> {
        shared.images.get(self.handle)
    }
}

/// `VkImageSubresourceRange`, with `VK_REMAINING_*` kept as written (resolve against the image).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubresourceRange {
    pub aspect_mask: vk::ImageAspectFlags,
    pub base_mip_level: u32,
    pub level_count: u32,
    pub base_array_layer: u32,
    pub layer_count: u32,
}

impl SubresourceRange {
    /// Layer count with `VK_REMAINING_ARRAY_LAYERS` resolved against the image's layers.
    pub fn layers_of(&self, image_layers: u32) -> u32 {
        if self.layer_count == vk::REMAINING_ARRAY_LAYERS {
            image_layers.saturating_sub(self.base_array_layer)
        } else {
            self.layer_count
        }
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImageView {
    pub handle: u64,
    pub image: u64,
    pub view_type: vk::ImageViewType,
    pub format: vk::Format,
    pub range: SubresourceRange,
}

/// `VkAttachmentDescription(2)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AttachmentDesc {
    pub format: vk::Format,
    pub samples: vk::SampleCountFlags,
    pub load_op: vk::AttachmentLoadOp,
    pub store_op: vk::AttachmentStoreOp,
    pub stencil_load_op: vk::AttachmentLoadOp,
    pub stencil_store_op: vk::AttachmentStoreOp,
    pub initial_layout: vk::ImageLayout,
    pub final_layout: vk::ImageLayout,
}

/// `VkAttachmentReference(2)`; `attachment` may be `VK_ATTACHMENT_UNUSED`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AttachmentRef {
    pub attachment: u32,
    pub layout: vk::ImageLayout,
}

impl AttachmentRef {
    pub fn used(&self) -> Option<u32> {
        (self.attachment != vk::ATTACHMENT_UNUSED).then_some(self.attachment)
    }
}

#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Subpass {
    pub color: Vec<AttachmentRef>,
    /// Same length as `color` when present.
    pub resolve: Vec<AttachmentRef>,
    pub depth_stencil: Option<AttachmentRef>,
    pub input: Vec<AttachmentRef>,
    /// Multiview: bit i = view i rendered; 0 = no multiview.
    pub view_mask: u32,
}

/// Which entry point created a render pass (the two have different chained structs and a later
/// injection must create its own passes compatibly).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RenderPassVersion {
    V1,
    V2,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderPass {
    pub handle: u64,
    pub version: RenderPassVersion,
    pub attachments: Vec<AttachmentDesc>,
    pub subpasses: Vec<Subpass>,
    /// `VkRenderPassMultiviewCreateInfo::pCorrelationMasks` or `VkRenderPassCreateInfo2`'s.
    pub correlation_masks: Vec<u32>,
    /// The shading-rate attachment the layer appended (variable-rate shading): its index, which
    /// is the app's attachment count. Everything else here is the app's view of the pass.
    pub layer_rate_attachment: Option<u32>,
}

impl RenderPass {
    /// Whether any subpass renders more than one view.
    pub fn is_multiview(&self) -> bool {
        self.subpasses.iter().any(|s| s.view_mask != 0)
    }
}

/// `VkFramebufferAttachmentImageInfo` of an imageless framebuffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImagelessAttachment {
    pub usage: vk::ImageUsageFlags,
    pub flags: vk::ImageCreateFlags,
    pub width: u32,
    pub height: u32,
    pub layer_count: u32,
    pub view_formats: Vec<vk::Format>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FramebufferAttachments {
    /// Image views given at creation.
    Views(Vec<u64>),
    /// `VK_FRAMEBUFFER_CREATE_IMAGELESS_BIT`: views come with each `vkCmdBeginRenderPass`.
    Imageless(Vec<ImagelessAttachment>),
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Framebuffer {
    pub handle: u64,
    pub render_pass: u64,
    pub attachments: FramebufferAttachments,
    pub width: u32,
    pub height: u32,
    pub layers: u32,
}

/// `VkPipelineRenderingCreateInfo` of a pipeline made for dynamic rendering.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderingFormats {
    pub view_mask: u32,
    pub color: Vec<vk::Format>,
    pub depth: vk::Format,
    pub stencil: vk::Format,
}

/// The parts of `VkGraphicsPipelineCreateInfo` that say how the pipeline uses depth (to find eye
/// passes and their depth convention) and which state it leaves dynamic (to restore after an
/// injected draw).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GraphicsPipeline {
    pub handle: u64,
    pub render_pass: u64,
    pub subpass: u32,
    /// Present when `render_pass` is null (dynamic rendering).
    pub rendering: Option<RenderingFormats>,
    pub depth_test_enable: bool,
    pub depth_write_enable: bool,
    pub depth_compare_op: vk::CompareOp,
    pub dynamic_states: Vec<vk::DynamicState>,
    /// The state subsets its own create info defines (`VkGraphicsPipelineLibraryCreateInfoEXT`;
    /// all of them for a pipeline made whole, none for a link of libraries alone).
    pub parts: vk::GraphicsPipelineLibraryFlagsEXT,
    /// The graphics pipeline libraries it links (`VkPipelineLibraryCreateInfoKHR`): the rest of
    /// its state is theirs (`link`).
    pub libraries: Vec<u64>,
}

impl GraphicsPipeline {
    pub fn is_dynamic(&self, state: vk::DynamicState) -> bool {
        self.dynamic_states.contains(&state)
    }

    /// A pipeline linked from libraries (DXVK builds nearly all its pipelines so) takes from
    /// each library the subsets that library defines: the depth test from the one with the
    /// fragment shader state, the rendering formats and render pass from any that has them,
    /// and every library's dynamic states.
    pub fn link(&mut self, libraries: &[&GraphicsPipeline]) {
        use vk::GraphicsPipelineLibraryFlagsEXT as P;
        for l in libraries {
            for ds in &l.dynamic_states {
                if !self.dynamic_states.contains(ds) {
                    self.dynamic_states.push(*ds);
                }
            }
            if l.parts.contains(P::FRAGMENT_SHADER) && !self.parts.contains(P::FRAGMENT_SHADER) {
                self.depth_test_enable = l.depth_test_enable;
                self.depth_write_enable = l.depth_write_enable;
                self.depth_compare_op = l.depth_compare_op;
            }
            let output = l.parts.contains(P::FRAGMENT_OUTPUT_INTERFACE) && !self.parts.contains(P::FRAGMENT_OUTPUT_INTERFACE);
            if l.rendering.is_some() && (self.rendering.is_none() || output) {
                self.rendering = l.rendering.clone();
            }
            if self.render_pass == 0 && l.render_pass != 0 {
                self.render_pass = l.render_pass;
                self.subpass = l.subpass;
            }
            self.parts |= l.parts;
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommandPool {
    pub handle: u64,
    pub flags: vk::CommandPoolCreateFlags,
    pub queue_family_index: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linked_pipeline_takes_its_libraries_state() {
        use vk::GraphicsPipelineLibraryFlagsEXT as P;
        let part = |parts: P, dynamic: &[vk::DynamicState], depth: bool| GraphicsPipeline {
            handle: 1,
            render_pass: 0,
            subpass: 0,
            rendering: parts.contains(P::FRAGMENT_OUTPUT_INTERFACE).then(|| RenderingFormats { view_mask: 0, color: vec![vk::Format::R8G8B8A8_SRGB], depth: vk::Format::D32_SFLOAT, stencil: vk::Format::UNDEFINED }),
            depth_test_enable: depth,
            depth_write_enable: depth,
            depth_compare_op: if depth { vk::CompareOp::GREATER } else { vk::CompareOp::NEVER },
            dynamic_states: dynamic.to_vec(),
            parts,
            libraries: Vec::new(),
        };
        let vertex_input = part(P::VERTEX_INPUT_INTERFACE, &[vk::DynamicState::VERTEX_INPUT_EXT], false);
        let raster = part(P::PRE_RASTERIZATION_SHADERS, &[vk::DynamicState::VIEWPORT_WITH_COUNT, vk::DynamicState::CULL_MODE], false);
        let fragment = part(P::FRAGMENT_SHADER, &[vk::DynamicState::DEPTH_COMPARE_OP], true);
        let output = part(P::FRAGMENT_OUTPUT_INTERFACE, &[vk::DynamicState::COLOR_BLEND_ENABLE_EXT], false);
        // The link's own create info defines nothing; what it says of depth is ignored.
        let mut linked = part(P::empty(), &[], false);
        linked.libraries = vec![2, 3, 4, 5];
        linked.link(&[&vertex_input, &raster, &fragment, &output]);
        assert!(linked.depth_test_enable && linked.depth_write_enable);
        assert_eq!(linked.depth_compare_op, vk::CompareOp::GREATER);
        assert_eq!(linked.rendering.as_ref().map(|r| r.depth), Some(vk::Format::D32_SFLOAT));
        for ds in [vk::DynamicState::VERTEX_INPUT_EXT, vk::DynamicState::CULL_MODE, vk::DynamicState::DEPTH_COMPARE_OP, vk::DynamicState::COLOR_BLEND_ENABLE_EXT] {
            assert!(linked.is_dynamic(ds), "{ds:?}");
        }
        assert_eq!(linked.parts, P::VERTEX_INPUT_INTERFACE | P::PRE_RASTERIZATION_SHADERS | P::FRAGMENT_SHADER | P::FRAGMENT_OUTPUT_INTERFACE);
    }

    #[test]
    fn remaining_layers_resolve_against_the_image() {
        let r = SubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 1,
            layer_count: vk::REMAINING_ARRAY_LAYERS,
        };
        assert_eq!(r.layers_of(2), 1);
        assert_eq!(SubresourceRange { layer_count: 2, base_array_layer: 0, ..r }.layers_of(6), 2);
    }

    #[test]
    fn multiview_and_unused_refs() {
        let unused = AttachmentRef { attachment: vk::ATTACHMENT_UNUSED, layout: vk::ImageLayout::UNDEFINED };
        assert_eq!(unused.used(), None);
        let rp = RenderPass {
            handle: 1,
            version: RenderPassVersion::V2,
            attachments: vec![],
            subpasses: vec![Subpass { view_mask: 0b11, ..Subpass::default() }],
            correlation_masks: vec![0b11],
            layer_rate_attachment: None,
        };
        assert!(rp.is_multiview());
    }
}
