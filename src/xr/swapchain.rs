//! Swapchain entry points: which `VkImage`s are swapchain images (published for the Vulkan half)
//! and which image the app is rendering into right now.

use super::session::{self, Session};
use super::{state, Instance};
use crate::core::guard;
use crate::bridge;
use crate::core::views::SwapchainDesc;
use crate::bridge::swapchain_images;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

pub(crate) struct Swapchain {
    pub session: Arc<Session>,
    pub desc: SwapchainDesc,
    /// What `xrCreateSwapchain` asked for, and the images the Vulkan half saw created meanwhile
    /// (`swapchain_images`): how the reported images are recognised under a wrapping layer.
    pub wanted: swapchain_images::Wanted,
    pub created_images: Vec<swapchain_images::CreatedImage>,
    /// Acquired, not yet released image indices, oldest first (the spec's acquire order).
    pub acquired: Mutex<VecDeque<u32>>,
    /// The upscale's interposition: the app renders into the layer's images at `desc`'s size, the
    /// runtime's swapchain is at the display size.
    pub upscale: Option<super::upscale::Interposed>,
}

/// The frame's interposed swapchains of session `s` (the upscale's, handed to it at `xrEndFrame`).
pub(super) fn interposed_of(s: &Session) -> Vec<(u64, Arc<Swapchain>)> {
    state().swapchains.values().into_iter().filter(|(_, sc)| sc.session.handle == s.handle && sc.upscale.is_some()).collect()
}

/// The swapchain's state, or the instance to forward an unknown handle through.
fn lookup(swapchain: xr::Swapchain) -> Result<Arc<Swapchain>, Option<Arc<Instance>>> {
    state().swapchains.get(swapchain.into_raw()).ok_or_else(super::sole_instance)
}

/// Resolves a swapchain handle to (instance, state if known), or returns the error for a handle
/// no instance can take.
macro_rules! swapchain_or_forward {
    ($swapchain:expr) => {
        match lookup($swapchain) {
            Ok(sc) => (sc.session.instance.clone(), Some(sc)),
            Err(Some(inst)) => (inst, None),
            Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
        }
    };
}

pub(super) unsafe extern "system" fn create_swapchain(
    session: xr::Session,
    create_info: *const xr::SwapchainCreateInfo,
    swapchain: *mut xr::Swapchain,
) -> xr::Result {
    let (inst, sess) = match session::lookup(session) {
        Ok(s) => (s.instance.clone(), Some(s)),
        Err(Some(inst)) => (inst, None),
        Err(None) => return xr::Result::ERROR_HANDLE_INVALID,
    };
    let Some(next) = inst.next.create_swapchain else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(session, create_info, swapchain) };
    guard::run("xrCreateSwapchain", &inst.pass_through, |down| {
        inst.check_fault("xrCreateSwapchain")?;
        // Features may add usage (an extra usage bit changes nothing the app can see).
        let settings = super::settings(&inst);
        let added = |usage: xr::SwapchainUsageFlags| {
            crate::registry::XR_FEATURES.iter().fold(xr::SwapchainUsageFlags::EMPTY, |a, f| a | f.swapchain_usage(&settings, usage)) & !usage
        };
        // The upscale: a swapchain of a told view size is made at the display size below, and
        // the app renders into the layer's images.
        // SAFETY: the app's create info, valid for this call.
        if let (Some(s), Some(ci)) = (sess.as_ref(), unsafe { create_info.as_ref() }) {
            // SAFETY: the app's arguments with the layer's create info, valid for the call.
            let mut create = |c: &xr::SwapchainCreateInfo| down.call(|| unsafe { next(session, c, swapchain) });
            // SAFETY: read only after a successful create wrote it.
            let handle = || unsafe { *swapchain };
            match super::upscale::create_swapchain(s, ci, added(ci.usage_flags), &mut create, &handle) {
                super::upscale::Created::No => {}
                super::upscale::Created::Yes(r, None) => return Ok(r),
                super::upscale::Created::Yes(r, Some(i)) => {
                    let desc = SwapchainDesc { usage_flags: ci.usage_flags.into_raw(), format: ci.format, sample_count: ci.sample_count, width: ci.width, height: ci.height, array_size: ci.array_size };
                    inst.stats.swapchains_created.fetch_add(1, Ordering::Relaxed);
                    let wanted = swapchain_images::Wanted { format: ci.format, width: ci.width, height: ci.height, array_size: ci.array_size, sample_count: ci.sample_count, mip_count: ci.mip_count };
                    let h = handle();
                    tracing::info!("swapchain {:#x}: {desc:?} (upscaled)", h.into_raw());
                    let sc = Swapchain { session: s.clone(), desc, wanted, created_images: Vec::new(), acquired: Mutex::new(VecDeque::new()), upscale: Some(*i) };
                    state().swapchains.insert(h.into_raw(), Arc::new(sc));
                    return Ok(r);
                }
            }
        }
        // SAFETY: the app's create info, valid for this call (null goes down unchanged).
        let (r, created_images) = swapchain_images::capture(|| match unsafe { create_info.as_ref() } {
            Some(ci) if added(ci.usage_flags) != xr::SwapchainUsageFlags::EMPTY => {
                let mut with = *ci;
                with.usage_flags |= added(ci.usage_flags);
                // SAFETY: the copy lives until the call returns.
                down.call(|| unsafe { next(session, &with, swapchain) })
            }
            _ => down.call(plain),
        });
        let (Some(sess), true) = (sess.clone(), r == xr::Result::SUCCESS) else { return Ok(r) };
        // SAFETY: success means the create info was valid and the handle was written.
        let (ci, handle) = unsafe { (&*create_info, *swapchain) };
        let desc = SwapchainDesc {
            usage_flags: ci.usage_flags.into_raw(),
            format: ci.format,
            sample_count: ci.sample_count,
            width: ci.width,
            height: ci.height,
            array_size: ci.array_size,
        };
        tracing::info!("swapchain {:#x}: {desc:?}", handle.into_raw());
        inst.stats.swapchains_created.fetch_add(1, Ordering::Relaxed);
        let wanted = swapchain_images::Wanted {
            format: ci.format,
            width: ci.width,
            height: ci.height,
            array_size: ci.array_size,
            sample_count: ci.sample_count,
            mip_count: ci.mip_count,
        };
        let sc = Swapchain { session: sess, desc, wanted, created_images, acquired: Mutex::new(VecDeque::new()), upscale: None };
        state().swapchains.insert(handle.into_raw(), Arc::new(sc));
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn destroy_swapchain(swapchain: xr::Swapchain) -> xr::Result {
    let (inst, sc) = swapchain_or_forward!(swapchain);
    let Some(next) = inst.next.destroy_swapchain else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's handle.
    let plain = || unsafe { next(swapchain) };
    guard::run("xrDestroySwapchain", &inst.pass_through, |down| {
        if let Some((sc, i)) = sc.as_ref().and_then(|sc| sc.upscale.as_ref().map(|i| (sc, i))) {
            super::upscale::destroy(&sc.session, i);
        }
        let r = down.call(plain);
        if r == xr::Result::SUCCESS && sc.is_some() {
            bridge::shared().remove_swapchain(swapchain.into_raw());
            state().swapchains.remove(swapchain.into_raw());
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn enumerate_swapchain_images(
    swapchain: xr::Swapchain,
    image_capacity_input: u32,
    image_count_output: *mut u32,
    images: *mut xr::SwapchainImageBaseHeader,
) -> xr::Result {
    let (inst, sc) = swapchain_or_forward!(swapchain);
    let Some(next) = inst.next.enumerate_swapchain_images else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(swapchain, image_capacity_input, image_count_output, images) };
    guard::run("xrEnumerateSwapchainImages", &inst.pass_through, |down| {
        inst.check_fault("xrEnumerateSwapchainImages")?;
        if let Some((sc, i)) = sc.as_ref().and_then(|sc| sc.upscale.as_ref().map(|i| (sc, i))) {
            // SAFETY: the app's output pointers, as the spec's two-call idiom has them.
            return Ok(unsafe { enumerate_interposed(swapchain, sc, i, image_capacity_input, image_count_output, images) });
        }
        let r = down.call(plain);
        let Some(sc) = sc.as_ref() else { return Ok(r) };
        if r != xr::Result::SUCCESS || image_capacity_input == 0 || images.is_null() || image_count_output.is_null() {
            return Ok(r);
        }
        // SAFETY: success with capacity > 0 means `*image_count_output` structs were written.
        let count = unsafe { *image_count_output }.min(image_capacity_input) as usize;
        // SAFETY: the array's element type is given by its first element's `ty`.
        if unsafe { (*images).ty } != xr::StructureType::SWAPCHAIN_IMAGE_VULKAN_KHR {
            return Ok(r);
        }
        // SAFETY: the array holds `count` XrSwapchainImageVulkanKHR (checked `ty` above).
        let vk = unsafe { std::slice::from_raw_parts(images as *const xr::SwapchainImageVulkanKHR, count) };
        let reported: Vec<u64> = vk.iter().map(|i| i.image).collect();
        let handles = match swapchain_images::match_images(&sc.wanted, &sc.created_images, &reported) {
            swapchain_images::Match::Created(created) => {
                tracing::info!("swapchain {:#x} images {created:x?} (created during xrCreateSwapchain; reported as {reported:x?})", swapchain.into_raw());
                created
            }
            swapchain_images::Match::Reported(reported, why) => {
                tracing::info!("swapchain {:#x} images {reported:x?} as reported ({why}): recognised only if no layer above wraps handles", swapchain.into_raw());
                reported
            }
        };
        inst.stats.swapchain_images.fetch_add(count as u64, Ordering::Relaxed);
        bridge::shared().add_swapchain(Arc::new(bridge::Swapchain::new(swapchain.into_raw(), sc.desc.clone(), handles)));
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn acquire_swapchain_image(
    swapchain: xr::Swapchain,
    acquire_info: *const xr::SwapchainImageAcquireInfo,
    index: *mut u32,
) -> xr::Result {
    let (inst, sc) = swapchain_or_forward!(swapchain);
    let Some(next) = inst.next.acquire_swapchain_image else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(swapchain, acquire_info, index) };
    guard::run("xrAcquireSwapchainImage", &inst.pass_through, |down| {
        inst.check_fault("xrAcquireSwapchainImage")?;
        let r = down.call(plain);
        if let (Some(sc), xr::Result::SUCCESS) = (sc.as_ref(), r) {
            // SAFETY: success means the index was written.
            let i = unsafe { *index };
            sc.acquired.lock().unwrap_or_else(|e| e.into_inner()).push_back(i);
            if let Some(u) = sc.upscale.as_ref() {
                super::upscale::acquired(&sc.session, u);
            }
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn wait_swapchain_image(
    swapchain: xr::Swapchain,
    wait_info: *const xr::SwapchainImageWaitInfo,
) -> xr::Result {
    let (inst, sc) = swapchain_or_forward!(swapchain);
    let Some(next) = inst.next.wait_swapchain_image else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(swapchain, wait_info) };
    guard::run("xrWaitSwapchainImage", &inst.pass_through, |down| {
        inst.check_fault("xrWaitSwapchainImage")?;
        let r = down.call(plain);
        if let (Some(u), xr::Result::SUCCESS) = (sc.as_ref().and_then(|sc| sc.upscale.as_ref()), r) {
            u.waited.store(true, Ordering::Release);
        }
        Ok(r)
    }, plain)
}

pub(super) unsafe extern "system" fn release_swapchain_image(
    swapchain: xr::Swapchain,
    release_info: *const xr::SwapchainImageReleaseInfo,
) -> xr::Result {
    let (inst, sc) = swapchain_or_forward!(swapchain);
    let Some(next) = inst.next.release_swapchain_image else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    // SAFETY: forwarding the app's arguments unchanged.
    let plain = || unsafe { next(swapchain, release_info) };
    guard::run("xrReleaseSwapchainImage", &inst.pass_through, |down| {
        inst.check_fault("xrReleaseSwapchainImage")?;
        if let Some((sc, u)) = sc.as_ref().and_then(|sc| sc.upscale.as_ref().map(|u| (sc, u))) {
            // The runtime keeps its image acquired until the frame ends; the app's call order is
            // checked here as the runtime would.
            let index = sc.acquired.lock().unwrap_or_else(|e| e.into_inner()).front().copied();
            let Some(index) = index.filter(|_| u.waited.load(Ordering::Acquire)) else { return Ok(xr::Result::ERROR_CALL_ORDER_INVALID) };
            crate::plugin::vk::before_release(sc.session.binding.map(|b| (b.device_key, b.queue_family_index, b.queue_index)), swapchain.into_raw(), Some(index));
            let r = super::upscale::release(&sc.session, super::upscale::Interposing { handle: swapchain.into_raw(), desc: &sc.desc, i: u }, index);
            if r.into_raw() >= 0 {
                sc.acquired.lock().unwrap_or_else(|e| e.into_inner()).pop_front();
            }
            return Ok(r);
        }
        if let Some(sc) = sc.as_ref() {
            // Radial density masking: fill the skipped quads before the runtime sees the image
            // (the oldest acquired one is the one going back).
            let index = sc.acquired.lock().unwrap_or_else(|e| e.into_inner()).front().copied();
            crate::plugin::vk::before_release(sc.session.binding.map(|b| (b.device_key, b.queue_family_index, b.queue_index)), swapchain.into_raw(), index);
        }
        let r = down.call(plain);
        if let (Some(sc), xr::Result::SUCCESS) = (sc.as_ref(), r) {
            // Images are released in acquire order (spec), so the oldest acquired one went back.
            sc.acquired.lock().unwrap_or_else(|e| e.into_inner()).pop_front();
        }
        Ok(r)
    }, plain)
}

/// `xrEnumerateSwapchainImages` of an interposed swapchain: the layer's images, as the app names
/// them; they are published to the Vulkan half as this swapchain's images.
///
/// # Safety
/// The app's arguments, valid per the two-call idiom.
unsafe fn enumerate_interposed(
    swapchain: xr::Swapchain,
    sc: &Swapchain,
    i: &super::upscale::Interposed,
    capacity: u32,
    count_out: *mut u32,
    images: *mut xr::SwapchainImageBaseHeader,
) -> xr::Result {
    let app = i.app_images();
    // SAFETY: the app's count pointer, null or valid per the spec.
    let Some(count) = (unsafe { count_out.as_mut() }) else { return xr::Result::ERROR_VALIDATION_FAILURE };
    *count = app.len() as u32;
    if capacity == 0 {
        return xr::Result::SUCCESS;
    }
    if capacity < app.len() as u32 {
        return xr::Result::ERROR_SIZE_INSUFFICIENT;
    }
    // SAFETY: `capacity` structs, whose type the first one's `ty` tells.
    let Some(first) = (unsafe { images.as_ref() }) else { return xr::Result::ERROR_VALIDATION_FAILURE };
    if first.ty != xr::StructureType::SWAPCHAIN_IMAGE_VULKAN_KHR {
        return xr::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: the array holds `capacity` ≥ `app.len()` XrSwapchainImageVulkanKHR (checked `ty`).
    let out = unsafe { std::slice::from_raw_parts_mut(images as *mut xr::SwapchainImageVulkanKHR, app.len()) };
    for (o, &h) in out.iter_mut().zip(&app) {
        o.image = h;
    }
    let ours = i.our_images();
    tracing::info!("swapchain {:#x}: the layer's images {ours:x?} (the app's names {app:x?})", swapchain.into_raw());
    sc.session.instance.stats.swapchain_images.fetch_add(app.len() as u64, Ordering::Relaxed);
    bridge::shared().add_swapchain(Arc::new(bridge::Swapchain::new(swapchain.into_raw(), sc.desc.clone(), ours).upscaled()));
    xr::Result::SUCCESS
}
