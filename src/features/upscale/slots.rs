//! The command buffers of a session's upscales (`Slots`): a small ring reused once each fence
//! signalled, with the timestamps that give `stats.file` the upscale's own GPU time and phases.

use crate::plugin::vk::DeviceState;
use ash::vk;
use ash::vk::Handle as _;

fn err(what: &'static str) -> impl Fn(vk::Result) -> String {
    move |e| format!("{what}: {e}")
}

/// The command buffers of one session's upscales: reused once their fence signalled, at most
/// `MAX` in flight (then the oldest is waited for).
pub(crate) struct Slots {
    pool: vk::CommandPool,
    ring: std::collections::VecDeque<(vk::CommandBuffer, vk::Fence)>,
    pub queue: vk::Queue,
    /// Two timestamps per slot (`MAX` slots), around each upscale's commands: its own GPU time,
    /// read back when the slot is reused (`take`). None where the queue has no timestamps.
    queries: Option<(vk::QueryPool, f64)>,
    /// Which query pair each ring entry wrote (by its command buffer).
    query_of: std::collections::HashMap<vk::CommandBuffer, u32>,
    /// The GPU time of the last upscale read back, ms, and its phases (`MARKS` - 1 intervals:
    /// barriers in, EASU, RCAS and the copy (or the fragment pass), barriers out) of the
    /// submission's last swapchain; the first interval also holds the earlier swapchains' work.
    pub last_gpu_ms: Option<f64>,
    pub last_phases_ms: Vec<f64>,
}

/// Timestamps per upscale: start, after the barriers in, after EASU, after RCAS and the copy (or
/// the fragment pass), end.
pub(crate) const MARKS: u32 = 5;

/// Upscales in flight before an `xrEndFrame` waits: a frame submits one per swapchain (two for
/// per-eye apps), and runtimes let an app run up to about three frames ahead.
const MAX: usize = 8;
/// How long `xrEndFrame` waits for an old upscale before giving up on this one.
const WAIT_NS: u64 = 2_000_000_000;

impl Slots {
    /// `timestamp_period`: ns per tick, 0 where the queue family has no timestamps.
    pub(crate) fn new(d: &DeviceState, family: u32, queue_index: u32, timestamp_period: f32) -> Result<Slots, String> {
        // SAFETY: a valid create info for the session's queue family on a live device.
        let pool = unsafe { d.fns.create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(family).flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER), None) }.map_err(err("vkCreateCommandPool"))?;
        // SAFETY: the binding's queue exists (the runtime accepted the binding).
        let queue = unsafe { d.fns.get_device_queue(family, queue_index) };
        let queries = (timestamp_period > 0.0).then(|| {
            let ci = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(MARKS * MAX as u32);
            // SAFETY: a valid create info; without the pool the upscale is only untimed.
            unsafe { d.fns.create_query_pool(&ci, None) }.ok().map(|q| (q, timestamp_period as f64 / 1e6))
        });
        Ok(Slots { pool, ring: Default::default(), queue, queries: queries.flatten(), query_of: Default::default(), last_gpu_ms: None, last_phases_ms: Vec::new() })
    }

    /// Records timestamp `k` (0: start, `MARKS` - 1: end) of `cb`'s upscale. Each is written once
    /// every earlier command on the queue completed: from the first on, the time is the
    /// upscale's, its layout transitions included.
    ///
    /// # Safety
    /// `cb` is recording, and was handed out by `take`.
    pub(crate) unsafe fn mark(&self, d: &DeviceState, cb: vk::CommandBuffer, k: u32) {
        let (Some((pool, _)), Some(&pair)) = (self.queries, self.query_of.get(&cb)) else { return };
        // SAFETY: per the contract; the queries belong to this buffer alone.
        unsafe {
            if k == 0 {
                d.fns.cmd_reset_query_pool(cb, pool, MARKS * pair, MARKS);
            }
            d.fns.cmd_write_timestamp(cb, vk::PipelineStageFlags::ALL_COMMANDS, pool, MARKS * pair + k.min(MARKS - 1));
        }
    }

    /// Reads the timestamps of a completed buffer.
    fn read(&mut self, d: &DeviceState, cb: vk::CommandBuffer) {
        let (Some((pool, ms_per_tick)), Some(&pair)) = (self.queries, self.query_of.get(&cb)) else { return };
        let mut t = [0u64; MARKS as usize];
        // SAFETY: the buffer completed (its fence signalled), so every query it wrote is written;
        // marks a recording skipped (no EASU) read as unavailable and fail the whole read.
        let r = unsafe { d.fns.get_query_pool_results(pool, MARKS * pair, &mut t, vk::QueryResultFlags::TYPE_64) };
        if r.is_ok() && t[MARKS as usize - 1] >= t[0] {
            self.last_gpu_ms = Some((t[MARKS as usize - 1] - t[0]) as f64 * ms_per_tick);
            self.last_phases_ms = t.windows(2).map(|w| w[1].saturating_sub(w[0]) as f64 * ms_per_tick).collect();
        }
    }

    /// The fence `take` would wait for next (the ring is full and its oldest upscale still runs):
    /// the caller waits for it with no lock held (`wait`), so `take` then finds it signalled.
    pub(crate) fn due(&self, d: &DeviceState) -> Option<vk::Fence> {
        let &(_, fence) = self.ring.front()?;
        // SAFETY: the layer's own fence of a live device.
        (self.ring.len() >= MAX && !unsafe { d.fns.get_fence_status(fence) }.unwrap_or(false)).then_some(fence)
    }

    /// A command buffer to record into (reset), with its fence (unsignalled).
    pub(crate) fn take(&mut self, d: &DeviceState) -> Result<(vk::CommandBuffer, vk::Fence), String> {
        // SAFETY: the layer's own objects of a live device; a fence is reset only once signalled
        // (its command buffer is then no longer in use).
        unsafe {
            let ready = self.ring.front().is_some_and(|&(_, f)| d.fns.get_fence_status(f).unwrap_or(false));
            let (cb, fence) = if ready || self.ring.len() >= MAX {
                let (cb, fence) = self.ring.pop_front().expect("checked non-empty");
                if !ready {
                    d.fns.wait_for_fences(&[fence], true, WAIT_NS).map_err(err("waiting for an earlier upscale"))?;
                }
                self.read(d, cb);
                d.fns.reset_fences(&[fence]).map_err(err("vkResetFences"))?;
                d.fns.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty()).map_err(err("vkResetCommandBuffer"))?;
                (cb, fence)
            } else {
                let alloc = vk::CommandBufferAllocateInfo::default().command_pool(self.pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
                let cb = d.fns.allocate_command_buffers(&alloc).map_err(err("vkAllocateCommandBuffers"))?[0];
                // The loader sets the dispatch word only on objects handed out through it.
                if let Some(set) = d.set_loader_data {
                    let r = set(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void);
                    if r != vk::Result::SUCCESS {
                        d.fns.free_command_buffers(self.pool, &[cb]);
                        return Err(format!("vkSetDeviceLoaderData: {r:?}"));
                    }
                }
                let fence = match d.fns.create_fence(&vk::FenceCreateInfo::default(), None) {
                    Ok(f) => f,
                    Err(e) => {
                        d.fns.free_command_buffers(self.pool, &[cb]);
                        return Err(format!("vkCreateFence: {e}"));
                    }
                };
                let pair = self.query_of.len() as u32;
                self.query_of.insert(cb, pair);
                (cb, fence)
            };
            self.ring.push_back((cb, fence));
            Ok((cb, fence))
        }
    }

    /// Waits for every upscale in flight (before their objects are destroyed).
    pub(crate) fn wait_all(&self, d: &DeviceState) {
        let fences: Vec<vk::Fence> = self.ring.iter().map(|&(_, f)| f).collect();
        if fences.is_empty() {
            return;
        }
        // SAFETY: the layer's own fences. A fence never submitted (its recording failed) was
        // taken out of the ring by `abandon`, so every fence here will signal.
        if let Err(e) = unsafe { d.fns.wait_for_fences(&fences, true, WAIT_NS) } {
            tracing::warn!("upscale: waiting for the last upscales failed ({e}); destroying their objects anyway");
        }
    }

    /// `cb` (handed out by `take`) was not submitted: its fence would never signal.
    pub(crate) fn abandon(&mut self, d: &DeviceState, cb: vk::CommandBuffer) {
        let Some(at) = self.ring.iter().position(|&(c, _)| c == cb) else { return };
        let (cb, fence) = self.ring.remove(at).expect("found");
        // Its query pair goes with it; the buffer holding the highest pair takes it over, so the
        // pairs stay 0..len.
        if let Some(freed) = self.query_of.remove(&cb) {
            let top = self.query_of.len() as u32;
            if let Some((_, last)) = self.query_of.iter_mut().find(|(_, p)| **p == top) {
                *last = freed;
            }
        }
        // SAFETY: never submitted, so not in use.
        unsafe {
            d.fns.destroy_fence(fence, None);
            d.fns.free_command_buffers(self.pool, &[cb]);
        }
    }

    pub(crate) fn destroy(&mut self, d: &DeviceState) {
        self.wait_all(d);
        // SAFETY: idle (waited above); the pool frees its command buffers.
        unsafe {
            for (_, f) in self.ring.drain(..) {
                d.fns.destroy_fence(f, None);
            }
            d.fns.destroy_command_pool(self.pool, None);
            if let Some((q, _)) = self.queries.take() {
                d.fns.destroy_query_pool(q, None);
            }
        }
    }
}

/// Waits for an upscale's `fence` (from `Slots::due`), as `take` would; a failure is `take`'s to
/// report when it waits again.
pub(crate) fn wait(d: &DeviceState, fence: vk::Fence) {
    // SAFETY: the layer's own fence, submitted (it is in the ring), of a live device; the ring
    // keeps it until `take` resets it after this wait.
    let _ = unsafe { d.fns.wait_for_fences(&[fence], true, WAIT_NS) };
}
