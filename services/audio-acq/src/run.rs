//! The service: configuration, ports, source, real-time set-up, readiness,
//! the loop until stopped, shutdown.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use grip_io::clock::{MonotonicClock, monotonic_now_ns};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_io::service::{ConfigArgs, ServiceConfig};
use grip_msgs::{AudioBlock, GroundTruth, topics};

use crate::alsa_src::{AlsaPcm, AlsaSource};
use crate::config::{AcqConfig, AlsaSection, SourceKind, WavSection};
use crate::synth::SynthSource;
use crate::wav::{WavSource, read_mono_i16};
use crate::{AcqError, AcqLoop, AcqStatus, Source, Step, monitor};

/// A paced source that falls further behind than this drops its backlog
/// (counted as an xrun), as a capture device with a 200 ms buffer would.
pub const PACER_SLACK_NS: u64 = 200_000_000;

/// Command-line choices (each overrides the file).
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config-dir` and `--config`.
    pub config: ConfigArgs,
    /// Source override.
    pub source: Option<SourceKind>,
    /// ALSA device override (creates an `[alsa]` section with defaults if
    /// the file has none).
    pub device: Option<String>,
    /// WAV file override.
    pub wav: Option<PathBuf>,
    /// WAV: play once (`Some(false)`) or looped (`Some(true)`).
    pub looped: Option<bool>,
    /// Stop by itself after this many seconds (`--run-for` takes 0 to
    /// 3.2e7, [`grip_io::service::args::seconds`]; a longer or infinite
    /// run length never ends the run).
    pub run_for: Option<f64>,
}

/// What a run did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RunSummary {
    /// Blocks published.
    pub blocks: u64,
    /// Overruns.
    pub xruns: u64,
    /// Publish failures.
    pub publish_errors: u64,
    /// True if the source ended (WAV once), false if stopped.
    pub source_ended: bool,
}

/// The effective configuration: file plus command-line overrides, validated.
pub fn effective_config(opts: &Options) -> Result<(PathBuf, AcqConfig), AcqError> {
    let file = opts.config.own_file::<AcqConfig>();
    let mut cfg = AcqConfig::load(&file)?;
    if let Some(s) = opts.source {
        cfg.audio.source = s;
    }
    if let Some(d) = &opts.device {
        match &mut cfg.alsa {
            Some(a) => a.device = d.clone(),
            None => cfg.alsa = Some(AlsaSection::with_device(d.clone())),
        }
    }
    if let Some(p) = &opts.wav {
        // a path typed on the command line is the shell's: relative to the
        // working directory (a relative `[wav] path` is the file's, below)
        let p = &std::path::absolute(p).unwrap_or_else(|_| p.clone());
        match &mut cfg.wav {
            Some(w) => w.path = p.clone(),
            None => {
                cfg.wav = Some(WavSection {
                    path: p.clone(),
                    looped: true,
                    channel: None,
                })
            }
        }
    }
    if let (Some(l), Some(w)) = (opts.looped, &mut cfg.wav) {
        w.looped = l;
    }
    cfg.validate(&file)?;
    Ok((file, cfg))
}

/// A `[wav] path` of the configuration file: relative to the
/// configuration directory `dir`, as the file says (it was tried in the
/// working directory first, so a file of the same name there was taken
/// instead); `--wav` is made absolute against the working directory
/// before ([`effective_config`]).
fn resolve(dir: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_owned()
    } else {
        dir.join(p)
    }
}

/// Runs the service until `stop` is set, `run_for` passes, or the source
/// ends. Start-up errors are returned before `READY=1`.
pub fn run(opts: &Options, stop: Arc<AtomicBool>) -> Result<RunSummary, AcqError> {
    let (file, cfg) = effective_config(opts)?;
    crate::config::check_source_under_systemd(
        &file,
        &cfg.audio,
        std::env::var_os("INVOCATION_ID").is_some(),
    )?;
    let rate = cfg.audio.sample_rate;
    let block = cfg.audio.block_samples;
    tracing::info!(
        config = %file.display(),
        source = cfg.audio.source.name(),
        rate,
        block,
        "audio-acq starting"
    );
    for note in cfg.synth.resolved_aliases(&file)?.notes {
        tracing::warn!("{note}");
    }
    let node = IpcNode::create(topics::node::AUDIO_ACQ)?;
    let publisher = node.publisher::<AudioBlock>(topics::AUDIO)?;
    let status = Arc::new(AcqStatus::default());
    match cfg.audio.source {
        SourceKind::Alsa => {
            let al = cfg.alsa.clone().ok_or_else(|| {
                AcqError::Config(grip_config::ConfigError::new(&file, "alsa", "missing"))
            })?;
            let pcm = AlsaPcm::open(&al, rate)?;
            let what = format!(
                "ALSA {} ({}, {} ch, channel {}, period {} frames, buffer {} frames)",
                pcm.device,
                pcm.format,
                al.channels,
                al.channel,
                pcm.period_frames,
                pcm.buffer_frames
            );
            let src = AlsaSource::new(pcm, &al, rate, block);
            serve(
                src,
                &cfg,
                &what,
                al.channel as u16,
                publisher,
                status,
                opts,
                stop,
            )
        }
        SourceKind::Wav => {
            let w = cfg.wav.clone().ok_or_else(|| {
                AcqError::Config(grip_config::ConfigError::new(&file, "wav", "missing"))
            })?;
            let path = resolve(&opts.config.config_dir, &w.path);
            let audio = read_mono_i16(&path, rate, w.channel)?;
            if let Some(w) = crate::wav::upsampled_note(&path, audio.file_rate, rate) {
                tracing::warn!("{w}");
            }
            let what = format!(
                "WAV {} ({} Hz, {} ch{}, {:.1} s, {})",
                path.display(),
                audio.file_rate,
                audio.file_channels,
                w.channel
                    .map_or_else(|| ", averaged".to_owned(), |c| format!(", channel {c}")),
                audio.samples.len() as f64 / f64::from(rate),
                if w.looped { "looped" } else { "once" }
            );
            let src = WavSource::new(
                audio.samples,
                rate,
                w.looped,
                MonotonicClock,
                PACER_SLACK_NS,
            );
            serve(src, &cfg, &what, 0, publisher, status, opts, stop)
        }
        SourceKind::Synth => {
            let truth = node.subscriber::<GroundTruth>(topics::TRUTH, SubscriberMode::Latest)?;
            let src = SynthSource::new(
                &cfg.synth,
                rate,
                block,
                truth,
                MonotonicClock,
                PACER_SLACK_NS,
            )?;
            let what = format!(
                "synth (seed {}, noise {}, truth from {}, on loss: {:?})",
                cfg.synth.seed,
                cfg.synth
                    .noise
                    .as_ref()
                    .map_or("off".to_string(), |n| format!(
                        "rain {} car {} SNR {} dB",
                        n.rain, n.car, n.snr_db
                    )),
                topics::TRUTH,
                cfg.synth.on_truth_lost
            );
            serve(src, &cfg, &what, 0, publisher, status, opts, stop)
        }
    }
}

fn serve<S: Source>(
    source: S,
    cfg: &AcqConfig,
    what: &str,
    channel: u16,
    mut publisher: grip_io::ipc::Publisher<AudioBlock>,
    status: Arc<AcqStatus>,
    opts: &Options,
    stop: Arc<AtomicBool>,
) -> Result<RunSummary, AcqError> {
    let done = Arc::new(AtomicBool::new(false));
    let helper = monitor::spawn_helper(
        Arc::clone(&status),
        cfg.audio.source == SourceKind::Synth,
        Arc::clone(&done),
    )?;
    let rt = grip_io::rt::apply(&cfg.rt);
    rt.log();
    let mut lp = AcqLoop::new(
        source,
        cfg.audio.block_samples,
        channel,
        Arc::clone(&status),
    );
    // saturating: a run length beyond the clock's range never ends the run
    let deadline = opts
        .run_for
        .map(|s| grip_io::service::args::deadline_ns(monotonic_now_ns(), s));
    tracing::info!(
        "source: {what}; publishing {} samples/block at {} Hz on {}",
        cfg.audio.block_samples,
        cfg.audio.sample_rate,
        topics::AUDIO
    );
    grip_io::systemd::notify_ready(&format!("capturing: {what}{}", rt.status_note()));
    let mut ended = false;
    let res = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        if let Some(d) = deadline
            && monotonic_now_ns() >= d
        {
            break Ok(());
        }
        match lp.step(&mut publisher) {
            Ok(Step::Published | Step::Timeout) => {}
            Ok(Step::End) => {
                ended = true;
                break Ok(());
            }
            Err(e) => break Err(e),
        }
    };
    grip_io::systemd::notify_stopping();
    done.store(true, Ordering::Relaxed);
    let _ = helper.join();
    drop(rt);
    let summary = RunSummary {
        blocks: lp.blocks(),
        xruns: status.xruns.load(Ordering::Relaxed),
        publish_errors: status.publish_errors.load(Ordering::Relaxed),
        source_ended: ended,
    };
    tracing::info!(
        blocks = summary.blocks,
        xruns = summary.xruns,
        publish_errors = summary.publish_errors,
        truth_errors = status.truth_errors.load(Ordering::Relaxed),
        source_ended = ended,
        "audio-acq stopped"
    );
    res.map(|()| summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--wav` is the shell's path (relative to the working directory);
    /// a relative `[wav] path` is the file's (relative to the
    /// configuration directory), even when the working directory has a
    /// file of that name.
    #[test]
    fn a_wav_path_is_relative_to_where_it_was_written() {
        let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let opts = Options {
            config: ConfigArgs::in_dir(&config),
            wav: Some(PathBuf::from("take/one.wav")),
            ..Options::default()
        };
        let (_, cfg) = effective_config(&opts).unwrap();
        let p = resolve(&config, &cfg.wav.unwrap().path);
        assert_eq!(p, std::env::current_dir().unwrap().join("take/one.wav"));
        // the shipped [wav] path, relative: the configuration directory's
        let (_, cfg) = effective_config(&Options {
            config: ConfigArgs::in_dir(&config),
            ..Options::default()
        })
        .unwrap();
        let shipped = cfg.wav.unwrap().path;
        assert!(shipped.is_relative());
        assert_eq!(resolve(&config, &shipped), config.join(&shipped));
        // a file of that name in the working directory does not change it
        // (Cargo.toml exists in the working directory of the tests)
        assert_eq!(
            resolve(&config, Path::new("Cargo.toml")),
            config.join("Cargo.toml")
        );
    }
}
