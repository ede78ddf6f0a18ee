//! `recorder`: writes every grip topic to an MCAP file.
//!
//! ```text
//! recorder [--config-dir DIR] [--config FILE] [--out FILE] [--meta KEY=VALUE]... [--attach NAME=FILE]...
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`): the
//!   configuration files in it (`*.toml`, the DBC, `roads/`, `scenarios/`,
//!   `vehicles/`, `models/`) are hashed into the `grip.run` metadata and attached.
//! - `--config FILE` (default `DIR/recorder.toml`).
//! - `--out FILE` (default: a new `<out_dir>/grip-<unix s>-<boot id>-<pid>.mcap`,
//!   never overwriting a log, the oldest finished logs of `out_dir` deleted
//!   to keep `max_total_mib` and `min_free_mib`: `grip_recorder::retention`;
//!   a new part of the run, named the same way, every `max_file_mib` or
//!   `max_file_s`, and after a write error once space is free again:
//!   `grip_recorder::parts`; with `--out` one file, nothing deleted).
//! - `--meta KEY=VALUE`: extra `grip.run` metadata (`grip drive` passes the
//!   scenario, controller, ARTE switch and seed).
//! - `--attach NAME=FILE`: one more file to hash and attach under NAME
//!   (`grip drive` attaches its `--vehicle` file as `drive/vehicle.toml`);
//!   a FILE that cannot be read is a fatal error at start, before anything
//!   is recorded.
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! Readiness: `READY=1` once the subscribers and the file are open and the
//! run metadata is written. Stop: SIGTERM/SIGINT → drains the subscribers and
//! the queue, writes the `grip.recorder` summary, finishes the file, exit 0.
//! Fatal error: one `error: ...` line on stderr, exit code 78
//! (`grip_io::service::EXIT_CONFIG`) for a refused configuration file, 1
//! otherwise (the output directory, a write error, an `--attach` file). An
//! output that cannot be created names what named it: ``recorder.toml:
//! field `out_dir`: DIR: cannot create ...`` or ``option `--out`: FILE:
//! ...``.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use grip_io::service::{ConfigArgs, Service};
use grip_recorder::{Options, run};

/// The grip recorder (every topic to MCAP).
#[derive(Debug, Parser)]
#[command(name = "recorder", version)]
#[command(mut_arg("config", |a| a.help("The service's TOML (default: <config-dir>/recorder.toml)")))]
struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Output MCAP file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Extra run metadata, KEY=VALUE (repeatable).
    #[arg(long, value_parser = parse_kv)]
    meta: Vec<(String, String)>,
    /// One more file to hash and attach, NAME=FILE (repeatable).
    #[arg(long, value_parser = parse_kv)]
    attach: Vec<(String, String)>,
}

fn parse_kv(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() => Ok((k.to_owned(), v.to_owned())),
        _ => Err(format!("expected KEY=VALUE, got {s:?}")),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        out: args.out,
        meta: args.meta,
        attach: args
            .attach
            .into_iter()
            .map(|(k, v)| (k, PathBuf::from(v)))
            .collect(),
    };
    Service::new().run(|signals| run(&opts, &signals.stop).map(drop))
}
