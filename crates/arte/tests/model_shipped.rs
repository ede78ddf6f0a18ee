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
