//! The command-recording hooks: command buffer begin / reset / execute, state the injection must
//! restore (pipelines, dynamic state, push constants, vertex buffers), render pass instances
//! (raising the features' begin events and the injection triggers), transfers and depth clears.
//! Extended dynamic state 3, vertex input, shader objects and the commands that veto injections
//! are in `dyn_state`.

use crate::plugin::vk::inject::Trigger;
use crate::plugin::vk::{convert, lifetime, DeviceState};
use super::{cmd, hook, hook_decided, state};
use crate::core::rect::PixelRect;
use crate::track::cmd::{PassKind, StateCmd};
use crate::track::eye_pass::TransferRegion;
use ash::vk::{self, Handle};
use std::ffi::c_void;

pub(in crate::vk) unsafe extern "system" fn begin_command_buffer(cb: vk::CommandBuffer, info: *const vk::CommandBufferBeginInfo<'_>) -> vk::Result {
    hook(
        "vkBeginCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().begin_command_buffer)(cb, info) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // Not pending (re-recording requires it): the layer's secondaries in it are free,
                // and its previous recording's holds go once its submissions are known complete.
                crate::plugin::vk::secondary::release(d, &[cb.as_raw()]);
                lifetime::close(d, &[cb.as_raw()]);
                // The data-flow walk is fed while anything injects (decided per recording).
                let flow = crate::vk::chassis::any_injects(d, &d.settings());
                // SAFETY: a valid begin info.
                d.track.begin_command_buffer(cb.as_raw(), unsafe { (*info).flags }, flow);
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn reset_command_buffer(cb: vk::CommandBuffer, flags: vk::CommandBufferResetFlags) -> vk::Result {
    hook(
        "vkResetCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().reset_command_buffer)(cb, flags) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                crate::plugin::vk::secondary::release(d, &[cb.as_raw()]);
                lifetime::close(d, &[cb.as_raw()]);
                d.track.with_cb(cb.as_raw(), |s| s.reset());
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_execute_commands(cb: vk::CommandBuffer, n: u32, cbs: *const vk::CommandBuffer) {
    hook_decided(
        "vkCmdExecuteCommands",
        cb,
        (),
        // An eye pass with secondary contents: the layer's draws, in its own secondary.
        |d| crate::vk::chassis::on_execute_commands(d, cb),
        |d, ours| {
            let execute = d.fns.fp_v1_0().cmd_execute_commands;
            if let Some(Some(ours)) = ours {
                let mut all = vec![*ours];
                // SAFETY: `n` app handles, valid during its call.
                all.extend_from_slice(unsafe { convert::slice(cbs, n) });
                // SAFETY: the app's secondaries behind the layer's, which inherits the same pass.
                return unsafe { execute(cb, all.len() as u32, all.as_ptr()) };
            }
            // SAFETY: forwarding the app's arguments unchanged.
            unsafe { execute(cb, n, cbs) }
        },
        |d, ()| {
            // The secondaries' reads and writes happen here, for the data-flow walk.
            // SAFETY: `n` app handles, valid during its call.
            let secondaries = unsafe { convert::slice(cbs, n) };
            let recorded: Vec<_> = secondaries.iter().filter_map(|s| d.track.with_cb(s.as_raw(), |st| st.flow.clone())).collect();
            d.track.with_cb(cb.as_raw(), |s| {
                if s.flow_on {
                    for r in &recorded {
                        s.flow.execute(r);
                    }
                }
                s.forget_graphics_state()
            });
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_bind_pipeline(cb: vk::CommandBuffer, bind_point: vk::PipelineBindPoint, pipeline: vk::Pipeline) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindPipeline", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_pipeline)(cb, bind_point, pipeline) }, |d, cb| {
        if bind_point == vk::PipelineBindPoint::GRAPHICS {
            d.track.bind_graphics_pipeline(cb, pipeline.as_raw());
        } else if bind_point == vk::PipelineBindPoint::COMPUTE {
            d.track.with_cb(cb, |s| {
                s.compute.pipeline = Some(pipeline.as_raw());
                s.compute.shader = None;
            });
        }
    })
}

pub(in crate::vk) unsafe extern "system" fn cmd_push_constants(
    cb: vk::CommandBuffer,
    layout: vk::PipelineLayout,
    stages: vk::ShaderStageFlags,
    offset: u32,
    size: u32,
    values: *const c_void,
) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdPushConstants", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_push_constants)(cb, layout, stages, offset, size, values) }, |d, cb| {
        // SAFETY: `values` holds `size` bytes during the app's call.
        state(d, cb, unsafe { convert::push_constants(layout, stages, offset, size, values) })
    })
}

#[allow(clippy::too_many_arguments)]
pub(in crate::vk) unsafe extern "system" fn cmd_bind_descriptor_sets(
    cb: vk::CommandBuffer,
    bind_point: vk::PipelineBindPoint,
    layout: vk::PipelineLayout,
    first: u32,
    n: u32,
    sets: *const vk::DescriptorSet,
    n_dynamic: u32,
    dynamic_offsets: *const u32,
) {
    cmd(
        "vkCmdBindDescriptorSets",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_bind_descriptor_sets)(cb, bind_point, layout, first, n, sets, n_dynamic, dynamic_offsets) },
        |d, cb| {
            if bind_point == vk::PipelineBindPoint::GRAPHICS || bind_point == vk::PipelineBindPoint::COMPUTE {
                // SAFETY: arrays valid with their counts during the app's call.
                let (sets, dynamic_offsets) = unsafe { (convert::slice(sets, n), convert::slice(dynamic_offsets, n_dynamic)) };
                let sets = sets.iter().map(|s| s.as_raw()).collect();
                let bind = StateCmd::BindDescriptorSets { layout: layout.as_raw(), first, sets, dynamic_offsets: dynamic_offsets.to_vec() };
                if bind_point == vk::PipelineBindPoint::GRAPHICS {
                    state(d, cb, bind)
                } else {
                    d.track.with_cb(cb, |s| s.compute.bind_sets(bind));
                }
            }
        },
    )
}

/// Hooks for dynamic-state commands: call down unchanged, record one `StateCmd`.
macro_rules! state_hook {
    ($name:ident, $call:literal, ($cb:ident, $($arg:ident : $ty:ty),*), |$d:ident| $next:expr, $cmd:expr) => {
        // Only some commands read app memory while recording; the shared `unsafe` covers those.
        #[allow(unused_unsafe)]
        pub(in crate::vk) unsafe extern "system" fn $name($cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                $cb,
                (),
                // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                |$d| unsafe { $next },
                // SAFETY: array arguments are valid with their counts during the app's call.
                |d, cb| state(d, cb, unsafe { $cmd }),
            )
        }
    };
}

state_hook!(cmd_set_viewport, "vkCmdSetViewport", (cb, first: u32, n: u32, p: *const vk::Viewport), |d| (d.fns.fp_v1_0().cmd_set_viewport)(cb, first, n, p),
    StateCmd::SetViewport { first, viewports: convert::slice(p, n).iter().map(convert::viewport).collect() });
state_hook!(cmd_set_scissor, "vkCmdSetScissor", (cb, first: u32, n: u32, p: *const vk::Rect2D), |d| (d.fns.fp_v1_0().cmd_set_scissor)(cb, first, n, p),
    StateCmd::SetScissor { first, scissors: convert::slice(p, n).iter().map(convert::rect).collect() });
state_hook!(cmd_set_viewport_with_count, "vkCmdSetViewportWithCount", (cb, n: u32, p: *const vk::Viewport), |d| (d.fns.fp_v1_3().cmd_set_viewport_with_count)(cb, n, p),
    StateCmd::SetViewportWithCount(convert::slice(p, n).iter().map(convert::viewport).collect()));
state_hook!(cmd_set_scissor_with_count, "vkCmdSetScissorWithCount", (cb, n: u32, p: *const vk::Rect2D), |d| (d.fns.fp_v1_3().cmd_set_scissor_with_count)(cb, n, p),
    StateCmd::SetScissorWithCount(convert::slice(p, n).iter().map(convert::rect).collect()));
state_hook!(cmd_set_line_width, "vkCmdSetLineWidth", (cb, w: f32), |d| (d.fns.fp_v1_0().cmd_set_line_width)(cb, w), StateCmd::LineWidth(w));
state_hook!(cmd_set_depth_bias, "vkCmdSetDepthBias", (cb, c: f32, clamp: f32, s: f32), |d| (d.fns.fp_v1_0().cmd_set_depth_bias)(cb, c, clamp, s),
    StateCmd::DepthBias { constant_factor: c, clamp, slope_factor: s });
state_hook!(cmd_set_blend_constants, "vkCmdSetBlendConstants", (cb, c: *const [f32; 4]), |d| (d.fns.fp_v1_0().cmd_set_blend_constants)(cb, c),
    StateCmd::BlendConstants(*c));
state_hook!(cmd_set_depth_bounds, "vkCmdSetDepthBounds", (cb, min: f32, max: f32), |d| (d.fns.fp_v1_0().cmd_set_depth_bounds)(cb, min, max),
    StateCmd::DepthBounds { min, max });
state_hook!(cmd_set_stencil_compare_mask, "vkCmdSetStencilCompareMask", (cb, face: vk::StencilFaceFlags, mask: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_compare_mask)(cb, face, mask), StateCmd::StencilCompareMask { face, mask });
state_hook!(cmd_set_stencil_write_mask, "vkCmdSetStencilWriteMask", (cb, face: vk::StencilFaceFlags, mask: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_write_mask)(cb, face, mask), StateCmd::StencilWriteMask { face, mask });
state_hook!(cmd_set_stencil_reference, "vkCmdSetStencilReference", (cb, face: vk::StencilFaceFlags, reference: u32),
    |d| (d.fns.fp_v1_0().cmd_set_stencil_reference)(cb, face, reference), StateCmd::StencilReference { face, reference });
state_hook!(cmd_set_cull_mode, "vkCmdSetCullMode", (cb, m: vk::CullModeFlags), |d| (d.fns.fp_v1_3().cmd_set_cull_mode)(cb, m), StateCmd::CullMode(m));
state_hook!(cmd_set_front_face, "vkCmdSetFrontFace", (cb, f: vk::FrontFace), |d| (d.fns.fp_v1_3().cmd_set_front_face)(cb, f), StateCmd::FrontFace(f));
state_hook!(cmd_set_primitive_topology, "vkCmdSetPrimitiveTopology", (cb, t: vk::PrimitiveTopology),
    |d| (d.fns.fp_v1_3().cmd_set_primitive_topology)(cb, t), StateCmd::PrimitiveTopology(t));
state_hook!(cmd_set_depth_test_enable, "vkCmdSetDepthTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_test_enable)(cb, e), StateCmd::DepthTestEnable(e != 0));
state_hook!(cmd_set_depth_write_enable, "vkCmdSetDepthWriteEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_write_enable)(cb, e), StateCmd::DepthWriteEnable(e != 0));
state_hook!(cmd_set_depth_compare_op, "vkCmdSetDepthCompareOp", (cb, op: vk::CompareOp),
    |d| (d.fns.fp_v1_3().cmd_set_depth_compare_op)(cb, op), StateCmd::DepthCompareOp(op));
state_hook!(cmd_set_depth_bounds_test_enable, "vkCmdSetDepthBoundsTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_bounds_test_enable)(cb, e), StateCmd::DepthBoundsTestEnable(e != 0));
state_hook!(cmd_set_stencil_test_enable, "vkCmdSetStencilTestEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_stencil_test_enable)(cb, e), StateCmd::StencilTestEnable(e != 0));
state_hook!(cmd_set_stencil_op, "vkCmdSetStencilOp",
    (cb, face: vk::StencilFaceFlags, fail_op: vk::StencilOp, pass_op: vk::StencilOp, depth_fail_op: vk::StencilOp, compare_op: vk::CompareOp),
    |d| (d.fns.fp_v1_3().cmd_set_stencil_op)(cb, face, fail_op, pass_op, depth_fail_op, compare_op),
    StateCmd::StencilOp { face, fail_op, pass_op, depth_fail_op, compare_op });
state_hook!(cmd_set_rasterizer_discard_enable, "vkCmdSetRasterizerDiscardEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_rasterizer_discard_enable)(cb, e), StateCmd::RasterizerDiscardEnable(e != 0));
state_hook!(cmd_set_depth_bias_enable, "vkCmdSetDepthBiasEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_depth_bias_enable)(cb, e), StateCmd::DepthBiasEnable(e != 0));
state_hook!(cmd_set_primitive_restart_enable, "vkCmdSetPrimitiveRestartEnable", (cb, e: vk::Bool32),
    |d| (d.fns.fp_v1_3().cmd_set_primitive_restart_enable)(cb, e), StateCmd::PrimitiveRestartEnable(e != 0));

/// Extension-only commands: the hook is handed out only when the next layer has the command, so
/// the `Option` is always `Some` when these run.
macro_rules! ext_state_hook {
    ($name:ident, $call:literal, $field:ident, ($($arg:ident : $ty:ty),*), $cmd:expr) => {
        // Only some commands read app memory while recording; the shared `unsafe` covers those.
        #[allow(unused_unsafe)]
        pub(in crate::vk) unsafe extern "system" fn $name(cb: vk::CommandBuffer, $($arg: $ty),*) {
            cmd(
                $call,
                cb,
                (),
                |d| {
                    if let Some(f) = d.ext.$field {
                        // SAFETY: forwarding the app's arguments unchanged to the next layer's command.
                        unsafe { f(cb, $($arg),*) }
                    }
                },
                // SAFETY: array arguments are valid with their counts during the app's call.
                |d, cb| state(d, cb, unsafe { $cmd }),
            )
        }
    };
}

ext_state_hook!(cmd_set_line_stipple, "vkCmdSetLineStippleEXT", cmd_set_line_stipple, (factor: u32, pattern: u16), StateCmd::LineStipple { factor, pattern });
ext_state_hook!(cmd_set_color_write_enable, "vkCmdSetColorWriteEnableEXT", cmd_set_color_write_enable, (n: u32, p: *const vk::Bool32),
    StateCmd::ColorWriteEnable(convert::slice(p, n).iter().map(|&b| b != 0).collect()));
ext_state_hook!(cmd_set_logic_op, "vkCmdSetLogicOpEXT", cmd_set_logic_op, (op: vk::LogicOp), StateCmd::LogicOp(op));
ext_state_hook!(cmd_set_patch_control_points, "vkCmdSetPatchControlPointsEXT", cmd_set_patch_control_points, (n: u32), StateCmd::PatchControlPoints(n));

// ---------------------------------------------------------------------------------------------
// Render pass instances

fn begin_pass(d: &DeviceState, cb: u64, kind: PassKind, info: *const vk::RenderPassBeginInfo<'_>) {
    // SAFETY: a valid begin info during the app's call.
    let begin = unsafe { convert::render_pass_begin(&*info) };
    d.track.begin_render_pass(crate::bridge::shared(), cb, kind, begin);
}

/// `vkCmdBeginRenderPass` and `vkCmdBeginRenderPass2` alike: the features may amend the app's
/// begin info (the first that amends wins); `down` makes the call with the info it is given (the
/// amended copy, or the app's own), and the pass is tracked and triggers the chassis after it.
///
/// # Safety
/// `info` is the app's valid begin info and `cb` is recording outside a pass (it is about to
/// begin one), for the duration of the call.
unsafe fn begin_render_pass(call: &'static str, cb: vk::CommandBuffer, info: *const vk::RenderPassBeginInfo<'_>, kind: PassKind, secondary: bool, down: impl Fn(&DeviceState, *const vk::RenderPassBeginInfo<'_>)) {
    hook_decided(
        call,
        cb,
        (),
        // SAFETY: per this function's contract.
        |d| d.features.all().iter().find_map(|f| unsafe { f.amend_render_pass_begin(d, cb, kind, info) }),
        |d, decided| match decided {
            Some(Some(v)) => down(d, &v.info),
            _ => down(d, info),
        },
        |d, _| {
            begin_pass(d, cb.as_raw(), kind, info);
            pass_begun(d, cb, secondary);
            crate::vk::chassis::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_begin_render_pass(cb: vk::CommandBuffer, info: *const vk::RenderPassBeginInfo<'_>, contents: vk::SubpassContents) {
    let secondary = contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS;
    // SAFETY: the app's arguments, valid during its call; `down` passes the app's info or the
    // feature's amended copy of it, with the app's other arguments unchanged.
    unsafe { begin_render_pass("vkCmdBeginRenderPass", cb, info, PassKind::RenderPass, secondary, |d, i| (d.fns.fp_v1_0().cmd_begin_render_pass)(cb, i, contents)) }
}

pub(in crate::vk) unsafe extern "system" fn cmd_next_subpass(cb: vk::CommandBuffer, contents: vk::SubpassContents) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_next_subpass)(cb, contents) }, |d, raw| {
        d.track.next_subpass(raw);
        crate::vk::chassis::on_trigger(d, cb, Trigger::NextSubpass { secondary: contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS });
    })
}

pub(in crate::vk) unsafe extern "system" fn cmd_end_render_pass(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    end_pass("vkCmdEndRenderPass", cb, |d| unsafe { (d.fns.fp_v1_0().cmd_end_render_pass)(cb) })
}

pub(in crate::vk) unsafe extern "system" fn cmd_begin_render_pass2(
    cb: vk::CommandBuffer,
    info: *const vk::RenderPassBeginInfo<'_>,
    subpass_info: *const vk::SubpassBeginInfo<'_>,
) {
    // SAFETY: as `cmd_begin_render_pass`; the subpass begin info goes down unchanged.
    unsafe {
        begin_render_pass("vkCmdBeginRenderPass2", cb, info, PassKind::RenderPass2, secondary_contents(subpass_info), |d, i| (d.fns.fp_v1_2().cmd_begin_render_pass2)(cb, i, subpass_info))
    }
}

pub(in crate::vk) unsafe extern "system" fn cmd_next_subpass2(cb: vk::CommandBuffer, begin: *const vk::SubpassBeginInfo<'_>, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass2", cb, (), |d| unsafe { (d.fns.fp_v1_2().cmd_next_subpass2)(cb, begin, end) }, |d, raw| {
        d.track.next_subpass(raw);
        crate::vk::chassis::on_trigger(d, cb, Trigger::NextSubpass { secondary: secondary_contents(begin) });
    })
}

pub(in crate::vk) unsafe extern "system" fn cmd_end_render_pass2(cb: vk::CommandBuffer, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    end_pass("vkCmdEndRenderPass2", cb, |d| unsafe { (d.fns.fp_v1_2().cmd_end_render_pass2)(cb, end) })
}

pub(in crate::vk) unsafe extern "system" fn cmd_begin_rendering(cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) {
    // SAFETY: the app's rendering info, valid during its call (which outlives `kept`).
    let kept = if super::super::device_of(cb).is_some_and(|d| crate::plugin::vk::keep_depth::wanted(&d)) { unsafe { crate::plugin::vk::keep_depth::rendering(info) } } else { None };
    let info = kept.as_ref().map_or(info, |k| &k.info as *const _);
    hook_decided(
        "vkCmdBeginRendering",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| d.features.all().iter().find_map(|f| unsafe { f.amend_rendering(d, cb, info) }),
        |d, decided| {
            let begin = d.fns.fp_v1_3().cmd_begin_rendering;
            match decided {
                // SAFETY: the app's info with only the feature's additions.
                Some(Some(v)) => unsafe { begin(cb, &v.info) },
                // SAFETY: the app's arguments (depth kept when a feature reads it).
                _ => unsafe { begin(cb, info) },
            }
        },
        |d, _| {
            let raw = cb.as_raw();
            // SAFETY: a valid rendering info during the app's call.
            let (area, rendering) = unsafe { convert::rendering(&d.track, &*info) };
            let secondary = rendering.flags.contains(vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS);
            d.track.begin_rendering(raw, area, rendering);
            crate::vk::chassis::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_end_rendering(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    end_pass("vkCmdEndRendering", cb, |d| unsafe { (d.fns.fp_v1_3().cmd_end_rendering)(cb) })
}

fn secondary_contents(info: *const vk::SubpassBeginInfo<'_>) -> bool {
    // SAFETY: null or a valid struct during the app's call.
    unsafe { info.as_ref() }.is_some_and(|i| i.contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS)
}

// ---------------------------------------------------------------------------------------------
// Vertex buffers (restored after a mask draw), transfers (intermediate eye targets), clears

pub(in crate::vk) unsafe extern "system" fn cmd_bind_vertex_buffers(cb: vk::CommandBuffer, first: u32, n: u32, buffers: *const vk::Buffer, offsets: *const vk::DeviceSize) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindVertexBuffers", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_vertex_buffers)(cb, first, n, buffers, offsets) }, |d, cb| {
        // SAFETY: arrays valid with their counts during the app's call.
        let bindings = unsafe { convert::vertex_bindings(n, buffers, offsets, std::ptr::null(), std::ptr::null(), false) };
        state(d, cb, StateCmd::BindVertexBuffers { first, bindings })
    })
}

pub(in crate::vk) unsafe extern "system" fn cmd_bind_vertex_buffers2(
    cb: vk::CommandBuffer,
    first: u32,
    n: u32,
    buffers: *const vk::Buffer,
    offsets: *const vk::DeviceSize,
    sizes: *const vk::DeviceSize,
    strides: *const vk::DeviceSize,
) {
    cmd(
        "vkCmdBindVertexBuffers2",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_3().cmd_bind_vertex_buffers2)(cb, first, n, buffers, offsets, sizes, strides) },
        |d, cb| {
            // SAFETY: arrays valid with their counts (optional ones null) during the app's call.
            let bindings = unsafe { convert::vertex_bindings(n, buffers, offsets, sizes, strides, true) };
            state(d, cb, StateCmd::BindVertexBuffers { first, bindings })
        },
    )
}

/// A copy / resolve / blit: learned for intermediate eye targets while anything injects, and
/// raised to the features.
fn transfer(d: &DeviceState, cb: vk::CommandBuffer, src: vk::Image, dst: vk::Image, regions: Vec<TransferRegion>) {
    if crate::vk::chassis::any_injects(d, &d.settings()) {
        d.track.record_transfer(crate::bridge::shared(), src.as_raw(), dst.as_raw(), &regions);
    }
    d.track.flow_transfer(cb.as_raw(), src.as_raw(), dst.as_raw(), &regions);
    for f in d.features.all() {
        f.transfer(d, cb, src.as_raw(), dst.as_raw(), &regions);
    }
}

/// The three pass ends: `pass_ending` before the end goes down, then the end trigger, the tracked
/// pass closed and `pass_ended`.
fn end_pass(call: &'static str, cb: vk::CommandBuffer, next: impl Fn(&DeviceState)) {
    hook_decided(call, cb, (), |d| pass_ending(d, cb), |d, _| next(d), |d, ()| {
        crate::vk::chassis::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(cb.as_raw());
        pass_ended(d, cb);
        Ok(())
    })
}

/// Raises `pass_ending` over the features: the pass is still open in `cb` (the end goes down next).
fn pass_ending(d: &DeviceState, cb: vk::CommandBuffer) {
    for f in d.features.all() {
        f.pass_ending(d, cb);
    }
}

/// Raises `pass_ended` over the features.
fn pass_ended(d: &DeviceState, cb: vk::CommandBuffer) {
    for f in d.features.all() {
        f.pass_ended(d, cb);
    }
}

/// Raises `pass_begun` over the features.
fn pass_begun(d: &DeviceState, cb: vk::CommandBuffer, secondary: bool) {
    for f in d.features.all() {
        f.pass_begun(d, cb, secondary);
    }
}

/// A region of any version of the copy, resolve and blit commands, as the trackers take it (a
/// blit that mirrors or has no area gives none).
trait Region {
    fn region(&self) -> Option<TransferRegion>;
}

/// Copies and resolves (both versions) have the same fields; this makes the one `ImageCopy` the
/// conversion reads.
macro_rules! copy_like_region {
    ($($ty:ty),*) => {$(
        impl Region for $ty {
            fn region(&self) -> Option<TransferRegion> {
                let r = self;
                Some(convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
            }
        }
    )*};
}
copy_like_region!(vk::ImageCopy, vk::ImageCopy2<'_>, vk::ImageResolve, vk::ImageResolve2<'_>);

impl Region for vk::ImageBlit {
    fn region(&self) -> Option<TransferRegion> {
        convert::blit_region(self.src_subresource, self.src_offsets, self.dst_subresource, self.dst_offsets)
    }
}

impl Region for vk::ImageBlit2<'_> {
    fn region(&self) -> Option<TransferRegion> {
        convert::blit_region(self.src_subresource, self.src_offsets, self.dst_subresource, self.dst_offsets)
    }
}

/// The `VkCopyImageInfo2` family: the images and the regions of a version-2 transfer.
trait Info2 {
    type Region: Region;
    fn images(&self) -> (vk::Image, vk::Image);
    /// # Safety
    /// `self` is the app's valid info, with a valid region array.
    unsafe fn regions(&self) -> &[Self::Region];
}

macro_rules! info2 {
    ($($info:ident => $region:ident),*) => {$(
        impl<'a> Info2 for vk::$info<'a> {
            type Region = vk::$region<'a>;
            fn images(&self) -> (vk::Image, vk::Image) {
                (self.src_image, self.dst_image)
            }
            unsafe fn regions(&self) -> &[vk::$region<'a>] {
                // SAFETY: per the contract.
                unsafe { convert::slice(self.p_regions, self.region_count) }
            }
        }
    )*};
}
info2!(CopyImageInfo2 => ImageCopy2, ResolveImageInfo2 => ImageResolve2, BlitImageInfo2 => ImageBlit2);

/// The version-1 transfer hooks after the call went down: `n` regions at `regions`.
///
/// # Safety
/// `regions` is the app's valid array of `n` regions.
unsafe fn transferred<R: Region>(d: &DeviceState, cb: vk::CommandBuffer, src: vk::Image, dst: vk::Image, regions: *const R, n: u32) {
    // SAFETY: per the contract.
    let regions = unsafe { convert::slice(regions, n) }.iter().filter_map(Region::region).collect();
    transfer(d, cb, src, dst, regions)
}

/// `vkCmdCopyImage2`, `vkCmdResolveImage2` and `vkCmdBlitImage2` alike: the call goes down
/// unchanged, then the transfer is tracked.
///
/// # Safety
/// `info` is the app's valid info, valid during the call.
unsafe fn transfer2<I: Info2>(call: &'static str, cb: vk::CommandBuffer, info: *const I, down: impl Fn(&DeviceState)) {
    cmd(call, cb, (), down, |d, _| {
        // SAFETY: a valid info with a valid region array (the contract).
        let (i, regions) = unsafe { (&*info, (*info).regions()) };
        let (src, dst) = i.images();
        transfer(d, cb, src, dst, regions.iter().filter_map(Region::region).collect())
    })
}

pub(in crate::vk) unsafe extern "system" fn cmd_copy_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageCopy,
) {
    cmd(
        "vkCmdCopyImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_copy_image)(cb, src, src_layout, dst, dst_layout, n, regions) },
        // SAFETY: the region array is valid with its count.
        |d, _| unsafe { transferred(d, cb, src, dst, regions, n) },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_copy_image2(cb: vk::CommandBuffer, info: *const vk::CopyImageInfo2<'_>) {
    // SAFETY: forwarding the app's valid info unchanged.
    unsafe { transfer2("vkCmdCopyImage2", cb, info, |d| (d.fns.fp_v1_3().cmd_copy_image2)(cb, info)) }
}

pub(in crate::vk) unsafe extern "system" fn cmd_resolve_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageResolve,
) {
    cmd(
        "vkCmdResolveImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_resolve_image)(cb, src, src_layout, dst, dst_layout, n, regions) },
        // SAFETY: the region array is valid with its count.
        |d, _| unsafe { transferred(d, cb, src, dst, regions, n) },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_resolve_image2(cb: vk::CommandBuffer, info: *const vk::ResolveImageInfo2<'_>) {
    // SAFETY: forwarding the app's valid info unchanged.
    unsafe { transfer2("vkCmdResolveImage2", cb, info, |d| (d.fns.fp_v1_3().cmd_resolve_image2)(cb, info)) }
}

#[allow(clippy::too_many_arguments)]
pub(in crate::vk) unsafe extern "system" fn cmd_blit_image(
    cb: vk::CommandBuffer,
    src: vk::Image,
    src_layout: vk::ImageLayout,
    dst: vk::Image,
    dst_layout: vk::ImageLayout,
    n: u32,
    regions: *const vk::ImageBlit,
    filter: vk::Filter,
) {
    cmd(
        "vkCmdBlitImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_blit_image)(cb, src, src_layout, dst, dst_layout, n, regions, filter) },
        // SAFETY: the region array is valid with its count.
        |d, _| unsafe { transferred(d, cb, src, dst, regions, n) },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_blit_image2(cb: vk::CommandBuffer, info: *const vk::BlitImageInfo2<'_>) {
    // SAFETY: forwarding the app's valid info unchanged.
    unsafe { transfer2("vkCmdBlitImage2", cb, info, |d| (d.fns.fp_v1_3().cmd_blit_image2)(cb, info)) }
}

pub(in crate::vk) unsafe extern "system" fn cmd_clear_attachments(
    cb: vk::CommandBuffer,
    n: u32,
    attachments: *const vk::ClearAttachment,
    rect_count: u32,
    rects: *const vk::ClearRect,
) {
    cmd(
        "vkCmdClearAttachments",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_clear_attachments)(cb, n, attachments, rect_count, rects) },
        |d, _| {
            if !crate::vk::chassis::any_injects(d, &d.settings()) {
                return;
            }
            // SAFETY: arrays valid with their counts during the app's call.
            let (atts, rects) = unsafe { (convert::slice(attachments, n), convert::slice(rects, rect_count)) };
            let depth = atts.iter().find(|a| a.aspect_mask.contains(vk::ImageAspectFlags::DEPTH));
            if let Some(a) = depth {
                d.track.with_cb(cb.as_raw(), |s| s.flow.depth_cleared());
                // SAFETY: a depth clear's value is the depthStencil member.
                let value = unsafe { a.clear_value.depth_stencil.depth };
                let rects = rects.iter().map(|r| PixelRect { x: r.rect.offset.x, y: r.rect.offset.y, width: r.rect.extent.width, height: r.rect.extent.height }).collect();
                crate::vk::chassis::on_trigger(d, cb, Trigger::Clear { depth: value, rects });
            }
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn cmd_clear_depth_stencil_image(
    cb: vk::CommandBuffer,
    image: vk::Image,
    layout: vk::ImageLayout,
    value: *const vk::ClearDepthStencilValue,
    n: u32,
    ranges: *const vk::ImageSubresourceRange,
) {
    cmd(
        "vkCmdClearDepthStencilImage",
        cb,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().cmd_clear_depth_stencil_image)(cb, image, layout, value, n, ranges) },
        |d, raw| {
            if !crate::vk::chassis::any_injects(d, &d.settings()) {
                return;
            }
            // SAFETY: valid pointers during the app's call.
            let (value, ranges) = unsafe { ((*value).depth, convert::slice(ranges, n)) };
            if ranges.iter().any(|r| r.aspect_mask.contains(vk::ImageAspectFlags::DEPTH)) {
                d.track.with_cb(raw, |s| {
                    s.depth_image_clears.retain(|(i, _)| *i != image.as_raw());
                    if s.depth_image_clears.len() < 64 {
                        s.depth_image_clears.push((image.as_raw(), value));
                    }
                });
            }
        },
    )
}
