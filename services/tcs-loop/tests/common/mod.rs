//! Test doubles: the in-process CAN bus (`grip_io::can::MemBus`) and
//! recording sinks.

#![allow(dead_code)]

pub use grip_io::can::MemBus;
use grip_msgs::{CanFrame, CycleRecord, RoadEstimate, can_dir};
use grip_tcs_loop::{RecordSink, RoadSource};

/// Keeps the last record and counts CAN log copies (allocation-free).
#[derive(Default)]
pub struct LastSink {
    pub last: Option<CycleRecord>,
    pub records: u64,
    pub can_rx: u64,
    pub can_tx: u64,
    pub can_rejected: u64,
}

impl RecordSink for LastSink {
    fn cycle(&mut self, rec: &CycleRecord) {
        self.last = Some(*rec);
        self.records += 1;
    }
    fn can(&mut self, f: &CanFrame) {
        if f.direction == can_dir::TX {
            self.can_tx += 1;
        } else {
            self.can_rx += 1;
        }
        if f.flags & grip_msgs::can_flags::E2E_REJECTED != 0 {
            self.can_rejected += 1;
        }
    }
}

/// A road source the test sets: `next`, then `burst` in order (what
/// arrived since the last cycle). Pushing within `burst`'s capacity does
/// not allocate.
#[derive(Default)]
pub struct SetRoad {
    pub next: Option<RoadEstimate>,
    pub burst: std::collections::VecDeque<RoadEstimate>,
}

impl RoadSource for SetRoad {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        self.next.take().or_else(|| self.burst.pop_front())
    }
}
