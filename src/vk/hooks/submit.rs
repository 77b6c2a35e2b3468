//! Queue submissions: before the app's command buffers go down the features refresh and apply
//! what their recordings hold (`VkFeature::before_submit`); after they went down, submissions
//! that carried held recordings are tracked to completion (`plugin::vk::lifetime`). The submission goes
//! down with the layer's own command buffers added to the app's batches, everything else about
//! them (semaphores, fence, pNext) passed on as it came: the features' one-time set-up work
//! (`VkFeature::queue_submitting`) at the head of the first batch, and with `stats.gpu_time` on
//! the GPU timer's two command buffers first in the first batch and last in the last
//! (`plugin::vk::gpu_time`).

use crate::plugin::vk::gpu_time::{self, Bracket};
use crate::plugin::vk::{convert, lifetime, secondary, DeviceState};
use super::hook_decided;
use ash::vk::{self, Handle};
use std::cell::RefCell;

/// The features' set-up command buffers for one submission, by feature (index in registry order).
#[derive(Default)]
struct SetUps {
    family: u32,
    by_feature: Vec<(usize, Vec<vk::CommandBuffer>)>,
}

impl SetUps {
    fn cbs(&self) -> Vec<vk::CommandBuffer> {
        self.by_feature.iter().flat_map(|(_, cbs)| cbs.iter().copied()).collect()
    }
    /// Tells each feature whether its set-up went down.
    fn finish(self, d: &DeviceState, ok: bool) {
        let all = d.features.all();
        for (i, cbs) in &self.by_feature {
            all[*i].set_up_submitted(d, self.family, cbs, ok);
        }
    }
}

/// Raises `queue_submitting` and `before_submit` over the features; keeps the command buffers
/// for `after`. Returns the features' set-up work for this submission.
fn before(d: &DeviceState, cbs: Vec<u64>, keep: &RefCell<Vec<u64>>) -> SetUps {
    lifetime::poll(d);
    crate::vk::chassis::walk_submitted(d, &cbs);
    let family = cbs.first().and_then(|cb| d.track.command_buffers.get(*cb)).and_then(|c| d.track.pools.get(c.pool)).map(|p| p.queue_family_index);
    let mut set_ups = SetUps::default();
    if let Some(family) = family {
        set_ups.family = family;
        for (i, f) in d.features.all().iter().enumerate() {
            let cbs = f.queue_submitting(d, family);
            if !cbs.is_empty() {
                set_ups.by_feature.push((i, cbs));
            }
        }
    }
    for f in d.features.all() {
        f.before_submit(d, &cbs);
    }
    *keep.borrow_mut() = cbs;
    set_ups
}

/// What the layer adds to one app submission: the timer's bracket (`stats.gpu_time`) and the
/// features' set-up work.
#[derive(Default)]
struct Added {
    bracket: Option<Bracket>,
    set_ups: SetUps,
}

impl Added {
    /// Nothing to add: the app's batches go down untouched.
    fn is_empty(&self) -> bool {
        self.bracket.is_none() && self.set_ups.by_feature.is_empty()
    }
    /// Command buffers at the head of the first batch and at the end of the last.
    fn head_tail(&self) -> (Vec<vk::CommandBuffer>, Option<vk::CommandBuffer>) {
        let mut head: Vec<vk::CommandBuffer> = self.bracket.iter().map(|b| b.begin).collect();
        head.extend(self.set_ups.cbs());
        (head, self.bracket.as_ref().map(|b| b.end))
    }
}

/// Decides what goes down with the app's batches. Where the batches cannot take command buffers
/// of the layer's (a device-group or protected submission), the set-up work goes down on its
/// own first, as the only way it can run before the app's command buffers.
fn add(d: &DeviceState, queue: vk::Queue, batches: u32, open: bool, set_ups: SetUps) -> Added {
    if open {
        return Added { bracket: gpu_time::start(d, queue, batches, true), set_ups };
    }
    // Tells the timer this submission goes untimed.
    let bracket = gpu_time::start(d, queue, batches, false);
    if !set_ups.by_feature.is_empty() {
        let r = secondary::submit_prepared(d, queue, &set_ups.cbs());
        if let Err(e) = &r {
            tracing::warn!("set-up work ahead of a device-group or protected submission: {e}; tried again with the next submission");
        }
        set_ups.finish(d, r.is_ok());
    }
    Added { bracket, set_ups: SetUps::default() }
}

/// The submission went down (`r`): track it when it carried held recordings; hand the timer its
/// bracket back and the features their set-up's fate.
fn after(d: &DeviceState, queue: vk::Queue, keep: &RefCell<Vec<u64>>, added: &RefCell<Added>, r: vk::Result) {
    let Added { bracket, set_ups } = added.take();
    if let Some(b) = bracket {
        gpu_time::submitted(d, b, queue, r == vk::Result::SUCCESS);
    }
    if !set_ups.by_feature.is_empty() {
        set_ups.finish(d, r == vk::Result::SUCCESS);
    }
    if r == vk::Result::SUCCESS {
        lifetime::submitted(d, queue, &keep.take());
    }
}

/// Whether a `pNext` chain has a struct that ties itself to the batch's command buffers
/// (`VkDeviceGroupSubmitInfo`: one device mask per command buffer) or makes it protected: the
/// layer must not add command buffers to such a batch.
///
/// # Safety
/// `p_next` must be a valid chain.
unsafe fn closed_chain(p_next: *const std::ffi::c_void) -> bool {
    // SAFETY: per the contract.
    unsafe {
        convert::find_in_chain::<vk::DeviceGroupSubmitInfo>(p_next, vk::StructureType::DEVICE_GROUP_SUBMIT_INFO).is_some()
            || convert::find_in_chain::<vk::ProtectedSubmitInfo>(p_next, vk::StructureType::PROTECTED_SUBMIT_INFO).is_some_and(|p| (*p).protected_submit != 0)
    }
}

/// What differs between `VkSubmitInfo` and `VkSubmitInfo2` for the submit hooks: how a batch
/// lists its command buffers, and whether the layer may add to it.
trait Batch<'a>: Copy + 'a {
    /// An entry of the batch's command buffer array.
    type Entry: Copy + 'a;
    /// # Safety
    /// `self` is one of the app's valid submit infos.
    unsafe fn entries(&self) -> &'a [Self::Entry];
    fn command_buffer(e: &Self::Entry) -> vk::CommandBuffer;
    fn entry(cb: vk::CommandBuffer) -> Self::Entry;
    /// Points the batch at `list` (which outlives the call down).
    fn set_entries(&mut self, list: &[Self::Entry]);
    /// The batch ties itself to its command buffers (one device mask each) or is protected: the
    /// layer must not add command buffers to it.
    ///
    /// # Safety
    /// As `entries`.
    unsafe fn closed(&self) -> bool;
}

impl<'a> Batch<'a> for vk::SubmitInfo<'a> {
    type Entry = vk::CommandBuffer;
    unsafe fn entries(&self) -> &'a [vk::CommandBuffer] {
        // SAFETY: per the contract.
        unsafe { convert::slice(self.p_command_buffers, self.command_buffer_count) }
    }
    fn command_buffer(e: &vk::CommandBuffer) -> vk::CommandBuffer {
        *e
    }
    fn entry(cb: vk::CommandBuffer) -> vk::CommandBuffer {
        cb
    }
    fn set_entries(&mut self, list: &[vk::CommandBuffer]) {
        self.command_buffer_count = list.len() as u32;
        self.p_command_buffers = list.as_ptr();
    }
    unsafe fn closed(&self) -> bool {
        // SAFETY: the app's valid pNext chain (the contract).
        unsafe { closed_chain(self.p_next) }
    }
}

impl<'a> Batch<'a> for vk::SubmitInfo2<'a> {
    type Entry = vk::CommandBufferSubmitInfo<'a>;
    unsafe fn entries(&self) -> &'a [vk::CommandBufferSubmitInfo<'a>] {
        // SAFETY: per the contract.
        unsafe { convert::slice(self.p_command_buffer_infos, self.command_buffer_info_count) }
    }
    fn command_buffer(e: &vk::CommandBufferSubmitInfo<'a>) -> vk::CommandBuffer {
        e.command_buffer
    }
    /// Device mask 0: the command buffer runs on every device of the group, as the app's would
    /// with its default.
    fn entry(cb: vk::CommandBuffer) -> vk::CommandBufferSubmitInfo<'a> {
        vk::CommandBufferSubmitInfo::default().command_buffer(cb)
    }
    fn set_entries(&mut self, list: &[vk::CommandBufferSubmitInfo<'a>]) {
        self.command_buffer_info_count = list.len() as u32;
        self.p_command_buffer_infos = list.as_ptr();
    }
    unsafe fn closed(&self) -> bool {
        self.flags.contains(vk::SubmitFlags::PROTECTED)
    }
}

/// The app's batches with the layer's command buffers added; the arrays the copies point into
/// live here, as long as the call down.
struct Amended<'a, B: Batch<'a>> {
    infos: Vec<B>,
    _cbs: Vec<Vec<B::Entry>>,
}

/// The app's batches with `head` in front of the first's command buffers and `tail` after the
/// last's.
///
/// # Safety
/// `app` must be the app's (≥ 1) valid submit infos.
unsafe fn amend<'a, B: Batch<'a>>(app: &[B], head: &[vk::CommandBuffer], tail: Option<vk::CommandBuffer>) -> Amended<'a, B> {
    let mut infos = app.to_vec();
    let mut cbs = Vec::new();
    let last = infos.len() - 1;
    for (i, info) in infos.iter_mut().enumerate().filter(|(i, _)| *i == 0 || *i == last) {
        // SAFETY: the app's command buffer array of this batch.
        let own = unsafe { info.entries() };
        let mut list = Vec::with_capacity(own.len() + head.len() + 1);
        if i == 0 {
            list.extend(head.iter().copied().map(B::entry));
        }
        list.extend_from_slice(own);
        if i == last {
            list.extend(tail.map(B::entry));
        }
        // The Vec's heap buffer does not move when the Vec moves into `cbs`.
        info.set_entries(&list);
        cbs.push(list);
    }
    Amended { infos, _cbs: cbs }
}

/// `vkQueueSubmit` and `vkQueueSubmit2` alike: the features refresh what the submitted
/// recordings read, the layer's set-up and timing command buffers go at the head and tail of the
/// app's batches, and `down` makes the call with the batches it is given (the amended copies or
/// the app's own).
///
/// # Safety
/// `submits` must be `count` valid submit infos of the app's, valid during the call.
unsafe fn queue_submit_any<'a, B: Batch<'a>>(call: &'static str, queue: vk::Queue, count: u32, submits: *const B, down: impl Fn(&DeviceState, *const B) -> vk::Result) -> vk::Result {
    let keep = Default::default();
    let added = RefCell::new(Added::default());
    hook_decided(
        call,
        queue,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            // SAFETY: `count` valid submit infos, each with its command buffer array.
            let infos = unsafe { convert::slice(submits, count) };
            // SAFETY: as above.
            let cbs: Vec<u64> = infos.iter().flat_map(|s| unsafe { s.entries() }.iter().map(|e| B::command_buffer(e).as_raw())).collect();
            // Semaphore-only submissions carry no work to time and need no set-up.
            let batches = if cbs.is_empty() { 0 } else { count };
            let set_ups = before(d, cbs, &keep);
            // SAFETY: the app's valid pNext chains.
            let open = !infos.iter().any(|s| unsafe { s.closed() });
            let a = add(d, queue, batches, open, set_ups);
            if a.is_empty() {
                return None;
            }
            let (head, tail) = a.head_tail();
            *added.borrow_mut() = a;
            // SAFETY: `count` ≥ 1 valid submit infos (nothing is added to a submission without
            // command buffers).
            Some(unsafe { amend(infos, &head, tail) })
        },
        |d, amended| match amended.and_then(|t| t.as_ref()) {
            // The app's batches, copied with only the layer's command buffers added (executable,
            // of the batch's queue family); every array they point to lives until the call
            // returns.
            Some(t) => down(d, t.infos.as_ptr()),
            None => down(d, submits),
        },
        |d, r| {
            after(d, queue, &keep, &added, r);
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn queue_submit(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo<'_>, fence: vk::Fence) -> vk::Result {
    // SAFETY: the app's arguments, valid during its call; `down` passes the app's batches or
    // their amended copies, with the app's other arguments unchanged.
    unsafe { queue_submit_any("vkQueueSubmit", queue, count, submits, |d, s| (d.fns.fp_v1_0().queue_submit)(queue, count, s, fence)) }
}

pub(in crate::vk) unsafe extern "system" fn queue_submit2(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo2<'_>, fence: vk::Fence) -> vk::Result {
    // SAFETY: as `queue_submit`.
    unsafe { queue_submit_any("vkQueueSubmit2", queue, count, submits, |d, s| (d.fns.fp_v1_3().queue_submit2)(queue, count, s, fence)) }
}
