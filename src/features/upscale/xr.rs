//! The upscale's OpenXR half (`upscale.enabled`; geometry and decisions in `rules`, the GPU work
//! in `vk`), called by the OpenXR shell at its places: the swapchain calls, `xrEndFrame`, the
//! session's end. Its state is the session's and the instance's (`SessionUpscale`,
//! `InstanceUpscale`, made by the registry); the shell hands it the session's interposed
//! swapchains (`Interposing`).
//!
//! - `xrEnumerateViewConfigurationViews` answers the recommended sizes times `upscale.scale`,
//!   latched from the first answer for the instance's life: engines ask once per instance (or
//!   poll), and a size that changed under their swapchains, or in a later session of the same
//!   instance, would break them. A changed `upscale.*` applies from the next instance.
//! - `xrCreateSwapchain` of a colour swapchain of a told view size (`rules::plan`) makes the
//!   runtime's swapchain at the display size, and the app's images, at the size it asked for, on
//!   its device (`Target`); `xrEnumerateSwapchainImages` hands out those.
//! - Acquire and wait go down as they are (the runtime's index is the app image's index);
//!   `xrReleaseSwapchainImage` keeps the runtime's image acquired (`pending`) until `xrEndFrame`,
//!   which upscales each pending image for the rects the frame submits, on the session's queue,
//!   then releases it and submits the frame with the rects in display pixels. The runtime's image
//!   is thus written only between its own acquire and release, and the app's calls pace as before.
//! - Anything the layer cannot make falls back to the swapchain the app asked for (logged); the
//!   runtime's own errors go to the app.

use crate::plugin::xr::{AmendedFrameEnd, Instance, Session, VulkanBinding};
use crate::core::rect::PixelRect;
use crate::core::views::SwapchainDesc;
use crate::features::upscale::rules::{self, Ask, Plan, ViewSizes};
use crate::features::upscale::record::{record_frame, Work};
use crate::features::upscale::slots::{Slots, MARKS};
use super::xr_layers::{pixel_rect, rewrite, sub_images};
use crate::features::upscale::lens::Tiles;
use crate::features::upscale::vk::{format_refusal, Job, Output, Pipelines, Target, TargetDesc};
use crate::features::upscale::UpscaleSettings;
use crate::plugin::settings::Settings;
use crate::plugin::vk::DeviceState;
use ash::vk;
use ash::vk::Handle as _;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The sizes latched for an instance: what the app was told while its sessions live.
#[derive(Clone, Debug)]
pub(crate) struct Latch {
    pub settings: UpscaleSettings,
    pub views: Vec<ViewSizes>,
}

/// An instance's upscale state.
#[derive(Default)]
pub(crate) struct InstanceUpscale {
    latch: Mutex<Option<Latch>>,
}

impl InstanceUpscale {
    pub(crate) fn latched(&self) -> Option<Latch> {
        lock(&self.latch).clone()
    }
}

/// `xrEnumerateViewConfigurationViews` answered `views`: told sizes replace the recommended ones
/// while the upscale is on (latched on the first answer).
pub(crate) fn views_enumerated(inst: &Instance, settings: &Settings, views: &mut [xr::ViewConfigurationView]) {
    let mut latch = lock(&inst.feature::<InstanceUpscale>().latch);
    let l = latch.get_or_insert_with(|| {
        if settings.of::<UpscaleSettings>().enabled && !settings.of::<UpscaleSettings>().mip_bias_valid {
            tracing::warn!("upscale: upscale.mip_bias is not auto, off or a number in -4..4; auto is used");
        }
        Latch { settings: *settings.of::<UpscaleSettings>(), views: Vec::new() }
    });
    if !l.settings.enabled {
        return;
    }
    if settings.of::<UpscaleSettings>().changed_from(&l.settings) {
        tracing::info!("upscale: its settings changed; the sizes told stay as latched until the instance ends");
    }
    let runtime: Vec<_> = views
        .iter()
        .map(|v| ((v.recommended_image_rect_width, v.recommended_image_rect_height), (v.max_image_rect_width, v.max_image_rect_height)))
        .collect();
    // The runtime's answer is the same on every call; a second call (or one for another view
    // configuration) re-derives the same told sizes.
    l.views = rules::told(&runtime, l.settings.scale);
    for (v, t) in views.iter_mut().zip(&l.views) {
        v.recommended_image_rect_width = t.render.0;
        v.recommended_image_rect_height = t.render.1;
    }
    // What the view features check the submitted sizes against.
    *lock(&inst.told_sizes) = Some(l.views.iter().map(|t| t.render).collect());
    tracing::info!("upscale: told the app {:?} for display sizes {:?} (scale {})", l.views.iter().map(|t| t.render).collect::<Vec<_>>(), l.views.iter().map(|t| t.display).collect::<Vec<_>>(), l.settings.scale);
}

/// The Vulkan functions at the app's level of the chain (the loader's entry points for the
/// session's instance and device): how the app-visible images are made, as a runtime makes its.
struct TopLevel {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    physical: vk::PhysicalDevice,
    family: u32,
    queue_index: u32,
}

/// A session's GPU objects, made at its first interposed swapchain.
struct Gpu {
    device: Arc<DeviceState>,
    top: TopLevel,
    pipelines: Pipelines,
    slots: Slots,
}

/// A session's upscale.
#[derive(Default)]
pub(crate) struct SessionUpscale {
    gpu: Mutex<Option<Gpu>>,
    /// Making the GPU objects failed: swapchains are left as the app asks (logged once).
    off: AtomicBool,
    /// Recording or submitting an upscale failed (logged once; counted).
    failures_logged: AtomicBool,
    unknown_layer_logged: AtomicBool,
    /// The lens's hidden area and the tiles it skips (`upscale.skip_hidden`).
    lens: super::xr_lens::LensCache,
}

impl std::fmt::Debug for SessionUpscale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionUpscale").field("off", &self.off).finish()
    }
}

/// One interposed swapchain.
pub(crate) struct Interposed {
    pub plan: Plan,
    pub sharpness: f32,
    target: Mutex<Target>,
    /// App images' first layout is recorded (at the first acquire).
    first_layouts: AtomicBool,
    /// Indices the app released and the layer still holds (oldest first), and whether the oldest
    /// acquired one was waited for.
    pub pending: Mutex<VecDeque<u32>>,
    pub waited: AtomicBool,
}

impl Interposed {
    /// The app images' handles as the app names them (`xrEnumerateSwapchainImages`).
    pub(crate) fn app_images(&self) -> Vec<u64> {
        lock(&self.target).app.iter().map(|i| i.top.as_raw()).collect()
    }
    /// The app images as this layer's Vulkan half names them.
    pub(crate) fn our_images(&self) -> Vec<u64> {
        lock(&self.target).app.iter().map(|i| i.ours.as_raw()).collect()
    }
}

fn xr_ok(what: &str, r: xr::Result) -> Result<(), String> {
    if r.into_raw() < 0 {
        Err(format!("{what}: {r:?}"))
    } else {
        Ok(())
    }
}

/// # Safety
/// The binding's handles are live (the session exists).
unsafe fn top_level(b: &VulkanBinding) -> Result<TopLevel, String> {
    // SAFETY: loading the system Vulkan loader, which the app's process has loaded already (its
    // instance was created through it); the handles are the app's live instance and device.
    unsafe {
        let entry = ash::Entry::load().map_err(|e| format!("the Vulkan loader: {e}"))?;
        let instance = ash::Instance::load(entry.static_fn(), vk::Instance::from_raw(b.instance));
        let device = ash::Device::load(instance.fp_v1_0(), vk::Device::from_raw(b.device));
        Ok(TopLevel { _entry: entry, instance, device, physical: vk::PhysicalDevice::from_raw(b.physical_device), family: b.queue_family_index, queue_index: b.queue_index })
    }
}

/// The session's upscale state (the registry makes it with the session).
fn up(s: &Session) -> &SessionUpscale {
    s.feature::<SessionUpscale>()
}

fn gpu_for(s: &Session) -> Result<(), String> {
    let mut g = lock(&up(s).gpu);
    if g.is_some() {
        return Ok(());
    }
    let b = s.binding.ok_or("the session has no Vulkan binding")?;
    if !s.vulkan_half {
        return Err("stereoshim's Vulkan layer is not in the session's device".into());
    }
    let device = b.device_key.state().ok_or("the session's device is not tracked")?;
    // SAFETY: the session is live, so its binding's handles are.
    let top = unsafe { top_level(&b) }?;
    let pipelines = Pipelines::new(&device)?;
    // SAFETY: the session's live physical device, at the app's level.
    let (props, families) = unsafe { (top.instance.get_physical_device_properties(top.physical), top.instance.get_physical_device_queue_family_properties(top.physical)) };
    let timed = families.get(b.queue_family_index as usize).is_some_and(|f| f.timestamp_valid_bits > 0);
    let period = if timed { props.limits.timestamp_period } else { 0.0 };
    let slots = match Slots::new(&device, b.queue_family_index, b.queue_index, period) {
        Ok(s) => s,
        Err(e) => {
            pipelines.destroy(&device);
            return Err(e);
        }
    };
    *g = Some(Gpu { device, top, pipelines, slots });
    Ok(())
}

/// What `xrCreateSwapchain` does for an interposed swapchain.
pub(crate) enum Created {
    /// Not interposed: create as the app asked.
    No,
    /// Interposed: the runtime's result, and the state (on success).
    Yes(xr::Result, Option<Box<Interposed>>),
}

fn usage_to_vk(u: xr::SwapchainUsageFlags) -> vk::ImageUsageFlags {
    use xr::SwapchainUsageFlags as X;
    [
        (X::COLOR_ATTACHMENT, vk::ImageUsageFlags::COLOR_ATTACHMENT),
        (X::DEPTH_STENCIL_ATTACHMENT, vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT),
        (X::UNORDERED_ACCESS, vk::ImageUsageFlags::STORAGE),
        (X::TRANSFER_SRC, vk::ImageUsageFlags::TRANSFER_SRC),
        (X::TRANSFER_DST, vk::ImageUsageFlags::TRANSFER_DST),
        (X::SAMPLED, vk::ImageUsageFlags::SAMPLED),
        (X::INPUT_ATTACHMENT, vk::ImageUsageFlags::INPUT_ATTACHMENT),
    ]
    .iter()
    .filter(|(x, _)| u.contains(*x))
    .fold(vk::ImageUsageFlags::empty(), |a, (_, v)| a | *v)
}


/// Decides and, when interposing, creates the runtime's swapchain at the display size
/// (`create` calls down with a create info) and the app's images.
pub(crate) fn create_swapchain(
    s: &Session,
    ci: &xr::SwapchainCreateInfo,
    features_usage: xr::SwapchainUsageFlags,
    create: &mut dyn FnMut(&xr::SwapchainCreateInfo) -> xr::Result,
    handle: &dyn Fn() -> xr::Swapchain,
) -> Created {
    let Some(latch) = s.instance.feature::<InstanceUpscale>().latched() else { return Created::No };
    if !latch.settings.enabled || up(s).off.load(Ordering::Relaxed) {
        return Created::No;
    }
    let format = i32::try_from(ci.format).map(vk::Format::from_raw).unwrap_or(vk::Format::UNDEFINED);
    let ask = Ask {
        width: ci.width,
        height: ci.height,
        sample_count: ci.sample_count,
        face_count: ci.face_count,
        mip_count: ci.mip_count,
        depth: ci.usage_flags.contains(xr::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT) || !crate::plugin::vk::convert::format_aspects(format).contains(vk::ImageAspectFlags::COLOR),
        protected: ci.create_flags.contains(xr::SwapchainCreateFlags::PROTECTED_CONTENT),
    };
    let plan = match rules::plan(&ask, &latch.views) {
        Ok(p) => p,
        Err(skip) => {
            tracing::info!("upscale: swapchain {}x{} format {} left as asked: {}", ci.width, ci.height, ci.format, skip.why());
            return Created::No;
        }
    };
    if let Err(e) = gpu_for(s) {
        tracing::warn!("upscale: cannot run on this session ({e}); its swapchains are left as the app asks");
        up(s).off.store(true, Ordering::Relaxed);
        return Created::No;
    }
    let refusal = {
        let g = lock(&up(s).gpu);
        let g = g.as_ref().expect("made above");
        // SAFETY: the session's live physical device, at the app's level.
        let props = unsafe { g.top.instance.get_physical_device_format_properties(g.top.physical, format) };
        format_refusal(props, latch.settings.method)
    };
    if let Some(why) = refusal {
        tracing::warn!("upscale: swapchain format {format:?} cannot be upscaled ({why}); this swapchain is left as the app asks");
        return Created::No;
    }
    let output = Output::of(format);
    // The upscale draws into the runtime's image as a colour attachment, or copies into it.
    let needs = match output {
        Output::Copy { .. } => xr::SwapchainUsageFlags::TRANSFER_DST,
        Output::Fragment => xr::SwapchainUsageFlags::COLOR_ATTACHMENT,
    };
    let runtime_ci = xr::SwapchainCreateInfo {
        width: plan.runtime.0,
        height: plan.runtime.1,
        // The app's mip chain stays its own: the runtime gets the upscaled level 0. Its samples
        // too: the runtime gets the upscale of their resolve.
        mip_count: 1,
        sample_count: 1,
        // What features add to swapchains (a screenshot's copy of the display-size image) too.
        usage_flags: ci.usage_flags | needs | features_usage,
        ..*ci
    };
    let (r, created) = crate::bridge::swapchain_images::capture(|| create(&runtime_ci));
    if r != xr::Result::SUCCESS {
        tracing::warn!("upscale: the runtime refused its {}x{} swapchain: {r:?} (given to the app)", plan.runtime.0, plan.runtime.1);
        return Created::Yes(r, None);
    }
    let swapchain = handle();
    match make_target(s, ci, &runtime_ci, (format, output), plan, swapchain, &created, &latch.settings) {
        Ok(i) => {
            let i = Box::new(i);
            tracing::info!(
                "upscale: swapchain {:#x}: the app renders {}x{} ({} samples, {} mip levels), the runtime shows {}x{} ({:?}, {output:?})",
                swapchain.into_raw(),
                ci.width,
                ci.height,
                ci.sample_count,
                ci.mip_count,
                plan.runtime.0,
                plan.runtime.1,
                latch.settings.method
            );
            Created::Yes(r, Some(i))
        }
        Err(e) => {
            tracing::warn!("upscale: swapchain {}x{} cannot be interposed ({e}); it is made as the app asks", ci.width, ci.height);
            if let Some(f) = s.instance.next.destroy_swapchain {
                // SAFETY: our just-created swapchain, nothing acquired.
                let _ = unsafe { f(swapchain) };
            }
            Created::No
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn make_target(
    s: &Session,
    ci: &xr::SwapchainCreateInfo,
    runtime_ci: &xr::SwapchainCreateInfo,
    (format, output): (vk::Format, Output),
    plan: Plan,
    swapchain: xr::Swapchain,
    created: &[crate::bridge::swapchain_images::CreatedImage],
    settings: &UpscaleSettings,
) -> Result<Interposed, String> {
    let enumerate = s.instance.next.enumerate_swapchain_images.ok_or("no xrEnumerateSwapchainImages")?;
    let mut n = 0u32;
    // SAFETY: our live swapchain; a count query.
    xr_ok("xrEnumerateSwapchainImages", unsafe { enumerate(swapchain, 0, &mut n, std::ptr::null_mut()) })?;
    let blank = xr::SwapchainImageVulkanKHR { ty: xr::SwapchainImageVulkanKHR::TYPE, next: std::ptr::null_mut(), image: 0 };
    let mut reported = vec![blank; n as usize];
    // SAFETY: `reported` holds `n` typed Vulkan image structs.
    xr_ok("xrEnumerateSwapchainImages", unsafe { enumerate(swapchain, n, &mut n, reported.as_mut_ptr().cast()) })?;
    reported.truncate(n as usize);
    let wanted = crate::bridge::swapchain_images::Wanted {
        format: runtime_ci.format,
        width: runtime_ci.width,
        height: runtime_ci.height,
        array_size: runtime_ci.array_size,
        sample_count: runtime_ci.sample_count,
        mip_count: runtime_ci.mip_count,
    };
    let runtime_images: Vec<vk::Image> = crate::bridge::swapchain_images::match_images(&wanted, created, &reported.iter().map(|r| r.image).collect::<Vec<_>>())
        .images()
        .iter()
        .map(|&h| vk::Image::from_raw(h))
        .collect();
    let desc = TargetDesc {
        format,
        extent: (ci.width, ci.height),
        layers: ci.array_size.max(1),
        mips: ci.mip_count.max(1),
        samples: ci.sample_count.max(1),
        usage: usage_to_vk(ci.usage_flags),
        mutable_format: ci.usage_flags.contains(xr::SwapchainUsageFlags::MUTABLE_FORMAT),
        runtime_extent: plan.runtime,
        runtime_images,
        method: settings.method,
        output,
    };
    let g = lock(&up(s).gpu);
    let g = g.as_ref().ok_or("no GPU objects")?;
    let capture = |f: &mut dyn FnMut()| -> Option<vk::Image> {
        let ((), c) = crate::bridge::swapchain_images::capture(f);
        c.first().map(|c| vk::Image::from_raw(c.image))
    };
    // SAFETY: `top` is the app-level table of the session's device; the runtime images are the
    // live images of the swapchain just made.
    let target = unsafe { Target::new(&g.device, &g.top.device, &g.pipelines, desc, n as usize, &capture) }?;
    Ok(Interposed {
        plan,
        sharpness: settings.sharpness,
        target: Mutex::new(target),
        first_layouts: AtomicBool::new(false),
        pending: Mutex::default(),
        waited: AtomicBool::new(false),
    })
}

/// The app's first acquire of an interposed swapchain: its images get the layout the binding
/// promises at acquire, on the session's queue, through the app's level (so layers above see it).
pub(crate) fn acquired(s: &Session, i: &Interposed) {
    if i.first_layouts.swap(true, Ordering::AcqRel) {
        return;
    }
    // What is needed is taken under the locks; the submission and its wait go without them.
    let (device, family, queue_index, barriers) = {
        let g = lock(&up(s).gpu);
        let Some(g) = g.as_ref() else { return };
        (g.top.device.clone(), g.top.family, g.top.queue_index, lock(&i.target).first_layout_barriers())
    };
    // SAFETY: objects made and destroyed here through the app-level table; the session's queue,
    // which the binding lets the runtime (and so a layer) use inside xrAcquireSwapchainImage;
    // the fence wait makes sure the buffer is done before it is freed.
    let r: Result<(), String> = unsafe {
        (|| {
            let pool = device.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family), None).map_err(|e| format!("vkCreateCommandPool: {e}"))?;
            let done = (|| {
                let cb = device.allocate_command_buffers(&vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1)).map_err(|e| format!("vkAllocateCommandBuffers: {e}"))?[0];
                device.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
                device.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT, vk::DependencyFlags::empty(), &[], &[], &barriers);
                device.end_command_buffer(cb).map_err(|e| format!("vkEndCommandBuffer: {e}"))?;
                let fence = device.create_fence(&vk::FenceCreateInfo::default(), None).map_err(|e| format!("vkCreateFence: {e}"))?;
                let queue = device.get_device_queue(family, queue_index);
                let cbs = [cb];
                let r = device.queue_submit(queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], fence).map_err(|e| format!("vkQueueSubmit: {e}"));
                let r = r.and_then(|()| device.wait_for_fences(&[fence], true, 2_000_000_000).map_err(|e| format!("vkWaitForFences: {e}")));
                device.destroy_fence(fence, None);
                r
            })();
            device.destroy_command_pool(pool, None);
            done
        })()
    };
    if let Err(e) = r {
        tracing::warn!("upscale: the first layout of the app's images failed ({e}); the app's first frame may show garbage");
    }
}

/// One held image's upscale for a frame: its jobs, and per job where EASU runs.
struct Held<'a> {
    handle: u64,
    /// The app's swapchain's description (at the app's size).
    desc: &'a SwapchainDesc,
    i: &'a Interposed,
    index: u32,
    jobs: Vec<Job>,
    fovea: Vec<[f32; 4]>,
    /// Per job, the projection view it shows (None: another layer's, or a whole image).
    views: Vec<Option<u32>>,
    /// Per job, the tiles the lens never shows (`upscale.skip_hidden`).
    tiles: Vec<Option<Arc<Tiles>>>,
}

/// A job of the frame: its swapchain, the job, where EASU runs, the projection view it shows and
/// the tiles the lens never shows there.
type FrameJob = (u64, Job, [f32; 4], Option<u32>, Option<Arc<Tiles>>);

/// The runtime rect of the app's `rect` of a projection view (`projection`) or another layer.
fn runtime_rect(i: &Interposed, app_extent: (u32, u32), rect: PixelRect, projection: bool) -> Option<(PixelRect, PixelRect)> {
    let src = rules::clamp_to(rect, app_extent)?;
    let dst = if projection { rules::runtime_rect(src, i.plan.k, i.plan.view, i.plan.runtime)? } else { rules::scaled_rect(src, i.plan.k, app_extent, i.plan.runtime)? };
    Some((src, dst))
}

/// Where EASU runs for a projection view's job (`upscale.fovea_only`): the foveation's inner
/// region of the view (its fixed centre when foveation publishes none), else everywhere.
fn fovea_of(settings: &Settings, view: Option<(u32, xr::Fovf)>, dst: PixelRect) -> [f32; 4] {
    let (true, Some((index, fov))) = (settings.of::<UpscaleSettings>().fovea_only, view) else { return [0.0; 4] };
    let published = crate::bridge::shared().foveation();
    let (center, inner) = published.views.iter().find(|f| f.view == index).map_or(([0.0, 0.0], settings.of::<UpscaleSettings>().fovea_inner_deg), |f| (f.center, f.inner_deg));
    let tan = [fov.angle_left.tan(), fov.angle_right.tan(), fov.angle_up.tan(), fov.angle_down.tan()];
    rules::fovea_ellipse(center, inner, tan, dst)
}

/// An interposed swapchain of a session, as the shell keeps it: its handle, its description at
/// the app's size, and the upscale's state of it.
#[derive(Clone, Copy)]
pub(crate) struct Interposing<'a> {
    pub handle: u64,
    pub desc: &'a SwapchainDesc,
    pub i: &'a Interposed,
}

/// Jobs of a whole image (an image released without being submitted in a frame).
fn whole_jobs(i: &Interposed, extent: (u32, u32), layers: u32) -> Vec<Job> {
    (0..layers.max(1))
        .filter_map(|layer| runtime_rect(i, extent, PixelRect { x: 0, y: 0, width: extent.0, height: extent.1 }, false).map(|(src, dst)| Job { layer, src, dst }))
        .collect()
}

/// `xrReleaseSwapchainImage` of an interposed swapchain: held until the frame ends. An image
/// still held from before goes first (upscaled whole: no frame named its rects).
pub(crate) fn release(s: &Session, sc: Interposing<'_>, index: u32) -> xr::Result {
    let Interposing { handle, desc, i } = sc;
    let older: Vec<u32> = lock(&i.pending).drain(..).collect();
    if !older.is_empty() {
        let (extent, layers) = ((desc.width, desc.height), desc.array_size);
        let work: Vec<Held<'_>> = older.iter().map(|&index| Held { handle, desc, i, index, jobs: whole_jobs(i, extent, layers), fovea: Vec::new(), views: Vec::new(), tiles: Vec::new() }).collect();
        let r = run_and_release(s, &work);
        if r.into_raw() < 0 {
            return r;
        }
    }
    lock(&i.pending).push_back(index);
    i.waited.store(false, Ordering::Release);
    xr::Result::SUCCESS
}

/// Records and submits the upscales of `work`, then releases their runtime images (oldest first):
/// the first failing release's result.
fn run_and_release(s: &Session, work: &[Held<'_>]) -> xr::Result {
    match submit(s, work) {
        Err(e) => {
            if !up(s).failures_logged.swap(true, Ordering::Relaxed) {
                tracing::warn!("upscale: an upscale could not be submitted ({e}); the runtime's image keeps its old pixels this frame");
            }
        }
        Ok(()) => display_ready(s, work),
    }
    let Some(release) = s.instance.next.release_swapchain_image else { return xr::Result::ERROR_FUNCTION_UNSUPPORTED };
    let info = xr::SwapchainImageReleaseInfo { ty: xr::SwapchainImageReleaseInfo::TYPE, next: std::ptr::null() };
    let mut first = xr::Result::SUCCESS;
    for w in work {
        // SAFETY: the runtime's swapchain, whose oldest acquired image is the one held.
        let r = unsafe { release(xr::Swapchain::from_raw(w.handle), &info) };
        if r.into_raw() < 0 && first == xr::Result::SUCCESS {
            first = r;
        }
    }
    first
}

/// The upscaled projection views of `work` go to the features that read the display-size images
/// (screenshots), on the session's queue after the upscale, before the runtime gets them back.
fn display_ready(s: &Session, work: &[Held<'_>]) {
    let binding = s.binding.map(|b| (b.device_key, b.queue_family_index, b.queue_index));
    for w in work {
        let views: Vec<(u32, crate::core::views::ImageRect, u32)> = w
            .jobs
            .iter()
            .zip(&w.views)
            .filter_map(|(j, v)| v.map(|v| (v, crate::core::views::ImageRect { x: j.dst.x, y: j.dst.y, width: j.dst.width as i32, height: j.dst.height as i32 }, j.layer)))
            .collect();
        let Some(&image) = lock(&w.i.target).desc.runtime_images.get(w.index as usize) else { continue };
        if views.is_empty() {
            continue;
        }
        let desc = crate::core::views::SwapchainDesc { width: w.i.plan.runtime.0, height: w.i.plan.runtime.1, ..w.desc.clone() };
        let display = crate::bridge::Swapchain::new(w.handle, desc, vec![image.as_raw()]);
        crate::plugin::vk::display_ready(binding, &display, image.as_raw(), &views);
    }
}

fn submit(s: &Session, work: &[Held<'_>]) -> Result<(), String> {
    let work: Vec<&Held<'_>> = work.iter().filter(|w| !w.jobs.is_empty()).collect();
    if work.is_empty() {
        return Ok(());
    }
    // A full slot ring's oldest upscale is waited for with no lock held.
    let due = lock(&up(s).gpu).as_ref().and_then(|g| g.slots.due(&g.device).map(|f| (g.device.clone(), f)));
    if let Some((d, fence)) = due {
        crate::features::upscale::slots::wait(&d, fence);
    }
    // Recorded under the session's lock; submitted after it is let go (no lock of the layer's is
    // held while the submission goes down the chain).
    let (d, queue, cb, fence, gpu_ms, phases_ms) = {
        let mut g = lock(&up(s).gpu);
        let g = g.as_mut().ok_or("no GPU objects")?;
        let d = g.device.clone();
        // Locked in the frame's swapchain order; no other code holds two targets at once.
        let mut targets: Vec<_> = work.iter().map(|w| lock(&w.i.target)).collect();
        let (cb, fence) = g.slots.take(&d)?;
        // SAFETY: a command buffer of the layer's, not in use (its fence signalled or it is new).
        let recorded = unsafe {
            (|| {
                d.fns.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
                g.slots.mark(&d, cb, 0);
                let preps: Vec<_> = work.iter().zip(targets.iter_mut()).map(|(w, t)| t.record_tile_uploads(&d, cb, &w.tiles)).collect();
                let frame: Vec<Work<'_>> = work
                    .iter()
                    .zip(&targets)
                    .zip(preps)
                    .map(|((w, t), prep)| Work { target: t, index: w.index as usize, jobs: &w.jobs, fovea: &w.fovea, tiles: &w.tiles, prep, sharpness: w.i.sharpness })
                    .collect();
                record_frame(&d, &g.pipelines, cb, &frame, &|k| g.slots.mark(&d, cb, k));
                g.slots.mark(&d, cb, MARKS - 1);
                d.fns.end_command_buffer(cb).map_err(|e| format!("vkEndCommandBuffer: {e}"))
            })()
        };
        if let Err(e) = recorded {
            g.slots.abandon(&d, cb);
            targets.iter_mut().for_each(|t| t.forget_tiles());
            return Err(e);
        }
        (d, g.slots.queue, cb, fence, g.slots.last_gpu_ms, g.slots.last_phases_ms.clone())
    };
    // SAFETY: the recorded command buffer and its fence (unsignalled); the session's queue, used
    // inside xrEndFrame / xrReleaseSwapchainImage as the binding allows.
    let r = unsafe {
        let bracket = crate::plugin::vk::gpu_time::start(&d, queue, 1, true);
        let cbs = match &bracket {
            Some(b) => vec![b.begin, cb, b.end],
            None => vec![cb],
        };
        let r = d.fns.queue_submit(queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], fence);
        if let Some(b) = bracket {
            crate::plugin::vk::gpu_time::submitted(&d, b, queue, r.is_ok());
        }
        r.map_err(|e| format!("vkQueueSubmit: {e}"))
    };
    if r.is_err() {
        if let Some(g) = lock(&up(s).gpu).as_mut() {
            g.slots.abandon(&d, cb);
        }
        // The tile uploads it recorded never ran.
        work.iter().for_each(|w| lock(&w.i.target).forget_tiles());
    } else {
        let jobs: usize = work.iter().map(|w| w.jobs.len()).sum();
        let pixels: u64 = work.iter().flat_map(|w| &w.jobs).map(|j| j.dst.area()).sum();
        let rendered: u64 = work.iter().flat_map(|w| &w.jobs).map(|j| j.src.area()).sum();
        crate::bridge::shared().upscale_counts(jobs as u64, rendered, pixels, gpu_ms, &phases_ms);
    }
    r
}

/// `xrEndFrame` of session `s` with the (possibly amended) `info`: upscales and releases the held
/// images of the session's interposed swapchains (`scs`), and returns the frame with every
/// interposed sub-image's rect in display pixels (None: nothing of the frame is interposed).
pub(crate) fn frame_end(s: &Session, info: &xr::FrameEndInfo, scs: &[Interposing<'_>]) -> Option<AmendedFrameEnd> {
    if scs.is_empty() {
        return None;
    }
    // SAFETY: the frame's layer pointers, valid for this call (non-null when counted: checked).
    let layers: Vec<*const xr::CompositionLayerBaseHeader> = if info.layer_count > 0 && info.layers.is_null() { Vec::new() } else { unsafe { crate::plugin::vk::convert::slice(info.layers, info.layer_count) }.to_vec() };
    let find = |h: xr::Swapchain| scs.iter().find(|sc| sc.handle == h.into_raw());
    // The jobs each interposed swapchain's latest held image gets from this frame, with where
    // EASU runs.
    let settings = crate::plugin::xr::settings(&s.instance);
    let mut jobs: Vec<FrameJob> = Vec::new();
    let mut unknown = false;
    for &l in &layers {
        // SAFETY: the app's layer, valid for this call.
        match unsafe { sub_images(l) } {
            Some((projection, subs)) => {
                for (sub, view) in subs {
                    let Some(sc) = find(sub.swapchain) else { continue };
                    let handle = sub.swapchain.into_raw();
                    let i = sc.i;
                    if let Some((src, dst)) = runtime_rect(i, (sc.desc.width, sc.desc.height), pixel_rect(&sub.image_rect), projection) {
                        let job = Job { layer: sub.image_array_index, src, dst };
                        if !jobs.iter().any(|(h, j, _, _, _)| *h == handle && *j == job) {
                            let tiles = view.filter(|_| settings.of::<UpscaleSettings>().skip_hidden).and_then(|(v, fov)| up(s).lens.tiles(s, v, &fov, dst));
                            jobs.push((handle, job, fovea_of(&settings, view, dst), view.map(|v| v.0), tiles));
                        }
                    }
                }
            }
            None => unknown = true,
        }
    }
    if unknown && !up(s).unknown_layer_logged.swap(true, Ordering::Relaxed) {
        tracing::warn!("upscale: the frame has a composition layer of a type the layer does not read; if it shows an interposed swapchain, its rect is in the app's pixels");
    }
    let mut work = Vec::new();
    for sc in scs {
        let (handle, desc, i) = (sc.handle, sc.desc, sc.i);
        let held: Vec<u32> = lock(&i.pending).drain(..).collect();
        let n = held.len();
        for (k, index) in held.into_iter().enumerate() {
            let mine: Vec<_> = jobs.iter().filter(|m| m.0 == handle).collect();
            // The latest held image is what the frame shows; older ones go out whole.
            let held = if k + 1 == n && !mine.is_empty() {
                Held {
                    handle,
                    desc,
                    i,
                    index,
                    jobs: mine.iter().map(|m| m.1).collect(),
                    fovea: mine.iter().map(|m| m.2).collect(),
                    views: mine.iter().map(|m| m.3).collect(),
                    tiles: mine.iter().map(|m| m.4.clone()).collect(),
                }
            } else {
                Held { handle, desc, i, index, jobs: whole_jobs(i, (desc.width, desc.height), desc.array_size), fovea: Vec::new(), views: Vec::new(), tiles: Vec::new() }
            };
            work.push(held);
        }
    }
    let r = run_and_release(s, &work);
    if r.into_raw() < 0 {
        tracing::warn!("upscale: the runtime refused a release ({r:?})");
    }
    Some(rewrite(info, &layers, &|h, rect, projection| {
        let sc = find(h)?;
        runtime_rect(sc.i, (sc.desc.width, sc.desc.height), rect, projection).map(|(_, dst)| dst)
    }))
}

/// Destroys an interposed swapchain's objects (before the runtime's swapchain goes down).
pub(crate) fn destroy(s: &Session, i: &Interposed) {
    // The app-facing images are the layer's, and the app may still have work in flight on them:
    // the spec asks it to finish first, but apps do not always (Bevy leaves its last frame's
    // submissions running when it drops the swapchain at exit), and runtimes tolerate it by
    // waiting on the session's queue. The layer waits the same way, through the app's level, so
    // that the layers above (validation among them) see the work retired before the images go;
    // a wait only on the layer's own fences would leave them counting the images as in use.
    // Taken outside the feature's lock: the wait may be long.
    let top = {
        let g = lock(&up(s).gpu);
        let Some(g) = g.as_ref() else { return };
        if !crate::plugin::vk::device_is_live(&g.device) {
            return;
        }
        (g.top.device.clone(), g.top.family, g.top.queue_index)
    };
    let (device, family, queue_index) = top;
    // SAFETY: the session's live device and queue at the app's level. xrDestroySwapchain is not
    // among the calls in which XR_KHR_vulkan_enable hands the runtime the queue, so an app
    // submitting on it from another thread during this call would race the wait; runtimes wait
    // here all the same (the mock runtime on this queue), and no app is known to do that.
    if let Err(e) = unsafe { device.queue_wait_idle(device.get_device_queue(family, queue_index)) } {
        tracing::warn!("upscale: waiting for the session's queue before destroying swapchain images failed ({e}); the layer waits for its own upscales only");
    }
    let g = lock(&up(s).gpu);
    let Some(g) = g.as_ref() else { return };
    g.slots.wait_all(&g.device);
    // SAFETY: the objects are idle (waited above); `top` is the app-level table of their device.
    unsafe { lock(&i.target).destroy(&g.device, &g.top.device) };
}

/// The session ends: the GPU objects go (its swapchains went first).
pub(crate) fn session_destroyed(s: &Session) {
    let Some(mut g) = lock(&up(s).gpu).take() else { return };
    if !crate::plugin::vk::device_is_live(&g.device) {
        tracing::warn!("upscale: the app destroyed the session's VkDevice before the session; its Vulkan objects went with the device");
        return;
    }
    g.slots.destroy(&g.device);
    g.pipelines.destroy(&g.device);
}
