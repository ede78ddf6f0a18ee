//! Model files: round trip, refusal of corrupt/mismatched/unknown files, fitting.

use grip_arte::eval::Samples;
use grip_arte::features::{FeatureConfig, FeatureSet};
use grip_arte::mlp::LmConfig;
use grip_arte::model::{ClassifierSpec, Model, ModelError, cross_validate, fit};
use grip_arte::svm::{Kernel, SvmConfig};
use grip_digest::sha256_hex;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn classes() -> Vec<String> {
    ["asphalt", "gravel", "snow", "stone"]
        .map(String::from)
        .to_vec()
}

/// 4 classes × `recs` recordings × 20 frames in 7 dimensions; each recording
/// has its own offset (recording-level variation) around its class centre.
fn dataset(recs: usize, seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nd = Normal::new(0.0, 1.0).unwrap();
    let mut s = Samples::new(7);
    let mut g = 0;
    for c in 0..4 {
        for _ in 0..recs {
            let off: Vec<f64> = (0..7).map(|_| 0.3 * nd.sample(&mut rng)).collect();
            for _ in 0..20 {
                let row: Vec<f64> = (0..7)
                    .map(|d| {
                        let centre = if d % 4 == c { 3.0 } else { 0.0 };
                        100.0 + 10.0 * (centre + off[d] + 0.7 * nd.sample(&mut rng))
                    })
                    .collect();
                s.push(&row, c, g);
            }
            g += 1;
        }
    }
    s
}

fn paper7() -> FeatureConfig {
    FeatureConfig::new(44_100, FeatureSet::Paper7)
}

fn mlp_spec() -> ClassifierSpec {
    ClassifierSpec::Mlp {
        lm: LmConfig {
            seed: 4,
            ..Default::default()
        },
        val_fraction: 0.2,
    }
}

fn svm_spec() -> ClassifierSpec {
    ClassifierSpec::Svm {
        cfg: SvmConfig {
            c: 10.0,
            kernel: Kernel::Rbf { gamma: 0.1 },
            prob_folds: 3,
            ..Default::default()
        },
        max_per_class: 60,
    }
}

fn models() -> Vec<Model> {
    let data = dataset(6, 1);
    [mlp_spec(), svm_spec()]
        .iter()
        .map(|spec| fit(&classes(), &paper7(), spec, &data).unwrap().0)
        .collect()
}

/// Replaces the payload and recomputes the checksum, so only the intended defect remains.
fn with_payload(payload: &[u8]) -> Vec<u8> {
    let mut out = format!("GRIP-ARTE-MODEL v1 sha256={}\n", sha256_hex(payload)).into_bytes();
    out.extend_from_slice(payload);
    out
}

fn payload_json(m: &Model) -> serde_json::Value {
    let bytes = m.to_bytes().unwrap();
    let nl = bytes.iter().position(|&b| b == b'\n').unwrap();
    serde_json::from_slice(&bytes[nl + 1..]).unwrap()
}

#[test]
fn round_trip_is_exact() {
    let test = dataset(2, 99);
    for m in models() {
        let a = m.to_bytes().unwrap();
        let back = Model::from_bytes(&a).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.to_bytes().unwrap(), a, "re-serialised bytes differ");
        let (mut p, mut q) = (m.predictor(), back.predictor());
        let (mut u, mut v) = ([0.0; 4], [0.0; 4]);
        for i in 0..test.len() {
            let cu = p.predict_proba(test.row(i), &mut u).unwrap();
            let cv = q.predict_proba(test.row(i), &mut v).unwrap();
            assert_eq!(cu, cv);
            assert_eq!(
                u.map(f64::to_bits),
                v.map(f64::to_bits),
                "probabilities not bit-identical"
            );
            assert!((u.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
        assert!(a.len() < 200_000, "model is {} bytes", a.len());
    }
}

#[test]
fn fitted_models_classify_held_out_recordings() {
    let test = dataset(3, 7);
    for m in models() {
        let acc = m.evaluate(&test).unwrap().metrics().accuracy;
        assert!(acc > 0.9, "{}: accuracy {acc}", m.classifier().describe());
    }
}

#[test]
fn fit_is_deterministic() {
    let data = dataset(5, 3);
    for spec in [mlp_spec(), svm_spec()] {
        let a = fit(&classes(), &paper7(), &spec, &data)
            .unwrap()
            .0
            .to_bytes()
            .unwrap();
        let b = fit(&classes(), &paper7(), &spec, &data)
            .unwrap()
            .0
            .to_bytes()
            .unwrap();
        assert_eq!(a, b);
    }
}

#[test]
fn cross_validation_scores_every_frame_once() {
    let data = dataset(5, 5);
    let conf = cross_validate(&classes(), &paper7(), &mlp_spec(), &data, 5, 1).unwrap();
    assert_eq!(conf.total() as usize, data.len());
    assert!(conf.metrics().macro_recall > 0.85, "{}", conf.metrics());
}

#[test]
fn corrupt_files_are_refused_with_the_reason() {
    let m = &models()[0];
    let good = m.to_bytes().unwrap();

    let mut flipped = good.clone();
    let at = good.len() - 10;
    flipped[at] ^= 0x01;
    let e = Model::from_bytes(&flipped).unwrap_err();
    assert!(matches!(e, ModelError::Checksum { .. }), "{e}");
    assert!(e.to_string().contains("checksum mismatch"), "{e}");

    let e = Model::from_bytes(&good[..good.len() / 2]).unwrap_err();
    assert!(matches!(e, ModelError::Checksum { .. }), "truncated: {e}");
    let nl = good.iter().position(|&b| b == b'\n').unwrap();
    let e = Model::from_bytes(&good[..nl - 3]).unwrap_err();
    assert!(
        matches!(e, ModelError::NotAModel(_)),
        "truncated header: {e}"
    );
    assert!(matches!(
        Model::from_bytes(b"").unwrap_err(),
        ModelError::NotAModel(_)
    ));
    let e = Model::from_bytes(b"{\"version\": 1}\n{}").unwrap_err();
    assert!(e.to_string().contains("GRIP-ARTE-MODEL"), "{e}");

    let e = Model::from_bytes(&with_payload(b"{\"version\": 1, \"classes\": [")).unwrap_err();
    assert!(matches!(e, ModelError::Json(_)), "{e}");
}

#[test]
fn unknown_versions_are_refused() {
    let m = &models()[0];
    let good = m.to_bytes().unwrap();
    let mut v2 = b"GRIP-ARTE-MODEL v2".to_vec();
    v2.extend_from_slice(&good["GRIP-ARTE-MODEL v1".len()..]);
    let e = Model::from_bytes(&v2).unwrap_err();
    assert!(
        matches!(&e, ModelError::UnknownVersion { found } if found == "2"),
        "{e}"
    );
    assert!(e.to_string().contains("version 2"), "{e}");

    // Header v1 but the payload claims version 7.
    let mut j = payload_json(m);
    j["version"] = 7.into();
    let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
    assert!(matches!(e, ModelError::UnknownVersion { .. }), "{e}");
}

#[test]
fn mismatched_parts_are_refused() {
    for m in models() {
        // Three class names for a four-output classifier.
        let mut j = payload_json(&m);
        j["classes"].as_array_mut().unwrap().pop();
        let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
        assert!(
            matches!(
                e,
                ModelError::Mismatch {
                    field: "classifier",
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("3 classes"), "{e}");

        // Paper20 config (20 features) for a 7-input model.
        let mut j = payload_json(&m);
        j["feature_config"]["set"] = "paper20".into();
        let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
        assert!(
            matches!(
                e,
                ModelError::Mismatch {
                    field: "standardiser",
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("20 features"), "{e}");

        // A zero std.
        let mut j = payload_json(&m);
        j["standardiser"]["std"][2] = 0.0.into();
        let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
        assert!(
            matches!(
                e,
                ModelError::Mismatch {
                    field: "standardiser.std",
                    ..
                }
            ),
            "{e}"
        );

        // Duplicate class name.
        let mut j = payload_json(&m);
        j["classes"][1] = "asphalt".into();
        let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
        assert!(e.to_string().contains("appears twice"), "{e}");

        // Unknown field.
        let mut j = payload_json(&m);
        j["extra"] = 1.into();
        let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
        assert!(matches!(e, ModelError::Json(_)), "{e}");
    }
}

#[test]
fn predictor_refuses_bad_vectors() {
    let m = &models()[1];
    let mut p = m.predictor();
    let mut out = [0.0; 4];
    assert!(matches!(
        p.predict_proba(&[0.0; 6], &mut out),
        Err(ModelError::FeatureCount {
            got: 6,
            expected: 7
        })
    ));
    assert!(matches!(
        p.predict_proba(&[0.0; 7], &mut [0.0; 3]),
        Err(ModelError::OutputCount { .. })
    ));
    let mut x = [100.0; 7];
    x[4] = f64::NAN;
    assert!(matches!(
        p.predict_proba(&x, &mut out),
        Err(ModelError::NotFinite { index: 4 })
    ));
}

#[test]
fn paper7_fit_prunes_paper20_rows_on_the_training_set() {
    // 20 columns: only columns 1 (LPC), 12 (PS) and 17 (cepstrum) carry the class.
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let nd = Normal::new(0.0, 1.0).unwrap();
    let mut s = Samples::new(20);
    for g in 0..24 {
        let c = g % 4;
        for _ in 0..10 {
            let row: Vec<f64> = (0..20)
                .map(|d| {
                    nd.sample(&mut rng)
                        + if [1, 12, 17].contains(&d) {
                            4.0 * c as f64
                        } else {
                            0.0
                        }
                })
                .collect();
            s.push(&row, c, g);
        }
    }
    let (m, _) = fit(&classes(), &paper7(), &mlp_spec(), &s).unwrap();
    let sel = &m.feature_config().selection;
    assert_eq!(sel.len(), 7);
    assert_eq!(m.dim(), 7);
    for want in [1, 12, 17] {
        assert!(
            sel.contains(&want),
            "selection {sel:?} misses informative column {want}"
        );
    }
    assert!(m.evaluate(&s).unwrap().metrics().accuracy > 0.95);
}
