//! Save and restore of the app's state around the layer's injected draws: the tracked state
//! (`CmdState::restore_commands`: pipeline, dynamic state, push constants, vertex buffers; and
//! the app's descriptor sets when a feature bound sets of its own, `Injection::bound_sets`) is
//! replayed when the `Restore` guard drops, so every path out of an injection — success, a
//! feature's failure, an early return — gives the app back the state it set, extended dynamic
//! state 3, vertex input and shader objects included. State the layer cannot restore vetoes the
//! injection before anything is recorded (`CmdState::veto`).
//! `RestoreCompute` does the same for the compute bind point around the layer's dispatches.

use crate::track::cmd::StateCmd;
use crate::track::ext_state::ExtState;
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};

/// Replays the app's state into `cb` when dropped.
pub(crate) struct Restore<'a> {
    d: &'a DeviceState,
    cb: vk::CommandBuffer,
    commands: &'a [StateCmd],
    sets: &'a [StateCmd],
    bound_sets: &'a std::cell::Cell<bool>,
}

impl<'a> Restore<'a> {
    /// `cb` must be recording inside the app's pass, with `commands` and `sets` taken from its
    /// tracked state when the injection point was reached; `bound_sets` says (when dropped)
    /// whether an injected draw bound descriptor sets.
    pub(crate) fn new(d: &'a DeviceState, cb: vk::CommandBuffer, commands: &'a [StateCmd], sets: &'a [StateCmd], bound_sets: &'a std::cell::Cell<bool>) -> Restore<'a> {
        Restore { d, cb, commands, sets, bound_sets }
    }
}

impl Drop for Restore<'_> {
    fn drop(&mut self) {
        let sets = if self.bound_sets.get() { self.sets } else { &[] };
        for c in self.commands.iter().chain(sets) {
            // SAFETY: `cb` is recording inside the app's pass (`new`'s contract); the commands
            // replay the app's own state, whose handles are alive while it records.
            unsafe { replay(self.d, self.cb, c) };
        }
    }
}

/// Rebinds the app's compute pipeline (or compute shader object) and descriptor sets when
/// dropped: a dispatch of the layer's in the app's command buffer (outside any pass) replaces
/// both. Push constants are left alone
/// (the layer's compute pipelines have none, and binding a pipeline does not disturb them).
pub(crate) struct RestoreCompute<'a> {
    d: &'a DeviceState,
    cb: vk::CommandBuffer,
    state: crate::track::cmd::ComputeState,
}

impl<'a> RestoreCompute<'a> {
    /// `cb` must be recording outside any pass; `state` is its tracked compute state taken before
    /// the layer binds anything there.
    pub(crate) fn new(d: &'a DeviceState, cb: vk::CommandBuffer, state: crate::track::cmd::ComputeState) -> RestoreCompute<'a> {
        RestoreCompute { d, cb, state }
    }
}

impl Drop for RestoreCompute<'_> {
    fn drop(&mut self) {
        let v0 = self.d.fns.fp_v1_0();
        // SAFETY: `cb` is recording (`new`'s contract); the handles are the app's own bindings,
        // alive while it records.
        unsafe {
            match (self.state.shader, self.d.ext.cmd_bind_shaders) {
                (Some(s), Some(bind)) => bind(self.cb, 1, &vk::ShaderStageFlags::COMPUTE, &vk::ShaderEXT::from_raw(s)),
                _ => {
                    if let Some(p) = self.state.pipeline {
                        (v0.cmd_bind_pipeline)(self.cb, vk::PipelineBindPoint::COMPUTE, vk::Pipeline::from_raw(p));
                    }
                }
            }
            for c in &self.state.sets {
                if let StateCmd::BindDescriptorSets { layout, first, sets, dynamic_offsets } = c {
                    let sets: Vec<vk::DescriptorSet> = sets.iter().map(|s| vk::DescriptorSet::from_raw(*s)).collect();
                    (v0.cmd_bind_descriptor_sets)(
                        self.cb,
                        vk::PipelineBindPoint::COMPUTE,
                        vk::PipelineLayout::from_raw(*layout),
                        *first,
                        sets.len() as u32,
                        sets.as_ptr(),
                        dynamic_offsets.len() as u32,
                        dynamic_offsets.as_ptr(),
                    );
                }
            }
        }
    }
}

/// Records one state command the app had in effect.
///
/// # Safety
/// `cb` must be recording; the command's handles are the app's, still valid.
pub(crate) unsafe fn replay(d: &DeviceState, cb: vk::CommandBuffer, c: &StateCmd) {
    let v0 = d.fns.fp_v1_0();
    let v3 = d.fns.fp_v1_3();
    let vp = |v: &crate::track::cmd::Viewport| vk::Viewport { x: v.x, y: v.y, width: v.width, height: v.height, min_depth: v.min_depth, max_depth: v.max_depth };
    let rc = |r: &crate::track::cmd::Rect| vk::Rect2D { offset: vk::Offset2D { x: r.x, y: r.y }, extent: vk::Extent2D { width: r.width, height: r.height } };
    // SAFETY: per this function's contract; arrays live across each call.
    unsafe {
        match c {
            StateCmd::BindPipeline(p) => (v0.cmd_bind_pipeline)(cb, vk::PipelineBindPoint::GRAPHICS, vk::Pipeline::from_raw(*p)),
            StateCmd::SetViewport { first, viewports } => {
                let v: Vec<_> = viewports.iter().map(vp).collect();
                (v0.cmd_set_viewport)(cb, *first, v.len() as u32, v.as_ptr())
            }
            StateCmd::SetViewportWithCount(viewports) => {
                let v: Vec<_> = viewports.iter().map(vp).collect();
                (v3.cmd_set_viewport_with_count)(cb, v.len() as u32, v.as_ptr())
            }
            StateCmd::SetScissor { first, scissors } => {
                let s: Vec<_> = scissors.iter().map(rc).collect();
                (v0.cmd_set_scissor)(cb, *first, s.len() as u32, s.as_ptr())
            }
            StateCmd::SetScissorWithCount(scissors) => {
                let s: Vec<_> = scissors.iter().map(rc).collect();
                (v3.cmd_set_scissor_with_count)(cb, s.len() as u32, s.as_ptr())
            }
            StateCmd::LineWidth(w) => (v0.cmd_set_line_width)(cb, *w),
            StateCmd::DepthBias { constant_factor, clamp, slope_factor } => (v0.cmd_set_depth_bias)(cb, *constant_factor, *clamp, *slope_factor),
            StateCmd::BlendConstants(c) => (v0.cmd_set_blend_constants)(cb, c),
            StateCmd::DepthBounds { min, max } => (v0.cmd_set_depth_bounds)(cb, *min, *max),
            StateCmd::StencilCompareMask { face, mask } => (v0.cmd_set_stencil_compare_mask)(cb, *face, *mask),
            StateCmd::StencilWriteMask { face, mask } => (v0.cmd_set_stencil_write_mask)(cb, *face, *mask),
            StateCmd::StencilReference { face, reference } => (v0.cmd_set_stencil_reference)(cb, *face, *reference),
            StateCmd::CullMode(m) => (v3.cmd_set_cull_mode)(cb, *m),
            StateCmd::FrontFace(f) => (v3.cmd_set_front_face)(cb, *f),
            StateCmd::PrimitiveTopology(t) => (v3.cmd_set_primitive_topology)(cb, *t),
            StateCmd::DepthTestEnable(e) => (v3.cmd_set_depth_test_enable)(cb, (*e).into()),
            StateCmd::DepthWriteEnable(e) => (v3.cmd_set_depth_write_enable)(cb, (*e).into()),
            StateCmd::DepthCompareOp(op) => (v3.cmd_set_depth_compare_op)(cb, *op),
            StateCmd::DepthBoundsTestEnable(e) => (v3.cmd_set_depth_bounds_test_enable)(cb, (*e).into()),
            StateCmd::StencilTestEnable(e) => (v3.cmd_set_stencil_test_enable)(cb, (*e).into()),
            StateCmd::StencilOp { face, fail_op, pass_op, depth_fail_op, compare_op } => {
                (v3.cmd_set_stencil_op)(cb, *face, *fail_op, *pass_op, *depth_fail_op, *compare_op)
            }
            StateCmd::RasterizerDiscardEnable(e) => (v3.cmd_set_rasterizer_discard_enable)(cb, (*e).into()),
            StateCmd::DepthBiasEnable(e) => (v3.cmd_set_depth_bias_enable)(cb, (*e).into()),
            StateCmd::PrimitiveRestartEnable(e) => (v3.cmd_set_primitive_restart_enable)(cb, (*e).into()),
            StateCmd::LineStipple { factor, pattern } => {
                if let Some(f) = d.ext.cmd_set_line_stipple {
                    f(cb, *factor, *pattern)
                }
            }
            StateCmd::ColorWriteEnable(v) => {
                if let Some(f) = d.ext.cmd_set_color_write_enable {
                    let b: Vec<vk::Bool32> = v.iter().map(|&x| x.into()).collect();
                    f(cb, b.len() as u32, b.as_ptr())
                }
            }
            StateCmd::LogicOp(op) => {
                if let Some(f) = d.ext.cmd_set_logic_op {
                    f(cb, *op)
                }
            }
            StateCmd::PatchControlPoints(n) => {
                if let Some(f) = d.ext.cmd_set_patch_control_points {
                    f(cb, *n)
                }
            }
            StateCmd::Ext(e) => replay_ext(d, cb, e),
            StateCmd::BindShaders { stages, shaders } => {
                if let Some(f) = d.ext.cmd_bind_shaders {
                    let shaders: Vec<vk::ShaderEXT> = shaders.iter().map(|s| vk::ShaderEXT::from_raw(*s)).collect();
                    f(cb, stages.len() as u32, stages.as_ptr(), shaders.as_ptr())
                }
            }
            StateCmd::PushConstants { layout, stages, offset, data } => {
                (v0.cmd_push_constants)(cb, vk::PipelineLayout::from_raw(*layout), *stages, *offset, data.len() as u32, data.as_ptr().cast())
            }
            StateCmd::BindDescriptorSets { layout, first, sets, dynamic_offsets } => {
                let sets: Vec<vk::DescriptorSet> = sets.iter().map(|s| vk::DescriptorSet::from_raw(*s)).collect();
                (v0.cmd_bind_descriptor_sets)(
                    cb,
                    vk::PipelineBindPoint::GRAPHICS,
                    vk::PipelineLayout::from_raw(*layout),
                    *first,
                    sets.len() as u32,
                    sets.as_ptr(),
                    dynamic_offsets.len() as u32,
                    dynamic_offsets.as_ptr(),
                )
            }
            StateCmd::BindVertexBuffers { first, bindings } => {
                let buffers: Vec<vk::Buffer> = bindings.iter().map(|b| vk::Buffer::from_raw(b.buffer)).collect();
                let offsets: Vec<u64> = bindings.iter().map(|b| b.offset).collect();
                let n = buffers.len() as u32;
                if bindings.iter().any(|b| b.v2) {
                    let sizes: Vec<u64> = bindings.iter().map(|b| b.size.unwrap_or(vk::WHOLE_SIZE)).collect();
                    let strides: Option<Vec<u64>> = bindings.iter().map(|b| b.stride).collect();
                    let has_sizes = bindings.iter().any(|b| b.size.is_some());
                    (v3.cmd_bind_vertex_buffers2)(
                        cb,
                        *first,
                        n,
                        buffers.as_ptr(),
                        offsets.as_ptr(),
                        if has_sizes { sizes.as_ptr() } else { std::ptr::null() },
                        strides.as_ref().map_or(std::ptr::null(), |s| s.as_ptr()),
                    )
                } else {
                    (v0.cmd_bind_vertex_buffers)(cb, *first, n, buffers.as_ptr(), offsets.as_ptr())
                }
            }
        }
    }
}

/// Records one extended dynamic state command the app had in effect (one attachment at a time
/// for per-attachment states).
///
/// # Safety
/// As `replay`.
unsafe fn replay_ext(d: &DeviceState, cb: vk::CommandBuffer, e: &ExtState) {
    if let ExtState::VertexInput { bindings, attributes } = e {
        let Some(f) = d.ext.cmd_set_vertex_input else { return };
        let b: Vec<vk::VertexInputBindingDescription2EXT<'_>> = bindings
            .iter()
            .map(|b| vk::VertexInputBindingDescription2EXT::default().binding(b.binding).stride(b.stride).input_rate(b.input_rate).divisor(b.divisor))
            .collect();
        let a: Vec<vk::VertexInputAttributeDescription2EXT<'_>> = attributes
            .iter()
            .map(|a| vk::VertexInputAttributeDescription2EXT::default().location(a.location).binding(a.binding).format(a.format).offset(a.offset))
            .collect();
        // SAFETY: per the contract; the app called this command, so the device has it.
        unsafe { f(cb, b.len() as u32, b.as_ptr(), a.len() as u32, a.as_ptr()) };
        return;
    }
    // Only reached for commands the app recorded through the same table.
    let Some(t) = &d.ext.eds3 else { return };
    let b = |v: bool| vk::Bool32::from(v);
    // SAFETY: per the contract; each command is one the app called (the device has it), and
    // the arrays live across each call.
    unsafe {
        match e {
            ExtState::TessellationDomainOrigin(o) => (t.cmd_set_tessellation_domain_origin_ext)(cb, *o),
            ExtState::DepthClampEnable(v) => (t.cmd_set_depth_clamp_enable_ext)(cb, b(*v)),
            ExtState::PolygonMode(m) => (t.cmd_set_polygon_mode_ext)(cb, *m),
            ExtState::RasterizationSamples(s) => (t.cmd_set_rasterization_samples_ext)(cb, *s),
            ExtState::SampleMask { samples, mask } => (t.cmd_set_sample_mask_ext)(cb, *samples, mask.as_ptr()),
            ExtState::AlphaToCoverageEnable(v) => (t.cmd_set_alpha_to_coverage_enable_ext)(cb, b(*v)),
            ExtState::AlphaToOneEnable(v) => (t.cmd_set_alpha_to_one_enable_ext)(cb, b(*v)),
            ExtState::LogicOpEnable(v) => (t.cmd_set_logic_op_enable_ext)(cb, b(*v)),
            ExtState::ColorBlendEnable { attachment, enable } => (t.cmd_set_color_blend_enable_ext)(cb, *attachment, 1, &b(*enable)),
            ExtState::ColorBlendEquation { attachment, equation } => (t.cmd_set_color_blend_equation_ext)(cb, *attachment, 1, &equation.to_vk()),
            ExtState::ColorWriteMask { attachment, mask } => (t.cmd_set_color_write_mask_ext)(cb, *attachment, 1, mask),
            ExtState::ColorBlendAdvanced { attachment, advanced } => (t.cmd_set_color_blend_advanced_ext)(cb, *attachment, 1, &advanced.to_vk()),
            ExtState::RasterizationStream(s) => (t.cmd_set_rasterization_stream_ext)(cb, *s),
            ExtState::ConservativeRasterizationMode(m) => (t.cmd_set_conservative_rasterization_mode_ext)(cb, *m),
            ExtState::ExtraPrimitiveOverestimationSize(s) => (t.cmd_set_extra_primitive_overestimation_size_ext)(cb, *s),
            ExtState::DepthClipEnable(v) => (t.cmd_set_depth_clip_enable_ext)(cb, b(*v)),
            ExtState::SampleLocationsEnable(v) => (t.cmd_set_sample_locations_enable_ext)(cb, b(*v)),
            ExtState::ProvokingVertexMode(m) => (t.cmd_set_provoking_vertex_mode_ext)(cb, *m),
            ExtState::LineRasterizationMode(m) => (t.cmd_set_line_rasterization_mode_ext)(cb, *m),
            ExtState::LineStippleEnable(v) => (t.cmd_set_line_stipple_enable_ext)(cb, b(*v)),
            ExtState::DepthClipNegativeOneToOne(v) => (t.cmd_set_depth_clip_negative_one_to_one_ext)(cb, b(*v)),
            ExtState::VertexInput { .. } => {}
        }
    }
}
