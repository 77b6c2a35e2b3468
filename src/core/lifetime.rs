//! When the layer may free (or reuse) an object it referenced from an app's command buffer: the
//! pure rules of the `in_use` tracking, in the manner of the validation layers' state objects.
//!
//! A recording *holds* every layer object recorded into it. When the app begins, resets or frees
//! the command buffer again, that recording is *closed*; its holds are released once every
//! submission of it has completed. A command buffer recorded once and submitted every frame keeps
//! its holds for as long as it lives. Submissions are identified by the shell (one id per queue
//! submission that carried held command buffers) and reported complete when the shell's fence
//! for them signalled.
#![forbid(unsafe_code)]

use std::collections::{BTreeSet, HashMap};

/// A queue submission the shell tracks.
pub type SubmissionId = u64;

#[derive(Debug)]
struct Recording<H> {
    holds: Vec<H>,
    /// Submissions of this recording not known complete.
    pending: BTreeSet<SubmissionId>,
}

impl<H> Default for Recording<H> {
    fn default() -> Self {
        Recording { holds: Vec::new(), pending: BTreeSet::new() }
    }
}

/// The holds of every command buffer of a device.
#[derive(Debug)]
pub struct Lifetimes<H> {
    open: HashMap<u64, Recording<H>>,
    closed: Vec<Recording<H>>,
    next: SubmissionId,
}

impl<H> Default for Lifetimes<H> {
    fn default() -> Self {
        Lifetimes { open: HashMap::new(), closed: Vec::new(), next: 1 }
    }
}

impl<H> Lifetimes<H> {
    /// `cb`'s current recording references `h`.
    pub fn hold(&mut self, cb: u64, h: H) {
        self.open.entry(cb).or_default().holds.push(h);
    }

    /// Whether `cb`'s current recording holds anything (its submissions need tracking).
    pub fn holds_any(&self, cb: u64) -> bool {
        self.open.get(&cb).is_some_and(|r| !r.holds.is_empty())
    }

    /// The holds of `cb`'s current recording (to refresh their contents before a submission).
    pub fn holds_of(&self, cb: u64) -> &[H] {
        self.open.get(&cb).map_or(&[], |r| &r.holds)
    }

    /// Whether a submission of `cb`'s current recording may still be executing.
    pub fn in_flight(&self, cb: u64) -> bool {
        self.open.get(&cb).is_some_and(|r| !r.pending.is_empty())
    }

    /// The command buffers were submitted together; returns the id to report completion with, or
    /// None when none of them holds anything (nothing to track).
    pub fn submitted(&mut self, cbs: &[u64]) -> Option<SubmissionId> {
        if !cbs.iter().any(|cb| self.holds_any(*cb)) {
            return None;
        }
        let id = self.next;
        self.next += 1;
        for cb in cbs {
            if let Some(r) = self.open.get_mut(cb).filter(|r| !r.holds.is_empty()) {
                r.pending.insert(id);
            }
        }
        Some(id)
    }

    /// `cb` is begun, reset or freed: its recording closes. Returns the holds released now (those
    /// of a recording with no submission in flight); the others go when their submissions
    /// complete.
    pub fn close(&mut self, cb: u64) -> Vec<H> {
        let Some(r) = self.open.remove(&cb) else { return Vec::new() };
        if r.pending.is_empty() {
            return r.holds;
        }
        self.closed.push(r);
        Vec::new()
    }

    /// Submission `id` completed; returns the holds released by it.
    pub fn completed(&mut self, id: SubmissionId) -> Vec<H> {
        for r in self.open.values_mut() {
            r.pending.remove(&id);
        }
        let mut released = Vec::new();
        self.closed.retain_mut(|r| {
            r.pending.remove(&id);
            if r.pending.is_empty() {
                released.append(&mut r.holds);
                false
            } else {
                true
            }
        });
        released
    }

    /// Everything, released (the device is idle and being destroyed).
    pub fn drain(&mut self) -> Vec<H> {
        let mut all: Vec<H> = self.open.drain().flat_map(|(_, r)| r.holds).collect();
        all.extend(self.closed.drain(..).flat_map(|r| r.holds));
        all
    }

    /// Recordings closed but still waiting for submissions (statistics, tests).
    pub fn closed_waiting(&self) -> usize {
        self.closed.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recorded_once_and_resubmitted_keeps_its_holds() {
        let mut l = Lifetimes::default();
        l.hold(1, "mask buffer");
        for _ in 0..100 {
            let id = l.submitted(&[1]).expect("tracked");
            assert!(l.in_flight(1));
            assert!(l.completed(id).is_empty(), "still recorded: nothing released");
            assert!(!l.in_flight(1));
        }
        assert_eq!(l.close(1), vec!["mask buffer"], "re-recorded after completion: released at once");
    }

    #[test]
    fn reset_while_a_submission_is_pending_waits_for_it() {
        let mut l = Lifetimes::default();
        l.hold(1, 'a');
        l.hold(2, 'b');
        let s1 = l.submitted(&[1, 2]).unwrap();
        let s2 = l.submitted(&[2]).unwrap();
        // The app may only reset a command buffer that is not pending, but the layer learns of
        // completion later than the app (its fence is polled): the holds wait for it.
        assert!(l.close(1).is_empty());
        assert!(l.close(2).is_empty());
        assert_eq!(l.closed_waiting(), 2);
        assert_eq!(l.completed(s1), vec!['a']);
        assert!(l.completed(999).is_empty(), "unknown ids release nothing");
        assert_eq!(l.completed(s2), vec!['b']);
        assert_eq!(l.closed_waiting(), 0);
    }

    #[test]
    fn submissions_without_holds_are_not_tracked() {
        let mut l: Lifetimes<u8> = Lifetimes::default();
        assert_eq!(l.submitted(&[7, 8]), None);
        l.hold(8, 1);
        let id = l.submitted(&[7, 8]).unwrap();
        assert!(!l.in_flight(7) && l.in_flight(8));
        l.hold(9, 2);
        assert_eq!(l.drain().len(), 2);
        assert!(l.completed(id).is_empty());
    }
}
