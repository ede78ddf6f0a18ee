//! The loop on a manual clock with an in-memory bus: safe state on sensor and
//! demand timeouts (and recovery), E2E rejection without effect on the
//! command, road-estimate age and the ARTE switch.

mod common;

use common::{LastSink, MemBus, SetRoad};
use grip_io::can::RxFilter;
use grip_io::can::protocol::{
    DriverDemand, E2eSender, MotorStatus, ProtocolMessage, TorqueCommand, WheelSpeeds, encode,
};
use grip_io::clock::{Clock, ManualClock};
use grip_msgs::{CanFrame, CycleRecord, NO_CLASS, RoadEstimate, can_flags};
use grip_physics::VehicleParams;
use grip_tcs::{ControllerKind, ControllersConfig};
use grip_tcs_loop::{CycleTick, NoRoad, SafetyConfig, TcsLoop};

const MS: u64 = 1_000_000;
const T0: u64 = 1_000 * MS;

/// The plant side of the test: encodes the sensor frames.
struct Feeder {
    ws: E2eSender<WheelSpeeds>,
    ms: E2eSender<MotorStatus>,
    dd: E2eSender<DriverDemand>,
    omega: f64,
    torque: f64,
    demand: f64,
    /// `Some(code)`: MotorStatus reports Fault with this FaultCode.
    fault_code: Option<u8>,
}

impl Feeder {
    fn new() -> Self {
        Self {
            ws: E2eSender::new(),
            ms: E2eSender::new(),
            dd: E2eSender::new(),
            omega: 10.0,
            torque: 50.0,
            demand: 200.0,
            fault_code: None,
        }
    }
    fn wheel(&self) -> WheelSpeeds {
        WheelSpeeds {
            driven_valid: true,
            ref_valid: true,
            omega_driven: self.omega,
            omega_ref: 9.9,
        }
    }
    fn ws_frame(&mut self, now: u64) -> CanFrame {
        let w = self.wheel();
        self.ws.encode(&w, now)
    }
    fn ms_frame(&mut self, now: u64) -> CanFrame {
        self.ms.encode(
            &MotorStatus {
                ready: true,
                fault: self.fault_code.is_some(),
                fault_code: self.fault_code.unwrap_or(0),
                torque_actual: self.torque,
                motor_speed: self.omega,
                ..MotorStatus::default()
            },
            now,
        )
    }
    fn dd_frame(&mut self, now: u64) -> CanFrame {
        self.dd.encode(
            &DriverDemand {
                brake_pressed: false,
                tcs_enable: true,
                torque_demand: self.demand,
                pedal_position: 20.0,
            },
            now,
        )
    }
}

/// A loop with the default configuration, ARTE off.
fn plain_loop(kind: ControllerKind) -> TcsLoop {
    TcsLoop::new(
        kind,
        false,
        &ControllersConfig::default(),
        &VehicleParams::default(),
        &SafetyConfig::default(),
    )
    .unwrap()
}

struct Rig {
    clock: ManualClock,
    bus: MemBus,
    sink: LastSink,
    lp: TcsLoop,
    feed: Feeder,
    k: u64,
}

impl Rig {
    fn new(kind: ControllerKind, arte: bool) -> Self {
        let lp = TcsLoop::new(
            kind,
            arte,
            &ControllersConfig::default(),
            &VehicleParams::default(),
            &SafetyConfig::default(),
        )
        .unwrap();
        Self {
            clock: ManualClock::new(T0),
            bus: MemBus::new(),
            sink: LastSink::default(),
            lp,
            feed: Feeder::new(),
            k: 0,
        }
    }
    fn now(&self) -> u64 {
        self.clock.now_ns()
    }
    /// Injects the frames of one millisecond (`ws`, `ms`: the 1 ms frames;
    /// `dd`: the 10 ms demand on its schedule).
    fn feed(&mut self, ws: bool, ms: bool, dd: bool) {
        let now = self.now();
        if ws {
            let f = self.feed.ws_frame(now);
            self.bus.inject(f);
        }
        if ms {
            let f = self.feed.ms_frame(now);
            self.bus.inject(f);
        }
        if dd && self.k.is_multiple_of(10) {
            let f = self.feed.dd_frame(now);
            self.bus.inject(f);
        }
    }
    /// One cycle at the current time, then the clock advances 1 ms.
    fn cycle_with<R: grip_tcs_loop::RoadSource>(
        &mut self,
        road: &mut R,
    ) -> (CycleRecord, TorqueCommand) {
        let tick = CycleTick::at(self.now());
        let rec = *self
            .lp
            .cycle(&tick, &self.clock, &mut self.bus, road, &mut self.sink);
        let sent = self.bus.take_sent();
        assert_eq!(sent.len(), 1, "one TorqueCommand per cycle");
        assert_eq!(sent[0].id, 0x100);
        let cmd = TorqueCommand::read_signals(&sent[0].data);
        self.clock.advance_ns(MS);
        self.k += 1;
        (rec, cmd)
    }
    fn cycle(&mut self) -> (CycleRecord, TorqueCommand) {
        self.cycle_with(&mut NoRoad)
    }
    /// `n` ms of normal traffic; returns the last cycle.
    fn run_ok(&mut self, n: usize) -> (CycleRecord, TorqueCommand) {
        let mut last = None;
        for _ in 0..n {
            self.feed(true, true, true);
            last = Some(self.cycle());
        }
        last.unwrap()
    }
}

fn assert_safe(rec: &CycleRecord, cmd: &TorqueCommand) {
    assert_eq!(rec.safe_state, 1);
    assert_eq!(rec.torque_cmd, 0.0);
    assert!(!cmd.enable, "enable must be cleared in the safe state");
    assert_eq!(cmd.torque_request, 0.0);
}

/// 80 cycles of valid frames: the cycle (counted from 0) in which the loop
/// left its safe state, having stayed safe before and in control after.
fn control_again(r: &mut Rig) -> Option<usize> {
    let mut left_at = None;
    for i in 0..80 {
        r.feed(true, true, true);
        let (rec, cmd) = r.cycle();
        if rec.safe_state == 0 {
            assert!(cmd.enable);
            left_at.get_or_insert(i);
        } else {
            assert!(left_at.is_none(), "re-entered the safe state at {i}");
            assert_safe(&rec, &cmd);
        }
    }
    left_at
}

#[test]
fn starts_safe_and_leaves_after_recover_time() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    // no frames at all: safe
    for _ in 0..20 {
        let (rec, cmd) = r.cycle();
        assert_safe(&rec, &cmd);
    }
    // valid frames: still safe until 50 ms of valid inputs
    assert_eq!(
        control_again(&mut r),
        Some(50),
        "leaves after exactly recover_ms = 50 ms"
    );
    assert_eq!(r.lp.safe_entries(), 0, "the start is not an entry");
}

#[test]
fn sensor_timeout_enters_safe_state_and_recovers_after_valid_frames() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    let (rec, cmd) = r.run_ok(100);
    assert_eq!(rec.safe_state, 0);
    assert!(cmd.enable && cmd.torque_request > 0.0, "{cmd:?}");

    // WheelSpeeds stop (motor status and demand keep coming)
    let mut entered = None;
    for i in 1..=20u64 {
        r.feed(false, true, true);
        let (rec, cmd) = r.cycle();
        if rec.safe_state == 1 {
            assert_safe(&rec, &cmd);
            entered.get_or_insert(i);
        } else {
            assert!(cmd.enable);
        }
    }
    // last frame at cycle 0; "older than 10 ms" is true at 11 ms
    assert_eq!(entered, Some(11), "safe state 10 ms after the last frame");
    assert_eq!(r.lp.safe_entries(), 1);
    assert_eq!(r.lp.last_record().faults.timeout, 1, "one timeout episode");

    // frames back: safe for recover_ms, then normal
    let mut left = None;
    for i in 0..70u64 {
        r.feed(true, true, true);
        let (rec, cmd) = r.cycle();
        if rec.safe_state == 0 {
            left.get_or_insert(i);
            assert!(cmd.enable);
        } else {
            assert!(left.is_none());
            assert_safe(&rec, &cmd);
        }
    }
    assert_eq!(left, Some(50));

    // a frame saying "driven wheel speed invalid" does not count as valid
    for _ in 0..15 {
        let now = r.now();
        let w = WheelSpeeds {
            driven_valid: false,
            ..r.feed.wheel()
        };
        let f = r.feed.ws.encode(&w, now);
        r.bus.inject(f);
        r.feed(false, true, true);
        r.cycle();
    }
    assert_eq!(r.lp.last_record().safe_state, 1);
    assert_eq!(r.lp.safe_entries(), 2);
}

#[test]
fn motor_status_timeout_enters_safe_state() {
    let mut r = Rig::new(ControllerKind::Src, false);
    r.run_ok(100);
    for _ in 0..12 {
        r.feed(true, false, true);
        r.cycle();
    }
    let (rec, cmd) = r.cycle();
    assert_safe(&rec, &cmd);
}

/// An inverter that reports Fault has zeroed (or will not deliver) the
/// torque: the loop enters its safe state in the cycle that reads it (0 N m,
/// Enable cleared, the controller not stepped), names the cause for the
/// transition log, and leaves recover_ms after the fault has cleared.
#[test]
fn an_inverter_fault_enters_the_safe_state_until_it_has_cleared() {
    use grip_tcs_loop::cycle::SafeCause;
    let mut r = Rig::new(ControllerKind::Src, false);
    r.run_ok(100);
    assert_eq!(r.lp.last_record().safe_state, 0);
    r.feed.fault_code = Some(0x2A);
    for _ in 0..30 {
        r.feed(true, true, true);
        let (rec, cmd) = r.cycle();
        assert_safe(&rec, &cmd);
    }
    assert_eq!(r.lp.safe_entries(), 1);
    let st = r.lp.status();
    let cause = st.safe_cause.load(std::sync::atomic::Ordering::Relaxed);
    assert_eq!(cause, SafeCause::INVERTER_FAULT);
    let code = st
        .inverter_fault_code
        .load(std::sync::atomic::Ordering::Relaxed);
    assert_eq!(
        SafeCause::describe(cause, code),
        "the inverter reports Fault (FaultCode 0x2A)"
    );
    // the fault clears: control again exactly recover_ms (50) later
    r.feed.fault_code = None;
    assert_eq!(control_again(&mut r), Some(50));
    assert_eq!(r.lp.safe_entries(), 1);
    // the inverter's own command timeout says whose fault it is
    assert!(
        SafeCause::describe(
            SafeCause::INVERTER_FAULT | SafeCause::INVERTER_CMD_TIMEOUT,
            1
        )
        .contains("with its command timeout: this loop's commands stopped reaching it")
    );
    // a missing frame and the fault together are both named
    assert_eq!(
        SafeCause::describe(SafeCause::WHEEL_SPEED | SafeCause::INVERTER_FAULT, 1),
        "wheel-speed frames missing or invalid, the inverter reports Fault (FaultCode 0x01)"
    );
}

#[test]
fn demand_timeout_enters_safe_state() {
    let mut r = Rig::new(ControllerKind::Mfc, false);
    r.run_ok(100);
    // the demand frame last came at k = 90 (every 10 ms); timeout 50 ms
    let mut entered = None;
    for i in 0..80u64 {
        r.feed(true, true, false);
        let (rec, cmd) = r.cycle();
        if rec.safe_state == 1 {
            assert_safe(&rec, &cmd);
            entered.get_or_insert(i);
        }
    }
    // last demand frame at t = 90 ms; now = 100 + i ms; > 50 ms old at i = 41
    assert_eq!(entered, Some(41));
    let (_, cmd) = r.run_ok(60);
    assert!(cmd.enable, "recovers once the demand is back");
}

/// A loop that gets corrupted frames on top of the valid ones sends exactly
/// the same commands as a twin that gets only the valid ones.
#[test]
fn corrupted_frames_are_rejected_counted_and_do_not_change_the_command() {
    let mut a = Rig::new(ControllerKind::Src, false);
    let mut b = Rig::new(ControllerKind::Src, false);
    for k in 0..400u64 {
        // identical valid traffic (slowly varying wheel speed)
        for r in [&mut a, &mut b] {
            r.feed.omega = 10.0 + 0.002 * k as f64;
            r.feed(true, true, true);
        }
        let now = a.now();
        match k {
            200 => {
                // bad CRC: a valid frame with one payload bit flipped
                let mut f = encode(
                    &WheelSpeeds {
                        omega_driven: 300.0,
                        ..a.feed.wheel()
                    },
                    a.feed.ws.next_counter(),
                    now,
                );
                f.data[3] ^= 0x10;
                a.bus.inject(f);
            }
            210 => {
                // repeated counter: correct CRC, counter of the frame just sent
                let last = a.feed.ws.next_counter().wrapping_sub(1) & 0x0F;
                a.bus.inject(encode(
                    &WheelSpeeds {
                        omega_driven: 300.0,
                        ..a.feed.wheel()
                    },
                    last,
                    now,
                ));
            }
            220 => {
                // wrong length
                let mut f = encode(
                    &MotorStatus {
                        torque_actual: 900.0,
                        ..MotorStatus::default()
                    },
                    a.feed.ms.next_counter(),
                    now,
                );
                f.dlc = 6;
                a.bus.inject(f);
            }
            230 => {
                // unknown id
                a.bus
                    .inject(CanFrame::new(0x7E5, &[1, 2, 3, 4, 5, 6, 7, 8]));
            }
            _ => {}
        }
        let (ra, ca) = a.cycle();
        let (rb, cb) = b.cycle();
        assert_eq!(ca, cb, "command differs at cycle {k}");
        assert_eq!(ra.torque_cmd.to_bits(), rb.torque_cmd.to_bits());
        assert_eq!(ra.omega, rb.omega);
        assert_eq!(ra.torque, rb.torque);
        if k > 100 {
            assert_eq!(ra.safe_state, 0);
        }
    }
    let f = a.lp.last_record().faults;
    assert_eq!(
        (f.crc, f.counter_repeated, f.length, f.unknown_id),
        (1, 1, 1, 1),
        "{f:?}"
    );
    assert_eq!(f.counter_skipped, 0);
    assert_eq!(f.timeout, 0);
    assert_eq!(b.lp.last_record().faults.total(), 0);
    assert_eq!(
        a.sink.can_rejected, 4,
        "rejected frames logged with E2E_REJECTED"
    );
    assert_eq!(a.sink.can_tx, 400);
    assert_eq!(a.sink.can_rx, b.sink.can_rx + 4);
    // the counters of the "stopped" log line agree with what was logged
    assert_eq!(a.lp.can_tx(), a.sink.can_tx);
    assert_eq!(a.lp.can_rx(), a.sink.can_rx);
}

/// Foreign traffic of a shared bus on the bus `run` opens for the loop
/// (filtered for [`grip_tcs_loop::ROLE`]; in memory here, the same rule as
/// SocketCAN's kernel filter and the simulated bus): no fault counted,
/// nothing held for `CAN_LOG`, commands bit-identical to a twin without it.
/// A twin on an unfiltered bus (every frame, as before filters) counts each
/// foreign frame as an unknown id. An id collision (another node sending on
/// WheelSpeeds' id) passes the filter and is still rejected by the E2E check.
#[test]
fn foreign_traffic_on_the_loops_filtered_bus_never_reaches_it() {
    let mut a = Rig::new(ControllerKind::Mtte, false);
    a.bus = MemBus::new().with_rx_filter(RxFilter::Role(grip_tcs_loop::ROLE));
    let mut b = Rig::new(ControllerKind::Mtte, false);
    let mut clean = Rig::new(ControllerKind::Mtte, false);
    let ext = |id: u32| {
        let mut f = CanFrame::new(id, &[0x55; 8]);
        f.flags = can_flags::EXTENDED;
        f
    };
    // per cycle: an unknown 11-bit id, a J1939-style extended frame, an
    // extended frame numbered like MotorStatus, and a TorqueCommand id (a
    // protocol message tcs-loop only sends)
    let foreign = [
        CanFrame::new(0x7FF, &[1, 2, 3, 4]),
        ext(0x18FF_50E5),
        ext(0x110),
        CanFrame::new(0x100, &[0; 8]),
    ];
    for k in 0..300 {
        for r in [&mut a, &mut b, &mut clean] {
            r.feed(true, true, true);
        }
        if (100..200).contains(&k) {
            for f in foreign {
                a.bus.inject(f);
                b.bus.inject(f);
            }
        }
        if k == 250 {
            let collision = CanFrame::new(0x120, &[0x12; 8]);
            a.bus.inject(collision);
            b.bus.inject(collision);
        }
        let (ra, ca) = a.cycle();
        let (rb, cb) = b.cycle();
        let (_, cc) = clean.cycle();
        assert_eq!(ca, cc, "command differs at cycle {k}");
        assert_eq!(cb, cc, "command differs at cycle {k}");
        assert_eq!(ra.torque_cmd.to_bits(), rb.torque_cmd.to_bits());
        if k > 100 {
            assert_eq!(ra.safe_state, 0);
        }
    }
    let fa = a.lp.last_record().faults;
    let fb = b.lp.last_record().faults;
    assert_eq!((fa.unknown_id, fa.crc, fa.total()), (0, 1, 1), "{fa:?}");
    // unfiltered: 0x7FF and the J1939 frame are unknown ids; the extended
    // 0x110 is taken for MotorStatus by id and fails its CRC (or counter)
    assert_eq!(fb.unknown_id, 200, "{fb:?}");
    assert!(fb.total() > fa.total() + 200, "{fb:?}");
    // CAN_LOG: the filtered loop logged its inputs and the collision only
    assert_eq!(a.sink.can_rx, clean.sink.can_rx + 1);
    assert_eq!(a.sink.can_rejected, 1);
    assert_eq!(b.sink.can_rx, clean.sink.can_rx + 1 + 400);
}

/// A late cycle after a stall finds a burst of bad-CRC frames at the head
/// of the queue (a flood) and the valid frames behind it: it must reach the
/// valid ones before their timeout, not go to the safe state because its
/// drain stopped inside the burst (seen in the HIL flood drive with a
/// 64-frame drain: an 8 ms late wake-up, 64 bad frames read, safe state).
#[test]
fn a_late_cycle_reaches_valid_frames_behind_a_burst_of_bad_ones() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    let (rec, _) = r.run_ok(100);
    assert_eq!(rec.safe_state, 0);
    // The loop stalls 11 ms. First a burst of 150 WheelSpeeds with a bad CRC
    // (a flood), then the bus's own traffic of each millisecond.
    let now = r.now();
    for _ in 0..150 {
        let mut f = encode(&r.feed.wheel(), r.feed.ws.next_counter(), now);
        f.data[3] ^= 0x10;
        r.bus.inject(f);
    }
    for _ in 0..11 {
        r.feed(true, true, true);
        r.clock.advance_ns(MS);
        r.k += 1;
    }
    // The late cycle: the last valid frame it took before the stall is
    // 12 ms old (the inputs' timeout is 10 ms), the newest on the bus 1 ms.
    r.feed(true, true, true);
    let (rec, cmd) = r.cycle();
    assert_eq!(
        rec.safe_state, 0,
        "safe state: the drain stopped in the burst"
    );
    assert!(cmd.enable);
    assert_eq!(rec.faults.crc, 150, "every bad frame read and counted");
    // (The 12 ms gap itself is counted as a timeout of WheelSpeeds and
    // MotorStatus: the fault counters say what happened on the bus.)
    assert_eq!(rec.faults.timeout, 2);
    assert_eq!(r.lp.safe_entries(), 0);
}

fn estimate(stamp_ns: u64, confidence: f64) -> RoadEstimate {
    RoadEstimate {
        seq: 1,
        stamp_ns,
        class_index: 2,
        n_classes: 4,
        class_name: grip_msgs::name_to_bytes("snow"),
        confidence,
        lambda_opt: 0.06,
        mu_peak: 0.19,
        alpha: 0.94,
        ..RoadEstimate::zeroed()
    }
}

#[test]
fn road_estimate_is_used_while_fresh_then_falls_back_by_age() {
    let mut r = Rig::new(ControllerKind::Mtte, true);
    r.run_ok(100);
    let mut road = SetRoad {
        next: Some(estimate(r.now() - 20 * MS, 0.9)),
        ..SetRoad::default()
    };
    // [arte] max_age_s = 0.3: the estimate stamped 20 ms ago is usable for
    // 280 more ms; no new estimate comes (arte died)
    let mut used = 0;
    let mut first_unused = None;
    for i in 0..400u64 {
        r.feed(true, true, true);
        let (rec, _) = r.cycle_with(&mut road);
        if rec.used_arte == 1 {
            assert!(first_unused.is_none(), "used again after falling back");
            assert_eq!(rec.road_class, 2);
            used += 1;
        } else {
            assert_eq!(rec.road_class, NO_CLASS);
            first_unused.get_or_insert(i);
        }
    }
    assert_eq!(used, 281, "age 20 ms .. 300 ms inclusive");
    assert_eq!(first_unused, Some(281));

    // a low-confidence estimate is not used
    road.next = Some(estimate(r.now(), 0.3));
    r.feed(true, true, true);
    assert_eq!(r.cycle_with(&mut road).0.used_arte, 0);
    // a stamp in the future (clock mismatch) is not used
    road.next = Some(estimate(r.now() + 5 * MS, 0.9));
    r.feed(true, true, true);
    assert_eq!(r.cycle_with(&mut road).0.used_arte, 0);
    // a fresh confident one is
    road.next = Some(estimate(r.now(), 0.9));
    r.feed(true, true, true);
    assert_eq!(r.cycle_with(&mut road).0.used_arte, 1);
}

#[test]
fn arte_off_ignores_estimates() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    r.run_ok(100);
    let mut road = SetRoad::default();
    for _ in 0..50 {
        road.next = Some(estimate(r.now(), 1.0));
        r.feed(true, true, true);
        let (rec, _) = r.cycle_with(&mut road);
        assert_eq!(rec.used_arte, 0);
    }
}

#[test]
fn record_carries_timing_and_measurements() {
    let mut r = Rig::new(ControllerKind::Src, false);
    r.run_ok(60);
    r.feed(true, true, true);
    let now = r.now();
    let tick = CycleTick {
        deadline_ns: now - 30_000,
        woke_ns: now,
        deadline_misses: 3,
    };
    let rec = *r
        .lp
        .cycle(&tick, &r.clock, &mut r.bus, &mut NoRoad, &mut r.sink);
    assert_eq!(rec.seq, 60);
    assert_eq!(rec.stamp_ns, now - 30_000);
    assert_eq!(rec.wakeup_latency_ns, 30_000);
    assert_eq!(rec.deadline_misses, 3);
    assert_eq!(rec.omega, 10.0);
    assert_eq!(rec.v_valid, 1);
    assert!((rec.v - 0.28 * 9.9).abs() < 1e-9, "V = r * OmegaRef");
    assert_eq!(rec.torque, 50.0);
    assert_eq!(rec.demand, 200.0);
    assert!(rec.torque_cmd <= 200.0 + 1e-9);
    assert_eq!(r.sink.records, 61);
}

#[test]
fn shutdown_sends_zero_torque_with_enable_cleared() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    r.run_ok(100);
    let now = r.now();
    assert!(r.lp.shutdown(now, &mut r.bus, &mut r.sink), "sent");
    let sent = r.bus.take_sent();
    assert_eq!(sent.len(), 1);
    let c = TorqueCommand::read_signals(&sent[0].data);
    assert!(!c.enable);
    assert_eq!(c.torque_request, 0.0);
    // and it passes the inverter's E2E check after the loop's commands
    let mut rx = grip_io::can::protocol::ProtocolRx::for_inverter();
    assert!(rx.receive(&sent[0], now).is_ok());
    // a bus that is gone: the loop says the frame did not go out (its stop
    // line said "zero torque sent" before), and counts the error
    let errors = r.lp.bus_errors();
    assert!(!r.lp.shutdown(now, &mut GoneBus, &mut r.sink), "not sent");
    assert_eq!(r.lp.bus_errors(), errors + 1);
}

/// A bus whose interface is gone: every send fails.
struct GoneBus;

impl grip_io::can::CanBus for GoneBus {
    fn send(&mut self, _: &CanFrame) -> Result<(), grip_io::can::CanError> {
        Err(grip_io::can::CanError::Transfer {
            op: "send",
            kind: std::io::ErrorKind::NotFound,
        })
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, grip_io::can::CanError> {
        Ok(None)
    }
    fn recv_timeout(
        &mut self,
        _: std::time::Duration,
    ) -> Result<Option<CanFrame>, grip_io::can::CanError> {
        Ok(None)
    }
    fn kind(&self) -> grip_io::can::BusKind {
        grip_io::can::BusKind::Sim
    }
}

/// The repository's road catalogue, road-knowledge rule, controllers and
/// the vehicle file `vehicle` (relative to `config/`).
struct Shipped {
    roads: grip_physics::RoadCatalogue,
    table: grip_tcs::RoadTable,
    controllers: grip_tcs::ControllersConfig,
    vehicle: grip_physics::VehicleParams,
}

/// A rig whose loop has the road knowledge (`grip sim`'s "with ARTE"),
/// the motor at 250 N m and the driver asking for 300.
fn aware_rig(
    kind: ControllerKind,
    roads: &grip_physics::RoadCatalogue,
    table: &grip_tcs::RoadTable,
    controllers: &grip_tcs::ControllersConfig,
    vehicle: &grip_physics::VehicleParams,
) -> Rig {
    let mut r = Rig::new(kind, true);
    r.lp = TcsLoop::new(kind, true, controllers, vehicle, &SafetyConfig::default())
        .unwrap()
        .with_road_aware(roads, table.clone(), controllers, vehicle)
        .unwrap();
    r.feed.torque = 250.0;
    r.feed.demand = 300.0;
    r
}

fn shipped(vehicle: &str) -> Shipped {
    let dir = grip_config::ConfigDir::new(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
    );
    let roads = dir.roads().unwrap();
    let table = dir.road_table(&roads).unwrap();
    let controllers = grip_config::load_controllers(dir.file("controllers.toml")).unwrap();
    let (vehicle, _) = grip_config::load_vehicle(dir.file(vehicle)).unwrap();
    Shipped {
        roads,
        table,
        controllers,
        vehicle,
    }
}

/// Snow heard ahead: with the microphone 2.77 m ahead of the driven wheel
/// (`config/vehicles/front-mic.toml`) and the shipped controllers, roads and
/// road table, estimates of snow queued where they were heard bring the
/// command down to snow's transmissible torque, μ_peak · N · r (0.19 ·
/// 3433.5 N · 0.28 m ≈ 183 N m), **before** the wheel's odometer reaches the
/// snow, for every controller; far from the snow the command is not capped.
#[test]
fn snow_heard_ahead_caps_the_torque_before_the_wheel_gets_there() {
    let Shipped {
        roads,
        table,
        controllers,
        vehicle,
    } = shipped("vehicles/front-mic.toml");
    assert!((vehicle.mic_lead_m - 2.77).abs() < 1e-12);
    let snow = roads.index_of("snow").unwrap();
    let limit = table.info(snow).mu_peak * vehicle.normal_force() * vehicle.r;
    assert!((limit - 183.0).abs() < 1.0, "snow carries {limit} N m");
    let frame_m = 0.1 * 0.28 * 9.9; // one 0.1 s frame at V = r·OmegaRef

    for kind in ControllerKind::ALL {
        let mut r = aware_rig(kind, &roads, &table, &controllers, &vehicle);
        let mut seq = 0;
        // an estimate of `road` for the frame that just ended, stamped by
        // arte with the odometer it was heard at
        let mut heard = |r: &Rig, road: &str| {
            seq += 1;
            let x = r.lp.odometer();
            RoadEstimate {
                seq,
                stamp_ns: r.now(),
                frame_t0_ns: r.now() - 100 * MS,
                frame_t1_ns: r.now(),
                class_index: 0,
                n_classes: 4,
                class_name: grip_msgs::name_to_bytes(road),
                confidence: 0.95,
                x_from: x - frame_m,
                x_to: x,
                ..RoadEstimate::zeroed()
            }
        };
        // 1 s on asphalt (out of the safe state after 50 ms), estimates every
        // 100 ms
        let mut snow_at = f64::INFINITY;
        let mut far_max: f64 = 0.0;
        let mut near_max: f64 = 0.0;
        let mut near = 0;
        let mut arrived = false;
        for k in 0..3_000u64 {
            let mut road = SetRoad::default();
            if k % 100 == 99 {
                let name = if k < 1_000 { "asphalt" } else { "snow" };
                let e = heard(&r, name);
                if name == "snow" && snow_at.is_infinite() {
                    // the snow begins where the microphone began hearing it
                    snow_at = e.x_from + vehicle.mic_lead_m;
                }
                road.next = Some(e);
            }
            r.feed(true, true, true);
            let (rec, cmd) = r.cycle_with(&mut road);
            if rec.safe_state == 1 {
                continue;
            }
            let to_go = snow_at - rec.odometer;
            if to_go <= 0.0 {
                arrived = true;
                break;
            }
            if to_go > 2.0 && k > 200 {
                far_max = far_max.max(cmd.torque_request);
            }
            // the last 20 ms before the wheel reaches the snow
            if to_go <= 0.02 * 2.77 {
                near_max = near_max.max(cmd.torque_request);
                near += 1;
                assert!(rec.torque_cap <= limit + 1e-9, "{kind}: cap {rec:?}");
            }
        }
        assert!(arrived, "{kind}: the wheel reached the snow");
        assert!(near >= 10, "{kind}: {near} cycles checked before the snow");
        assert!(
            near_max <= limit + 1e-9,
            "{kind}: {near_max} N m commanded just before the snow (limit {limit})"
        );
        assert!(
            far_max > limit + 20.0,
            "{kind}: far from the snow the torque is not capped ({far_max} N m)"
        );
    }
}

/// A snow patch heard while arte was behind (a 0.4 s stall: its estimates
/// go out at once when it catches up) is still queued: the loop takes every
/// estimate of the burst, in order, so the torque is at snow's limit before
/// the wheel reaches the patch, and the record says how many it took. The
/// same burst cut to its newest estimate (what the loop took before
/// 2026-12-05) leaves the patch as the asphalt heard before it: no cap.
#[test]
fn a_burst_of_estimates_is_queued_whole() {
    let Shipped {
        roads,
        table,
        controllers,
        vehicle,
    } = shipped("vehicles/front-mic.toml");
    let snow = roads.index_of("snow").unwrap();
    let limit = table.info(snow).mu_peak * vehicle.normal_force() * vehicle.r;
    let frame_ns = 100 * MS;

    // (the most torque commanded in the last 20 ms before the patch, the
    // cycle that took the burst's record)
    let drive = |kind: ControllerKind, newest_only: bool| -> (f64, CycleRecord) {
        let mut r = aware_rig(kind, &roads, &table, &controllers, &vehicle);
        // (stamp, odometer) of every cycle: where each frame was heard
        let mut odo: Vec<(u64, f64)> = Vec::new();
        let at = |odo: &[(u64, f64)], t: u64| {
            odo.iter()
                .rev()
                .find(|(s, _)| *s <= t)
                .map_or(0.0, |&(_, x)| x)
        };
        let mut held = Vec::new();
        let mut seq = 0;
        let mut patch = (f64::INFINITY, f64::INFINITY);
        let mut burst_rec = None;
        let mut near_max: f64 = 0.0;
        let mut near = 0;
        for k in 0..4_000u64 {
            let now = r.now();
            let mut road = SetRoad::default();
            // a frame ends every 100 ms: snow for the two ending at 1.1 and
            // 1.2 s, asphalt otherwise
            if k % 100 == 0 && k >= 100 {
                seq += 1;
                let name = if k == 1_100 || k == 1_200 {
                    "snow"
                } else {
                    "asphalt"
                };
                let (x_from, x_to) = (at(&odo, now - frame_ns), at(&odo, now));
                if name == "snow" {
                    patch.0 = patch.0.min(x_from + vehicle.mic_lead_m);
                    patch.1 = x_to + vehicle.mic_lead_m;
                }
                held.push(RoadEstimate {
                    seq,
                    stamp_ns: now,
                    frame_t0_ns: now - frame_ns,
                    frame_t1_ns: now,
                    class_index: 0,
                    n_classes: 4,
                    class_name: grip_msgs::name_to_bytes(name),
                    confidence: 0.95,
                    x_from,
                    x_to,
                    ..RoadEstimate::zeroed()
                });
                // arte stalled from 1.0 s to 1.4 s: what it heard meanwhile
                // goes out at 1.4 s, stamped then
                if !(1_000..1_400).contains(&k) {
                    for mut e in held.drain(..) {
                        e.stamp_ns = now;
                        road.burst.push_back(e);
                    }
                    if newest_only {
                        let last = road.burst.pop_back();
                        road.burst.clear();
                        road.burst.extend(last);
                    }
                }
            }
            r.feed(true, true, true);
            let (rec, cmd) = r.cycle_with(&mut road);
            odo.push((now, rec.odometer));
            if k == 1_400 {
                burst_rec = Some(rec);
            }
            let to_go = patch.0 - rec.odometer;
            if k > 1_400 && to_go <= 0.0 {
                break;
            }
            if k > 1_400 && to_go <= 0.02 * 2.77 {
                near_max = near_max.max(cmd.torque_request);
                near += 1;
            }
        }
        assert!(near >= 10, "{kind}: {near} cycles checked before the patch");
        assert!(patch.1 > patch.0, "{kind}: a patch was heard");
        (near_max, burst_rec.unwrap())
    };
    for kind in ControllerKind::ALL {
        let (near_max, rec) = drive(kind, false);
        assert_eq!(
            rec.roads_taken, 5,
            "{kind}: the burst of 1.0-1.4 s taken whole"
        );
        assert_eq!(rec.road_taken, 15, "{kind}: its newest, seq 14, named");
        assert!(
            near_max <= limit + 1e-9,
            "{kind}: {near_max} N m commanded just before the snow (limit {limit})"
        );
        let (lost, rec) = drive(kind, true);
        assert_eq!(rec.roads_taken, 1);
        assert!(
            lost > limit + 20.0,
            "{kind}: with the newest estimate only, the patch was not known ({lost} N m)"
        );
    }
}

/// A stall (the timer skipped periods, it never bursts) still counts on
/// the odometer: the car moved on meanwhile. A wheel-speed frame older than
/// the sensor timeout is no speed: the record says V unknown and the
/// odometer does not run on the frozen value.
#[test]
fn the_odometer_counts_skipped_periods_and_no_stale_speed() {
    let mut r = Rig::new(ControllerKind::Mtte, false);
    r.run_ok(100);
    let v = VehicleParams::default().r * 9.9; // V = r · OmegaRef
    let dt = 1e-3;
    let x0 = r.lp.odometer();
    r.run_ok(1);
    assert!((r.lp.odometer() - x0 - v * dt).abs() < 1e-12);
    // a 10 ms stall: the next deadline the timer keeps is 10 periods on
    let x0 = r.lp.odometer();
    r.clock.advance_ns(9 * MS);
    r.run_ok(1);
    let moved = r.lp.odometer() - x0;
    assert!(
        (moved - 10.0 * v * dt).abs() < 1e-9,
        "{moved} m over a 10 ms stall at {v} m/s"
    );

    // WheelSpeeds stop: after the 10 ms sensor timeout, no speed
    let mut rec = None;
    for _ in 0..30 {
        r.feed(false, true, true);
        rec = Some(r.cycle().0);
    }
    let rec = rec.unwrap();
    assert_eq!(rec.safe_state, 1);
    assert_eq!(rec.v_valid, 0, "{rec:?}");
    assert!(rec.v.is_nan() && rec.omega == 0.0, "{rec:?}");
    let x1 = r.lp.odometer();
    r.feed(false, true, true);
    r.cycle();
    assert_eq!(r.lp.odometer(), x1, "no speed, no distance");
}

/// The live path (road knowledge tied to places): an estimate stamped
/// ahead of the loop's clock (a clock fault) keeps the stream alive no
/// longer than `[arte] max_age_s` after it came, and an estimate whose
/// confidence is no number is no decision.
#[test]
fn a_future_stamp_or_a_nan_confidence_does_not_keep_knowledge_alive() {
    let Shipped {
        roads,
        table,
        controllers,
        vehicle,
    } = shipped("vehicle.toml");
    let max_age_ms = (controllers.arte.max_age_s * 1e3).round() as usize;
    let build = || {
        TcsLoop::new(
            ControllerKind::Mtte,
            true,
            &controllers,
            &vehicle,
            &SafetyConfig::default(),
        )
        .unwrap()
        .with_road_aware(&roads, table.clone(), &controllers, &vehicle)
        .unwrap()
    };
    // one estimate of asphalt under the wheel, then arte falls silent;
    // returns the cycles ARTE was used in over the next second
    let used_after = |stamp_ahead_ns: u64, confidence: f64| {
        let mut r = Rig::new(ControllerKind::Mtte, true);
        r.lp = build();
        r.run_ok(100);
        let x = r.lp.odometer();
        let mut road = SetRoad {
            next: Some(RoadEstimate {
                seq: 1,
                stamp_ns: r.now() + stamp_ahead_ns,
                frame_t0_ns: r.now() - 100 * MS,
                frame_t1_ns: r.now(),
                class_index: 0,
                n_classes: 4,
                class_name: grip_msgs::name_to_bytes("asphalt"),
                confidence,
                x_from: x - 0.3,
                x_to: x,
                ..RoadEstimate::zeroed()
            }),
            ..SetRoad::default()
        };
        let mut used = 0;
        for _ in 0..1_000 {
            r.feed(true, true, true);
            used += usize::from(r.cycle_with(&mut road).0.used_arte);
        }
        used
    };
    let on_time = used_after(0, 0.95);
    assert!(
        on_time > 0 && on_time <= max_age_ms + 1,
        "an estimate on time: used {on_time} ms (max age {max_age_ms} ms)"
    );
    let ahead = used_after(10_000 * MS, 0.95);
    assert!(
        ahead <= max_age_ms + 1,
        "stamped 10 s ahead: used {ahead} ms after arte stopped (max age {max_age_ms} ms)"
    );
    assert_eq!(
        used_after(0, f64::NAN),
        0,
        "a NaN confidence is no decision"
    );
}

/// SRC without a vehicle speed (OmegaRef invalid, no VehicleSpeed frame)
/// passes the driver's demand through: the status the helper thread logs
/// its transitions from says so, and says so no longer once V is back.
#[test]
fn src_without_a_vehicle_speed_reports_the_passthrough() {
    use std::sync::atomic::Ordering::Relaxed;
    let mut r = Rig::new(ControllerKind::Src, false);
    let st = r.lp.status();
    r.run_ok(100);
    assert!(!st.passthrough.load(Relaxed));
    for _ in 0..20 {
        let now = r.now();
        let w = WheelSpeeds {
            ref_valid: false,
            ..r.feed.wheel()
        };
        let f = r.feed.ws.encode(&w, now);
        r.bus.inject(f);
        r.feed(false, true, true);
        let (rec, _) = r.cycle();
        assert_eq!(rec.safe_state, 0, "no speed is no safe state");
        assert_eq!(rec.v_valid, 0);
    }
    assert!(st.passthrough.load(Relaxed));
    assert_eq!(r.lp.last_record().torque_cmd, r.feed.demand);
    r.run_ok(5);
    assert!(!st.passthrough.load(Relaxed), "V back: active again");
}

/// A bus that counts the frames sent on it, shared with [`OrderSink`].
struct CountingBus {
    inner: MemBus,
    sent: std::rc::Rc<std::cell::Cell<u64>>,
}

impl grip_io::can::CanBus for CountingBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), grip_io::can::CanError> {
        self.sent.set(self.sent.get() + 1);
        self.inner.send(frame)
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, grip_io::can::CanError> {
        self.inner.try_recv()
    }
    fn recv_timeout(
        &mut self,
        timeout: std::time::Duration,
    ) -> Result<Option<CanFrame>, grip_io::can::CanError> {
        self.inner.recv_timeout(timeout)
    }
    fn kind(&self) -> grip_io::can::BusKind {
        self.inner.kind()
    }
}

/// Each CAN-log copy with the bus's sent count when it was made.
struct OrderSink {
    sent: std::rc::Rc<std::cell::Cell<u64>>,
    log: Vec<(u8, u32, u64)>,
}

impl grip_tcs_loop::RecordSink for OrderSink {
    fn cycle(&mut self, _: &CycleRecord) {}
    fn can(&mut self, f: &CanFrame) {
        self.log.push((f.direction, f.id, self.sent.get()));
    }
}

#[test]
fn the_command_goes_out_before_anything_is_published() {
    // Publishing can stall (iceoryx2 connects a new subscriber, e.g. a
    // recorder starting, inside its send): the cycle's received frames are
    // logged after the command is on the bus, still in bus order.
    let sent = std::rc::Rc::new(std::cell::Cell::new(0));
    let mut bus = CountingBus {
        inner: MemBus::new(),
        sent: sent.clone(),
    };
    let mut sink = OrderSink {
        sent: sent.clone(),
        log: Vec::new(),
    };
    let clock = ManualClock::new(T0);
    let mut lp = plain_loop(ControllerKind::Mfc);
    let mut feed = Feeder::new();
    for k in 0..100u64 {
        let now = clock.now_ns();
        bus.inner.inject(feed.ws_frame(now));
        bus.inner.inject(feed.ms_frame(now));
        if k % 10 == 0 {
            bus.inner.inject(feed.dd_frame(now));
        }
        let before = sent.get();
        sink.log.clear();
        lp.cycle(
            &CycleTick::at(now),
            &clock,
            &mut bus,
            &mut NoRoad,
            &mut sink,
        );
        assert_eq!(sent.get(), before + 1, "one command per cycle");
        let rx = if k % 10 == 0 { 3 } else { 2 };
        assert_eq!(sink.log.len(), rx + 1, "cycle {k}: {:?}", sink.log);
        // every copy made after the command was sent
        assert!(
            sink.log.iter().all(|&(_, _, n)| n == before + 1),
            "cycle {k}: a CAN-log copy before the command went out: {:?}",
            sink.log
        );
        // bus order: the received frames, then the command
        let dirs: Vec<u8> = sink.log.iter().map(|e| e.0).collect();
        assert!(dirs[..rx].iter().all(|&d| d == grip_msgs::can_dir::RX));
        assert_eq!(dirs[rx], grip_msgs::can_dir::TX);
        assert_eq!(sink.log[rx].1, 0x100);
        clock.advance_ns(MS);
    }
}

#[test]
fn a_frame_drained_late_is_not_stamped_before_it_arrived() {
    // CI's HIL run: under emulation the loop was preempted ~3 ms between
    // its clock read and the drain, the last WheelSpeeds arrived in that
    // gap, and the safe state came 7.1 ms after that frame was on the wire
    // (timeout 10 ms). The cycle's "now" is read after the drain.
    let clock = ManualClock::new(T0);
    let mut bus = MemBus::new();
    let mut sink = LastSink::default();
    let mut lp = plain_loop(ControllerKind::Mtte);
    let mut feed = Feeder::new();
    let mut last_ws_arrival = 0;
    let mut entered_at = None;
    for k in 0..140u64 {
        let wake = clock.now_ns();
        // WheelSpeeds stop after cycle 100; its last frame arrives 4 ms
        // into that cycle, while the loop is not running
        let ws = k <= 100;
        if k == 100 {
            bus.deliver_late(&clock, 4 * MS);
        }
        if ws {
            bus.inject(feed.ws_frame(wake));
        }
        bus.inject(feed.ms_frame(wake));
        if k % 10 == 0 {
            bus.inject(feed.dd_frame(wake));
        }
        let rec = *lp.cycle(
            &CycleTick::at(wake),
            &clock,
            &mut bus,
            &mut NoRoad,
            &mut sink,
        );
        if ws {
            // handed over after the clock jumped
            last_ws_arrival = clock.now_ns();
        }
        if k > 100 && rec.safe_state == 1 {
            entered_at.get_or_insert(clock.now_ns());
        }
        assert!(
            !(60..=100).contains(&k) || rec.safe_state == 0,
            "cycle {k}: safe state while every frame came"
        );
        clock.advance_ns(MS);
    }
    let entered = entered_at.expect("the safe state after WheelSpeeds stopped");
    let after_ms = (entered - last_ws_arrival) as f64 / MS as f64;
    // the 10 ms timeout counts from the frame's arrival: 11 ms on a 1 ms
    // grid (a stamp taken before the drain gave 7 ms)
    assert_eq!(
        after_ms, 11.0,
        "safe state {after_ms} ms after the last frame arrived"
    );
}
