//! `arte-svc.toml`: the model, the streaming estimator's settings, input
//! handling and real-time settings.
//!
//! (`config/sim-confusion.toml` is the offline simulator's confusion-matrix
//! configuration, read by `grip sim`; the live service's file is
//! `config/arte-svc.toml`.)

use std::path::{Path, PathBuf};

use grip_arte::stream::{Smoothing, StreamConfig};
use grip_config::ConfigError;
use grip_io::rt::RtConfig;
use grip_io::service::{ServiceConfig, validate_rt};
use serde::{Deserialize, Serialize};

/// `[input]`: how audio blocks are taken from the topic.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSection {
    /// Sleep between polls of the audio topic when it is empty, ms. A block
    /// waits at most this long before it is processed.
    #[serde(default = "default_poll")]
    pub poll_interval_ms: f64,
    /// A block whose stamp is further than this from where the previous
    /// block ended (audio-acq restarted, a long overrun, lost blocks)
    /// restarts the estimator (its frame and smoothing state), s.
    #[serde(default = "default_resync")]
    pub resync_gap_s: f64,
    /// The vehicle speed (newest tcs-loop cycle record on `grip/tcs/cycle`
    /// with `v_valid = 1`) is given to the estimator while its stamp is at
    /// most this old; older or absent: speed unknown, s.
    #[serde(default = "default_speed_timeout")]
    pub speed_timeout_s: f64,
    /// A block whose audio ended longer ago than this when the service
    /// takes it from the topic (a backlog: a starved CPU, a stopped and
    /// resumed process) is not classified but dropped and counted, so that
    /// no estimate is ever made of audio that old; the estimator starts a
    /// fresh frame at the next block in time, s.
    #[serde(default = "default_max_lag")]
    pub max_lag_s: f64,
}

fn default_poll() -> f64 {
    2.0
}
fn default_resync() -> f64 {
    0.2
}
fn default_speed_timeout() -> f64 {
    crate::DEFAULT_SPEED_TIMEOUT_S
}
fn default_max_lag() -> f64 {
    crate::DEFAULT_MAX_LAG_S
}

impl Default for InputSection {
    fn default() -> Self {
        Self {
            poll_interval_ms: default_poll(),
            resync_gap_s: default_resync(),
            speed_timeout_s: default_speed_timeout(),
            max_lag_s: default_max_lag(),
        }
    }
}

/// The whole `arte-svc.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArteServiceConfig {
    /// Model file (`--model` overrides); relative to the configuration directory.
    #[serde(default = "default_model")]
    pub model: PathBuf,
    /// `[knowledge]`: per-road overrides of the road-knowledge rule
    /// (`grip_tcs::knowledge`; also read by tcs-loop and `grip sim`).
    #[serde(default)]
    pub knowledge: grip_tcs::KnowledgeConfig,
    /// Streaming estimator: `hop_s` and `smoothing`.
    #[serde(default)]
    pub stream: StreamConfig,
    /// `[input]`.
    #[serde(default)]
    pub input: InputSection,
    /// `[rt]`.
    #[serde(default)]
    pub rt: RtConfig,
}

fn default_model() -> PathBuf {
    PathBuf::from("models/default.model")
}

impl Default for ArteServiceConfig {
    fn default() -> Self {
        Self {
            model: default_model(),
            knowledge: grip_tcs::KnowledgeConfig::default(),
            stream: StreamConfig::default(),
            input: InputSection::default(),
            rt: RtConfig::default(),
        }
    }
}

impl ServiceConfig for ArteServiceConfig {
    const FILE_NAME: &'static str = "arte-svc.toml";

    /// Range checks (the estimator checks hop and smoothing again when built).
    fn validate(&self, file: &Path) -> Result<(), ConfigError> {
        let bad = |field: &str, reason: String| Err(ConfigError::new(file, field, reason));
        if !(self.stream.hop_s > 0.0 && self.stream.hop_s <= 10.0) {
            return bad(
                "stream.hop_s",
                format!("{} s is outside (0, 10]", self.stream.hop_s),
            );
        }
        if let Smoothing::Hmm { stay, floor } = self.stream.smoothing {
            if !(stay > 0.0 && stay < 1.0) {
                return bad(
                    "stream.smoothing.hmm.stay",
                    format!("{stay} is outside (0, 1)"),
                );
            }
            if !(floor > 0.0 && floor <= 1.0) {
                return bad(
                    "stream.smoothing.hmm.floor",
                    format!("{floor} is outside (0, 1]"),
                );
            }
        }
        let i = &self.input;
        if !(i.poll_interval_ms >= 0.1 && i.poll_interval_ms <= 100.0) {
            return bad(
                "input.poll_interval_ms",
                format!("{} ms is outside [0.1, 100]", i.poll_interval_ms),
            );
        }
        if !(i.resync_gap_s > 0.0 && i.resync_gap_s <= 60.0) {
            return bad(
                "input.resync_gap_s",
                format!("{} s is outside (0, 60]", i.resync_gap_s),
            );
        }
        // a speed older than 10 s says nothing about the tyre noise now
        if !(i.speed_timeout_s > 0.0 && i.speed_timeout_s <= 10.0) {
            return bad(
                "input.speed_timeout_s",
                format!("{} s is outside (0, 10]", i.speed_timeout_s),
            );
        }
        // at least one hop of audio late; at most what a resync allows
        if !(i.max_lag_s >= 0.05 && i.max_lag_s <= 60.0) {
            return bad(
                "input.max_lag_s",
                format!("{} s is outside [0.05, 60]", i.max_lag_s),
            );
        }
        validate_rt(&self.rt, file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
model = "models/x.model"
[stream]
hop_s = 0.05
smoothing = { hmm = { stay = 0.9, floor = 0.01 } }
[input]
poll_interval_ms = 2.0
[rt]
fifo_priority = 50
"#;

    #[test]
    fn parses_and_defaults() {
        let c = ArteServiceConfig::parse(Path::new("a.toml"), GOOD).unwrap();
        assert_eq!(c.model, PathBuf::from("models/x.model"));
        assert_eq!(
            c.stream.smoothing,
            Smoothing::Hmm {
                stay: 0.9,
                floor: 0.01
            }
        );
        assert_eq!(c.input.resync_gap_s, 0.2);
        assert_eq!(c.input.speed_timeout_s, 0.2);
        assert_eq!(c.input.max_lag_s, crate::DEFAULT_MAX_LAG_S);
        let s = ArteServiceConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("[input]", "[input]\nspeed_timeout_s = 0.5"),
        )
        .unwrap();
        assert_eq!(s.input.speed_timeout_s, 0.5);
        let d = ArteServiceConfig::parse(Path::new("a.toml"), "").unwrap();
        assert_eq!(d, ArteServiceConfig::default());
        let n = ArteServiceConfig::parse(
            Path::new("a.toml"),
            "[stream]\nhop_s = 0.1\nsmoothing = \"none\"\n",
        )
        .unwrap();
        assert_eq!(n.stream.smoothing, Smoothing::None);
    }

    #[test]
    fn errors_name_the_field() {
        let e = ArteServiceConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("stay = 0.9", "stay = 1.5"),
        )
        .unwrap_err();
        assert_eq!(e.field, "stream.smoothing.hmm.stay", "{e}");
        let e = ArteServiceConfig::parse(Path::new("a.toml"), &GOOD.replace("hop_s", "hops"))
            .unwrap_err();
        assert!(e.field.starts_with("stream"), "{e}");
        let e = ArteServiceConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("poll_interval_ms = 2.0", "poll_interval_ms = 0.0"),
        )
        .unwrap_err();
        assert_eq!(e.field, "input.poll_interval_ms");
        assert!(
            e.to_string()
                .starts_with("a.toml: field `input.poll_interval_ms`")
        );
        for bad in ["0.0", "0.01", "-1.0", "61.0", "nan"] {
            let e = ArteServiceConfig::parse(
                Path::new("a.toml"),
                &GOOD.replace("[input]", &format!("[input]\nmax_lag_s = {bad}")),
            )
            .unwrap_err();
            assert_eq!(e.field, "input.max_lag_s", "{bad}: {e}");
            assert!(e.to_string().contains("[0.05, 60]"), "{bad}: {e}");
        }
    }

    #[test]
    fn speed_timeout_must_be_positive() {
        for bad in ["0.0", "-0.1", "nan", "inf", "11.0"] {
            let text = GOOD.replace("[input]", &format!("[input]\nspeed_timeout_s = {bad}"));
            let e = ArteServiceConfig::parse(Path::new("dir/arte-svc.toml"), &text).unwrap_err();
            assert_eq!(e.field, "input.speed_timeout_s", "{bad}: {e}");
            let msg = e.to_string();
            assert!(
                msg.starts_with("dir/arte-svc.toml: field `input.speed_timeout_s`")
                    && msg.contains("outside (0, 10]"),
                "{bad}: {msg}"
            );
        }
        // a string is a type error naming the field, not a panic
        let text = GOOD.replace("[input]", "[input]\nspeed_timeout_s = \"fast\"");
        let e = ArteServiceConfig::parse(Path::new("a.toml"), &text).unwrap_err();
        assert!(e.to_string().contains("speed_timeout_s"), "{e}");
    }
}
