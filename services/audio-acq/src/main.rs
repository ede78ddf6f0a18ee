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
//! it names), 1 for the ALSA device (it does not open, refuses its
//! parameters or fails to capture: restarted, a USB microphone may come
//! later).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use grip_audio_acq::{Options, SourceKind, run};
use grip_io::service::args::RunFor;
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
    #[command(flatten)]
    run_for: RunFor,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let opts = Options {
        config: args.config,
        source: args.source,
        device: args.device,
        wav: args.wav,
        looped: args.once.then_some(false),
        run_for: args.run_for.seconds,
    };
    Service::new().run(|signals| run(&opts, signals.stop.clone()).map(drop))
}
