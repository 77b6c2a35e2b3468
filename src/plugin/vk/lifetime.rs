//! Layer objects live as long as the GPU needs them: the shell of `core::lifetime`. Every layer
//! object an injection records into an app's command buffer is *held* by that command buffer's
//! recording (an `Arc`), and the recording releases it only when the app begins, resets or frees
//! the command buffer again **and** every submission of it has completed.
//!
//! Completion: after an app's `vkQueueSubmit(2)` that carried held command buffers, the layer
//! submits an empty batch with a fence of its own to the same queue (the spec: a fence submitted
//! with no batches signals when all work previously submitted to the queue has completed), and
//! polls its fences at every submission and every frame end. This works on every Vulkan version
//! and needs no feature (a timeline semaphore would need `timelineSemaphore` enabled by the app).
//!
//! Objects are released by dropping the last `Arc`; their `Drop` hands the raw handles to the
//! device's trash (or back to a pool), emptied at those same points — nothing is destroyed from
//! inside an app's recording call.

use super::DeviceState;
use crate::core::lifetime::{Lifetimes, SubmissionId};
use ash::vk;
use std::any::Any;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Something a recording holds.
pub(crate) type Hold = Arc<dyn Any + Send + Sync>;

/// Raw handles whose last holder is gone.
#[derive(Debug)]
pub(crate) enum Garbage {
    Buffer(vk::Buffer, vk::DeviceMemory),
    Image(vk::ImageView, vk::Image, vk::DeviceMemory),
    DescriptorPool(vk::DescriptorPool),
}

/// Per-device lifetime state.
#[derive(Default)]
pub(crate) struct LifetimeDevice {
    lifetimes: Mutex<Lifetimes<Hold>>,
    /// (submission, the layer's fence for it), oldest first.
    fences: Mutex<VecDeque<(SubmissionId, vk::Fence)>>,
    free_fences: Mutex<Vec<vk::Fence>>,
    pub(crate) trash: Arc<Mutex<Vec<Garbage>>>,
    pub(crate) buffers: Arc<Mutex<Vec<HostBuffer>>>,
}

/// `cb`'s current recording references `h`.
pub(crate) fn hold(d: &DeviceState, cb: u64, h: Hold) {
    lock(&d.lifetime.lifetimes).hold(cb, h);
}

/// Whether a submission of `cb`'s current recording may still be executing.
pub(crate) fn in_flight(d: &DeviceState, cb: u64) -> bool {
    lock(&d.lifetime.lifetimes).in_flight(cb)
}

/// Runs `f` over the holds of `cb`'s current recording (in recording order).
pub(crate) fn with_holds(d: &DeviceState, cb: u64, f: impl FnOnce(&[Hold])) {
    let holds: Vec<Hold> = lock(&d.lifetime.lifetimes).holds_of(cb).to_vec();
    f(&holds);
}

/// The app begins, resets or frees these command buffers: their recordings close.
pub(crate) fn close(d: &DeviceState, cbs: &[u64]) {
    // Whatever a feature keeps for a pass still open in those recordings is void now.
    for f in d.features.all() {
        f.recordings_closed(d, cbs);
    }
    let released: Vec<Hold> = {
        let mut l = lock(&d.lifetime.lifetimes);
        cbs.iter().flat_map(|cb| l.close(*cb)).collect()
    };
    drop(released);
}

/// After the app's submission of `cbs` to `queue` went down successfully: tracks it when it
/// carried held recordings.
pub(crate) fn submitted(d: &DeviceState, queue: vk::Queue, cbs: &[u64]) {
    let Some(id) = lock(&d.lifetime.lifetimes).submitted(cbs) else { return };
    // Popped in a statement of its own: a guard in the `match` scrutinee would live through the
    // arms, which call down (vkCreateFence, vkDeviceWaitIdle).
    let free = lock(&d.lifetime.free_fences).pop();
    let fence = match free {
        Some(f) => f,
        // SAFETY: a valid, default create info.
        None => match unsafe { d.fns.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(e) => {
                d.warn_repeated("lifetime fence", format_args!("{e}; the layer waits for the device instead"));
                wait_idle_and_complete(d, id);
                return;
            }
        },
    };
    // SAFETY: the app's queue, which it does not use concurrently while inside its own
    // vkQueueSubmit (external synchronization); zero batches and our unsignalled fence.
    match unsafe { (d.fns.fp_v1_0().queue_submit)(queue, 0, std::ptr::null(), fence) } {
        vk::Result::SUCCESS => lock(&d.lifetime.fences).push_back((id, fence)),
        e => {
            d.warn_repeated("lifetime fence submission", format_args!("{e:?}; the layer waits for the device instead"));
            lock(&d.lifetime.free_fences).push(fence);
            wait_idle_and_complete(d, id);
        }
    }
    poll(d);
}

fn wait_idle_and_complete(d: &DeviceState, id: SubmissionId) {
    // SAFETY: a valid device; only reached when the layer could not track the submission.
    let _ = unsafe { d.fns.device_wait_idle() };
    let released = lock(&d.lifetime.lifetimes).completed(id);
    drop(released);
}

/// Releases what completed submissions held and empties the trash.
pub(crate) fn poll(d: &DeviceState) {
    loop {
        let Some((id, fence)) = lock(&d.lifetime.fences).front().copied() else { break };
        // SAFETY: our fence.
        match unsafe { d.fns.get_fence_status(fence) } {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => {
                d.warn_repeated("lifetime fence status", e);
                break;
            }
        }
        lock(&d.lifetime.fences).pop_front();
        // SAFETY: our signalled fence, no longer in use.
        if unsafe { d.fns.reset_fences(&[fence]) }.is_ok() {
            lock(&d.lifetime.free_fences).push(fence);
        }
        let released = lock(&d.lifetime.lifetimes).completed(id);
        drop(released);
    }
    empty_trash(d);
}

/// A session on the device ended: the pool's idle buffers are destroyed, with the trash. What
/// the layer keeps between sessions is then what the device needs, not how many buffers the last
/// session happened to have in flight at once (a later session's frames take new ones as they
/// need them); a buffer is in the pool only once the recordings that held it are done.
pub(crate) fn session_ended(d: &DeviceState) {
    let idle = std::mem::take(&mut *lock(&d.lifetime.buffers));
    drop(idle);
    empty_trash(d);
}

fn empty_trash(d: &DeviceState) {
    let garbage = std::mem::take(&mut *lock(&d.lifetime.trash));
    for g in garbage {
        match g {
            // SAFETY: ours; its last holder is gone, so no recording that may still execute
            // references it.
            Garbage::Buffer(b, m) => unsafe {
                d.fns.destroy_buffer(b, None);
                d.fns.free_memory(m, None);
            },
            // SAFETY: as above.
            Garbage::Image(v, i, m) => unsafe {
                d.fns.destroy_image_view(v, None);
                d.fns.destroy_image(i, None);
                d.fns.free_memory(m, None);
            },
            // SAFETY: as above; destroying the pool frees its sets.
            Garbage::DescriptorPool(p) => unsafe { d.fns.destroy_descriptor_pool(p, None) },

        }
    }
}

/// At vkDestroyDevice (the device is idle): every recording's holds go (their objects to the
/// trash, emptied by `destroy`).
pub(crate) fn release_holds(d: &DeviceState) {
    let all = lock(&d.lifetime.lifetimes).drain();
    drop(all);
}

/// At vkDestroyDevice (the device is idle): everything goes.
pub(crate) fn destroy(d: &DeviceState) {
    let all = lock(&d.lifetime.lifetimes).drain();
    drop(all);
    let fences: Vec<vk::Fence> = lock(&d.lifetime.fences).drain(..).map(|(_, f)| f).chain(lock(&d.lifetime.free_fences).drain(..)).collect();
    for f in fences {
        // SAFETY: ours; the device is idle.
        unsafe { d.fns.destroy_fence(f, None) };
    }
    let pooled = std::mem::take(&mut *lock(&d.lifetime.buffers));
    drop(pooled);
    empty_trash(d);
}

/// The first memory type among `bits` with all of `wanted`.
pub(crate) fn memory_type(props: &vk::PhysicalDeviceMemoryProperties, bits: u32, wanted: vk::MemoryPropertyFlags) -> Option<u32> {
    (0..props.memory_type_count).find(|&i| bits & (1 << i) != 0 && props.memory_types[i as usize].property_flags.contains(wanted))
}

/// A buffer of `size` bytes with `usage`, bound to new memory of the first type that has all of
/// one entry of `preferences` (tried in order); the type's flags come back with it. Nothing is
/// left behind on failure. The layer's one way to make a buffer with memory of its own.
pub(crate) fn bound_buffer(
    fns: &ash::Device,
    props: &vk::PhysicalDeviceMemoryProperties,
    size: u64,
    usage: vk::BufferUsageFlags,
    preferences: &[vk::MemoryPropertyFlags],
) -> Result<(vk::Buffer, vk::DeviceMemory, vk::MemoryPropertyFlags), String> {
    let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: a valid create info on the caller's device.
    let buffer = unsafe { fns.create_buffer(&info, None) }.map_err(|e| format!("vkCreateBuffer: {e}"))?;
    // SAFETY: our buffer, just made.
    let req = unsafe { fns.get_buffer_memory_requirements(buffer) };
    let Some(t) = preferences.iter().find_map(|&wanted| memory_type(props, req.memory_type_bits, wanted)) else {
        // SAFETY: our unused buffer.
        unsafe { fns.destroy_buffer(buffer, None) };
        return Err(format!("no memory type with {preferences:?}"));
    };
    let alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t);
    // SAFETY: a valid allocate info; the memory is bound once, to our unused buffer; on failure
    // both are freed (nothing else knows them).
    let r = unsafe { fns.allocate_memory(&alloc, None).and_then(|m| fns.bind_buffer_memory(buffer, m, 0).map(|_| m).inspect_err(|_| fns.free_memory(m, None))) };
    match r {
        Ok(m) => Ok((buffer, m, props.memory_types[t as usize].property_flags)),
        Err(e) => {
            // SAFETY: our unused buffer.
            unsafe { fns.destroy_buffer(buffer, None) };
            Err(format!("vkAllocateMemory / vkBindBufferMemory: {e}"))
        }
    }
}

/// A host buffer that goes back to its device's pool (bounded) when its last holder lets go:
/// what a recording's injected draws read.
pub(crate) struct PooledBuffer {
    buf: Option<HostBuffer>,
    pool: Arc<Mutex<Vec<HostBuffer>>>,
}

impl PooledBuffer {
    /// A pooled buffer of at least `size` bytes, or a new one.
    pub(crate) fn take(d: &DeviceState, size: u64, memory: &vk::PhysicalDeviceMemoryProperties) -> Result<PooledBuffer, String> {
        Ok(PooledBuffer { buf: Some(HostBuffer::take(d, size, memory)?), pool: d.lifetime.buffers.clone() })
    }
}

impl std::ops::Deref for PooledBuffer {
    type Target = HostBuffer;
    fn deref(&self) -> &HostBuffer {
        // Only `Drop` takes it out.
        self.buf.as_ref().expect("a pooled buffer is present until dropped")
    }
}

impl Drop for PooledBuffer {
    fn drop(&mut self) {
        if let Some(b) = self.buf.take() {
            let mut p = lock(&self.pool);
            if p.len() < 32 {
                p.push(b);
            }
        }
    }
}

/// A persistently mapped, host-visible, coherent buffer of the layer's. Dropped: back to the
/// device's pool (up to a bound) or into its trash.
pub(crate) struct HostBuffer {
    pub buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    ptr: *mut u8,
    pub size: u64,
    trash: Arc<Mutex<Vec<Garbage>>>,
}

// SAFETY: the mapping is only written through `write`, by the thread that owns the buffer's
// recording or submission (callers serialize writes with their own locks); the handles are plain
// values.
unsafe impl Send for HostBuffer {}
// SAFETY: as above; `&HostBuffer` only reads plain values.
unsafe impl Sync for HostBuffer {}

impl HostBuffer {
    /// A pooled buffer of at least `size` bytes (vertex, indirect and storage usage: draws read
    /// it as either, RDM's compute reconstruction reads its tile list from it), or a new one.
    fn take(d: &DeviceState, size: u64, memory: &vk::PhysicalDeviceMemoryProperties) -> Result<HostBuffer, String> {
        {
            let mut pool = lock(&d.lifetime.buffers);
            if let Some(i) = pool.iter().position(|b| b.size >= size && b.size <= size.max(4096) * 4) {
                return Ok(pool.swap_remove(i));
            }
        }
        let size = size.next_power_of_two().max(4096);
        // TRANSFER_DST: query results are copied into some; STORAGE: RDM's compute reads tile
        // lists from some.
        let usage = vk::BufferUsageFlags::VERTEX_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::STORAGE_BUFFER;
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: a valid create info.
        let buffer = unsafe { d.fns.create_buffer(&info, None) }.map_err(|e| e.to_string())?;
        // SAFETY: our buffer.
        let req = unsafe { d.fns.get_buffer_memory_requirements(buffer) };
        let wanted = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let Some(t) = memory_type(memory, req.memory_type_bits, wanted) else {
            // SAFETY: our unused buffer.
            unsafe { d.fns.destroy_buffer(buffer, None) };
            return Err("no host-visible coherent memory type".into());
        };
        let alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(t);
        // SAFETY: a valid allocate info; on failure our buffer is destroyed; the memory is bound
        // once and mapped for its whole life (unmapped implicitly when freed).
        let r = unsafe {
            d.fns.allocate_memory(&alloc, None).and_then(|m| {
                d.fns.bind_buffer_memory(buffer, m, 0).and_then(|_| d.fns.map_memory(m, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())).map(|p| (m, p)).inspect_err(|_| d.fns.free_memory(m, None))
            })
        };
        match r {
            Ok((memory, p)) => Ok(HostBuffer { buffer, memory, ptr: p.cast(), size, trash: d.lifetime.trash.clone() }),
            Err(e) => {
                // SAFETY: our unused buffer.
                unsafe { d.fns.destroy_buffer(buffer, None) };
                Err(e.to_string())
            }
        }
    }

    /// Copies `data` to `offset`. The caller makes sure no submission that may still execute
    /// reads the range (a fresh buffer, or one whose recordings are idle).
    pub(crate) fn write<T: Copy>(&self, offset: u64, data: &[T]) -> bool {
        let len = std::mem::size_of_val(data) as u64;
        if offset + len > self.size {
            return false;
        }
        // SAFETY: in bounds of the mapping (checked); coherent memory, so the write is visible to
        // every later queue submission.
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr().cast::<u8>(), self.ptr.add(offset as usize), len as usize) };
        true
    }
}

impl HostBuffer {
    /// Reads `n` values at `offset` (what the GPU wrote, once the writing submission completed
    /// and made it visible to the host); empty when out of bounds.
    pub(crate) fn read<T: Copy + Default>(&self, offset: u64, n: usize) -> Vec<T> {
        let len = (n * std::mem::size_of::<T>()) as u64;
        if offset + len > self.size {
            return Vec::new();
        }
        let mut out = vec![T::default(); n];
        // SAFETY: in bounds of the mapping (checked); coherent memory; `T` is plain data.
        unsafe { std::ptr::copy_nonoverlapping(self.ptr.add(offset as usize), out.as_mut_ptr().cast::<u8>(), len as usize) };
        out
    }
}

impl Drop for HostBuffer {
    fn drop(&mut self) {
        if self.buffer != vk::Buffer::null() {
            lock(&self.trash).push(Garbage::Buffer(std::mem::take(&mut self.buffer), std::mem::take(&mut self.memory)));
        }
    }
}
