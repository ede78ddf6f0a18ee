//! What the loop reads and writes besides the CAN bus, as two small traits
//! so tests drive the loop with in-memory doubles and `run` with iceoryx2
//! ports. Implementations must not allocate, block or log.

use grip_io::ipc::{Publisher, Subscriber};
use grip_msgs::{CanFrame, CycleRecord, RoadEstimate};

/// The `ROAD` topic, latest value wins.
pub trait RoadSource {
    /// The newest estimate that arrived since the last call, if any.
    fn poll_latest(&mut self) -> Option<RoadEstimate>;
}

/// Where the loop's per-cycle outputs go (the recorder's topics).
pub trait RecordSink {
    /// One `CycleRecord` per cycle (`CYCLE`).
    fn cycle(&mut self, rec: &CycleRecord);
    /// A copy of a CAN frame sent or received (`CAN_LOG`).
    fn can(&mut self, frame: &CanFrame);
}

/// No road estimator (ARTE off, or tests).
#[derive(Debug, Default, Clone, Copy)]
pub struct NoRoad;

impl RoadSource for NoRoad {
    fn poll_latest(&mut self) -> Option<RoadEstimate> {
        None
    }
}

/// Discards everything.
#[derive(Debug, Default, Clone, Copy)]
pub struct NullSink;

impl RecordSink for NullSink {
    fn cycle(&mut self, _: &CycleRecord) {}
    fn can(&mut self, _: &CanFrame) {}
}

/// The ROAD subscriber. A receive error counts and reads as "nothing new".
#[derive(Debug)]
pub struct IpcRoad {
    /// Subscriber in latest-value mode.
    pub sub: Subscriber<RoadEstimate>,
    /// Receive errors so far.
    pub errors: u64,
}

impl RoadSource for IpcRoad {
    fn poll_latest(&mut self) -> Option<RoadEstimate> {
        match self.sub.latest() {
            Ok(v) => v,
            Err(_) => {
                self.errors += 1;
                None
            }
        }
    }
}

/// The recorder topics. A publish error (all samples loaned: a stuck
/// subscriber) is counted, never fatal: the loop keeps its deadline.
#[derive(Debug)]
pub struct IpcSink {
    /// `CYCLE` publisher.
    pub cycle: Publisher<CycleRecord>,
    /// `CAN_LOG` publisher.
    pub can: Publisher<CanFrame>,
    /// Failed publishes so far.
    pub errors: u64,
    /// `CycleRecord`s published.
    pub cycle_published: u64,
    /// `CAN_LOG` copies published.
    pub can_published: u64,
}

impl IpcSink {
    /// A sink on the two publishers, counters at zero.
    pub fn new(cycle: Publisher<CycleRecord>, can: Publisher<CanFrame>) -> Self {
        Self {
            cycle,
            can,
            errors: 0,
            cycle_published: 0,
            can_published: 0,
        }
    }
}

impl RecordSink for IpcSink {
    fn cycle(&mut self, rec: &CycleRecord) {
        match self.cycle.publish(rec) {
            Ok(_) => self.cycle_published += 1,
            Err(_) => self.errors += 1,
        }
    }
    fn can(&mut self, frame: &CanFrame) {
        match self.can.publish(frame) {
            Ok(_) => self.can_published += 1,
            Err(_) => self.errors += 1,
        }
    }
}
