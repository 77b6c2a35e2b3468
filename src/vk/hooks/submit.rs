//! Queue submissions: before the app's command buffers go down the features refresh and apply
//! what their recordings hold (`VkFeature::before_submit`); after they went down, submissions
//! that carried held recordings are tracked to completion (`vk::lifetime`). With
//! `stats.gpu_time` on, the submission goes down with the GPU timer's two command buffers added
//! first to its first batch and last to its last batch (`vk::gpu_time`); everything else about
//! the app's batches (semaphores, fence, pNext) is passed on as it came.

use super::super::gpu_time::{self, Bracket};
use super::super::{convert, lifetime, DeviceState};
use super::hook_decided;
use ash::vk::{self, Handle};
use std::cell::RefCell;

/// Raises `queue_submitting` and `before_submit` over the features; keeps the command buffers
/// for `after`.
fn before(d: &DeviceState, queue: vk::Queue, cbs: Vec<u64>, keep: &RefCell<Vec<u64>>) {
    lifetime::poll(d);
    let family = cbs.first().and_then(|cb| d.track.command_buffers.get(*cb)).and_then(|c| d.track.pools.get(c.pool)).map(|p| p.queue_family_index);
    for f in d.features.all() {
        f.queue_submitting(d, queue, family);
    }
    for f in d.features.all() {
        f.before_submit(d, &cbs);
    }
    *keep.borrow_mut() = cbs;
}

/// The submission went down (`r`): track it when it carried held recordings; hand the timer its
/// bracket back.
fn after(d: &DeviceState, queue: vk::Queue, keep: &RefCell<Vec<u64>>, bracket: &RefCell<Option<Bracket>>, r: vk::Result) {
    if let Some(b) = bracket.take() {
        gpu_time::submitted(d, b, queue, r == vk::Result::SUCCESS);
    }
    if r == vk::Result::SUCCESS {
        lifetime::submitted(d, queue, &keep.take());
    }
}

/// Whether a `pNext` chain has a struct that ties itself to the batch's command buffers
/// (`VkDeviceGroupSubmitInfo`: one device mask per command buffer) or makes it protected: the
/// timer must not add command buffers to such a batch.
///
/// # Safety
/// `p_next` must be a valid chain.
unsafe fn untimeable_chain(p_next: *const std::ffi::c_void) -> bool {
    // SAFETY: per the contract.
    unsafe {
        convert::find_in_chain::<vk::DeviceGroupSubmitInfo>(p_next, vk::StructureType::DEVICE_GROUP_SUBMIT_INFO).is_some()
            || convert::find_in_chain::<vk::ProtectedSubmitInfo>(p_next, vk::StructureType::PROTECTED_SUBMIT_INFO).is_some_and(|p| (*p).protected_submit != 0)
    }
}

/// The app's `vkQueueSubmit` batches with the timer's command buffers added; the arrays the copies
/// point into live here, as long as the call down.
struct Timed1<'a> {
    infos: Vec<vk::SubmitInfo<'a>>,
    _cbs: Vec<Vec<vk::CommandBuffer>>,
}

/// # Safety
/// `submits` must be `count` (≥ 1) valid submit infos.
unsafe fn bracket_submit<'a>(submits: *const vk::SubmitInfo<'a>, count: u32, b: &Bracket) -> Timed1<'a> {
    // SAFETY: per the contract.
    let app = unsafe { convert::slice(submits, count) };
    let mut infos = app.to_vec();
    let mut cbs = Vec::new();
    let last = infos.len() - 1;
    for (i, info) in infos.iter_mut().enumerate().filter(|(i, _)| *i == 0 || *i == last) {
        let mut list = Vec::with_capacity(info.command_buffer_count as usize + 2);
        if i == 0 {
            list.push(b.begin);
        }
        // SAFETY: the app's command buffer array of this batch.
        list.extend_from_slice(unsafe { convert::slice(info.p_command_buffers, info.command_buffer_count) });
        if i == last {
            list.push(b.end);
        }
        info.command_buffer_count = list.len() as u32;
        // The Vec's heap buffer does not move when the Vec moves into `cbs`.
        info.p_command_buffers = list.as_ptr();
        cbs.push(list);
    }
    Timed1 { infos, _cbs: cbs }
}

pub(in crate::vk) unsafe extern "system" fn queue_submit(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    let bracket = RefCell::new(None);
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
            // Semaphore-only submissions carry no work to time.
            let batches = if cbs.is_empty() { 0 } else { count };
            before(d, queue, cbs, &keep);
            // SAFETY: the app's valid pNext chains.
            let timeable = !infos.iter().any(|s| unsafe { untimeable_chain(s.p_next) });
            let b = gpu_time::start(d, queue, batches, timeable)?;
            // SAFETY: `count` ≥ 1 valid submit infos (`start` times no submission without work).
            let timed = unsafe { bracket_submit(submits, count, &b) };
            *bracket.borrow_mut() = Some(b);
            Some(timed)
        },
        |d, timed| match timed.and_then(|t| t.as_ref()) {
            // SAFETY: the app's batches, copied with only the timer's command buffers added; every
            // array they point to lives until the call returns.
            Some(t) => unsafe { (d.fns.fp_v1_0().queue_submit)(queue, count, t.infos.as_ptr(), fence) },
            // SAFETY: forwarding the app's arguments unchanged.
            None => unsafe { (d.fns.fp_v1_0().queue_submit)(queue, count, submits, fence) },
        },
        |d, r| {
            after(d, queue, &keep, &bracket, r);
            Ok(())
        },
    )
}

/// The app's `vkQueueSubmit2` batches with the timer's command buffers added.
struct Timed2<'a> {
    infos: Vec<vk::SubmitInfo2<'a>>,
    _cbs: Vec<Vec<vk::CommandBufferSubmitInfo<'a>>>,
}

/// # Safety
/// `submits` must be `count` (≥ 1) valid submit infos.
unsafe fn bracket_submit2<'a>(submits: *const vk::SubmitInfo2<'a>, count: u32, b: &Bracket) -> Timed2<'a> {
    // SAFETY: per the contract.
    let app = unsafe { convert::slice(submits, count) };
    let mut infos = app.to_vec();
    let mut cbs = Vec::new();
    let last = infos.len() - 1;
    // Device mask 0: the command buffer runs on every device of the group, as the app's would
    // with its default.
    let ours = |cb| vk::CommandBufferSubmitInfo::default().command_buffer(cb);
    for (i, info) in infos.iter_mut().enumerate().filter(|(i, _)| *i == 0 || *i == last) {
        let mut list = Vec::with_capacity(info.command_buffer_info_count as usize + 2);
        if i == 0 {
            list.push(ours(b.begin));
        }
        // SAFETY: the app's command buffer info array of this batch.
        list.extend_from_slice(unsafe { convert::slice(info.p_command_buffer_infos, info.command_buffer_info_count) });
        if i == last {
            list.push(ours(b.end));
        }
        info.command_buffer_info_count = list.len() as u32;
        info.p_command_buffer_infos = list.as_ptr();
        cbs.push(list);
    }
    Timed2 { infos, _cbs: cbs }
}

pub(in crate::vk) unsafe extern "system" fn queue_submit2(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo2<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    let bracket = RefCell::new(None);
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
            // Semaphore-only submissions carry no work to time.
            let batches = if cbs.is_empty() { 0 } else { count };
            before(d, queue, cbs, &keep);
            let timeable = !infos.iter().any(|s| s.flags.contains(vk::SubmitFlags::PROTECTED));
            let b = gpu_time::start(d, queue, batches, timeable)?;
            // SAFETY: `count` ≥ 1 valid submit infos (`start` times no submission without work).
            let timed = unsafe { bracket_submit2(submits, count, &b) };
            *bracket.borrow_mut() = Some(b);
            Some(timed)
        },
        |d, timed| match timed.and_then(|t| t.as_ref()) {
            // SAFETY: the app's batches, copied with only the timer's command buffers added; every
            // array they point to lives until the call returns.
            Some(t) => unsafe { (d.fns.fp_v1_3().queue_submit2)(queue, count, t.infos.as_ptr(), fence) },
            // SAFETY: forwarding the app's arguments unchanged.
            None => unsafe { (d.fns.fp_v1_3().queue_submit2)(queue, count, submits, fence) },
        },
        |d, r| {
            after(d, queue, &keep, &bracket, r);
            Ok(())
        },
    )
}
