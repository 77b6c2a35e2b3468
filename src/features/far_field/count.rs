//! Counting the pixels the far field reuses, exactly: an occlusion query around each reuse draw
//! counts the samples that survive its depth test and its `discard`, i.e. the reused ones. After
//! the pass the results are copied into a host buffer and the queries reset (both outside the pass,
//! so a command buffer recorded once counts every submission); the host adds them up once the
//! submission has completed (before the recording's next submission, or when its hold goes).
//!
//! Query pools are recycled: a counter whose hold went has had its queries reset by its own
//! readback (or never used them), so the next counter takes them as they are; only new pools need
//! the one-time reset ahead of their first submission, recorded when the pool is made.

use crate::plugin::vk::lifetime::PooledBuffer;
use crate::plugin::vk::DeviceState;
use ash::vk;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// One reuse op's queries.
pub(super) struct Counter {
    pub(super) pool: vk::QueryPool,
    pub(super) queries: u32,
    results: PooledBuffer,
    /// Samples per pixel of the pass (occlusion queries count samples).
    samples: u64,
    /// Where collected counts go: the device's running total of reused pixels.
    total: Arc<AtomicU64>,
    /// Reset pools ready for reuse, by query count.
    free: Arc<Mutex<Vec<(vk::QueryPool, u32)>>>,
}

/// The device's pools ready for reuse.
pub(super) type FreePools = Arc<Mutex<Vec<(vk::QueryPool, u32)>>>;

impl Counter {
    /// A counter of `queries` queries for a pass recorded in a command buffer of queue family
    /// `family`, with, when its pool is new, the one-time reset of that pool already recorded in
    /// a command buffer of that family, to be submitted ahead of the next submission there.
    ///
    /// The reset is prepared here, not at submission: once the app's command buffer has the
    /// queries in it, a reset that cannot be made (no command pool, no command buffer) would
    /// leave the app's submission using unreset queries (issue 11, found by tests/hardening/faults_vk.rs).
    /// Failing now, the pool is destroyed and the pass is not counted; nothing reaches the app.
    pub(super) fn new(
        d: &DeviceState,
        memory: &vk::PhysicalDeviceMemoryProperties,
        queries: u32,
        samples: u32,
        total: Arc<AtomicU64>,
        free: &FreePools,
        family: Option<u32>,
    ) -> Result<(Counter, Option<(u32, vk::CommandBuffer)>), String> {
        let results = PooledBuffer::take(d, 8 * queries as u64, memory)?;
        // A pooled buffer may hold an earlier user's numbers.
        results.write(0, &vec![0u64; queries as usize]);
        let reused = {
            let mut f = free.lock().unwrap_or_else(|e| e.into_inner());
            f.iter().position(|(_, n)| *n == queries).map(|i| f.swap_remove(i).0)
        };
        let (pool, reset) = match reused {
            Some(p) => (p, None),
            None => {
                let family = family.ok_or("the command buffer's queue family is unknown: its new query pool cannot be reset")?;
                let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::OCCLUSION).query_count(queries);
                // SAFETY: a valid create info; the pool is ours until the device goes (`destroy`).
                let pool = unsafe { d.fns.create_query_pool(&info, None) }.map_err(|e| e.to_string())?;
                let reset = crate::plugin::vk::secondary::prepare_once(d, family, |cb| {
                    // SAFETY: our one-time command buffer, recording, outside any pass; our new
                    // pool, which no submission has used yet.
                    unsafe { (d.fns.fp_v1_0().cmd_reset_query_pool)(cb, pool, 0, queries) }
                });
                match reset {
                    Ok(cb) => (pool, Some((family, cb))),
                    Err(e) => {
                        // SAFETY: our pool, never recorded anywhere.
                        unsafe { d.fns.destroy_query_pool(pool, None) };
                        return Err(format!("query pool reset: {e}"));
                    }
                }
            }
        };
        Ok((Counter { pool, queries, results, samples: samples.max(1) as u64, total, free: free.clone() }, reset))
    }

    /// Records, after the pass that used the queries: their results into the host buffer (waiting
    /// for them on the GPU), made visible to the host, then the reset for the next submission.
    pub(super) fn record_readback(&self, d: &DeviceState, cb: vk::CommandBuffer) {
        let fns = d.fns.fp_v1_0();
        let barrier = vk::MemoryBarrier::default().src_access_mask(vk::AccessFlags::TRANSFER_WRITE).dst_access_mask(vk::AccessFlags::HOST_READ);
        // SAFETY: `cb` is the app's command buffer outside any pass; the pool and the buffer are
        // held by its recording (the op owning this counter).
        unsafe {
            (fns.cmd_copy_query_pool_results)(cb, self.pool, 0, self.queries, self.results.buffer, 0, 8, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT);
            (fns.cmd_pipeline_barrier)(cb, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::HOST, vk::DependencyFlags::empty(), 1, &barrier, 0, std::ptr::null(), 0, std::ptr::null());
            (fns.cmd_reset_query_pool)(cb, self.pool, 0, self.queries);
        }
    }

    /// Adds what the last completed submission counted to the total (and clears it, so nothing
    /// is counted twice). Only called while no submission of the recording may execute.
    pub(super) fn collect(&self) -> u64 {
        let counts = self.results.read::<u64>(0, self.queries as usize);
        let samples: u64 = counts.iter().sum();
        if samples == 0 {
            return 0;
        }
        self.results.write(0, &vec![0u64; self.queries as usize]);
        let pixels = samples / self.samples;
        self.total.fetch_add(pixels, Ordering::Relaxed);
        pixels
    }
}

impl Drop for Counter {
    /// The hold is released once every submission completed: the last one's count is in.
    fn drop(&mut self) {
        self.collect();
        self.free.lock().unwrap_or_else(|e| e.into_inner()).push((std::mem::take(&mut self.pool), self.queries));
    }
}

/// Destroys the pools ready for reuse (at `vkDestroyDevice`, after every hold went).
pub(super) fn destroy(d: &DeviceState, free: &FreePools) {
    // Taken in a statement of its own: a guard in the `for` expression lives through the loop,
    // whose body calls down.
    let pools = std::mem::take(&mut *free.lock().unwrap_or_else(|e| e.into_inner()));
    for (pool, _) in pools {
        // SAFETY: our pool; the device is idle and no recording holds it any more.
        unsafe { d.fns.destroy_query_pool(pool, None) };
    }
}
