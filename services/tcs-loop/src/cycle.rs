//! [`TcsLoop`]: one traction-control cycle, driven by `run` at the loop rate
//! on the real clock and by the tests on a manual clock.
//!
//! A cycle, in this order:
//! 1. **Drain CAN** (non-blocking, at most [`MAX_RX_PER_CYCLE`] frames),
//!    then read the clock ("now" of the cycle, so no frame is stamped
//!    earlier than it arrived and a timeout never fires early); the bus
//!    `run` opens delivers only the ids of [`ROLE`] (foreign traffic is
//!    filtered below the loop); each frame goes through
//!    `ProtocolRx::for_role(ROLE)` (length, CRC, alive counter, unknown id;
//!    faults counted) and is held for `CAN_LOG` (direction RX,
//!    flag `E2E_REJECTED` when rejected; logged in step 5). Accepted frames
//!    update the latest `WheelSpeeds`, `MotorStatus`, `VehicleSpeed`, `DriverDemand`.
//! 2. **Road**: every `RoadEstimate` that arrived since the last cycle, in
//!    order (at most [`MAX_ROADS_PER_CYCLE`]; more wait for the next cycle):
//!    each is queued by the places it was heard at (step 4), and the newest
//!    replaces the held one; its age is `now − stamp_ns` (both
//!    CLOCK_MONOTONIC). Until 2026-12-05 the newest alone was taken, and
//!    the estimates of a burst (arte catching up after a stall) were lost
//!    to the queue: their stretches of road kept the road heard before.
//! 3. **Safe state**: inputs are valid when a `WheelSpeeds` frame with
//!    `DrivenValid` and a `MotorStatus` frame were accepted within
//!    `sensor_timeout_ms` and a `DriverDemand` frame within
//!    `demand_timeout_ms`. Invalid inputs (including none yet, at start)
//!    put the loop in its safe state; it leaves the safe state only when the
//!    inputs have been valid without interruption for `recover_ms`, and then
//!    resets the controller (its integrators are stale).
//! 4. **Control**: in the safe state the command is 0 N m with `Enable`
//!    cleared and the controller is not stepped. Otherwise the controller
//!    steps on the [`Measurement`] (ω = OmegaDriven; V = r_ref·OmegaRef
//!    when `RefValid`, r_ref the reference wheel's radius, else
//!    `VehicleSpeed` when valid and fresh, else none;
//!    T = TorqueActual; T_d = TorqueDemand, 0 while `BrakePressed`) and the
//!    road knowledge (ARTE on and an estimate held; the controller's own
//!    fallback rule `[arte]` of controllers.toml decides whether it is used).
//!    With ARTE on and [`TcsLoop::with_road_aware`] (what `run` builds), this
//!    is `grip sim`'s "with ARTE" path: each new estimate is queued in
//!    [`RoadAware`] at the odometer positions it was heard at (arte's
//!    `x_from`/`x_to`, the microphone's `mic_lead_m` added), every cycle
//!    `RoadAware::step` at the odometer gives the knowledge of the believed
//!    road and a torque cap, and the command is `min(T*, cap)`.
//!    With `TcsEnable` = 0 the demand is passed through unchanged. A
//!    non-finite controller output is sent as 0 N m.
//! 5. **Send** `TorqueCommand` (E2E counter + CRC); then copy the cycle's
//!    received frames and the command (direction TX) to `CAN_LOG`, in bus
//!    order. Nothing is published before the command is on the bus: a
//!    publish can stall while iceoryx2 (0.10) sets up the connection to a
//!    new subscriber inside its send (a recorder starting or restarting:
//!    0.1-0.2 ms natively, 10-20 ms under emulation; `grip-io`'s
//!    `subscriber_churn` bench), and that must not delay the command.
//! 6. **Publish** the `CycleRecord` (with the odometer, integral of the
//!    measured speed V, else r·ω; the cap and the believed road with ARTE;
//!    `road_taken` and `roads_taken`, the newest estimate step 2 took and
//!    how many, so that `grip replay` can hand the loop the same estimates
//!    in the same cycle).
//!
//! Nothing here allocates, blocks or logs; transitions are reported through
//! [`SharedStatus`] atomics that a non-real-time thread reads and logs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};

use grip_io::can::protocol::{
    DriverDemand, E2eSender, InverterMsg, MotorStatus, ProtocolMessage, ProtocolRx, Role,
    TorqueCommand, VehicleSpeed, WheelSpeeds,
};
use grip_io::can::{CanBus, CanFrame, drain};
use grip_io::clock::Clock;
use grip_io::rt::CycleTiming;
use grip_msgs::{CycleRecord, NAME_LEN, NO_CLASS, RoadEstimate, can_dir, can_flags, name_to_bytes};
use grip_physics::{RoadCatalogue, VehicleParams};
use grip_tcs::{
    AnyController, Controller, ControllersConfig, Measurement, RoadAware, RoadKnowledge,
};

use crate::config::SafetyConfig;
use crate::ports::{RecordSink, RoadSource};

/// The part tcs-loop plays on the bus (the DBC's `TCS`): what its
/// [`ProtocolRx`] checks and what `run` opens the bus to receive
/// (`RxFilter::Role(ROLE)`), one constant so the two cannot differ.
pub const ROLE: Role = Role::Tcs;

/// Most frames drained from the bus in one cycle (grip-io's, shared with
/// plant-sim: why 256 is written there).
pub use grip_io::can::MAX_RX_PER_CYCLE;

/// Most road estimates taken in one cycle (more wait for the next): 32,
/// more than a burst arte publishes after catching up on its default
/// `max_lag_s` of audio (20), and a bound on the cycle's work (one queue
/// push each, about 0.1 µs).
pub const MAX_ROADS_PER_CYCLE: usize = 32;

/// When a cycle runs: its deadline and actual wake-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleTick {
    /// Nominal start of the cycle (the timer's absolute deadline), ns.
    pub deadline_ns: u64,
    /// When the thread actually woke, ns.
    pub woke_ns: u64,
    /// Deadline misses since start (from the timer).
    pub deadline_misses: u64,
}

impl CycleTick {
    /// From the periodic timer's report and its miss count.
    pub fn from_timing(t: &CycleTiming, deadline_misses: u64) -> Self {
        Self {
            deadline_ns: t.deadline_ns,
            woke_ns: t.woke_ns,
            deadline_misses,
        }
    }
    /// A cycle woken exactly at its deadline `t_ns` (tests).
    pub fn at(t_ns: u64) -> Self {
        Self {
            deadline_ns: t_ns,
            woke_ns: t_ns,
            deadline_misses: 0,
        }
    }
}

/// Why the loop's inputs were invalid: bits of
/// [`SharedStatus::safe_cause`].
pub struct SafeCause;

impl SafeCause {
    /// No fresh `WheelSpeeds` frame with `DrivenValid` valid.
    pub const WHEEL_SPEED: u8 = 1;
    /// No fresh `MotorStatus` frame.
    pub const MOTOR_STATUS: u8 = 2;
    /// The inverter's `MotorStatus` reports `Fault` (it has zeroed, or
    /// will not deliver, the torque: the controller's state would wind up
    /// on a torque that is not there).
    pub const INVERTER_FAULT: u8 = 4;
    /// No fresh `DriverDemand` frame.
    pub const DEMAND: u8 = 8;
    /// With [`Self::INVERTER_FAULT`]: the `MotorStatus` also reports
    /// `CmdTimeout`, i.e. this loop's commands stopped reaching the inverter
    /// (a stall of the loop, or of the bus), not a fault of the inverter's own.
    pub const INVERTER_CMD_TIMEOUT: u8 = 16;

    /// The causes in `bits`, in words, for the transition log.
    pub fn describe(bits: u8, fault_code: u8) -> String {
        let mut parts = Vec::new();
        if bits & Self::WHEEL_SPEED != 0 {
            parts.push("wheel-speed frames missing or invalid".to_owned());
        }
        if bits & Self::MOTOR_STATUS != 0 {
            parts.push("motor-status frames missing".to_owned());
        }
        if bits & Self::INVERTER_FAULT != 0 {
            parts.push(if bits & Self::INVERTER_CMD_TIMEOUT != 0 {
                format!(
                    "the inverter reports Fault (FaultCode 0x{fault_code:02X}) with its command timeout: this loop's commands stopped reaching it (a stall of the loop or of the bus)"
                )
            } else {
                format!("the inverter reports Fault (FaultCode 0x{fault_code:02X})")
            });
        }
        if bits & Self::DEMAND != 0 {
            parts.push("driver-demand frames missing".to_owned());
        }
        if parts.is_empty() {
            "inputs invalid".to_owned()
        } else {
            parts.join(", ")
        }
    }
}

/// Loop state published for the non-real-time helper thread (watchdog,
/// transition logging). Written with relaxed stores every cycle.
#[derive(Debug, Default)]
pub struct SharedStatus {
    /// Cycles completed (the watchdog heartbeat).
    pub heartbeat: AtomicU64,
    /// In the safe state now.
    pub safe_state: AtomicBool,
    /// Times the safe state was entered.
    pub safe_entries: AtomicU64,
    /// Why the inputs were invalid in the last cycle that found them so
    /// ([`SafeCause`] bits; kept while they are valid again, so the
    /// transition log can name the cause of the entry it reports).
    pub safe_cause: AtomicU8,
    /// The inverter's `FaultCode` in the last cycle whose `MotorStatus`
    /// reported `Fault`.
    pub inverter_fault_code: AtomicU8,
    /// The controller used ARTE's knowledge in the last cycle.
    pub used_arte: AtomicBool,
    /// Road estimates received so far.
    pub road_estimates: AtomicU64,
    /// Sum of all E2E faults so far.
    pub faults_total: AtomicU64,
    /// CAN send/receive errors so far.
    pub bus_errors: AtomicU64,
    /// Deadline misses so far.
    pub deadline_misses: AtomicU64,
    /// The controller passed the driver's demand through in the last
    /// cycle for want of a measurement (SRC without a vehicle speed).
    pub passthrough: AtomicBool,
    /// The SocketCAN interface is gone (deleted, unplugged): its socket
    /// unbound, waiting for it to be back (set by `run` after each cycle).
    pub bus_gone: AtomicBool,
    /// Times the SocketCAN socket was reopened on a re-created interface.
    pub bus_reopens: AtomicU64,
}

/// Errors building the loop.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// The controller or the road knowledge rejected its parameters (field
    /// named).
    #[error("controller parameters: field `{field}`: {reason}")]
    Controller {
        /// Offending field.
        field: String,
        /// Why.
        reason: String,
    },
}

/// The traction-control loop's state. Build once; [`cycle`](Self::cycle)
/// allocates nothing.
#[derive(Debug)]
pub struct TcsLoop {
    controller: AnyController,
    arte: bool,
    /// Road knowledge tied to places (ARTE on, built by
    /// [`TcsLoop::with_road_aware`]): the preview queue, the road belief and
    /// the torque cap, the same code as `grip sim`'s.
    aware: Option<RoadAware>,
    /// Catalogue road names, to map an estimate's class name to the
    /// catalogue index `aware` uses.
    road_names: Vec<[u8; NAME_LEN]>,
    /// Integral of the measured vehicle speed since start, m.
    odometer: f64,
    /// The previous cycle's deadline, ns: periods skipped after a stall
    /// (the timer skips them, it never bursts) still count on the
    /// odometer.
    last_deadline_ns: Option<u64>,
    dt: f64,
    r: f64,
    /// The non-driven reference wheel's rolling radius (`r_ref`, else `r`):
    /// V = r_ref · OmegaRef.
    r_ref: f64,
    /// `[preview] standstill_mps`: below it the odometer stands.
    standstill_mps: f64,
    sensor_timeout_ns: u64,
    demand_timeout_ns: u64,
    vspeed_timeout_ns: u64,
    recover_ns: u64,
    rx: ProtocolRx,
    tx: E2eSender<TorqueCommand>,
    /// The bus number the commands are sent on (`can.toml`'s `bus_id`,
    /// the bus stamps what it receives with the same): written into every
    /// command the loop sends and logs ([`TcsLoop::with_bus_id`]).
    bus_id: u8,
    t0_ns: Option<u64>,
    ws: Option<(WheelSpeeds, u64)>,
    ms: Option<(MotorStatus, u64)>,
    vs: Option<(VehicleSpeed, u64)>,
    dd: Option<(DriverDemand, u64)>,
    road: Option<RoadEstimate>,
    safe: bool,
    valid_since_ns: Option<u64>,
    safe_entries: u64,
    bus_errors: u64,
    can_tx: u64,
    can_rx: u64,
    seq: u64,
    record: CycleRecord,
    /// This cycle's received frames, held for `CAN_LOG` until the command
    /// is on the bus (step 5): publishing can stall (a new subscriber's
    /// connection is set up inside iceoryx2's send), the command must not.
    rx_log: [CanFrame; MAX_RX_PER_CYCLE],
    rx_log_len: usize,
    status: Arc<SharedStatus>,
}

impl TcsLoop {
    /// A loop running `kind` with `controllers` parameters for `vehicle`
    /// at `controllers.loop_.rate_hz`, with or without ARTE.
    pub fn new(
        kind: grip_tcs::ControllerKind,
        arte: bool,
        controllers: &ControllersConfig,
        vehicle: &VehicleParams,
        safety: &SafetyConfig,
    ) -> Result<Self, LoopError> {
        let controller = AnyController::new(kind, controllers, vehicle, controllers.loop_.dt())
            .map_err(|e| LoopError::Controller {
                field: e.field,
                reason: e.reason,
            })?;
        let mut rx = ProtocolRx::for_role(ROLE);
        for (id, t) in [
            (WheelSpeeds::spec().id, safety.sensor_timeout_ns()),
            (MotorStatus::spec().id, safety.sensor_timeout_ns()),
            (DriverDemand::spec().id, safety.demand_timeout_ns()),
        ] {
            if let Some(r) = rx.receiver_mut(id) {
                *r = r.clone().with_timeout_ns(t);
            }
        }
        Ok(Self {
            controller,
            arte,
            aware: None,
            road_names: Vec::new(),
            odometer: 0.0,
            last_deadline_ns: None,
            dt: controllers.loop_.dt(),
            standstill_mps: controllers.preview.standstill_mps,
            r: vehicle.r,
            r_ref: vehicle.ref_radius(),
            sensor_timeout_ns: safety.sensor_timeout_ns(),
            demand_timeout_ns: safety.demand_timeout_ns(),
            vspeed_timeout_ns: u64::from(VehicleSpeed::spec().timeout_ms) * 1_000_000,
            recover_ns: safety.recover_ns(),
            rx,
            tx: E2eSender::new(),
            bus_id: 0,
            t0_ns: None,
            ws: None,
            ms: None,
            vs: None,
            dd: None,
            road: None,
            safe: true,
            valid_since_ns: None,
            safe_entries: 0,
            bus_errors: 0,
            can_tx: 0,
            can_rx: 0,
            seq: 0,
            record: CycleRecord::zeroed(),
            rx_log: [CanFrame::default(); MAX_RX_PER_CYCLE],
            rx_log_len: 0,
            status: Arc::new(SharedStatus {
                safe_state: AtomicBool::new(true),
                ..SharedStatus::default()
            }),
        })
    }

    /// Sends (and logs) its commands as frames of bus `bus_id`
    /// (`can.toml`'s `bus_id`, which [`crate::build`] gives it: the bus
    /// the service opens stamps the frames it receives with the same), so
    /// the CAN log's sent and received frames carry one bus number. Without
    /// it: 0.
    pub fn with_bus_id(mut self, bus_id: u8) -> Self {
        self.bus_id = bus_id;
        self
    }

    /// The bus number written into the commands ([`TcsLoop::with_bus_id`]).
    pub fn bus_id(&self) -> u8 {
        self.bus_id
    }

    /// With ARTE on, the "with ARTE" behaviour of `grip sim`: road
    /// knowledge from [`RoadAware`] for `roads` (its `[arte]`, `[preview]`,
    /// `[fusion]` of `controllers`, the road table and the vehicle's
    /// `mic_lead_m`), decisions queued where they were heard, the torque
    /// capped to what the road allows. Without ARTE nothing changes.
    pub fn with_road_aware(
        mut self,
        roads: &RoadCatalogue,
        table: grip_tcs::RoadTable,
        controllers: &ControllersConfig,
        vehicle: &VehicleParams,
    ) -> Result<Self, LoopError> {
        if !self.arte {
            return Ok(self);
        }
        let aware = RoadAware::new(
            self.controller.kind(),
            roads,
            table,
            vehicle,
            controllers,
            self.dt,
        )
        .map_err(|e| LoopError::Controller {
            field: e.field,
            reason: e.reason,
        })?;
        self.road_names = roads.iter().map(|r| name_to_bytes(r.name())).collect();
        self.aware = Some(aware);
        Ok(self)
    }

    /// Whether the road knowledge of [`TcsLoop::with_road_aware`] is in use.
    pub fn road_aware(&self) -> bool {
        self.aware.is_some()
    }

    /// The odometer: integral of the measured vehicle speed since start, m.
    pub fn odometer(&self) -> f64 {
        self.odometer
    }

    /// Queues estimate `e` in the road knowledge at the odometer positions
    /// it was heard at (arte's `x_from`/`x_to`; when arte had no fresh cycle
    /// record, this loop's odometer at the frame's times). Allocation-free.
    fn queue_estimate(&mut self, e: &RoadEstimate, now: u64, t0: u64, v: f64) {
        let Some(aware) = self.aware.as_mut() else {
            return;
        };
        let Some(road) = self.road_names.iter().position(|n| *n == e.class_name) else {
            return;
        };
        // a confidence that is no number is no decision
        if !e.confidence.is_finite() {
            return;
        }
        let (x_from, x_to) = if e.x_from.is_finite() && e.x_to.is_finite() {
            (e.x_from, e.x_to)
        } else {
            let ago = |t: u64| {
                if t == 0 || t > now {
                    0.0
                } else {
                    (now - t) as f64 * 1e-9
                }
            };
            (
                self.odometer - v * ago(e.frame_t0_ns),
                self.odometer - v * ago(e.frame_t1_ns),
            )
        };
        // a stamp ahead of this loop's clock (a clock fault) counts as
        // taken now: it must not keep a stream alive that has stopped
        let stamp = (e.stamp_ns.min(now) as i128 - t0 as i128) as f64 * 1e-9;
        aware.decision(road, e.confidence.clamp(0.0, 1.0), stamp, x_from, x_to);
    }

    /// The status shared with the helper thread.
    pub fn status(&self) -> Arc<SharedStatus> {
        Arc::clone(&self.status)
    }

    /// Which controller runs.
    pub fn controller_kind(&self) -> grip_tcs::ControllerKind {
        self.controller.kind()
    }

    /// ARTE on.
    pub fn arte(&self) -> bool {
        self.arte
    }

    /// In the safe state.
    pub fn in_safe_state(&self) -> bool {
        self.safe
    }

    /// Times the safe state was entered from normal operation (the loop
    /// also *starts* in the safe state; that is not counted).
    pub fn safe_entries(&self) -> u64 {
        self.safe_entries
    }

    /// The receive side (fault counters per message).
    pub fn protocol_rx(&self) -> &ProtocolRx {
        &self.rx
    }

    /// The last published record.
    pub fn last_record(&self) -> &CycleRecord {
        &self.record
    }

    fn fresh<T: Copy>(v: &Option<(T, u64)>, now: u64, timeout: u64) -> Option<T> {
        match v {
            Some((m, t)) if now.saturating_sub(*t) <= timeout => Some(*m),
            _ => None,
        }
    }

    /// Checks the drained frame `rx_log[i]` at `now` (flags it when the
    /// E2E check rejects it) and keeps its content when accepted.
    fn on_frame(&mut self, i: usize, now: u64) {
        let frame = &mut self.rx_log[i];
        frame.direction = can_dir::RX;
        match self.rx.receive(frame, now) {
            Ok(Some(msg)) => match msg {
                InverterMsg::WheelSpeeds(m) => {
                    // a frame saying the driven wheel speed is invalid is no
                    // valid sensor frame: it does not refresh the timeout
                    if m.driven_valid {
                        self.ws = Some((m, now));
                    }
                }
                InverterMsg::MotorStatus(m) => self.ms = Some((m, now)),
                InverterMsg::VehicleSpeed(m) => self.vs = Some((m, now)),
                InverterMsg::DriverDemand(m) => self.dd = Some((m, now)),
                InverterMsg::TorqueCommand(_) => {}
            },
            Ok(None) => {}
            Err(_) => frame.flags |= can_flags::E2E_REJECTED,
        }
    }

    /// One cycle at `tick` (see the module docs). `clock` gives "now" for
    /// E2E timeouts and the road estimate's age, and the compute time.
    /// Returns the published record. Allocation-free.
    pub fn cycle<B: CanBus, R: RoadSource, S: RecordSink, C: Clock>(
        &mut self,
        tick: &CycleTick,
        clock: &C,
        bus: &mut B,
        road: &mut R,
        sink: &mut S,
    ) -> &CycleRecord {
        let t0 = *self.t0_ns.get_or_insert(tick.deadline_ns);

        // 1. drain CAN (at most MAX_RX_PER_CYCLE frames, held for the log),
        // then read the clock: every frame drained is stamped no earlier
        // than it reached the socket, so a timeout cannot fire before
        // `timeout_ms` after the last frame's arrival (a clock read before
        // the drain stamped a frame that arrived while the thread was
        // preempted up to that long too early)
        let d = drain(bus, &mut self.rx_log);
        self.rx_log_len = d.frames;
        self.can_rx += d.frames as u64;
        if d.error {
            self.bus_errors += 1;
        }
        let now = clock.now_ns();
        for i in 0..self.rx_log_len {
            self.on_frame(i, now);
        }
        // counts timeout episodes into the E2E fault counters
        self.rx.poll_timeouts(now);

        // measured vehicle speed (V = r_ref·OmegaRef when valid, r_ref the
        // reference wheel's radius, not the driven tyre's r; else the
        // VehicleSpeed frame when valid and fresh), from fresh frames only:
        // a wheel-speed frame older than `sensor_timeout_ms` is no
        // measurement (the loop is then in its safe state; its record says
        // V unknown, and the odometer does not run on a frozen speed)
        let ws = Self::fresh(&self.ws, now, self.sensor_timeout_ns);
        let omega = ws.map_or(0.0, |w| w.omega_driven);
        let v = match ws {
            Some(w) if w.ref_valid => Some(self.r_ref * w.omega_ref),
            _ => Self::fresh(&self.vs, now, self.vspeed_timeout_ns)
                .filter(|s| s.valid)
                .map(|s| s.speed),
        };
        // the odometer's speed: V, else the wheel's r·ω (as grip sim)
        let v_odo = grip_tcs::odometer_speed(v, omega, self.r, self.standstill_mps);
        // periods the timer skipped since the last cycle (a stall): the car
        // moved on meanwhile, at about this speed
        if let Some(prev) = self.last_deadline_ns {
            let periods = tick.deadline_ns.saturating_sub(prev) as f64 * 1e-9 / self.dt;
            let skipped = periods.round() - 1.0;
            if skipped >= 1.0 {
                self.odometer += v_odo * self.dt * skipped;
            }
        }
        self.last_deadline_ns = Some(tick.deadline_ns);

        // 2. road estimates: every one that arrived, in order (each says
        // what lies on its own stretch of the path); the newest is held
        let mut road_taken = 0;
        let mut roads_taken = 0u8;
        while usize::from(roads_taken) < MAX_ROADS_PER_CYCLE {
            let Some(e) = road.poll_next() else { break };
            road_taken = (e.seq as u32).wrapping_add(1);
            roads_taken += 1;
            self.road = Some(e);
            self.status.road_estimates.fetch_add(1, Ordering::Relaxed);
            if e.class_index != NO_CLASS {
                self.queue_estimate(&e, now, t0, v_odo);
            }
        }

        // 3. safe state
        let ms = Self::fresh(&self.ms, now, self.sensor_timeout_ns);
        let dd = Self::fresh(&self.dd, now, self.demand_timeout_ns);
        // an inverter that reports a fault has zeroed (or will not deliver)
        // the torque: the controller is not stepped on a torque that is not
        // there, and is reset once the fault has been gone for recover_ms
        let inverter_fault = ms.is_some_and(|m| m.fault);
        let inputs_ok = ws.is_some() && ms.is_some() && !inverter_fault && dd.is_some();
        if !inputs_ok {
            let bit = |on: bool, b: u8| if on { b } else { 0 };
            let cause = bit(ws.is_none(), SafeCause::WHEEL_SPEED)
                | bit(ms.is_none(), SafeCause::MOTOR_STATUS)
                | bit(inverter_fault, SafeCause::INVERTER_FAULT)
                | bit(dd.is_none(), SafeCause::DEMAND)
                | bit(
                    ms.is_some_and(|m| m.fault && m.cmd_timeout),
                    SafeCause::INVERTER_CMD_TIMEOUT,
                );
            self.status.safe_cause.store(cause, Ordering::Relaxed);
            if let Some(m) = ms.filter(|m| m.fault) {
                self.status
                    .inverter_fault_code
                    .store(m.fault_code, Ordering::Relaxed);
            }
        }
        if inputs_ok {
            self.valid_since_ns.get_or_insert(now);
        } else {
            self.valid_since_ns = None;
            if !self.safe {
                self.safe = true;
                self.safe_entries += 1;
            }
        }
        if self.safe
            && let Some(since) = self.valid_since_ns
            && now.saturating_sub(since) >= self.recover_ns
        {
            self.safe = false;
            self.controller.reset();
            // the road knowledge is kept: the decisions queued so far are
            // places ahead of the wheel that the microphone heard (`reset`
            // at this point left the wheel without acoustic knowledge for
            // its first `mic_lead_m` metres, and the slip evidence alone
            // then settled on ice at the start of a drive)
        }

        // 4. measurement and control
        let torque = self.ms.map_or(0.0, |(m, _)| m.torque_actual);
        let (demand, tcs_enable) = match self.dd {
            Some((d, _)) if d.brake_pressed => (0.0, d.tcs_enable),
            Some((d, _)) => (d.torque_demand, d.tcs_enable),
            None => (0.0, true),
        };
        let knowledge = match (self.arte, &self.road) {
            (true, Some(e)) => Some(RoadKnowledge {
                lambda_opt: e.lambda_opt,
                mu_peak: e.mu_peak,
                alpha: e.alpha,
                confidence: e.confidence,
                // negative when the stamp is in the future: the fallback
                // rule rejects it
                age: (now as i128 - e.stamp_ns as i128) as f64 / 1e9,
            }),
            _ => None,
        };
        let mut rec = CycleRecord::zeroed();
        let (cmd, enable) = if self.safe {
            self.status.passthrough.store(false, Ordering::Relaxed);
            rec.internal = f64::NAN;
            rec.mu_hat = f64::NAN;
            (0.0, false)
        } else {
            let m = Measurement {
                t: tick.deadline_ns.saturating_sub(t0) as f64 * 1e-9,
                omega,
                v,
                torque,
                demand,
            };
            let out = match self.aware.as_mut() {
                Some(aware) => {
                    let (g, out) = aware.control(&mut self.controller, &m, self.odometer);
                    rec.belief_road = g.belief.0 as u32;
                    rec.belief_prob = g.belief.1;
                    if g.torque_cap.is_finite() {
                        rec.torque_cap = g.torque_cap;
                    }
                    out
                }
                None => self.controller.step(&m, knowledge.as_ref()),
            };
            rec.internal = out.internal;
            rec.mu_hat = out.mu_hat;
            rec.used_arte = u8::from(out.used_arte);
            self.status
                .passthrough
                .store(out.passthrough, Ordering::Relaxed);
            if out.used_arte {
                rec.road_class = self.road.map_or(NO_CLASS, |e| e.class_index);
            }
            let cmd = if tcs_enable { out.torque_cmd } else { demand };
            (if cmd.is_finite() { cmd } else { 0.0 }, true)
        };

        // 5. send the command
        let frame = self.command(
            &TorqueCommand {
                torque_request: cmd,
                enable,
            },
            now,
        );
        self.send(bus, &frame);
        // then the log: this cycle's received frames and the command, in
        // bus order
        for f in &self.rx_log[..self.rx_log_len] {
            sink.can(f);
        }
        self.rx_log_len = 0;
        sink.can(&frame);

        // 6. record
        let done = clock.now_ns();
        rec.seq = self.seq;
        rec.stamp_ns = tick.deadline_ns;
        // the difference, saturated (a replayed tick is a log's; the
        // timer's differ by a wake-up latency)
        rec.wakeup_latency_ns = (i128::from(tick.woke_ns) - i128::from(tick.deadline_ns))
            .clamp(i64::MIN.into(), i64::MAX.into()) as i64;
        rec.compute_ns = done.saturating_sub(tick.woke_ns);
        rec.deadline_misses = tick.deadline_misses;
        rec.omega = omega;
        rec.v = v.unwrap_or(f64::NAN);
        rec.v_valid = u8::from(v.is_some());
        rec.torque = torque;
        rec.demand = demand;
        rec.torque_cmd = cmd;
        rec.safe_state = u8::from(self.safe);
        rec.faults = self.rx.faults();
        rec.odometer = self.odometer;
        rec.road_taken = road_taken;
        rec.roads_taken = roads_taken;
        sink.cycle(&rec);
        self.odometer += v_odo * self.dt;
        self.record = rec;
        self.seq += 1;

        let s = &self.status;
        s.heartbeat.store(self.seq, Ordering::Relaxed);
        s.safe_state.store(self.safe, Ordering::Relaxed);
        s.safe_entries.store(self.safe_entries, Ordering::Relaxed);
        s.used_arte.store(rec.used_arte != 0, Ordering::Relaxed);
        s.faults_total.store(rec.faults.total(), Ordering::Relaxed);
        s.bus_errors.store(self.bus_errors, Ordering::Relaxed);
        s.deadline_misses
            .store(tick.deadline_misses, Ordering::Relaxed);
        &self.record
    }

    /// Stop: sends 0 N m with `Enable` cleared (and logs the frame), so the
    /// inverter drops torque at once instead of after its command timeout.
    /// Returns whether the frame went out (not when the bus is gone or
    /// down: the inverter's own command timeout then drops the torque).
    pub fn shutdown<B: CanBus, S: RecordSink>(
        &mut self,
        now_ns: u64,
        bus: &mut B,
        sink: &mut S,
    ) -> bool {
        let frame = self.command(
            &TorqueCommand {
                torque_request: 0.0,
                enable: false,
            },
            now_ns,
        );
        let sent = self.send(bus, &frame);
        sink.can(&frame);
        sent
    }

    /// The next command frame (alive counter advanced), of this loop's bus.
    fn command(&mut self, cmd: &TorqueCommand, now_ns: u64) -> CanFrame {
        let mut frame = self.tx.encode(cmd, now_ns);
        frame.bus = self.bus_id;
        frame
    }

    /// Sends `frame`, counting it or the error; whether it went out.
    fn send<B: CanBus>(&mut self, bus: &mut B, frame: &CanFrame) -> bool {
        if bus.send(frame).is_ok() {
            self.can_tx += 1;
            true
        } else {
            self.bus_errors += 1;
            false
        }
    }

    /// CAN frames sent successfully (every cycle's command and the shutdown frame).
    pub fn can_tx(&self) -> u64 {
        self.can_tx
    }

    /// CAN frames received from the bus (accepted or rejected).
    pub fn can_rx(&self) -> u64 {
        self.can_rx
    }

    /// CAN send/receive errors.
    pub fn bus_errors(&self) -> u64 {
        self.bus_errors
    }
}
