//! The model files shipped in `config/models/` load, are small, and classify.

use grip_arte::features::{FeatureExtractor, FeatureSet};
use grip_arte::model::{Classifier, Model};
use grip_arte::synth::{Segment, SynthConfig, render, road_index};
use std::path::PathBuf;

fn load(name: &str) -> (Model, usize) {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/models")
        .join(name);
    let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let m = Model::from_bytes(&bytes).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    (m, bytes.len())
}

#[test]
fn shipped_models_load_and_classify() {
    for (name, set) in [
        ("default.model", FeatureSet::Rich),
        ("paper.model", FeatureSet::Paper7),
    ] {
        let (m, size) = load(name);
        assert!(size < 4_000_000, "{name} is {size} bytes");
        assert_eq!(m.feature_config().set, set, "{name}");
        assert_eq!(m.classes().len(), 6, "{name}");
        if name == "paper.model" {
            let Classifier::Mlp(net) = m.classifier() else {
                panic!("paper model is not an MLP")
            };
            assert_eq!(net.sizes(), [7, 4, 3, 2, 6]);
        }
        let road = road_index("gravel").unwrap();
        let audio = render(
            &SynthConfig::default(),
            12_345,
            &[Segment {
                road,
                speed_mps: 20.0 / 3.6,
                duration_s: 1.0,
            }],
        )
        .unwrap();
        let mut ex = FeatureExtractor::new(m.feature_config()).unwrap();
        let mut feat = vec![0.0; ex.dim()];
        let mut p = m.predictor();
        let mut probs = vec![0.0; 6];
        let mut hits = 0;
        let n = audio.len() / ex.frame_len();
        for f in 0..n {
            ex.extract(
                &audio[f * ex.frame_len()..(f + 1) * ex.frame_len()],
                &mut feat,
            )
            .unwrap();
            let c = p.predict_proba(&feat, &mut probs).unwrap();
            assert!((probs.iter().sum::<f64>() - 1.0).abs() < 1e-6);
            hits += usize::from(m.classes()[c] == "gravel");
        }
        // Clean gravel at 20 km/h: the default model gets most frames right.
        if name == "default.model" {
            assert!(hits * 2 > n, "{name}: {hits}/{n} gravel frames");
        }
    }
}

/// The default model carries the streaming estimator's confidence
/// calibration (format v2, added by `grip calibrate`, crate README
/// "Confidence calibration"); the paper model has none (format v1).
/// Without the calibration the default model hashes to the value below:
/// the classifier `grip train --calib-data` wrote on 2026-12-02 with the
/// command of the crate README ("Results"); a retrained or edited
/// classifier fails here until the README and this hash say so.
#[test]
fn default_model_is_calibrated_and_its_classifier_unchanged() {
    use grip_arte::calib::Calibration;
    use grip_arte::stream::StreamConfig;
    use grip_digest::sha256_hex;
    let (m, _) = load("default.model");
    assert_eq!(m.format_version(), 2);
    let cal = m.calibration().expect("default.model has a calibration");
    assert!(
        matches!(cal.map, Calibration::Isotonic { .. }),
        "{:?}",
        cal.map
    );
    assert_eq!(cal.stream, StreamConfig::default());
    // Monotone, within [0, 1], and lower than the saturated posterior.
    let mut prev = 0.0;
    for i in 0..=10_000 {
        let c = cal.map.apply(f64::from(i) / 10_000.0);
        assert!((0.0..=1.0).contains(&c) && c >= prev, "{i}: {c}");
        prev = c;
    }
    assert!(cal.map.apply(0.9988) < 0.99);
    let uncalibrated = m.with_calibration(None).unwrap().to_bytes().unwrap();
    assert_eq!(
        sha256_hex(&uncalibrated),
        "5d58c42ca78e561d77dfacab40579c2c6f01e432b4f860c5e33b354d62c57d2f"
    );
    let (p, _) = load("paper.model");
    assert_eq!((p.format_version(), p.calibration()), (1, None));
}

/// The shipped models were written before `meta.speeds` existed: they
/// load without it (their bytes, and so their SHA-256 that the reference
/// drive and the hash above pin, are unchanged), and their training speeds
/// come from `grip train`'s note in their metadata, "training speeds:
/// 4.0-29.8 km/h" (the manifest's slowest and fastest recording of the
/// log-uniform 4-30 km/h training set).
#[test]
fn shipped_models_give_their_training_speeds_from_their_notes() {
    use grip_arte::speeds::{SpeedRange, TrainingSpeeds};
    for name in ["default.model", "paper.model"] {
        let (m, _) = load(name);
        assert_eq!(m.meta.speeds, None, "{name}");
        assert_eq!(
            m.training_speeds(),
            TrainingSpeeds::FromNote(SpeedRange::new(4.0, 29.8).unwrap()),
            "{name}"
        );
    }
}
