//! Model files: round trip, refusal of corrupt/mismatched/unknown files, fitting.

use grip_arte::calib::{Calibration, StreamCalibration};
use grip_arte::eval::Samples;
use grip_arte::eval::holdout_groups;
use grip_arte::features::{FeatureConfig, FeatureSet};
use grip_arte::mlp::LmConfig;
use grip_arte::model::{
    ClassifierSpec, FitCheck, FitReport, Model, ModelError, PoorFit, cross_validate,
    cross_validate_with, fit, fit_with_split,
};
use grip_arte::stream::{StreamConfig, StreamEstimator};
use grip_arte::svm::{Kernel, SvmConfig};
use grip_arte::synth::{Segment, SynthConfig, render};
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
    // the progress callback: once per fold, in order, and the same result
    let mut calls = Vec::new();
    let again = cross_validate_with(&classes(), &paper7(), &mlp_spec(), &data, 5, 1, |k, n| {
        calls.push((k, n))
    })
    .unwrap();
    assert_eq!(calls, [(1, 5), (2, 5), (3, 5), (4, 5), (5, 5)]);
    assert_eq!(again.total(), conf.total());
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
    let mut v3 = b"GRIP-ARTE-MODEL v3".to_vec();
    v3.extend_from_slice(&good["GRIP-ARTE-MODEL v1".len()..]);
    let e = Model::from_bytes(&v3).unwrap_err();
    assert!(
        matches!(&e, ModelError::UnknownVersion { found } if found == "3"),
        "{e}"
    );
    assert!(e.to_string().contains("version 3"), "{e}");
    assert!(e.to_string().contains("versions 1 and 2"), "{e}");

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

/// Loads a payload edited by `edit` (checksum recomputed).
fn load_edited(m: &Model, edit: impl FnOnce(&mut serde_json::Value)) -> Result<Model, ModelError> {
    let mut j = payload_json(m);
    edit(&mut j);
    Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap()))
}

#[test]
fn svm_pair_tables_need_each_pair_of_classes_once() {
    let m = &models()[1];
    let pairs = |j: &serde_json::Value| j["classifier"]["svm"]["pairs"].clone();
    let ab = |j: &serde_json::Value, k: usize| {
        let p = &pairs(j)[k];
        (p["a"].as_u64().unwrap(), p["b"].as_u64().unwrap())
    };
    let j = payload_json(m);
    assert_eq!(pairs(&j).as_array().unwrap().len(), 6, "4 classes, 6 pairs");
    let (a0, b0) = ab(&j, 0);
    // pair 3 made a second machine for pair 0's classes, as stored and
    // the other way round: 6 machines, but one pair of classes has none
    // (its probabilities would stay 0 and the coupling divide by zero)
    for (a, b) in [(a0, b0), (b0, a0)] {
        let e = load_edited(m, |j| {
            let p = &mut j["classifier"]["svm"]["pairs"][3];
            p["a"] = a.into();
            p["b"] = b.into();
        })
        .unwrap_err();
        assert!(matches!(e, ModelError::Svm(_)), "{e}");
        let e = e.to_string();
        assert!(
            e.contains("field `pairs`")
                && e.contains("pair 3")
                && e.contains("pair 0")
                && e.contains(&format!("classes {} and {}", a0.min(b0), a0.max(b0))),
            "{e}"
        );
    }
    // the pairs in another order are the same machines
    let mut reordered = load_edited(m, |j| {
        j["classifier"]["svm"]["pairs"]
            .as_array_mut()
            .unwrap()
            .reverse();
    })
    .unwrap()
    .predictor();
    let mut out = [0.0; 4];
    reordered.predict_proba(&[100.0; 7], &mut out).unwrap();
    assert!((out.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{out:?}");
}

#[test]
fn absurd_dimensions_are_refused_not_overflowed() {
    let ms = models();
    // an SVM of 2^33 classes: n(n-1) does not fit 64 bits
    let e = load_edited(&ms[1], |j| {
        j["classifier"]["svm"]["n_classes"] = (1u64 << 33).into();
    })
    .unwrap_err();
    assert!(matches!(e, ModelError::Svm(_)), "{e}");
    assert!(e.to_string().contains("too many"), "{e}");
    // an MLP whose weight count (2^32 + 1) · 2^32 does not fit 64 bits
    let e = load_edited(&ms[0], |j| {
        j["classifier"]["mlp"]["sizes"] = serde_json::json!([7, 1u64 << 32, 1u64 << 32, 4]);
    })
    .unwrap_err();
    assert!(matches!(e, ModelError::Mlp(_)), "{e}");
    assert!(
        e.to_string().contains("more weights than can be counted"),
        "{e}"
    );
}

#[test]
fn a_std_below_the_writers_floor_is_refused() {
    let m = &models()[0];
    // the writer stores a std below 1e-12 as 1, so a file with one is not
    // its own, and it would blow the feature up towards infinity
    let e = load_edited(m, |j| j["standardiser"]["std"][2] = 1e-300.into()).unwrap_err();
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
    assert!(e.to_string().contains("entry 2 = 1e-300"), "{e}");
    load_edited(m, |j| j["standardiser"]["std"][2] = 1e-12.into()).unwrap();
}

/// Weights of `sizes` (layer by layer; per unit its inputs' weights, then
/// its bias): hidden units 0 weights and bias 1, output units `w` everywhere.
fn saturated_weights(sizes: &[usize], w: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let last = sizes.len() - 2;
    for (l, p) in sizes.windows(2).enumerate() {
        for _ in 0..p[1] {
            for _ in 0..p[0] {
                out.push(if l == last { w } else { 0.0 });
            }
            out.push(if l == last { w } else { 1.0 });
        }
    }
    out
}

#[test]
fn a_classifier_output_that_is_not_finite_reads_as_uniform() {
    let m = &models()[0];
    let sizes: Vec<usize> =
        serde_json::from_value(payload_json(m)["classifier"]["mlp"]["sizes"].clone()).unwrap();
    assert!(sizes.len() >= 3, "{sizes:?}: needs a hidden layer");
    // valid weights (finite), but every output unit sums to +inf: the
    // softmax gives inf − inf = NaN
    let huge = load_edited(m, |j| {
        j["classifier"]["mlp"]["weights"] = serde_json::json!(saturated_weights(&sizes, f64::MAX));
    })
    .unwrap();
    let mut p = huge.predictor();
    let mut out = [0.0; 4];
    let class = p.predict_proba(&[100.0; 7], &mut out).unwrap();
    assert_eq!((class, out), (0, [0.25; 4]));
    // what the stream makes of it without smoothing: a finite confidence
    let cfg = StreamConfig {
        smoothing: grip_arte::stream::Smoothing::None,
        ..StreamConfig::default()
    };
    let mut est = StreamEstimator::new(huge.predictor(), huge.feature_config(), &cfg).unwrap();
    let x: Vec<f32> = (0..8820)
        .map(|i| ((i * 7919) % 200) as f32 / 1000.0 - 0.1)
        .collect();
    let mut decisions = 0;
    est.push(&x, |d| {
        decisions += 1;
        assert_eq!(d.confidence, 0.25, "{:?}", d.probs);
        assert!(d.probs.iter().chain(d.raw).all(|v| v.is_finite()));
    });
    assert!(decisions > 0);
    // an ordinary model is untouched by the guard: its probabilities as before
    let mut q = m.predictor();
    let test = dataset(1, 5);
    q.predict_proba(test.row(0), &mut out).unwrap();
    assert!(
        out.iter().all(|v| v.is_finite() && *v > 0.0 && *v < 1.0),
        "{out:?}"
    );
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

fn calibrations() -> Vec<StreamCalibration> {
    [
        Calibration::Temperature { t: 2.0114 },
        Calibration::Platt {
            a: 0.6371,
            b: -0.8078,
        },
        Calibration::Isotonic {
            x: vec![0.31, 0.6, 0.9, 0.998_878_1],
            y: vec![0.05, 0.55, 0.8, 0.987_654_321],
        },
    ]
    .into_iter()
    .map(|map| StreamCalibration {
        map,
        stream: StreamConfig::default(),
        notes: vec!["test".into()],
        files: vec![],
    })
    .collect()
}

/// Decisions of a stream estimator over a few seconds of synthetic audio:
/// (class, probabilities as bits, confidence as bits).
fn stream_outputs(m: &Model) -> Vec<(usize, Vec<u64>, u64)> {
    let audio = render(
        &SynthConfig::default(),
        3,
        &[
            Segment {
                road: 0,
                speed_mps: 5.0,
                duration_s: 1.0,
            },
            Segment {
                road: 2,
                speed_mps: 5.0,
                duration_s: 1.0,
            },
        ],
    )
    .unwrap();
    let mut est =
        StreamEstimator::new(m.predictor(), m.feature_config(), &StreamConfig::default()).unwrap();
    let mut out = Vec::new();
    est.push(&audio, |d| {
        out.push((
            d.class,
            d.probs.iter().map(|p| p.to_bits()).collect(),
            d.confidence.to_bits(),
        ));
    });
    out
}

#[test]
fn calibration_round_trip_is_exact() {
    let m = models().remove(0);
    let plain = m.to_bytes().unwrap();
    for cal in calibrations() {
        let c = m.clone().with_calibration(Some(cal.clone())).unwrap();
        assert_eq!(c.format_version(), 2);
        let bytes = c.to_bytes().unwrap();
        assert!(bytes.starts_with(b"GRIP-ARTE-MODEL v2 sha256="));
        let back = Model::from_bytes(&bytes).unwrap();
        assert_eq!(back, c);
        assert_eq!(back.calibration(), Some(&cal));
        assert_eq!(
            back.to_bytes().unwrap(),
            bytes,
            "re-serialised bytes differ"
        );
        // The mapping is bit for bit the same ...
        let map = &back.calibration().unwrap().map;
        for i in 0..=1000 {
            let p = f64::from(i) / 1000.0;
            assert_eq!(map.apply(p).to_bits(), cal.map.apply(p).to_bits(), "{p}");
        }
        // ... and so is what the stream reports.
        let (a, b) = (stream_outputs(&c), stream_outputs(&back));
        assert!(a.len() > 50);
        assert_eq!(a, b);
        // Removing the calibration gives back the version 1 file byte for
        // byte: the classifier part is untouched.
        assert_eq!(
            back.with_calibration(None).unwrap().to_bytes().unwrap(),
            plain
        );
    }
}

#[test]
fn version_1_files_load_without_calibration() {
    let m = models().remove(0);
    let v1 = m.to_bytes().unwrap();
    assert!(v1.starts_with(b"GRIP-ARTE-MODEL v1 sha256="));
    let back = Model::from_bytes(&v1).unwrap();
    assert_eq!(back.format_version(), 1);
    assert!(back.calibration().is_none());
    assert!(
        !payload_json(&back)
            .as_object()
            .unwrap()
            .contains_key("calibration")
    );
    // Without calibration the stream reports the filter's posterior itself.
    let mut est = StreamEstimator::new(
        back.predictor(),
        back.feature_config(),
        &StreamConfig::default(),
    )
    .unwrap();
    let audio = render(
        &SynthConfig::default(),
        4,
        &[Segment {
            road: 1,
            speed_mps: 5.0,
            duration_s: 0.5,
        }],
    )
    .unwrap();
    let mut n = 0;
    est.push(&audio, |d| {
        assert_eq!(d.probs, d.posterior);
        assert_eq!(d.confidence, d.posterior[d.class]);
        n += 1;
    });
    assert!(n > 10);
}

#[test]
fn calibration_and_version_must_agree() {
    let m = models().remove(0);
    let cal = calibrations().remove(0);
    let c = m.clone().with_calibration(Some(cal)).unwrap();
    // A version 2 header over a payload without calibration.
    let mut j = payload_json(&m);
    j["version"] = 2.into();
    let payload = serde_json::to_vec(&j).unwrap();
    let mut f = format!("GRIP-ARTE-MODEL v2 sha256={}\n", sha256_hex(&payload)).into_bytes();
    f.extend_from_slice(&payload);
    let e = Model::from_bytes(&f).unwrap_err();
    assert!(
        matches!(
            e,
            ModelError::Mismatch {
                field: "calibration",
                ..
            }
        ),
        "{e}"
    );
    // A calibration in a version 1 payload.
    let mut j = payload_json(&c);
    j["version"] = 1.into();
    let e = Model::from_bytes(&with_payload(&serde_json::to_vec(&j).unwrap())).unwrap_err();
    assert!(
        matches!(
            e,
            ModelError::Mismatch {
                field: "calibration",
                ..
            }
        ),
        "{e}"
    );
    // A version 2 payload under a version 1 header.
    let e = Model::from_bytes(&with_payload(
        &serde_json::to_vec(&payload_json(&c)).unwrap(),
    ))
    .unwrap_err();
    assert!(
        matches!(
            e,
            ModelError::Mismatch {
                field: "version",
                ..
            }
        ),
        "{e}"
    );
    // A calibration that falls is refused, naming the field.
    let mut j = payload_json(&c);
    j["calibration"]["map"] = serde_json::json!({"platt": {"a": -1.0, "b": 0.0}});
    let payload = serde_json::to_vec(&j).unwrap();
    let mut f = format!("GRIP-ARTE-MODEL v2 sha256={}\n", sha256_hex(&payload)).into_bytes();
    f.extend_from_slice(&payload);
    let e = Model::from_bytes(&f).unwrap_err();
    assert!(matches!(e, ModelError::Calib(_)), "{e}");
    assert!(
        e.to_string().contains("calibration") && e.to_string().contains("`a`"),
        "{e}"
    );
}

/// `meta.speeds`, the training recordings' vehicle speeds: written and read
/// back exactly; a file without it (every model written before it existed)
/// loads, says "training speeds not recorded" (or reads `grip train`'s
/// note on them) and writes back byte-identical; a range that is not one
/// is refused naming the field.
#[test]
fn training_speeds_round_trip_and_old_files_load() {
    use grip_arte::speeds::{SpeedRange, TrainingSpeeds};
    let old = models().remove(0);
    assert_eq!(old.meta.speeds, None);
    let old_bytes = old.to_bytes().unwrap();
    assert!(
        !String::from_utf8_lossy(&old_bytes).contains("\"speeds\""),
        "no field written when there is none"
    );
    let back = Model::from_bytes(&old_bytes).unwrap();
    assert_eq!(back.training_speeds(), TrainingSpeeds::NotRecorded);
    assert_eq!(
        back.training_speeds().describe(),
        "training speeds not recorded"
    );
    assert_eq!(back.to_bytes().unwrap(), old_bytes);

    // with the range: exact round trip, and the field in the payload
    let mut m = old.clone();
    m.meta.speeds = SpeedRange::new(4.017, 29.843);
    let bytes = m.to_bytes().unwrap();
    let back = Model::from_bytes(&bytes).unwrap();
    assert_eq!(back, m);
    assert_eq!(back.to_bytes().unwrap(), bytes);
    assert_eq!(
        payload_json(&m)["meta"]["speeds"],
        serde_json::json!({"min_kmh": 4.017, "max_kmh": 29.843})
    );
    let r = back.training_speeds();
    assert_eq!(
        r,
        TrainingSpeeds::Recorded(SpeedRange::new(4.017, 29.843).unwrap())
    );
    assert_eq!(r.describe(), "4.0-29.8 km/h");
    // the same with a calibration (format v2)
    let cal = m
        .clone()
        .with_calibration(Some(calibrations().remove(0)))
        .unwrap();
    let back = Model::from_bytes(&cal.to_bytes().unwrap()).unwrap();
    assert_eq!(back.meta.speeds, m.meta.speeds);

    // an old file whose notes carry `grip train`'s line on the speeds
    let mut noted = old.clone();
    noted.meta.notes = vec![
        "training speeds: 4.0-29.8 km/h".into(),
        "svm: C = 10".into(),
    ];
    let back = Model::from_bytes(&noted.to_bytes().unwrap()).unwrap();
    assert_eq!(back.meta.speeds, None);
    assert_eq!(
        back.training_speeds(),
        TrainingSpeeds::FromNote(SpeedRange::new(4.0, 29.8).unwrap())
    );
    assert_eq!(
        back.training_speeds().describe(),
        "4.0-29.8 km/h (from the model's training notes)"
    );
    // the field wins over the note
    noted.meta.speeds = SpeedRange::new(5.0, 20.0);
    assert_eq!(noted.training_speeds().range(), SpeedRange::new(5.0, 20.0));

    for bad in [
        serde_json::json!({"min_kmh": 30.0, "max_kmh": 4.0}),
        serde_json::json!({"min_kmh": -1.0, "max_kmh": 4.0}),
    ] {
        let e = load_edited(&old, |j| j["meta"]["speeds"] = bad.clone()).unwrap_err();
        assert!(e.to_string().contains("meta.speeds"), "{e}");
    }
    let e = load_edited(&old, |j| {
        j["meta"]["speeds"] = serde_json::json!({"min_kmh": 4.0});
    })
    .unwrap_err();
    assert!(matches!(e, ModelError::Json(_)), "{e}");
}

/// 4 classes x 2 recordings x 20 frames, the user trial's shape (`grip
/// train` on 2 recordings per class): the recording `spec`'s validation
/// split holds out of each class sounds like the next class, so whatever
/// the training side teaches raises the validation error.
fn contradicting_validation(spec: &ClassifierSpec) -> Samples {
    let ClassifierSpec::Mlp { lm, val_fraction } = spec else {
        unreachable!("an MLP spec")
    };
    let groups: Vec<usize> = (0..8).collect();
    let labels: Vec<usize> = groups.iter().map(|g| g / 2).collect();
    let (_, held) = holdout_groups(&labels, &groups, 4, *val_fraction, lm.seed).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let nd = Normal::new(0.0, 1.0).unwrap();
    let mut s = Samples::new(7);
    for g in 0..8 {
        let c = g / 2;
        let sounds_like = if held.contains(&g) { (c + 1) % 4 } else { c };
        for _ in 0..20 {
            let row: Vec<f64> = (0..7)
                .map(|d| if d == sounds_like { 3.0 } else { 0.0 } + 0.3 * nd.sample(&mut rng))
                .collect();
            s.push(&row, c, g);
        }
    }
    s
}

/// The user trial's case (2 recordings per class; `best epoch 0`, the
/// written model the random initial network): the final fit is scored on
/// its own frames and said to be poor, naming why.
#[test]
fn a_fit_that_never_left_its_initial_weights_is_a_poor_fit() {
    let spec = ClassifierSpec::Mlp {
        lm: LmConfig {
            epochs: 100,
            ..Default::default()
        },
        val_fraction: 0.15,
    };
    let data = contradicting_validation(&spec);
    let (m, rep, split) = fit_with_split(&classes(), &paper7(), &spec, &data).unwrap();
    let FitReport::Mlp(lm) = &rep else {
        unreachable!()
    };
    assert_eq!(lm.best_epoch, 0, "{lm:?}");
    assert!(lm.kept_initial_weights());
    // one recording of each class held out, the other trains
    assert_eq!((split.train.len(), split.val.len()), (80, 80));
    let check = FitCheck::new(&m, &rep, &data, &split).unwrap();
    assert_eq!((check.train_recordings, check.val_recordings), (4, 4));
    assert_eq!(check.train.total(), 80);
    assert_eq!(check.val.as_ref().unwrap().total(), 80);
    let problems = check.problems();
    let k = check.kept_initial.unwrap();
    assert!(k.validated && k.epochs > 0, "{k:?}");
    assert!(
        matches!(problems.first(), Some(PoorFit::KeptInitialWeights(_))),
        "{problems:?}"
    );
    let said = problems[0].to_string();
    assert!(
        said.contains("never improved on its random initial weights")
            && said.contains("best epoch 0")
            && said.contains("untrained initial network"),
        "{said}"
    );
    // no epoch at all is the same: the initial network
    let none = ClassifierSpec::Mlp {
        lm: LmConfig {
            epochs: 0,
            ..Default::default()
        },
        val_fraction: 0.0,
    };
    let (m, rep, split) = fit_with_split(&classes(), &paper7(), &none, &data).unwrap();
    let check = FitCheck::new(&m, &rep, &data, &split).unwrap();
    assert!(check.val.is_none() && check.train.total() == 160);
    let said = check.problems()[0].to_string();
    assert!(said.contains("ran no Levenberg-Marquardt epoch"), "{said}");
}

/// Features that carry nothing (every frame the same): the model cannot
/// beat always answering the most common class on its own training
/// frames, and says so (the MLP does improve its training error here, by
/// learning the class shares: no kept initial weights).
#[test]
fn a_model_no_better_than_the_most_common_class_is_a_poor_fit() {
    let mut s = Samples::new(7);
    // asphalt 3 recordings, the others 1: asphalt is 50 % of the frames
    for (g, c) in [0, 0, 0, 1, 2, 3].into_iter().enumerate() {
        for _ in 0..10 {
            s.push(&[1.0; 7], c, g);
        }
    }
    let mlp = ClassifierSpec::Mlp {
        lm: LmConfig::default(),
        val_fraction: 0.0,
    };
    for spec in [mlp, svm_spec()] {
        let (m, rep, split) = fit_with_split(&classes(), &paper7(), &spec, &s).unwrap();
        let check = FitCheck::new(&m, &rep, &s, &split).unwrap();
        assert_eq!(check.majority, (0, 30));
        assert!(check.kept_initial.is_none(), "{rep:?}");
        let problems = check.problems();
        assert_eq!(problems.len(), 1, "{problems:?}");
        let PoorFit::NoBetterThanMajority {
            correct,
            frames,
            class,
            majority,
        } = &problems[0]
        else {
            panic!("{problems:?}")
        };
        assert!(*correct <= 30 && *frames == 60 && class == "asphalt" && *majority == 30);
        let said = problems[0].to_string();
        assert!(
            said.contains("no better than always answering `asphalt`")
                && said.contains("(30 of 60, 50.0 %)"),
            "{said}"
        );
    }
}

/// A normal fit: no problem, and its own figures are those of the written
/// model on its training and validation recordings (disjoint, together
/// every frame).
#[test]
fn a_normal_fit_scores_its_own_frames_and_is_no_poor_fit() {
    let data = dataset(6, 1);
    for spec in [mlp_spec(), svm_spec()] {
        let (m, rep, split) = fit_with_split(&classes(), &paper7(), &spec, &data).unwrap();
        assert_eq!(
            (m.clone(), rep.clone()),
            fit(&classes(), &paper7(), &spec, &data).unwrap()
        );
        let check = FitCheck::new(&m, &rep, &data, &split).unwrap();
        assert!(check.problems().is_empty(), "{:?}", check.problems());
        assert!(check.kept_initial.is_none());
        let acc = check.train.metrics().accuracy;
        assert!(acc > 0.9, "training accuracy {acc}");
        assert_eq!(
            check.train.metrics().accuracy,
            m.evaluate(&data.subset(&split.train))
                .unwrap()
                .metrics()
                .accuracy
        );
        match &check.val {
            Some(v) => {
                assert!(matches!(spec, ClassifierSpec::Mlp { .. }));
                assert!(v.metrics().accuracy > 0.8, "{}", v.metrics());
                assert_eq!(check.train_recordings + check.val_recordings, 24);
                let mut all: Vec<usize> = split.train.iter().chain(&split.val).copied().collect();
                all.sort_unstable();
                assert_eq!(all, (0..data.len()).collect::<Vec<_>>());
            }
            None => {
                assert!(matches!(spec, ClassifierSpec::Svm { .. }));
                assert_eq!(check.train.total() as usize, data.len());
            }
        }
    }
    // a split that does not fit the data is an error, not a panic
    let (m, rep, _) = fit_with_split(&classes(), &paper7(), &svm_spec(), &data).unwrap();
    let bad = grip_arte::model::FitSplit {
        train: vec![data.len()],
        val: Vec::new(),
    };
    let e = FitCheck::new(&m, &rep, &data, &bad).unwrap_err();
    assert!(e.to_string().contains("split"), "{e}");
}
