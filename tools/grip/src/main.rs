//! `grip`: the command line of the grip traction-control runtime.
//!
//! Each subcommand lives in `cmd/<name>.rs` as an `Args` struct and a `run`
//! function; this file only dispatches.

// serde_json::json! of `grip inspect --json`'s object (drive/json.rs)
#![recursion_limit = "256"]

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod cmd;
mod dataset;
mod drive;
mod plot;
mod replay;

#[derive(Parser)]
#[command(
    name = "grip",
    version,
    about = "Acoustic road-aware traction control for electric vehicles"
)]
struct Cli {
    /// Directory holding grip's configuration (vehicle, roads, controllers, scenarios).
    #[arg(long, global = true, default_value = "config", env = "GRIP_CONFIG_DIR")]
    config_dir: std::path::PathBuf,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the road catalogue with lambda_opt and mu_peak; --plot draws the mu-lambda curves.
    Roads(cmd::roads::Args),
    /// Offline closed-loop simulation of the six controller variants on a scenario.
    Sim(cmd::sim::Args),
    /// Linear analysis: transfer functions, the K_MFC bound and Vinnicombe nu-gaps.
    Analyze(cmd::analyze::Args),
    /// Train an ARTE road classifier on a labelled WAV dataset (CV by recording, model file).
    Train(Box<cmd::train::Args>),
    /// Fit the streaming estimator's confidence calibration of a model on road-change recordings.
    Calibrate(cmd::calibrate::Args),
    /// Classify a WAV recording frame by frame with an ARTE model.
    Classify(cmd::classify::Args),
    /// Labelled datasets: `grip dataset synth` writes synthetic tyre-road recordings.
    Dataset(cmd::dataset::Args),
    /// Acoustic features of a WAV file per frame (--csv), or pruning and KL report of a dataset.
    Features(cmd::features::Args),
    /// Drive: all five services as processes on a scenario in real time, MCAP log, summary.
    Drive(cmd::drive::Args),
    /// Summary, timing histogram, road timeline, CSV and plots of a drive log (MCAP).
    Inspect(cmd::inspect::Args),
    /// Many simulated drive logs, fast: the services' own code in lock step on a scripted clock.
    Generate(cmd::generate::Args),
    /// Replay a drive log through the services' own code (open loop); what-if options.
    Replay(cmd::replay::Args),
}

/// Where the Debian package puts the configuration (`tools/package`).
const INSTALLED_CONFIG_DIR: &str = "/etc/grip";

/// The configuration directory of an installed `grip` left to its default:
/// `installed` (`/etc/grip`) when `grip` is the package's (`exe` in
/// `PREFIX/bin`, its services in `PREFIX/lib/grip/bin`), `default`
/// (`config`) does not exist from here, and `installed` does; `None`
/// otherwise (the default stands: a checkout's `config/`). On the ECU
/// every command needed `--config-dir /etc/grip`, and without it failed
/// on `config/roads.toml`.
fn installed_config_dir(
    exe: &std::path::Path,
    installed: &std::path::Path,
    default: &std::path::Path,
) -> Option<std::path::PathBuf> {
    let prefix = exe.parent().filter(|b| b.ends_with("bin"))?.parent()?;
    (prefix.join("lib/grip/bin").is_dir() && !default.is_dir() && installed.is_dir())
        .then(|| installed.to_path_buf())
}

fn main() -> std::process::ExitCode {
    // warnings and errors of the services' code that grip runs in-process
    // (a replay's tcs-loop and arte, generate): their start-up info lines
    // (the CAN protocol, ...) are for a service's journal, not for a
    // command's output; RUST_LOG=info shows them
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        // no colour codes in a file or a pipe (or with NO_COLOR set)
        .with_ansi(
            std::io::IsTerminal::is_terminal(&std::io::stderr())
                && std::env::var_os("NO_COLOR").is_none(),
        )
        .init();
    let matches = Cli::command().get_matches();
    let given = matches.value_source("config_dir") == Some(clap::parser::ValueSource::CommandLine);
    let defaulted =
        matches.value_source("config_dir") == Some(clap::parser::ValueSource::DefaultValue);
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(c) => c,
        Err(e) => e.exit(),
    };
    let config_dir = match (defaulted, std::env::current_exe()) {
        (true, Ok(exe)) => installed_config_dir(
            &exe,
            std::path::Path::new(INSTALLED_CONFIG_DIR),
            &cli.config_dir,
        )
        .unwrap_or(cli.config_dir),
        _ => cli.config_dir,
    };
    let ctx = cmd::Ctx {
        config_dir,
        config_dir_given: given,
    };
    let result = match cli.command {
        Command::Roads(a) => cmd::roads::run(&ctx, a),
        Command::Sim(a) => cmd::sim::run(&ctx, a),
        Command::Analyze(a) => cmd::analyze::run(&ctx, a),
        Command::Train(a) => cmd::train::run(&ctx, *a),
        Command::Calibrate(a) => cmd::calibrate::run(&ctx, a),
        Command::Classify(a) => cmd::classify::run(&ctx, a),
        Command::Dataset(a) => cmd::dataset::run(&ctx, a),
        Command::Features(a) => cmd::features::run(&ctx, a),
        Command::Drive(a) => cmd::drive::run(&ctx, a),
        Command::Inspect(a) => cmd::inspect::run(&ctx, a),
        Command::Replay(a) => cmd::replay::run(&ctx, a),
        Command::Generate(a) => cmd::generate::run(&ctx, a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::installed_config_dir;

    /// The package's `grip` (PREFIX/bin, services in PREFIX/lib/grip/bin)
    /// takes the installed configuration when `config` is not there; a
    /// checkout's grip, or a directory with `config/`, keeps the default.
    #[test]
    fn the_installed_grip_finds_its_configuration() {
        let d = tempfile::tempdir().unwrap();
        let prefix = d.path().join("usr");
        std::fs::create_dir_all(prefix.join("bin")).unwrap();
        std::fs::create_dir_all(prefix.join("lib/grip/bin")).unwrap();
        let etc = d.path().join("etc/grip");
        std::fs::create_dir_all(&etc).unwrap();
        let exe = prefix.join("bin/grip");
        let none = d.path().join("nowhere/config");
        assert_eq!(installed_config_dir(&exe, &etc, &none), Some(etc.clone()));
        // a config/ where grip runs: the default stands
        let here = d.path().join("work/config");
        std::fs::create_dir_all(&here).unwrap();
        assert_eq!(installed_config_dir(&exe, &etc, &here), None);
        // a checkout's grip (target/release/grip): the default stands
        let built = d.path().join("repo/target/release/grip");
        assert_eq!(installed_config_dir(&built, &etc, &none), None);
        // no /etc/grip: the default stands, and its error names it
        assert_eq!(
            installed_config_dir(&exe, &d.path().join("etc/none"), &none),
            None
        );
    }
}
