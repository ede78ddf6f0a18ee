//! plant-sim's loop on a manual clock with an in-memory bus: the inverter's
//! command timeout, E2E rejection, frame rates and contents, start triggers,
//! the end of a scenario.

mod common;

use common::{LastTruth, MemBus, sim};
use grip_io::can::RxFilter;
use grip_io::can::protocol::{
    E2eSender, InverterMsg, MotorStatus, ProtocolMessage, ProtocolRx, TorqueCommand, encode,
};
use grip_io::clock::{Clock, ManualClock};
use grip_msgs::{CanFrame, can_flags};
use grip_plant_sim::{
    FAULT_CMD_TIMEOUT, Outcome, Phase, PlantSim, PlantSimConfig, PlantTick, StartOn,
};

const MS: u64 = 1_000_000;

struct Rig {
    clock: ManualClock,
    bus: MemBus,
    truth: LastTruth,
    sim: PlantSim,
    tx: E2eSender<TorqueCommand>,
    tcs_rx: ProtocolRx,
    last_status: Option<MotorStatus>,
}

impl Rig {
    fn new(cfg: &PlantSimConfig) -> Self {
        Self {
            clock: ManualClock::new(5_000 * MS),
            bus: MemBus::new(),
            truth: LastTruth::default(),
            sim: sim(cfg),
            tx: E2eSender::new(),
            tcs_rx: ProtocolRx::for_tcs(),
            last_status: None,
        }
    }
    fn send_cmd(&mut self, torque: f64, enable: bool) {
        let f = self.tx.encode(
            &TorqueCommand {
                torque_request: torque,
                enable,
            },
            self.clock.now_ns(),
        );
        self.bus.inject(f);
    }
    /// `n` cycles, each with an enabled command of `torque`.
    fn run_cmds(&mut self, n: usize, torque: f64) {
        for _ in 0..n {
            self.send_cmd(torque, true);
            self.cycle();
        }
    }
    /// One cycle; checks every frame sent with a tcs-side receiver.
    fn cycle(&mut self) -> (Outcome, Vec<CanFrame>) {
        let now = self.clock.now_ns();
        let o = self.sim.cycle(
            &PlantTick::at(now),
            &self.clock,
            &mut self.bus,
            &mut self.truth,
        );
        let sent = self.bus.take_sent();
        for f in &sent {
            match self.tcs_rx.receive(f, now) {
                Ok(Some(InverterMsg::MotorStatus(m))) => self.last_status = Some(m),
                Ok(_) => {}
                Err(e) => panic!("plant-sim sent a frame that fails E2E: {e}"),
            }
        }
        self.clock.advance_ns(MS);
        (o, sent)
    }
}

fn immediate() -> PlantSimConfig {
    PlantSimConfig {
        start_on: StartOn::Immediate,
        ..PlantSimConfig::with_scenario("paper")
    }
}

#[test]
fn inverter_zeroes_torque_when_commands_stop_and_resumes_on_valid_ones() {
    let mut r = Rig::new(&immediate());
    r.run_cmds(100, 100.0);
    assert_eq!(r.sim.applied_torque(), 100.0);
    assert!(!r.sim.cmd_timed_out());
    let st = r.last_status.unwrap();
    assert!(!st.cmd_timeout && !st.fault && st.fault_code == 0);
    let t_before = r.truth.last.unwrap().torque;
    assert!(t_before > 80.0, "motor lag 50 ms: {t_before}");

    // commands stop at cycle 100 (last one at t = 99 ms)
    let mut zero_at = None;
    for i in 1..=40u64 {
        r.cycle();
        if r.sim.applied_torque() == 0.0 {
            zero_at.get_or_insert(i);
            let st = r.last_status.unwrap();
            assert!(st.cmd_timeout && st.fault, "{st:?}");
            assert_eq!(st.fault_code, FAULT_CMD_TIMEOUT);
        } else {
            assert_eq!(r.sim.applied_torque(), 100.0);
        }
    }
    // "older than 20 ms" first holds 21 ms after the last command
    assert_eq!(zero_at, Some(21));
    assert_eq!(r.sim.cmd_timeouts(), 1);
    let t_after = r.truth.last.unwrap().torque;
    // 20 cycles at 0 N m through the 50 ms motor lag: exp(-20/50) = 0.67
    assert!(t_after < 0.75 * t_before, "motor torque decays: {t_after}");

    // one valid command: torque resumes at once, the episode count stays
    r.send_cmd(100.0, true);
    r.cycle();
    assert_eq!(r.sim.applied_torque(), 100.0);
    assert!(!r.last_status.unwrap().cmd_timeout);
    assert_eq!(r.sim.cmd_timeouts(), 1);

    // enable = 0 applies 0 N m without a fault
    r.send_cmd(100.0, false);
    r.cycle();
    assert_eq!(r.sim.applied_torque(), 0.0);
    assert!(!r.last_status.unwrap().fault);
}

#[test]
fn a_command_drained_late_is_not_stamped_before_it_arrived() {
    // the last command reaches the socket 4 ms after the cycle woke (the
    // thread was preempted before its drain): the 20 ms timeout counts from
    // its arrival, not from the wake-up (which zeroed the torque 4 ms early)
    let mut r = Rig::new(&immediate());
    r.run_cmds(99, 100.0);
    r.send_cmd(100.0, true);
    r.bus.deliver_late(&r.clock, 4 * MS);
    r.cycle();
    let arrived = r.clock.now_ns() - MS;
    let mut zero_at = None;
    for _ in 0..40 {
        let now = r.clock.now_ns();
        r.cycle();
        if r.sim.applied_torque() == 0.0 {
            zero_at.get_or_insert(now);
        }
    }
    let after_ms = (zero_at.expect("the command timeout") - arrived) as f64 / MS as f64;
    assert_eq!(
        after_ms, 21.0,
        "torque zeroed {after_ms} ms after the last command arrived"
    );
}

#[test]
fn corrupted_commands_are_rejected_counted_and_ignored() {
    let mut r = Rig::new(&immediate());
    for _ in 0..50 {
        r.send_cmd(120.0, true);
        r.cycle();
    }
    let now = r.clock.now_ns();
    let evil = TorqueCommand {
        torque_request: 900.0,
        enable: true,
    };
    let mut bad_crc = encode(&evil, r.tx.next_counter(), now);
    bad_crc.data[2] ^= 0x01;
    let repeated = encode(&evil, r.tx.next_counter().wrapping_sub(1) & 0x0F, now);
    let mut short = encode(&evil, r.tx.next_counter(), now);
    short.dlc = 4;
    for f in [bad_crc, repeated, short, CanFrame::new(0x555, &[0; 8])] {
        r.bus.inject(f);
        r.cycle();
        assert_eq!(r.sim.applied_torque(), 120.0);
    }
    let f = r.sim.protocol_rx().faults();
    assert_eq!(
        (f.crc, f.counter_repeated, f.length, f.unknown_id),
        (1, 1, 1, 1),
        "{f:?}"
    );
    // the rejected frames were no valid commands: 20 ms later torque is zeroed
    for _ in 0..20 {
        r.cycle();
    }
    assert_eq!(r.sim.applied_torque(), 0.0);
}

/// On the bus `run` opens for the inverter (filtered for
/// [`grip_plant_sim::ROLE`]) nothing but TorqueCommand arrives: foreign ids,
/// an extended frame numbered like TorqueCommand and the sensor messages of
/// another node are dropped below the loop, no fault counted, torque as
/// commanded; unfiltered, the foreign ids count as unknown.
#[test]
fn only_the_torque_command_reaches_the_inverters_filtered_bus() {
    let mut a = Rig::new(&immediate());
    a.bus = MemBus::new().with_rx_filter(RxFilter::Role(grip_plant_sim::ROLE));
    let mut b = Rig::new(&immediate());
    let mut ext = CanFrame::new(0x100, &[0x55; 8]);
    ext.flags = can_flags::EXTENDED;
    let foreign = [
        CanFrame::new(0x7FF, &[1; 8]),
        CanFrame::new(0x555, &[0; 8]),
        ext,
        CanFrame::new(0x120, &[0; 8]),
    ];
    for k in 0..100 {
        for r in [&mut a, &mut b] {
            r.send_cmd(120.0, true);
            if k >= 50 {
                for f in foreign {
                    r.bus.inject(f);
                }
            }
            r.cycle();
            assert_eq!(r.sim.applied_torque(), 120.0, "cycle {k}");
        }
    }
    let fa = a.sim.protocol_rx().faults();
    assert_eq!(fa.total(), 0, "{fa:?}");
    let fb = b.sim.protocol_rx().faults();
    assert_eq!(fb.unknown_id, 100, "{fb:?}");
}

#[test]
fn frames_follow_the_dbc_rates_and_carry_the_state() {
    let mut r = Rig::new(&immediate());
    let mut counts = [0usize; 5];
    for _ in 0..100 {
        r.send_cmd(0.0, true);
        let (_, sent) = r.cycle();
        for f in sent {
            counts[((f.id - 0x100) / 0x10) as usize] += 1;
        }
    }
    assert_eq!(
        counts,
        [0, 100, 100, 10, 10],
        "TC, MS, WS, VS, DD per 100 ms"
    );
    let g = r.truth.last.unwrap();
    assert_eq!(r.truth.n, 100);
    assert_eq!(g.seq, 99);
    assert_eq!(g.road_name(), Some("asphalt"));
    assert!((g.v - 10.0 / 3.6).abs() < 0.1, "{g:?}");
}

#[test]
fn signal_start_needs_the_request_and_enabled_commands() {
    let cfg = PlantSimConfig::with_scenario("paper");
    assert_eq!(cfg.start_on, StartOn::Signal);
    let mut r = Rig::new(&cfg);
    let x0 = r.sim.plant().state().x;
    // commands alone do not start it
    for _ in 0..100 {
        r.send_cmd(300.0, true);
        r.cycle();
    }
    assert_eq!(r.sim.phase(), Phase::Holding);
    assert_eq!(r.sim.plant().state().x, x0, "vehicle held");
    assert_eq!(r.sim.applied_torque(), 0.0, "no torque while holding");
    // the request with disabled commands does not either
    r.sim.request_start();
    for _ in 0..30 {
        r.send_cmd(0.0, false);
        r.cycle();
    }
    assert_eq!(r.sim.phase(), Phase::Holding);
    // 20 consecutive enabled commands after the request: running
    for i in 0..20 {
        r.send_cmd(0.0, true);
        r.cycle();
        assert_eq!(r.sim.phase() == Phase::Running, i == 19, "cycle {i}");
    }
    r.send_cmd(300.0, true);
    r.cycle();
    assert!(r.sim.scenario_time() > 0.0);
    assert!(r.sim.plant().state().x > x0);
}

#[test]
fn commands_start_and_demand_follows_the_scenario() {
    let cfg = PlantSimConfig {
        start_on: StartOn::Commands,
        start_commands: 5,
        ..PlantSimConfig::with_scenario("paper")
    };
    let mut r = Rig::new(&cfg);
    let mut demand = Vec::new();
    for _ in 0..40 {
        r.send_cmd(0.0, true);
        let (_, sent) = r.cycle();
        for f in sent.iter().filter(|f| f.id == 0x140) {
            demand.push(grip_io::can::protocol::DriverDemand::read_signals(&f.data).torque_demand);
        }
    }
    assert_eq!(r.sim.phase(), Phase::Running);
    // holding: demand 0; running: the paper's constant 300 N m
    assert_eq!(demand.first(), Some(&0.0));
    assert_eq!(demand.last(), Some(&300.0));
}

#[test]
fn exit_at_end_holds_zero_torque_then_finishes() {
    let cfg = PlantSimConfig {
        exit_at_end: true,
        ..immediate()
    };
    let mut r = Rig::new(&cfg);
    let duration_ms = (r.sim.scenario().duration * 1000.0).round() as u64;
    let mut ended_at = None;
    let mut finished_at = None;
    for k in 0..duration_ms + 300 {
        r.send_cmd(150.0, true);
        let (o, _) = r.cycle();
        if r.sim.phase() == Phase::Ended {
            // the cycle that reaches the end still applied the last command
            if ended_at.is_some() {
                assert_eq!(r.sim.applied_torque(), 0.0, "zero torque after the end");
            }
            ended_at.get_or_insert(k);
        }
        if o == Outcome::Finished {
            finished_at = Some(k);
            break;
        }
    }
    let e = ended_at.unwrap();
    assert_eq!(e + 1, duration_ms, "ended after the scenario's duration");
    assert_eq!(finished_at.unwrap(), e + 100, "100 ms zero-torque hold");
    let g = r.truth.last.unwrap();
    assert!(g.v.is_finite() && g.x > 0.0);
    assert_eq!(
        g.road_name(),
        Some("snow"),
        "last segment of the paper scenario"
    );
}

#[test]
fn skipped_periods_advance_the_scenario_clock() {
    let mut r = Rig::new(&immediate());
    let now = r.clock.now_ns();
    r.sim.cycle(
        &PlantTick {
            deadline_ns: now,
            skipped: 4,
        },
        &r.clock,
        &mut r.bus,
        &mut r.truth,
    );
    assert!((r.sim.scenario_time() - 0.005).abs() < 1e-12);
}

/// With the microphone in the front wheel arch (2.77 m ahead of the driven
/// wheel), the truth names the road at the microphone apart from the road
/// under the wheel: at the end of the pre-roll (wheel at x = 0) snow is at
/// the microphone while the wheel is still on asphalt (paper: asphalt for
/// the first 1.28 m).
#[test]
fn truth_names_the_road_at_the_microphone() {
    let mut r = Rig::new(&immediate());
    r.sim = common::sim_with_vehicle(&immediate(), "vehicles/front-mic.toml").unwrap();
    while r.sim.phase() != Phase::Running {
        r.cycle();
    }
    let g = r.truth.last.unwrap();
    assert_eq!(g.x, 0.0, "{g:?}");
    assert_eq!(g.road_name(), Some("asphalt"));
    assert_eq!(
        g.mic_road_name(),
        Some("snow"),
        "1.28 m <= x + 2.77 m < 3.81 m"
    );
    assert_ne!(g.mic_road_index, g.road_index);
    // the shipped vehicle (lead 0): both are the wheel's road
    let mut r = Rig::new(&immediate());
    r.cycle();
    let g = r.truth.last.unwrap();
    assert_eq!(g.mic_road_name(), Some("asphalt"));
    assert_eq!(g.mic_road_index, g.road_index);
}

/// A truth sink that fails to publish (what `IpcTruth` counts when the
/// iceoryx2 publish fails) reaches the shared status the helper thread warns
/// from, count for count; the loop goes on.
#[test]
fn failed_truth_publishes_reach_the_status() {
    use std::sync::atomic::Ordering;
    let mut r = Rig::new(&immediate());
    r.cycle();
    assert_eq!(r.sim.status().truth_errors.load(Ordering::Relaxed), 0);
    r.truth.failing = true;
    for _ in 0..3 {
        r.cycle();
    }
    assert_eq!(r.sim.status().truth_errors.load(Ordering::Relaxed), 3);
    r.truth.failing = false;
    r.cycle();
    assert_eq!(r.sim.status().truth_errors.load(Ordering::Relaxed), 3);
    assert_eq!(r.truth.n, 2, "the loop went on");
}

/// The pre-roll (front-mic vehicle, 2.77 m lead, paper from 10 km/h): the
/// car is held 2.77 m before the scenario's start (rounded up to whole
/// cycles, as `grip sim`'s pre-roll) with the microphone over x = 0; once
/// started it rolls there at v0 without torque or demand, x advancing
/// v0·dt per cycle, the microphone hearing asphalt and then the snow that
/// begins at 1.28 m; at x = 0 the scenario clock starts and the plant is
/// driven. The shipped vehicle (lead 0) has no pre-roll.
#[test]
fn pre_roll_rolls_the_lead_at_v0_before_the_scenario_clock_starts() {
    let cfg = PlantSimConfig::with_scenario("paper");
    let mut r = Rig::new(&cfg);
    r.sim = common::sim_with_vehicle(&cfg, "vehicles/front-mic.toml").unwrap();
    let v0 = 10.0 / 3.6;
    let n = grip_physics::VehicleParams {
        mic_lead_m: 2.77,
        ..Default::default()
    }
    .pre_roll_cycles(v0, 1e-3);
    assert_eq!(n, 998, "⌈2.77 m / (2.78 m/s · 1 ms)⌉");
    let x_hold = -(n as f64) * v0 * 1e-3;
    assert!(x_hold <= -2.77 && x_hold > -2.77 - v0 * 1e-3);
    // held: x fixed, the microphone over the scenario's start
    for _ in 0..50 {
        r.send_cmd(300.0, true);
        r.cycle();
    }
    assert_eq!(r.sim.phase(), Phase::Holding);
    let g = r.truth.last.unwrap();
    assert_eq!(g.x, x_hold);
    assert_eq!(g.mic_road_name(), Some("asphalt"));
    r.sim.request_start();
    let mut demand = Vec::new();
    let mut mic_snow_at = None;
    let mut prev_x = x_hold;
    for k in 1..=n {
        r.send_cmd(300.0, true);
        let (_, sent) = r.cycle();
        for f in sent.iter().filter(|f| f.id == 0x140) {
            demand.push(grip_io::can::protocol::DriverDemand::read_signals(&f.data).torque_demand);
        }
        let g = r.truth.last.unwrap();
        if k < n {
            assert_eq!(r.sim.phase(), Phase::PreRoll, "cycle {k}");
        }
        assert!((g.x - prev_x - v0 * 1e-3).abs() < 1e-9, "cycle {k}: {g:?}");
        assert_eq!(g.v, v0, "rolling at v0");
        assert_eq!(g.lambda, 0.0, "without slip");
        assert_eq!(g.torque, 0.0);
        assert_eq!(r.sim.applied_torque(), 0.0, "no torque in the pre-roll");
        assert_eq!(r.sim.scenario_time(), 0.0);
        assert_eq!(g.road_name(), Some("asphalt"));
        if g.mic_road_name() == Some("snow") {
            mic_snow_at.get_or_insert(g.x + 2.77);
        }
        prev_x = g.x;
    }
    assert!(
        demand.iter().all(|&d| d == 0.0),
        "no demand in the pre-roll"
    );
    let snow = mic_snow_at.expect("the microphone heard the snow");
    assert!((snow - 1.28).abs() < 0.01, "snow heard at {snow} m");
    assert_eq!(r.sim.phase(), Phase::Running);
    assert_eq!(r.truth.last.unwrap().x, 0.0, "pre-roll ends at x = 0");
    r.send_cmd(300.0, true);
    r.cycle();
    assert!((r.sim.scenario_time() - 1e-3).abs() < 1e-12);
    assert!(r.truth.last.unwrap().x > 0.0);
    assert!(r.sim.applied_torque() > 0.0, "the scenario drives");

    // lead 0: no pre-roll, running from x = 0 at the start
    assert_eq!(
        grip_physics::VehicleParams {
            mic_lead_m: 0.0,
            ..Default::default()
        }
        .pre_roll_cycles(v0, 1e-3),
        0
    );
    assert_eq!(
        grip_physics::VehicleParams {
            mic_lead_m: 2.77,
            ..Default::default()
        }
        .pre_roll_cycles(0.0, 1e-3),
        0
    );
    let mut r = Rig::new(&cfg);
    assert_eq!(r.sim.plant().state().x, 0.0);
    r.sim.request_start();
    for _ in 0..20 {
        r.send_cmd(0.0, true);
        r.cycle();
    }
    assert_eq!(r.sim.phase(), Phase::Running);
}

/// A time-segment scenario cannot say where a road begins ahead of the
/// wheel: refused with a lead, the error naming the field and the way out.
#[test]
fn time_segments_with_a_lead_are_refused() {
    let cfg = PlantSimConfig {
        start_on: StartOn::Immediate,
        ..PlantSimConfig::with_scenario("e2e")
    };
    let e = common::sim_with_vehicle(&cfg, "vehicles/front-mic.toml").unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("mic_lead_m") && msg.contains("time segments") && msg.contains("distance"),
        "{msg}"
    );
    assert!(common::sim_with_vehicle(&cfg, "vehicle.toml").is_ok());
}
