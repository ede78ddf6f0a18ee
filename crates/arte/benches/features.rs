//! Feature extraction of one 0.1 s frame at 44.1 kHz per feature set; the
//! streaming synthesiser (1024-sample block); the streaming estimator's
//! per-hop cost with a stand-in classifier (the classifier itself is
//! benched in `classify.rs`).

use criterion::{Criterion, criterion_group, criterion_main};
use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet};
use grip_arte::stream::{Classify, StreamConfig, StreamEstimator};
use grip_arte::synth::{NoiseConfig, RoadAudioSynth, Segment, SynthConfig, render};
use std::hint::black_box;

struct Uniform(usize);

impl Classify for Uniform {
    fn n_classes(&self) -> usize {
        6
    }
    fn n_features(&self) -> usize {
        self.0
    }
    fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
        out.fill(1.0 / 6.0);
    }
}

fn bench(c: &mut Criterion) {
    let audio = render(
        &SynthConfig::default(),
        7,
        &[Segment {
            road: 1,
            speed_mps: 20.0 / 3.6,
            duration_s: 0.5,
        }],
    )
    .expect("synth");
    for set in [FeatureSet::Paper20, FeatureSet::Paper7, FeatureSet::Rich] {
        let cfg = FeatureConfig::new(44_100, set);
        let mut ex = FeatureExtractor::new(&cfg).expect("features");
        let frame = &audio[..ex.frame_len()];
        let mut out = vec![0.0; ex.dim()];
        c.bench_function(&format!("features_0.1s_44k1/{}", set.name()), |b| {
            b.iter(|| ex.extract(black_box(frame), &mut out).expect("extract"))
        });
    }
    let cfg = FeatureConfig::new(44_100, FeatureSet::Rich);
    let mut est =
        StreamEstimator::new(Uniform(cfg.dim()), &cfg, &StreamConfig::default()).expect("stream");
    let hop = &audio[..est.hop_len()];
    est.push(&audio[..est.frame_len()], |_| {});
    c.bench_function("stream_hop_0.05s/rich_uniform_classifier", |b| {
        b.iter(|| est.push(black_box(hop), |d| _ = black_box(d.class)))
    });
    let noisy = SynthConfig {
        sample_rate: 44_100,
        noise: Some(NoiseConfig {
            rain: true,
            car: true,
            snr_db: 10.0,
        }),
    };
    for (name, sc) in [("clean", SynthConfig::default()), ("rain_car", noisy)] {
        let mut s = RoadAudioSynth::new(&sc, 1).expect("synth");
        let mut block = vec![0f32; 1024];
        c.bench_function(&format!("synth_fill_1024/{name}"), |b| {
            b.iter(|| s.fill(3, 6.0, black_box(&mut block)))
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
