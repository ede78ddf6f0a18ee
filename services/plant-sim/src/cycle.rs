//! [`PlantSim`]: the motor inverter, vehicle and road of a scenario on the
//! CAN bus, one cycle at a time. `run` drives it at `rate_hz` on the real
//! clock; tests drive it on a manual clock.
//!
//! A cycle, in this order:
//! 1. **Drain CAN** (non-blocking, at most [`MAX_RX_PER_CYCLE`] frames),
//!    then read the clock (the cycle's "now": no command is stamped earlier
//!    than it arrived, so the command timeout never fires early), then
//!    check each frame through `ProtocolRx::for_role(ROLE)` (E2E checked,
//!    faults counted; the bus `run` opens delivers only [`ROLE`]'s ids):
//!    the newest valid `TorqueCommand` is held with its arrival time.
//! 2. **Inverter**: a command is *valid* while the last accepted one is at
//!    most `cmd_timeout_ms` old. Without a valid command the inverter applies
//!    0 N m and reports `CmdTimeout` = 1, `Fault` = 1 and `FaultCode` =
//!    [`FAULT_CMD_TIMEOUT`] in `MotorStatus`; each valid → timed-out
//!    transition counts one episode ([`PlantSim::cmd_timeouts`]). The next
//!    valid command resumes torque at once. `Enable` = 0 also applies 0 N m
//!    (not a fault).
//! 3. **Start** (phase `Holding` → `PreRoll` → `Running`) per [`StartOn`].
//! 4. **Plant**: `Holding` — not stepped (the vehicle is held at the
//!    scenario's initial state: rolling at `v0` without slip, torque 0, at
//!    `x = -pre-roll distance`). `PreRoll` (only with a microphone ahead of
//!    the wheel, `mic_lead_m > 0`, and `v0 > 0`) — the car rolls at `v0`
//!    (kinematically: no torque, no demand, x advancing by `v0` per second)
//!    over the pre-roll distance `n · v0 · dt`, `n = ⌈mic_lead_m / (v0 dt)⌉`
//!    cycles (the `pre_roll` of `grip sim`), so that it reaches `x = 0` with
//!    the microphone having heard the road from 0 to `mic_lead_m`; the
//!    scenario clock then starts at 0 with the car at x = 0, as in the
//!    simulator. `Running` — stepped by the elapsed period (one period, plus any periods
//!    the timer skipped after a deadline miss, so the scenario clock stays
//!    real-time) with the applied torque on the scenario's road and grade
//!    at (t, x); the motor lag is the plant's. After the scenario's duration
//!    the phase is `Ended`: the inverter applies 0 N m, the demand is 0, the
//!    plant coasts on the last road; with `exit_at_end` the cycle returns
//!    [`Outcome::Finished`] once `end_hold_ms` have passed.
//! 5. **Sensors** (`grip_physics::Sensors`, seeded) sample the plant; the
//!    frames go out at the bus DBC's periods (`GenMsgCycleTime`, in whole
//!    cycles): in grip's own DBC `WheelSpeeds` and `MotorStatus` every
//!    cycle (1 ms), `VehicleSpeed` and `DriverDemand` every 10 ms,
//!    each with its E2E counter and CRC. `DriverDemand` carries the scenario's
//!    demand at t while `Running`, 0 otherwise.
//! 6. **GroundTruth** is published every cycle (1 kHz): the true road
//!    (catalogue index and name), V, ω, λ, T, x.
//!
//! The sensor model's own transport delay (`delay_samples`) is set to 0:
//! the delay is the real one of the bus and the two processes' timer phases.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};

use grip_io::can::protocol::{
    DriverDemand, E2eSender, InverterMsg, MotorStatus, ProtocolMessage, ProtocolRx, Role,
    TorqueCommand, VehicleSpeed, WheelSpeeds,
};
use grip_io::can::{CanBus, CanFrame, drain};
use grip_io::clock::Clock;
use grip_io::rt::CycleTiming;
use grip_msgs::{GroundTruth, NAME_LEN, name_to_bytes};
use grip_physics::{
    InvalidField, Plant, PlantState, RoadCatalogue, Scenario, SensorParams, Sensors, VehicleParams,
};

use crate::config::{PlantSimConfig, StartOn};

/// Most frames drained from the bus in one cycle (grip-io's, shared with
/// tcs-loop: over 30 ms of a flooded bus, so a late cycle reaches the valid
/// commands behind a burst of bad frames before the inverter's command
/// timeout).
pub use grip_io::can::MAX_RX_PER_CYCLE;

/// The part plant-sim plays on the bus as a receiver: the DBC's inverter
/// (`INV`). What its [`ProtocolRx`] checks and what `run` opens the bus to
/// receive (`RxFilter::Role(ROLE)`), one constant so the two cannot differ.
/// (It also sends as `ABS` and `VCU`, which receive nothing.)
pub const ROLE: Role = Role::Inverter;
/// `MotorStatus.FaultCode` while torque is zeroed because commands stopped.
pub const FAULT_CMD_TIMEOUT: u8 = 0x01;

/// When a cycle runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlantTick {
    /// The timer's absolute deadline, ns.
    pub deadline_ns: u64,
    /// Periods the timer skipped before this one (after an overrun).
    pub skipped: u64,
}

impl PlantTick {
    /// From the periodic timer's report.
    pub fn from_timing(t: &CycleTiming) -> Self {
        Self {
            deadline_ns: t.deadline_ns,
            skipped: t.skipped,
        }
    }
    /// A regular cycle at `t_ns` (tests).
    pub fn at(t_ns: u64) -> Self {
        Self {
            deadline_ns: t_ns,
            skipped: 0,
        }
    }
}

/// Where the ground truth goes.
pub trait TruthSink {
    /// One sample per cycle.
    fn truth(&mut self, g: &GroundTruth);
    /// Samples this sink failed to deliver so far (the cycle copies it into
    /// [`PlantStatus::truth_errors`], which the helper thread warns about).
    fn errors(&self) -> u64 {
        0
    }
}

/// Discards the truth.
#[derive(Debug, Default, Clone, Copy)]
pub struct NullTruth;

impl TruthSink for NullTruth {
    fn truth(&mut self, _: &GroundTruth) {}
}

/// Scenario phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for the start trigger; vehicle held at its initial state.
    Holding = 0,
    /// Scenario clock running.
    Running = 1,
    /// Past the scenario's duration: zero torque, zero demand, coasting.
    Ended = 2,
    /// Started, rolling at `v0` towards x = 0 (the microphone's lead) before
    /// the scenario clock runs; only with `mic_lead_m > 0` and `v0 > 0`.
    PreRoll = 3,
}

/// What the caller should do after a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Keep cycling.
    Continue,
    /// `exit_at_end`: the scenario ended and the hold time passed.
    Finished,
}

/// State shared with the non-real-time helper thread.
#[derive(Debug, Default)]
pub struct PlantStatus {
    /// Cycles done (heartbeat).
    pub heartbeat: AtomicU64,
    /// [`Phase`] as u8.
    pub phase: AtomicU8,
    /// The inverter is zeroing torque for lack of valid commands.
    pub cmd_timed_out: AtomicBool,
    /// Command-timeout episodes so far.
    pub cmd_timeouts: AtomicU64,
    /// E2E faults on the command path so far.
    pub faults_total: AtomicU64,
    /// CAN errors so far.
    pub io_errors: AtomicU64,
    /// Ground-truth samples the truth sink failed to publish so far.
    pub truth_errors: AtomicU64,
    /// The SocketCAN interface is gone (deleted, unplugged): its socket
    /// unbound, waiting for it to be back (set by `run` after each cycle).
    pub bus_gone: AtomicBool,
    /// Times the SocketCAN socket was reopened on a re-created interface.
    pub bus_reopens: AtomicU64,
}

/// Errors building the simulator.
#[derive(Debug, thiserror::Error)]
pub enum PlantSimError {
    /// A model rejected a parameter (field named, prefixed by its section).
    #[error("field `{}`: {}", .0.field, .0.reason)]
    Invalid(InvalidField),
}

/// The plant simulator's state. [`cycle`](Self::cycle) allocates nothing.
#[derive(Debug)]
pub struct PlantSim {
    scenario: Scenario,
    roads: RoadCatalogue,
    names: Vec<[u8; NAME_LEN]>,
    /// The microphone's lead ahead of the driven wheel, m.
    mic_lead: f64,
    /// Pre-roll cycles (0: none) and those done.
    pre_roll_n: u64,
    pre_roll_k: u64,
    plant: Plant,
    sensors: Sensors,
    /// The non-driven reference wheel's rolling radius (`r_ref`, else the
    /// driven tyre's `r`): OmegaRef = V / r_ref.
    r_ref: f64,
    dt: f64,
    rx: ProtocolRx,
    tx_ws: E2eSender<WheelSpeeds>,
    tx_ms: E2eSender<MotorStatus>,
    tx_vs: E2eSender<VehicleSpeed>,
    tx_dd: E2eSender<DriverDemand>,
    div_ws: u64,
    div_ms: u64,
    div_vs: u64,
    div_dd: u64,
    k: u64,
    cmd: TorqueCommand,
    cmd_ns: Option<u64>,
    cmd_timeout_ns: u64,
    cmd_valid: bool,
    cmd_timeouts: u64,
    enabled_streak: u32,
    start_on: StartOn,
    start_commands: u32,
    start_requested: bool,
    phase: Phase,
    t_s: f64,
    ended_ns: u64,
    exit_at_end: bool,
    end_hold_ns: u64,
    prev_v: f64,
    applied: f64,
    io_errors: u64,
    can_tx: u64,
    can_rx: u64,
    /// This cycle's drained frames, checked after the clock is read.
    rx_buf: [CanFrame; MAX_RX_PER_CYCLE],
    seq: u64,
    truth: GroundTruth,
    status: Arc<PlantStatus>,
}

fn divider(cycle_ms: u32, rate_hz: f64) -> u64 {
    ((f64::from(cycle_ms) * 1e-3 * rate_hz).round() as u64).max(1)
}

impl PlantSim {
    /// A simulator of `scenario` (roads resolved against `roads`) with the
    /// vehicle and sensor models, configured by `cfg` (rate, timeout, start,
    /// end, seed, sub-step).
    pub fn new(
        cfg: &PlantSimConfig,
        scenario: Scenario,
        roads: RoadCatalogue,
        vehicle: &VehicleParams,
        sensors: &SensorParams,
    ) -> Result<Self, PlantSimError> {
        let dt = 1.0 / cfg.rate_hz;
        let pre_roll_n = vehicle.pre_roll_cycles(scenario.v0, dt);
        let init = PlantState {
            x: -(pre_roll_n as f64) * scenario.v0 * dt,
            ..PlantState::rolling(scenario.v0, vehicle.r)
        };
        let mut plant = Plant::new(*vehicle, init)
            .map_err(|e| PlantSimError::Invalid(e.prefixed("vehicle")))?;
        plant.set_max_substep(cfg.max_substep_s).map_err(|_| {
            PlantSimError::Invalid(InvalidField::new("max_substep_s", "must be > 0"))
        })?;
        let sp = SensorParams {
            delay_samples: 0,
            ..*sensors
        };
        let sensors = Sensors::new(sp, cfg.seed)
            .map_err(|e| PlantSimError::Invalid(e.prefixed("sensors")))?;
        for (i, s) in scenario.segments.iter().enumerate() {
            if roads.by_index(s.road).is_none() {
                return Err(PlantSimError::Invalid(InvalidField::new(
                    format!("segment[{i}].road"),
                    format!("road index {} not in the catalogue", s.road),
                )));
            }
        }
        // a scenario read by `grip_config` was checked so already
        // (`Scenario::check_for`); one built otherwise is checked here
        scenario
            .check_mic_lead(vehicle.mic_lead_m)
            .map_err(|e| PlantSimError::Invalid(e.prefixed("scenario")))?;
        let names = roads.iter().map(|r| name_to_bytes(r.name())).collect();
        Ok(Self {
            mic_lead: vehicle.mic_lead_m,
            pre_roll_n,
            pre_roll_k: 0,
            names,
            plant,
            sensors,
            r_ref: vehicle.ref_radius(),
            dt,
            rx: ProtocolRx::for_role(ROLE),
            tx_ws: E2eSender::new(),
            tx_ms: E2eSender::new(),
            tx_vs: E2eSender::new(),
            tx_dd: E2eSender::new(),
            div_ws: divider(WheelSpeeds::spec().cycle_ms, cfg.rate_hz),
            div_ms: divider(MotorStatus::spec().cycle_ms, cfg.rate_hz),
            div_vs: divider(VehicleSpeed::spec().cycle_ms, cfg.rate_hz),
            div_dd: divider(DriverDemand::spec().cycle_ms, cfg.rate_hz),
            k: 0,
            cmd: TorqueCommand::default(),
            cmd_ns: None,
            cmd_timeout_ns: (cfg.cmd_timeout_ms * 1e6).round() as u64,
            cmd_valid: false,
            cmd_timeouts: 0,
            enabled_streak: 0,
            start_on: cfg.start_on,
            start_commands: cfg.start_commands,
            start_requested: false,
            phase: Phase::Holding,
            t_s: 0.0,
            ended_ns: 0,
            exit_at_end: cfg.exit_at_end,
            end_hold_ns: (cfg.end_hold_ms * 1e6).round() as u64,
            prev_v: scenario.v0,
            applied: 0.0,
            io_errors: 0,
            can_tx: 0,
            can_rx: 0,
            rx_buf: [CanFrame::default(); MAX_RX_PER_CYCLE],
            seq: 0,
            truth: GroundTruth::zeroed(),
            status: Arc::new(PlantStatus::default()),
            scenario,
            roads,
        })
    }

    /// Asks for the start (SIGUSR1 in `run`); with [`StartOn::Signal`] the
    /// scenario starts once enough valid enabled commands have also arrived.
    pub fn request_start(&mut self) {
        self.start_requested = true;
    }

    /// Current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }
    /// Scenario time, s (0 until started).
    pub fn scenario_time(&self) -> f64 {
        self.t_s
    }
    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }
    /// The plant (true state).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }
    /// Torque command the inverter applied in the last cycle, N m.
    pub fn applied_torque(&self) -> f64 {
        self.applied
    }
    /// True while the inverter zeroes torque for lack of valid commands.
    pub fn cmd_timed_out(&self) -> bool {
        !self.cmd_valid
    }
    /// Command-timeout episodes (valid → timed out transitions).
    pub fn cmd_timeouts(&self) -> u64 {
        self.cmd_timeouts
    }
    /// The command receiver (E2E fault counters).
    pub fn protocol_rx(&self) -> &ProtocolRx {
        &self.rx
    }
    /// The last published ground truth.
    pub fn last_truth(&self) -> &GroundTruth {
        &self.truth
    }
    /// Status shared with the helper thread.
    pub fn status(&self) -> Arc<PlantStatus> {
        Arc::clone(&self.status)
    }

    fn send<B: CanBus>(&mut self, bus: &mut B, f: &CanFrame) {
        if bus.send(f).is_ok() {
            self.can_tx += 1;
        } else {
            self.io_errors += 1;
        }
    }

    /// CAN frames sent successfully.
    pub fn can_tx(&self) -> u64 {
        self.can_tx
    }

    /// CAN frames received (accepted or rejected).
    pub fn can_rx(&self) -> u64 {
        self.can_rx
    }

    /// CAN send/receive errors.
    pub fn io_errors(&self) -> u64 {
        self.io_errors
    }

    /// One cycle at `tick` (see the module docs). Allocation-free.
    pub fn cycle<B: CanBus, T: TruthSink, C: Clock>(
        &mut self,
        tick: &PlantTick,
        clock: &C,
        bus: &mut B,
        truth: &mut T,
    ) -> Outcome {
        // 1. commands: drain, then read the clock, so that a command that
        // arrived while the thread was preempted before the drain is never
        // stamped earlier than it arrived (the command timeout would fire
        // that much early)
        let d = drain(bus, &mut self.rx_buf);
        self.can_rx += d.frames as u64;
        if d.error {
            self.io_errors += 1;
        }
        let now = clock.now_ns();
        for i in 0..d.frames {
            let f = self.rx_buf[i];
            if let Ok(Some(InverterMsg::TorqueCommand(c))) = self.rx.receive(&f, now) {
                self.cmd = c;
                self.cmd_ns = Some(now);
                if c.enable {
                    self.enabled_streak = self.enabled_streak.saturating_add(1);
                } else {
                    self.enabled_streak = 0;
                }
            }
        }
        self.rx.poll_timeouts(now);

        // 2. inverter command timeout
        let valid = self
            .cmd_ns
            .is_some_and(|t| now.saturating_sub(t) <= self.cmd_timeout_ns);
        if self.cmd_valid && !valid {
            self.cmd_timeouts += 1;
        }
        if !valid {
            self.enabled_streak = 0;
        }
        self.cmd_valid = valid;

        // 3. start
        if self.phase == Phase::Holding {
            let enough = self.enabled_streak >= self.start_commands;
            let go = match self.start_on {
                StartOn::Signal => self.start_requested && enough,
                StartOn::Commands => enough,
                StartOn::Immediate => true,
            };
            if go {
                self.t_s = 0.0;
                self.phase = if self.pre_roll_n > 0 {
                    Phase::PreRoll
                } else {
                    Phase::Running
                };
            }
        }

        // 4. plant
        let step = self.dt * (1 + tick.skipped) as f64;
        let state = *self.plant.state();
        let seg = self.scenario.segment_at(self.t_s, state.x);
        let road_idx = self.scenario.segments[seg].road;
        let demand = if self.phase == Phase::Running {
            self.scenario.demand_at(self.t_s)
        } else {
            0.0
        };
        let cmd_torque = if valid && self.cmd.enable {
            self.cmd.torque_request
        } else {
            0.0
        };
        self.applied = match self.phase {
            Phase::Running => cmd_torque,
            Phase::Holding | Phase::PreRoll | Phase::Ended => 0.0,
        };
        if self.phase == Phase::PreRoll {
            // kinematic: rolling at v0 without slip, only x advances; the
            // last pre-roll cycle puts the car exactly at x = 0 and starts
            // the scenario clock (its first step is the next cycle's)
            self.pre_roll_k = (self.pre_roll_k + 1 + tick.skipped).min(self.pre_roll_n);
            let left = (self.pre_roll_n - self.pre_roll_k) as f64;
            let held = PlantState {
                x: -left * self.scenario.v0 * self.dt,
                ..state
            };
            // x is finite and the rest is the state the plant accepted
            let _ = self.plant.set_state(held);
            if self.pre_roll_k == self.pre_roll_n {
                self.phase = Phase::Running;
                self.t_s = 0.0;
            }
        } else if self.phase != Phase::Holding {
            let grade = self.scenario.segments[seg].grade_rad();
            self.plant
                .step(step, self.applied, &self.roads[road_idx], grade);
            if self.phase == Phase::Running {
                self.t_s += step;
                if self.t_s >= self.scenario.duration - 1e-9 {
                    self.phase = Phase::Ended;
                    self.ended_ns = now;
                }
            }
        }
        let s = *self.plant.state();

        // 5. sensors and frames
        let reading = self.sensors.sample(&s, step);
        let ws = WheelSpeeds {
            driven_valid: true,
            ref_valid: reading.v.is_some(),
            omega_driven: reading.omega,
            omega_ref: reading.v.map_or(0.0, |v| v / self.r_ref),
        };
        if self.k.is_multiple_of(self.div_ws) {
            let f = self.tx_ws.encode(&ws, now);
            self.send(bus, &f);
        }
        let timed_out = !valid;
        let ms = MotorStatus {
            ready: true,
            fault: timed_out,
            // the vehicle file's power limit cut the command (never without one)
            derating: self.plant.derating(),
            cmd_timeout: timed_out,
            torque_actual: reading.torque,
            motor_speed: reading.omega,
            fault_code: if timed_out { FAULT_CMD_TIMEOUT } else { 0 },
        };
        if self.k.is_multiple_of(self.div_ms) {
            let f = self.tx_ms.encode(&ms, now);
            self.send(bus, &f);
        }
        if self.k.is_multiple_of(self.div_vs) {
            let dt_vs = self.dt * self.div_vs as f64;
            let vs = VehicleSpeed {
                valid: reading.v.is_some(),
                speed: reading.v.unwrap_or(0.0),
                long_accel: (s.v - self.prev_v) / dt_vs,
            };
            self.prev_v = s.v;
            let f = self.tx_vs.encode(&vs, now);
            self.send(bus, &f);
        }
        if self.k.is_multiple_of(self.div_dd) {
            let dd = DriverDemand {
                brake_pressed: false,
                tcs_enable: true,
                torque_demand: demand,
                pedal_position: (demand / self.plant.params().torque_max * 100.0).clamp(0.0, 100.0),
            };
            let f = self.tx_dd.encode(&dd, now);
            self.send(bus, &f);
        }
        self.k += 1;

        // 6. ground truth
        let seg = self.scenario.segment_at(self.t_s, s.x);
        let road_idx = self.scenario.segments[seg].road;
        // the microphone hears the road `mic_lead_m` ahead of the wheel
        let mic_seg = self.scenario.segment_at(self.t_s, s.x + self.mic_lead);
        let mic_idx = self.scenario.segments[mic_seg].road;
        let g = GroundTruth {
            seq: self.seq,
            stamp_ns: now,
            road_index: road_idx as u32,
            mic_road_index: mic_idx as u32,
            road_name: self.names[road_idx],
            mic_road_name: self.names[mic_idx],
            v: s.v,
            omega: s.omega,
            lambda: self.plant.lambda(),
            torque: s.torque,
            x: s.x,
        };
        truth.truth(&g);
        self.truth = g;
        self.seq += 1;

        let st = &self.status;
        st.heartbeat.store(self.seq, Ordering::Relaxed);
        st.phase.store(self.phase as u8, Ordering::Relaxed);
        st.cmd_timed_out.store(timed_out, Ordering::Relaxed);
        st.cmd_timeouts.store(self.cmd_timeouts, Ordering::Relaxed);
        st.faults_total
            .store(self.rx.faults().total(), Ordering::Relaxed);
        st.io_errors.store(self.io_errors, Ordering::Relaxed);
        st.truth_errors.store(truth.errors(), Ordering::Relaxed);

        if self.phase == Phase::Ended
            && self.exit_at_end
            && now.saturating_sub(self.ended_ns) >= self.end_hold_ns
        {
            Outcome::Finished
        } else {
            Outcome::Continue
        }
    }
}
