//! Hooks for the state that engines and translation layers set dynamically (DXVK above all):
//! extended dynamic state 3, vertex input dynamic state and shader objects are tracked
//! (`track::ext_state`, `CmdState`) so that the layer's injected draws restore them afterwards;
//! the few commands whose state the layer does not restore mark their command buffer instead
//! (`CmdState::veto`: the app's own shading rate, NVIDIA's extended dynamic state 3 commands,
//! the attachment remapping of `VK_KHR_dynamic_rendering_local_read`), and every such command
//! still goes down unchanged.

use super::cmd;
use crate::plugin::vk::{convert, DeviceState};
use crate::track::cmd::StateCmd;
use crate::track::ext_state::{per_attachment, BlendAdvanced, BlendEquation, ExtState, VertexInputAttribute, VertexInputBinding};
use ash::vk::{self, Handle};

/// Records the app's extended dynamic state, one value per attachment where it has several.
fn ext(d: &DeviceState, cb: u64, states: Vec<ExtState>) {
    d.track.with_cb(cb, |s| {
        for e in states {
            s.record(StateCmd::Ext(e));
        }
    });
}

/// Extended dynamic state 3's commands: forwarded through `ExtFns::eds3`, then recorded.
macro_rules! eds3_hook {
    ($name:ident, $call:literal, $field:ident, ($($arg:ident : $ty:ty),*), |$d:ident, $cb:ident| $record:expr) => {
        pub(in crate::vk) unsafe extern "system" fn $name(cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                cb,
                (),
                |d| {
                    if let Some(t) = &d.ext.eds3 {
                        // SAFETY: forwarding the app's arguments unchanged to the next layer's
                        // command (the app reaches this hook only when the next layer has it).
                        unsafe { (t.$field)(cb, $($arg),*) }
                    }
                },
                |$d, $cb| $record,
            )
        }
    };
}

eds3_hook!(cmd_set_tessellation_domain_origin, "vkCmdSetTessellationDomainOriginEXT", cmd_set_tessellation_domain_origin_ext, (o: vk::TessellationDomainOrigin),
    |d, cb| ext(d, cb, vec![ExtState::TessellationDomainOrigin(o)]));
eds3_hook!(cmd_set_depth_clamp_enable, "vkCmdSetDepthClampEnableEXT", cmd_set_depth_clamp_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::DepthClampEnable(e != 0)]));
eds3_hook!(cmd_set_polygon_mode, "vkCmdSetPolygonModeEXT", cmd_set_polygon_mode_ext, (m: vk::PolygonMode),
    |d, cb| ext(d, cb, vec![ExtState::PolygonMode(m)]));
eds3_hook!(cmd_set_rasterization_samples, "vkCmdSetRasterizationSamplesEXT", cmd_set_rasterization_samples_ext, (s: vk::SampleCountFlags),
    |d, cb| ext(d, cb, vec![ExtState::RasterizationSamples(s)]));
eds3_hook!(cmd_set_sample_mask, "vkCmdSetSampleMaskEXT", cmd_set_sample_mask_ext, (samples: vk::SampleCountFlags, mask: *const vk::SampleMask), |d, cb| {
    // One 32-bit word per 32 samples.
    let words = samples.as_raw().div_ceil(32);
    // SAFETY: the app's mask holds that many words during its call.
    let mask = unsafe { convert::slice(mask, words) }.to_vec();
    ext(d, cb, vec![ExtState::SampleMask { samples, mask }])
});
eds3_hook!(cmd_set_alpha_to_coverage_enable, "vkCmdSetAlphaToCoverageEnableEXT", cmd_set_alpha_to_coverage_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::AlphaToCoverageEnable(e != 0)]));
eds3_hook!(cmd_set_alpha_to_one_enable, "vkCmdSetAlphaToOneEnableEXT", cmd_set_alpha_to_one_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::AlphaToOneEnable(e != 0)]));
eds3_hook!(cmd_set_logic_op_enable, "vkCmdSetLogicOpEnableEXT", cmd_set_logic_op_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::LogicOpEnable(e != 0)]));
eds3_hook!(cmd_set_color_blend_enable, "vkCmdSetColorBlendEnableEXT", cmd_set_color_blend_enable_ext, (first: u32, n: u32, p: *const vk::Bool32), |d, cb| {
    // SAFETY: the app's array holds `n` values during its call.
    let values = unsafe { convert::slice(p, n) };
    ext(d, cb, per_attachment(first, values, |attachment, e| ExtState::ColorBlendEnable { attachment, enable: e != 0 }))
});
eds3_hook!(cmd_set_color_blend_equation, "vkCmdSetColorBlendEquationEXT", cmd_set_color_blend_equation_ext, (first: u32, n: u32, p: *const vk::ColorBlendEquationEXT), |d, cb| {
    // SAFETY: as above.
    let values: Vec<BlendEquation> = unsafe { convert::slice(p, n) }.iter().map(BlendEquation::from).collect();
    ext(d, cb, per_attachment(first, &values, |attachment, equation| ExtState::ColorBlendEquation { attachment, equation }))
});
eds3_hook!(cmd_set_color_write_mask, "vkCmdSetColorWriteMaskEXT", cmd_set_color_write_mask_ext, (first: u32, n: u32, p: *const vk::ColorComponentFlags), |d, cb| {
    // SAFETY: as above.
    let values = unsafe { convert::slice(p, n) };
    ext(d, cb, per_attachment(first, values, |attachment, mask| ExtState::ColorWriteMask { attachment, mask }))
});
eds3_hook!(cmd_set_color_blend_advanced, "vkCmdSetColorBlendAdvancedEXT", cmd_set_color_blend_advanced_ext, (first: u32, n: u32, p: *const vk::ColorBlendAdvancedEXT), |d, cb| {
    // SAFETY: as above.
    let values: Vec<BlendAdvanced> = unsafe { convert::slice(p, n) }.iter().map(BlendAdvanced::from).collect();
    ext(d, cb, per_attachment(first, &values, |attachment, advanced| ExtState::ColorBlendAdvanced { attachment, advanced }))
});
eds3_hook!(cmd_set_rasterization_stream, "vkCmdSetRasterizationStreamEXT", cmd_set_rasterization_stream_ext, (s: u32),
    |d, cb| ext(d, cb, vec![ExtState::RasterizationStream(s)]));
eds3_hook!(cmd_set_conservative_rasterization_mode, "vkCmdSetConservativeRasterizationModeEXT", cmd_set_conservative_rasterization_mode_ext,
    (m: vk::ConservativeRasterizationModeEXT), |d, cb| ext(d, cb, vec![ExtState::ConservativeRasterizationMode(m)]));
eds3_hook!(cmd_set_extra_primitive_overestimation_size, "vkCmdSetExtraPrimitiveOverestimationSizeEXT", cmd_set_extra_primitive_overestimation_size_ext,
    (s: f32), |d, cb| ext(d, cb, vec![ExtState::ExtraPrimitiveOverestimationSize(s)]));
eds3_hook!(cmd_set_depth_clip_enable, "vkCmdSetDepthClipEnableEXT", cmd_set_depth_clip_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::DepthClipEnable(e != 0)]));
eds3_hook!(cmd_set_sample_locations_enable, "vkCmdSetSampleLocationsEnableEXT", cmd_set_sample_locations_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::SampleLocationsEnable(e != 0)]));
eds3_hook!(cmd_set_provoking_vertex_mode, "vkCmdSetProvokingVertexModeEXT", cmd_set_provoking_vertex_mode_ext, (m: vk::ProvokingVertexModeEXT),
    |d, cb| ext(d, cb, vec![ExtState::ProvokingVertexMode(m)]));
eds3_hook!(cmd_set_line_rasterization_mode, "vkCmdSetLineRasterizationModeEXT", cmd_set_line_rasterization_mode_ext, (m: vk::LineRasterizationModeEXT),
    |d, cb| ext(d, cb, vec![ExtState::LineRasterizationMode(m)]));
eds3_hook!(cmd_set_line_stipple_enable, "vkCmdSetLineStippleEnableEXT", cmd_set_line_stipple_enable_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::LineStippleEnable(e != 0)]));
eds3_hook!(cmd_set_depth_clip_negative_one_to_one, "vkCmdSetDepthClipNegativeOneToOneEXT", cmd_set_depth_clip_negative_one_to_one_ext, (e: vk::Bool32),
    |d, cb| ext(d, cb, vec![ExtState::DepthClipNegativeOneToOne(e != 0)]));

/// NVIDIA's extended dynamic state 3 commands: forwarded, and their command buffer vetoed (the
/// layer does not keep their values; no engine it knows sets them).
macro_rules! eds3_veto_hook {
    ($name:ident, $call:literal, $field:ident, ($($arg:ident : $ty:ty),*)) => {
        eds3_hook!($name, $call, $field, ($($arg: $ty),*), |d, cb| veto(d, cb, $call));
    };
}

eds3_veto_hook!(cmd_set_viewport_w_scaling_enable_nv, "vkCmdSetViewportWScalingEnableNV", cmd_set_viewport_w_scaling_enable_nv, (e: vk::Bool32));
eds3_veto_hook!(cmd_set_viewport_swizzle_nv, "vkCmdSetViewportSwizzleNV", cmd_set_viewport_swizzle_nv, (first: u32, n: u32, p: *const vk::ViewportSwizzleNV));
eds3_veto_hook!(cmd_set_coverage_to_color_enable_nv, "vkCmdSetCoverageToColorEnableNV", cmd_set_coverage_to_color_enable_nv, (e: vk::Bool32));
eds3_veto_hook!(cmd_set_coverage_to_color_location_nv, "vkCmdSetCoverageToColorLocationNV", cmd_set_coverage_to_color_location_nv, (l: u32));
eds3_veto_hook!(cmd_set_coverage_modulation_mode_nv, "vkCmdSetCoverageModulationModeNV", cmd_set_coverage_modulation_mode_nv, (m: vk::CoverageModulationModeNV));
eds3_veto_hook!(cmd_set_coverage_modulation_table_enable_nv, "vkCmdSetCoverageModulationTableEnableNV", cmd_set_coverage_modulation_table_enable_nv, (e: vk::Bool32));
eds3_veto_hook!(cmd_set_coverage_modulation_table_nv, "vkCmdSetCoverageModulationTableNV", cmd_set_coverage_modulation_table_nv, (n: u32, p: *const f32));
eds3_veto_hook!(cmd_set_shading_rate_image_enable_nv, "vkCmdSetShadingRateImageEnableNV", cmd_set_shading_rate_image_enable_nv, (e: vk::Bool32));
eds3_veto_hook!(cmd_set_representative_fragment_test_enable_nv, "vkCmdSetRepresentativeFragmentTestEnableNV", cmd_set_representative_fragment_test_enable_nv, (e: vk::Bool32));
eds3_veto_hook!(cmd_set_coverage_reduction_mode_nv, "vkCmdSetCoverageReductionModeNV", cmd_set_coverage_reduction_mode_nv, (m: vk::CoverageReductionModeNV));

fn veto(d: &DeviceState, cb: u64, call: &'static str) {
    d.track.with_cb(cb, |s| {
        s.veto.get_or_insert(call);
    });
}

pub(in crate::vk) unsafe extern "system" fn cmd_set_vertex_input(
    cb: vk::CommandBuffer,
    nb: u32,
    b: *const vk::VertexInputBindingDescription2EXT<'_>,
    na: u32,
    a: *const vk::VertexInputAttributeDescription2EXT<'_>,
) {
    cmd(
        "vkCmdSetVertexInputEXT",
        cb,
        (),
        |d| {
            if let Some(f) = d.ext.cmd_set_vertex_input {
                // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                unsafe { f(cb, nb, b, na, a) }
            }
        },
        |d, cb| {
            // SAFETY: the app's arrays hold `nb` and `na` descriptions during its call.
            let (bindings, attributes) = unsafe { (convert::slice(b, nb), convert::slice(a, na)) };
            let bindings = bindings.iter().map(|b| VertexInputBinding { binding: b.binding, stride: b.stride, input_rate: b.input_rate, divisor: b.divisor }).collect();
            let attributes = attributes.iter().map(|a| VertexInputAttribute { location: a.location, binding: a.binding, format: a.format, offset: a.offset }).collect();
            ext(d, cb, vec![ExtState::VertexInput { bindings, attributes }])
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_bind_shaders(cb: vk::CommandBuffer, n: u32, stages: *const vk::ShaderStageFlags, shaders: *const vk::ShaderEXT) {
    cmd(
        "vkCmdBindShadersEXT",
        cb,
        (),
        |d| {
            if let Some(f) = d.ext.cmd_bind_shaders {
                // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                unsafe { f(cb, n, stages, shaders) }
            }
        },
        |d, cb| {
            // SAFETY: `n` stages, and `n` shaders unless the pointer is null (then every stage
            // is unbound), during the app's call.
            let stages = unsafe { convert::slice(stages, n) }.to_vec();
            let shaders = if shaders.is_null() {
                vec![0; stages.len()]
            } else {
                // SAFETY: as above.
                unsafe { convert::slice(shaders, n) }.iter().map(|s| s.as_raw()).collect()
            };
            d.track.with_cb(cb, |s| s.record(StateCmd::BindShaders { stages, shaders }));
        },
    )
}

/// Hooks for commands that veto injections: forwarded through `ExtFns`, their command buffer
/// marked.
macro_rules! veto_hook {
    ($name:ident, $call:literal, $field:ident, ($cb:ident, $($arg:ident : $ty:ty),*)) => {
        pub(in crate::vk) unsafe extern "system" fn $name($cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                $cb,
                (),
                |d| {
                    if let Some(f) = d.ext.$field {
                        // SAFETY: forwarding the app's arguments unchanged to the next layer's
                        // command (only handed out when the next layer has it).
                        unsafe { f($cb, $($arg),*) }
                    }
                },
                |d, cb| veto(d, cb, $call),
            )
        }
    };
}

veto_hook!(cmd_set_fragment_shading_rate, "vkCmdSetFragmentShadingRateKHR", cmd_set_fragment_shading_rate, (cb, size: *const vk::Extent2D, ops: *const [vk::FragmentShadingRateCombinerOpKHR; 2]));
veto_hook!(cmd_set_rendering_attachment_locations, "vkCmdSetRenderingAttachmentLocations", cmd_set_rendering_attachment_locations,
    (cb, info: *const vk::RenderingAttachmentLocationInfoKHR<'_>));
veto_hook!(cmd_set_rendering_input_attachment_indices, "vkCmdSetRenderingInputAttachmentIndices", cmd_set_rendering_input_attachment_indices,
    (cb, info: *const vk::RenderingInputAttachmentIndexInfoKHR<'_>));
