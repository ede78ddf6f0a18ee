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
                    self.gaps += missing;
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
    /// The receive thread's idle sleep, ms (the resolution of stamps taken
    /// at read).
    pub poll_ms: u64,
    /// The counters.
    pub stats: crate::bus::BusStats,
}

impl RecvStats {
    /// Counters of `topic` (created on first use).
    pub fn topic(&mut self, topic: &'static str) -> &mut TopicStats {
        self.topics.entry(topic).or_default()
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
