//! The in-headset stats overlay's OpenXR half (`overlay.enabled`; the text and placement rules are
//! in `rules`), called by the OpenXR shell at `xrEndFrame` and when sessions end; its state is the
//! session's `OverlaySession` (made by the registry). At a session's first frame with the overlay on, the layer makes
//! its own objects down the chain — a small colour swapchain, a VIEW reference space (the panel
//! is head-locked) and, on the session's Vulkan device, a staging buffer, a command buffer and a
//! fence — and from then on appends one quad layer after the app's layers at every `xrEndFrame`.
//! Its text changes at most once a second (a completed second of the stats window): only then is
//! one swapchain image acquired, filled by a buffer-to-image copy on the session's queue (allowed
//! inside `xrEndFrame` by the OpenXR Vulkan binding, as RDM's reconstruction is inside
//! `xrReleaseSwapchainImage`) and released; the runtime shows the last released image otherwise.
//! Anything that fails is logged once and the session goes on without the overlay. The objects
//! die with the session (`destroy`, before `xrDestroySession` goes down).

use super::OverlaySettings;
use super::rules::{self, Window};
use crate::plugin::xr::Session;
use crate::plugin::settings::Settings;
use crate::report::summary::Second;
use crate::plugin::vk::DeviceState;
use ash::vk;
use ash::vk::Handle as _;
use openxr_sys as xr;
use openxr_sys::Handle as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// How long the layer waits for its previous upload or for the swapchain image: the runtime has
/// long released it (one upload a second), so this is only reached on a broken device.
const WAIT_NS: u64 = 1_000_000_000;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A session's overlay.
#[derive(Default)]
pub(crate) struct OverlaySession {
    /// The objects, once made; taken out while in use, so no lock is held while calling down.
    live: Mutex<Option<Box<Overlay>>>,
    /// Making or using the objects failed: no overlay for the rest of the session.
    off: AtomicBool,
    /// The app already uses every layer the system allows (logged once).
    layers_full_logged: AtomicBool,
    text: Mutex<Text>,
}

#[derive(Default)]
struct Text {
    window: Window,
    last: Option<Second>,
    /// The last frames' times (between their `xrEndFrame`s), ms, oldest first: the graph.
    times: std::collections::VecDeque<f32>,
    last_end: Option<f64>,
    enabled: Vec<(&'static str, bool)>,
    /// The text changed since the last upload.
    dirty: bool,
}

/// The layer's own objects for one session's overlay.
struct Overlay {
    device: Arc<DeviceState>,
    swapchain: xr::Swapchain,
    space: xr::Space,
    /// The swapchain's images, as this layer's Vulkan calls must name them.
    images: Vec<vk::Image>,
    bgra: bool,
    width: u32,
    height: u32,
    max_layers: u32,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    /// `memory` mapped for the whole session (host-coherent), as an address.
    mapped: usize,
    pool: vk::CommandPool,
    cb: vk::CommandBuffer,
    fence: vk::Fence,
    queue: vk::Queue,
    /// An image was released: the quad may be submitted.
    released: bool,
}

fn xr_check(what: &str, r: xr::Result) -> Result<(), String> {
    if r.into_raw() < 0 {
        Err(format!("{what}: {r:?}"))
    } else {
        Ok(())
    }
}

fn vk_err(what: &'static str) -> impl Fn(vk::Result) -> String {
    move |e| format!("{what}: {e}")
}

/// The session's overlay state (the registry makes it with the session).
fn state(s: &Session) -> &OverlaySession {
    s.feature::<OverlaySession>()
}

/// The quad to append to this frame's layers (`app_layers`: how many the app submits), with the
/// overlay's objects made on first use and its image refreshed when the text changed. None: the
/// overlay is off, failed, or there is no room for another layer. `enabled_now`: the features on
/// under `settings` (the registry's list), for the first image, before any frame told them.
pub(crate) fn quad(s: &Session, settings: &Settings, app_layers: u32, enabled_now: &dyn Fn() -> Vec<(&'static str, bool)>) -> Option<xr::CompositionLayerQuad> {
    let o = state(s);
    if !settings.of::<OverlaySettings>().enabled || o.off.load(Ordering::Relaxed) {
        return None;
    }
    let taken = lock(&o.live).take();
    let mut ov = match taken {
        Some(ov) => ov,
        None => match setup(s) {
            Ok(ov) => {
                tracing::info!("overlay: {}x{} swapchain {:#x} in a VIEW space, up to {} layers a frame", ov.width, ov.height, ov.swapchain.into_raw(), ov.max_layers);
                // The first image shows the features on, before any second is complete.
                lock(&o.text).dirty = true;
                Box::new(ov)
            }
            Err(e) => {
                tracing::warn!("overlay: cannot be shown ({e}); the session goes on without it");
                o.off.store(true, Ordering::Relaxed);
                return None;
            }
        },
    };
    if app_layers >= ov.max_layers {
        if !o.layers_full_logged.swap(true, Ordering::Relaxed) {
            tracing::warn!("overlay: the app submits {app_layers} layers, the system's maxLayerCount; no room for the overlay (not shown while that lasts)");
        }
        *lock(&o.live) = Some(ov);
        return None;
    }
    let lines = {
        let mut t = lock(&o.text);
        if std::mem::take(&mut t.dirty) || !ov.released {
            if t.enabled.is_empty() {
                t.enabled = enabled_now();
            }
            Some((rules::lines(&t.enabled, t.last.as_ref(), last_ab().as_deref()), t.times.iter().copied().collect::<Vec<f32>>()))
        } else {
            None
        }
    };
    if let Some((lines, graph)) = lines {
        if let Err(e) = upload(s, &mut ov, &lines, &graph) {
            tracing::warn!("overlay: updating its image failed ({e}); the session goes on without it");
            o.off.store(true, Ordering::Relaxed);
            destroy_objects(s, *ov);
            return None;
        }
    }
    let q = ov.released.then(|| {
        let p = rules::placement(settings.of::<OverlaySettings>().position, settings.of::<OverlaySettings>().distance_m, settings.of::<OverlaySettings>().scale);
        xr::CompositionLayerQuad {
            ty: xr::CompositionLayerQuad::TYPE,
            next: std::ptr::null(),
            layer_flags: xr::CompositionLayerFlags::BLEND_TEXTURE_SOURCE_ALPHA,
            space: ov.space,
            eye_visibility: xr::EyeVisibility::BOTH,
            sub_image: xr::SwapchainSubImage {
                swapchain: ov.swapchain,
                image_rect: xr::Rect2Di { offset: xr::Offset2Di { x: 0, y: 0 }, extent: xr::Extent2Di { width: ov.width as i32, height: ov.height as i32 } },
                image_array_index: 0,
            },
            pose: xr::Posef {
                orientation: xr::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w: 1.0 },
                position: xr::Vector3f { x: p.position.x, y: p.position.y, z: p.position.z },
            },
            size: xr::Extent2Df { width: p.width_m, height: p.height_m },
        }
    });
    *lock(&o.live) = Some(ov);
    q
}

/// A frame ended under `settings` with `record`: the stats window learns it, and the text is
/// redrawn when a second completed or the features on changed.
pub(crate) fn frame_ended(s: &Session, settings: &Settings, record: &crate::report::stats_file::FrameRecord, enabled: &[(&'static str, bool)]) {
    if !settings.of::<OverlaySettings>().enabled || state(s).off.load(Ordering::Relaxed) {
        return;
    }
    let frame = crate::report::summary::parse_line(&record.to_json());
    let mut t = lock(&state(s).text);
    if let Some(before) = t.last_end.replace(record.time) {
        if t.times.len() == rules::graph_frames() {
            t.times.pop_front();
        }
        t.times.push_back(((record.time - before) * 1e3).max(0.0) as f32);
    }
    if t.enabled != enabled {
        t.enabled = enabled.to_vec();
        t.dirty = true;
    }
    if let Ok(Some(f)) = frame {
        if let Some(second) = t.window.add(&f) {
            t.last = Some(second);
            t.dirty = true;
        }
    }
}

/// The first outcome of the last A/B `stereoshim top` ran in this app (`core::live::ab_file`),
/// read when the text is redrawn (once a second at most).
fn last_ab() -> Option<String> {
    let base = crate::manifests::private_fs::private_base(&|k| std::env::var(k).ok())?;
    let text = std::fs::read_to_string(crate::core::live::ab_file(&crate::core::live::folder(&base), std::process::id())).ok()?;
    text.lines().next().map(|l| l.trim().to_string()).filter(|l| !l.is_empty())
}

/// The runtime refused a frame with the overlay's quad (`r`): no overlay for the rest of the
/// session (the frame then went down without it).
pub(crate) fn refused(s: &Session, r: xr::Result) {
    if !state(s).off.swap(true, Ordering::Relaxed) {
        tracing::warn!("overlay: the runtime refused the frame with the overlay's layer ({r:?}); the app's frame went down without it, and the overlay stays off");
    }
}

/// Reads a two-call list of swapchain formats.
fn formats(s: &Session) -> Result<Vec<i64>, String> {
    let f = s.instance.next.enumerate_swapchain_formats.ok_or("no xrEnumerateSwapchainFormats")?;
    let mut n = 0u32;
    // SAFETY: the session is live; a count query with a valid output pointer.
    xr_check("xrEnumerateSwapchainFormats", unsafe { f(s.handle, 0, &mut n, std::ptr::null_mut()) })?;
    let mut v = vec![0i64; n as usize];
    // SAFETY: `v` holds `n` elements.
    xr_check("xrEnumerateSwapchainFormats", unsafe { f(s.handle, n, &mut n, v.as_mut_ptr()) })?;
    v.truncate(n as usize);
    Ok(v)
}

/// The system's `maxLayerCount`.
fn max_layers(s: &Session) -> Result<u32, String> {
    let f = s.instance.next.get_system_properties.ok_or("no xrGetSystemProperties")?;
    // SAFETY: a plain-data output struct: zero is a valid value of every field.
    let mut p: xr::SystemProperties = unsafe { std::mem::zeroed() };
    p.ty = xr::SystemProperties::TYPE;
    // SAFETY: the instance is live, the system id the one the session was created for, `p` a
    // valid output struct with its type set.
    xr_check("xrGetSystemProperties", unsafe { f(s.instance.handle, s.system_id, &mut p) })?;
    Ok(p.graphics_properties.max_layer_count)
}

fn setup(s: &Session) -> Result<Overlay, String> {
    let b = s.binding.ok_or("the session has no Vulkan binding")?;
    if !s.vulkan_half {
        return Err("stereoshim's Vulkan layer is not in the session's device".into());
    }
    let device = b.device_key.state().ok_or("the session's device is not tracked")?;
    let max_layers = max_layers(s)?;
    let offered = formats(s)?;
    let format = rules::choose_format(&offered).ok_or_else(|| format!("no 8-bit RGBA/BGRA swapchain format among {offered:?}"))?;
    let (width, height) = rules::texture_size();
    let next = &s.instance.next;
    let (create, enumerate, destroy_sc) = match (next.create_swapchain, next.enumerate_swapchain_images, next.destroy_swapchain) {
        (Some(c), Some(e), Some(d)) => (c, e, d),
        _ => return Err("the runtime lacks swapchain functions".into()),
    };
    let create_space = next.create_reference_space.ok_or("no xrCreateReferenceSpace")?;
    let ci = xr::SwapchainCreateInfo {
        ty: xr::SwapchainCreateInfo::TYPE,
        next: std::ptr::null(),
        create_flags: xr::SwapchainCreateFlags::EMPTY,
        // Colour attachment: the usage every runtime supports and whose layout the binding
        // names at release; transfer: how the layer writes it.
        usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT | xr::SwapchainUsageFlags::TRANSFER_DST,
        format: format.as_raw() as i64,
        sample_count: 1,
        width,
        height,
        face_count: 1,
        array_size: 1,
        mip_count: 1,
    };
    let mut swapchain = xr::Swapchain::NULL;
    // The images as the Vulkan half sees them are noted while they are made (a layer above may
    // wrap the handles the runtime reports).
    // SAFETY: the session is live; `ci` and the output are valid for the call.
    let (r, created) = crate::bridge::swapchain_images::capture(|| unsafe { create(s.handle, &ci, &mut swapchain) });
    xr_check("xrCreateSwapchain", r)?;
    let made = (|| -> Result<Overlay, String> {
        let mut n = 0u32;
        // SAFETY: our live swapchain; a count query.
        xr_check("xrEnumerateSwapchainImages", unsafe { enumerate(swapchain, 0, &mut n, std::ptr::null_mut()) })?;
        let blank = xr::SwapchainImageVulkanKHR { ty: xr::SwapchainImageVulkanKHR::TYPE, next: std::ptr::null_mut(), image: 0 };
        let mut reported = vec![blank; n as usize];
        // SAFETY: `reported` holds `n` typed Vulkan image structs (the session's graphics API).
        xr_check("xrEnumerateSwapchainImages", unsafe { enumerate(swapchain, n, &mut n, reported.as_mut_ptr().cast()) })?;
        reported.truncate(n as usize);
        let images: Vec<vk::Image> = if created.len() == reported.len() {
            created.iter().map(|c| vk::Image::from_raw(c.image)).collect()
        } else {
            reported.iter().map(|r| vk::Image::from_raw(r.image)).collect()
        };
        let space_ci = xr::ReferenceSpaceCreateInfo {
            ty: xr::ReferenceSpaceCreateInfo::TYPE,
            next: std::ptr::null(),
            reference_space_type: xr::ReferenceSpaceType::VIEW,
            pose_in_reference_space: xr::Posef { orientation: xr::Quaternionf { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }, position: xr::Vector3f { x: 0.0, y: 0.0, z: 0.0 } },
        };
        let mut space = xr::Space::NULL;
        // SAFETY: the session is live; valid create info and output.
        xr_check("xrCreateReferenceSpace(VIEW)", unsafe { create_space(s.handle, &space_ci, &mut space) })?;
        let mut ov = Overlay {
            device: device.clone(),
            swapchain,
            space,
            images,
            bgra: rules::is_bgra(format),
            width,
            height,
            max_layers,
            buffer: vk::Buffer::null(),
            memory: vk::DeviceMemory::null(),
            mapped: 0,
            pool: vk::CommandPool::null(),
            cb: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            queue: vk::Queue::null(),
            released: false,
        };
        if let Err(e) = vulkan_objects(&device, b.queue_family_index, b.queue_index, &mut ov) {
            // The swapchain goes below, with the other failures'.
            ov.swapchain = xr::Swapchain::NULL;
            destroy_objects(s, ov);
            return Err(e);
        }
        Ok(ov)
    })();
    if made.is_err() {
        // SAFETY: our swapchain, no image of it acquired (the space, where it was made, went
        // with `destroy_objects`).
        unsafe { destroy_sc(swapchain) };
    }
    made
}

/// The staging buffer (mapped), command pool and buffer, fence and queue, into `ov`.
fn vulkan_objects(d: &DeviceState, family: u32, queue_index: u32, ov: &mut Overlay) -> Result<(), String> {
    let set_loader_data = d.set_loader_data.ok_or("the loader gave no vkSetDeviceLoaderData")?;
    let size = ov.width as u64 * ov.height as u64 * 4;
    // SAFETY: valid create infos on the session's device, through the layer's counted table;
    // whatever was made before a failure is in `ov` and destroyed by the caller.
    unsafe {
        let host = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        (ov.buffer, ov.memory, _) = crate::plugin::vk::lifetime::bound_buffer(&d.fns, &d.memory, size, vk::BufferUsageFlags::TRANSFER_SRC, &[host])?;
        ov.mapped = d.fns.map_memory(ov.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()).map_err(vk_err("vkMapMemory"))? as usize;
        ov.pool = d
            .fns
            .create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family).flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER), None)
            .map_err(vk_err("vkCreateCommandPool"))?;
        let alloc = vk::CommandBufferAllocateInfo::default().command_pool(ov.pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
        ov.cb = d.fns.allocate_command_buffers(&alloc).map_err(vk_err("vkAllocateCommandBuffers"))?[0];
        // The loader sets the dispatch word only on objects handed out through it.
        let r = set_loader_data(d.handle, ov.cb.as_raw() as usize as *mut std::ffi::c_void);
        if r != vk::Result::SUCCESS {
            return Err(format!("vkSetDeviceLoaderData: {r:?}"));
        }
        ov.fence = d.fns.create_fence(&vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED), None).map_err(vk_err("vkCreateFence"))?;
        ov.queue = d.fns.get_device_queue(family, queue_index);
    }
    Ok(())
}

/// Draws `lines` into the next swapchain image: acquire, wait, copy from the staging buffer on
/// the session's queue, release.
fn upload(s: &Session, ov: &mut Overlay, lines: &[String], graph: &[f32]) -> Result<(), String> {
    let next = &s.instance.next;
    let (acquire, wait, release) = match (next.acquire_swapchain_image, next.wait_swapchain_image, next.release_swapchain_image) {
        (Some(a), Some(w), Some(r)) => (a, w, r),
        _ => return Err("the runtime lacks swapchain image functions".into()),
    };
    let d = &ov.device;
    let texels = rules::rasterise(lines, graph, ov.bgra);
    // SAFETY: our fence; once it signalled, the previous copy no longer reads the buffer, which
    // is mapped, host-coherent and `texels.len()` bytes long (the panel's fixed size).
    unsafe {
        d.fns.wait_for_fences(&[ov.fence], true, WAIT_NS).map_err(vk_err("waiting for the previous overlay upload"))?;
        std::ptr::copy_nonoverlapping(texels.as_ptr(), ov.mapped as *mut u8, texels.len());
    }
    let mut index = 0u32;
    let acquire_info = xr::SwapchainImageAcquireInfo { ty: xr::SwapchainImageAcquireInfo::TYPE, next: std::ptr::null() };
    // SAFETY: our live swapchain, valid info and output.
    xr_check("xrAcquireSwapchainImage", unsafe { acquire(ov.swapchain, &acquire_info, &mut index) })?;
    let wait_info = xr::SwapchainImageWaitInfo { ty: xr::SwapchainImageWaitInfo::TYPE, next: std::ptr::null(), timeout: xr::Duration::from_nanos(WAIT_NS as i64) };
    // SAFETY: as above.
    let r = unsafe { wait(ov.swapchain, &wait_info) };
    let release_info = xr::SwapchainImageReleaseInfo { ty: xr::SwapchainImageReleaseInfo::TYPE, next: std::ptr::null() };
    if r != xr::Result::SUCCESS {
        return Err(format!("xrWaitSwapchainImage: {r:?}"));
    }
    let image = *ov.images.get(index as usize).ok_or_else(|| format!("image index {index} of {}", ov.images.len()))?;
    let recorded = record_and_submit(ov, image);
    // Released even when the copy could not go: the image must go back to the runtime.
    // SAFETY: the image acquired and waited for above.
    let r = unsafe { release(ov.swapchain, &release_info) };
    recorded?;
    xr_check("xrReleaseSwapchainImage", r)?;
    ov.released = true;
    Ok(())
}

fn record_and_submit(ov: &Overlay, image: vk::Image) -> Result<(), String> {
    let d = &ov.device;
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 };
    let barrier = |old, new, src, dst| crate::plugin::vk::gpu::image_barrier(image, range, (old, new), (src, dst));
    // SAFETY: our command buffer and fence (the fence signalled: the buffer is not in use); the
    // image acquired and waited for; the session's queue, which the OpenXR Vulkan binding lets
    // the layer use inside xrEndFrame (the app synchronizes its queue use around frame calls).
    unsafe {
        d.fns.reset_fences(&[ov.fence]).map_err(vk_err("vkResetFences"))?;
        d.fns.reset_command_buffer(ov.cb, vk::CommandBufferResetFlags::empty()).map_err(vk_err("vkResetCommandBuffer"))?;
        d.fns.begin_command_buffer(ov.cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(vk_err("vkBeginCommandBuffer"))?;
        // The old contents are not needed: from undefined.
        let to_dst = barrier(vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::empty(), vk::AccessFlags::TRANSFER_WRITE);
        d.fns.cmd_pipeline_barrier(ov.cb, vk::PipelineStageFlags::TOP_OF_PIPE, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[to_dst]);
        let region = vk::BufferImageCopy {
            buffer_offset: 0,
            buffer_row_length: 0,
            buffer_image_height: 0,
            image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: 0, layer_count: 1 },
            image_offset: vk::Offset3D { x: 0, y: 0, z: 0 },
            image_extent: vk::Extent3D { width: ov.width, height: ov.height, depth: 1 },
        };
        d.fns.cmd_copy_buffer_to_image(ov.cb, ov.buffer, image, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[region]);
        // The OpenXR Vulkan binding: a colour-attachment swapchain image is released in
        // COLOR_ATTACHMENT_OPTIMAL.
        let to_release = barrier(
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
            vk::AccessFlags::TRANSFER_WRITE,
            vk::AccessFlags::MEMORY_READ,
        );
        d.fns.cmd_pipeline_barrier(ov.cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &[to_release]);
        d.fns.end_command_buffer(ov.cb).map_err(vk_err("vkEndCommandBuffer"))?;
        // `stats.gpu_time`: the layer's own work is timed in the frame it is submitted in.
        let bracket = crate::plugin::vk::gpu_time::start(d, ov.queue, 1, true);
        let cbs = match &bracket {
            Some(b) => vec![b.begin, ov.cb, b.end],
            None => vec![ov.cb],
        };
        let r = d.fns.queue_submit(ov.queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], ov.fence);
        if let Some(b) = bracket {
            crate::plugin::vk::gpu_time::submitted(d, b, ov.queue, r.is_ok());
        }
        r.map_err(vk_err("vkQueueSubmit"))
    }
}

/// Destroys an overlay's objects: its Vulkan objects once its last copy is done, then its space
/// and swapchain down the chain.
fn destroy_objects(s: &Session, ov: Overlay) {
    let d = &ov.device;
    // The spec has the device outlive the session; an app that destroyed it first took the
    // overlay's Vulkan objects with it (vkDestroyDevice), and the device must not be touched.
    if !crate::plugin::vk::device_is_live(d) {
        tracing::warn!("overlay: the app destroyed the session's VkDevice before the session; its Vulkan objects went with the device");
    } else {
        // SAFETY: our objects on the session's device, checked live just above; the fence wait
        // makes sure the GPU no longer uses them; null handles are skipped.
        unsafe {
            if ov.fence != vk::Fence::null() {
                if let Err(e) = d.fns.wait_for_fences(&[ov.fence], true, WAIT_NS) {
                    tracing::warn!("overlay: waiting for its last upload failed ({e}); destroying its objects anyway");
                }
                d.fns.destroy_fence(ov.fence, None);
            }
            if ov.pool != vk::CommandPool::null() {
                d.fns.destroy_command_pool(ov.pool, None);
            }
            if ov.buffer != vk::Buffer::null() {
                d.fns.destroy_buffer(ov.buffer, None);
            }
            if ov.memory != vk::DeviceMemory::null() {
                d.fns.free_memory(ov.memory, None);
            }
        }
    }
    let next = &s.instance.next;
    if let (Some(f), false) = (next.destroy_space, ov.space == xr::Space::NULL) {
        // SAFETY: our space of the live session.
        let _ = unsafe { f(ov.space) };
    }
    if let (Some(f), false) = (next.destroy_swapchain, ov.swapchain == xr::Swapchain::NULL) {
        // SAFETY: our swapchain of the live session; no image of it is acquired.
        let _ = unsafe { f(ov.swapchain) };
    }
}

/// The session is about to be destroyed: the overlay's objects go first.
pub(crate) fn destroy(s: &Session) {
    if let Some(ov) = lock(&state(s).live).take() {
        destroy_objects(s, *ov);
        tracing::info!("overlay: objects of session {:#x} destroyed", s.handle.into_raw());
    }
}
