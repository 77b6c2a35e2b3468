//! What features drew into a command buffer's open (sub)passes, judged when the pass ends: a pass
//! with no depth-tested draw after the injection point (a post pass with a depth attachment,
//! recorded before the data-flow walk knew it) saved nothing, so the feature's data there must
//! draw nothing and count as `post_pass`. One mechanism for every feature that injects at a
//! pass's beginning (the mask, RDM's checkerboard); the flow record (`track::flow`) says whether a
//! depth-tested draw came.

use super::lock;
use crate::plugin::vk::DeviceState;
use std::collections::HashMap;
use std::sync::Mutex;

/// Per device and feature: command buffer → (the flow record's index of the (sub)pass, data).
pub(crate) struct OpenPasses<T> {
    open: Mutex<HashMap<u64, Vec<(usize, T)>>>,
}

impl<T> Default for OpenPasses<T> {
    fn default() -> Self {
        OpenPasses { open: Mutex::default() }
    }
}

impl<T> OpenPasses<T> {
    /// `data` went into `owner`'s open (sub)pass. Not kept when the recording feeds no flow
    /// record (nothing can judge it then).
    pub(crate) fn opened(&self, d: &DeviceState, owner: u64, data: T) {
        let index = d.track.with_cb(owner, |s| if s.flow_on { s.flow.open_index() } else { None }).flatten();
        if let Some(index) = index {
            lock(&self.open).entry(owner).or_default().push((index, data));
        }
    }

    /// The pass open in `cb` is ending: the data of its (sub)passes that had no depth-tested draw.
    pub(crate) fn ending(&self, d: &DeviceState, cb: u64) -> Vec<T> {
        let Some(open) = lock(&self.open).remove(&cb) else { return Vec::new() };
        d.track.with_cb(cb, |s| open.into_iter().filter(|(index, _)| s.flow.pass_tested(*index) == Some(false)).map(|(_, data)| data).collect()).unwrap_or_default()
    }

    /// The recordings of `cbs` are over (`VkFeature::recordings_closed`): their open passes never end.
    pub(crate) fn closed(&self, cbs: &[u64]) {
        let mut open = lock(&self.open);
        for cb in cbs {
            open.remove(cb);
        }
    }
}
