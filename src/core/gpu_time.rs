//! Layer-side GPU time per frame (`stats.gpu_time`): the pure bookkeeping behind the timer in
//! `plugin::vk::gpu_time`. Every timed queue submission gets a *ticket* and a *slot* (two timestamp
//! queries) of its queue's ring; the ticket belongs to the frame being recorded when it was
//! submitted (frames end at `xrEndFrame`); when its two timestamps are read back (later, without
//! stalling) they join that frame, and once the frame is closed and every ticket of it is back,
//! the frame's time is complete: the union of its submissions' [start, end] intervals (busy: work
//! on several queues, or submissions that overlap, is counted once) and first start → last end
//! (span).
#![forbid(unsafe_code)]

use std::collections::{BTreeMap, HashMap, VecDeque};

/// One timed submission.
pub type Ticket = u64;

/// A frame's GPU time as measured by the layer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuFrameTime {
    /// Union of the submissions' intervals, milliseconds.
    pub busy_ms: f64,
    /// First start to last end, milliseconds.
    pub span_ms: f64,
    /// Submissions timed.
    pub submissions: u32,
    /// Submissions of the frame that could not be timed (ring full, a queue family without
    /// timestamps, a protected or device-group submission): the times then miss their work.
    pub untimed: u32,
}

impl GpuFrameTime {
    /// The same frame measured on another device: busy times add up (different GPUs), the span
    /// is the longer one.
    pub fn add(&mut self, o: &GpuFrameTime) {
        self.busy_ms += o.busy_ms;
        self.span_ms = self.span_ms.max(o.span_ms);
        self.submissions += o.submissions;
        self.untimed += o.untimed;
    }
}

/// The bits of a timestamp that count (`timestampValidBits`, 1..=64).
pub fn valid_mask(bits: u32) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

/// Signed distance `b - a` on a counter of `bits` bits that wraps (the shorter way round).
fn signed_delta(a: u64, b: u64, bits: u32) -> i128 {
    let mask = valid_mask(bits);
    let d = b.wrapping_sub(a) & mask;
    let half = if bits >= 64 { 1u128 << 63 } else { 1u128 << (bits - 1) };
    if d as u128 >= half {
        d as i128 - (mask as i128 + 1)
    } else {
        d as i128
    }
}

/// Busy (union of the intervals) and span (first start → last end) of raw timestamp pairs, in
/// ticks. Each submission's own length is taken modulo the counter (it may wrap inside one);
/// submissions are placed relative to the first one by the shorter way round the counter.
pub fn busy_and_span(stamps: &[(u64, u64)], bits: u32) -> (u128, u128) {
    let Some(&(base, _)) = stamps.first() else { return (0, 0) };
    let mask = valid_mask(bits);
    let mut iv: Vec<(i128, i128)> = stamps
        .iter()
        .map(|&(s, e)| {
            let start = signed_delta(base & mask, s & mask, bits);
            (start, start + ((e.wrapping_sub(s)) & mask) as i128)
        })
        .collect();
    iv.sort_unstable();
    let (mut busy, mut cur) = (0u128, iv[0]);
    for &(s, e) in &iv[1..] {
        if s <= cur.1 {
            cur.1 = cur.1.max(e);
        } else {
            busy += (cur.1 - cur.0) as u128;
            cur = (s, e);
        }
    }
    busy += (cur.1 - cur.0) as u128;
    let span = iv.iter().map(|i| i.1).max().unwrap_or(0) - iv[0].0;
    (busy, span as u128)
}

/// The query slots of one queue: a fixed ring (slot `s` owns queries `2s` and `2s + 1`). A slot
/// is in flight from its submission until its results were read (its fence signalled), so the
/// GPU never writes a slot the host still has to read, and the host never reads a slot before
/// the reset recorded with its new use has executed. One reader at a time (`claim`), so the shell
/// reads and resets a slot's fence without holding a lock while it calls the driver.
#[derive(Debug)]
pub struct Ring {
    free: Vec<u32>,
    in_flight: VecDeque<(u32, Ticket)>,
    reading: bool,
}

impl Ring {
    pub fn new(slots: u32) -> Ring {
        Ring { free: (0..slots).rev().collect(), in_flight: VecDeque::new(), reading: false }
    }

    /// A free slot for `ticket` (None: all in flight, the submission goes untimed).
    pub fn start(&mut self, ticket: Ticket) -> Option<u32> {
        let slot = self.free.pop()?;
        self.in_flight.push_back((slot, ticket));
        Some(slot)
    }

    /// The oldest slot in flight, for the one reader (None: nothing in flight, or another reader
    /// is at it). The reader hands it back with `read`.
    pub fn claim(&mut self) -> Option<(u32, Ticket)> {
        if self.reading {
            return None;
        }
        let oldest = *self.in_flight.front()?;
        self.reading = true;
        Some(oldest)
    }

    /// The reader is done with the claimed slot: `done` when its results were read (the slot is
    /// free again), else it stays in flight.
    pub fn read(&mut self, slot: u32, ticket: Ticket, done: bool) {
        self.reading = false;
        if done {
            self.finish(slot, ticket);
        }
    }

    /// `slot` of `ticket` is done with (its submission failed); false when it is not in flight
    /// for that ticket.
    pub fn finish(&mut self, slot: u32, ticket: Ticket) -> bool {
        let Some(i) = self.in_flight.iter().position(|&x| x == (slot, ticket)) else { return false };
        self.in_flight.remove(i);
        self.free.push(slot);
        true
    }

    pub fn free_slots(&self) -> usize {
        self.free.len()
    }
}

#[derive(Debug, Default)]
struct Acc {
    /// Set when the frame was closed by `xrEndFrame`.
    frame: Option<u64>,
    outstanding: u32,
    stamps: Vec<(u64, u64)>,
    untimed: u32,
}

/// Which frame each ticket belongs to; complete frames come out in order.
#[derive(Debug)]
pub struct Frames {
    next_ticket: Ticket,
    /// Ticket → epoch (the accumulator of the frame it was submitted in).
    tickets: HashMap<Ticket, u64>,
    /// Epoch → its accumulator; the last one is open (being recorded).
    accs: BTreeMap<u64, Acc>,
    open: u64,
}

impl Default for Frames {
    fn default() -> Self {
        let mut accs = BTreeMap::new();
        accs.insert(0, Acc::default());
        Frames { next_ticket: 1, tickets: HashMap::new(), accs, open: 0 }
    }
}

impl Frames {
    fn open_acc(&mut self) -> &mut Acc {
        self.accs.entry(self.open).or_default()
    }

    /// A submission of the frame being recorded is timed: its ticket.
    pub fn begin(&mut self) -> Ticket {
        let t = self.next_ticket;
        self.next_ticket += 1;
        self.tickets.insert(t, self.open);
        self.open_acc().outstanding += 1;
        t
    }

    /// A submission of the frame being recorded could not be timed.
    pub fn untimed(&mut self) {
        self.open_acc().untimed += 1;
    }

    /// The ticket's two timestamps (raw); unknown tickets are ignored.
    pub fn finish(&mut self, t: Ticket, start: u64, end: u64) {
        if let Some(acc) = self.tickets.remove(&t).and_then(|e| self.accs.get_mut(&e)) {
            acc.outstanding -= 1;
            acc.stamps.push((start, end));
        }
    }

    /// The ticket's submission did not go down (the app's call failed): it never happened.
    pub fn cancel(&mut self, t: Ticket) {
        if let Some(acc) = self.tickets.remove(&t).and_then(|e| self.accs.get_mut(&e)) {
            acc.outstanding -= 1;
        }
    }

    /// The ticket's timestamps are lost (a failed read): its frame counts it untimed.
    pub fn lost(&mut self, t: Ticket) {
        if let Some(acc) = self.tickets.remove(&t).and_then(|e| self.accs.get_mut(&e)) {
            acc.outstanding -= 1;
            acc.untimed += 1;
        }
    }

    /// `xrEndFrame` closed frame `frame`: what was submitted since the last close is its work.
    pub fn close_frame(&mut self, frame: u64) {
        self.open_acc().frame = Some(frame);
        self.open += 1;
        self.accs.insert(self.open, Acc::default());
    }

    /// Closed frames whose every ticket is back, in frame order (ticks converted with
    /// `period_ns`, the device's `timestampPeriod`).
    pub fn take_complete(&mut self, bits: u32, period_ns: f64) -> Vec<(u64, GpuFrameTime)> {
        // In order: a frame waits for the frames before it (results of one queue come back in
        // order anyway).
        let done: Vec<u64> = self.accs.iter().take_while(|(_, a)| a.frame.is_some() && a.outstanding == 0).map(|(e, _)| *e).collect();
        done.into_iter()
            .filter_map(|e| {
                let a = self.accs.remove(&e)?;
                let (busy, span) = busy_and_span(&a.stamps, bits);
                let ms = |t: u128| t as f64 * period_ns / 1.0e6;
                Some((a.frame?, GpuFrameTime { busy_ms: ms(busy), span_ms: ms(span), submissions: a.stamps.len() as u32, untimed: a.untimed }))
            })
            .collect()
    }

    /// Tickets not back yet (tests, statistics).
    pub fn outstanding(&self) -> usize {
        self.tickets.len()
    }
}

/// Frame records waiting for their GPU time before they are written, so that each `stats.file`
/// line carries its own frame's time. A record waits at most `max_wait` frames (then it is
/// written without a time) and everything goes at the end of the session.
#[derive(Debug)]
pub struct Waiting<R> {
    /// (frame, whether it waits for a time, the record, its time once known).
    queue: VecDeque<(u64, bool, R, Option<GpuFrameTime>)>,
    max_wait: u64,
}

impl<R> Waiting<R> {
    pub fn new(max_wait: u64) -> Waiting<R> {
        Waiting { queue: VecDeque::new(), max_wait }
    }

    /// Frame `frame`'s record; `wants_time`: the timer ran during it.
    pub fn push(&mut self, frame: u64, wants_time: bool, record: R) {
        self.queue.push_back((frame, wants_time, record, None));
    }

    /// Times of frames (of any record still waiting; others are dropped).
    pub fn times(&mut self, times: &[(u64, GpuFrameTime)]) {
        for (frame, t) in times {
            if let Some(w) = self.queue.iter_mut().find(|w| w.0 == *frame) {
                match &mut w.3 {
                    Some(have) => have.add(t),
                    None => w.3 = Some(*t),
                }
            }
        }
    }

    /// Records ready to be written, in order: those with their time, those not waiting for one,
    /// those waited for too long behind the newest frame, or all (`all`: the session ends).
    pub fn ready(&mut self, all: bool) -> Vec<(R, Option<GpuFrameTime>)> {
        let newest = self.queue.back().map_or(0, |w| w.0);
        let mut out = Vec::new();
        while let Some(w) = self.queue.front() {
            let go = all || !w.1 || w.3.is_some() || newest.saturating_sub(w.0) >= self.max_wait;
            if !go {
                break;
            }
            let (_, _, r, t) = self.queue.pop_front().expect("front exists");
            out.push((r, t));
        }
        out
    }

    pub fn len(&self) -> usize {
        self.queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn union_counts_overlap_once() {
        assert_eq!(busy_and_span(&[], 64), (0, 0));
        assert_eq!(busy_and_span(&[(100, 200)], 64), (100, 100));
        // Overlapping, nested and disjoint intervals, in any order.
        assert_eq!(busy_and_span(&[(150, 250), (100, 200), (300, 310), (120, 130)], 64), (160, 210));
        // Touching intervals merge.
        assert_eq!(busy_and_span(&[(0, 10), (10, 20)], 64), (20, 20));
    }

    #[test]
    fn counters_that_wrap() {
        // 8 valid bits: 250 → 4 is 10 ticks; the second submission starts after the wrap.
        assert_eq!(busy_and_span(&[(250, 4), (2, 8)], 8), (14, 14));
        // A submission that started before the first one seen (another queue), across the wrap.
        assert_eq!(busy_and_span(&[(3, 9), (254, 1)], 8), (9, 11));
        // Garbage above the valid bits is ignored.
        assert_eq!(busy_and_span(&[(0xff00 | 10, 0xab00 | 20)], 8), (10, 10));
        assert_eq!(valid_mask(64), u64::MAX);
        assert_eq!(busy_and_span(&[(u64::MAX - 5, 4)], 64), (10, 10));
    }

    #[test]
    fn ring_slots_are_reused_only_when_finished() {
        let mut r = Ring::new(2);
        assert_eq!(r.start(10), Some(0));
        assert_eq!(r.start(11), Some(1));
        assert_eq!(r.start(12), None, "full: untimed, never a slot still in flight");
        assert!(!r.finish(0, 11), "wrong ticket");
        assert_eq!(r.claim(), Some((0, 10)));
        assert_eq!(r.claim(), None, "one reader at a time");
        r.read(0, 10, false);
        assert_eq!(r.claim(), Some((0, 10)), "not done: still the oldest");
        r.read(0, 10, true);
        assert!(!r.finish(0, 10), "finished once");
        assert_eq!(r.claim(), Some((1, 11)));
        r.read(1, 11, false);
        assert_eq!(r.start(13), Some(0));
        assert_eq!(r.free_slots(), 0);
    }

    #[test]
    fn frames_complete_in_order_once_every_ticket_is_back() {
        let mut f = Frames::default();
        let a = f.begin();
        let b = f.begin();
        f.untimed();
        f.close_frame(0);
        let c = f.begin();
        f.close_frame(1);
        f.close_frame(2); // no submission at all
        let d = f.begin(); // frame 3, still open
        f.finish(c, 1000, 1500);
        f.finish(a, 0, 100);
        assert!(f.take_complete(64, 1.0).is_empty(), "frame 0 waits for b, 1 and 2 for 0");
        f.finish(b, 50, 300);
        f.finish(b, 0, 1_000_000); // twice: ignored
        let done = f.take_complete(64, 1_000.0);
        assert_eq!(done.iter().map(|x| x.0).collect::<Vec<_>>(), vec![0, 1, 2]);
        let t = done[0].1;
        assert_eq!((t.submissions, t.untimed), (2, 1));
        assert!((t.busy_ms - 0.3).abs() < 1e-12 && (t.span_ms - 0.3).abs() < 1e-12, "{t:?}");
        assert_eq!(f.outstanding(), 1);
        f.cancel(d);
        f.close_frame(3);
        assert_eq!(f.take_complete(64, 1.0), vec![(3, GpuFrameTime::default())]);
    }

    #[test]
    fn lost_tickets_count_untimed() {
        let mut f = Frames::default();
        let a = f.begin();
        f.close_frame(7);
        f.lost(a);
        assert_eq!(f.take_complete(64, 1.0), vec![(7, GpuFrameTime { untimed: 1, ..Default::default() })]);
    }

    #[test]
    fn waiting_records_keep_frame_order() {
        let mut w = Waiting::new(3);
        w.push(0, true, "a");
        w.push(1, true, "b");
        w.push(2, false, "c");
        assert!(w.ready(false).is_empty());
        let t = GpuFrameTime { busy_ms: 1.0, span_ms: 2.0, submissions: 1, untimed: 0 };
        w.times(&[(1, t)]);
        assert!(w.ready(false).is_empty(), "frame 0 first");
        w.push(3, true, "d");
        let out = w.ready(false);
        assert_eq!(out.iter().map(|x| x.0).collect::<Vec<_>>(), vec!["a", "b", "c"], "0 waited 3 frames; 1 has its time; 2 waits for none");
        assert_eq!((out[0].1, out[1].1), (None, Some(t)));
        assert_eq!(w.len(), 1);
        assert_eq!(w.ready(true).len(), 1);
        assert!(w.is_empty());
    }

    proptest! {
        /// The union is at most the sum and at most the span, at least the longest submission,
        /// and equals a brute-force count of covered ticks.
        #[test]
        fn union_matches_brute_force(iv in proptest::collection::vec((0u64..200, 0u64..50), 1..8)) {
            let stamps: Vec<(u64, u64)> = iv.iter().map(|&(s, l)| (s, s + l)).collect();
            let (busy, span) = busy_and_span(&stamps, 64);
            let mut covered = [false; 260];
            for &(s, e) in &stamps {
                for c in covered.iter_mut().take(e as usize).skip(s as usize) {
                    *c = true;
                }
            }
            prop_assert_eq!(busy, covered.iter().filter(|c| **c).count() as u128);
            let sum: u64 = iv.iter().map(|x| x.1).sum();
            prop_assert!(busy <= sum as u128 && busy <= span);
            prop_assert!(busy >= iv.iter().map(|x| x.1).max().unwrap() as u128);
            let first = stamps.iter().map(|x| x.0).min().unwrap();
            let last = stamps.iter().map(|x| x.1).max().unwrap();
            prop_assert_eq!(span, (last - first) as u128);
        }

        /// Shifting every timestamp by the same amount, across the wrap of a narrow counter,
        /// changes nothing.
        #[test]
        fn wrap_invariant(iv in proptest::collection::vec((0u64..1000, 0u64..100), 1..6), shift in 0u64..(1 << 20), bits in 20u32..=64) {
            let stamps: Vec<(u64, u64)> = iv.iter().map(|&(s, l)| (s, s + l)).collect();
            let mask = valid_mask(bits);
            let shifted: Vec<(u64, u64)> = stamps.iter().map(|&(s, e)| (s.wrapping_add(shift) & mask, e.wrapping_add(shift) & mask)).collect();
            prop_assert_eq!(busy_and_span(&stamps, 64), busy_and_span(&shifted, bits));
        }

        /// Whatever the order of submissions, frame ends and results, every closed frame comes
        /// out exactly once, in frame order, with all its submissions.
        #[test]
        fn every_frame_once(ops in proptest::collection::vec(0u8..4, 0..60)) {
            let mut f = Frames::default();
            let mut pending: Vec<Ticket> = Vec::new();
            let (mut frame, mut submitted, mut out) = (0u64, BTreeMap::new(), Vec::new());
            for op in ops {
                match op {
                    0 => { pending.push(f.begin()); *submitted.entry(frame).or_insert(0u32) += 1; }
                    1 => { f.close_frame(frame); frame += 1; }
                    2 => if let Some(t) = pending.pop() { f.finish(t, 0, 1); },
                    _ => out.extend(f.take_complete(64, 1.0)),
                }
            }
            for t in pending.drain(..) {
                f.finish(t, 0, 1);
            }
            out.extend(f.take_complete(64, 1.0));
            let frames: Vec<u64> = out.iter().map(|x| x.0).collect();
            prop_assert_eq!(frames, (0..frame).collect::<Vec<_>>());
            for (n, t) in out {
                prop_assert_eq!(t.submissions, submitted.get(&n).copied().unwrap_or(0));
            }
        }
    }
}
