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
//! the catalogue, a bad config: one `error: ...` line naming the file,
//! exit code 78 (`grip_io::service::EXIT_CONFIG`: the unit is not
//! restarted on it); iceoryx2 or the helper thread failing: exit code 1.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use grip_arte_svc::{Options, run};
use grip_io::service::args::seconds;
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
    /// Stop after this many seconds (0 to 3.2e7).
    #[arg(long, value_parser = seconds, allow_negative_numbers = true)]
    run_for: Option<f64>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        model: args.model,
        run_for: args.run_for,
    };
    Service::new().run(|signals| run(&opts, signals.stop.clone()).map(drop))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--run-for` takes the services' one parser (tcs-loop's): `inf` or
    /// `1e300` is a usage error here, not a deadline that wraps into the
    /// past; `-1` reaches the parser in either spelling.
    #[test]
    fn run_for_is_the_shared_parser() {
        let a = Args::try_parse_from(["arte", "--run-for", "2.5"]).unwrap();
        assert_eq!(a.run_for, Some(2.5));
        assert_eq!(Args::try_parse_from(["arte"]).unwrap().run_for, None);
        for bad in ["inf", "NaN", "-1", "1e300", "soon"] {
            for argv in [
                vec!["arte".to_string(), format!("--run-for={bad}")],
                vec!["arte".into(), "--run-for".into(), bad.into()],
            ] {
                let e = Args::try_parse_from(&argv).unwrap_err();
                assert_eq!(
                    e.kind(),
                    clap::error::ErrorKind::ValueValidation,
                    "{argv:?}: {e}"
                );
                let msg = e.to_string();
                assert!(msg.contains("--run-for") && msg.contains(bad), "{msg}");
            }
        }
        let e = Args::try_parse_from(["arte", "--run-for", "-1"]).unwrap_err();
        assert!(e.to_string().contains("seconds from 0 to 3.2e7"), "{e}");
    }
}
