//! The ARTE model file loader (`Model::from_bytes`: header, checksum, JSON,
//! cross-field validation), then what arte builds from a model at start-up
//! and runs per frame: the predictor, the streaming estimator (feature
//! extractor, classifier, smoothing, calibration) over one frame of audio.
//!
//! Each input is loaded twice: as it is, and with its header's checksum
//! replaced by the right one (version token kept), so that mutations of the
//! JSON payload reach the parser and the validation instead of stopping at
//! the checksum.
//!
//! Checked besides "no panic": a model that loads saves and reloads to an
//! equal model; the predictor and the estimator give finite probabilities
//! that sum to 1.
#![no_main]

use grip_arte::model::{MAGIC, Model};
use grip_arte::stream::{StreamConfig, StreamEstimator};
use grip_digest::sha256_hex;
use libfuzzer_sys::fuzz_target;

fn check_probs(p: &[f64], what: &str) {
    assert!(
        p.iter().all(|v| v.is_finite() && *v >= 0.0),
        "{what}: {p:?}"
    );
    let s: f64 = p.iter().sum();
    assert!((s - 1.0).abs() < 1e-6, "{what}: sum {s}");
}

fn exercise(m: &Model, audio: &[u8]) {
    let bytes = m.to_bytes().expect("a loaded model serialises");
    let again = Model::from_bytes(&bytes).expect("a saved model reloads");
    assert_eq!(&again, m, "save/reload changed the model");

    let mut pred = m.predictor();
    let mut out = vec![0.0; m.classes().len()];
    let x = vec![0.0; m.dim()];
    pred.predict_proba(&x, &mut out)
        .expect("right sizes, finite input");
    check_probs(&out, "predict_proba(0)");

    let Ok(mut est) =
        StreamEstimator::new(m.predictor(), m.feature_config(), &StreamConfig::default())
    else {
        return;
    };
    // one frame of audio from the input's bytes (a frame is at most 2 s)
    let n = est.frame_len();
    let block: Vec<f32> = (0..n)
        .map(|i| {
            let b = audio.get(i % audio.len().max(1)).copied().unwrap_or(0);
            (f32::from(b) - 128.0) / 128.0
        })
        .collect();
    est.push(&block, |d| {
        check_probs(d.probs, "decision probs");
        assert!(d.class < d.probs.len());
        assert!(d.confidence.is_finite());
    });
}

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Model::from_bytes(data) {
        exercise(&m, data);
    }
    let Some(nl) = data.iter().position(|&b| b == b'\n') else {
        return;
    };
    let payload = &data[nl + 1..];
    let version = std::str::from_utf8(&data[..nl])
        .ok()
        .and_then(|h| h.split_whitespace().nth(1))
        .unwrap_or("v1");
    let mut fixed = format!("{MAGIC} {version} sha256={}\n", sha256_hex(payload)).into_bytes();
    fixed.extend_from_slice(payload);
    if let Ok(m) = Model::from_bytes(&fixed) {
        exercise(&m, payload);
    }
});
