//! Screenshots on the Vulkan side: while a frame is armed (`request`), each swapchain image the
//! app releases is copied — every view it shows, its `imageRect` of its array layer — into a
//! host-visible buffer by a layer command buffer on the session's queue, after the app's work and
//! the other features' (RDM's reconstruction: this feature is last in the registry), with a fence.
//! The app's `xrReleaseSwapchainImage` waits for nothing, and makes no large allocation: the
//! read-back buffers are made on a thread of the layer's when the request comes (`prepare`), and
//! the frames begun before they are ready are not copied. Once every view is copied (or the next
//! `xrBeginFrame` comes), a thread of the layer's waits for the fences, reads the buffers, frees
//! every object and encodes the PNGs (`write`). `vkDestroyDevice` waits for the read-back (bounded
//! by the fence timeout) and briefly for the encoding, and reads anything still pending itself.

use super::rules::{self, Texels};
use super::write::{self, Picture};
use super::ScreenshotStats;
use crate::core::stats::FeatureStats;
use crate::plugin::settings::Settings;
use crate::bridge::shared;
use crate::core::views::ImageRect;
use crate::plugin::vk::feature::{DeviceInit, Plugin, VkFeature};
use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// How long the read-back waits for one copy's fence: a GPU this far behind is hung, and the
/// screenshot is dropped rather than the device's teardown held up.
const FENCE_WAIT_NS: u64 = 2_000_000_000;
/// How long `vkDestroyDevice` lets a screenshot being encoded finish writing its files.
const ENCODE_WAIT: Duration = Duration::from_secs(5);

/// What was asked for, from the OpenXR side.
#[derive(Clone, Debug)]
pub(crate) struct Request {
    /// The request number of `stereoshim screenshot` (0: a touch of `screenshot.trigger`).
    pub token: u64,
    pub app: String,
    /// Where the PNGs go (None: no folder is known; logged).
    pub dir: Option<PathBuf>,
    /// The result file in the runtime folder `stereoshim screenshot --wait` reads.
    pub done: Option<PathBuf>,
}

/// The answer to a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Requested {
    Armed,
    /// The previous screenshot is still being encoded (the request stays for later).
    Busy,
    NoDevice,
}

/// One view of one copy: where its texels are in the buffer.
#[derive(Clone, Copy, Debug)]
pub(super) struct ViewCopy {
    pub view: u32,
    pub region: (u32, u32, u32, u32),
    pub layer: u32,
    pub texels: Texels,
    pub format: i32,
    pub swapchain: u64,
    pub offset: u64,
    /// The upscale's display-size image (`display_ready`), not the app's.
    pub display: bool,
}

/// One released image's copy: its objects and views.
struct Copy {
    pool: vk::CommandPool,
    fence: vk::Fence,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    coherent: bool,
    views: Vec<ViewCopy>,
    /// Its buffer was made ahead (`prepare`), not inside the release.
    made_ahead: bool,
}

/// A host-visible read-back buffer, made ahead for one swapchain's views.
struct Staging {
    swapchain: u64,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    coherent: bool,
    size: u64,
}

/// An armed frame and the copies made of it so far.
struct Armed {
    frame: u64,
    request: Request,
    copies: Vec<Copy>,
    /// Time spent in the app's `xrReleaseSwapchainImage` calls on the copies, µs.
    release_us: u64,
    /// Frames armed without a copy so far.
    empty_frames: u32,
    /// The read-back buffers were ready when this frame began: only then are its images copied
    /// (so a frame is copied whole, never one eye before the buffers came and one after).
    ready: bool,
}

/// Frames a request stays armed while nothing can be copied (no image tied to a view yet, or
/// none that can be copied) before it is answered with an error instead of waiting forever.
const MAX_EMPTY_FRAMES: u32 = 30;

#[derive(Default)]
struct State {
    armed: Option<Armed>,
    /// A complete frame waiting for the thread to take it.
    handoff: Option<Armed>,
    /// A screenshot is between its handoff and its files written.
    busy: bool,
    /// The thread holds copies (reads them with the device's functions).
    reading: bool,
    /// The device is being destroyed: the thread takes nothing more.
    closed: bool,
    /// Copies whose fence did not signal in time: freed at `vkDestroyDevice` (the device idle).
    leftover: Vec<Copy>,
    /// The read-back buffers are being made (`prepare`).
    preparing: bool,
    /// Read-back buffers made ahead and not used yet.
    staging: Vec<Staging>,
}

struct Jobs {
    state: Mutex<State>,
    changed: Condvar,
}

/// The screenshot feature of one device.
pub(crate) struct ScreenshotDevice {
    memory: vk::PhysicalDeviceMemoryProperties,
    set_loader_data: Option<crate::plugin::vk::PfnSetDeviceLoaderData>,
    jobs: Arc<Jobs>,
    /// Whether a frame is armed: the only thing a release looks at otherwise.
    armed: AtomicBool,
    frame: Mutex<ScreenshotStats>,
    total: Mutex<ScreenshotStats>,
    logged: Mutex<HashSet<String>>,
}

impl ScreenshotDevice {
    /// The device's object of this feature (the registry made one for every device).
    pub(crate) fn of(d: &DeviceState) -> &ScreenshotDevice {
        d.features.get::<ScreenshotDevice>()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Plugin for ScreenshotDevice {
    fn new(init: &DeviceInit<'_>) -> ScreenshotDevice {
        ScreenshotDevice {
            memory: init.memory,
            set_loader_data: init.set_loader_data,
            jobs: Arc::new(Jobs { state: Mutex::default(), changed: Condvar::new() }),
            armed: AtomicBool::new(false),
            frame: Mutex::default(),
            total: Mutex::default(),
            logged: Mutex::default(),
        }
    }
    fn empty_stats() -> Box<dyn FeatureStats> {
        Box::new(ScreenshotStats::default())
    }
    /// Never counted as "on but applied to nothing": screenshots are taken on request only.
    fn enabled(_s: &Settings, _frame: &crate::core::stats::FrameStats) -> bool {
        false
    }
}

impl ScreenshotDevice {
    fn count(&self, f: impl Fn(&mut ScreenshotStats)) {
        f(&mut lock(&self.frame));
        f(&mut lock(&self.total));
    }
    fn log_once(&self, key: &str, f: impl FnOnce()) {
        if lock(&self.logged).insert(key.to_string()) {
            f();
        }
    }
    fn not_applied(&self, why: &'static str, what: impl FnOnce() -> String) {
        self.count(|s| *s.not_applied.entry(why).or_insert(0) += 1);
        self.log_once(why, || tracing::warn!("screenshot: {}; this view is left out", what()));
    }
}

/// Arms `frame` on `device` for `request` (the OpenXR side, at `xrBeginFrame`).
pub(crate) fn request(device: crate::plugin::vk::DeviceKey, frame: u64, request: Request) -> Requested {
    let Some(d) = device.state() else { return Requested::NoDevice };
    let me = ScreenshotDevice::of(&d);
    let mut st = lock(&me.jobs.state);
    if st.busy || st.handoff.is_some() || st.armed.is_some() || st.closed {
        return Requested::Busy;
    }
    // The buffers for every swapchain image the last xrEndFrame tied to a view, made on a thread
    // of the layer's: allocating tens of MB of host memory inside the app's release would cost it
    // a frame (12 ms on an H100 at the Index's size).
    let needs: Vec<(u64, u64)> = shared()
        .swapchains
        .values()
        .iter()
        .filter_map(|(_, sc)| {
            let uses: Vec<_> = sc.uses().into_iter().filter(|u| !u.depth).map(|u| (u.view, u.image_rect, u.image_array_index)).collect();
            let views = views_of(me, sc, &uses)?;
            Some((sc.handle, buffer_size(&views)))
        })
        .collect();
    st.preparing = !needs.is_empty();
    st.armed = Some(Armed { frame, request, copies: Vec::new(), release_us: 0, empty_frames: 0, ready: needs.is_empty() });
    me.armed.store(true, Ordering::Release);
    if !needs.is_empty() {
        drop(st);
        let (fns, jobs, memory) = (d.fns.clone(), me.jobs.clone(), me.memory);
        let spawned = std::thread::Builder::new().name("stereoshim-screenshot".into()).spawn(move || prepare(&fns, &memory, &jobs, &needs));
        if let Err(e) = spawned {
            // The releases make their buffers themselves, as they would for a swapchain not
            // known at the request.
            tracing::warn!("screenshot: no thread to prepare the read-back ({e}); made at the release");
            let mut st = lock(&me.jobs.state);
            st.preparing = false;
            if let Some(a) = st.armed.as_mut() {
                a.ready = true;
            }
        }
    }
    Requested::Armed
}

/// The thread of a request: makes the read-back buffers of `needs` (swapchain, size), then marks
/// the request ready for the next frame begun.
fn prepare(fns: &ash::Device, memory: &vk::PhysicalDeviceMemoryProperties, jobs: &Jobs, needs: &[(u64, u64)]) {
    let mut made = Vec::new();
    for &(swapchain, size) in needs {
        match make_staging(fns, memory, swapchain, size) {
            Ok(s) => made.push(s),
            // That swapchain's release makes its own (and logs if it cannot either).
            Err(e) => tracing::warn!("screenshot: read-back buffer for swapchain {swapchain:#x}: {e}"),
        }
    }
    let mut st = lock(&jobs.state);
    st.staging.extend(made);
    st.preparing = false;
    jobs.changed.notify_all();
}

/// A host-visible buffer of `size` bytes (cached memory where there is some: it is read by the CPU).
fn make_staging(fns: &ash::Device, memory: &vk::PhysicalDeviceMemoryProperties, swapchain: u64, size: u64) -> Result<Staging, String> {
    let host = vk::MemoryPropertyFlags::HOST_VISIBLE;
    let (buffer, memory, flags) = crate::plugin::vk::lifetime::bound_buffer(fns, memory, size, vk::BufferUsageFlags::TRANSFER_DST, &[host | vk::MemoryPropertyFlags::HOST_CACHED, host])?;
    Ok(Staging { swapchain, buffer, memory, coherent: flags.contains(vk::MemoryPropertyFlags::HOST_COHERENT), size })
}

/// # Safety
/// The buffer is not in use by the GPU (never submitted, or its copy completed).
unsafe fn destroy_staging(fns: &ash::Device, s: &Staging) {
    // SAFETY: per the contract; null handles are ignored.
    unsafe {
        fns.destroy_buffer(s.buffer, None);
        fns.free_memory(s.memory, None);
    }
}

/// `xrBeginFrame` of `frame`: the armed frame (an earlier one) is over. Its copies go to the
/// thread; an armed frame that copied nothing (no image was tied to a view yet: the first frame)
/// stays armed for this one, up to `MAX_EMPTY_FRAMES` (then the thread answers with an error).
/// Returns whether a frame is still armed.
pub(crate) fn frame_begun(device: crate::plugin::vk::DeviceKey, frame: u64) -> bool {
    let Some(d) = device.state() else { return false };
    let me = ScreenshotDevice::of(&d);
    let mut st = lock(&me.jobs.state);
    let preparing = st.preparing;
    match st.armed.as_mut() {
        None => false,
        Some(a) if a.copies.is_empty() && a.empty_frames + 1 < MAX_EMPTY_FRAMES => {
            a.frame = frame;
            a.empty_frames += 1;
            a.ready = !preparing;
            true
        }
        Some(_) => {
            let a = st.armed.take();
            me.armed.store(false, Ordering::Release);
            hand_off(&d, me, st, a);
            false
        }
    }
}

/// Gives a finished frame to a new thread of the layer's.
fn hand_off(d: &DeviceState, me: &ScreenshotDevice, mut st: MutexGuard<'_, State>, armed: Option<Armed>) {
    if let Some(a) = &armed {
        let views: usize = a.copies.iter().map(|c| c.views.len()).sum();
        let ahead = a.copies.iter().filter(|c| c.made_ahead).count();
        tracing::info!("screenshot: frame {}: {views} view(s) in {} copies submitted ({ahead} into buffers made ahead), {} µs in xrReleaseSwapchainImage", a.frame, a.copies.len(), a.release_us);
    }
    st.handoff = armed;
    st.busy = true;
    drop(st);
    let jobs = me.jobs.clone();
    let fns = d.fns.clone();
    let spawned = std::thread::Builder::new().name("stereoshim-screenshot".into()).spawn(move || work(&fns, &jobs));
    if let Err(e) = spawned {
        // The handoff stays: vkDestroyDevice reads and writes it.
        tracing::warn!("screenshot: no thread for the encoding ({e}); written at the device's end");
        lock(&me.jobs.state).busy = false;
    }
}

/// The thread: reads the copies, frees their objects, writes the files.
fn work(fns: &ash::Device, jobs: &Jobs) {
    let armed = {
        let mut st = lock(&jobs.state);
        if st.closed {
            st.busy = false;
            jobs.changed.notify_all();
            return;
        }
        st.reading = true;
        st.handoff.take()
    };
    let pictures = armed.map(|a| {
        let frame = a.frame;
        let request = a.request.clone();
        let (pictures, leftover) = read_back(fns, a.copies);
        (pictures, leftover, frame, request)
    });
    let pictures = pictures.map(|(pictures, leftover, frame, request)| {
        lock(&jobs.state).leftover.extend(leftover);
        (pictures, frame, request)
    });
    let unused = {
        let mut st = lock(&jobs.state);
        st.reading = false;
        jobs.changed.notify_all();
        std::mem::take(&mut st.staging)
    };
    for s in unused {
        // SAFETY: made ahead and never submitted (a used one left `staging` for its copy).
        unsafe { destroy_staging(fns, &s) };
    }
    if let Some((pictures, frame, request)) = pictures {
        write::write(&request, frame, pictures);
    }
    let mut st = lock(&jobs.state);
    st.busy = false;
    jobs.changed.notify_all();
}

/// Waits for each copy, reads its views into pictures and destroys its objects; copies that did
/// not finish in time are returned, not freed (their GPU work may still run).
fn read_back(fns: &ash::Device, copies: Vec<Copy>) -> (Vec<Picture>, Vec<Copy>) {
    let mut pictures = Vec::new();
    let mut leftover = Vec::new();
    for c in copies {
        // SAFETY: the copy's own objects on this device, whose fence guards the GPU's last use of
        // them; once it signalled (or never will: the wait timed out and nothing is read, the
        // objects are then left to the device's end rather than freed under a running copy).
        unsafe {
            let done = fns.wait_for_fences(&[c.fence], true, FENCE_WAIT_NS);
            if let Err(e) = done {
                tracing::warn!("screenshot: the copy did not finish ({e}); dropped");
                leftover.push(c);
                continue;
            }
            match fns.map_memory(c.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) {
                Ok(p) => {
                    if !c.coherent {
                        let r = vk::MappedMemoryRange::default().memory(c.memory).offset(0).size(vk::WHOLE_SIZE);
                        let _ = fns.invalidate_mapped_memory_ranges(&[r]);
                    }
                    for v in &c.views {
                        let (_, _, w, h) = v.region;
                        let len = (w as u64 * h as u64 * v.texels.bytes_per_texel()) as usize;
                        let bytes = std::slice::from_raw_parts((p as *const u8).add(v.offset as usize), len);
                        pictures.push(Picture::new(v, v.texels.to_rgb8(bytes, (w * h) as usize)));
                    }
                    fns.unmap_memory(c.memory);
                }
                Err(e) => tracing::warn!("screenshot: vkMapMemory: {e}"),
            }
            destroy_copy(fns, &c);
        }
    }
    (pictures, leftover)
}

/// # Safety
/// The copy's work must have completed (or never been submitted).
unsafe fn destroy_copy(fns: &ash::Device, c: &Copy) {
    // SAFETY: per the contract; null handles are ignored; freeing the pool frees its command buffer.
    unsafe {
        fns.destroy_buffer(c.buffer, None);
        fns.free_memory(c.memory, None);
        fns.destroy_fence(c.fence, None);
        fns.destroy_command_pool(c.pool, None);
    }
}

impl ScreenshotDevice {
    /// Copies `uses` (view, rect, layer) of `image` of `sc` on the session's queue into the armed
    /// frame; `display`: the upscale's display-size image, written as its own pictures. Hands the
    /// frame off once every expected view is in.
    fn capture(&self, d: &DeviceState, (family, queue_index): (u32, u32), sc: &crate::bridge::Swapchain, image: u64, uses: &[(u32, ImageRect, u32)], display: bool) {
        let started = std::time::Instant::now();
        let swapchain = sc.handle;
        if uses.is_empty() {
            return;
        }
        // Not before the read-back buffers are made (the frame stays armed for a later one).
        if !lock(&self.jobs.state).armed.as_ref().is_some_and(|a| a.ready) {
            return;
        }
        let Some(mut views) = plan(self, d, sc, image, uses) else { return };
        for v in &mut views {
            v.display = display;
        }
        let size = buffer_size(&views);
        let staging = {
            let mut st = lock(&self.jobs.state);
            let i = st.staging.iter().position(|s| s.swapchain == swapchain && s.size >= size);
            i.map(|i| st.staging.swap_remove(i))
        };
        let copy = match copy(self, d, image, &sc.desc, views, staging, family, queue_index) {
            Ok(c) => c,
            Err(e) => {
                self.log_once("copy failed", || tracing::warn!("screenshot: the copy of swapchain {swapchain:#x} failed: {e}"));
                return;
            }
        };
        self.count(|s| s.views += copy.views.len() as u64);
        let mut st = lock(&self.jobs.state);
        let Some(a) = st.armed.as_mut() else {
            // Disarmed meanwhile (cannot happen: only this device's frames arm and close it).
            drop(st);
            // SAFETY: the device is alive; the submission's fence is waited for first.
            unsafe {
                let _ = d.fns.wait_for_fences(&[copy.fence], true, FENCE_WAIT_NS);
                destroy_copy(&d.fns, &copy);
            }
            return;
        };
        a.copies.push(copy);
        a.release_us += started.elapsed().as_micros() as u64;
        // Every view of the frame (as the last xrEndFrame tied them to images) copied: done now.
        let captured: Vec<(u32, bool)> = a.copies.iter().flat_map(|c| c.views.iter().map(|v| (v.view, v.display))).collect();
        if rules::views_complete(&expected_views(), &captured) {
            let a = st.armed.take();
            self.armed.store(false, Ordering::Release);
            hand_off(d, self, st, a);
        }
    }
}

impl VkFeature for ScreenshotDevice {
    fn id(&self) -> &'static str {
        "screenshot"
    }
    fn take_frame(&self) -> Box<dyn FeatureStats> {
        Box::new(std::mem::take(&mut *lock(&self.frame)))
    }
    fn summary(&self) -> Option<String> {
        let t = lock(&self.total);
        (!t.is_empty()).then(|| t.summary())
    }

    fn before_release(&self, d: &DeviceState, family: u32, queue_index: u32, swapchain: u64, image_index: u32) {
        if !self.armed.load(Ordering::Acquire) || d.pass_through.is_on() {
            return;
        }
        let Some(sc) = shared().swapchains.get(swapchain) else { return };
        let Some(&image) = sc.images.get(image_index as usize) else { return };
        let uses: Vec<_> = sc.uses().into_iter().filter(|u| !u.depth).map(|u| (u.view, u.image_rect, u.image_array_index)).collect();
        self.capture(d, (family, queue_index), &sc, image, &uses, false);
    }

    fn display_ready(&self, d: &DeviceState, family: u32, queue_index: u32, display: &crate::bridge::Swapchain, image: u64, views: &[(u32, ImageRect, u32)]) {
        if !self.armed.load(Ordering::Acquire) || d.pass_through.is_on() {
            return;
        }
        self.capture(d, (family, queue_index), display, image, views, true);
    }

    /// `vkDestroyDevice` (the device is idle): no thread keeps using the device past this point.
    fn destroy(&self, d: &DeviceState) {
        let mut st = lock(&self.jobs.state);
        st.closed = true;
        // Reading is bounded by the fence timeout, so this wait is too; making buffers is short.
        while st.reading || st.preparing {
            st = self.jobs.changed.wait(st).unwrap_or_else(|e| e.into_inner());
        }
        let deadline = std::time::Instant::now() + ENCODE_WAIT;
        while st.busy && st.handoff.is_none() {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                tracing::warn!("screenshot: still encoding at the device's end; not waited for");
                break;
            }
            st = self.jobs.changed.wait_timeout(st, left).map(|(g, _)| g).unwrap_or_else(|e| e.into_inner().0);
        }
        let pending: Vec<Armed> = [st.handoff.take(), st.armed.take()].into_iter().flatten().collect();
        let leftover = std::mem::take(&mut st.leftover);
        let unused = std::mem::take(&mut st.staging);
        self.armed.store(false, Ordering::Release);
        drop(st);
        for s in unused {
            // SAFETY: never submitted.
            unsafe { destroy_staging(&d.fns, &s) };
        }
        // What is still pending is read and written here: the app is ending anyway.
        for a in pending {
            let (pictures, late) = read_back(&d.fns, a.copies);
            write::write(&a.request, a.frame, pictures);
            for c in late {
                // SAFETY: the device is idle (vkDestroyDevice's contract): the copy's work is over.
                unsafe { destroy_copy(&d.fns, &c) };
            }
        }
        for c in leftover {
            // SAFETY: as above.
            unsafe { destroy_copy(&d.fns, &c) };
        }
    }
}

/// The views of every swapchain image the last `xrEndFrame` named, (view, false); and of an
/// upscaled swapchain, the display-size image's too, (view, true).
fn expected_views() -> Vec<(u32, bool)> {
    let mut views: Vec<(u32, bool)> = shared()
        .swapchains
        .values()
        .iter()
        .flat_map(|(_, sc)| sc.uses().into_iter().filter(|u| !u.depth).flat_map(move |u| [Some((u.view, false)), sc.upscaled.then_some((u.view, true))]).flatten())
        .collect();
    views.sort_unstable();
    views.dedup();
    views
}

/// What to copy of `image` for its `uses` (view, rect, layer), with each view's offset in the
/// buffer; None (counted, logged once) when the image cannot be copied.
fn plan(me: &ScreenshotDevice, d: &DeviceState, sc: &crate::bridge::Swapchain, image: u64, uses: &[(u32, ImageRect, u32)]) -> Option<Vec<ViewCopy>> {
    let usage = d.track.images.get(image).map(|i| i.usage);
    if usage.is_some_and(|u| !u.contains(vk::ImageUsageFlags::TRANSFER_SRC)) {
        me.not_applied("usage", || format!("swapchain image usage {usage:?} lacks TRANSFER_SRC"));
        return None;
    }
    views_of(me, sc, uses)
}

/// The views of `uses` (view, rect, layer) of one of the swapchain's images and their offsets in
/// the read-back buffer; None (counted, logged once) when its images cannot be copied.
fn views_of(me: &ScreenshotDevice, sc: &crate::bridge::Swapchain, uses: &[(u32, ImageRect, u32)]) -> Option<Vec<ViewCopy>> {
    let desc = &sc.desc;
    let Some(texels) = Texels::of(desc.format as i32) else {
        me.not_applied("format", || format!("swapchain format {:?} is not converted", vk::Format::from_raw(desc.format as i32)));
        return None;
    };
    if desc.sample_count > 1 {
        me.not_applied("multisampled", || format!("swapchain {:#x} is multisampled", sc.handle));
        return None;
    }
    let mut offset = 0;
    let mut views = Vec::new();
    for &(view, rect, layer) in uses {
        let Some(region) = rules::copy_region(rect, desc.width, desc.height) else { continue };
        if layer >= desc.array_size.max(1) {
            continue;
        }
        views.push(ViewCopy { view, region, layer, texels, format: desc.format as i32, swapchain: sc.handle, offset, display: false });
        offset += (region.2 as u64 * region.3 as u64 * texels.bytes_per_texel()).div_ceil(16) * 16;
    }
    (!views.is_empty()).then_some(views)
}

/// The read-back buffer's size for `views`.
fn buffer_size(views: &[ViewCopy]) -> u64 {
    views.iter().map(|v| v.offset + v.region.2 as u64 * v.region.3 as u64 * v.texels.bytes_per_texel()).max().unwrap_or(0).max(16)
}

/// Records and submits the copy of `views` of `image` on the session's queue, into `staging` (made
/// ahead) or a buffer made here (a swapchain not known at the request).
#[allow(clippy::too_many_arguments)]
fn copy(me: &ScreenshotDevice, d: &DeviceState, image: u64, desc: &crate::core::views::SwapchainDesc, views: Vec<ViewCopy>, staging: Option<Staging>, family: u32, queue_index: u32) -> Result<Copy, String> {
    let Some(set_loader_data) = me.set_loader_data else {
        if let Some(s) = staging {
            // SAFETY: never submitted.
            unsafe { destroy_staging(&d.fns, &s) };
        }
        return Err("the loader gave no vkSetDeviceLoaderData".into());
    };
    let made_ahead = staging.is_some();
    let staging = match staging {
        Some(s) => s,
        None => make_staging(&d.fns, &me.memory, 0, buffer_size(&views))?,
    };
    let mut c = Copy { pool: vk::CommandPool::null(), fence: vk::Fence::null(), buffer: staging.buffer, memory: staging.memory, coherent: staging.coherent, views, made_ahead };
    let e = |what: &'static str| move |r: vk::Result| format!("{what}: {r}");
    // SAFETY: valid create infos on our device; our own command buffer recorded and submitted
    // once on the session's queue, which the OpenXR Vulkan binding lets a call inside
    // xrReleaseSwapchainImage use (the app synchronizes its queue use around these calls); the
    // released swapchain image is in COLOR_ATTACHMENT_OPTIMAL (what the binding requires at
    // release) and is put back in it. Every object made is destroyed on failure here, else by
    // the read-back or at vkDestroyDevice.
    let r = unsafe {
        (|| -> Result<(), String> {
            let f = &d.fns;
            c.pool = f.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family), None).map_err(e("command pool"))?;
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(c.pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
            let cb = f.allocate_command_buffers(&alloc).map_err(e("command buffer"))?[0];
            // The loader sets the dispatch word only on objects handed out through it.
            let r = set_loader_data(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void);
            if r != vk::Result::SUCCESS {
                return Err(format!("vkSetDeviceLoaderData: {r:?}"));
            }
            c.fence = f.create_fence(&vk::FenceCreateInfo::default(), None).map_err(e("fence"))?;
            f.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).map_err(e("begin"))?;
            record(f, cb, vk::Image::from_raw(image), desc.array_size.max(1), c.buffer, &c.views);
            f.end_command_buffer(cb).map_err(e("end"))?;
            let queue = f.get_device_queue(family, queue_index);
            // `stats.gpu_time`: the layer's own work is timed like the app's.
            let bracket = crate::plugin::vk::gpu_time::start(d, queue, 1, true);
            let cbs = match &bracket {
                Some(b) => vec![b.begin, cb, b.end],
                None => vec![cb],
            };
            let r = f.queue_submit(queue, &[vk::SubmitInfo::default().command_buffers(&cbs)], c.fence);
            if let Some(b) = bracket {
                crate::plugin::vk::gpu_time::submitted(d, b, queue, r.is_ok());
            }
            r.map_err(e("vkQueueSubmit"))
        })()
    };
    match r {
        Ok(()) => Ok(c),
        Err(msg) => {
            // SAFETY: nothing of it was submitted (the submission is the last step and failed).
            unsafe { destroy_copy(&d.fns, &c) };
            Err(msg)
        }
    }
}

/// The copy's commands: the image to TRANSFER_SRC after everything before it on the queue, each
/// view's region into the buffer, the image back, the buffer made visible to the host.
///
/// # Safety
/// `cb` is recording; `image` has `layers` array layers, in COLOR_ATTACHMENT_OPTIMAL; the buffer
/// holds every view at its offset.
unsafe fn record(f: &ash::Device, cb: vk::CommandBuffer, image: vk::Image, layers: u32, buffer: vk::Buffer, views: &[ViewCopy]) {
    let range = vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: layers };
    let to_src = crate::plugin::vk::gpu::image_barrier(image, range, (vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::TRANSFER_SRC_OPTIMAL), (vk::AccessFlags::MEMORY_WRITE, vk::AccessFlags::TRANSFER_READ));
    let regions: Vec<vk::BufferImageCopy> = views
        .iter()
        .map(|v| vk::BufferImageCopy {
            buffer_offset: v.offset,
            buffer_row_length: 0,
            buffer_image_height: 0,
            image_subresource: vk::ImageSubresourceLayers { aspect_mask: vk::ImageAspectFlags::COLOR, mip_level: 0, base_array_layer: v.layer, layer_count: 1 },
            image_offset: vk::Offset3D { x: v.region.0 as i32, y: v.region.1 as i32, z: 0 },
            image_extent: vk::Extent3D { width: v.region.2, height: v.region.3, depth: 1 },
        })
        .collect();
    let back = crate::plugin::vk::gpu::image_barrier(image, range, (vk::ImageLayout::TRANSFER_SRC_OPTIMAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL), (vk::AccessFlags::empty(), vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE));
    let host = vk::BufferMemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::HOST_READ)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .buffer(buffer)
        .offset(0)
        .size(vk::WHOLE_SIZE);
    // SAFETY: per the contract.
    unsafe {
        f.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::ALL_COMMANDS, vk::PipelineStageFlags::TRANSFER, vk::DependencyFlags::empty(), &[], &[], &[to_src]);
        f.cmd_copy_image_to_buffer(cb, image, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, buffer, &regions);
        f.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::ALL_COMMANDS, vk::DependencyFlags::empty(), &[], &[], &[back]);
        f.cmd_pipeline_barrier(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::HOST, vk::DependencyFlags::empty(), &[], &[host], &[]);
    }
}
