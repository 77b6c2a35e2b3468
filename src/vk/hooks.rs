//! The intercepted commands. Every hook runs the same prologue (`hook`): find the device state by
//! dispatch key, open a span, then *decide → call down → record* inside `guard::run`, so a fault
//! in layer logic turns the instance to pass-through and the app still gets the driver's result.
//! With all features off no hook changes what reaches the driver (instance and device creation,
//! which may, live in `chain`).

use super::mask::{self, Trigger};
use super::{convert, device_of, DeviceState};
use crate::guard::{self, Fault};
use crate::track::cmd::{PassKind, StateCmd};
use ash::vk::{self, Handle};
use std::ffi::c_void;
use std::sync::Arc;

/// The prologue shared by all device-level hooks. `next` is the plain call down; `record` runs
/// after it with its result (and must itself check for success before recording).
fn hook<H: Handle + Copy, R: Copy>(
    call: &'static str,
    handle: H,
    unknown: R,
    next: impl Fn(&DeviceState) -> R,
    record: impl FnOnce(&DeviceState, R) -> Result<(), Fault>,
) -> R {
    hook_decided(call, handle, unknown, |_| (), |dev, _| next(dev), record)
}

/// Like `hook`, for calls whose arguments the layer may change: `decide` runs first (layered path
/// only) and `next` calls down with its decision (None: the app's arguments, unchanged).
fn hook_decided<H: Handle + Copy, R: Copy, D>(
    call: &'static str,
    handle: H,
    unknown: R,
    decide: impl FnOnce(&DeviceState) -> D,
    next: impl Fn(&DeviceState, Option<&D>) -> R,
    record: impl FnOnce(&DeviceState, R) -> Result<(), Fault>,
) -> R {
    let Some(dev) = device_of(handle) else {
        // No dispatch table: there is nothing to call down to.
        return unknown;
    };
    let span = if call.starts_with("vkCmd") {
        tracing::trace_span!("vk", call)
    } else {
        tracing::debug_span!("vk", call)
    };
    let _entered = span.entered();
    guard::run(
        call,
        &dev.pass_through,
        |down| {
            dev.check(call)?;
            let decision = decide(&dev);
            let r = down.call(|| next(&dev, Some(&decision)));
            record(&dev, r)?;
            Ok(r)
        },
        || next(&dev, None),
    )
}

/// Command-buffer hooks that only record state.
fn cmd<R: Copy>(call: &'static str, cb: vk::CommandBuffer, unknown: R, next: impl Fn(&DeviceState) -> R, record: impl FnOnce(&DeviceState, u64)) -> R {
    hook(call, cb, unknown, next, |dev, _| {
        record(dev, cb.as_raw());
        Ok(())
    })
}

fn state(dev: &DeviceState, cb: u64, c: StateCmd) {
    dev.track.with_cb(cb, |s| s.record(c));
}


// ---------------------------------------------------------------------------------------------
// Resources

/// Creation hooks: record `make(handle)` only when the call down succeeded.
macro_rules! create_hook {
    ($name:ident, $call:literal, $info:ty, $handle:ty, $fp:ident . $f:ident, $map:ident, |$h:ident, $ci:ident| $make:expr) => {
        pub(super) unsafe extern "system" fn $name(
            device: vk::Device,
            ci: *const $info,
            allocator: *const vk::AllocationCallbacks<'_>,
            out: *mut $handle,
        ) -> vk::Result {
            hook(
                $call,
                device,
                vk::Result::ERROR_INITIALIZATION_FAILED,
                // SAFETY: forwarding the app's arguments unchanged.
                |d| unsafe { (d.fns.$fp().$f)(device, ci, allocator, out) },
                |d, r| {
                    if r == vk::Result::SUCCESS {
                        // SAFETY: on success the handle was written; the create info is valid
                        // during the app's call.
                        let ($h, $ci) = unsafe { (*out, &*ci) };
                        d.track.$map.insert($h.as_raw(), Arc::new($make));
                    }
                    Ok(())
                },
            )
        }
    };
}

macro_rules! destroy_hook {
    ($name:ident, $call:literal, $handle:ty, $fp:ident . $f:ident, |$d:ident, $h:ident| $forget:expr) => {
        pub(super) unsafe extern "system" fn $name(device: vk::Device, handle: $handle, allocator: *const vk::AllocationCallbacks<'_>) {
            hook(
                $call,
                device,
                (),
                // SAFETY: forwarding the app's arguments unchanged.
                |d| unsafe { (d.fns.$fp().$f)(device, handle, allocator) },
                |$d, _| {
                    let $h = handle.as_raw();
                    $forget;
                    Ok(())
                },
            )
        }
    };
}

/// Like the other create hooks, and also notes the image for `swapchain_images`: a runtime creating
/// swapchain images inside `xrCreateSwapchain` is recognised by the handle seen here, whatever
/// layer above wraps it.
pub(super) unsafe extern "system" fn create_image(
    device: vk::Device,
    ci: *const vk::ImageCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Image,
) -> vk::Result {
    hook(
        "vkCreateImage",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().create_image)(device, ci, allocator, out) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                crate::swapchain_images::note_created(crate::swapchain_images::CreatedImage {
                    image: h.as_raw(),
                    format: ci.format.as_raw(),
                    width: ci.extent.width,
                    height: ci.extent.height,
                    array_layers: ci.array_layers,
                    samples: ci.samples.as_raw(),
                    mip_levels: ci.mip_levels,
                });
                d.track.images.insert(h.as_raw(), Arc::new(convert::image(h, ci)));
            }
            Ok(())
        },
    )
}
destroy_hook!(destroy_image, "vkDestroyImage", vk::Image, fp_v1_0.destroy_image, |d, h| {
    d.track.forget_image(h);
    super::rdm::forget_image(d, h)
});
create_hook!(create_image_view, "vkCreateImageView", vk::ImageViewCreateInfo<'_>, vk::ImageView, fp_v1_0.create_image_view, views, |h, ci| convert::image_view(h, ci));
destroy_hook!(destroy_image_view, "vkDestroyImageView", vk::ImageView, fp_v1_0.destroy_image_view, |d, h| d.track.views.remove(h));
/// `vkCreateRenderPass` / `vkCreateRenderPass2(KHR)`: with variable-rate shading's attachment
/// appended where the layer enabled attachment rates (`vk::vrs`; v1 infos go down translated to
/// `vkCreateRenderPass2`); the tracked description is the app's, with the appended index.
fn create_render_pass_common(
    call: &'static str,
    device: vk::Device,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
    decide: impl FnOnce(&DeviceState) -> Option<super::vrs::RatePass>,
    app: impl Fn(&DeviceState) -> vk::Result,
    describe: impl FnOnce(vk::RenderPass) -> crate::track::resources::RenderPass,
) -> vk::Result {
    let appended = std::cell::Cell::new(None);
    hook_decided(
        call,
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        decide,
        |d, decided| {
            if let Some(Some(rp)) = decided {
                // SAFETY: the app's pass with only the rate attachment added (see `vk::vrs`), with
                // the app's allocator (the app destroys the pass).
                let r = unsafe { (d.fns.fp_v1_2().create_render_pass2)(device, &rp.info, allocator, out) };
                if r == vk::Result::SUCCESS {
                    appended.set(Some(rp.index));
                    return r;
                }
                tracing::warn!(?r, "{call} failed with the shading-rate attachment; retrying as the app asked");
            }
            appended.set(None);
            app(d)
        },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written.
                let h = unsafe { *out };
                let mut desc = describe(h);
                desc.layer_rate_attachment = appended.get();
                d.track.render_passes.insert(h.as_raw(), Arc::new(desc));
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn create_render_pass(
    device: vk::Device,
    ci: *const vk::RenderPassCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
) -> vk::Result {
    create_render_pass_common(
        "vkCreateRenderPass",
        device,
        allocator,
        out,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::render_pass_v1(d, ci) },
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().create_render_pass)(device, ci, allocator, out) },
        // SAFETY: the create info is valid during the app's call.
        |h| unsafe { convert::render_pass(h, &*ci) },
    )
}

pub(super) unsafe extern "system" fn create_render_pass2(
    device: vk::Device,
    ci: *const vk::RenderPassCreateInfo2<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
) -> vk::Result {
    create_render_pass_common(
        "vkCreateRenderPass2",
        device,
        allocator,
        out,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::render_pass_v2(d, ci) },
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_2().create_render_pass2)(device, ci, allocator, out) },
        // SAFETY: the create info is valid during the app's call.
        |h| unsafe { convert::render_pass2(h, &*ci) },
    )
}

destroy_hook!(destroy_render_pass, "vkDestroyRenderPass", vk::RenderPass, fp_v1_0.destroy_render_pass, |d, h| {
    d.track.render_passes.remove(h);
    super::mask::forget_render_pass(d, h)
});
/// `vkCreateFramebuffer`: a framebuffer of a pass with variable-rate shading's attachment gets
/// the layer's rate image as that attachment (`vk::vrs`); tracked as the app described it.
pub(super) unsafe extern "system" fn create_framebuffer(
    device: vk::Device,
    ci: *const vk::FramebufferCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Framebuffer,
) -> vk::Result {
    let pending = std::cell::Cell::new(None);
    hook_decided(
        "vkCreateFramebuffer",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's info, valid during its call; the copies live in the decision.
        |d| match unsafe { super::vrs::framebuffer_info(d, ci) } {
            Ok(Some((info, rate))) => {
                pending.set(Some(rate));
                Some(info)
            }
            Ok(None) => None,
            Err(e) => {
                tracing::warn!("vrs rate image for a framebuffer: {e}");
                None
            }
        },
        |d, decided| match decided {
            // SAFETY: the app's info with only the rate attachment added.
            Some(Some(f)) => unsafe { (d.fns.fp_v1_0().create_framebuffer)(device, &f.info, allocator, out) },
            // SAFETY: forwarding the app's arguments unchanged.
            _ => unsafe { (d.fns.fp_v1_0().create_framebuffer)(device, ci, allocator, out) },
        },
        |d, r| {
            let ok = r == vk::Result::SUCCESS;
            if let Some(rate) = pending.take() {
                // SAFETY: on success the handle was written.
                super::vrs::framebuffer_created(d, ok.then(|| unsafe { *out }), rate);
            }
            if ok {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                // SAFETY: as above.
                d.track.framebuffers.insert(h.as_raw(), Arc::new(unsafe { convert::framebuffer(h, ci) }));
            }
            Ok(())
        },
    )
}
destroy_hook!(destroy_framebuffer, "vkDestroyFramebuffer", vk::Framebuffer, fp_v1_0.destroy_framebuffer, |d, h| {
    d.track.framebuffers.remove(h);
    super::vrs::forget_framebuffer(d, h)
});
destroy_hook!(destroy_pipeline, "vkDestroyPipeline", vk::Pipeline, fp_v1_0.destroy_pipeline, |d, h| d.track.pipelines.remove(h));
create_hook!(create_command_pool, "vkCreateCommandPool", vk::CommandPoolCreateInfo<'_>, vk::CommandPool, fp_v1_0.create_command_pool, pools, |h, ci| {
    crate::track::resources::CommandPool { handle: h.as_raw(), flags: ci.flags, queue_family_index: ci.queue_family_index }
});
destroy_hook!(destroy_command_pool, "vkDestroyCommandPool", vk::CommandPool, fp_v1_0.destroy_command_pool, |d, h| {
    super::secondary::release(d, &d.track.buffers_of_pool(h));
    d.track.destroy_pool(h)
});

pub(super) unsafe extern "system" fn create_graphics_pipelines(
    device: vk::Device,
    cache: vk::PipelineCache,
    count: u32,
    infos: *const vk::GraphicsPipelineCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Pipeline,
) -> vk::Result {
    hook_decided(
        "vkCreateGraphicsPipelines",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's infos, valid during its call; the copies live in the decision.
        |d| unsafe { super::vrs::pipeline_infos(d, infos, count) },
        |d, decided| {
            let create = d.fns.fp_v1_0().create_graphics_pipelines;
            if let Some(Some(m)) = decided.filter(|m| m.as_ref().is_some_and(|m| m.changed > 0)) {
                // SAFETY: the app's infos with only the shading-rate state added (see `vk::vrs`).
                let r = unsafe { create(device, cache, count, m.infos.as_ptr(), allocator, out) };
                if r == vk::Result::SUCCESS || r == vk::Result::PIPELINE_COMPILE_REQUIRED {
                    return r;
                }
                tracing::warn!(?r, "vkCreateGraphicsPipelines failed with the shading-rate state; retrying as the app asked");
            }
            // SAFETY: forwarding the app's arguments unchanged.
            unsafe { create(device, cache, count, infos, allocator, out) }
        },
        |d, r| {
            if r != vk::Result::SUCCESS {
                return Ok(());
            }
            // SAFETY: `count` infos and, on success, `count` written pipelines.
            let (infos, pipelines) = unsafe { (convert::slice(infos, count), convert::slice(out as *const vk::Pipeline, count)) };
            for (ci, &p) in infos.iter().zip(pipelines) {
                if p != vk::Pipeline::null() {
                    // SAFETY: the create info is valid during the app's call.
                    d.track.add_pipeline(unsafe { convert::graphics_pipeline(p, ci) });
                }
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn reset_command_pool(device: vk::Device, pool: vk::CommandPool, flags: vk::CommandPoolResetFlags) -> vk::Result {
    hook(
        "vkResetCommandPool",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().reset_command_pool)(device, pool, flags) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                super::secondary::release(d, &d.track.buffers_of_pool(pool.as_raw()));
                d.track.reset_pool(pool.as_raw());
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn allocate_command_buffers(
    device: vk::Device,
    info: *const vk::CommandBufferAllocateInfo<'_>,
    out: *mut vk::CommandBuffer,
) -> vk::Result {
    hook(
        "vkAllocateCommandBuffers",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().allocate_command_buffers)(device, info, out) },
        |d, r| {
            if r != vk::Result::SUCCESS {
                return Ok(());
            }
            // SAFETY: a valid allocate info; on success `count` buffers were written. They are
            // keyed by handle: their dispatch key is only set by the loader after we return.
            let (info, cbs) = unsafe { (&*info, convert::slice(out as *const vk::CommandBuffer, (*info).command_buffer_count)) };
            for cb in cbs {
                let state = crate::track::CommandBuffer::new(cb.as_raw(), info.command_pool.as_raw(), info.level);
                d.track.command_buffers.insert(cb.as_raw(), Arc::new(state));
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn free_command_buffers(device: vk::Device, pool: vk::CommandPool, count: u32, cbs: *const vk::CommandBuffer) {
    hook(
        "vkFreeCommandBuffers",
        device,
        (),
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().free_command_buffers)(device, pool, count, cbs) },
        |d, _| {
            // SAFETY: `count` handles (some may be null, which match nothing).
            let handles: Vec<u64> = unsafe { convert::slice(cbs, count) }.iter().map(|c| c.as_raw()).collect();
            super::secondary::release(d, &handles);
            d.track.free_command_buffers(&handles);
            Ok(())
        },
    )
}

// ---------------------------------------------------------------------------------------------
// Command buffers

pub(super) unsafe extern "system" fn begin_command_buffer(cb: vk::CommandBuffer, info: *const vk::CommandBufferBeginInfo<'_>) -> vk::Result {
    hook(
        "vkBeginCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().begin_command_buffer)(cb, info) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // Not pending (re-recording requires it): the layer's secondaries in it are free.
                super::secondary::release(d, &[cb.as_raw()]);
                // SAFETY: a valid begin info.
                d.track.begin_command_buffer(cb.as_raw(), unsafe { (*info).flags });
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn reset_command_buffer(cb: vk::CommandBuffer, flags: vk::CommandBufferResetFlags) -> vk::Result {
    hook(
        "vkResetCommandBuffer",
        cb,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: forwarding the app's arguments unchanged.
        |d| unsafe { (d.fns.fp_v1_0().reset_command_buffer)(cb, flags) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                super::secondary::release(d, &[cb.as_raw()]);
                d.track.with_cb(cb.as_raw(), |s| s.reset());
            }
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_execute_commands(cb: vk::CommandBuffer, n: u32, cbs: *const vk::CommandBuffer) {
    hook_decided(
        "vkCmdExecuteCommands",
        cb,
        (),
        // An eye pass with secondary contents: the layer's draws, in its own secondary.
        |d| mask::on_execute_commands(d, cb),
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
            d.track.with_cb(cb.as_raw(), |s| s.forget_graphics_state());
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_bind_pipeline(cb: vk::CommandBuffer, bind_point: vk::PipelineBindPoint, pipeline: vk::Pipeline) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindPipeline", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_pipeline)(cb, bind_point, pipeline) }, |d, cb| {
        if bind_point == vk::PipelineBindPoint::GRAPHICS {
            d.track.bind_graphics_pipeline(cb, pipeline.as_raw());
        }
    })
}

pub(super) unsafe extern "system" fn cmd_push_constants(
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

/// Hooks for dynamic-state commands: call down unchanged, record one `StateCmd`.
macro_rules! state_hook {
    ($name:ident, $call:literal, ($cb:ident, $($arg:ident : $ty:ty),*), |$d:ident| $next:expr, $cmd:expr) => {
        // Only some commands read app memory while recording; the shared `unsafe` covers those.
        #[allow(unused_unsafe)]
        pub(super) unsafe extern "system" fn $name($cb: vk::CommandBuffer, $($arg: $ty),*) {
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
        pub(super) unsafe extern "system" fn $name(cb: vk::CommandBuffer, $($arg: $ty),*) {
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
    d.track.begin_render_pass(crate::shared::shared(), cb, kind, begin);
}

pub(super) unsafe extern "system" fn cmd_begin_render_pass(cb: vk::CommandBuffer, info: *const vk::RenderPassBeginInfo<'_>, contents: vk::SubpassContents) {
    let secondary = contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS;
    hook_decided(
        "vkCmdBeginRenderPass",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_render_pass_begin(d, cb, PassKind::RenderPass, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_0().cmd_begin_render_pass;
            match decided {
                // SAFETY: the app's info with the rate view appended (imageless framebuffer).
                Some(Some(v)) => unsafe { begin(cb, &v.info, contents) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info, contents) },
            }
        },
        |d, _| {
            begin_pass(d, cb.as_raw(), PassKind::RenderPass, info);
            super::vrs::on_render_pass_begin(d, cb, secondary);
            mask::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_next_subpass(cb: vk::CommandBuffer, contents: vk::SubpassContents) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_next_subpass)(cb, contents) }, |d, raw| {
        d.track.next_subpass(raw);
        mask::on_trigger(d, cb, Trigger::NextSubpass { secondary: contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS });
    })
}

pub(super) unsafe extern "system" fn cmd_end_render_pass(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRenderPass", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_end_render_pass)(cb) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

pub(super) unsafe extern "system" fn cmd_begin_render_pass2(
    cb: vk::CommandBuffer,
    info: *const vk::RenderPassBeginInfo<'_>,
    subpass_info: *const vk::SubpassBeginInfo<'_>,
) {
    hook_decided(
        "vkCmdBeginRenderPass2",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_render_pass_begin(d, cb, PassKind::RenderPass2, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_2().cmd_begin_render_pass2;
            match decided {
                // SAFETY: the app's info with the rate view appended (imageless framebuffer).
                Some(Some(v)) => unsafe { begin(cb, &v.info, subpass_info) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info, subpass_info) },
            }
        },
        |d, _| {
            begin_pass(d, cb.as_raw(), PassKind::RenderPass2, info);
            super::vrs::on_render_pass_begin(d, cb, secondary_contents(subpass_info));
            mask::on_trigger(d, cb, Trigger::Begin { secondary: secondary_contents(subpass_info) });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_next_subpass2(cb: vk::CommandBuffer, begin: *const vk::SubpassBeginInfo<'_>, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdNextSubpass2", cb, (), |d| unsafe { (d.fns.fp_v1_2().cmd_next_subpass2)(cb, begin, end) }, |d, raw| {
        d.track.next_subpass(raw);
        mask::on_trigger(d, cb, Trigger::NextSubpass { secondary: secondary_contents(begin) });
    })
}

pub(super) unsafe extern "system" fn cmd_end_render_pass2(cb: vk::CommandBuffer, end: *const vk::SubpassEndInfo<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRenderPass2", cb, (), |d| unsafe { (d.fns.fp_v1_2().cmd_end_render_pass2)(cb, end) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

pub(super) unsafe extern "system" fn cmd_begin_rendering(cb: vk::CommandBuffer, info: *const vk::RenderingInfo<'_>) {
    hook_decided(
        "vkCmdBeginRendering",
        cb,
        (),
        // SAFETY: the app's valid info; `cb` is recording outside a pass (it is about to begin one).
        |d| unsafe { super::vrs::for_rendering(d, cb, info) },
        |d, decided| {
            let begin = d.fns.fp_v1_3().cmd_begin_rendering;
            match decided {
                // SAFETY: the app's info with variable-rate shading's attachment chained first.
                Some(Some(v)) => unsafe { begin(cb, &v.info) },
                // SAFETY: forwarding the app's arguments unchanged.
                _ => unsafe { begin(cb, info) },
            }
        },
        |d, _| {
            let raw = cb.as_raw();
            // SAFETY: a valid rendering info during the app's call.
            let (area, rendering) = unsafe { convert::rendering(&d.track, &*info) };
            let secondary = rendering.flags.contains(vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS);
            d.track.begin_rendering(raw, area, rendering);
            mask::on_trigger(d, cb, Trigger::Begin { secondary });
            Ok(())
        },
    )
}

pub(super) unsafe extern "system" fn cmd_end_rendering(cb: vk::CommandBuffer) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdEndRendering", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_end_rendering)(cb) }, |d, raw| {
        mask::on_trigger(d, cb, Trigger::End);
        d.track.end_pass(raw)
    })
}

fn secondary_contents(info: *const vk::SubpassBeginInfo<'_>) -> bool {
    // SAFETY: null or a valid struct during the app's call.
    unsafe { info.as_ref() }.is_some_and(|i| i.contents == vk::SubpassContents::SECONDARY_COMMAND_BUFFERS)
}

// ---------------------------------------------------------------------------------------------
// Vertex buffers (restored after a mask draw), transfers (intermediate eye targets), clears

pub(super) unsafe extern "system" fn cmd_bind_vertex_buffers(cb: vk::CommandBuffer, first: u32, n: u32, buffers: *const vk::Buffer, offsets: *const vk::DeviceSize) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBindVertexBuffers", cb, (), |d| unsafe { (d.fns.fp_v1_0().cmd_bind_vertex_buffers)(cb, first, n, buffers, offsets) }, |d, cb| {
        // SAFETY: arrays valid with their counts during the app's call.
        let bindings = unsafe { convert::vertex_bindings(n, buffers, offsets, std::ptr::null(), std::ptr::null(), false) };
        state(d, cb, StateCmd::BindVertexBuffers { first, bindings })
    })
}

pub(super) unsafe extern "system" fn cmd_bind_vertex_buffers2(
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

fn transfer(d: &DeviceState, src: vk::Image, dst: vk::Image, regions: Vec<crate::track::eye_pass::TransferRegion>) {
    let settings = d.mask.settings(&d.config);
    if settings.enabled || settings.rdm {
        d.track.record_transfer(crate::shared::shared(), src.as_raw(), dst.as_raw(), &regions);
    }
    if settings.rdm {
        super::rdm::on_transfer(d, src.as_raw(), dst.as_raw(), &regions);
    }
}

pub(super) unsafe extern "system" fn cmd_copy_image(
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
        |d, _| transfer(d, src, dst, unsafe { convert::slice(regions, n) }.iter().map(convert::copy_region).collect()),
    )
}

pub(super) unsafe extern "system" fn cmd_copy_image2(cb: vk::CommandBuffer, info: *const vk::CopyImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdCopyImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_copy_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

pub(super) unsafe extern "system" fn cmd_resolve_image(
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
        |d, _| {
            // SAFETY: the region array is valid with its count.
            let regions = unsafe { convert::slice(regions, n) }
                .iter()
                .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
                .collect();
            transfer(d, src, dst, regions)
        },
    )
}

pub(super) unsafe extern "system" fn cmd_resolve_image2(cb: vk::CommandBuffer, info: *const vk::ResolveImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdResolveImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_resolve_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .map(|r| convert::copy_region(&vk::ImageCopy { src_subresource: r.src_subresource, src_offset: r.src_offset, dst_subresource: r.dst_subresource, dst_offset: r.dst_offset, extent: r.extent }))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

#[allow(clippy::too_many_arguments)]
pub(super) unsafe extern "system" fn cmd_blit_image(
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
        |d, _| {
            // SAFETY: the region array is valid with its count.
            let regions = unsafe { convert::slice(regions, n) }
                .iter()
                .filter_map(|r| convert::blit_region(r.src_subresource, r.src_offsets, r.dst_subresource, r.dst_offsets))
                .collect();
            transfer(d, src, dst, regions)
        },
    )
}

pub(super) unsafe extern "system" fn cmd_blit_image2(cb: vk::CommandBuffer, info: *const vk::BlitImageInfo2<'_>) {
    // SAFETY: forwarding the app's arguments unchanged.
    cmd("vkCmdBlitImage2", cb, (), |d| unsafe { (d.fns.fp_v1_3().cmd_blit_image2)(cb, info) }, |d, _| {
        // SAFETY: a valid info with a valid region array.
        let (i, regions) = unsafe { (&*info, convert::slice((*info).p_regions, (*info).region_count)) };
        let regions = regions
            .iter()
            .filter_map(|r| convert::blit_region(r.src_subresource, r.src_offsets, r.dst_subresource, r.dst_offsets))
            .collect();
        transfer(d, i.src_image, i.dst_image, regions)
    })
}

pub(super) unsafe extern "system" fn cmd_clear_attachments(
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
            if !d.mask.settings(&d.config).any() {
                return;
            }
            // SAFETY: arrays valid with their counts during the app's call.
            let (atts, rects) = unsafe { (convert::slice(attachments, n), convert::slice(rects, rect_count)) };
            let depth = atts.iter().find(|a| a.aspect_mask.contains(vk::ImageAspectFlags::DEPTH));
            if let Some(a) = depth {
                // SAFETY: a depth clear's value is the depthStencil member.
                let value = unsafe { a.clear_value.depth_stencil.depth };
                let rects = rects.iter().map(|r| crate::mask::PixelRect { x: r.rect.offset.x, y: r.rect.offset.y, width: r.rect.extent.width, height: r.rect.extent.height }).collect();
                mask::on_trigger(d, cb, Trigger::Clear { depth: value, rects });
            }
        },
    )
}

pub(super) unsafe extern "system" fn cmd_clear_depth_stencil_image(
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
            if !d.mask.settings(&d.config).any() {
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
