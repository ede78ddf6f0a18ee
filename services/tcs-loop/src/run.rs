//! [`run`]: loads the configuration, opens the real ports, applies the
//! real-time set-up and runs [`TcsLoop`] on the absolute-deadline timer
//! until the stop flag is set.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use grip_config::{ConfigDir, ConfigError, load_controllers};
use grip_io::can::{CanBus, CanBusConfig, CanError, RxFilter, open_bus};
use grip_io::clock::{Clock, MonotonicClock};
use grip_io::ipc::{IpcError, IpcNode};
use grip_io::rt::{self, LatencyHistogram, PeriodicTimer};
use grip_io::service::monitor::HelperError;
use grip_io::service::{ConfigArgs, ServiceConfig, load_can};
use grip_msgs::topics;
use grip_tcs::ControllerKind;

use crate::config::TcsLoopConfig;
use crate::cycle::{CycleTick, LoopError, TcsLoop};
use crate::monitor;
use crate::ports::{Ports, open_ports};

/// Command-line choices (see `main.rs` for the flags).
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config-dir` and `--config`.
    pub config: ConfigArgs,
    /// `--controller` override.
    pub controller: Option<ControllerKind>,
    /// `--arte on|off` override.
    pub arte: Option<bool>,
    /// Stop by itself after this many seconds (benchmarks).
    pub run_for_s: Option<f64>,
    /// `--vehicle FILE` (default `<config-dir>/vehicle.toml`).
    pub vehicle: Option<PathBuf>,
}

/// Fatal start-up errors.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A configuration file is wrong (file, field, reason).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The controller rejected its parameters.
    #[error("{file}: {error}")]
    Loop {
        /// controllers.toml
        file: PathBuf,
        /// The error (said in the message, not returned as the source:
        /// a chain printed in full would say it twice).
        error: LoopError,
    },
    /// iceoryx2.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The CAN bus could not be opened.
    #[error(transparent)]
    Can(#[from] CanError),
    /// The helper thread could not be started.
    #[error(transparent)]
    Helper(#[from] HelperError),
}

impl grip_io::service::ServiceError for RunError {
    fn is_config(&self) -> bool {
        matches!(self, Self::Config(_) | Self::Loop { .. })
    }
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct RunSummary {
    /// Cycles run.
    pub cycles: u64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Wake-up latency histogram.
    pub latency: LatencyHistogram,
    /// Wake-ups later than 1 ms after their deadline.
    pub late_1ms: u64,
    /// Safe-state entries (from normal operation).
    pub safe_entries: u64,
    /// E2E faults at the end.
    pub faults_total: u64,
    /// Whether SCHED_FIFO was applied.
    pub fifo: bool,
    /// Whether cpu_dma_latency was held at 0.
    pub dma_latency: bool,
}

/// The files a run reads.
#[derive(Debug, Clone)]
pub struct LoadedConfig {
    /// The service's own TOML.
    pub own: TcsLoopConfig,
    /// `controllers.toml`.
    pub controllers: grip_tcs::ControllersConfig,
    /// `vehicle.toml` `[vehicle]`.
    pub vehicle: grip_physics::VehicleParams,
    /// `vehicle.toml` `[sensors]`: the car's sensors as the file states
    /// them (the loop reads its measurements from CAN; this is what the
    /// start-up check of the road belief's slip noise takes).
    pub sensors: grip_physics::SensorParams,
    /// `can.toml`.
    pub can: CanBusConfig,
    /// `roads.toml`.
    pub roads: grip_physics::RoadCatalogue,
    /// The road-knowledge table (roads.toml + `[knowledge]` of arte-svc.toml).
    pub road_table: grip_tcs::RoadTable,
    /// Path of the vehicle file (for error messages).
    pub vehicle_path: PathBuf,
    /// Path of `controllers.toml` (for error messages).
    pub controllers_path: PathBuf,
    /// Path of the service's own TOML.
    pub own_path: PathBuf,
}

/// Loads and validates every file the service needs, applying the overrides.
pub fn load(opts: &Options) -> Result<LoadedConfig, ConfigError> {
    load_as(opts, grip_config::VehicleUse::Offline)
}

/// [`load`], its vehicle file loaded for `vehicle_use`: for the service
/// itself, which drives a car or a rig ([`grip_config::VehicleUse::Drive`]),
/// a file that leaves a `[vehicle]` field out is refused instead of taking
/// the paper's default with a warning, as `grip replay` and `grip generate`
/// need for logs whose attached vehicle files predate a field
/// ([`grip_config::VehicleUse::Offline`]).
fn load_as(
    opts: &Options,
    vehicle_use: grip_config::VehicleUse,
) -> Result<LoadedConfig, ConfigError> {
    load_with(opts, vehicle_use, Protocol::Install).map(|(cfg, _)| cfg)
}

/// What [`load_with`] does with the bus's protocol.
enum Protocol {
    /// Installs it as the process's ([`grip_io::service::install_protocol_with`]),
    /// saying its start-up lines and what it cannot carry for the vehicle
    /// once per process: the service, and a replay's loop.
    Install,
    /// Only reads it, says nothing, and returns it: [`check`].
    Read,
}

/// [`load_as`], the protocol installed or only read (then returned).
fn load_with(
    opts: &Options,
    vehicle_use: grip_config::VehicleUse,
    protocol: Protocol,
) -> Result<(LoadedConfig, Option<grip_io::can::protocol::Protocol>), ConfigError> {
    let dir = ConfigDir::new(&opts.config.config_dir);
    let own_path = opts.config.own_file::<TcsLoopConfig>();
    let mut own = TcsLoopConfig::load(&own_path)?;
    if let Some(k) = opts.controller {
        own.controller = k.as_str().to_owned();
    }
    if let Some(a) = opts.arte {
        own.arte = a;
    }
    let controllers_path = dir.file("controllers.toml");
    let controllers = load_controllers(&controllers_path)?;
    let vehicle_path = opts.vehicle.clone().unwrap_or_else(|| dir.vehicle_path());
    let (vehicle, sensors) = grip_config::load_vehicle_for(&vehicle_path, vehicle_use)?;
    let can = load_can(&dir)?;
    // the wheels' radii convert a wheel speed the DBC gives in km/h or m/s
    let radii = grip_io::can::protocol::WheelRadii::of(&vehicle);
    let read = match protocol {
        Protocol::Install => {
            let first = grip_io::can::protocol::installed().is_none();
            let protocol = grip_io::service::install_protocol_with(&dir, &can, Some(radii))?;
            // the speeds and torques the loop controls with, against this
            // vehicle (said once per process, as the protocol's own line: a
            // replay loads the configuration once per candidate start)
            let dbc = can.dbc.as_deref().map_or_else(
                || "the built-in protocol".to_owned(),
                |f| dir.file(f).display().to_string(),
            );
            if first {
                for w in protocol.envelope_warnings(&dbc, &vehicle) {
                    tracing::warn!("{w}");
                }
            }
            None
        }
        Protocol::Read => Some(grip_io::service::resolve_protocol(&dir, &can, Some(radii))?.0),
    };
    let roads = dir.roads()?;
    let road_table = dir.road_table(&roads)?;
    Ok((
        LoadedConfig {
            own,
            controllers,
            vehicle,
            sensors,
            can,
            roads,
            road_table,
            vehicle_path,
            controllers_path,
            own_path,
        },
        read,
    ))
}

/// Every check of the service's start-up short of opening its ports and
/// its bus, with nothing installed or said: its files as the service
/// reads them (the vehicle file complete), the bus against its settings
/// ([`check_bus_timing_in`]: `TorqueRequest` carrying `torque_max`, the
/// periods, the timeouts) and the loop built from them. `grip drive` runs
/// it before starting any service, so that a configuration tcs-loop
/// refuses fails there, once, and not after four services started.
pub fn check(opts: &Options) -> Result<(), RunError> {
    let (cfg, protocol) = load_with(opts, grip_config::VehicleUse::Drive, Protocol::Read)?;
    if let Some(p) = &protocol {
        check_bus_timing_in(&cfg, p)?;
    }
    build_checked(&cfg).map(|_| ())
}

/// The bus against tcs-loop's settings: `TorqueRequest` must carry the
/// vehicle's `torque_max` (within its bit field and its DBC range) and zero
/// torque; it sends `TorqueCommand` every
/// cycle, so the DBC's period for it must be the loop's; its input
/// timeouts (`[safety]`) must span at least two periods of the message they
/// watch (a timeout shorter than that fires between two punctual frames,
/// and the loop would never leave its safe state: found in review with a
/// DBC's DriverDemand at 100 ms against the 50 ms demand timeout).
pub fn check_bus_timing(cfg: &LoadedConfig) -> Result<(), ConfigError> {
    check_bus_timing_in(cfg, grip_io::can::protocol::active())
}

/// [`check_bus_timing`] against the protocol `p`.
pub fn check_bus_timing_in(
    cfg: &LoadedConfig,
    p: &grip_io::can::protocol::Protocol,
) -> Result<(), ConfigError> {
    use grip_io::can::protocol::MsgKind;
    let dbc = cfg.can.dbc.as_deref().unwrap_or("the built-in protocol");
    let loop_ms = 1e3 / cfg.controllers.loop_.rate_hz;
    let tc = p.spec(MsgKind::TorqueCommand).cycle_ms;
    if (f64::from(tc) - loop_ms).abs() > 1e-9 {
        return Err(ConfigError::new(
            &cfg.controllers_path,
            "loop.rate_hz",
            format!(
                "tcs-loop sends TorqueCommand every cycle ({loop_ms} ms), but {dbc} gives it a period of {tc} ms (GenMsgCycleTime)"
            ),
        ));
    }
    // the command must reach the motor's limit on the wire: a narrower
    // field, or a narrower DBC range, saturates it silently (an 8-bit
    // TorqueRequest capped a drive at 127 N m; a [-250|250] range let
    // torque_max 1000 through: both found in review). Zero torque, the
    // safe state's command, must be sendable. A negative command is only
    // ever the driver's own negative demand passed through: its limit is
    // the range's minimum, not checked here.
    let req = &p.spec(MsgKind::TorqueCommand).signals[3];
    let t_max = cfg.vehicle.torque_max;
    let (lo, hi) = req.phys_limits();
    let half_step = 0.5 * req.factor.abs() * (1.0 + 1e-9);
    if t_max > hi + half_step || lo > 0.0 || hi < 0.0 {
        // the limits as a reader writes them: 127 x 0.1 prints 12.7, not
        // 12.700000000000001
        let tidy = |x: f64| format!("{x:.9}").parse::<f64>().unwrap_or(x);
        let (lo, hi) = (tidy(lo), tidy(hi));
        let names = |grip: &str| cfg.can.dbc_names.get(grip).cloned();
        let in_dbc = match (names("TorqueCommand"), names("TorqueCommand.TorqueRequest")) {
            (None, None) => String::new(),
            (m, s) => format!(
                " ({}.{} in the DBC)",
                m.as_deref().unwrap_or("TorqueCommand"),
                s.as_deref().unwrap_or("TorqueRequest")
            ),
        };
        let range = if req.has_range() {
            format!("its DBC range [{}|{}] N m", req.min, req.max)
        } else {
            "no DBC range ([0|0])".to_owned()
        };
        let (f_lo, f_hi) = (
            tidy(req.to_phys(req.field_raw_min())),
            tidy(req.to_phys(req.field_raw_max())),
        );
        let detail = format!("{range}, a {}-bit field of {f_lo} to {f_hi} N m", req.len);
        if lo > 0.0 || hi < 0.0 {
            return Err(ConfigError::new(
                dbc,
                "signal TorqueCommand.TorqueRequest",
                format!(
                    "carries {lo} to {hi} N m{in_dbc}; {detail}: zero torque, the safe state's command, cannot be sent; its range must include 0"
                ),
            ));
        }
        return Err(ConfigError::new(
            &cfg.vehicle_path,
            "vehicle.torque_max",
            format!(
                "{t_max} N m is beyond what TorqueCommand's TorqueRequest carries in {dbc} ({lo} to {hi} N m){in_dbc}; {detail}: commands above {hi} N m would be cut to it on the wire; set torque_max to at most {hi}, or widen the range in {dbc} if the inverter takes more"
            ),
        ));
    }
    let safety = &cfg.own.safety;
    for (kind, field, timeout_ms) in [
        (
            MsgKind::WheelSpeeds,
            "safety.sensor_timeout_ms",
            safety.sensor_timeout_ms,
        ),
        (
            MsgKind::MotorStatus,
            "safety.sensor_timeout_ms",
            safety.sensor_timeout_ms,
        ),
        (
            MsgKind::DriverDemand,
            "safety.demand_timeout_ms",
            safety.demand_timeout_ms,
        ),
    ] {
        let m = p.spec(kind);
        if timeout_ms < 2.0 * f64::from(m.cycle_ms) {
            return Err(ConfigError::new(
                &cfg.own_path,
                field,
                format!(
                    "{timeout_ms} ms is less than two periods of {} ({} ms in {dbc}): the loop would time out between punctual frames",
                    m.name, m.cycle_ms
                ),
            ));
        }
        // A fail-safe trial (2026-12-07): 5000 ms was taken, and with the
        // plant's frames stopped for 1.5 s the loop went on commanding
        // torque on a wheel speed the bus itself declared timed out.
        if timeout_ms > f64::from(m.timeout_ms) {
            return Err(ConfigError::new(
                &cfg.own_path,
                field,
                format!(
                    "{timeout_ms} ms is longer than {}'s receive timeout on the bus (GripTimeoutMs {} ms in {dbc}): the loop would go on commanding torque on a {} the bus declares timed out; set at most {}, or raise GripTimeoutMs in {dbc} if the ECU that sends it may really be that late",
                    m.name, m.timeout_ms, m.name, m.timeout_ms
                ),
            ));
        }
    }
    Ok(())
}

/// The loop the service runs for `cfg`: its controller, ARTE switch,
/// safety timeouts, the bus number its commands carry (`can.toml`'s
/// `bus_id`) and (ARTE on) road knowledge. `run` and `grip replay`
/// build it here, so a replay runs the very loop the service ran.
pub fn build(cfg: &LoadedConfig) -> Result<TcsLoop, RunError> {
    check_bus_timing(cfg)?;
    build_checked(cfg)
}

/// [`build`] after the bus's check.
fn build_checked(cfg: &LoadedConfig) -> Result<TcsLoop, RunError> {
    let kind = cfg
        .own
        .controller_kind()
        .map_err(|(field, reason)| ConfigError::new(&cfg.own_path, field, reason))?;
    let lp = TcsLoop::new(
        kind,
        cfg.own.arte,
        &cfg.controllers,
        &cfg.vehicle,
        &cfg.own.safety,
    )
    .map_err(|error| RunError::Loop {
        file: cfg.controllers_path.clone(),
        error,
    })?
    // the bus `run` opens (`open_bus(&cfg.can, ..)`) stamps what it
    // receives with this number; the commands carry it too
    .with_bus_id(cfg.can.bus_id)
    .with_road_aware(
        &cfg.roads,
        cfg.road_table.clone(),
        &cfg.controllers,
        &cfg.vehicle,
    )
    .map_err(|error| RunError::Loop {
        file: cfg.controllers_path.clone(),
        error,
    })?;
    Ok(lp)
}

/// What the loop says at its start about settings it runs but that do not
/// suit the vehicle, one line each: MFC's and SRC's gains are the paper's
/// car's ([`grip_tcs::analysis::vehicle_tf::gain_warning`]: MFC's k_mfc
/// against bound (4) per road, SRC's gains against their derivation from
/// the wheel and the motor lag; a check that cannot run is said), and the
/// road belief's slip noise is the shipped sensors'
/// ([`grip_tcs::analysis::sensors::sensor_warning`], only for the ARTE
/// variants, which have a belief). [`run`] logs them; `grip replay` prints
/// them for the loop it runs.
pub fn start_warnings(cfg: &LoadedConfig, lp: &TcsLoop) -> Vec<String> {
    let kind = lp.controller_kind();
    let mut out = Vec::new();
    match grip_tcs::analysis::vehicle_tf::gain_warning(
        kind,
        &cfg.vehicle,
        &cfg.vehicle_path,
        &cfg.roads,
        &cfg.controllers,
        &cfg.controllers_path,
    ) {
        Ok(Some(w)) => out.push(w),
        Ok(None) => {}
        Err(e) => out.push(format!(
            "the {} gain check could not run: {e}",
            kind.as_str().to_uppercase()
        )),
    }
    if lp.road_aware()
        && let Some(w) = grip_tcs::analysis::sensors::sensor_warning(
            &cfg.vehicle,
            &cfg.sensors,
            &cfg.vehicle_path,
            &cfg.controllers.fusion,
            &cfg.controllers_path,
            1.0 / cfg.controllers.loop_.rate_hz,
        )
    {
        out.push(w);
    }
    out
}

/// Runs the service until `stop` is set (SIGTERM/SIGINT in `main`) or
/// `run_for_s` has passed. Sends `READY=1` once the ports are open and the
/// real-time set-up is done. Only start-up errors are returned; nothing
/// after start is fatal.
pub fn run(opts: &Options, stop: &Arc<AtomicBool>) -> Result<RunSummary, RunError> {
    let cfg = load_as(opts, grip_config::VehicleUse::Drive)?;
    let mut lp = build(&cfg)?;
    let kind = lp.controller_kind();
    for w in start_warnings(&cfg, &lp) {
        tracing::warn!("{w}");
    }
    let rate = cfg.controllers.loop_.rate_hz;
    let period_ns = (1e9 / rate).round() as u64;
    tracing::info!(
        controller = %kind,
        arte = cfg.own.arte,
        road_aware = lp.road_aware(),
        mic_lead_m = cfg.vehicle.mic_lead_m,
        vehicle = %cfg.vehicle_path.display(),
        rate_hz = rate,
        sensor_timeout_ms = cfg.own.safety.sensor_timeout_ms,
        demand_timeout_ms = cfg.own.safety.demand_timeout_ms,
        recover_ms = cfg.own.safety.recover_ms,
        can_bus = %grip_io::can::protocol::active().describe_bus(),
        "tcs-loop starting"
    );

    let node = IpcNode::create(topics::node::TCS_LOOP)?;
    // only the ids tcs-loop consumes reach it: foreign traffic on a shared
    // bus neither wakes the loop nor counts as a fault
    let mut bus = open_bus(&cfg.can, &node, RxFilter::Role(crate::cycle::ROLE))?;
    let Ports {
        mut sink,
        mut road,
        missing,
    } = open_ports(&node, topics::CYCLE, topics::CAN_LOG, topics::ROAD);
    for (topic, error) in &missing {
        tracing::error!(
            topic = %topic,
            error = %error,
            "tcs-loop: cannot open this topic; traction control runs without it ({})",
            if topic.as_str() == topics::ROAD {
                "no road knowledge: the controller as without ARTE"
            } else {
                "no cycle records or CAN copies for the recorder and arte"
            }
        );
    }

    // helper first, so it stays SCHED_OTHER and unpinned
    let done = Arc::new(AtomicBool::new(false));
    let helper = monitor::spawn_helper(lp.status(), cfg.own.arte, Arc::clone(&done))?;
    let report = rt::apply(&cfg.own.rt);
    report.log();

    let clock = MonotonicClock;
    let mut timer = PeriodicTimer::new(clock, period_ns);
    let end_ns = opts
        .run_for_s
        .map(|s| grip_io::service::args::deadline_ns(clock.now_ns(), s));
    let degraded: Vec<&str> = missing.iter().map(|(t, _)| t.as_str()).collect();
    grip_io::systemd::notify_ready(&format!(
        "{} arte={} at {rate} Hz, bus {:?}{}{}",
        kind,
        if cfg.own.arte { "on" } else { "off" },
        bus.kind(),
        if degraded.is_empty() {
            String::new()
        } else {
            format!(", DEGRADED: without {}", degraded.join(", "))
        },
        report.status_note()
    ));
    tracing::info!("tcs-loop ready");
    let stale = grip_io::can::discard_pending(&mut bus, 1 << 16);
    if stale > 0 {
        tracing::info!(
            frames = stale,
            "CAN frames queued during start-up dropped (stale)"
        );
    }

    let mut late_1ms = 0u64;
    let status = lp.status();
    while !stop.load(Ordering::Relaxed) {
        let t = timer.wait_next();
        late_1ms += u64::from(t.latency_ns > 1_000_000);
        let tick = CycleTick::from_timing(&t, timer.deadline_misses());
        lp.cycle(&tick, &clock, &mut bus, &mut road, &mut sink);
        // a deleted interface (adapter unplugged): the bus reopens its
        // socket when it is back; the helper logs both
        let (gone, reopens) = bus.presence();
        status.bus_gone.store(gone, Ordering::Relaxed);
        status.bus_reopens.store(reopens, Ordering::Relaxed);
        if end_ns.is_some_and(|e| t.woke_ns >= e) {
            break;
        }
    }
    grip_io::systemd::notify_stopping();
    let stop_sent = lp.shutdown(clock.now_ns(), &mut bus, &mut sink);
    done.store(true, Ordering::Relaxed);
    let _ = helper.join();

    let h = timer.histogram().clone();
    let summary = RunSummary {
        cycles: h.count(),
        deadline_misses: timer.deadline_misses(),
        safe_entries: lp.safe_entries(),
        faults_total: lp.protocol_rx().faults().total(),
        fifo: report.fifo.is_applied(),
        dma_latency: report.dma_latency.is_applied(),
        latency: h,
        late_1ms,
    };
    tracing::info!(
        cycles = summary.cycles,
        latency_p50_us = summary.latency.p50_ns() as f64 / 1e3,
        latency_p99_us = summary.latency.p99_ns() as f64 / 1e3,
        latency_max_us = summary.latency.max_ns() as f64 / 1e3,
        wakeups_over_1ms = summary.late_1ms,
        deadline_misses = summary.deadline_misses,
        safe_entries = summary.safe_entries,
        e2e_faults = summary.faults_total,
        // of them, input timeout episodes (the rest are frames rejected:
        // CRC, length, alive counter, unknown id)
        e2e_timeouts = lp.protocol_rx().faults().timeout,
        can_tx = lp.can_tx(),
        can_rx = lp.can_rx(),
        bus_errors = lp.bus_errors(),
        bus_reopens = status.bus_reopens.load(Ordering::Relaxed),
        cycle_published = sink.cycle_published,
        can_log_published = sink.can_published,
        publish_errors = sink.errors,
        road_errors = road.errors,
        stop_frame = if stop_sent {
            "sent"
        } else {
            "NOT sent: the bus is gone or down, the inverter's own command timeout drops the torque"
        },
        "tcs-loop stopped (last command: zero torque, enable cleared; see stop_frame)"
    );
    drop(report);
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::can::protocol::Protocol;

    fn shipped() -> LoadedConfig {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        load(&Options {
            config: ConfigArgs::in_dir(dir),
            ..Options::default()
        })
        .unwrap()
    }

    fn dbc_text() -> String {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/inverter.dbc");
        std::fs::read_to_string(p).unwrap()
    }

    /// The shipped DBC with TorqueCommand.TorqueRequest declared as `sg`.
    fn with_request(sg: &str) -> Protocol {
        let from = "TorqueRequest : 16|16@1- (0.1,0) [-3276.8|3276.7] \"Nm\"";
        let text = dbc_text();
        assert!(text.contains(from));
        Protocol::from_dbc(
            &text.replacen(from, &format!("TorqueRequest : {sg} \"Nm\""), 1),
            "inverter.dbc",
            &Default::default(),
        )
        .unwrap()
    }

    /// The review's repro (2026-12-05): a TorqueRequest of 16 bits at 0.5
    /// N m (a field to ±16384 N m) whose DBC range is [-250|250] took
    /// `torque_max = 1000` (only the bit field was checked); it is refused
    /// naming the vehicle file's field, the DBC, the signal and the range.
    /// Up to the range's end (and half a step beyond: the same raw value)
    /// it passes.
    #[test]
    fn a_torque_max_beyond_the_dbc_range_is_refused() {
        let mut cfg = shipped();
        cfg.vehicle.torque_max = 1000.0; // the shipped car's
        let p = with_request("23|16@0- (0.5,0) [-250|250]");
        let e = check_bus_timing_in(&cfg, &p).unwrap_err();
        assert_eq!(e.field, "vehicle.torque_max", "{e}");
        assert_eq!(e.file, cfg.vehicle_path, "{e}");
        for want in [
            "1000 N m is beyond what TorqueCommand's TorqueRequest carries in inverter.dbc (-250 to 250 N m)",
            "its DBC range [-250|250] N m, a 16-bit field of -16384 to 16383.5 N m",
            "set torque_max to at most 250",
        ] {
            assert!(e.reason.contains(want), "{e}\nwanted: {want}");
        }
        cfg.vehicle.torque_max = 250.0;
        check_bus_timing_in(&cfg, &p).unwrap();
        cfg.vehicle.torque_max = 250.2;
        check_bus_timing_in(&cfg, &p).unwrap();
        cfg.vehicle.torque_max = 250.3;
        assert!(check_bus_timing_in(&cfg, &p).is_err());
        // the built-in protocol carries the shipped car's 1000 N m
        cfg.vehicle.torque_max = 1000.0;
        check_bus_timing_in(&cfg, Protocol::builtin()).unwrap();
        // and [0|0], no range: the bit field alone
        check_bus_timing_in(&cfg, &with_request("16|16@1- (0.1,0) [0|0]")).unwrap();
        // an 8-bit field at 0.1 N m: its limits as written, 127 x 0.1 =
        // 12.7 (was 12.700000000000001)
        let e = check_bus_timing_in(&cfg, &with_request("16|8@1- (0.1,0) [0|0]")).unwrap_err();
        assert!(
            e.reason.contains("(-12.8 to 12.7 N m)") && e.reason.contains("at most 12.7,"),
            "{e}"
        );
    }

    /// A range that leaves zero torque out is refused: the safe state's
    /// command (and a non-finite one's substitute) would be its nearer end.
    #[test]
    fn a_torque_request_range_without_zero_is_refused() {
        let mut cfg = shipped();
        cfg.vehicle.torque_max = 1000.0;
        let e = check_bus_timing_in(&cfg, &with_request("16|16@1- (0.1,0) [10|2000]")).unwrap_err();
        assert_eq!(e.field, "signal TorqueCommand.TorqueRequest", "{e}");
        assert!(
            e.reason.contains("carries 10 to 2000 N m")
                && e.reason
                    .contains("zero torque, the safe state's command, cannot be sent"),
            "{e}"
        );
    }

    /// Where `[dbc_names]` maps grip's names, the refusal also gives the
    /// DBC's.
    #[test]
    fn the_refusal_names_the_dbcs_own_message_and_signal() {
        let mut cfg = shipped();
        cfg.vehicle.torque_max = 1000.0;
        cfg.can.dbc = Some("own-bus.dbc".into());
        cfg.can.dbc_names = grip_testkit::own_bus::names();
        let text = std::fs::read_to_string(grip_testkit::own_bus::dbc_path())
            .unwrap()
            .replacen(
                "TrqReq : 16|16@1- (0.1,0) [-3276.8|3276.7]",
                "TrqReq : 16|16@1- (0.1,0) [-400|400]",
                1,
            );
        let p = Protocol::from_dbc(&text, "own-bus.dbc", &cfg.can.dbc_names).unwrap();
        let e = check_bus_timing_in(&cfg, &p).unwrap_err();
        assert!(
            e.reason.contains(
                "carries in own-bus.dbc (-400 to 400 N m) (MCU_TrqCmd.TrqReq in the DBC); its DBC range [-400|400] N m"
            ),
            "{e}"
        );
    }
}
