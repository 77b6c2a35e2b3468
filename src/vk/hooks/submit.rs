//! Queue submissions: before the app's command buffers go down the features refresh and apply
//! what their recordings hold (`VkFeature::before_submit`); after they went down, submissions
//! that carried held recordings are tracked to completion (`vk::lifetime`).

use super::super::{convert, lifetime, DeviceState};
use super::hook_decided;
use ash::vk::{self, Handle};

/// Raises `queue_submitting` and `before_submit` over the features; keeps the command buffers
/// for `after`.
fn before(d: &DeviceState, queue: vk::Queue, cbs: Vec<u64>, keep: &std::cell::RefCell<Vec<u64>>) {
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

/// The submission went down successfully: track it when it carried held recordings.
fn after(d: &DeviceState, queue: vk::Queue, keep: &std::cell::RefCell<Vec<u64>>) {
    lifetime::submitted(d, queue, &keep.take());
}

pub(in crate::vk) unsafe extern "system" fn queue_submit(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    hook_decided(
        "vkQueueSubmit",
        queue,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            // SAFETY: `count` valid submit infos, each with its command buffer array.
            let cbs = unsafe { convert::slice(submits, count) }
                .iter()
                // SAFETY: as above.
                .flat_map(|s| unsafe { convert::slice(s.p_command_buffers, s.command_buffer_count) }.iter().map(|c| c.as_raw()))
                .collect();
            before(d, queue, cbs, &keep)
        },
        // SAFETY: forwarding the app's arguments unchanged.
        |d, _| unsafe { (d.fns.fp_v1_0().queue_submit)(queue, count, submits, fence) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                after(d, queue, &keep);
            }
            Ok(())
        },
    )
}

pub(in crate::vk) unsafe extern "system" fn queue_submit2(queue: vk::Queue, count: u32, submits: *const vk::SubmitInfo2<'_>, fence: vk::Fence) -> vk::Result {
    let keep = Default::default();
    hook_decided(
        "vkQueueSubmit2",
        queue,
        vk::Result::ERROR_INITIALIZATION_FAILED,
        |d| {
            // SAFETY: `count` valid submit infos, each with its command buffer info array.
            let cbs = unsafe { convert::slice(submits, count) }
                .iter()
                // SAFETY: as above.
                .flat_map(|s| unsafe { convert::slice(s.p_command_buffer_infos, s.command_buffer_info_count) }.iter().map(|c| c.command_buffer.as_raw()))
                .collect();
            before(d, queue, cbs, &keep)
        },
        // SAFETY: forwarding the app's arguments unchanged.
        |d, _| unsafe { (d.fns.fp_v1_3().queue_submit2)(queue, count, submits, fence) },
        |d, r| {
            if r == vk::Result::SUCCESS {
                after(d, queue, &keep);
            }
            Ok(())
        },
    )
}
