//! `arte`: acoustic road-type estimation, audio blocks in, road estimates out;
//! the vehicle speed from tcs-loop's cycle records (`grip/tcs/cycle`) goes
//! to the estimator (`README.md`, "Vehicle speed").
//!
//! ```text
//! arte [--config-dir DIR] [--config FILE] [--model FILE] [--run-for SECONDS]
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`): reads
//!   `roads.toml` and, by default, `models/default.model` from it.
//! - `--config FILE` (default `DIR/arte-svc.toml`; `DIR/arte.toml` is the
//!   offline simulator's file).
//! - `--model FILE` overrides the file's `model`.
//! - `--run-for SECONDS`: stop by itself (0 to 3.2e7 s; anything else is
//!   a usage error, [`grip_io::service::args::seconds`]).
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! `READY=1` once model, road table and ports are ready. SIGTERM/SIGINT:
//! exit 0. A missing/corrupt/mismatched model, a class without a road in
//! the catalogue, a bad config: one `error: ...` line naming the file (a
//! model that cannot be read or is not one: the model file, and the
//! configuration file and field `model`, or the option `--model`, that
//! named it), exit code 78 (`grip_io::service::EXIT_CONFIG`: the unit is not
//! restarted on it); iceoryx2 or the helper thread failing: exit code 1.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use grip_arte_svc::{Options, run};
use grip_io::service::args::RunFor;
use grip_io::service::{ConfigArgs, Service};

/// grip ARTE service: road estimates on grip/arte/road from audio on grip/audio/block.
#[derive(Debug, Parser)]
#[command(name = "arte", version)]
#[command(mut_arg("config", |a| a.help("The service's TOML (default: <config-dir>/arte-svc.toml)")))]
struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Model file (default: the config's `model`, i.e. `<config-dir>/models/default.model`).
    #[arg(long)]
    model: Option<PathBuf>,
    #[command(flatten)]
    run_for: RunFor,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        model: args.model,
        run_for: args.run_for.seconds,
    };
    Service::new().run(|signals| run(&opts, signals.stop.clone()).map(drop))
}
