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
//! One command pool per queue family (command buffers must come from a pool of the family of the
//! primary they are executed in). Pools are externally synchronized, so each has a mutex, held while
//! one secondary is allocated, begun, recorded and ended: only the layer's own objects are touched
//! under it, and nothing recorded into them calls back into the layer.

use super::DeviceState;
use ash::vk::{self, Handle};
use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};

#[derive(Default)]
pub(crate) struct SecondaryDevice {
    /// Queue family → its pool and the secondaries free for reuse.
    pools: Mutex<HashMap<u32, Mutex<Pool>>>,
    /// App primary → the layer's secondaries executed in it (family, handle).
    owned: Mutex<HashMap<u64, Vec<(u32, vk::CommandBuffer)>>>,
}

struct Pool {
    pool: vk::CommandPool,
    free: Vec<vk::CommandBuffer>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
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
    let pools = lock(&d.secondary.pools);
    if !pools.contains_key(&family) {
        drop(pools);
        let info = vk::CommandPoolCreateInfo::default()
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER)
            .queue_family_index(family);
        // SAFETY: a valid create info for a queue family the app's own pool uses.
        let pool = unsafe { d.fns.create_command_pool(&info, None) }.map_err(|e| format!("vkCreateCommandPool: {e}"))?;
        let mut pools = lock(&d.secondary.pools);
        match pools.entry(family) {
            // Another thread made one meanwhile.
            // SAFETY: ours, never used.
            std::collections::hash_map::Entry::Occupied(_) => unsafe { d.fns.destroy_command_pool(pool, None) },
            std::collections::hash_map::Entry::Vacant(v) => {
                v.insert(Mutex::new(Pool { pool, free: Vec::new() }));
            }
        }
        drop(pools);
        return self::record(d, primary, inherit, record);
    }
    let pool = &pools[&family];
    let mut p = lock(pool);
    let cb = match p.free.pop() {
        Some(cb) => cb,
        None => {
            let info = vk::CommandBufferAllocateInfo::default()
                .command_pool(p.pool)
                .level(vk::CommandBufferLevel::SECONDARY)
                .command_buffer_count(1);
            // SAFETY: our pool, synchronized by its mutex.
            let cbs = unsafe { d.fns.allocate_command_buffers(&info) }.map_err(|e| format!("vkAllocateCommandBuffers: {e}"))?;
            let cb = cbs[0];
            // Dispatchable: the loader sets the dispatch word only on objects handed out through
            // it, so a layer must set it on its own before using them.
            let set = d.set_loader_data.ok_or("the loader gave no vkSetDeviceLoaderData")?;
            // SAFETY: the loader's callback for this device and a command buffer allocated on it.
            let r = unsafe { set(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void) };
            if r != vk::Result::SUCCESS {
                // SAFETY: ours, never used; its pool is locked.
                unsafe { d.fns.free_command_buffers(p.pool, &[cb]) };
                return Err(format!("vkSetDeviceLoaderData: {r:?}"));
            }
            cb
        }
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
    // SAFETY: our secondary, not pending (free or new), its pool locked; valid begin info.
    let begun = unsafe { d.fns.begin_command_buffer(cb, &begin) };
    if let Err(e) = begun {
        p.free.push(cb);
        return Err(format!("vkBeginCommandBuffer: {e}"));
    }
    record(cb);
    // SAFETY: as above, recording.
    if let Err(e) = unsafe { d.fns.end_command_buffer(cb) } {
        p.free.push(cb);
        return Err(format!("vkEndCommandBuffer: {e}"));
    }
    drop(p);
    drop(pools);
    lock(&d.secondary.owned).entry(primary).or_default().push((family, cb));
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
    let pool = {
        let pools = lock(&d.secondary.pools);
        pools.get(&family).map(|p| lock(p).pool)
    };
    let pool = match pool {
        Some(p) => p,
        None => {
            let info = vk::CommandPoolCreateInfo::default().flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER).queue_family_index(family);
            // SAFETY: a valid create info for a queue family the app submits to.
            let pool = unsafe { d.fns.create_command_pool(&info, None) }.map_err(|e| format!("vkCreateCommandPool: {e}"))?;
            let mut pools = lock(&d.secondary.pools);
            match pools.entry(family) {
                std::collections::hash_map::Entry::Occupied(o) => {
                    // SAFETY: ours, never used (another thread made one meanwhile).
                    unsafe { d.fns.destroy_command_pool(pool, None) };
                    lock(o.get()).pool
                }
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(Mutex::new(Pool { pool, free: Vec::new() }));
                    pool
                }
            }
        }
    };
    let cb = {
        // The pool is externally synchronized: held while allocating and recording, released
        // before the submission goes down.
        let pools = lock(&d.secondary.pools);
        let _pool_guard = pools.get(&family).map(lock);
        let info = vk::CommandBufferAllocateInfo::default().command_pool(pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
        // SAFETY: our pool, synchronized by its mutex (held).
        let cb = unsafe { d.fns.allocate_command_buffers(&info) }.map_err(|e| format!("vkAllocateCommandBuffers: {e}"))?[0];
        let set = d.set_loader_data.ok_or("the loader gave no vkSetDeviceLoaderData")?;
        // SAFETY: the loader's callback for this device and a command buffer allocated on it.
        let r = unsafe { set(d.handle, cb.as_raw() as usize as *mut std::ffi::c_void) };
        if r != vk::Result::SUCCESS {
            return Err(format!("vkSetDeviceLoaderData: {r:?}"));
        }
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: our new command buffer, its pool locked.
        unsafe { d.fns.begin_command_buffer(cb, &begin) }.map_err(|e| format!("vkBeginCommandBuffer: {e}"))?;
        record(cb);
        // SAFETY: as above, recording.
        unsafe { d.fns.end_command_buffer(cb) }.map_err(|e| format!("vkEndCommandBuffer: {e}"))?;
        cb
    };
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
    let released: Vec<(u32, vk::CommandBuffer)> = {
        let mut owned = lock(&d.secondary.owned);
        if owned.is_empty() {
            return;
        }
        primaries.iter().filter_map(|p| owned.remove(p)).flatten().collect()
    };
    if released.is_empty() {
        return;
    }
    let pools = lock(&d.secondary.pools);
    for (family, cb) in released {
        if let Some(pool) = pools.get(&family) {
            lock(pool).free.push(cb);
        }
    }
}

/// `vkDestroyDevice`: the device is idle (the app's obligation), so every pool can go.
pub(crate) fn destroy(d: &DeviceState) {
    let pools = std::mem::take(&mut *lock(&d.secondary.pools));
    lock(&d.secondary.owned).clear();
    for (_, pool) in pools {
        let pool = pool.into_inner().unwrap_or_else(|e| e.into_inner());
        // SAFETY: our pool; the device is idle; destroying it frees its command buffers.
        unsafe { d.fns.destroy_command_pool(pool.pool, None) };
    }
}
