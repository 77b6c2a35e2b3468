//! Queue submissions: before the app's command buffers go down the features refresh and apply
//! what their recordings hold (`VkFeature::before_submit`); after they went down, submissions
//! that carried held recordings are tracked to completion (`vk::lifetime`). The submission goes
//! down with the layer's own command buffers added to the app's batches, everything else about
//! them (semaphores, fence, pNext) passed on as it came: the features' one-time set-up work
//! (`VkFeature::queue_submitting`) at the head of the first batch, and with `stats.gpu_time` on
//! the GPU timer's two command buffers first in the first batch and last in the last
//! (`vk::gpu_time`).

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

/// The app's `vkQueueSubmit` batches with the layer's command buffers added; the arrays the
/// copies point into live here, as long as the call down.
struct Amended1<'a> {
    infos: Vec<vk::SubmitInfo<'a>>,
    _cbs: Vec<Vec<vk::CommandBuffer>>,
}

/// # Safety
/// `submits` must be `count` (≥ 1) valid submit infos.
unsafe fn amend_submit<'a>(submits: *const vk::SubmitInfo<'a>, count: u32, head: &[vk::CommandBuffer], tail: Option<vk::CommandBuffer>) -> Amended1<'a> {
    // SAFETY: per the contract.
    let app = unsafe { convert::slice(submits, count) };
    let mut infos = app.to_vec();
    let mut cbs = Vec::new();
    let last = infos.len() - 1;
    for (i, info) in infos.iter_mut().enumerate().filter(|(i, _)| *i == 0 || *i == last) {
        let mut list = Vec::with_capacity(info.command_buffer_count as usize + head.len() + 1);
        if i == 0 {
            list.extend_from_slice(head);
        }
        // SAFETY: the app's command buffer array of this batch.
        list.extend_from_slice(unsafe { convert::slice(info.p_command_buffers, info.command_buffer_count) });
        if i == last {
            list.extend(tail);
        }
        info.command_buffer_count = list.len() as u32;
        // The Vec's heap buffer does not move when the Vec moves into `cbs`.
        info.p_command_buffers = list.as_ptr();
        cbs.push(list);
    }
    Amended1 { infos, _cbs: cbs }
}

pub(in crate::vk) unsafe extern "system" fn queue_submit(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    let added = RefCell::new(Added::default());
    hook_decided(
        "vkQueueSubmit",
        queue,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            // SAFETY: `count` valid submit infos, each with its command buffer array.
            let infos = unsafe { convert::slice(submits, count) };
            let cbs: Vec<u64> = infos
                .iter()
                // SAFETY: as above.
                .flat_map(|s| unsafe { convert::slice(s.p_command_buffers, s.command_buffer_count) }.iter().map(|c| c.as_raw()))
                .collect();
            // Semaphore-only submissions carry no work to time and need no set-up.
            let batches = if cbs.is_empty() { 0 } else { count };
            let set_ups = before(d, cbs, &keep);
            // SAFETY: the app's valid pNext chains.
            let open = !infos.iter().any(|s| unsafe { closed_chain(s.p_next) });
            let a = add(d, queue, batches, open, set_ups);
            if a.is_empty() {
                return None;
            }
            let (head, tail) = a.head_tail();
            *added.borrow_mut() = a;
            // SAFETY: `count` ≥ 1 valid submit infos (nothing is added to a submission without
            // command buffers).
            Some(unsafe { amend_submit(submits, count, &head, tail) })
        },
        |d, amended| match amended.and_then(|t| t.as_ref()) {
            // SAFETY: the app's batches, copied with only the layer's command buffers added
            // (executable, of the batch's queue family); every array they point to lives until
            // the call returns.
            Some(t) => unsafe { (d.fns.fp_v1_0().queue_submit)(queue, count, t.infos.as_ptr(), fence) },
            // SAFETY: forwarding the app's arguments unchanged.
            None => unsafe { (d.fns.fp_v1_0().queue_submit)(queue, count, submits, fence) },
        },
        |d, r| {
            after(d, queue, &keep, &added, r);
            Ok(())
        },
    )
}

/// The app's `vkQueueSubmit2` batches with the layer's command buffers added.
struct Amended2<'a> {
    infos: Vec<vk::SubmitInfo2<'a>>,
    _cbs: Vec<Vec<vk::CommandBufferSubmitInfo<'a>>>,
}

/// # Safety
/// `submits` must be `count` (≥ 1) valid submit infos.
unsafe fn amend_submit2<'a>(submits: *const vk::SubmitInfo2<'a>, count: u32, head: &[vk::CommandBuffer], tail: Option<vk::CommandBuffer>) -> Amended2<'a> {
    // SAFETY: per the contract.
    let app = unsafe { convert::slice(submits, count) };
    let mut infos = app.to_vec();
    let mut cbs = Vec::new();
    let last = infos.len() - 1;
    // Device mask 0: the command buffer runs on every device of the group, as the app's would
    // with its default.
    let ours = |cb| vk::CommandBufferSubmitInfo::default().command_buffer(cb);
    for (i, info) in infos.iter_mut().enumerate().filter(|(i, _)| *i == 0 || *i == last) {
        let mut list = Vec::with_capacity(info.command_buffer_info_count as usize + head.len() + 1);
        if i == 0 {
            list.extend(head.iter().copied().map(ours));
        }
        // SAFETY: the app's command buffer info array of this batch.
        list.extend_from_slice(unsafe { convert::slice(info.p_command_buffer_infos, info.command_buffer_info_count) });
        if i == last {
            list.extend(tail.map(ours));
        }
        info.command_buffer_info_count = list.len() as u32;
        info.p_command_buffer_infos = list.as_ptr();
        cbs.push(list);
    }
    Amended2 { infos, _cbs: cbs }
}

pub(in crate::vk) unsafe extern "system" fn queue_submit2(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo2<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    let added = RefCell::new(Added::default());
    hook_decided(
        "vkQueueSubmit2",
        queue,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            // SAFETY: `count` valid submit infos, each with its command buffer info array.
            let infos = unsafe { convert::slice(submits, count) };
            let cbs: Vec<u64> = infos
                .iter()
                // SAFETY: as above.
                .flat_map(|s| unsafe { convert::slice(s.p_command_buffer_infos, s.command_buffer_info_count) }.iter().map(|c| c.command_buffer.as_raw()))
                .collect();
            // Semaphore-only submissions carry no work to time and need no set-up.
            let batches = if cbs.is_empty() { 0 } else { count };
            let set_ups = before(d, cbs, &keep);
            let open = !infos.iter().any(|s| s.flags.contains(vk::SubmitFlags::PROTECTED));
            let a = add(d, queue, batches, open, set_ups);
            if a.is_empty() {
                return None;
            }
            let (head, tail) = a.head_tail();
            *added.borrow_mut() = a;
            // SAFETY: `count` ≥ 1 valid submit infos (nothing is added to a submission without
            // command buffers).
            Some(unsafe { amend_submit2(submits, count, &head, tail) })
        },
        |d, amended| match amended.and_then(|t| t.as_ref()) {
            // SAFETY: the app's batches, copied with only the layer's command buffers added;
            // every array they point to lives until the call returns.
            Some(t) => unsafe { (d.fns.fp_v1_3().queue_submit2)(queue, count, t.infos.as_ptr(), fence) },
            // SAFETY: forwarding the app's arguments unchanged.
            None => unsafe { (d.fns.fp_v1_3().queue_submit2)(queue, count, submits, fence) },
        },
        |d, r| {
            after(d, queue, &keep, &added, r);
            Ok(())
        },
    )
}
