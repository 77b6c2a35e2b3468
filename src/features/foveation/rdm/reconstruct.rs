//! Radial density masking on the Vulkan side, the reconstruction half: before the runtime sees a
//! swapchain image (`xrReleaseSwapchainImage`), a layer command buffer on the session's queue
//! fills the quads the checkerboard skipped from their shaded neighbours (`rules`' weights): by
//! the compute pass over periphery tiles (`compute`) where `rules::compute_path` allows, else by
//! the full-screen fragment fill (`fill`), counted by reason. The slots (command buffer, fence,
//! descriptor pool, temp images) are kept here, up to `MAX_SLOTS` in flight.

use crate::features::foveation::FoveationSettings;
use super::compute;
use super::fill::{destroy_fill, destroy_temp, fill_objects, record_and_submit, FillObjects, Temp};
use super::rules::{compute_path, NotApplied, Pending};
use super::vk::{lock, log_once, RdmDevice};
use crate::core::rect::PixelRect;
use crate::features::foveation::Reconstruction;
use crate::bridge::{self, shared};

use crate::plugin::vk::DeviceState;
use ash::vk::{self, Handle};
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::Mutex;


/// Command buffers (with their temp image) in flight before a release waits
/// (`rules::slot_choice`). A per-eye app releases two images a frame and runtimes let it run up
/// to about three frames ahead, so 8 covers every conforming frame loop without a wait inside the
/// app's `xrReleaseSwapchainImage` (it was 3: per-eye apps waited for the GPU every frame).
const MAX_SLOTS: usize = 8;
/// How long a release waits for an old reconstruction to finish before giving up on this one.
const SLOT_WAIT_NS: u64 = 2_000_000_000;

/// The reconstruction's objects of one device. Locks guard bookkeeping only.
pub(crate) struct Reconstruct {
    set_loader_data: Option<crate::plugin::vk::PfnSetDeviceLoaderData>,
    pub(super) memory: vk::PhysicalDeviceMemoryProperties,
    pub(super) fill: Mutex<Option<FillObjects>>,
    slots: Mutex<VecDeque<Slot>>,
    slot_count: std::sync::atomic::AtomicUsize,
    /// Releases that had to wait for an earlier reconstruction (`rules::SlotChoice::WaitOldest`).
    pub(crate) release_waits: std::sync::atomic::AtomicU64,
    /// A reconstruction failed after its checkerboard was drawn (its submission was refused: the
    /// image went to the runtime with holes): no pass gets a checkerboard on this device any more
    /// (`ready`), since the next reconstruction could fail too.
    failed: std::sync::atomic::AtomicBool,
    pub(super) compute: compute::Compute,
}

impl Reconstruct {
    pub(crate) fn new(memory: vk::PhysicalDeviceMemoryProperties, set_loader_data: Option<crate::plugin::vk::PfnSetDeviceLoaderData>) -> Reconstruct {
        Reconstruct { set_loader_data, memory, fill: Mutex::default(), slots: Mutex::default(), slot_count: Default::default(), release_waits: Default::default(), failed: Default::default(), compute: Default::default() }
    }
    /// At vkDestroyDevice (the device is idle).
    pub(crate) fn destroy(&self, d: &DeviceState) {
        destroy_all(self, d);
        self.compute.destroy(d);
    }
}

/// A command buffer with everything one reconstruction uses, reused once its fence signalled.
pub(super) struct Slot {
    /// The queue family its command pool records for.
    pub(super) family: u32,
    pub(super) pool: vk::CommandPool,
    pub(super) cb: vk::CommandBuffer,
    pub(super) fence: vk::Fence,
    pub(super) descriptor_pool: vk::DescriptorPool,
    pub(super) set: vk::DescriptorSet,
    pub(super) temp: Option<Temp>,
    /// Views and framebuffers of the swapchain image of the last use.
    pub(super) transient: Vec<(vk::ImageView, vk::Framebuffer)>,
    /// The compute pass's temp image, tile buffer and descriptor set.
    pub(super) compute: compute::SlotData,
}

/// Called by the OpenXR half in `xrReleaseSwapchainImage`, before calling down: reconstructs the
/// skipped quads of the released image, on the session's queue, after the app's submitted work.
pub(super) fn before_release(me: &RdmDevice, d: &DeviceState, queue_family: u32, queue_index: u32, swapchain: u64, image_index: u32) {
    if d.pass_through.is_on() {
        return;
    }
    let Some(sc) = shared().swapchains.get(swapchain) else { return };
    let Some(&image) = sc.images.get(image_index as usize) else { return };
    let pending = lock(&me.books).pending.remove(&image).unwrap_or_default();
    if pending.is_empty() {
        return;
    }
    let how = d.settings().of::<FoveationSettings>().rdm_reconstruction;
    if how == Reconstruction::Off {
        log_once(me, "reconstruction off".into(), || tracing::warn!("radial density masking: foveation.rdm_reconstruction = off: skipped quads are left as holes"));
        return;
    }
    match reconstruct(d, &sc, image, &pending, queue_family, queue_index, how == Reconstruction::Fill) {
        Ok(how) => me.count(|s| {
            for p in &pending {
                *s.reconstructed.entry(p.view).or_insert(0) += 1;
            }
            match how {
                How::Compute(tiles) => {
                    s.compute += pending.len() as u64;
                    s.compute_tiles += tiles;
                }
                How::Fill(why) => *s.fill_fallback.entry(why.name()).or_insert(0) += pending.len() as u64,
                How::Nothing => {}
            }
        }),
        Err((why, msg)) => {
            if why == NotApplied::LayerError {
                me.reconstruct.failed.store(true, Ordering::Relaxed);
            }
            me.count(|s| s.count_not_applied(why));
            log_once(me, format!("reconstruct {}", why.name()), || tracing::warn!("radial density masking: no reconstruction of swapchain {swapchain:#x}: {msg}"));
        }
    }
}

pub(super) type Failure = (NotApplied, String);

/// Which reconstruction ran: the compute pass (tiles dispatched), or the fill and why.
enum How {
    Compute(u64),
    Fill(super::rules::FillFallback),
    Nothing,
}

pub(super) fn layer_error(what: &str) -> impl Fn(vk::Result) -> Failure + '_ {
    move |e| (NotApplied::LayerError, format!("{what}: {e}"))
}

fn reconstruct(d: &DeviceState, sc: &bridge::Swapchain, image: u64, pending: &[Pending], family: u32, queue_index: u32, fill_only: bool) -> Result<How, Failure> {
    let usage = d.track.images.get(image).map(|img| img.usage);
    let format = vk::Format::from_raw(sc.desc.format as i32);
    let (width, height, layers) = (sc.desc.width, sc.desc.height, sc.desc.array_size.max(1));
    let whole = PixelRect { x: 0, y: 0, width, height };
    let eyes: Vec<Pending> = pending.iter().filter(|p| p.layer < layers && p.params.rect.intersect(&whole).area() > 0).copied().collect();
    if eyes.is_empty() {
        return Ok(How::Nothing);
    }
    // An image the layer never saw created is taken to have the usage the layer asked for.
    let has = |u: vk::ImageUsageFlags| usage.is_none_or(|have| have.contains(u));
    if !has(vk::ImageUsageFlags::TRANSFER_SRC) {
        return Err((NotApplied::SwapchainUsage, format!("image usage {usage:?} lacks TRANSFER_SRC")));
    }
    let path = if fill_only { Err(super::rules::FillFallback::Configured) } else { compute_path(format, has(vk::ImageUsageFlags::TRANSFER_DST)) };
    let fallback = match path {
        Ok(storage) => {
            let mut slot = take_slot(d, family)?;
            let r = record_compute(d, &mut slot, image, storage, (width, height, layers), &eyes, family, queue_index);
            give_back(d, slot, r.is_ok());
            match r {
                Ok(tiles) => return Ok(How::Compute(tiles)),
                // Nothing was submitted: the fill may still do it.
                Err(e) => {
                    log_once(super::vk::RdmDevice::of(d), "compute failure".into(), || tracing::warn!("radial density masking: compute reconstruction failed ({}), using the fill", e.1));
                    super::rules::FillFallback::LayerError
                }
            }
        }
        Err(why) => why,
    };
    log_once(super::vk::RdmDevice::of(d), format!("fill {}", fallback.name()), || {
        tracing::info!(?format, ?usage, "radial density masking: reconstruction by the full-screen fill, not the compute pass: {}", fallback.name())
    });
    if !has(vk::ImageUsageFlags::COLOR_ATTACHMENT) {
        return Err((NotApplied::SwapchainUsage, format!("image usage {usage:?} lacks COLOR_ATTACHMENT")));
    }
    let (layout, set_layout, render_pass, pipeline, sampler) = fill_objects(d, format).map_err(|e| (NotApplied::LayerError, e))?;
    let mut slot = take_slot(d, family)?;
    let r = record_and_submit(d, &mut slot, image, format, (width, height, layers), &eyes, family, queue_index, (layout, set_layout, render_pass, pipeline, sampler));
    give_back(d, slot, r.is_ok());
    r.map(|()| How::Fill(fallback))
}

/// Makes sure a reconstruction can run for a pass recorded now for `family`'s queues: the compute
/// objects and one slot with its descriptor set exist. Called before the checkerboard is drawn;
/// on failure the pass gets no checkerboard (and so no holes to fill at the image's release).
/// `with_compute`: the compute pass is wanted (not `rdm_reconstruction = fill`).
pub(super) fn ready(d: &DeviceState, family: u32, with_compute: bool) -> Result<(), Failure> {
    let r = &super::vk::RdmDevice::of(d).reconstruct;
    if r.failed.load(Ordering::Relaxed) {
        return Err((NotApplied::LayerError, "an earlier reconstruction failed".into()));
    }
    if lock(&r.slots).iter().any(|s| s.family == family && (!with_compute || s.compute.set != vk::DescriptorSet::null())) {
        return Ok(());
    }
    let mut slot = new_slot(d, family)?;
    let prepared = if with_compute { compute::ready(d, &mut slot.compute, slot.descriptor_pool) } else { Ok(()) };
    match prepared {
        Ok(()) => {
            lock(&r.slots).push_back(slot);
            Ok(())
        }
        Err(e) => {
            // SAFETY: the slot was never submitted.
            unsafe { destroy_slot(d, slot) };
            r.slot_count.fetch_sub(1, Ordering::Relaxed);
            Err(e)
        }
    }
}

/// Returns a slot for reuse after its submission; a slot whose recording failed was never
/// submitted, so its fence (reset) would never signal: it is destroyed instead.
fn give_back(d: &DeviceState, slot: Slot, submitted: bool) {
    if submitted {
        lock(&super::vk::RdmDevice::of(d).reconstruct.slots).push_back(slot);
    } else {
        // SAFETY: nothing of the slot was submitted since its fence last signalled.
        unsafe { destroy_slot(d, slot) };
        super::vk::RdmDevice::of(d).reconstruct.slot_count.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Begins the slot's command buffer, records the compute reconstruction and submits it.
#[allow(clippy::too_many_arguments)]
fn record_compute(
    d: &DeviceState,
    slot: &mut Slot,
    image: u64,
    storage: super::rules::ComputeStorage,
    shape: (u32, u32, u32),
    eyes: &[Pending],
    family: u32,
    queue_index: u32,
) -> Result<u64, Failure> {
    let cb = slot.cb;
    // SAFETY: our command buffer, reset and not in use (its fence signalled).
    unsafe { d.fns.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)) }.map_err(layer_error("begin"))?;
    let tiles = compute::record(d, &mut slot.compute, slot.descriptor_pool, cb, vk::Image::from_raw(image), storage, (shape.0, shape.1), eyes)?;
    submit(d, slot, family, queue_index)?;
    Ok(tiles)
}

/// Ends the slot's command buffer and submits it with the slot's fence.
pub(super) fn submit(d: &DeviceState, slot: &Slot, family: u32, queue_index: u32) -> Result<(), Failure> {
    // SAFETY: the slot's command buffer, recording; the session's queue, which the OpenXR Vulkan
    // binding lets a call inside xrReleaseSwapchainImage use (the app synchronizes its queue use
    // around these calls); our unsignalled fence.
    unsafe {
        d.fns.end_command_buffer(slot.cb).map_err(layer_error("end"))?;
        let queue = d.fns.get_device_queue(family, queue_index);
        // `stats.gpu_time`: the layer's own work is timed like the app's, in the frame it is
        // submitted in.
        let bracket = crate::plugin::vk::gpu_time::start(d, queue, 1, true);
        let cbs = match &bracket {
            Some(b) => vec![b.begin, slot.cb, b.end],
            None => vec![slot.cb],
        };
        let submit = vk::SubmitInfo::default().command_buffers(&cbs);
        let r = d.fns.queue_submit(queue, &[submit], slot.fence);
        if let Some(b) = bracket {
            crate::plugin::vk::gpu_time::submitted(d, b, queue, r.is_ok());
        }
        r.map_err(layer_error("vkQueueSubmit"))
    }
}

/// A free slot (waiting for the oldest if all are in flight), reset for recording.
fn take_slot(d: &DeviceState, family: u32) -> Result<Slot, Failure> {
    let mut front = lock(&super::vk::RdmDevice::of(d).reconstruct.slots).pop_front();
    // A slot made for another queue family (a command buffer of another pool) cannot record for
    // this queue: it goes back, and this release gets its own.
    if let Some(s) = front.take_if(|s| s.family != family) {
        lock(&super::vk::RdmDevice::of(d).reconstruct.slots).push_back(s);
    }
    // SAFETY: our fence.
    let done = front.as_ref().map(|s| unsafe { d.fns.get_fence_status(s.fence) }.unwrap_or(false));
    let count = super::vk::RdmDevice::of(d).reconstruct.slot_count.load(Ordering::Relaxed);
    let slot = match (super::rules::slot_choice(done, count, MAX_SLOTS), front) {
        (super::rules::SlotChoice::New, front) => match (new_slot(d, family), front) {
            (Ok(made), front) => {
                if let Some(s) = front {
                    lock(&super::vk::RdmDevice::of(d).reconstruct.slots).push_back(s);
                }
                made
            }
            // No new slot can be made: the oldest one, once its work is done, is better than
            // leaving this image's holes (`ready` made sure one exists before the checkerboard).
            (Err(e), Some(s)) => {
                log_once(super::vk::RdmDevice::of(d), "slot fallback".into(), || tracing::warn!("radial density masking: no new reconstruction slot ({}); reusing the oldest", e.1));
                s
            }
            (Err(e), None) => return Err(e),
        },
        (choice, Some(s)) => {
            if choice == super::rules::SlotChoice::WaitOldest {
                super::vk::RdmDevice::of(d).reconstruct.release_waits.fetch_add(1, Ordering::Relaxed);
                log_once(super::vk::RdmDevice::of(d), "release wait".into(), || {
                    tracing::warn!("radial density masking: xrReleaseSwapchainImage waits for an earlier reconstruction ({MAX_SLOTS} in flight: the GPU is that many behind)")
                });
            }
            s
        }
        (_, None) => new_slot(d, family)?,
    };
    // SAFETY: our fence, pool and transient objects; once the fence signalled the GPU is done
    // with everything the slot's last submission used.
    unsafe {
        if let Err(e) = d.fns.wait_for_fences(&[slot.fence], true, SLOT_WAIT_NS) {
            lock(&super::vk::RdmDevice::of(d).reconstruct.slots).push_back(slot);
            return Err((NotApplied::LayerError, format!("waiting for an earlier reconstruction: {e}")));
        }
        let mut slot = slot;
        for (view, fb) in slot.transient.drain(..) {
            d.fns.destroy_framebuffer(fb, None);
            d.fns.destroy_image_view(view, None);
        }
        let reset = d.fns.reset_fences(&[slot.fence]).and_then(|_| d.fns.reset_command_pool(slot.pool, vk::CommandPoolResetFlags::empty()));
        if let Err(e) = reset {
            lock(&super::vk::RdmDevice::of(d).reconstruct.slots).push_back(slot);
            return Err((NotApplied::LayerError, format!("reset: {e}")));
        }
        Ok(slot)
    }
}

fn new_slot(d: &DeviceState, family: u32) -> Result<Slot, Failure> {
    let Some(set_loader_data) = super::vk::RdmDevice::of(d).reconstruct.set_loader_data else {
        return Err((NotApplied::LayerError, "the loader gave no vkSetDeviceLoaderData".into()));
    };
    // SAFETY: valid create infos on our device; every object made here is destroyed on failure
    // paths by `destroy_slot` or at vkDestroyDevice.
    unsafe {
        let pool = d
            .fns
            .create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family), None)
            .map_err(layer_error("command pool"))?;
        let mut slot = Slot {
            family,
            pool,
            cb: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            descriptor_pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            temp: None,
            transient: Vec::new(),
            compute: Default::default(),
        };
        let r = (|| -> Result<(), Failure> {
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
            slot.cb = d.fns.allocate_command_buffers(&alloc).map_err(layer_error("command buffer"))?[0];
            // The loader sets the dispatch word only on objects handed out through it.
            let r = set_loader_data(d.handle, slot.cb.as_raw() as usize as *mut std::ffi::c_void);
            if r != vk::Result::SUCCESS {
                return Err((NotApplied::LayerError, format!("vkSetDeviceLoaderData: {r:?}")));
            }
            slot.fence = d.fns.create_fence(&vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED), None).map_err(layer_error("fence"))?;
            // One set for the fill, one for the compute pass, each allocated on first use.
            let sizes = [
                vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 1 },
                vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 2 },
            ];
            slot.descriptor_pool =
                d.fns.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(2).pool_sizes(&sizes), None).map_err(layer_error("descriptor pool"))?;
            Ok(())
        })();
        if let Err(e) = r {
            destroy_slot(d, slot);
            return Err(e);
        }
        super::vk::RdmDevice::of(d).reconstruct.slot_count.fetch_add(1, Ordering::Relaxed);
        Ok(slot)
    }
}

/// # Safety
/// The slot's work must have completed (or never been submitted).
unsafe fn destroy_slot(d: &DeviceState, mut slot: Slot) {
    // SAFETY: per the contract; null handles are ignored by the destroy functions.
    unsafe {
        for (view, fb) in slot.transient {
            d.fns.destroy_framebuffer(fb, None);
            d.fns.destroy_image_view(view, None);
        }
        if let Some(t) = slot.temp {
            destroy_temp(d, t);
        }
        slot.compute.destroy(d);
        d.fns.destroy_descriptor_pool(slot.descriptor_pool, None);
        d.fns.destroy_fence(slot.fence, None);
        d.fns.destroy_command_pool(slot.pool, None);
    }
}

/// Destroys every RDM object of the device (at vkDestroyDevice, before calling down; the app has
/// waited for the device to go idle, and our submissions are on its queues).
fn destroy_all(r: &Reconstruct, d: &DeviceState) {
    let slots: Vec<Slot> = lock(&r.slots).drain(..).collect();
    let fill = lock(&r.fill).take();
    // SAFETY: our objects; the device is idle (fences waited for safety all the same).
    unsafe {
        for s in slots {
            let _ = d.fns.wait_for_fences(&[s.fence], true, SLOT_WAIT_NS);
            destroy_slot(d, s);
        }
        if let Some(f) = fill {
            destroy_fill(d, f);
        }
    }
}
