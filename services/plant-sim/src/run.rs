//! [`run`]: loads the configuration, opens the CAN bus and the `TRUTH`
//! publisher, applies the real-time set-up and runs [`PlantSim`] on the
//! absolute-deadline timer until stopped or (with `exit_at_end`) finished.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use grip_config::{ConfigDir, ConfigError};
use grip_io::can::{CanBus, CanBusConfig, CanError, RxFilter, Transport, open_bus};
use grip_io::clock::MonotonicClock;
use grip_io::ipc::{IpcError, IpcNode, Publisher};
use grip_io::rt::{self, PeriodicTimer};
use grip_io::service::monitor::HelperError;
use grip_io::service::{ConfigArgs, ServiceConfig, load_can};
use grip_msgs::{GroundTruth, topics};

use crate::config::{PlantSimConfig, StartOn};
use crate::cycle::{Outcome, PlantSim, PlantSimError, PlantTick, TruthSink};
use crate::monitor;

/// Command-line choices (see `main.rs`).
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config-dir` and `--config`.
    pub config: ConfigArgs,
    /// `--scenario NAME|PATH`.
    pub scenario: Option<String>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--exit-at-end` (only ever switches it on).
    pub exit_at_end: bool,
    /// `--start-on`.
    pub start_on: Option<StartOn>,
    /// `--vehicle FILE` (default `<config-dir>/vehicle.toml`).
    pub vehicle: Option<PathBuf>,
}

/// Fatal start-up errors.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A configuration file is wrong.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A model rejected a parameter.
    #[error("{file}: {error}")]
    Model {
        /// The file the parameter came from.
        file: PathBuf,
        /// The error (said in the message, not returned as the source:
        /// a chain printed in full would say it twice).
        error: PlantSimError,
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
    /// can.toml names a CAN interface backed by a real controller.
    #[error(
        "can.toml: interface {iface:?} is a physical CAN interface ({} exists): plant-sim plays the inverter, the wheel-speed sensors and the driver, and its frames would reach the real ECUs on that bus. Use a virtual bus (ip link add dev vcan0 type vcan && ip link set vcan0 up, and interface = \"vcan0\" in can.toml), or set allow_physical_bus = true in {} for a bench bus with nothing else on it",
        device.display(),
        own_file.display()
    )]
    PhysicalBus {
        /// The interface.
        iface: String,
        /// Its sysfs device link.
        device: PathBuf,
        /// plant-sim's own configuration file.
        own_file: PathBuf,
    },
}

impl grip_io::service::ServiceError for RunError {
    fn is_config(&self) -> bool {
        matches!(
            self,
            Self::Config(_) | Self::Model { .. } | Self::PhysicalBus { .. }
        )
    }
}

/// Refuses a CAN interface backed by a device (under the sysfs root
/// `sys_class_net`) unless `allow`; the simulated transport is never refused.
pub fn check_bus(
    can: &CanBusConfig,
    allow: bool,
    own_file: &Path,
    sys_class_net: &Path,
) -> Result<(), RunError> {
    if allow || can.transport == Transport::Sim {
        return Ok(());
    }
    match grip_io::can::physical_interface_in(sys_class_net, &can.interface) {
        Some(device) => Err(RunError::PhysicalBus {
            iface: can.interface.clone(),
            device,
            own_file: own_file.to_owned(),
        }),
        None => Ok(()),
    }
}

/// Everything a run reads, loaded and validated, overrides applied.
pub fn load(opts: &Options) -> Result<(PlantSimConfig, PlantSim, CanBusConfig), RunError> {
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
) -> Result<(PlantSimConfig, PlantSim, CanBusConfig), RunError> {
    let dir = ConfigDir::new(&opts.config.config_dir);
    let own_path = opts.config.own_file::<PlantSimConfig>();
    let mut cfg = PlantSimConfig::load(&own_path)?;
    if let Some(s) = &opts.scenario {
        cfg.scenario = s.clone();
    }
    if let Some(s) = opts.seed {
        cfg.seed = s;
    }
    if let Some(s) = opts.start_on {
        cfg.start_on = s;
    }
    cfg.exit_at_end |= opts.exit_at_end;
    let roads = dir.roads()?;
    let vehicle_path = opts.vehicle.clone().unwrap_or_else(|| dir.vehicle_path());
    let (vehicle, sensors) = grip_config::load_vehicle_for(&vehicle_path, vehicle_use)?;
    // the scenario against this vehicle's motor limit and this loop's
    // cycle count, as `grip sim` checks it (`Scenario::check_for`)
    let scenario = dir.scenario_for(
        &cfg.scenario,
        &roads,
        grip_config::RunsOn {
            vehicle: &vehicle,
            vehicle_file: &vehicle_path,
            dt: 1.0 / cfg.rate_hz,
        },
    )?;
    let can = load_can(&dir)?;
    // the wheels' radii convert the wheel speeds it sends where the DBC
    // gives them in km/h or m/s (v = ω · r), as tcs-loop reads them
    let radii = grip_io::can::protocol::WheelRadii::of(&vehicle);
    let protocol = grip_io::service::install_protocol_with(&dir, &can, Some(radii))?;
    // the inverter's command timeout must span two of the command's periods
    let tc = protocol.spec(grip_io::can::protocol::MsgKind::TorqueCommand);
    if cfg.cmd_timeout_ms < 2.0 * f64::from(tc.cycle_ms) {
        return Err(ConfigError::new(
            &own_path,
            "cmd_timeout_ms",
            format!(
                "{} ms is less than two periods of TorqueCommand ({} ms in {}): the inverter would time out between punctual commands",
                cfg.cmd_timeout_ms,
                tc.cycle_ms,
                can.dbc.as_deref().unwrap_or("the built-in protocol")
            ),
        )
        .into());
    }
    // nor longer than the bus declares it (the DBC's GripTimeoutMs for
    // TorqueCommand is the inverter's): a simulated inverter that waits
    // longer goes on applying a command the bus declares timed out, and a
    // drive against it hides what the car's inverter would do
    if cfg.cmd_timeout_ms > f64::from(tc.timeout_ms) {
        return Err(ConfigError::new(
            &own_path,
            "cmd_timeout_ms",
            format!(
                "{} ms is longer than TorqueCommand's timeout on the bus (GripTimeoutMs {} ms in {}): the simulated inverter would go on applying a command the bus declares timed out; set at most {}, or raise GripTimeoutMs in the DBC if the inverter really waits that long",
                cfg.cmd_timeout_ms,
                tc.timeout_ms,
                can.dbc.as_deref().unwrap_or("the built-in protocol"),
                tc.timeout_ms
            ),
        )
        .into());
    }
    check_bus(
        &can,
        cfg.allow_physical_bus,
        &own_path,
        Path::new("/sys/class/net"),
    )?;
    let sim = PlantSim::new(&cfg, scenario, roads, &vehicle, &sensors).map_err(|error| {
        RunError::Model {
            file: vehicle_path,
            error,
        }
    })?;
    Ok((cfg, sim, can))
}

/// The `TRUTH` publisher; errors counted, never fatal.
#[derive(Debug)]
pub struct IpcTruth {
    /// Publisher.
    pub publisher: Publisher<GroundTruth>,
    /// Failed publishes.
    pub errors: u64,
    /// Samples published.
    pub published: u64,
}

impl TruthSink for IpcTruth {
    fn truth(&mut self, g: &GroundTruth) {
        match self.publisher.publish(g) {
            Ok(_) => self.published += 1,
            Err(_) => self.errors += 1,
        }
    }

    fn errors(&self) -> u64 {
        self.errors
    }
}

/// Runs until `stop` (SIGTERM/SIGINT) or, with `exit_at_end`, the scenario's
/// end plus the hold time. `start` (SIGUSR1) requests the scenario start.
/// Sends `READY=1` once the bus and the publisher are open and the
/// real-time set-up is done (vehicle held, frames about to flow).
pub fn run(
    opts: &Options,
    stop: &Arc<AtomicBool>,
    start: &Arc<AtomicBool>,
) -> Result<(), RunError> {
    let (cfg, mut sim, can) = load_as(opts, grip_config::VehicleUse::Drive)?;
    tracing::info!(
        scenario = %sim.scenario().name,
        duration_s = sim.scenario().duration,
        seed = cfg.seed,
        rate_hz = cfg.rate_hz,
        cmd_timeout_ms = cfg.cmd_timeout_ms,
        start_on = ?cfg.start_on,
        start_commands = cfg.start_commands,
        exit_at_end = cfg.exit_at_end,
        "plant-sim starting"
    );
    let node = IpcNode::create(topics::node::PLANT_SIM)?;
    // only TorqueCommand reaches the inverter; anything else on the bus is
    // filtered below it
    let mut bus = open_bus(&can, &node, RxFilter::Role(crate::cycle::ROLE))?;
    let mut truth = IpcTruth {
        publisher: node.publisher::<GroundTruth>(topics::TRUTH)?,
        errors: 0,
        published: 0,
    };
    let done = Arc::new(AtomicBool::new(false));
    let helper = monitor::spawn_helper(sim.status(), Arc::clone(&done))?;
    let report = rt::apply(&cfg.rt);
    report.log();

    let clock = MonotonicClock;
    let period_ns = (1e9 / cfg.rate_hz).round() as u64;
    let mut timer = PeriodicTimer::new(clock, period_ns);
    grip_io::systemd::notify_ready(&format!(
        "holding scenario {} (start on {:?}), bus {:?}{}",
        sim.scenario().name,
        cfg.start_on,
        bus.kind(),
        report.status_note()
    ));
    tracing::info!("plant-sim ready: vehicle held at its initial state, sensor frames flowing");

    let mut finished = false;
    let status = sim.status();
    while !stop.load(Ordering::Relaxed) {
        if start.load(Ordering::Relaxed) {
            sim.request_start();
        }
        let t = timer.wait_next();
        let outcome = sim.cycle(&PlantTick::from_timing(&t), &clock, &mut bus, &mut truth);
        // a deleted interface (adapter unplugged): the bus reopens its
        // socket when it is back; the helper logs both, as tcs-loop's does
        let (gone, reopens) = bus.presence();
        status.bus_gone.store(gone, Ordering::Relaxed);
        status.bus_reopens.store(reopens, Ordering::Relaxed);
        if outcome == Outcome::Finished {
            finished = true;
            break;
        }
    }
    grip_io::systemd::notify_stopping();
    done.store(true, Ordering::Relaxed);
    let _ = helper.join();
    let h = timer.histogram();
    tracing::info!(
        finished,
        scenario_time_s = sim.scenario_time(),
        cycles = h.count(),
        latency_p50_us = h.p50_ns() as f64 / 1e3,
        latency_p99_us = h.p99_ns() as f64 / 1e3,
        latency_max_us = h.max_ns() as f64 / 1e3,
        deadline_misses = timer.deadline_misses(),
        cmd_timeouts = sim.cmd_timeouts(),
        e2e_faults = sim.protocol_rx().faults().total(),
        can_tx = sim.can_tx(),
        can_rx = sim.can_rx(),
        can_errors = sim.io_errors(),
        bus_reopens = status.bus_reopens.load(Ordering::Relaxed),
        truth_published = truth.published,
        publish_errors = truth.errors,
        x_m = sim.plant().state().x,
        v_kmh = sim.plant().state().v * 3.6,
        "plant-sim stopped"
    );
    drop(report);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::can::Transport;

    fn can(transport: Transport, iface: &str) -> CanBusConfig {
        CanBusConfig {
            transport,
            interface: iface.into(),
            ..CanBusConfig::default()
        }
    }

    /// A fake /sys/class/net with a real controller `can0` and a `vcan0`:
    /// plant-sim refuses can0 (socketcan or auto) unless allowed, naming
    /// the interface, the device and its own file; vcan0 and the simulated
    /// transport are always fine.
    #[test]
    fn a_physical_can_interface_is_refused_unless_allowed() {
        let sys = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(sys.path().join("can0/device")).unwrap();
        std::fs::create_dir_all(sys.path().join("vcan0")).unwrap();
        let own = Path::new("/etc/grip/plant-sim.toml");
        for t in [Transport::Socketcan, Transport::Auto] {
            let e = check_bus(&can(t, "can0"), false, own, sys.path()).unwrap_err();
            let msg = e.to_string();
            assert!(
                msg.contains("\"can0\" is a physical CAN interface"),
                "{msg}"
            );
            assert!(msg.contains("can0/device"), "{msg}");
            assert!(
                msg.contains("allow_physical_bus = true in /etc/grip/plant-sim.toml"),
                "{msg}"
            );
            check_bus(&can(t, "can0"), true, own, sys.path()).unwrap();
            check_bus(&can(t, "vcan0"), false, own, sys.path()).unwrap();
        }
        check_bus(&can(Transport::Sim, "can0"), false, own, sys.path()).unwrap();
    }
}
