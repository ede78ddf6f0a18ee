//! `plant-sim`: the motor inverter, vehicle and road of a scenario on the
//! CAN bus, in real time (tests, demos, HIL).
//!
//! ```text
//! plant-sim [--config-dir DIR] [--config FILE] [--scenario NAME|PATH] [--seed N]
//!           [--start-on signal|commands|immediate] [--exit-at-end] [--vehicle FILE]
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`): reads
//!   `vehicle.toml` (vehicle + sensors), `roads.toml`, `scenarios/`, `can.toml`.
//! - `--config FILE` (default `DIR/plant-sim.toml`).
//! - `--vehicle FILE` (default `DIR/vehicle.toml`): vehicle + sensors (e.g.
//!   `config/vehicles/front-mic.toml`).
//! - `--scenario`, `--seed`, `--start-on`, `--exit-at-end` override the file.
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! Readiness: `READY=1` via `sd_notify` once the CAN bus and the `TRUTH`
//! publisher are open and the real-time set-up is done. From then on the
//! vehicle is *held* at the scenario's initial state (rolling at v0, no
//! slip, torque 0) and the sensor frames flow every millisecond, with a
//! driver demand of 0.
//!
//! Start (default `--start-on signal`): the scenario clock starts at the
//! first cycle in which **SIGUSR1 has been received and the last
//! `start_commands` (default 20) TorqueCommand frames were valid with
//! Enable = 1**, i.e. tcs-loop is out of its safe state. SIGUSR1 may come
//! before or after that; it is remembered. `commands`: the command condition
//! alone; `immediate`: at once.
//!
//! End: with `--exit-at-end`, after the scenario's duration the inverter
//! holds 0 N m (demand 0) for `end_hold_ms` (default 100 ms) and the process
//! exits 0. Without it, it coasts until SIGTERM/SIGINT (exit 0). Fatal
//! start-up error: one `error: ...` line on stderr, exit code 78
//! (`grip_io::service::EXIT_CONFIG`) for a refused configuration, 1
//! otherwise (CAN, iceoryx2).

use std::process::ExitCode;

use clap::Parser;
use grip_io::service::{ConfigArgs, Service};
use grip_plant_sim::{Options, StartOn, run};

/// The grip plant simulator (inverter + vehicle + road on the CAN bus).
#[derive(Debug, Parser)]
#[command(name = "plant-sim", version)]
#[command(mut_arg("config", |a| a.help("The service's TOML (default: <config-dir>/plant-sim.toml)")))]
struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Scenario name (in `<config-dir>/scenarios`) or path to a scenario TOML.
    #[arg(long)]
    scenario: Option<String>,
    /// Sensor-noise seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Start trigger.
    #[arg(long, value_enum)]
    start_on: Option<StartOn>,
    /// Exit 0 at the scenario's end (after the zero-torque hold).
    #[arg(long)]
    exit_at_end: bool,
    /// The vehicle's TOML (default: `<config-dir>/vehicle.toml`).
    #[arg(long)]
    vehicle: Option<std::path::PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        scenario: args.scenario,
        seed: args.seed,
        exit_at_end: args.exit_at_end,
        start_on: args.start_on,
        vehicle: args.vehicle,
    };
    Service::new()
        .with_start_signal()
        .run(|signals| run(&opts, &signals.stop, &signals.start))
}
