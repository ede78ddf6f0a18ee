//! `plant-sim`: the motor inverter, vehicle and road of a scenario on the
//! CAN bus, in real time (tests, demos, HIL).
//!
//! ```text
//! plant-sim [--config-dir DIR] [--config FILE] [--scenario NAME|PATH] [--seed N]
//!           [--start-on signal|commands|immediate] [--exit-at-end]
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`): reads
//!   `vehicle.toml` (vehicle + sensors), `roads.toml`, `scenarios/`, `can.toml`.
//! - `--config FILE` (default `DIR/plant-sim.toml`).
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
//! start-up error: one `error: ...` line on stderr, exit code 1.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::Parser;
use grip_plant_sim::{Options, StartOn, run};

/// The grip plant simulator (inverter + vehicle + road on the CAN bus).
#[derive(Debug, Parser)]
#[command(name = "plant-sim", version)]
struct Args {
    /// Shared configuration directory.
    #[arg(long, default_value = "config")]
    config_dir: PathBuf,
    /// The service's TOML (default: <config-dir>/plant-sim.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Scenario name (in <config-dir>/scenarios) or path to a scenario TOML.
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
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .init();
    let args = Args::parse();
    let stop = Arc::new(AtomicBool::new(false));
    let start = Arc::new(AtomicBool::new(false));
    let regs = [
        (signal_hook::consts::SIGTERM, &stop),
        (signal_hook::consts::SIGINT, &stop),
        (signal_hook::consts::SIGUSR1, &start),
    ];
    for (sig, flag) in regs {
        if let Err(e) = signal_hook::flag::register(sig, Arc::clone(flag)) {
            eprintln!("error: cannot install the handler for signal {sig}: {e}");
            return ExitCode::from(1);
        }
    }
    let opts = Options {
        config_dir: args.config_dir,
        config: args.config,
        scenario: args.scenario,
        seed: args.seed,
        exit_at_end: args.exit_at_end,
        start_on: args.start_on,
    };
    match run(&opts, &stop, &start) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}
