//! Shared by the arte service tests: a small model trained on synthetic
//! audio (deterministic), the road table from the shipped catalogue, and
//! blocks of synthetic audio.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use grip_arte::eval::Samples;
use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet};
use grip_arte::mlp::LmConfig;
use grip_arte::model::{ClassifierSpec, Model, fit};
use grip_arte::stream::Classify;
use grip_arte::synth::{RoadAudioSynth, SynthConfig, road_index};
use grip_arte_svc::{ClassKnowledge, EstimateSink, road_table};
use grip_io::ipc::IpcError;
use grip_msgs::{AUDIO_MAX_SAMPLES, AudioBlock, RoadEstimate};

pub const RATE: u32 = 44_100;
pub const CLASSES: [&str; 4] = ["asphalt", "gravel", "snow", "stone"];

pub fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// An MLP (one hidden layer of 16) on the Rich features of 0.1 s frames:
/// `recordings` synthetic recordings per class (seeds 100.., speeds 6..18
/// m/s), 20 frames each.
pub fn train_model(recordings: usize) -> Model {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let mut ex = FeatureExtractor::new(&fcfg).unwrap();
    let mut data = Samples::new(ex.dim());
    let mut frame = vec![0f32; fcfg.frame_len()];
    let mut row = vec![0.0; ex.dim()];
    for r in 0..recordings {
        let mut synth = RoadAudioSynth::new(&SynthConfig::default(), 100 + r as u64).unwrap();
        for (c, name) in CLASSES.iter().enumerate() {
            let road = road_index(name).unwrap();
            let speed = 6.0 + 12.0 * (r as f64 / recordings.max(2).saturating_sub(1) as f64);
            // settle the filters on this road first
            synth.fill(road, speed, &mut frame);
            for _ in 0..20 {
                synth.fill(road, speed, &mut frame);
                ex.extract(&frame, &mut row).unwrap();
                data.push(&row, c, r * CLASSES.len() + c);
            }
        }
    }
    let classes: Vec<String> = CLASSES.iter().map(|s| s.to_string()).collect();
    let spec = ClassifierSpec::Mlp {
        lm: LmConfig {
            hidden: vec![16],
            epochs: 150,
            ..Default::default()
        },
        val_fraction: 0.0,
    };
    fit(&classes, &fcfg, &spec, &data).unwrap().0
}

pub fn roads_for(model: &Model) -> Vec<ClassKnowledge> {
    let dir = config_dir();
    let roads = grip_config::load_roads(dir.join("roads.toml")).unwrap();
    let rule = grip_config::ConfigDir::new(&dir)
        .road_table(&roads)
        .unwrap();
    road_table(
        model.classes(),
        &roads,
        &rule,
        Path::new("test.model"),
        &dir.join("roads.toml"),
    )
    .unwrap()
}

/// Synthetic audio as a sequence of blocks: `segments` of (road name,
/// speed m/s, seconds), blocks of `block` samples, stamps from `t0_ns`.
pub fn blocks(
    seed: u64,
    segments: &[(&str, f64, f64)],
    block: usize,
    t0_ns: u64,
) -> Vec<AudioBlock> {
    assert!(block <= AUDIO_MAX_SAMPLES);
    let mut synth = RoadAudioSynth::new(&SynthConfig::default(), seed).unwrap();
    let mut out = Vec::new();
    let mut buf = vec![0f32; block];
    let mut total = 0u64;
    for &(road, speed, secs) in segments {
        let ri = road_index(road).unwrap();
        let n_blocks = (secs * f64::from(RATE) / block as f64).round() as usize;
        for _ in 0..n_blocks {
            synth.fill(ri, speed, &mut buf);
            let mut b = AudioBlock::zeroed();
            b.seq = out.len() as u64;
            b.stamp_ns = t0_ns + (u128::from(total) * 1_000_000_000 / u128::from(RATE)) as u64;
            b.sample_rate = RATE;
            b.n_samples = block as u32;
            for (d, &s) in b.samples.iter_mut().zip(&buf) {
                *d = (f64::from(s) * 32767.0).round().clamp(-32768.0, 32767.0) as i16;
            }
            out.push(b);
            total += block as u64;
        }
    }
    out
}

/// A stand-in classifier with fixed class probabilities, for tests that must
/// not depend on what a model hears.
pub struct Toy {
    /// Feature vector length it accepts.
    pub dim: usize,
    /// The probabilities it always returns (one per class).
    pub probs: &'static [f64],
}

impl Classify for Toy {
    fn n_classes(&self) -> usize {
        self.probs.len()
    }
    fn n_features(&self) -> usize {
        self.dim
    }
    fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
        out.copy_from_slice(self.probs);
    }
}

/// Keeps every estimate sent to it.
#[derive(Default)]
pub struct VecSink(pub Vec<RoadEstimate>);

impl EstimateSink for VecSink {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), IpcError> {
        self.0.push(*e);
        Ok(())
    }
}
