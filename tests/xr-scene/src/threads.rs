//! `--threads`: the frame loop spread over threads as engines spread it (tests/threads.rs).
//!
//! - **Frame pacing** ([`Pacer`]): `xrWaitFrame` runs on a thread of its own, which hands each
//!   `XrFrameState` to the render thread over a channel. The render thread asks for the next wait
//!   right after `xrBeginFrame`, so frame N+1's `xrWaitFrame` runs while frame N is recorded,
//!   submitted and ended (the spec lets it start once frame N is begun).
//! - **Recording** ([`Workers`]): each pass's secondary command buffer is recorded on a worker
//!   thread with a `VkCommandPool` of its own; the render thread records the primary after them.
//! - **Submission** ([`Submitter`]): a thread of its own makes every `vkQueueSubmit`.
//!
//! Session state (events, `xrBeginSession` / `xrEndSession`), swapchain image acquire / release and
//! `xrEndFrame` stay on the render thread.

use crate::error::{Ctx, Error, Result};
use crate::gpu::Gpu;
use crate::xr::XrSession;
use ash::vk;
use openxr as oxr;
use std::sync::mpsc;
use std::thread::JoinHandle;

/// Where `xrWaitFrame` runs: inline on the render thread, or (`--threads`) on the frame-pacing
/// thread.
pub struct Pacer {
    thread: Option<PacerThread>,
}

struct PacerThread {
    /// A message asks for one `xrWaitFrame`; dropping the sender ends the thread.
    request: Option<mpsc::Sender<()>>,
    result: mpsc::Receiver<std::result::Result<oxr::FrameState, oxr::sys::Result>>,
    /// Hands the `FrameWaiter` back when it ends.
    handle: Option<JoinHandle<oxr::FrameWaiter>>,
    /// A wait was asked for and its result not yet taken.
    outstanding: bool,
}

impl Pacer {
    /// With `threaded`, moves the session's `FrameWaiter` to a new frame-pacing thread (given
    /// back by [`Pacer::join`]).
    pub fn new(xs: &mut XrSession, threaded: bool) -> Result<Pacer> {
        if !threaded {
            return Ok(Pacer { thread: None });
        }
        let mut waiter = xs.waiter.take().ok_or_else(|| Error("internal: the session's frame waiter is taken".into()))?;
        let (request, requests) = mpsc::channel::<()>();
        let (results, result) = mpsc::channel();
        let handle = std::thread::Builder::new()
            .name("xr-wait-frame".into())
            .spawn(move || {
                // Only when asked: the render thread asks while the session runs, never after
                // it began ending it, so no xrWaitFrame runs after xrEndSession.
                while requests.recv().is_ok() {
                    if results.send(waiter.wait()).is_err() {
                        break;
                    }
                }
                waiter
            })
            .ctx("spawning the frame-pacing thread")?;
        Ok(Pacer { thread: Some(PacerThread { request: Some(request), result, handle: Some(handle), outstanding: false }) })
    }

    /// The next frame's state: waited for here, or taken from the pacing thread (asking it first
    /// if [`Pacer::begun`] did not already).
    pub fn wait(&mut self, xs: &mut XrSession) -> Result<oxr::FrameState> {
        let Some(t) = &mut self.thread else {
            return xs.waiter.as_mut().ok_or_else(|| Error("internal: no frame waiter".into()))?.wait().ctx("xrWaitFrame");
        };
        if !t.outstanding {
            t.ask()?;
        }
        t.outstanding = false;
        t.result.recv().map_err(|_| Error("the frame-pacing thread ended".into()))?.ctx("xrWaitFrame (frame-pacing thread)")
    }

    /// Called after `xrBeginFrame`: the pacing thread starts the next frame's `xrWaitFrame` now,
    /// while this frame is recorded, submitted and ended.
    pub fn begun(&mut self) -> Result<()> {
        match &mut self.thread {
            Some(t) => t.ask(),
            None => Ok(()),
        }
    }

    /// Before `xrEndSession`: waits for a wait in flight and drops its frame (never begun, which
    /// the spec allows), so that none runs during or after `xrEndSession`.
    pub fn stop(&mut self) -> Result<()> {
        if let Some(t) = &mut self.thread {
            if t.outstanding {
                t.outstanding = false;
                // A failed wait of a session that is ending anyway is of no consequence.
                let _ = t.result.recv().map_err(|_| Error("the frame-pacing thread ended".into()))?;
            }
        }
        Ok(())
    }

    /// Ends the pacing thread and gives the `FrameWaiter` back to the session: before the session
    /// is destroyed.
    pub fn join(mut self, xs: &mut XrSession) -> Result<()> {
        self.stop()?;
        if let Some(waiter) = self.thread.as_mut().map(PacerThread::end).transpose()?.flatten() {
            xs.waiter = Some(waiter);
        }
        Ok(())
    }
}

impl PacerThread {
    fn ask(&mut self) -> Result<()> {
        let gone = || Error("the frame-pacing thread ended".into());
        self.request.as_ref().ok_or_else(gone)?.send(()).map_err(|_| gone())?;
        self.outstanding = true;
        Ok(())
    }

    fn end(&mut self) -> Result<Option<oxr::FrameWaiter>> {
        drop(self.request.take());
        match self.handle.take() {
            Some(h) => h.join().map(Some).map_err(|_| Error("the frame-pacing thread panicked".into())),
            None => Ok(None),
        }
    }
}

impl Drop for PacerThread {
    /// On an error path: the thread ends once a wait in flight returns (its result is dropped).
    fn drop(&mut self) {
        let _ = self.end();
    }
}

/// One submission's command buffer and fence, and whether it goes down with vkQueueSubmit2.
#[derive(Debug, Clone, Copy)]
pub struct Submission {
    pub cmd: vk::CommandBuffer,
    pub fence: vk::Fence,
    pub submit2: bool,
}

/// Makes the queue submissions: on the calling thread, or (`--threads`) on the submit thread,
/// which owns every `vkQueueSubmit` of the renderer. [`Submitter::submit`] returns only once the
/// submission was made, because the OpenXR Vulkan binding makes the app externally synchronize the
/// queue with the runtime's `xrBeginFrame`, `xrEndFrame`, `xrAcquireSwapchainImage` and
/// `xrReleaseSwapchainImage`, which the render thread calls next.
pub struct Submitter {
    device: ash::Device,
    queue: vk::Queue,
    thread: Option<SubmitThread>,
}

struct SubmitThread {
    request: Option<mpsc::Sender<Submission>>,
    result: mpsc::Receiver<Result<f64>>,
    handle: Option<JoinHandle<()>>,
}

impl Submitter {
    pub fn new(gpu: &Gpu, threaded: bool) -> Result<Submitter> {
        let thread = if threaded {
            let (request, requests) = mpsc::channel::<Submission>();
            let (results, result) = mpsc::channel();
            let (device, queue) = (gpu.device.clone(), gpu.queue);
            let handle = std::thread::Builder::new()
                .name("vk-submit".into())
                .spawn(move || {
                    for s in requests {
                        if results.send(queue_submit(&device, queue, s)).is_err() {
                            break;
                        }
                    }
                })
                .ctx("spawning the submit thread")?;
            Some(SubmitThread { request: Some(request), result, handle: Some(handle) })
        } else {
            None
        };
        Ok(Submitter { device: gpu.device.clone(), queue: gpu.queue, thread })
    }

    /// Submits `s` and returns once `vkQueueSubmit(2)` returned, with the CPU time of the call
    /// itself in µs (measured on the thread that made it).
    pub fn submit(&self, s: Submission) -> Result<f64> {
        match &self.thread {
            None => queue_submit(&self.device, self.queue, s),
            Some(t) => {
                let gone = || Error("the submit thread ended".into());
                t.request.as_ref().ok_or_else(gone)?.send(s).map_err(|_| gone())?;
                t.result.recv().map_err(|_| gone())?
            }
        }
    }
}

impl Drop for Submitter {
    fn drop(&mut self) {
        if let Some(t) = &mut self.thread {
            drop(t.request.take());
            if let Some(h) = t.handle.take() {
                let _ = h.join();
            }
        }
    }
}

/// One `vkQueueSubmit` (or `vkQueueSubmit2`) of one command buffer signalling `fence`; returns
/// the call's CPU time in µs.
fn queue_submit(d: &ash::Device, queue: vk::Queue, s: Submission) -> Result<f64> {
    let start = std::time::Instant::now();
    submit_one(d, queue, s)?;
    Ok(start.elapsed().as_secs_f64() * 1e6)
}

fn submit_one(d: &ash::Device, queue: vk::Queue, s: Submission) -> Result<()> {
    let cmds = [s.cmd];
    if s.submit2 {
        let infos = [vk::CommandBufferSubmitInfo::default().command_buffer(s.cmd)];
        // SAFETY: the caller hands over a fully recorded command buffer that is not pending and an
        // unsignalled fence, and waits for this call before it touches the queue again
        // (`Submitter::submit`), so access to the queue is externally synchronized. Only
        // requested with synchronization2 enabled (`--submit2`).
        unsafe { d.queue_submit2(queue, &[vk::SubmitInfo2::default().command_buffer_infos(&infos)], s.fence) }.ctx("vkQueueSubmit2")
    } else {
        // SAFETY: as above.
        unsafe { d.queue_submit(queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], s.fence) }.ctx("vkQueueSubmit")
    }
}

/// The recording workers of `--threads`: worker `i` records pass `i`'s secondary command buffer,
/// allocated from worker `i`'s own command pool (pools are externally synchronized: one thread
/// at a time per pool, so two workers must not share one).
///
/// The workers are scoped threads, started for each frame that records and joined before the
/// primary is recorded, rather than a persistent pool: the borrow checker then proves that every
/// worker is done with the draw state, the pass targets and its pool before the render thread
/// records the primary, frees or re-records anything, with no shutdown protocol to get wrong. The
/// price, two thread starts per recorded frame (tens of µs), is nothing next to the recording
/// itself under validation.
pub struct Workers {
    device: ash::Device,
    pools: Vec<vk::CommandPool>,
    /// Frames whose passes were recorded on workers, and those in which two workers' recordings
    /// overlapped in time.
    pub recorded: u64,
    pub overlapped: u64,
}

impl Workers {
    pub fn new(gpu: &Gpu, count: usize) -> Result<Workers> {
        let mut w = Workers { device: gpu.device.clone(), pools: Vec::new(), recorded: 0, overlapped: 0 };
        for _ in 0..count {
            let info = vk::CommandPoolCreateInfo::default()
                .queue_family_index(gpu.queue_family)
                .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
            // SAFETY: plain object creation on a live device; destroyed in Drop (also on failure).
            w.pools.push(unsafe { gpu.device.create_command_pool(&info, None) }.ctx("vkCreateCommandPool(worker)")?);
        }
        Ok(w)
    }

    /// Worker `i`'s command pool. Used only by worker `i` while [`Workers::record`] runs and by
    /// the render thread otherwise (allocation, destruction).
    pub fn pool(&self, i: usize) -> vk::CommandPool {
        self.pools[i]
    }

    /// Runs `job(i, meet)` for every worker `i` < `n` at once, each on a thread of its own, and
    /// returns once all are done (the first error, if any). A job calls [`MeetHandle::arrive`]
    /// after recording its commands and before ending its command buffer.
    pub fn record(&mut self, n: usize, job: impl Fn(usize, &MeetHandle<'_>) -> Result<()> + Sync) -> Result<()> {
        assert!(n <= self.pools.len(), "more passes than recording workers");
        // All workers start recording together, so that two passes really are recorded at the
        // same time when two cores are free: a recording takes less time than waking a thread
        // blocked on a futex, so with a blocking barrier the last worker to arrive would usually
        // be done before the other ran. The workers spin (yielding now and then, for a machine
        // with fewer free cores than workers) until all have started.
        let start = std::sync::atomic::AtomicUsize::new(0);
        let meet = Meet { n, state: std::sync::Mutex::new((0, false)), arrived: std::sync::Condvar::new() };
        let (start, meet, job) = (&start, &meet, &job);
        let spans: Vec<Result<(std::time::Instant, std::time::Instant)>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..n)
                .map(|i| {
                    scope.spawn(move || {
                        // Whatever happens to this job (an error, a panic), the others do not
                        // wait for it at `arrive` for ever.
                        let _release = ReleaseOnDrop(meet);
                        start.fetch_add(1, std::sync::atomic::Ordering::AcqRel);
                        let mut spins = 0u32;
                        while start.load(std::sync::atomic::Ordering::Acquire) < n {
                            spins = spins.wrapping_add(1);
                            if spins.is_multiple_of(1024) {
                                std::thread::yield_now();
                            }
                            std::hint::spin_loop();
                        }
                        let t0 = std::time::Instant::now();
                        let t1 = std::cell::Cell::new(None);
                        job(i, &MeetHandle { meet, at: &t1 })?;
                        Ok((t0, t1.get().unwrap_or_else(std::time::Instant::now)))
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap_or_else(|_| Err(Error("a recording worker panicked".into())))).collect()
        });
        let spans = spans.into_iter().collect::<Result<Vec<_>>>()?;
        self.recorded += 1;
        let overlap = spans.iter().enumerate().any(|(i, a)| spans[i + 1..].iter().any(|b| a.0 < b.1 && b.0 < a.1));
        if overlap {
            self.overlapped += 1;
        }
        Ok(())
    }
}

/// The meeting point of a frame's workers: each arrives once its commands are recorded and waits
/// there, before it ends its command buffer, until every worker has arrived. So in every frame
/// all the secondaries are in the recording state at once (each begun before any is ended),
/// whatever the scheduler does: a layer that kept "the command buffer being recorded" per device
/// or per queue instead of per command buffer would mix them up.
pub struct Meet {
    n: usize,
    /// (workers arrived, a worker failed or ended without arriving)
    state: std::sync::Mutex<(usize, bool)>,
    arrived: std::sync::Condvar,
}

/// A worker's handle on the meeting point, noting when the worker arrived (the end of its
/// recording's span, not counting the wait for the others).
pub struct MeetHandle<'a> {
    meet: &'a Meet,
    at: &'a std::cell::Cell<Option<std::time::Instant>>,
}

impl Meet {
    fn release(&self) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.1 = true;
        self.arrived.notify_all();
    }
}

impl MeetHandle<'_> {
    /// Blocks until every worker of the frame has arrived (or one of them failed).
    pub fn arrive(&self) {
        self.at.set(Some(std::time::Instant::now()));
        let mut s = self.meet.state.lock().unwrap_or_else(|e| e.into_inner());
        s.0 += 1;
        self.meet.arrived.notify_all();
        while s.0 < self.meet.n && !s.1 {
            s = self.meet.arrived.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// Releases the other workers when its worker ends, however it ends. Harmless after a normal
/// arrival: by then every worker has arrived.
struct ReleaseOnDrop<'a>(&'a Meet);

impl Drop for ReleaseOnDrop<'_> {
    fn drop(&mut self) {
        self.0.release();
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        for &pool in &self.pools {
            // SAFETY: the renderer waited for the device before dropping its workers, so none of
            // the pool's command buffers is pending; no worker runs outside `record`.
            unsafe { self.device.destroy_command_pool(pool, None) };
        }
    }
}
