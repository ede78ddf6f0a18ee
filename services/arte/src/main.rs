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
//! - `--run-for SECONDS`: stop by itself.
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! `READY=1` once model, road table and ports are ready. SIGTERM/SIGINT:
//! exit 0. A missing/corrupt/mismatched model, a class without a road in
//! the catalogue, a bad config: one `error: ...` line naming the file,
//! exit code 1.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::Parser;
use grip_arte_svc::{Options, run};

/// grip ARTE service: road estimates on grip/arte/road from audio on grip/audio/block.
#[derive(Debug, Parser)]
#[command(name = "arte", version)]
struct Args {
    /// Shared configuration directory.
    #[arg(long, default_value = "config")]
    config_dir: PathBuf,
    /// The service's TOML (default: <config-dir>/arte-svc.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Model file (default: the config's `model`, i.e. <config-dir>/models/default.model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Stop after this many seconds.
    #[arg(long)]
    run_for: Option<f64>,
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .init();
    let args = Args::parse();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        if let Err(e) = signal_hook::flag::register(sig, Arc::clone(&stop)) {
            eprintln!("error: cannot install the handler for signal {sig}: {e}");
            return ExitCode::from(1);
        }
    }
    let opts = Options {
        config_dir: args.config_dir,
        config: args.config,
        model: args.model,
        run_for: args.run_for,
    };
    match run(&opts, stop) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}
