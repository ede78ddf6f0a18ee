//! Classification cost of the shipped models: one feature vector, and
//! features + classification of one 0.1 s frame at 44.1 kHz.
//!
//! Reads `config/models/{default,paper}.model` (run from anywhere; the path
//! is relative to this crate).

use criterion::{Criterion, criterion_group, criterion_main};
use grip_arte::features::FeatureExtractor;
use grip_arte::model::Model;
use grip_arte::synth::{Segment, SynthConfig, render, road_index};
use std::hint::black_box;
use std::path::PathBuf;

fn load(name: &str) -> Model {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/models")
        .join(name);
    let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()));
    Model::from_bytes(&bytes).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn bench(c: &mut Criterion) {
    let road = road_index("gravel").unwrap_or(0);
    let audio = render(
        &SynthConfig::default(),
        7,
        &[Segment {
            road,
            speed_mps: 20.0 / 3.6,
            duration_s: 0.5,
        }],
    )
    .expect("synth");
    for name in ["default", "paper"] {
        let model = load(&format!("{name}.model"));
        let mut pred = model.predictor();
        let mut ex = FeatureExtractor::new(model.feature_config()).expect("features");
        let frame = &audio[..ex.frame_len()];
        let mut feat = vec![0.0; ex.dim()];
        ex.extract(frame, &mut feat).expect("extract");
        let mut probs = vec![0.0; model.classes().len()];
        c.bench_function(&format!("classify_vector/{name}"), |b| {
            b.iter(|| {
                pred.predict_proba(black_box(&feat), &mut probs)
                    .expect("predict")
            })
        });
        c.bench_function(&format!("frame_features_and_classify/{name}"), |b| {
            b.iter(|| {
                ex.extract(black_box(frame), &mut feat).expect("extract");
                pred.predict_proba(&feat, &mut probs).expect("predict")
            })
        });
        if model.feature_config().speed_norm.is_some() {
            // Worst case of a speed-normalised model: the speed changes
            // between every two frames, so the warped filter banks are
            // rebuilt for every frame (the frame above runs at the
            // reference speed, where they are built once).
            let mut k = 0u32;
            c.bench_function(
                &format!("frame_features_and_classify/{name}_speed_changing"),
                |b| {
                    b.iter(|| {
                        k = k.wrapping_add(1);
                        ex.set_speed(Some(if k.is_multiple_of(2) {
                            5.0 / 3.6
                        } else {
                            35.0 / 3.6
                        }));
                        ex.extract(black_box(frame), &mut feat).expect("extract");
                        pred.predict_proba(&feat, &mut probs).expect("predict")
                    })
                },
            );
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
