//! One rule for the commands that give arte audio: arte's model and the
//! audio blocks must be at one sample rate. arte refuses (counts, never
//! resamples) every block at another rate than its model's, so a drive or
//! a replay would run to the end and record no road estimate. Here: the
//! model arte's start-up loads and its rate ([`arte_model`]), the rate
//! audio-acq publishes ([`audio_rate`]), and the refusal naming both files
//! and both rates ([`require_one_rate`]). `grip drive` checks with them
//! before any service starts, `grip generate` before any log is generated;
//! `grip replay` finds its model with [`arte_model`].

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use grip_io::service::{ConfigArgs, ServiceConfig};

/// A model file and the audio sample rate it was trained for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelRate {
    /// The file arte loads.
    pub path: PathBuf,
    /// Its sample rate, Hz.
    pub hz: u32,
}

/// The model arte's start-up loads with the configuration directory `dir`
/// (arte's own resolution): `model` (its `--model`) if given, else the
/// `model` of `dir/arte-svc.toml`, relative to `dir`; read and its rate
/// taken. A missing or unreadable file is an error naming it.
pub fn arte_model(dir: &Path, model: Option<&Path>) -> anyhow::Result<ModelRate> {
    let path = match model {
        Some(m) => m.to_path_buf(),
        None => {
            let file = ConfigArgs::in_dir(dir).own_file::<grip_arte_svc::ArteServiceConfig>();
            let cfg = grip_arte_svc::ArteServiceConfig::load(&file)?;
            if cfg.model.is_absolute() {
                cfg.model
            } else {
                dir.join(cfg.model)
            }
        }
    };
    // its message once (the error's source repeats it in a chain)
    let m = grip_arte_svc::load_model(&path).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(ModelRate {
        hz: m.feature_config().sample_rate,
        path,
    })
}

/// arte's start-up check of a model's classes, made before any service
/// starts: every class a road of `dir`'s catalogue (`roads.toml`, whose
/// μ-λ curve the estimate carries) and at most as many as a road estimate
/// carries (`grip_arte_svc::road_table`, the code arte runs). The error
/// names `model` as the user gave it, not the copy the services get.
pub fn check_model_classes(dir: &Path, model: &Path) -> anyhow::Result<()> {
    let m = grip_arte_svc::load_model(model).map_err(|e| anyhow::anyhow!("{e}"))?;
    let cfg = grip_config::ConfigDir::new(dir);
    let roads = cfg.roads().map_err(|e| anyhow::anyhow!("{e}"))?;
    let rule = cfg.road_table(&roads).map_err(|e| anyhow::anyhow!("{e}"))?;
    grip_arte_svc::road_table(m.classes(), &roads, &rule, model, &cfg.roads_path())
        .map_err(|e| anyhow::anyhow!("{e}; arte would refuse it at start-up"))?;
    Ok(())
}

/// The rate audio-acq publishes with the configuration directory `dir`
/// (its `[audio] sample_rate`, read by audio-acq's own start-up code), and
/// the file it comes from.
pub fn audio_rate(dir: &Path) -> anyhow::Result<(PathBuf, u32)> {
    let (file, cfg) = grip_audio_acq::run::effective_config(&grip_audio_acq::Options {
        config: ConfigArgs::in_dir(dir),
        ..grip_audio_acq::Options::default()
    })
    .context("audio-acq's configuration")?;
    Ok((file, cfg.audio.sample_rate))
}

/// The rule: audio at `audio_hz` (`[audio] sample_rate` of `audio_file`)
/// for a model (`model`, as the user gave it: e.g. `--model FILE` or
/// `arte's model FILE`) at `model_hz` is refused unless the rates are
/// equal. `outcome`: what would happen otherwise; `other_fix`: the
/// command's own way out besides changing the audio's rate.
pub fn require_one_rate(
    audio_file: &Path,
    audio_hz: u32,
    model: &str,
    model_hz: u32,
    outcome: &str,
    other_fix: &str,
) -> anyhow::Result<()> {
    if audio_hz == model_hz {
        return Ok(());
    }
    bail!(
        "{}: field audio.sample_rate is {audio_hz} Hz, but {model} expects {model_hz} Hz: arte refuses every audio block at another rate than its model's, so {outcome}. Set [audio] sample_rate = {model_hz} in {}, or {other_fix}",
        audio_file.display(),
        audio_file.display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The repository's configuration: the default model and the audio at
    /// one rate, read as arte and audio-acq read them.
    #[test]
    fn the_repository_configuration_is_at_one_rate() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let m = arte_model(&dir, None).unwrap();
        assert!(m.path.ends_with("models/default.model"), "{m:?}");
        let (file, hz) = audio_rate(&dir).unwrap();
        assert!(file.ends_with("audio-acq.toml"), "{}", file.display());
        assert_eq!(hz, m.hz);
        require_one_rate(&file, hz, "arte's model", m.hz, "x", "y").unwrap();
    }

    /// A missing model file is named; another rate is refused naming both
    /// files, both rates and the fixes.
    #[test]
    fn a_missing_model_and_another_rate_are_refused_naming_them() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let e = format!(
            "{:#}",
            arte_model(&dir, Some(Path::new("/nonexistent/x.model"))).unwrap_err()
        );
        assert!(e.contains("/nonexistent/x.model"), "{e}");
        let e = require_one_rate(
            Path::new("c/audio-acq.toml"),
            48_000,
            "--model m16.model",
            16_000,
            "no estimate",
            "another model",
        )
        .unwrap_err()
        .to_string();
        for want in [
            "c/audio-acq.toml: field audio.sample_rate is 48000 Hz",
            "--model m16.model expects 16000 Hz",
            "so no estimate",
            "Set [audio] sample_rate = 16000 in c/audio-acq.toml, or another model",
        ] {
            assert!(e.contains(want), "{want}: {e}");
        }
    }
}
