//! The layer's own secondary command buffers, for eye passes whose contents the app records into
//! secondary command buffers (`VK_SUBPASS_CONTENTS_SECONDARY_COMMAND_BUFFERS`,
//! `VK_RENDERING_CONTENTS_SECONDARY_COMMAND_BUFFERS_BIT`): nothing but `vkCmdExecuteCommands` may
//! be recorded into such a pass, so the layer records its draws into a secondary of its own that
//! inherits the pass and executes it first, ahead of the app's.
//!
//! Lifetime: each of the layer's secondaries belongs to the app's primary it was executed in, and
//! goes back to the free list only when the app begins, resets or frees that primary (or resets or
//! destroys its pool). The spec requires the primary not to be pending then, so neither is ours: a
//! primary recorded once and resubmitted every frame keeps its secondary for as long as it lives.
//!
//! Command pools per queue family (command buffers must come from a pool of the family of the
//! primary they are executed in). Pools are externally synchronized, so a thread *takes* one out
//! of the family's idle list while it allocates, begins, records and ends command buffers of it,
//! and puts it back after; a thread that finds none idle makes another. No lock is held across
//! those calls down: what is below the layer may call back into it (tests/hardening/reentry.rs).

use super::DeviceState;
use ash::vk::{self, Handle};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};

#[derive(Default)]
pub(crate) struct SecondaryDevice {
    /// Queue family → its pools that no thread is using now.
    idle: Mutex<HashMap<u32, Vec<Arc<Pool>>>>,
    /// Every pool of the layer's, destroyed with the device.
    all: Mutex<Vec<Arc<Pool>>>,
    /// App primary → the layer's secondaries executed in it.
    owned: Mutex<HashMap<u64, Vec<Owned>>>,
}

/// One of the layer's secondaries and the pool it came from.
type Owned = (Arc<Pool>, vk::CommandBuffer);

struct Pool {
    pool: vk::CommandPool,
    /// Secondaries free for reuse. Bookkeeping only (no call down under it): `release` returns
    /// command buffers here whichever thread has the pool taken.
    free: Mutex<Vec<vk::CommandBuffer>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A pool taken out of its family's idle list: this thread alone uses it (external
/// synchronization) until it goes back, when this is dropped.
struct Taken<'a> {
    secondary: &'a SecondaryDevice,
    family: u32,
    pool: Arc<Pool>,
}

impl Drop for Taken<'_> {
    fn drop(&mut self) {
        lock(&self.secondary.idle).entry(self.family).or_default().push(self.pool.clone());
    }
}

/// Takes an idle pool of `family`, or makes one (with no lock held while it is made).
fn take(d: &DeviceState, family: u32) -> Result<Taken<'_>, String> {
    let idle = lock(&d.secondary.idle).get_mut(&family).and_then(Vec::pop);
    let pool = match idle {
        Some(p) => p,
        None => {
            let info = vk::CommandPoolCreateInfo::default().flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER).queue_family_index(family);
            // SAFETY: a valid create info for a queue family the app's own pool uses or the app
            // submits to.
            let pool = unsafe { d.fns.create_command_pool(&info, None) }.map_err(|e| format!("vkCreateCommandPool: {e}"))?;
            let pool = Arc::new(Pool { pool, free: Mutex::default() });
            lock(&d.secondary.all).push(pool.clone());
            pool
        }
    };
    Ok(Taken { secondary: &d.secondary, family, pool })
}

/// Allocates one command buffer of `level` from a taken pool and hands it to the loader.
fn allocate(d: &DeviceState, pool: &Taken<'_>, level: vk::CommandBufferLevel) -> Result<vk::CommandBuffer, String> {
    let info = vk::CommandBufferAllocateInfo::default().command_pool(pool.pool.pool).level(level).command_buffer_count(1);
    // SAFETY: our pool, taken by this thread.
    let cb = unsafe { d.fns.allocate_command_buffers(&info) }.map_err(|e| format!("vkAllocateCommandBuffers: {e}"))?[0];
    // Dispatchable: the loader sets the dispatch word only on objects handed out through it, so a
    // layer must set it on its own before using them.
    let set = d.set_loader_data.ok_or("the loader gave no vkSetDeviceLoaderData")?;
    // SAFETY: the loader's callback for this device and a command buffer allocated on it.
    let r = unsafe { set(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void) };
    if r != vk::Result::SUCCESS {
        // SAFETY: ours, never used; its pool is taken by this thread.
        unsafe { d.fns.free_command_buffers(pool.pool.pool, &[cb]) };
        return Err(format!("vkSetDeviceLoaderData: {r:?}"));
    }
    Ok(cb)
}

/// The pass a secondary must inherit.
pub(crate) enum Inherit<'a> {
    RenderPass { render_pass: u64, subpass: u32, framebuffer: u64 },
    Rendering { flags: vk::RenderingFlags, view_mask: u32, colors: &'a [vk::Format], depth: vk::Format, stencil: vk::Format, samples: vk::SampleCountFlags },
}

/// Records `record` into a secondary of the layer's that inherits `inherit`, owned by `primary`
/// from now on. Returns the secondary to execute ahead of the app's, or why there is none.
pub(crate) fn record(
    d: &DeviceState,
    primary: u64,
    inherit: &Inherit<'_>,
    record: impl FnOnce(vk::CommandBuffer),
) -> Result<vk::CommandBuffer, String> {
    let family = d
        .track
        .command_buffers
        .get(primary)
        .and_then(|c| d.track.pools.get(c.pool))
        .map(|p| p.queue_family_index)
        .ok_or("the primary's command pool is unknown")?;
    let pool = take(d, family)?;
    let reused = lock(&pool.pool.free).pop();
    let cb = match reused {
        Some(cb) => cb,
        None => allocate(d, &pool, vk::CommandBufferLevel::SECONDARY)?,
    };
    let mut rendering_info;
    let mut inheritance = vk::CommandBufferInheritanceInfo::default();
    match inherit {
        Inherit::RenderPass { render_pass, subpass, framebuffer } => {
            inheritance = inheritance
                .render_pass(vk::RenderPass::from_raw(*render_pass))
                .subpass(*subpass)
                .framebuffer(vk::Framebuffer::from_raw(*framebuffer));
        }
        Inherit::Rendering { flags, view_mask, colors, depth, stencil, samples } => {
            rendering_info = vk::CommandBufferInheritanceRenderingInfo::default()
                // The flags of the app's VkRenderingInfo without the contents bit
                // (VUID-vkCmdExecuteCommands-flags-06025).
                .flags(*flags & !vk::RenderingFlags::CONTENTS_SECONDARY_COMMAND_BUFFERS)
                .view_mask(*view_mask)
                .color_attachment_formats(colors)
                .depth_attachment_format(*depth)
                .stencil_attachment_format(*stencil)
                .rasterization_samples(*samples);
            inheritance = inheritance.push_next(&mut rendering_info);
        }
    }
    let begin = vk::CommandBufferBeginInfo::default()
        .flags(vk::CommandBufferUsageFlags::RENDER_PASS_CONTINUE)
        .inheritance_info(&inheritance);
    // SAFETY: our secondary, not pending (free or new), its pool taken by this thread; valid
    // begin info.
    let begun = unsafe { d.fns.begin_command_buffer(cb, &begin) };
    if let Err(e) = begun {
        lock(&pool.pool.free).push(cb);
        return Err(format!("vkBeginCommandBuffer: {e}"));
    }
    record(cb);
    // SAFETY: as above, recording.
    if let Err(e) = unsafe { d.fns.end_command_buffer(cb) } {
        lock(&pool.pool.free).push(cb);
        return Err(format!("vkEndCommandBuffer: {e}"));
    }
    let owner = pool.pool.clone();
    drop(pool);
    lock(&d.secondary.owned).entry(primary).or_default().push((owner, cb));
    Ok(cb)
}

/// Records `record` into a one-time primary of the layer's of queue `family`, for
/// [`submit_prepared`] ahead of a later app submission there: rare set-up work (image layout
/// initialisation, query pool resets); the command buffer stays allocated until the device goes.
/// Set-up work that an app command buffer depends on is prepared
/// when the layer records that dependency, so a failure to make the command buffer can still
/// turn the feature off for that command buffer (issue 11: once the app's command buffer is
/// recorded, a set-up submission that cannot be made would leave it reading uninitialised state).
pub(crate) fn prepare_once(d: &DeviceState, family: u32, record: impl FnOnce(vk::CommandBuffer)) -> Result<vk::CommandBuffer, String> {
    // The pool is externally synchronized: taken while allocating and recording, back before
    // the submission goes down.
    let pool = take(d, family)?;
    let cb = allocate(d, &pool, vk::CommandBufferLevel::PRIMARY)?;
    let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
    // SAFETY: our new command buffer, its pool taken by this thread.
    unsafe { d.fns.begin_command_buffer(cb, &begin) }.map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
    record(cb);
    // SAFETY: as above, recording.
    unsafe { d.fns.end_command_buffer(cb) }.map_err(|e| format!("vkEndCommandBuffer: {e}"))?;
    Ok(cb)
}

/// Submits command buffers made by [`prepare_once`] to `queue` (of their family), ahead of the
/// app's submission that is about to go down.
pub(crate) fn submit_prepared(d: &DeviceState, queue: vk::Queue, prepared: &[vk::CommandBuffer]) -> Result<(), String> {
    // `stats.gpu_time`: the layer's own work is timed like the app's, in the frame it is
    // submitted in.
    let bracket = super::gpu_time::start(d, queue, 1, true);
    let cbs = match &bracket {
        Some(b) => [&[b.begin][..], prepared, &[b.end]].concat(),
        None => prepared.to_vec(),
    };
    let submit = vk::SubmitInfo::default().command_buffers(&cbs);
    // SAFETY: the app's queue, held by the app's vkQueueSubmit that called us (external
    // synchronization); our executable command buffers, never freed before the device, and the
    // timer's, if any.
    let r = unsafe { (d.fns.fp_v1_0().queue_submit)(queue, 1, &submit, vk::Fence::null()) };
    if let Some(b) = bracket {
        super::gpu_time::submitted(d, b, queue, r == vk::Result::SUCCESS);
    }
    r.result().map_err(|e| format!("vkQueueSubmit: {e}"))
}

/// The app begins, resets or frees `primaries` (or their pool): they are not pending, so the
/// layer's secondaries executed in them can be reused.
pub(crate) fn release(d: &DeviceState, primaries: &[u64]) {
    let released: Vec<Owned> = {
        let mut owned = lock(&d.secondary.owned);
        if owned.is_empty() {
            return;
        }
        primaries.iter().filter_map(|p| owned.remove(p)).flatten().collect()
    };
    for (pool, cb) in released {
        lock(&pool.free).push(cb);
    }
}

/// `vkDestroyDevice`: the device is idle (the app's obligation), so every pool can go.
pub(crate) fn destroy(d: &DeviceState) {
    let pools = std::mem::take(&mut *lock(&d.secondary.all));
    lock(&d.secondary.idle).clear();
    lock(&d.secondary.owned).clear();
    for pool in pools {
        // SAFETY: our pool; the device is idle (no layer call is using it); destroying it frees
        // its command buffers.
        unsafe { d.fns.destroy_command_pool(pool.pool, None) };
    }
}
