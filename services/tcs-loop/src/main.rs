//! `tcs-loop`: the 1 kHz traction-control loop of grip.
//!
//! ```text
//! tcs-loop [--config-dir DIR] [--config FILE] [--controller mfc|src|mtte] [--arte on|off]
//!          [--run-for SECONDS] [--vehicle FILE]
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`): reads
//!   `controllers.toml` (parameters, `[loop] rate_hz`), `vehicle.toml`,
//!   `can.toml` from it.
//! - `--vehicle FILE` (default `DIR/vehicle.toml`): the vehicle (e.g.
//!   `config/vehicles/front-mic.toml`).
//! - `--config FILE` (default `DIR/tcs-loop.toml`): controller, ARTE on/off,
//!   `[safety]` timeouts, `[rt]` (SCHED_FIFO priority, mlockall, CPUs,
//!   cpu_dma_latency).
//! - `--controller`, `--arte` override the file.
//! - `--run-for SECONDS`: stop by itself (benchmarks; 0 to 3.2e7 s, anything
//!   else is a usage error, [`grip_io::service::args::seconds`]); normally it
//!   runs until SIGTERM/SIGINT.
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! Readiness: `READY=1` via `sd_notify` once the CAN bus, the `CYCLE`,
//! `CAN_LOG` publishers and the `ROAD` subscriber are open and the real-time
//! set-up is done, immediately before the first cycle. With `WATCHDOG_USEC`
//! set, `WATCHDOG=1` goes out at half that period from a helper thread while
//! the loop's heartbeat advances.
//!
//! Stop: SIGTERM/SIGINT → the loop finishes its cycle, sends 0 N m with
//! `Enable` cleared, exits 0. A bad configuration: one `error: ...` line
//! on stderr (file, field, reason), exit code 78
//! (`grip_io::service::EXIT_CONFIG`: the unit is not restarted on it); a
//! CAN interface that is not there (yet) or iceoryx2: exit code 1.

use std::process::ExitCode;

use clap::Parser;
use grip_io::service::args::RunFor;
use grip_io::service::{ConfigArgs, Service};
use grip_tcs::ControllerKind;
use grip_tcs_loop::{Options, run};

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum OnOff {
    On,
    Off,
}

/// The grip traction-control loop (CAN in/out, ARTE road estimates, cycle records).
#[derive(Debug, Parser)]
#[command(name = "tcs-loop", version)]
#[command(mut_arg("config", |a| a.help("The service's TOML (default: <config-dir>/tcs-loop.toml)")))]
struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Controller override: mfc, src or mtte.
    #[arg(long)]
    controller: Option<ControllerKind>,
    /// ARTE override.
    #[arg(long, value_enum)]
    arte: Option<OnOff>,
    #[command(flatten)]
    run_for: RunFor,
    /// The vehicle's TOML (default: `<config-dir>/vehicle.toml`).
    #[arg(long)]
    vehicle: Option<std::path::PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        controller: args.controller,
        arte: args.arte.map(|a| a == OnOff::On),
        run_for_s: args.run_for.seconds,
        vehicle: args.vehicle,
    };
    Service::new().run(|signals| run(&opts, &signals.stop).map(drop))
}
