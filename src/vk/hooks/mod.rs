//! The intercepted commands. Every hook runs the same prologue (`hook`): find the device state by
//! dispatch key, open a span, then *decide → call down → record* inside `guard::run`, so a fault
//! in layer logic turns the instance to pass-through and the app still gets the driver's result.
//! With all features off no hook changes what reaches the driver (instance and device creation,
//! which may, live in `chain`).
//!
//! Hooks know no feature: they track state (`crate::track`) and raise the events of
//! `feature::VkFeature` over the registry (`DeviceFeatures::all()`), and the injection triggers of
//! `inject`. `record` holds the command-recording hooks, `submit` the queue submissions.

use crate::features::upscale::UpscaleSettings;
use crate::plugin::vk::feature::{Destroyed, RenderPassInfo};
use super::device_of;
use crate::plugin::vk::{convert, lifetime, DeviceState};
use crate::core::guard::{self, Fault};
use crate::track::cmd::StateCmd;
use ash::vk::{self, Handle};
use std::sync::Arc;

mod descriptors;
mod draw;
mod dyn_state;
mod record;
mod submit;
pub(super) use descriptors::*;
pub(super) use draw::*;
pub(super) use dyn_state::*;
pub(super) use record::*;
pub(super) use submit::*;

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
                |d| unsafe { (d.next.$fp().$f)(device, ci, allocator, out) },
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
                |d| unsafe { (d.next.$fp().$f)(device, handle, allocator) },
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
    let added = std::cell::Cell::new(vk::ImageUsageFlags::empty());
    hook(
        "vkCreateImage",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's create info, with the usage the features add (retried unchanged if
        // the driver refuses it), forwarded to the next layer.
        |d| unsafe {
            let settings = d.settings();
            let extra = d.features.all().iter().fold(vk::ImageUsageFlags::empty(), |u, f| u | f.image_usage(&settings, (*ci).usage));
            if !extra.is_empty() && !(*ci).usage.contains(extra) {
                let amended = vk::ImageCreateInfo { usage: (*ci).usage | extra, ..*ci };
                let r = (d.next.fp_v1_0().create_image)(device, &amended, allocator, out);
                if r == vk::Result::SUCCESS {
                    added.set(extra);
                    return r;
                }
                tracing::debug!(?r, "vkCreateImage with the layer's added usage failed; the app's own create info is used");
            }
            (d.next.fp_v1_0().create_image)(device, ci, allocator, out)
        },
        |d, r| {
            if r == vk::Result::SUCCESS {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                crate::bridge::swapchain_images::note_created(crate::bridge::swapchain_images::CreatedImage {
                    image: h.as_raw(),
                    format: ci.format.as_raw(),
                    width: ci.extent.width,
                    height: ci.extent.height,
                    array_layers: ci.array_layers,
                    samples: ci.samples.as_raw(),
                    mip_levels: ci.mip_levels,
                });
                let mut image = convert::image(h, ci);
                // What the image really has: the app's usage and whatever the layer added.
                image.usage |= added.get();
                d.track.images.insert(h.as_raw(), Arc::new(image));
            }
            Ok(())
        },
    )
}
/// `vkCreateSampler`: with the upscale on, the app's samplers get the LOD bias that keeps textures
/// as sharp as at the display size (`upscale.mip_bias`; the app's own bias stays, added to).
pub(super) unsafe extern "system" fn create_sampler(
    device: vk::Device,
    ci: *const vk::SamplerCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Sampler,
) -> vk::Result {
    hook_decided(
        "vkCreateSampler",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's create info, valid during its call (null goes down unchanged).
        |d| d.settings().of::<UpscaleSettings>().sampler_bias().and_then(|bias| unsafe { ci.as_ref() }.map(|ci| crate::features::upscale::rules::biased(ci.mip_lod_bias, bias))),
        |d, decided| match decided {
            Some(Some(bias)) => {
                // SAFETY: the app's create info (non-null: the decision read it), valid for the call.
                let app = unsafe { *ci };
                let amended = vk::SamplerCreateInfo { mip_lod_bias: *bias, ..app };
                // Once per process: the log line says the bias is in effect, the rest is the same.
                static LOGGED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
                if !LOGGED.swap(true, std::sync::atomic::Ordering::Relaxed) {
                    tracing::info!("upscale: the app's samplers get the upscale's LOD bias (the first: {} -> {bias})", app.mip_lod_bias);
                }
                // SAFETY: as above, with the app's allocator (the app destroys the sampler).
                unsafe { (d.next.fp_v1_0().create_sampler)(device, &amended, allocator, out) }
            }
            // SAFETY: forwarding the app's arguments unchanged.
            _ => unsafe { (d.next.fp_v1_0().create_sampler)(device, ci, allocator, out) },
        },
        |_, _| Ok(()),
    )
}
destroy_hook!(destroy_image, "vkDestroyImage", vk::Image, fp_v1_0.destroy_image, |d, h| {
    d.track.forget_image(h);
    destroyed(d, Destroyed::Image(h))
});

/// Raises `destroyed` over the features.
fn destroyed(d: &DeviceState, what: Destroyed) {
    for f in d.features.all() {
        f.destroyed(d, what);
    }
}
create_hook!(create_image_view, "vkCreateImageView", vk::ImageViewCreateInfo<'_>, vk::ImageView, fp_v1_0.create_image_view, views, |h, ci| convert::image_view(h, ci));
destroy_hook!(destroy_image_view, "vkDestroyImageView", vk::ImageView, fp_v1_0.destroy_image_view, |d, h| d.track.views.remove(h));
/// `vkCreateRenderPass` / `vkCreateRenderPass2(KHR)`: a feature may amend the pass (e.g. append
/// an attachment; the amended info goes down as `vkCreateRenderPass2`); the tracked description is
/// the app's, with the appended attachment's index.
fn create_render_pass_common(
    call: &'static str,
    device: vk::Device,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::RenderPass,
    info: RenderPassInfo,
    app: impl Fn(&DeviceState) -> vk::Result,
    describe: impl FnOnce(vk::RenderPass) -> crate::track::resources::RenderPass,
) -> vk::Result {
    let appended = std::cell::Cell::new(None);
    hook_decided(
        call,
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        // SAFETY: the app's info, valid during its call; the amendment lives in the decision.
        |d| d.features.all().iter().find_map(|f| unsafe { f.amend_render_pass(d, info) }),
        |d, decided| {
            if let Some(Some(rp)) = decided {
                // SAFETY: the app's pass with only the feature's additions, with the app's
                // allocator (the app destroys the pass).
                let r = unsafe { (d.next.fp_v1_2().create_render_pass2)(device, &rp.amended.info, allocator, out) };
                if r == vk::Result::SUCCESS {
                    appended.set(Some(rp.appended_attachment));
                    return r;
                }
                tracing::warn!(?r, "{call} failed with the layer's additions; retrying as the app asked");
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
    // SAFETY: the app's create info, valid during its call (which outlives `kept`).
    let kept = if device_of(device).is_some_and(|d| crate::plugin::vk::keep_depth::wanted(&d)) { unsafe { crate::plugin::vk::keep_depth::render_pass(ci) } } else { None };
    let ci = kept.as_ref().map_or(ci, |k| &k.info as *const _);
    create_render_pass_common(
        "vkCreateRenderPass",
        device,
        allocator,
        out,
        RenderPassInfo::V1(ci.cast()),
        // SAFETY: the app's arguments, the create info with depth kept when a feature reads it.
        |d| unsafe { (d.next.fp_v1_0().create_render_pass)(device, ci, allocator, out) },
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
    // SAFETY: the app's create info, valid during its call (which outlives `kept`).
    let kept = if device_of(device).is_some_and(|d| crate::plugin::vk::keep_depth::wanted(&d)) { unsafe { crate::plugin::vk::keep_depth::render_pass2(ci) } } else { None };
    let ci = kept.as_ref().map_or(ci, |k| &k.info as *const _);
    create_render_pass_common(
        "vkCreateRenderPass2",
        device,
        allocator,
        out,
        RenderPassInfo::V2(ci.cast()),
        // SAFETY: the app's arguments, the create info with depth kept when a feature reads it.
        |d| unsafe { (d.next.fp_v1_2().create_render_pass2)(device, ci, allocator, out) },
        // SAFETY: the create info is valid during the app's call.
        |h| unsafe { convert::render_pass2(h, &*ci) },
    )
}

destroy_hook!(destroy_render_pass, "vkDestroyRenderPass", vk::RenderPass, fp_v1_0.destroy_render_pass, |d, h| {
    d.track.render_passes.remove(h);
    crate::plugin::vk::inject::pipeline::forget_render_pass(d, h)
});
/// `vkCreateFramebuffer`: a feature may amend the framebuffer (e.g. append its own attachment for
/// a render pass it amended); tracked as the app described it.
pub(super) unsafe extern "system" fn create_framebuffer(
    device: vk::Device,
    ci: *const vk::FramebufferCreateInfo<'_>,
    allocator: *const vk::AllocationCallbacks<'_>,
    out: *mut vk::Framebuffer,
) -> vk::Result {
    let pending: std::cell::RefCell<Option<(usize, Box<dyn std::any::Any>)>> = Default::default();
    hook_decided(
        "vkCreateFramebuffer",
        device,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            d.features.all().iter().enumerate().find_map(|(i, f)| {
                let mut p = None;
                // SAFETY: the app's info, valid during its call; the amendment lives in the decision.
                let amended = unsafe { f.amend_framebuffer(d, ci, &mut p) }?;
                *pending.borrow_mut() = p.map(|p| (i, p));
                Some(amended)
            })
        },
        |d, decided| match decided {
            // SAFETY: the app's info with only the feature's additions.
            Some(Some(f)) => unsafe { (d.next.fp_v1_0().create_framebuffer)(device, &f.info, allocator, out) },
            // SAFETY: forwarding the app's arguments unchanged.
            _ => unsafe { (d.next.fp_v1_0().create_framebuffer)(device, ci, allocator, out) },
        },
        |d, r| {
            let ok = r == vk::Result::SUCCESS;
            if let Some((i, p)) = pending.take() {
                // SAFETY: on success the handle was written.
                d.features.all()[i].framebuffer_created(d, ok.then(|| unsafe { *out }), p);
            }
            if ok {
                // SAFETY: on success the handle was written; the create info is valid during the
                // app's call.
                let (h, ci) = unsafe { (*out, &*ci) };
                // SAFETY: the create info is valid during the app's call.
                d.track.framebuffers.insert(h.as_raw(), Arc::new(unsafe { convert::framebuffer(h, ci) }));
            }
            Ok(())
        },
    )
}
destroy_hook!(destroy_framebuffer, "vkDestroyFramebuffer", vk::Framebuffer, fp_v1_0.destroy_framebuffer, |d, h| {
    d.track.framebuffers.remove(h);
    destroyed(d, Destroyed::Framebuffer(h))
});
destroy_hook!(destroy_pipeline, "vkDestroyPipeline", vk::Pipeline, fp_v1_0.destroy_pipeline, |d, h| d.track.pipelines.remove(h));
create_hook!(create_command_pool, "vkCreateCommandPool", vk::CommandPoolCreateInfo<'_>, vk::CommandPool, fp_v1_0.create_command_pool, pools, |h, ci| {
    crate::track::resources::CommandPool { handle: h.as_raw(), flags: ci.flags, queue_family_index: ci.queue_family_index }
});
destroy_hook!(destroy_command_pool, "vkDestroyCommandPool", vk::CommandPool, fp_v1_0.destroy_command_pool, |d, h| {
    let buffers = d.track.buffers_of_pool(h);
    crate::plugin::vk::secondary::release(d, &buffers);
    lifetime::close(d, &buffers);
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
        // SAFETY: the app's infos, valid during its call; the amendment lives in the decision.
        |d| d.features.all().iter().find_map(|f| unsafe { f.amend_pipelines(d, infos, count) }),
        |d, decided| {
            let create = d.next.fp_v1_0().create_graphics_pipelines;
            if let Some(Some(m)) = decided {
                // SAFETY: the app's infos with only the feature's additions.
                let r = unsafe { create(device, cache, count, m.info.as_ptr(), allocator, out) };
                if r == vk::Result::SUCCESS || r == vk::Result::PIPELINE_COMPILE_REQUIRED {
                    return r;
                }
                tracing::warn!(?r, "vkCreateGraphicsPipelines failed with the layer's additions; retrying as the app asked");
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
                let buffers = d.track.buffers_of_pool(pool.as_raw());
                crate::plugin::vk::secondary::release(d, &buffers);
                lifetime::close(d, &buffers);
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
            crate::plugin::vk::secondary::release(d, &handles);
            lifetime::close(d, &handles);
            d.track.free_command_buffers(&handles);
            Ok(())
        },
    )
}

