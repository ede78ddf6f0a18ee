//! `audio-acq`: tyre-road audio (ALSA microphone, WAV file or synthesiser)
//! in blocks on the iceoryx2 topic `grip/audio/block`.
//!
//! ```text
//! audio-acq [--config-dir DIR] [--config FILE] [--source alsa|wav|synth]
//!           [--device PCM] [--wav FILE] [--once] [--run-for SECONDS]
//! ```
//! - `--config-dir DIR` (default `config`; systemd: `/etc/grip`); relative
//!   WAV paths are resolved against it.
//! - `--config FILE` (default `DIR/audio-acq.toml`).
//! - `--source`, `--device` (e.g. `hw:Loopback,1,0`), `--wav`, `--once`
//!   override the file (HIL tests use `--source alsa --device ...`).
//! - `--run-for SECONDS`: stop by itself (0 to 3.2e7 s; anything else is
//!   a usage error, [`grip_io::service::args::seconds`]).
//! - `GRIP_INSTANCE` (environment) selects an isolated iceoryx2 namespace.
//!
//! `READY=1` once the publisher and the source are open and the real-time
//! set-up is done. SIGTERM/SIGINT: finish the block, exit 0. A WAV file
//! played once: exit 0 after its last block. Start-up errors: one
//! `error: ...` line; exit code 78 (`grip_io::service::EXIT_CONFIG`, not
//! restarted by the unit) for a refused configuration (the file, a WAV file
//! it names, settings the device refuses), 1 for a device that does not
//! open or a capture error (restarted: a USB microphone may come later).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use grip_audio_acq::{Options, SourceKind, run};
use grip_io::service::args::seconds;
use grip_io::service::{ConfigArgs, Service};

/// grip audio acquisition: blocks of mono PCM on topic grip/audio/block.
#[derive(Debug, Parser)]
#[command(name = "audio-acq", version)]
#[command(mut_arg("config", |a| a.help("The service's TOML (default: <config-dir>/audio-acq.toml)")))]
struct Args {
    #[command(flatten)]
    config: ConfigArgs,
    /// Source override.
    #[arg(long, value_enum)]
    source: Option<SourceKind>,
    /// ALSA capture PCM override, e.g. hw:Loopback,1,0 or default.
    #[arg(long)]
    device: Option<String>,
    /// WAV file override.
    #[arg(long)]
    wav: Option<PathBuf>,
    /// Play the WAV file once, then exit 0 (default: as configured).
    #[arg(long)]
    once: bool,
    /// Stop after this many seconds (0 to 3.2e7).
    #[arg(long, value_parser = seconds, allow_negative_numbers = true)]
    run_for: Option<f64>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        source: args.source,
        device: args.device,
        wav: args.wav,
        looped: args.once.then_some(false),
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
        let a = Args::try_parse_from(["audio-acq", "--run-for", "2.5"]).unwrap();
        assert_eq!(a.run_for, Some(2.5));
        assert_eq!(Args::try_parse_from(["audio-acq"]).unwrap().run_for, None);
        for bad in ["inf", "NaN", "-1", "1e300", "soon"] {
            for argv in [
                vec!["audio-acq".to_string(), format!("--run-for={bad}")],
                vec!["audio-acq".into(), "--run-for".into(), bad.into()],
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
        let e = Args::try_parse_from(["audio-acq", "--run-for", "-1"]).unwrap_err();
        assert!(e.to_string().contains("seconds from 0 to 3.2e7"), "{e}");
    }
}
