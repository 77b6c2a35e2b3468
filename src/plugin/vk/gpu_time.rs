//! The layer's GPU frame timer (`stats.gpu_time`), the Vulkan shell of `core::gpu_time`: every
//! queue submission — the app's (`vkQueueSubmit`, `vkQueueSubmit2`) and the layer's own work
//! (RDM's reconstruction, `plugin::vk::secondary::prepare_once` / `submit_prepared`) — is bracketed by two command buffers of
//! the layer's, one writing a `TOP_OF_PIPE` timestamp put first into the first batch, one writing
//! a `BOTTOM_OF_PIPE` timestamp put last into the last batch. Inside the app's own batches, the batches' semaphore waits come
//! before the first and their signals and the app's fence after the last, so the app's
//! synchronization is unchanged; a timestamp's synchronization scope is every command earlier in
//! submission order, so the second one is written when all of the submission's work is done.
//!
//! Per queue: one query pool, a ring of slots (two queries, the two command buffers recorded once,
//! and a fence each). After a timed submission the layer submits an empty batch with the slot's
//! fence (it signals once everything submitted before it completed); a slot's results are read
//! only after its fence signalled — never waiting, at later submissions and frame ends — and only
//! then is the slot reused, so no command buffer is resubmitted while pending and no query is read
//! before the reset of its new use ran. Frames: `core::gpu_time::Frames`.
//!
//! Off (the default): nothing here runs but one settings check per submission. Any failure logs
//! once and stops the timer for the device (its submissions pass through unchanged).

use super::DeviceState;
use crate::core::gpu_time::{valid_mask, Frames, GpuFrameTime, Ring, Ticket};
use ash::vk::{self, Handle};
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

/// Slots per queue: submissions whose results may be outstanding at once (several frames of
/// several submissions each); when all are in flight a submission goes untimed.
const SLOTS: u32 = 128;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What the device's physical device tells about timestamps, read at the timer's first use.
struct Props {
    period_ns: f64,
    /// `timestampValidBits` per queue family (0: no timestamps), and whether the family can reset
    /// queries in a command buffer (graphics or compute).
    families: Vec<(u32, bool)>,
    /// The fewest valid bits among the families that are timed: the bits all of them share.
    bits: u32,
    /// Queue → family, from the device's queue create infos.
    queue_family: HashMap<u64, u32>,
}

/// The app's device's queue create infos (family, count, flags), kept so queues can be mapped to
/// their families without a hook of vkGetDeviceQueue.
pub(crate) type QueueInfos = Vec<(u32, u32, vk::DeviceQueueCreateFlags)>;

/// Per-device timer state; all of it made lazily at the first timed submission.
pub(crate) struct GpuTimeDevice {
    instance: ash::Instance,
    physical: vk::PhysicalDevice,
    queue_infos: QueueInfos,
    props: OnceLock<Props>,
    /// Queue → its timer (None: its family cannot be timed).
    queues: Mutex<HashMap<u64, Option<Arc<QueueTimer>>>>,
    frames: Mutex<Frames>,
    used: AtomicBool,
    failed: AtomicBool,
    logged: Mutex<HashSet<String>>,
    /// Submissions timed / not timed (the device's stats line).
    timed: AtomicU64,
    untimed: AtomicU64,
}

struct Slot {
    begin: vk::CommandBuffer,
    end: vk::CommandBuffer,
    fence: vk::Fence,
}

struct QueueTimer {
    query_pool: vk::QueryPool,
    command_pool: vk::CommandPool,
    slots: Vec<Slot>,
    ring: Mutex<Ring>,
}

/// A timed submission: put `begin` first into its first batch and `end` last into its last, then
/// hand it to `submitted`.
pub(crate) struct Bracket {
    pub begin: vk::CommandBuffer,
    pub end: vk::CommandBuffer,
    timer: Arc<QueueTimer>,
    slot: u32,
    ticket: Ticket,
}

impl GpuTimeDevice {
    pub(crate) fn new(instance: ash::Instance, physical: vk::PhysicalDevice, queue_infos: QueueInfos) -> GpuTimeDevice {
        GpuTimeDevice {
            instance,
            physical,
            queue_infos,
            props: OnceLock::new(),
            queues: Mutex::default(),
            frames: Mutex::default(),
            used: AtomicBool::new(false),
            failed: AtomicBool::new(false),
            logged: Mutex::default(),
            timed: AtomicU64::new(0),
            untimed: AtomicU64::new(0),
        }
    }
}

fn log_once(d: &DeviceState, key: &str, msg: impl FnOnce() -> String) {
    if lock(&d.gpu_time.logged).insert(key.to_string()) {
        tracing::warn!("gpu time: {}", msg());
    }
}

/// A failure: logged once, and the device's timer stops (its frames are written without times).
fn fail(d: &DeviceState, msg: String) {
    d.gpu_time.failed.store(true, Ordering::Relaxed);
    log_once(d, "failed", || format!("{msg}; no more GPU times on this device"));
}

/// The physical device's timestamp properties and the device's queues (calls down; no lock held).
fn props(d: &DeviceState) -> &Props {
    if let Some(p) = d.gpu_time.props.get() {
        return p;
    }
    let g = &d.gpu_time;
    // SAFETY: the physical device the app created this device on; the next layer's instance
    // functions of its instance, which outlives the device.
    let (limits, families) = unsafe { (g.instance.get_physical_device_properties(g.physical).limits, g.instance.get_physical_device_queue_family_properties(g.physical)) };
    let families: Vec<(u32, bool)> =
        families.iter().map(|f| (f.timestamp_valid_bits, f.queue_flags.intersects(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE))).collect();
    let mut queue_family = HashMap::new();
    for &(family, count, flags) in &g.queue_infos {
        // Queues created with flags (protected) are only reachable through vkGetDeviceQueue2;
        // their submissions stay untimed.
        if !flags.is_empty() {
            continue;
        }
        for index in 0..count {
            // SAFETY: a queue the app's create info asked for, with no flags.
            let q = unsafe { d.fns.get_device_queue(family, index) };
            queue_family.insert(q.as_raw(), family);
        }
    }
    let bits = queue_family.values().filter_map(|f| families.get(*f as usize)).filter(|f| f.0 > 0 && f.1).map(|f| f.0).min().unwrap_or(64);
    let _ = g.props.set(Props { period_ns: limits.timestamp_period as f64, families, bits, queue_family });
    g.props.get().expect("set above")
}

/// `queue`'s timer, made at its first timed submission; None when its family cannot be timed.
fn queue_timer(d: &DeviceState, queue: vk::Queue) -> Option<Arc<QueueTimer>> {
    if let Some(t) = lock(&d.gpu_time.queues).get(&queue.as_raw()) {
        return t.clone();
    }
    let p = props(d);
    let timer = match p.queue_family.get(&queue.as_raw()) {
        None => {
            log_once(d, &format!("queue {:#x}", queue.as_raw()), || format!("queue {:#x} is not one of the device's create infos without flags: not timed", queue.as_raw()));
            None
        }
        Some(&family) => match p.families.get(family as usize).copied().unwrap_or((0, false)) {
            (0, _) => {
                log_once(d, &format!("family {family}"), || format!("queue family {family} has no timestamps (timestampValidBits = 0): its submissions are not timed"));
                None
            }
            (_, false) => {
                log_once(d, &format!("family {family}"), || format!("queue family {family} has neither graphics nor compute (no query reset in a command buffer): its submissions are not timed"));
                None
            }
            _ => match create_queue_timer(d, family) {
                Ok(t) => {
                    tracing::info!("gpu time: timing the submissions of queue {:#x} (family {family}, {SLOTS} slots, {} ns per tick, {} valid bits)", queue.as_raw(), p.period_ns, p.bits);
                    Some(Arc::new(t))
                }
                Err(e) => {
                    fail(d, format!("queue family {family}: {e}"));
                    return None;
                }
            },
        },
    };
    let mut queues = lock(&d.gpu_time.queues);
    match queues.get(&queue.as_raw()) {
        // Another thread made one meanwhile (the app may use queues from several threads); ours
        // was never submitted.
        Some(existing) => {
            let existing = existing.clone();
            drop(queues);
            if let Some(t) = timer.and_then(|t| Arc::try_unwrap(t).ok()) {
                // SAFETY: ours, never submitted.
                unsafe { destroy_queue_timer(d, t) };
            }
            existing
        }
        None => {
            queues.insert(queue.as_raw(), timer.clone());
            timer
        }
    }
}

fn create_queue_timer(d: &DeviceState, family: u32) -> Result<QueueTimer, String> {
    if d.settings().fails_in("stats.gpu_time") {
        return Err("failing on purpose (debug.fail_in)".into());
    }
    let set_loader_data = d.set_loader_data.ok_or("the loader gave no vkSetDeviceLoaderData")?;
    let mut t = QueueTimer { query_pool: vk::QueryPool::null(), command_pool: vk::CommandPool::null(), slots: Vec::new(), ring: Mutex::new(Ring::new(SLOTS)) };
    // SAFETY: valid create infos on our device; on failure everything made so far is destroyed
    // (never submitted); the command buffers are ours and recorded here only.
    let r = unsafe {
        (|| -> Result<(), String> {
            t.query_pool = d
                .fns
                .create_query_pool(&vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2 * SLOTS), None)
                .map_err(|e| format!("vkCreateQueryPool: {e}"))?;
            t.command_pool = d.fns.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family), None).map_err(|e| format!("vkCreateCommandPool: {e}"))?;
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(t.command_pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(2 * SLOTS);
            let cbs = d.fns.allocate_command_buffers(&alloc).map_err(|e| format!("vkAllocateCommandBuffers: {e}"))?;
            for (s, pair) in cbs.chunks(2).enumerate() {
                let first = 2 * s as u32;
                for cb in pair {
                    // The loader sets the dispatch word only on objects handed out through it.
                    let r = set_loader_data(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void);
                    if r != vk::Result::SUCCESS {
                        return Err(format!("vkSetDeviceLoaderData: {r:?}"));
                    }
                }
                // Recorded once, submitted once per use of the slot (never while pending: the
                // slot is reused only after its fence signalled).
                let begin_info = vk::CommandBufferBeginInfo::default();
                d.fns.begin_command_buffer(pair[0], &begin_info).map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
                // Both queries are reset here, ahead of both writes in submission order.
                d.fns.cmd_reset_query_pool(pair[0], t.query_pool, first, 2);
                d.fns.cmd_write_timestamp(pair[0], vk::PipelineStageFlags::TOP_OF_PIPE, t.query_pool, first);
                d.fns.end_command_buffer(pair[0]).map_err(|e| format!("vkEndCommandBuffer: {e}"))?;
                d.fns.begin_command_buffer(pair[1], &begin_info).map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
                d.fns.cmd_write_timestamp(pair[1], vk::PipelineStageFlags::BOTTOM_OF_PIPE, t.query_pool, first + 1);
                d.fns.end_command_buffer(pair[1]).map_err(|e| format!("vkEndCommandBuffer: {e}"))?;
                let fence = d.fns.create_fence(&vk::FenceCreateInfo::default(), None).map_err(|e| format!("vkCreateFence: {e}"))?;
                t.slots.push(Slot { begin: pair[0], end: pair[1], fence });
            }
            Ok(())
        })()
    };
    match r {
        Ok(()) => Ok(t),
        Err(e) => {
            // SAFETY: nothing of it was submitted.
            unsafe { destroy_queue_timer(d, t) };
            Err(e)
        }
    }
}

/// # Safety
/// No submission using the timer's objects may be pending.
unsafe fn destroy_queue_timer(d: &DeviceState, t: QueueTimer) {
    // SAFETY: per the contract; null handles are ignored; freeing the pool frees its buffers.
    unsafe {
        for s in &t.slots {
            d.fns.destroy_fence(s.fence, None);
        }
        d.fns.destroy_command_pool(t.command_pool, None);
        d.fns.destroy_query_pool(t.query_pool, None);
    }
}

/// Before a submission of `batches` batches to `queue` (0: no command buffer in any, nothing to
/// time): the bracket to add, or None (timer off, nothing to time, or this submission cannot be
/// timed — then counted untimed for its frame).
/// `timeable`: false for submissions the layer must not add command buffers to (protected ones,
/// device-group masks per command buffer).
pub(crate) fn start(d: &DeviceState, queue: vk::Queue, batches: u32, timeable: bool) -> Option<Bracket> {
    if batches == 0 || !d.settings().stats_gpu_time || d.gpu_time.failed.load(Ordering::Relaxed) {
        return None;
    }
    d.gpu_time.used.store(true, Ordering::Relaxed);
    let timer = queue_timer(d, queue);
    let (Some(timer), true) = (timer, timeable) else {
        if !timeable {
            log_once(d, "untimeable", || "a protected or device-group submission is not timed".into());
        }
        lock(&d.gpu_time.frames).untimed();
        d.gpu_time.untimed.fetch_add(1, Ordering::Relaxed);
        return None;
    };
    poll_queue(d, &timer);
    let ticket = lock(&d.gpu_time.frames).begin();
    let Some(slot) = lock(&timer.ring).start(ticket) else {
        log_once(d, "ring full", || format!("all {SLOTS} timestamp slots of a queue in flight: submissions go untimed until results come back"));
        let mut f = lock(&d.gpu_time.frames);
        f.cancel(ticket);
        f.untimed();
        d.gpu_time.untimed.fetch_add(1, Ordering::Relaxed);
        return None;
    };
    d.gpu_time.timed.fetch_add(1, Ordering::Relaxed);
    let s = &timer.slots[slot as usize];
    Some(Bracket { begin: s.begin, end: s.end, slot, ticket, timer })
}

/// After the bracketed submission to `queue` went down (`ok`: it succeeded). A failed call leaves
/// the command buffers not pending (the spec), so the slot is free again.
pub(crate) fn submitted(d: &DeviceState, b: Bracket, queue: vk::Queue, ok: bool) {
    if !ok {
        lock(&b.timer.ring).finish(b.slot, b.ticket);
        lock(&d.gpu_time.frames).cancel(b.ticket);
        return;
    }
    let fence = b.timer.slots[b.slot as usize].fence;
    // SAFETY: the app's queue, which it does not use concurrently while inside its own submission
    // (external synchronization) or while the layer submits its own work on it; zero batches and
    // the slot's unsignalled fence (a slot is taken only with its fence reset).
    let r = unsafe { (d.fns.fp_v1_0().queue_submit)(queue, 0, std::ptr::null(), fence) };
    if r != vk::Result::SUCCESS {
        // The slot stays in flight for good: its command buffers may be pending, and the timer
        // stops, so it is never reused.
        lock(&d.gpu_time.frames).lost(b.ticket);
        fail(d, format!("fence submission: {r:?}"));
    }
}

/// Reads the results of the queue's slots whose fences signalled, oldest first, without waiting.
fn poll_queue(d: &DeviceState, t: &QueueTimer) {
    let mask = valid_mask(props(d).bits);
    loop {
        let Some((slot, ticket)) = lock(&t.ring).claim() else { return };
        let fence = t.slots[slot as usize].fence;
        // SAFETY: the slot's fence, submitted after its work; only this (claiming) reader touches
        // it until `read` hands the slot back.
        let signalled = unsafe { d.fns.get_fence_status(fence) };
        match signalled {
            Ok(true) => {}
            Ok(false) => {
                lock(&t.ring).read(slot, ticket, false);
                return;
            }
            Err(e) => {
                lock(&t.ring).read(slot, ticket, false);
                fail(d, format!("vkGetFenceStatus: {e}"));
                return;
            }
        }
        // Two queries, each a 64-bit value followed by its availability.
        let mut data = [0u64; 4];
        // SAFETY: two queries of our pool whose submission completed (its fence signalled after
        // it); the array holds two (value, availability) pairs of u64 with a 16-byte stride.
        let r = unsafe {
            (d.fns.fp_v1_0().get_query_pool_results)(
                d.handle,
                t.query_pool,
                2 * slot,
                2,
                std::mem::size_of_val(&data),
                data.as_mut_ptr().cast(),
                16,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WITH_AVAILABILITY,
            )
        };
        // SAFETY: our signalled fence; its submission completed, and the slot is not taken again
        // before `read` frees it below.
        let reset = unsafe { d.fns.reset_fences(&[fence]) };
        let available = (r == vk::Result::SUCCESS || r == vk::Result::NOT_READY) && data[1] != 0 && data[3] != 0;
        {
            let mut f = lock(&d.gpu_time.frames);
            if available {
                f.finish(ticket, data[0] & mask, data[2] & mask);
            } else {
                f.lost(ticket);
            }
        }
        if let Err(e) = reset {
            lock(&t.ring).read(slot, ticket, false);
            fail(d, format!("vkResetFences: {e}"));
            return;
        }
        lock(&t.ring).read(slot, ticket, true);
        if !available {
            log_once(d, "unavailable", || format!("timestamps unavailable after their fence signalled ({r:?}): those submissions count untimed"));
        }
    }
}

/// Reads what completed on every queue of the device.
fn poll(d: &DeviceState) {
    let timers: Vec<Arc<QueueTimer>> = lock(&d.gpu_time.queues).values().flatten().cloned().collect();
    for t in timers {
        poll_queue(d, &t);
    }
}

/// `xrEndFrame` closed frame `frame`: the device's submissions since the last close are its work.
/// Returns the frames whose times are complete now (usually earlier ones).
pub(crate) fn end_frame(d: &DeviceState, frame: u64) -> Vec<(u64, GpuFrameTime)> {
    if !d.gpu_time.used.load(Ordering::Relaxed) {
        return Vec::new();
    }
    if d.gpu_time.failed.load(Ordering::Relaxed) {
        // A stopped timer may have slots that never come back: keep nothing per frame (the
        // frames' lines go out without a time).
        *lock(&d.gpu_time.frames) = Frames::default();
        return Vec::new();
    }
    poll(d);
    let p = props(d);
    let mut f = lock(&d.gpu_time.frames);
    f.close_frame(frame);
    f.take_complete(p.bits, p.period_ns)
}

/// The frames whose times completed since the last frame end (the session ends).
pub(crate) fn complete(d: &DeviceState) -> Vec<(u64, GpuFrameTime)> {
    if !d.gpu_time.used.load(Ordering::Relaxed) {
        return Vec::new();
    }
    poll(d);
    let p = props(d);
    lock(&d.gpu_time.frames).take_complete(p.bits, p.period_ns)
}

/// `gpu_timed=… gpu_untimed=…` for the device's stats line; None when the timer never ran.
pub(crate) fn summary(d: &DeviceState) -> Option<String> {
    d.gpu_time.used.load(Ordering::Relaxed).then(|| format!("gpu_timed={} gpu_untimed={}", d.gpu_time.timed.load(Ordering::Relaxed), d.gpu_time.untimed.load(Ordering::Relaxed)))
}

/// At vkDestroyDevice (the app waited for the device to go idle).
pub(crate) fn destroy(d: &DeviceState) {
    let timers: Vec<Arc<QueueTimer>> = lock(&d.gpu_time.queues).drain().filter_map(|(_, t)| t).collect();
    for t in timers {
        match Arc::try_unwrap(t) {
            // SAFETY: the device is idle; nothing of ours is pending.
            Ok(t) => unsafe { destroy_queue_timer(d, t) },
            Err(_) => tracing::warn!("gpu time: a queue timer still in use at vkDestroyDevice; its objects go with the device"),
        }
    }
}
