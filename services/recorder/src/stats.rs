//! Per-topic counters: received, gaps by sequence number, sequence resets
//! (a publisher restarted), queue drops, written. For the CAN log, whose
//! payload has no sequence number, gaps are counted from the E2E alive
//! counters per (identifier, direction): a lower bound (jumps are seen
//! modulo 16), and it also includes frames lost on the bus before the
//! logging process saw them.

use std::collections::BTreeMap;

use grip_msgs::CanFrame;

/// Sequence-number tracking of one stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeqTracker {
    last: Option<u64>,
    /// Sequence numbers skipped (messages lost before the recorder).
    pub gaps: u64,
    /// Gap events (runs of lost messages).
    pub gap_events: u64,
    /// Times the sequence went backwards (publisher restarted) or repeated.
    pub resets: u64,
}

impl SeqTracker {
    /// Account for a message with sequence number `seq`.
    pub fn push(&mut self, seq: u64) {
        if let Some(last) = self.last {
            if seq > last {
                let missing = seq - last - 1;
                if missing > 0 {
                    // a publisher's sequence numbers are another
                    // process's data: a jump near u64::MAX must not
                    // overflow the count (it saturates: plainly not a
                    // real loss)
                    self.gaps = self.gaps.saturating_add(missing);
                    self.gap_events += 1;
                }
            } else {
                self.resets += 1;
            }
        }
        self.last = Some(seq);
    }
    /// Last sequence number seen.
    pub fn last(&self) -> Option<u64> {
        self.last
    }
}

/// Most (id, direction) pairs tracked; frames of further pairs are counted in
/// [`CanCounterTracker::untracked`] (bounded memory against a bus full of
/// unknown identifiers).
pub const MAX_CAN_KEYS: usize = 1024;

/// Alive-counter tracking of the CAN log, per (id, direction).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CanCounterTracker {
    /// Frames of pairs beyond [`MAX_CAN_KEYS`] (not tracked).
    pub untracked: u64,
    last: BTreeMap<(u32, u8), u8>,
    /// Frames missing according to the alive counters (lower bound).
    pub gaps: u64,
    /// Frames whose counter repeated the previous one of the same id and
    /// direction (a replay, or the first frame after a publisher restart).
    pub repeats: u64,
}

impl CanCounterTracker {
    /// Account for `f`: its alive counter where the process's bus protocol
    /// puts it (`grip_io::can::protocol::counter_of`; bits 8-11 for an id
    /// the protocol does not know). Frames shorter than 2 bytes carry no
    /// counter.
    pub fn push(&mut self, f: &CanFrame) {
        if f.dlc < 2 {
            return;
        }
        let c = grip_io::can::protocol::counter_of(f);
        let key = (f.id, f.direction);
        if self.last.len() >= MAX_CAN_KEYS && !self.last.contains_key(&key) {
            self.untracked += 1;
            return;
        }
        if let Some(&prev) = self.last.get(&key) {
            let delta = c.wrapping_sub(prev) & 0x0F;
            if delta == 0 {
                self.repeats += 1;
            } else {
                self.gaps += u64::from(delta - 1);
            }
        }
        self.last.insert(key, c);
    }
}

/// Counters of one topic.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TopicStats {
    /// Samples taken from the subscriber.
    pub received: u64,
    /// Samples dropped because the write queue was full.
    pub queue_dropped: u64,
    /// Sequence tracking (for CAN: see [`CanCounterTracker`]).
    pub seq: SeqTracker,
    /// Receive errors.
    pub receive_errors: u64,
}

/// Everything the receive side counted, by topic (in `topics::ALL` order).
#[derive(Debug, Clone, Default)]
pub struct RecvStats {
    /// Per-topic counters, keyed by topic name.
    pub topics: BTreeMap<&'static str, TopicStats>,
    /// CAN alive-counter tracking.
    pub can: CanCounterTracker,
    /// The bus log's counters (`None`: `bus = "off"`).
    pub bus: Option<BusSummary>,
}

/// The bus log of a recording: its mode and counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusSummary {
    /// `recorder.toml`'s `bus`.
    pub mode: &'static str,
    /// The receive thread's idle sleep, ms.
    pub poll_ms: u64,
    /// The counters.
    pub stats: crate::bus::BusStats,
}

impl RecvStats {
    /// Counters of `topic` (created on first use).
    pub fn topic(&mut self, topic: &'static str) -> &mut TopicStats {
        self.topics.entry(topic).or_default()
    }

    /// What was counted after `earlier` (an earlier snapshot of the same
    /// counters): the counters of one part of a run. The CAN alive-counter
    /// table is not copied (only its counts).
    pub fn since(&self, earlier: &RecvStats) -> RecvStats {
        let mut out = RecvStats::default();
        for (t, s) in &self.topics {
            let e = earlier.topics.get(t).copied().unwrap_or_default();
            let mut seq = SeqTracker {
                gaps: s.seq.gaps.saturating_sub(e.seq.gaps),
                gap_events: s.seq.gap_events.saturating_sub(e.seq.gap_events),
                resets: s.seq.resets.saturating_sub(e.seq.resets),
                ..SeqTracker::default()
            };
            seq.last = s.seq.last;
            out.topics.insert(
                t,
                TopicStats {
                    received: s.received.saturating_sub(e.received),
                    queue_dropped: s.queue_dropped.saturating_sub(e.queue_dropped),
                    seq,
                    receive_errors: s.receive_errors.saturating_sub(e.receive_errors),
                },
            );
        }
        out.can.gaps = self.can.gaps.saturating_sub(earlier.can.gaps);
        out.can.repeats = self.can.repeats.saturating_sub(earlier.can.repeats);
        out.can.untracked = self.can.untracked.saturating_sub(earlier.can.untracked);
        out.bus = self.bus.map(|b| {
            let (s, e) = (b.stats, earlier.bus.map(|e| e.stats).unwrap_or_default());
            BusSummary {
                stats: crate::bus::BusStats {
                    received: s.received.saturating_sub(e.received),
                    skipped_own: s.skipped_own.saturating_sub(e.skipped_own),
                    queue_dropped: s.queue_dropped.saturating_sub(e.queue_dropped),
                    receive_errors: s.receive_errors.saturating_sub(e.receive_errors),
                    kernel_dropped: s.kernel_dropped.saturating_sub(e.kernel_dropped),
                    kernel_stamped: s.kernel_stamped.saturating_sub(e.kernel_stamped),
                    reopens: s.reopens.saturating_sub(e.reopens),
                    open_failures: s.open_failures.saturating_sub(e.open_failures),
                    transport: s.transport,
                },
                ..b
            }
        });
        out
    }
}

/// The receive thread's counters, handed to the writing thread on request
/// (when a part ends: [`crate::parts`]). The receive thread checks
/// [`StatsTap::wanted`] once a pass (one atomic load) and copies its
/// counters only when asked, a few times an hour.
#[derive(Debug, Default)]
pub struct StatsTap {
    want: std::sync::atomic::AtomicBool,
    slot: std::sync::Mutex<Option<RecvStats>>,
}

impl StatsTap {
    /// Whether the writing thread waits for a copy (receive thread).
    pub fn wanted(&self) -> bool {
        self.want.load(std::sync::atomic::Ordering::Acquire)
    }

    /// Hands over a copy of `stats` (receive thread).
    pub fn give(&self, stats: &RecvStats) {
        if let Ok(mut s) = self.slot.lock() {
            *s = Some(stats.clone());
        }
        self.want.store(false, std::sync::atomic::Ordering::Release);
    }

    /// Asks the receive thread for its counters and waits for them at most
    /// `within` (writing thread); `None` when it did not answer in time.
    pub fn take(&self, within: std::time::Duration) -> Option<RecvStats> {
        if let Ok(mut s) = self.slot.lock() {
            *s = None;
        }
        self.want.store(true, std::sync::atomic::Ordering::Release);
        let t0 = std::time::Instant::now();
        loop {
            if let Ok(mut s) = self.slot.lock()
                && let Some(x) = s.take()
            {
                return Some(x);
            }
            if t0.elapsed() >= within {
                self.want.store(false, std::sync::atomic::Ordering::Release);
                return None;
            }
            std::thread::sleep(std::time::Duration::from_micros(500));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn contiguous_has_no_gaps() {
        let mut t = SeqTracker::default();
        for s in 0..100 {
            t.push(s);
        }
        assert_eq!((t.gaps, t.gap_events, t.resets), (0, 0, 0));
    }

    #[test]
    fn gap_and_reset_are_counted() {
        let mut t = SeqTracker::default();
        for s in [0, 1, 2, 5, 6, 0, 1, 3] {
            t.push(s);
        }
        assert_eq!(t.gaps, 2 + 1);
        assert_eq!(t.gap_events, 2);
        assert_eq!(t.resets, 1);
    }

    /// Sequence numbers are another process's data: wild jumps (to
    /// u64::MAX and back, then on) are counted without overflowing (a
    /// debug build's receive thread panicked on them).
    #[test]
    fn wild_sequence_numbers_do_not_overflow_the_counts() {
        let mut t = SeqTracker::default();
        for s in [0, u64::MAX, 0, 3, u64::MAX, 0, u64::MAX - 1] {
            t.push(s);
        }
        assert_eq!(t.gaps, u64::MAX);
        assert_eq!(t.gap_events, 4);
        assert_eq!(t.resets, 2);
    }

    proptest! {
        /// Any sequence of numbers: no panic, and the counts are those of
        /// a wide (u128) count, saturated.
        #[test]
        fn any_sequence_is_counted(seqs in proptest::collection::vec(any::<u64>(), 0..50)) {
            let mut t = SeqTracker::default();
            let (mut gaps, mut events, mut resets) = (0u128, 0u64, 0u64);
            for w in seqs.windows(2) {
                if w[1] > w[0] {
                    let m = u128::from(w[1] - w[0] - 1);
                    if m > 0 {
                        gaps += m;
                        events += 1;
                    }
                } else {
                    resets += 1;
                }
            }
            for &s in &seqs {
                t.push(s);
            }
            prop_assert_eq!(u128::from(t.gaps), gaps.min(u128::from(u64::MAX)));
            prop_assert_eq!((t.gap_events, t.resets), (events, resets));
        }
    }

    fn frame(id: u32, counter: u8) -> CanFrame {
        let mut f = CanFrame::new(id, &[0, counter, 0, 0, 0, 0, 0, 0]);
        f.direction = 1;
        f
    }

    #[test]
    fn can_counter_gaps() {
        let mut t = CanCounterTracker::default();
        for c in [14, 15, 0, 1, 4, 5] {
            t.push(&frame(0x100, c));
        }
        t.push(&frame(0x110, 3)); // other id: independent
        t.push(&frame(0x110, 3));
        assert_eq!(t.gaps, 2);
        assert_eq!(t.repeats, 1);
    }

    #[test]
    fn can_tracking_is_bounded() {
        let mut t = CanCounterTracker::default();
        for id in 0..(MAX_CAN_KEYS as u32 + 10) {
            t.push(&frame(id, 0));
        }
        assert_eq!(t.untracked, 10);
    }

    proptest! {
        /// Dropping k messages out of a contiguous stream is counted as
        /// exactly k gaps (when the last message is kept).
        #[test]
        fn dropped_messages_equal_gaps(n in 2u64..500, drop in proptest::collection::btree_set(1u64..499, 0..50)) {
            let mut t = SeqTracker::default();
            let mut dropped = 0;
            for s in 0..n {
                if drop.contains(&s) && s + 1 < n {
                    dropped += 1;
                    continue;
                }
                t.push(s);
            }
            prop_assert_eq!(t.gaps, dropped);
            prop_assert_eq!(t.resets, 0);
        }
    }
}
