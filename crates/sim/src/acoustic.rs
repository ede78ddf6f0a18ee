//! The acoustic road estimator in the offline loop (`grip sim --arte acoustic`).
//!
//! [`AcousticArte`] implements [`RoadEstimator`] with the real ARTE
//! chain instead of a confusion matrix. Every controller cycle `[t, t + dt)`:
//!
//! 1. the plant's true road (catalogue index) is mapped to a road of the
//!    synthesiser by name (`grip_arte::synth::road_index`); roads the
//!    synthesiser has no model for follow [`AcousticConfig::sound_as`]:
//!    the `[synth.aliases]` of `audio-acq.toml`, the rule `grip drive`'s
//!    audio-acq plays them by ([`AcousticConfig::with_config_dir`]; default:
//!    the shipped file's, `asphalt_mf` sounds like `asphalt`, `gravel_table`
//!    like `gravel`, i.e. the same surface with another friction model);
//!    every other road, e.g. `ice`, is [`SoundAs::Silence`]: the
//!    synthesiser's vehicle and microphone sound with no tyre-road
//!    component;
//! 2. `RoadAudioSynth::fill` generates the samples that fall due in the
//!    cycle, `round((t + dt) f_s) − samples so far` (44.1 per millisecond at
//!    44.1 kHz, so the count alternates 44/45 and never drifts), at the
//!    plant's true vehicle speed, with rain and passing-car noise mixed in
//!    at [`AcousticConfig::noise`]'s SNR (default here: none; `grip sim`
//!    defaults to 10 dB, the shipped models' training condition). For speed, samples
//!    are rendered in runs of at most 256 (5.8 ms, the synthesiser's own
//!    filter-retune interval) at the speed of the run's first cycle: causal,
//!    and 6x cheaper than a `fill` per cycle (each call retunes the filters).
//!    A road change starts a new run exactly at its cycle boundary, and a run
//!    always ends where a decision falls due, so the decision comes out in
//!    the cycle whose end it stamps;
//! 3. the samples go through the real `StreamEstimator` (features of the
//!    model's `FeatureConfig`, the model's classifier, HMM smoothing);
//! 4. a decision completed in the cycle becomes an [`Estimate`]: the class
//!    name is mapped to the catalogue index, the confidence is the smoothed
//!    probability of that class, `t_stamp` is the end of the decision's
//!    frame (run time; the decision is available then).
//!
//! [`AcousticArte::update`] allocates nothing (tested with a counting
//! allocator); [`RoadEstimator::reset`] rebuilds the synthesiser from the
//! seed (a new car, tyre and microphone per seed, drawn by the
//! synthesiser) and clears the stream, so a run is a function of its seed.

use std::collections::BTreeMap;
use std::path::Path;

use grip_arte::model::{Model, Predictor};
use grip_arte::stream::{StreamConfig, StreamEstimator};
use grip_arte::synth::{self, NoiseConfig, RoadAudioSynth, SynthConfig};
use grip_physics::RoadCatalogue;

use crate::SimError;
use crate::estimator::{Estimate, RoadEstimator};

/// Synthesiser road index that has no tyre-road sound (out of range on
/// purpose: `RoadAudioSynth::fill` then renders vehicle and microphone only).
const SILENCE: usize = usize::MAX;

/// Longest block handed to the synthesiser and the stream at once, s. A
/// cycle longer than this is processed in several blocks (no allocation).
const MAX_BLOCK_S: f64 = 0.01;

/// Longest run of samples rendered at one speed (the synthesiser's own
/// filter-retune interval). Every `fill` call retunes the synthesiser's
/// filters, which costs far more than the 44 samples of a 1 kHz cycle, so
/// samples due are collected and rendered when this many are due, when the
/// road changes (exactly at the cycle boundary) or when a decision falls
/// due (so that it comes out in its own cycle).
const SPEED_HOLD_SAMPLES: u64 = 256;

/// What a catalogue road sounds like to the acoustic chain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SoundAs {
    /// Like this synthesiser road (one of `grip_arte::synth::ROADS`).
    Road(String),
    /// No tyre-road sound: the vehicle and microphone only.
    Silence,
}

/// Settings of [`AcousticArte`].
#[derive(Debug, Clone, PartialEq)]
pub struct AcousticConfig {
    /// Rain and passing-car noise; `None` (default) for clean road sound.
    pub noise: Option<NoiseConfig>,
    /// Hop and temporal smoothing of the stream (default: 0.025 s, HMM 0.9/0.01).
    pub stream: StreamConfig,
    /// Sound of catalogue roads the synthesiser has no model of, by road
    /// name. A road neither synthesisable by name nor listed here is silent.
    pub sound_as: BTreeMap<String, SoundAs>,
    /// The `[synth.aliases]` entries `sound_as` left out, one line each to
    /// print (an alias of a road the synthesiser has a sound for, ignored
    /// as audio-acq ignores it); empty for the shipped file.
    pub alias_notes: Vec<String>,
}

/// The shipped `config/audio-acq.toml`: [`AcousticConfig::default`]'s
/// sound map is its `[synth.aliases]`, the rule `grip drive`'s audio-acq
/// follows (one home for it).
const SHIPPED_AUDIO_ACQ: &str = include_str!("../../../config/audio-acq.toml");

impl Default for AcousticConfig {
    /// No noise, the default stream, and the sound map of the shipped
    /// `config/audio-acq.toml` (`asphalt_mf` as `asphalt`, `gravel_table` as
    /// `gravel`; every other road without a sound silent).
    fn default() -> Self {
        Self {
            noise: None,
            stream: StreamConfig::default(),
            // the file ships with the crate's workspace; a test parses it
            sound_as: sound_as_of_audio_acq(SHIPPED_AUDIO_ACQ).unwrap_or_default(),
            alias_notes: Vec::new(),
        }
    }
}

/// The sound map of an `audio-acq.toml` (its text): `[synth.aliases]`
/// under the one rule audio-acq follows too
/// (`grip_arte::synth::SynthAliases::resolve`), each ROAD = SOUND a
/// [`SoundAs::Road`] (audio-acq plays ROAD with the synthesiser road SOUND;
/// a road neither synthesisable nor listed is silent, as here); an alias of
/// a road the synthesiser has is left out, as audio-acq ignores it. No
/// `[synth.aliases]`: an empty map. Fails, as audio-acq's start-up does,
/// when the text is not TOML, or an alias is not a string or names a sound
/// the synthesiser does not have (the error's field:
/// `audio-acq.toml: synth.aliases.ROAD`).
pub fn sound_as_of_audio_acq(text: &str) -> Result<BTreeMap<String, SoundAs>, SimError> {
    sound_as_of(Path::new("audio-acq.toml"), text).map(|(sounds, _)| sounds)
}

/// [`sound_as_of_audio_acq`] of `file`'s text, with the notes on ignored
/// aliases; errors name `file`.
fn sound_as_of(
    file: &Path,
    text: &str,
) -> Result<(BTreeMap<String, SoundAs>, Vec<String>), SimError> {
    let doc: synth::AudioAcqAliases = toml::from_str(text)
        .map_err(|e| SimError::invalid(file.display().to_string(), e.to_string()))?;
    let r = doc
        .aliases()
        .resolve(file)
        .map_err(|e| SimError::invalid(format!("{}: {}", e.file.display(), e.field), e.reason))?;
    let sounds = r
        .sounds
        .into_iter()
        .map(|(road, sound)| (road, SoundAs::Road(sound)))
        .collect();
    Ok((sounds, r.notes))
}

impl AcousticConfig {
    /// Rain and passing cars together at `snr_db` (road-sound power over
    /// noise power, following the synthesiser's 1 s running estimate).
    pub fn with_noise_snr(mut self, snr_db: f64) -> Self {
        self.noise = Some(NoiseConfig {
            rain: true,
            car: true,
            snr_db,
        });
        self
    }

    /// The settings with the sound map of the configuration directory
    /// `dir`: its `audio-acq.toml`'s `[synth.aliases]`
    /// ([`sound_as_of_audio_acq`]), the map `grip drive`'s audio-acq plays
    /// the plant's roads with; a directory without `audio-acq.toml` keeps
    /// [`AcousticConfig::default`]'s (the shipped file's). Aliases left out
    /// are noted in `alias_notes`. Errors name the file.
    pub fn with_config_dir(mut self, dir: &Path) -> Result<Self, SimError> {
        let path = dir.join("audio-acq.toml");
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(self),
            Err(e) => {
                return Err(SimError::invalid(
                    path.display().to_string(),
                    format!("cannot read: {e}"),
                ));
            }
        };
        (self.sound_as, self.alias_notes) = sound_as_of(&path, &text)?;
        Ok(self)
    }

    /// Parse `ROAD=SOUND[,ROAD=SOUND...]` (SOUND: a synthesiser road or
    /// `silence`) into `sound_as`, replacing entries of the same road.
    pub fn parse_sound_as(&mut self, spec: &str) -> Result<(), SimError> {
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let Some((road, sound)) = item.split_once('=') else {
                return Err(SimError::invalid(
                    "sound_as",
                    format!("`{item}` is not ROAD=SOUND"),
                ));
            };
            let (road, sound) = (road.trim(), sound.trim());
            let sound = if sound == "silence" {
                SoundAs::Silence
            } else {
                SoundAs::Road(sound.to_owned())
            };
            self.sound_as.insert(road.to_owned(), sound);
        }
        Ok(())
    }
}

/// The real acoustic chain as a road estimator (see the module docs).
pub struct AcousticArte {
    synth_cfg: SynthConfig,
    synth: RoadAudioSynth,
    stream: StreamEstimator<Predictor>,
    /// Catalogue index → synthesiser road index (or [`SILENCE`]).
    synth_road: Vec<usize>,
    /// Model class → catalogue index.
    class_road: Vec<usize>,
    fs: f64,
    buf: Vec<f32>,
    /// Samples rendered and classified since the reset.
    generated: u64,
    /// Samples due (up to the end of the last cycle) since the reset.
    due: u64,
    /// Road and speed of the due samples not rendered yet (their first cycle's).
    pending: Option<(usize, f64)>,
    /// Sample count at which the stream's next decision falls due.
    next_decision: u64,
    /// Run time of the first sample (the `t` of the first update).
    t0: Option<f64>,
    frame_s: f64,
}

impl std::fmt::Debug for AcousticArte {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AcousticArte")
            .field("fs", &self.fs)
            .field("synth_road", &self.synth_road)
            .field("class_road", &self.class_road)
            .field("generated", &self.generated)
            .finish_non_exhaustive()
    }
}

impl AcousticArte {
    /// The chain for `model` on catalogue `roads`. Fails (naming the class
    /// or road) when a model class is not a catalogue road, a `sound_as`
    /// entry names an unknown road or sound, or the model's sample rate is
    /// outside the synthesiser's range.
    pub fn new(
        model: &Model,
        roads: &RoadCatalogue,
        cfg: &AcousticConfig,
    ) -> Result<Self, SimError> {
        let class_road = model
            .classes()
            .iter()
            .map(|c| {
                roads.index_of(c).ok_or_else(|| {
                    SimError::invalid(
                        "model.classes",
                        format!(
                            "model class `{c}` is not a road of the catalogue (roads: {})",
                            roads.names()
                        ),
                    )
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        for (road, sound) in &cfg.sound_as {
            // Entries for roads this catalogue lacks are harmless defaults
            // (the shipped map names asphalt_mf and gravel_table); a sound
            // must exist.
            if let SoundAs::Road(s) = sound
                && synth::road_index(s).is_none()
            {
                return Err(SimError::invalid(
                    format!("sound_as.{road}"),
                    format!(
                        "`{s}` is not a synthesiser road (known: {}, or silence)",
                        synth::ROADS.join(", ")
                    ),
                ));
            }
        }
        let synth_road = roads
            .iter()
            .map(|r| match cfg.sound_as.get(r.name()) {
                Some(SoundAs::Road(s)) => synth::road_index(s).unwrap_or(SILENCE),
                Some(SoundAs::Silence) => SILENCE,
                None => synth::road_index(r.name()).unwrap_or(SILENCE),
            })
            .collect();
        let fcfg = model.feature_config();
        let synth_cfg = SynthConfig {
            sample_rate: fcfg.sample_rate,
            noise: cfg.noise.clone(),
        };
        let synth = RoadAudioSynth::new(&synth_cfg, 0)
            .map_err(|e| SimError::invalid("acoustic.synthesiser", e.to_string()))?;
        let stream = StreamEstimator::new(Predictor::new(model.clone()), fcfg, &cfg.stream)
            .map_err(|e| SimError::invalid("acoustic.stream", e.to_string()))?;
        let fs = f64::from(fcfg.sample_rate);
        let block = ((MAX_BLOCK_S * fs).ceil() as usize).max(1);
        let next_decision = stream.frame_len() as u64;
        Ok(Self {
            synth_cfg,
            synth,
            stream,
            synth_road,
            class_road,
            fs,
            buf: vec![0.0; block],
            generated: 0,
            due: 0,
            pending: None,
            next_decision,
            t0: None,
            frame_s: fcfg.frame_s,
        })
    }

    /// The synthesiser road a catalogue road sounds like (`None`: silence).
    pub fn sound_of(&self, road_index: usize) -> Option<&'static str> {
        self.synth_road
            .get(road_index)
            .and_then(|&i| synth::ROADS.get(i).copied())
    }

    /// Analysis frame length, s.
    pub fn frame_s(&self) -> f64 {
        self.frame_s
    }

    /// Audio sample rate, Hz.
    pub fn sample_rate(&self) -> f64 {
        self.fs
    }

    /// Render the pending samples (road and speed of their first cycle)
    /// through the stream; the last decision, if any completed.
    fn flush(&mut self, t0: f64) -> Option<Estimate> {
        let (road, speed) = self.pending.take()?;
        let mut out = None;
        let frame_s = self.frame_s;
        let Self {
            synth,
            stream,
            buf,
            class_road,
            generated,
            due,
            next_decision,
            ..
        } = self;
        let hop = stream.hop_len() as u64;
        while *generated < *due {
            let n = usize::try_from(*due - *generated)
                .unwrap_or(usize::MAX)
                .min(buf.len());
            let block = &mut buf[..n];
            synth.fill(road, speed, block);
            // A speed-normalised model hears the audio at the vehicle speed
            // it was rendered at (the ECU measures it; see the arte service).
            stream.set_speed(Some(speed));
            stream.push(block, |d| {
                if let Some(&road_index) = class_road.get(d.class) {
                    out = Some(Estimate {
                        road_index,
                        confidence: d.probs.get(d.class).copied().unwrap_or(0.0),
                        t_stamp: t0 + d.t_end,
                        frame_s,
                    });
                }
            });
            *generated += n as u64;
        }
        while *next_decision <= *generated {
            *next_decision += hop.max(1);
        }
        out
    }

    /// Samples synthesised since the last reset.
    #[cfg(test)]
    pub fn samples_generated(&self) -> u64 {
        self.generated
    }
}

impl RoadEstimator for AcousticArte {
    fn reset(&mut self, seed: u64) {
        // The config was validated by the first construction, so this cannot
        // fail; if it ever did, the old synthesiser keeps playing.
        if let Ok(s) = RoadAudioSynth::new(&self.synth_cfg, seed) {
            self.synth = s;
        }
        self.stream.reset();
        self.generated = 0;
        self.due = 0;
        self.pending = None;
        self.next_decision = self.stream.frame_len() as u64;
        self.t0 = None;
    }

    fn update(
        &mut self,
        t: f64,
        dt: f64,
        true_road_index: usize,
        speed_mps: f64,
    ) -> Option<Estimate> {
        if !(t.is_finite() && dt.is_finite() && dt > 0.0) {
            return None;
        }
        let t0 = *self.t0.get_or_insert(t);
        let road = self
            .synth_road
            .get(true_road_index)
            .copied()
            .unwrap_or(SILENCE);
        let mut out = None;
        // Samples due earlier on another road are rendered now, on that road.
        if self.pending.is_some_and(|(r, _)| r != road) {
            out = self.flush(t0);
        }
        let due = ((t + dt - t0) * self.fs).round();
        self.due = if due > 0.0 { due as u64 } else { 0 }.max(self.due);
        if self.due > self.generated && self.pending.is_none() {
            self.pending = Some((road, speed_mps));
        }
        // Render when a decision falls due in this cycle (so that it comes
        // out now) or when a speed-hold block is full.
        if (self.due >= self.next_decision || self.due - self.generated >= SPEED_HOLD_SAMPLES)
            && let Some(e) = self.flush(t0)
        {
            out = Some(e);
        }
        out
    }

    fn name(&self) -> &str {
        "acoustic"
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use grip_arte::eval::Samples;
    use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet};
    use grip_arte::mlp::LmConfig;
    use grip_arte::model::{ClassifierSpec, fit};
    use grip_physics::Road;

    // Counts allocations per thread, so the other tests of this binary
    // running in parallel do not disturb the count.
    #[global_allocator]
    static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;
    fn allocs() -> u64 {
        grip_testkit::thread_allocations()
    }

    pub(crate) fn roads() -> RoadCatalogue {
        RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("gravel", 0.6212, 20.80, 0.0712).unwrap(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
            Road::burckhardt("stone", 1.3713, 6.4565, 0.6691).unwrap(),
            Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap(),
        ])
        .unwrap()
    }

    /// A small real model (asphalt vs snow vs stone, Rich features, MLP),
    /// trained on synthetic frames in a few seconds.
    pub(crate) fn tiny_model() -> Model {
        let fcfg = FeatureConfig::new(44_100, FeatureSet::Rich);
        let mut ex = FeatureExtractor::new(&fcfg).unwrap();
        let mut train = Samples::new(ex.dim());
        let mut buf = vec![0f32; ex.frame_len()];
        let mut row = vec![0.0; ex.dim()];
        let classes = ["asphalt", "snow", "stone"];
        for (c, name) in classes.iter().enumerate() {
            let road = synth::road_index(name).unwrap();
            for rec in 0..4 {
                let mut s = RoadAudioSynth::new(&SynthConfig::default(), 100 + rec + 10 * c as u64)
                    .unwrap();
                for i in 0..15 {
                    s.fill(road, 3.0 + 0.3 * i as f64, &mut buf);
                    ex.extract(&buf, &mut row).unwrap();
                    train.push(&row, c, c * 4 + rec as usize);
                }
            }
        }
        let spec = ClassifierSpec::Mlp {
            lm: LmConfig {
                epochs: 30,
                ..Default::default()
            },
            val_fraction: 0.0,
        };
        let names: Vec<String> = classes.iter().map(|s| (*s).to_owned()).collect();
        fit(&names, &fcfg, &spec, &train).unwrap().0
    }

    /// Drive the estimator like the simulator: 1 kHz cycles, road by time.
    pub(crate) fn drive(
        e: &mut dyn RoadEstimator,
        seed: u64,
        plan: &[(f64, usize)],
        end: f64,
    ) -> Vec<Estimate> {
        e.reset(seed);
        let dt = 1e-3;
        let mut out = Vec::new();
        let n = (end / dt).round() as usize;
        for k in 0..n {
            let t = k as f64 * dt;
            let road = plan
                .iter()
                .rev()
                .find(|p| p.0 <= t + 1e-12)
                .map_or(0, |p| p.1);
            if let Some(x) = e.update(t, dt, road, 4.0 + t) {
                // A decision comes out in the cycle whose end it stamps
                // (stamps are whole samples: the cycle's samples are
                // rounded, so a stamp may lie up to half a sample past it).
                let half_sample = 0.5 / 44_100.0;
                assert!(
                    x.t_stamp <= t + dt + half_sample + 1e-9 && x.t_stamp > t - 1e-9,
                    "{x:?} at {t}"
                );
                out.push(x);
            }
        }
        out
    }

    #[test]
    fn cycle_is_allocation_free_and_deterministic() {
        let model = tiny_model();
        let roads = roads();
        for cfg in [
            AcousticConfig::default(),
            AcousticConfig::default().with_noise_snr(10.0),
        ] {
            let mut e = AcousticArte::new(&model, &roads, &cfg).unwrap();
            e.reset(3);
            let dt = 1e-3;
            // Warm up: the first frame and one decision.
            for k in 0..150 {
                e.update(k as f64 * dt, dt, 0, 5.0);
            }
            let before = allocs();
            let mut decisions = 0;
            for k in 150..1500 {
                let road = [0, 2, 3, 4][(k / 300) % 4];
                // Also a cycle longer than the internal block (several blocks).
                let dt_k = if k == 700 { 0.025 } else { dt };
                if e.update(k as f64 * dt, dt_k, road, 3.0 + k as f64 * 0.01)
                    .is_some()
                {
                    decisions += 1;
                }
            }
            let after = allocs();
            assert!(decisions > 20, "{decisions} decisions");
            assert_eq!(after - before, 0, "{cfg:?}: allocations in update");
        }
        // Same seed, same decisions; another seed, another car.
        let mut e = AcousticArte::new(&model, &roads, &AcousticConfig::default()).unwrap();
        let plan = [(0.0, 0), (0.5, 2), (1.0, 3)];
        let a = drive(&mut e, 7, &plan, 1.5);
        let b = drive(&mut e, 7, &plan, 1.5);
        assert_eq!(a, b);
        assert_eq!(e.samples_generated(), 66_150);
    }

    #[test]
    fn recognises_roads_and_maps_names() {
        let model = tiny_model();
        let roads = roads();
        let mut e = AcousticArte::new(&model, &roads, &AcousticConfig::default()).unwrap();
        assert_eq!(e.sound_of(0), Some("asphalt"));
        assert_eq!(e.sound_of(4), None, "ice is silent");
        let plan = [(0.0, 0), (1.0, 2), (2.0, 3)];
        let est = drive(&mut e, 11, &plan, 3.0);
        // One decision per hop (default 0.025 s = 1103 samples at 44.1 kHz)
        // once the first 0.1 s frame (4410 samples) is full.
        let hop = 1103.0 / 44_100.0;
        assert_eq!(est.len(), ((3.0 - 0.1) / hop) as usize + 1);
        assert!((est[0].t_stamp - 0.1).abs() < 1e-9);
        assert!((est[1].t_stamp - 0.1 - hop).abs() < 1e-9);
        // Late in each segment the decision is that road (catalogue index),
        // with a smoothed confidence in (0.5, 1].
        for (t, road) in [(0.9, 0), (1.9, 2), (2.9, 3)] {
            let d = est.iter().rev().find(|d| d.t_stamp <= t + 1e-9).unwrap();
            assert_eq!(d.road_index, road, "at {t} s: {d:?}");
            assert!(d.confidence > 0.5 && d.confidence <= 1.0, "{d:?}");
        }
    }

    #[test]
    fn bad_model_class_and_sound_are_refused() {
        let model = tiny_model();
        let only_snow = RoadCatalogue::new(vec![
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
            Road::burckhardt("stone", 1.3713, 6.4565, 0.6691).unwrap(),
        ])
        .unwrap();
        let e = AcousticArte::new(&model, &only_snow, &AcousticConfig::default()).unwrap_err();
        assert!(e.to_string().contains("`asphalt`"), "{e}");
        let mut cfg = AcousticConfig::default();
        cfg.parse_sound_as("ice=tarmac").unwrap();
        let e = AcousticArte::new(&model, &roads(), &cfg).unwrap_err();
        assert!(e.to_string().contains("`tarmac`"), "{e}");
        assert!(cfg.parse_sound_as("ice").is_err());
        let mut cfg = AcousticConfig::default();
        cfg.parse_sound_as("ice=snow, asphalt = silence").unwrap();
        let e = AcousticArte::new(&model, &roads(), &cfg).unwrap();
        assert_eq!(e.sound_of(4), Some("snow"));
        assert_eq!(e.sound_of(0), None);
    }

    /// `grip sim --arte acoustic` plays the plant's roads as `grip drive`'s
    /// audio-acq does: by the configuration directory's `audio-acq.toml`
    /// `[synth.aliases]` (a trial's `wet_gravel = "gravel"` was silent in
    /// grip sim, which had the shipped aliases built in). The shipped file
    /// gives exactly the map that was built in.
    #[test]
    fn the_sound_map_is_audio_acq_toml_s_aliases() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let before = BTreeMap::from([
            ("asphalt_mf".to_owned(), SoundAs::Road("asphalt".to_owned())),
            (
                "gravel_table".to_owned(),
                SoundAs::Road("gravel".to_owned()),
            ),
        ]);
        assert_eq!(AcousticConfig::default().sound_as, before);
        let cfg = AcousticConfig::default().with_config_dir(&shipped).unwrap();
        assert_eq!(cfg.sound_as, before);
        // a configuration directory with one more road, mapped to gravel
        let d = tempfile::tempdir().unwrap();
        let text = std::fs::read_to_string(shipped.join("audio-acq.toml")).unwrap();
        let text = text.replace(
            "gravel_table = \"gravel\"\n",
            "gravel_table = \"gravel\"\nwet_gravel = \"gravel\"\n",
        );
        std::fs::write(d.path().join("audio-acq.toml"), &text).unwrap();
        let cfg = AcousticConfig::default().with_config_dir(d.path()).unwrap();
        assert_eq!(
            cfg.sound_as.get("wet_gravel"),
            Some(&SoundAs::Road("gravel".to_owned()))
        );
        assert_eq!(cfg.sound_as.len(), 3);
        // an alias of a road the synthesiser has is ignored, as audio-acq
        // ignores it (it plays snow as snow)
        let with_snow = text.replace("wet_gravel = \"gravel\"\n", "snow = \"gravel\"\n");
        assert_eq!(
            sound_as_of_audio_acq(&with_snow).unwrap(),
            before,
            "{with_snow}"
        );
        let snow_dir = tempfile::tempdir().unwrap();
        std::fs::write(snow_dir.path().join("audio-acq.toml"), &with_snow).unwrap();
        let snowy = AcousticConfig::default()
            .with_config_dir(snow_dir.path())
            .unwrap();
        assert_eq!(snowy.sound_as, before);
        assert_eq!(snowy.alias_notes.len(), 1, "{:?}", snowy.alias_notes);
        assert!(
            snowy.alias_notes[0].contains("field `synth.aliases.snow` = \"gravel\" is ignored"),
            "{:?}",
            snowy.alias_notes
        );
        // an unknown sound is refused as audio-acq refuses it, naming the
        // field, also for a road the synthesiser has (was: ignored here),
        // and so is a value that is not a string
        for (road, bad) in [
            ("wet_gravel", "\"tarmac\""),
            ("snow", "\"tarmac\""),
            ("snow", "3"),
        ] {
            let bad = text.replace("wet_gravel = \"gravel\"\n", &format!("{road} = {bad}\n"));
            let e = sound_as_of_audio_acq(&bad).unwrap_err().to_string();
            assert!(
                e.contains(&format!("audio-acq.toml: synth.aliases.{road}`")),
                "{e}"
            );
        }
        let wet_gravel = RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
            Road::burckhardt("stone", 1.3713, 6.4565, 0.6691).unwrap(),
            Road::burckhardt("wet_gravel", 0.9, 20.0, 0.4).unwrap(),
            Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap(),
        ])
        .unwrap();
        let e = AcousticArte::new(&tiny_model(), &wet_gravel, &cfg).unwrap();
        assert_eq!(e.sound_of(3), Some("gravel"));
        assert_eq!(e.sound_of(4), None, "ice: no alias, silent");
        // no aliases at all: every road without a sound is silent
        std::fs::write(d.path().join("audio-acq.toml"), "[synth]\nseed = 1\n").unwrap();
        let cfg = AcousticConfig::default().with_config_dir(d.path()).unwrap();
        assert!(cfg.sound_as.is_empty());
        // no audio-acq.toml: the shipped map
        let empty = tempfile::tempdir().unwrap();
        let cfg = AcousticConfig::default()
            .with_config_dir(empty.path())
            .unwrap();
        assert_eq!(cfg.sound_as, before);
        // a bad alias names the file and the key
        std::fs::write(
            d.path().join("audio-acq.toml"),
            "[synth.aliases]\nwet_gravel = 3\n",
        )
        .unwrap();
        let e = AcousticConfig::default()
            .with_config_dir(d.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("audio-acq.toml: synth.aliases.wet_gravel"),
            "{e}"
        );
    }
}
