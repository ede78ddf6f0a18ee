//! What the loop reads and writes besides the CAN bus, as two small traits
//! so tests drive the loop with in-memory doubles and `run` with iceoryx2
//! ports. Implementations must not allocate, block or log.

use grip_io::ipc::{Publisher, Subscriber};
use grip_msgs::{CanFrame, CycleRecord, RoadEstimate};

/// The `ROAD` topic: a stream in which every estimate counts (each says
/// what lies on its own stretch of the path).
pub trait RoadSource {
    /// The oldest estimate not taken yet, if any (the loop takes them in
    /// order until none is left, at most `MAX_ROADS_PER_CYCLE` a cycle).
    fn poll_next(&mut self) -> Option<RoadEstimate>;
}

/// The loop's buffer on `grip/arte/road`: 64 estimates, 1.6 s of arte's
/// stream at its 40 a second. What arte publishes at once after catching
/// up on its audio is at most its `max_lag_s` (0.5 s by default, 20
/// estimates); when the loop does not read for longer than the buffer
/// holds, the oldest are overwritten.
pub const ROAD_BUFFER: usize = 64;

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
    fn poll_next(&mut self) -> Option<RoadEstimate> {
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

/// The ROAD subscriber. A receive error counts and reads as "nothing new";
/// without a subscriber (the topic could not be opened at start-up) there
/// is never anything new.
#[derive(Debug)]
pub struct IpcRoad {
    /// Subscriber with a buffer of [`ROAD_BUFFER`], if the topic opened.
    pub sub: Option<Subscriber<RoadEstimate>>,
    /// Receive errors so far.
    pub errors: u64,
}

impl RoadSource for IpcRoad {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        match self.sub.as_ref()?.recv() {
            Ok(v) => v,
            Err(_) => {
                self.errors += 1;
                None
            }
        }
    }
}

/// The recorder topics. A publish error (all samples loaned: a stuck
/// subscriber) is counted, never fatal: the loop keeps its deadline. A
/// topic that could not be opened at start-up is `None` and skipped.
#[derive(Debug)]
pub struct IpcSink {
    /// `CYCLE` publisher, if the topic opened.
    pub cycle: Option<Publisher<CycleRecord>>,
    /// `CAN_LOG` publisher, if the topic opened.
    pub can: Option<Publisher<CanFrame>>,
    /// Failed publishes so far.
    pub errors: u64,
    /// `CycleRecord`s published.
    pub cycle_published: u64,
    /// `CAN_LOG` copies published.
    pub can_published: u64,
}

impl IpcSink {
    /// A sink on the two publishers, counters at zero.
    pub fn new(cycle: Option<Publisher<CycleRecord>>, can: Option<Publisher<CanFrame>>) -> Self {
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
        let Some(p) = &self.cycle else { return };
        match p.publish(rec) {
            Ok(_) => self.cycle_published += 1,
            Err(_) => self.errors += 1,
        }
    }
    fn can(&mut self, frame: &CanFrame) {
        let Some(p) = &self.can else { return };
        match p.publish(frame) {
            Ok(_) => self.can_published += 1,
            Err(_) => self.errors += 1,
        }
    }
}

/// The loop's iceoryx2 ports besides the CAN bus, opened at start-up. None
/// of them is needed to control the wheel: a topic that cannot be opened
/// (another grip version's payload on it after a partial upgrade, a full
/// service) leaves its port out and is named in `missing`, so traction
/// control still starts, without road knowledge (ROAD) or without what the
/// recorder and arte read (CYCLE, CAN_LOG).
#[derive(Debug)]
pub struct Ports {
    /// CYCLE and CAN_LOG.
    pub sink: IpcSink,
    /// ROAD.
    pub road: IpcRoad,
    /// (topic, error) of each port left out.
    pub missing: Vec<(String, String)>,
}

/// Opens the ports on `node` for the topics `cycle`, `can_log` and `road`
/// (`grip_msgs::topics` in the service; other names in tests).
pub fn open_ports(node: &grip_io::ipc::IpcNode, cycle: &str, can_log: &str, road: &str) -> Ports {
    let mut missing = Vec::new();
    let mut keep = |topic: &str, e: grip_io::ipc::IpcError| {
        missing.push((topic.to_owned(), e.to_string()));
    };
    let cycle_pub = node
        .publisher::<CycleRecord>(cycle)
        .map_err(|e| keep(cycle, e))
        .ok();
    let can_pub = node
        .publisher::<CanFrame>(can_log)
        .map_err(|e| keep(can_log, e))
        .ok();
    let road_sub = node
        .subscriber::<RoadEstimate>(road, grip_io::ipc::SubscriberMode::Buffered(ROAD_BUFFER))
        .map_err(|e| keep(road, e))
        .ok();
    Ports {
        sink: IpcSink::new(cycle_pub, can_pub),
        road: IpcRoad {
            sub: road_sub,
            errors: 0,
        },
        missing,
    }
}
