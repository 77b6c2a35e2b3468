//! The dynamic state of `VK_EXT_extended_dynamic_state3` and `VK_EXT_vertex_input_dynamic_state`
//! as the app set it: owned copies of each command's values, kept to be replayed after the
//! layer's injected draws (`plugin::vk::inject::restore`). Engines and translation layers (DXVK
//! above all) set nearly all pipeline state this way; binding the layer's own pipeline replaces
//! every state it does not declare dynamic, so each one is remembered and restored, never lost.
//! Per-attachment states (blend enable, equation, write mask, advanced blend) are kept per
//! attachment: a later command for some attachments replaces only theirs.
#![forbid(unsafe_code)]

use ash::vk;

/// `VkColorBlendEquationEXT`, comparable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlendEquation {
    pub src_color: vk::BlendFactor,
    pub dst_color: vk::BlendFactor,
    pub color_op: vk::BlendOp,
    pub src_alpha: vk::BlendFactor,
    pub dst_alpha: vk::BlendFactor,
    pub alpha_op: vk::BlendOp,
}

impl From<&vk::ColorBlendEquationEXT> for BlendEquation {
    fn from(e: &vk::ColorBlendEquationEXT) -> BlendEquation {
        BlendEquation {
            src_color: e.src_color_blend_factor,
            dst_color: e.dst_color_blend_factor,
            color_op: e.color_blend_op,
            src_alpha: e.src_alpha_blend_factor,
            dst_alpha: e.dst_alpha_blend_factor,
            alpha_op: e.alpha_blend_op,
        }
    }
}

impl BlendEquation {
    pub fn to_vk(self) -> vk::ColorBlendEquationEXT {
        vk::ColorBlendEquationEXT {
            src_color_blend_factor: self.src_color,
            dst_color_blend_factor: self.dst_color,
            color_blend_op: self.color_op,
            src_alpha_blend_factor: self.src_alpha,
            dst_alpha_blend_factor: self.dst_alpha,
            alpha_blend_op: self.alpha_op,
        }
    }
}

/// `VkColorBlendAdvancedEXT`, comparable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlendAdvanced {
    pub op: vk::BlendOp,
    pub src_premultiplied: bool,
    pub dst_premultiplied: bool,
    pub overlap: vk::BlendOverlapEXT,
    pub clamp_results: bool,
}

impl From<&vk::ColorBlendAdvancedEXT> for BlendAdvanced {
    fn from(a: &vk::ColorBlendAdvancedEXT) -> BlendAdvanced {
        BlendAdvanced {
            op: a.advanced_blend_op,
            src_premultiplied: a.src_premultiplied != 0,
            dst_premultiplied: a.dst_premultiplied != 0,
            overlap: a.blend_overlap,
            clamp_results: a.clamp_results != 0,
        }
    }
}

impl BlendAdvanced {
    pub fn to_vk(self) -> vk::ColorBlendAdvancedEXT {
        vk::ColorBlendAdvancedEXT {
            advanced_blend_op: self.op,
            src_premultiplied: self.src_premultiplied.into(),
            dst_premultiplied: self.dst_premultiplied.into(),
            blend_overlap: self.overlap,
            clamp_results: self.clamp_results.into(),
        }
    }
}

/// One `VkVertexInputBindingDescription2EXT`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VertexInputBinding {
    pub binding: u32,
    pub stride: u32,
    pub input_rate: vk::VertexInputRate,
    pub divisor: u32,
}

/// One `VkVertexInputAttributeDescription2EXT`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VertexInputAttribute {
    pub location: u32,
    pub binding: u32,
    pub format: vk::Format,
    pub offset: u32,
}

/// One state-setting command of the two extensions, as recorded and as replayed; the
/// per-attachment ones hold one attachment each.
#[derive(Clone, Debug, PartialEq)]
pub enum ExtState {
    TessellationDomainOrigin(vk::TessellationDomainOrigin),
    DepthClampEnable(bool),
    PolygonMode(vk::PolygonMode),
    RasterizationSamples(vk::SampleCountFlags),
    /// `vkCmdSetSampleMaskEXT`: the mask's words for `samples` samples.
    SampleMask { samples: vk::SampleCountFlags, mask: Vec<u32> },
    AlphaToCoverageEnable(bool),
    AlphaToOneEnable(bool),
    LogicOpEnable(bool),
    ColorBlendEnable { attachment: u32, enable: bool },
    ColorBlendEquation { attachment: u32, equation: BlendEquation },
    ColorWriteMask { attachment: u32, mask: vk::ColorComponentFlags },
    ColorBlendAdvanced { attachment: u32, advanced: BlendAdvanced },
    RasterizationStream(u32),
    ConservativeRasterizationMode(vk::ConservativeRasterizationModeEXT),
    ExtraPrimitiveOverestimationSize(f32),
    DepthClipEnable(bool),
    SampleLocationsEnable(bool),
    ProvokingVertexMode(vk::ProvokingVertexModeEXT),
    LineRasterizationMode(vk::LineRasterizationModeEXT),
    LineStippleEnable(bool),
    DepthClipNegativeOneToOne(bool),
    /// `vkCmdSetVertexInputEXT`: replaces the whole vertex input state.
    VertexInput { bindings: Vec<VertexInputBinding>, attributes: Vec<VertexInputAttribute> },
}

impl ExtState {
    /// The `VkDynamicState` a pipeline lists to take this value from the command buffer.
    pub fn dynamic_state(&self) -> vk::DynamicState {
        use vk::DynamicState as D;
        match self {
            ExtState::TessellationDomainOrigin(_) => D::TESSELLATION_DOMAIN_ORIGIN_EXT,
            ExtState::DepthClampEnable(_) => D::DEPTH_CLAMP_ENABLE_EXT,
            ExtState::PolygonMode(_) => D::POLYGON_MODE_EXT,
            ExtState::RasterizationSamples(_) => D::RASTERIZATION_SAMPLES_EXT,
            ExtState::SampleMask { .. } => D::SAMPLE_MASK_EXT,
            ExtState::AlphaToCoverageEnable(_) => D::ALPHA_TO_COVERAGE_ENABLE_EXT,
            ExtState::AlphaToOneEnable(_) => D::ALPHA_TO_ONE_ENABLE_EXT,
            ExtState::LogicOpEnable(_) => D::LOGIC_OP_ENABLE_EXT,
            ExtState::ColorBlendEnable { .. } => D::COLOR_BLEND_ENABLE_EXT,
            ExtState::ColorBlendEquation { .. } => D::COLOR_BLEND_EQUATION_EXT,
            ExtState::ColorWriteMask { .. } => D::COLOR_WRITE_MASK_EXT,
            ExtState::ColorBlendAdvanced { .. } => D::COLOR_BLEND_ADVANCED_EXT,
            ExtState::RasterizationStream(_) => D::RASTERIZATION_STREAM_EXT,
            ExtState::ConservativeRasterizationMode(_) => D::CONSERVATIVE_RASTERIZATION_MODE_EXT,
            ExtState::ExtraPrimitiveOverestimationSize(_) => D::EXTRA_PRIMITIVE_OVERESTIMATION_SIZE_EXT,
            ExtState::DepthClipEnable(_) => D::DEPTH_CLIP_ENABLE_EXT,
            ExtState::SampleLocationsEnable(_) => D::SAMPLE_LOCATIONS_ENABLE_EXT,
            ExtState::ProvokingVertexMode(_) => D::PROVOKING_VERTEX_MODE_EXT,
            ExtState::LineRasterizationMode(_) => D::LINE_RASTERIZATION_MODE_EXT,
            ExtState::LineStippleEnable(_) => D::LINE_STIPPLE_ENABLE_EXT,
            ExtState::DepthClipNegativeOneToOne(_) => D::DEPTH_CLIP_NEGATIVE_ONE_TO_ONE_EXT,
            ExtState::VertexInput { .. } => D::VERTEX_INPUT_EXT,
        }
    }

    /// The colour attachment a per-attachment state belongs to: its value is kept beside the
    /// other attachments' (0 for every other state).
    pub fn attachment(&self) -> u32 {
        match self {
            ExtState::ColorBlendEnable { attachment, .. }
            | ExtState::ColorBlendEquation { attachment, .. }
            | ExtState::ColorWriteMask { attachment, .. }
            | ExtState::ColorBlendAdvanced { attachment, .. } => *attachment,
            _ => 0,
        }
    }
}

/// Splits a per-attachment command (`first`, one value per attachment) into one state per
/// attachment.
pub fn per_attachment<T: Copy>(first: u32, values: &[T], make: impl Fn(u32, T) -> ExtState) -> Vec<ExtState> {
    values.iter().enumerate().map(|(i, &v)| make(first + i as u32, v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_attachment_commands_split() {
        let states = per_attachment(2, &[true, false, true], |attachment, enable| ExtState::ColorBlendEnable { attachment, enable });
        assert_eq!(states.len(), 3);
        assert_eq!(states[1], ExtState::ColorBlendEnable { attachment: 3, enable: false });
        assert!(states.iter().all(|s| s.dynamic_state() == vk::DynamicState::COLOR_BLEND_ENABLE_EXT));
        assert_eq!(states.iter().map(ExtState::attachment).collect::<Vec<_>>(), vec![2, 3, 4]);
    }

    #[test]
    fn every_state_names_its_own_dynamic_state() {
        let all = [
            ExtState::TessellationDomainOrigin(vk::TessellationDomainOrigin::LOWER_LEFT),
            ExtState::DepthClampEnable(true),
            ExtState::PolygonMode(vk::PolygonMode::LINE),
            ExtState::RasterizationSamples(vk::SampleCountFlags::TYPE_4),
            ExtState::SampleMask { samples: vk::SampleCountFlags::TYPE_4, mask: vec![0xf] },
            ExtState::AlphaToCoverageEnable(true),
            ExtState::AlphaToOneEnable(true),
            ExtState::LogicOpEnable(true),
            ExtState::ColorBlendEnable { attachment: 0, enable: true },
            ExtState::ColorBlendEquation { attachment: 0, equation: BlendEquation::from(&vk::ColorBlendEquationEXT::default()) },
            ExtState::ColorWriteMask { attachment: 0, mask: vk::ColorComponentFlags::RGBA },
            ExtState::ColorBlendAdvanced { attachment: 0, advanced: BlendAdvanced::from(&vk::ColorBlendAdvancedEXT::default()) },
            ExtState::RasterizationStream(1),
            ExtState::ConservativeRasterizationMode(vk::ConservativeRasterizationModeEXT::OVERESTIMATE),
            ExtState::ExtraPrimitiveOverestimationSize(0.5),
            ExtState::DepthClipEnable(false),
            ExtState::SampleLocationsEnable(true),
            ExtState::ProvokingVertexMode(vk::ProvokingVertexModeEXT::LAST_VERTEX),
            ExtState::LineRasterizationMode(vk::LineRasterizationModeEXT::BRESENHAM),
            ExtState::LineStippleEnable(true),
            ExtState::DepthClipNegativeOneToOne(true),
            ExtState::VertexInput { bindings: Vec::new(), attributes: Vec::new() },
        ];
        let mut seen: Vec<i32> = all.iter().map(|s| s.dynamic_state().as_raw()).collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), all.len(), "two states share a VkDynamicState");
        // The blend equation and advanced blend round-trip through Vulkan's structs.
        let e = vk::ColorBlendEquationEXT { src_color_blend_factor: vk::BlendFactor::SRC_ALPHA, color_blend_op: vk::BlendOp::MAX, ..Default::default() };
        assert_eq!(BlendEquation::from(&e).to_vk().color_blend_op, vk::BlendOp::MAX);
        let a = vk::ColorBlendAdvancedEXT { clamp_results: vk::TRUE, ..Default::default() };
        assert!(BlendAdvanced::from(&BlendAdvanced::from(&a).to_vk()).clamp_results);
    }
}
