//! Test doubles: the in-process CAN bus (`grip_io::can::MemBus`),
//! recording sinks, the inverter's and VCU's frames of a healthy drive, one
//! cycle of the loop, and the configuration files tcs-loop reads.

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

/// The shipped files tcs-loop reads (a configuration directory's copy for
/// `grip_testkit::svc::copy_config`).
pub const CONFIG: [&str; 8] = [
    "controllers.toml",
    "vehicle.toml",
    "can.toml",
    "inverter.dbc",
    "tcs-loop.toml",
    "roads.toml",
    "roads",
    "arte-svc.toml",
];

/// The inverter's and the VCU's side of a healthy drive, one cycle `k` at
/// `now`: a MotorStatus (ready, 50 N m, the motor at `omega`) and, every
/// 10th cycle, a DriverDemand of 100 N m (TCS on, no brake).
pub struct Inverter {
    pub ms: grip_io::can::protocol::E2eSender<grip_io::can::protocol::MotorStatus>,
    pub dd: grip_io::can::protocol::E2eSender<grip_io::can::protocol::DriverDemand>,
}

impl Inverter {
    pub fn new() -> Self {
        Self {
            ms: grip_io::can::protocol::E2eSender::new(),
            dd: grip_io::can::protocol::E2eSender::new(),
        }
    }

    /// Puts cycle `k`'s frames on `bus`.
    pub fn send(&mut self, bus: &mut MemBus, k: u64, now: u64, omega: f64) {
        use grip_io::can::protocol::{DriverDemand, MotorStatus};
        bus.inject(self.ms.encode(
            &MotorStatus {
                ready: true,
                torque_actual: 50.0,
                motor_speed: omega,
                ..MotorStatus::default()
            },
            now,
        ));
        if k.is_multiple_of(10) {
            bus.inject(self.dd.encode(
                &DriverDemand {
                    brake_pressed: false,
                    tcs_enable: true,
                    torque_demand: 100.0,
                    pedal_position: 20.0,
                },
                now,
            ));
        }
    }
}

/// One cycle of `lp` at the clock's now, its command taken off the bus,
/// then the clock a millisecond on; the record.
pub fn step(
    lp: &mut grip_tcs_loop::TcsLoop,
    clock: &grip_io::clock::ManualClock,
    bus: &mut MemBus,
    sink: &mut LastSink,
) -> CycleRecord {
    use grip_io::clock::Clock;
    let rec = *lp.cycle(
        &grip_tcs_loop::CycleTick::at(clock.now_ns()),
        clock,
        bus,
        &mut grip_tcs_loop::NoRoad,
        sink,
    );
    bus.take_sent();
    clock.advance_ns(1_000_000);
    rec
}
