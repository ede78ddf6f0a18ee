//! `audio-acq.toml`: which source, block size, rate, device and real-time
//! settings. Parsed with `grip_config::parse_toml` (unknown fields refused,
//! errors name file, field and line) and range-checked by [`ServiceConfig::validate`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use grip_arte::synth::{ResolvedAliases, SynthAliases};
use grip_config::ConfigError;
use grip_io::rt::RtConfig;
use grip_io::service::{ServiceConfig, validate_rt};
use serde::{Deserialize, Serialize};

use crate::format::FormatSetting;

/// Where the audio comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// An ALSA capture PCM (the microphone on the car, `hw:Loopback,1,0` in HIL tests).
    Alsa,
    /// A WAV file, played once or looped, paced in real time.
    Wav,
    /// Synthetic tyre-road audio following plant-sim's ground truth.
    Synth,
}

impl SourceKind {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            SourceKind::Alsa => "alsa",
            SourceKind::Wav => "wav",
            SourceKind::Synth => "synth",
        }
    }
}

/// `[audio]`: what every source shares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AudioSection {
    /// Source kind (`--source` overrides).
    pub source: SourceKind,
    /// Sample rate of the published blocks, Hz (8000..=192000).
    pub sample_rate: u32,
    /// Samples per block (1..=`grip_msgs::AUDIO_MAX_SAMPLES`).
    pub block_samples: usize,
    /// A bench or rig, where a source other than the microphone is meant:
    /// only then does audio-acq run as a systemd unit on `synth` or `wav`
    /// ([`check_source_under_systemd`]). Default `false`.
    #[serde(default)]
    pub bench: bool,
}

/// Under systemd (the car's deployment) only the microphone is a source,
/// unless `[audio] bench = true`: a car left on the shipped `synth` source
/// would publish silence (no plant-sim, no ground truth) with every unit
/// `active (running)` and ARTE dead, as `can.toml`'s `transport = "auto"`
/// is refused under systemd rather than fall back to a simulated bus.
/// `source` is the effective one (after `--source`); the error names
/// `file`'s `audio.source`.
pub fn check_source_under_systemd(
    file: &std::path::Path,
    audio: &AudioSection,
    under_systemd: bool,
) -> Result<(), grip_config::ConfigError> {
    if !under_systemd || audio.bench || audio.source == SourceKind::Alsa {
        return Ok(());
    }
    Err(grip_config::ConfigError::new(
        file,
        "audio.source",
        format!(
            "\"{}\" under systemd: {}; a unit on the car listens to the microphone (source = \"alsa\"). On a bench or rig where this source is meant, set [audio] bench = true",
            audio.source.name(),
            match audio.source {
                SourceKind::Synth =>
                    "synthetic audio follows plant-sim's ground truth, which a car does not have (it would publish silence)",
                _ => "a recording is not the road under the car",
            }
        ),
    ))
}

/// `[alsa]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlsaSection {
    /// PCM name (`--device` overrides), e.g. `default`, `hw:Loopback,1,0`.
    pub device: String,
    /// Channels to open the device with (1..=32).
    #[serde(default = "one")]
    pub channels: u32,
    /// Which of them is published (0-based, < channels).
    #[serde(default)]
    pub channel: u32,
    /// ALSA period size, frames.
    pub period_frames: usize,
    /// ALSA buffer size, frames (≥ 2 periods).
    pub buffer_frames: usize,
    /// Longest single wait for data, ms; on expiry the loop checks its stop
    /// flag and waits again (no unbounded waits).
    #[serde(default = "default_wait_ms")]
    pub wait_timeout_ms: u32,
    /// Sample format to capture in: `"auto"` (default: the first of S16_LE,
    /// S32_LE, S24_3LE, S24_LE, FLOAT_LE the device offers) or one of them
    /// (an error if the device does not offer it). Converted to S16.
    #[serde(default)]
    pub format: FormatSetting,
    /// Let alsa-lib resample when the device cannot capture at `[audio]
    /// sample_rate` itself. Takes effect only through a plug device
    /// (`plughw:...`, `plug:...`, or a `default` that is one); `hw:`
    /// devices never resample. Default `false`: the rate must be one the
    /// device offers.
    #[serde(default)]
    pub resample: bool,
}

impl AlsaSection {
    /// `device` with the defaults of every other field (what `--device`
    /// uses when the file has no `[alsa]` section).
    pub fn with_device(device: impl Into<String>) -> Self {
        Self {
            device: device.into(),
            channels: 1,
            channel: 0,
            period_frames: 512,
            buffer_frames: 4096,
            wait_timeout_ms: default_wait_ms(),
            format: FormatSetting::Auto,
            resample: false,
        }
    }
}

fn one() -> u32 {
    1
}
fn default_wait_ms() -> u32 {
    200
}

/// `[wav]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WavSection {
    /// The file (`--wav` overrides); relative paths are relative to the
    /// configuration directory.
    pub path: PathBuf,
    /// Start again at the end (`false`: publish the file once, then exit 0).
    #[serde(default = "yes")]
    pub looped: bool,
    /// The file's channel to publish (0-based), as the live ALSA source
    /// publishes its `[alsa] channel`; absent: the average of all channels
    /// (a mono file's only one). A channel the file does not have is an
    /// error naming the file at start-up.
    #[serde(default)]
    pub channel: Option<u16>,
}

fn yes() -> bool {
    true
}

/// What the synth source does when ground truth stops arriving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthLost {
    /// Keep generating the last known road at the last known speed.
    Hold,
    /// Publish digital silence (zeros) until truth returns.
    Silence,
}

/// Noise mixed into the synthetic road sound (see `grip_arte::synth`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthNoise {
    /// Rain.
    #[serde(default)]
    pub rain: bool,
    /// Passing cars.
    #[serde(default)]
    pub car: bool,
    /// Road-sound power over noise power, dB.
    pub snr_db: f64,
}

/// `[synth]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthSection {
    /// Seed of the per-recording variation (tyre, microphone, surfaces).
    #[serde(default = "one64")]
    pub seed: u64,
    /// Ground truth older than this (no new sample for this long) counts as lost, s.
    #[serde(default = "default_truth_timeout")]
    pub truth_timeout_s: f64,
    /// Behaviour while truth is lost (and before the first truth arrives:
    /// always silence then, there is no last road).
    #[serde(default = "default_truth_lost")]
    pub on_truth_lost: TruthLost,
    /// Noise; leave out for clean road sound.
    #[serde(default)]
    pub noise: Option<SynthNoise>,
    /// Catalogue road names the synthesiser does not know, mapped to one it
    /// does (`grip_arte::synth::ROADS`). A road neither known nor aliased
    /// gives vehicle and microphone sound only (no tyre-road sound). The
    /// rule is `grip_arte::synth::SynthAliases::resolve`
    /// ([`SynthSection::resolved_aliases`]): an unknown sound is refused, an
    /// alias of a road the synthesiser knows is ignored (a warning at start-up).
    #[serde(default = "default_aliases")]
    pub aliases: BTreeMap<String, String>,
}

fn one64() -> u64 {
    1
}
fn default_truth_timeout() -> f64 {
    0.5
}
fn default_truth_lost() -> TruthLost {
    TruthLost::Hold
}
fn default_aliases() -> BTreeMap<String, String> {
    BTreeMap::new()
}

impl SynthSection {
    /// `aliases` under the one rule of `grip_arte::synth::SynthAliases::resolve`
    /// (an unknown sound refused; an alias of a road the synthesiser has a
    /// sound for ignored, with a note to print). Errors name `file`.
    pub fn resolved_aliases(&self, file: &Path) -> Result<ResolvedAliases, ConfigError> {
        SynthAliases::from(&self.aliases)
            .resolve(file)
            .map_err(|e| ConfigError::new(e.file, e.field, e.reason))
    }
}

impl Default for SynthSection {
    fn default() -> Self {
        Self {
            seed: 1,
            truth_timeout_s: default_truth_timeout(),
            on_truth_lost: default_truth_lost(),
            noise: None,
            aliases: default_aliases(),
        }
    }
}

/// The whole `audio-acq.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcqConfig {
    /// `[audio]`.
    pub audio: AudioSection,
    /// `[alsa]` (needed when the source is alsa).
    #[serde(default)]
    pub alsa: Option<AlsaSection>,
    /// `[wav]` (needed when the source is wav).
    #[serde(default)]
    pub wav: Option<WavSection>,
    /// `[synth]`.
    #[serde(default)]
    pub synth: SynthSection,
    /// `[rt]`: SCHED_FIFO priority, mlockall, CPUs, cpu_dma_latency.
    #[serde(default)]
    pub rt: RtConfig,
}

impl ServiceConfig for AcqConfig {
    const FILE_NAME: &'static str = "audio-acq.toml";

    /// Range checks; the error names `file`, the field and the reason.
    fn validate(&self, file: &Path) -> Result<(), ConfigError> {
        let bad = |field: &str, reason: String| Err(ConfigError::new(file, field, reason));
        let a = &self.audio;
        if !(8_000..=192_000).contains(&a.sample_rate) {
            return bad(
                "audio.sample_rate",
                format!("{} Hz is outside 8000..=192000", a.sample_rate),
            );
        }
        if !(1..=grip_msgs::AUDIO_MAX_SAMPLES).contains(&a.block_samples) {
            return bad(
                "audio.block_samples",
                format!(
                    "{} is outside 1..={} (grip_msgs::AUDIO_MAX_SAMPLES)",
                    a.block_samples,
                    grip_msgs::AUDIO_MAX_SAMPLES
                ),
            );
        }
        match (a.source, &self.alsa, &self.wav) {
            (SourceKind::Alsa, None, _) => {
                return bad(
                    "alsa",
                    "source is \"alsa\" but there is no [alsa] section".into(),
                );
            }
            (SourceKind::Wav, _, None) => {
                return bad(
                    "wav",
                    "source is \"wav\" but there is no [wav] section".into(),
                );
            }
            _ => {}
        }
        if let Some(al) = &self.alsa {
            if al.device.is_empty() {
                return bad("alsa.device", "is empty".into());
            }
            if !(1..=32).contains(&al.channels) {
                return bad(
                    "alsa.channels",
                    format!("{} is outside 1..=32", al.channels),
                );
            }
            if al.channel >= al.channels {
                return bad(
                    "alsa.channel",
                    format!("{} is not below channels = {}", al.channel, al.channels),
                );
            }
            if !(16..=65_536).contains(&al.period_frames) {
                return bad(
                    "alsa.period_frames",
                    format!("{} is outside 16..=65536", al.period_frames),
                );
            }
            if al.buffer_frames < 2 * al.period_frames || al.buffer_frames > 1 << 20 {
                return bad(
                    "alsa.buffer_frames",
                    format!(
                        "{} must be at least 2 periods ({}) and at most 1048576",
                        al.buffer_frames,
                        2 * al.period_frames
                    ),
                );
            }
            if !(1..=10_000).contains(&al.wait_timeout_ms) {
                return bad(
                    "alsa.wait_timeout_ms",
                    format!("{} is outside 1..=10000", al.wait_timeout_ms),
                );
            }
        }
        let s = &self.synth;
        if !(s.truth_timeout_s > 0.0 && s.truth_timeout_s <= 60.0) {
            return bad(
                "synth.truth_timeout_s",
                format!("{} s is outside (0, 60]", s.truth_timeout_s),
            );
        }
        if let Some(n) = &s.noise
            && !grip_arte::synth::SNR_LIMITS_DB.contains(&n.snr_db)
        {
            let limits = grip_arte::synth::SNR_LIMITS_DB;
            return bad(
                "synth.noise.snr_db",
                format!(
                    "{} dB is outside {}..={}",
                    n.snr_db,
                    limits.start(),
                    limits.end()
                ),
            );
        }
        s.resolved_aliases(file)?;
        validate_rt(&self.rt, file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Under systemd only the microphone, unless `[audio] bench`; outside
    /// systemd (grip drive, a shell) any source.
    #[test]
    fn a_source_other_than_the_microphone_under_systemd_needs_bench() {
        let f = std::path::Path::new("audio-acq.toml");
        let mut a = AudioSection {
            source: SourceKind::Synth,
            sample_rate: 44_100,
            block_samples: 1024,
            bench: false,
        };
        check_source_under_systemd(f, &a, false).unwrap();
        let e = check_source_under_systemd(f, &a, true).unwrap_err();
        assert_eq!(e.field, "audio.source");
        assert!(
            e.to_string().contains("\"synth\" under systemd")
                && e.to_string().contains("set [audio] bench = true"),
            "{e}"
        );
        a.source = SourceKind::Wav;
        assert!(check_source_under_systemd(f, &a, true).is_err());
        a.bench = true;
        check_source_under_systemd(f, &a, true).unwrap();
        a.bench = false;
        a.source = SourceKind::Alsa;
        check_source_under_systemd(f, &a, true).unwrap();
    }

    const GOOD: &str = r#"
[audio]
source = "synth"
sample_rate = 44100
block_samples = 1024
[alsa]
device = "hw:Loopback,1,0"
period_frames = 512
buffer_frames = 4096
[synth]
seed = 3
aliases = { asphalt_mf = "asphalt" }
[rt]
fifo_priority = 60
"#;

    #[test]
    fn good_config_parses() {
        let c = AcqConfig::parse(Path::new("a.toml"), GOOD).unwrap();
        assert_eq!(c.audio.source, SourceKind::Synth);
        assert_eq!(c.alsa.as_ref().unwrap().channels, 1);
        assert_eq!(c.alsa.as_ref().unwrap().format, FormatSetting::Auto);
        assert!(!c.alsa.as_ref().unwrap().resample);
        assert_eq!(c.synth.seed, 3);
        assert_eq!(c.synth.on_truth_lost, TruthLost::Hold);
        assert_eq!(c.rt.fifo_priority, Some(60));
    }

    #[test]
    fn errors_name_file_field_and_reason() {
        let e = AcqConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("block_samples = 1024", "block_samples = 5000"),
        )
        .unwrap_err();
        assert_eq!(e.field, "audio.block_samples");
        assert!(
            e.to_string()
                .starts_with("a.toml: field `audio.block_samples`: 5000")
        );
        let e = AcqConfig::parse(Path::new("a.toml"), &GOOD.replace("seed = 3", "sed = 3"))
            .unwrap_err();
        assert_eq!(e.field, "synth.sed");
        let e = AcqConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("\"asphalt\" }", "\"tarmac\" }"),
        )
        .unwrap_err();
        assert_eq!(e.field, "synth.aliases.asphalt_mf");
        let e = AcqConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("source = \"synth\"", "source = \"wav\""),
        )
        .unwrap_err();
        assert_eq!(e.field, "wav");
        let e = AcqConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace("buffer_frames = 4096", "buffer_frames = 600"),
        )
        .unwrap_err();
        assert_eq!(e.field, "alsa.buffer_frames");
    }

    /// `[synth.aliases]` follows the one rule of grip-arte: an alias of a
    /// road the synthesiser has is ignored with a note, an unknown sound
    /// is refused (for such a road too), a value that is not a string is
    /// refused naming the field.
    #[test]
    fn aliases_follow_the_one_rule() {
        let f = Path::new("a.toml");
        let with = |aliases: &str| {
            AcqConfig::parse(f, &GOOD.replace("{ asphalt_mf = \"asphalt\" }", aliases))
        };
        let c = with("{ asphalt_mf = \"asphalt\", snow = \"gravel\" }").unwrap();
        let r = c.synth.resolved_aliases(f).unwrap();
        assert_eq!(
            r.sounds,
            BTreeMap::from([("asphalt_mf".to_owned(), "asphalt".to_owned())])
        );
        assert_eq!(r.notes.len(), 1);
        assert!(
            r.notes[0].starts_with("a.toml: field `synth.aliases.snow` = \"gravel\" is ignored"),
            "{:?}",
            r.notes
        );
        let e = with("{ snow = \"tarmac\" }").unwrap_err();
        assert_eq!(e.field, "synth.aliases.snow");
        assert!(
            e.to_string().starts_with(
                "a.toml: field `synth.aliases.snow`: `tarmac` is not a road the synthesiser knows"
            ),
            "{e}"
        );
        let e = with("{ wet_gravel = 3 }").unwrap_err();
        assert_eq!(e.field, "synth.aliases.wet_gravel", "{e}");
    }

    /// The good configuration with `extra` added to its `[alsa]` section.
    fn with_alsa(extra: &str) -> Result<AcqConfig, ConfigError> {
        AcqConfig::parse(
            Path::new("a.toml"),
            &GOOD.replace(
                "buffer_frames = 4096",
                &format!("buffer_frames = 4096\n{extra}"),
            ),
        )
    }

    #[test]
    fn alsa_format_and_resample_parse() {
        let with = with_alsa;
        for (text, want) in [
            ("auto", FormatSetting::Auto),
            ("S16_LE", FormatSetting::S16Le),
            ("S32_LE", FormatSetting::S32Le),
            ("S24_3LE", FormatSetting::S24_3Le),
            ("S24_LE", FormatSetting::S24Le),
            ("FLOAT_LE", FormatSetting::FloatLe),
        ] {
            let c = with(&format!("format = \"{text}\"")).unwrap();
            assert_eq!(c.alsa.unwrap().format, want, "{text}");
        }
        let c = with("resample = true").unwrap();
        assert!(c.alsa.unwrap().resample);
    }

    #[test]
    fn alsa_format_and_resample_errors_name_the_field() {
        let with = |extra: &str| with_alsa(extra).unwrap_err();
        for bad in ["S24_BE", "s16_le", "S8", "float", ""] {
            let e = with(&format!("format = \"{bad}\""));
            assert_eq!(e.field, "alsa.format", "{bad}: {e}");
            let msg = e.to_string();
            assert!(msg.starts_with("a.toml: field `alsa.format`"), "{msg}");
            assert!(msg.contains("line 10"), "{msg}");
            for name in ["auto", "S16_LE", "S32_LE", "S24_3LE", "S24_LE", "FLOAT_LE"] {
                assert!(msg.contains(name), "the error lists {name}: {msg}");
            }
        }
        let e = with("format = 32");
        assert_eq!(e.field, "alsa.format", "{e}");
        let e = with("resample = \"yes\"");
        assert_eq!(e.field, "alsa.resample", "{e}");
        assert!(e.to_string().contains("line 10"), "{e}");
        let e = with("resampling = true");
        assert_eq!(e.field, "alsa.resampling", "{e}");
    }
}
