//! Streaming estimator: framing, time stamps, smoothing, detection delay.

use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet};
use grip_arte::stream::{
    Classify, Smoothing, StreamConfig, StreamError, StreamEstimator, detection_delays, percentile,
};

/// Two classes from the Rich set's spectral centroid: low tones are class 0,
/// high tones class 1 (a stand-in for a trained model).
struct Centroid {
    idx: usize,
    dim: usize,
}

impl Centroid {
    fn new(cfg: &FeatureConfig) -> Self {
        let names = cfg.names();
        Self {
            idx: names.iter().position(|n| n == "centroid_khz").unwrap(),
            dim: names.len(),
        }
    }
}

impl Classify for Centroid {
    fn n_classes(&self) -> usize {
        2
    }
    fn n_features(&self) -> usize {
        self.dim
    }
    fn predict_proba(&mut self, x: &[f64], out: &mut [f64]) {
        let p1 = 1.0 / (1.0 + (-(x[self.idx] - 2.5) * 4.0).exp());
        out[0] = 1.0 - p1;
        out[1] = p1;
    }
}

fn tone(f: f64, n: usize, start: usize) -> Vec<f32> {
    (start..start + n)
        .map(|i| (0.3 * (2.0 * std::f64::consts::PI * f * i as f64 / 44_100.0).sin()) as f32)
        .collect()
}

fn fcfg() -> FeatureConfig {
    FeatureConfig::new(44_100, FeatureSet::Rich)
}

fn run(
    block: usize,
    x: &[f32],
    cfg: &StreamConfig,
) -> Vec<(u64, f64, f64, usize, usize, Vec<f64>)> {
    let f = fcfg();
    let mut s = StreamEstimator::new(Centroid::new(&f), &f, cfg).unwrap();
    let mut out = Vec::new();
    for b in x.chunks(block) {
        s.push(b, |d| {
            out.push((
                d.seq,
                d.t_start,
                d.t_end,
                d.class,
                d.raw_class,
                d.probs.to_vec(),
            ))
        });
    }
    out
}

#[test]
fn one_decision_per_hop_with_exact_time_stamps() {
    let x = tone(500.0, 44_100, 0);
    let cfg = StreamConfig::default();
    let d = run(1000, &x, &cfg);
    // First decision when the first 0.1 s frame is full, then every hop.
    let hop = (cfg.hop_s * 44_100.0).round() as usize;
    assert_eq!(hop, 1103, "default hop 0.025 s");
    assert_eq!(d.len(), (44_100 - 4410) / hop + 1);
    for (i, e) in d.iter().enumerate() {
        assert_eq!(e.0, i as u64);
        let t_end = (4410 + i * hop) as f64 / 44_100.0;
        assert!((e.2 - t_end).abs() < 1e-12 && (e.1 - (t_end - 0.1)).abs() < 1e-12);
        assert_eq!(e.3, 0);
        assert!((e.5.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn decisions_do_not_depend_on_block_size() {
    let mut x = tone(500.0, 30_000, 0);
    x.extend(tone(6000.0, 30_000, 30_000));
    let cfg = StreamConfig::default();
    let reference = run(60_000, &x, &cfg);
    for block in [1, 17, 256, 2205, 4410, 9999] {
        assert_eq!(run(block, &x, &cfg), reference, "block {block}");
    }
}

#[test]
fn hmm_follows_an_abrupt_change_within_two_hops_of_a_clean_frame() {
    let mut x = tone(500.0, 44_100, 0);
    x.extend(tone(6000.0, 44_100, 44_100));
    let d = run(512, &x, &StreamConfig::default());
    let decisions: Vec<(f64, usize)> = d.iter().map(|e| (e.2, e.3)).collect();
    let delays = detection_delays(&decisions, &[(0.0, 0), (1.0, 1)], 2.0, 0.3);
    let delay = delays[1].expect("change detected");
    // The frame is wholly on the new tone 0.1 s after the change; the HMM
    // must switch by then (it may switch at the half-new frame already).
    assert!(delay <= 0.1 + 1e-9, "delay {delay}");
    assert!(delays[0].unwrap() <= 0.1 + 1e-9);
}

#[test]
fn hmm_ignores_a_single_unconfident_wrong_frame() {
    // A classifier that says 60 % class 1 once, inside a long run of class 0.
    struct Blip {
        n: usize,
    }
    impl Classify for Blip {
        fn n_classes(&self) -> usize {
            2
        }
        fn n_features(&self) -> usize {
            grip_arte::features::N_RICH_DEFAULT
        }
        fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
            self.n += 1;
            let p1 = if self.n == 10 { 0.6 } else { 0.1 };
            out[0] = 1.0 - p1;
            out[1] = p1;
        }
    }
    let f = fcfg();
    for (smoothing, expect_flip) in [
        (StreamConfig::default().smoothing, false),
        (Smoothing::None, true),
    ] {
        let mut s = StreamEstimator::new(
            Blip { n: 0 },
            &f,
            &StreamConfig {
                hop_s: 0.05,
                smoothing,
            },
        )
        .unwrap();
        let mut classes = Vec::new();
        s.push(&tone(500.0, 44_100, 0), |d| classes.push(d.class));
        assert_eq!(
            classes.contains(&1),
            expect_flip,
            "{smoothing:?}: {classes:?}"
        );
    }
}

/// A classifier's NaN, infinite or all-zero output says nothing: with
/// either smoothing every decision stays a finite distribution (uniform
/// without smoothing), never a NaN confidence.
#[test]
fn unusable_classifier_output_gives_finite_decisions() {
    struct Broken {
        dim: usize,
        n: usize,
    }
    impl Classify for Broken {
        fn n_classes(&self) -> usize {
            2
        }
        fn n_features(&self) -> usize {
            self.dim
        }
        fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
            self.n += 1;
            out.copy_from_slice(match self.n % 4 {
                0 => &[f64::NAN, 0.5],
                1 => &[0.0, 0.0],
                2 => &[f64::INFINITY, 0.0],
                _ => &[0.2, 0.8],
            });
        }
    }
    let f = fcfg();
    let dim = FeatureExtractor::new(&f).unwrap().dim();
    for smoothing in [StreamConfig::default().smoothing, Smoothing::None] {
        let cfg = StreamConfig {
            smoothing,
            ..StreamConfig::default()
        };
        let mut s = StreamEstimator::new(Broken { dim, n: 0 }, &f, &cfg).unwrap();
        let mut seen = Vec::new();
        s.push(&tone(500.0, 44_100, 0), |d| {
            assert!(
                d.confidence.is_finite() && d.probs.iter().all(|p| p.is_finite()),
                "{smoothing:?}: {:?}",
                d.probs
            );
            assert!((d.probs.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            seen.push(d.confidence);
        });
        if smoothing == Smoothing::None {
            // three of every four frames say nothing; the fourth is its own
            for (i, c) in seen.iter().enumerate() {
                let want = if (i + 1) % 4 == 3 { 0.8 } else { 0.5 };
                assert_eq!(*c, want, "decision {i}");
            }
        }
    }
}

#[test]
fn construction_errors_are_clear() {
    let f = fcfg();
    let mut bad = Centroid::new(&f);
    bad.dim = 7;
    let e = StreamEstimator::new(bad, &f, &StreamConfig::default()).unwrap_err();
    assert_eq!(
        e,
        StreamError::FeatureCount {
            expected: 7,
            got: 43
        }
    );
    let e = StreamEstimator::new(
        Centroid::new(&f),
        &f,
        &StreamConfig {
            hop_s: 0.0,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("hop_s"));
    let e = StreamEstimator::new(
        Centroid::new(&f),
        &f,
        &StreamConfig {
            hop_s: 0.05,
            smoothing: Smoothing::Hmm {
                stay: 1.0,
                floor: 0.01,
            },
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("stay"));
    let _ = FeatureExtractor::new(&f).unwrap();
}

#[test]
fn reset_restarts_time_and_sequence() {
    let f = fcfg();
    let mut s = StreamEstimator::new(Centroid::new(&f), &f, &StreamConfig::default()).unwrap();
    let x = tone(500.0, 10_000, 0);
    let mut first = Vec::new();
    s.push(&x, |d| first.push((d.seq, d.t_end)));
    s.reset();
    let mut second = Vec::new();
    s.push(&x, |d| second.push((d.seq, d.t_end)));
    assert_eq!(first, second);
}

#[test]
fn detection_delay_definition() {
    // Decisions every 0.05 s: class 0 until 1.1 s, one wrong blip, then 1.
    let mut dec = Vec::new();
    for i in 2..60 {
        let t = i as f64 * 0.05;
        let c = usize::from(!(t < 1.1 || (t - 1.15).abs() < 1e-9));
        dec.push((t, c));
    }
    let d = detection_delays(&dec, &[(0.0, 0), (1.0, 1)], 3.0, 0.2);
    // 1.10 is class 1 but 1.15 is not: it does not persist; 1.20 does.
    assert!((d[1].unwrap() - 0.2).abs() < 1e-9, "{d:?}");
    let never = detection_delays(&dec, &[(0.0, 0), (1.0, 2)], 3.0, 0.2);
    assert_eq!(never[1], None);
    assert_eq!(percentile(&[3.0, 1.0, 2.0, 4.0], 50.0), Some(2.5));
    assert_eq!(percentile(&[1.0, 2.0], 100.0), Some(2.0));
    assert_eq!(percentile(&[], 50.0), None);
    let inf = f64::INFINITY;
    assert_eq!(percentile(&[0.1, inf, inf], 90.0), Some(inf));
    assert_eq!(percentile(&[0.1, 0.2, inf], 75.0), Some(inf));
}

/// A three-class toy classifier with a calibration: frames say class 0
/// with 0.7, then class 2 with 0.8.
struct Calibrated {
    dim: usize,
    n: usize,
    cal: Option<grip_arte::calib::StreamCalibration>,
}

impl Classify for Calibrated {
    fn n_classes(&self) -> usize {
        3
    }
    fn n_features(&self) -> usize {
        self.dim
    }
    fn predict_proba(&mut self, _x: &[f64], out: &mut [f64]) {
        self.n += 1;
        let q = if self.n <= 20 {
            [0.7, 0.2, 0.1]
        } else {
            [0.1, 0.1, 0.8]
        };
        out.copy_from_slice(&q);
    }
    fn calibration(&self) -> Option<&grip_arte::calib::StreamCalibration> {
        self.cal.as_ref()
    }
}

#[test]
fn calibration_maps_the_decided_roads_posterior_and_leaves_the_decision() {
    use grip_arte::calib::{Calibration, StreamCalibration};
    let f = fcfg();
    let dim = FeatureExtractor::new(&f).unwrap().dim();
    let map = Calibration::Platt { a: 0.5, b: -0.5 };
    let cal = StreamCalibration {
        map: map.clone(),
        stream: StreamConfig::default(),
        notes: vec![],
        files: vec![],
    };
    let x = tone(500.0, 44_100, 0);
    let collect = |cal: Option<StreamCalibration>| {
        let c = Calibrated { dim, n: 0, cal };
        let mut s = StreamEstimator::new(c, &f, &StreamConfig::default()).unwrap();
        let mut out = Vec::new();
        s.push(&x, |d| {
            out.push((
                d.class,
                d.confidence,
                d.probs.to_vec(),
                d.posterior.to_vec(),
            ))
        });
        out
    };
    let plain = collect(None);
    let calibrated = collect(Some(cal.clone()));
    assert_eq!(plain.len(), calibrated.len());
    assert!(plain.iter().any(|d| d.0 == 0) && plain.iter().any(|d| d.0 == 2));
    for (u, c) in plain.iter().zip(&calibrated) {
        // Same decision, same filter state.
        assert_eq!(u.0, c.0);
        assert_eq!(u.3, c.3);
        assert_eq!(u.2, u.3, "without calibration probs are the posterior");
        let p = u.3[u.0];
        assert_eq!(u.1, p);
        // The decided road's confidence is the map of its posterior ...
        assert_eq!(c.1, map.apply(p));
        assert_eq!(c.2[c.0], c.1);
        // ... the others share the rest in proportion to their posteriors.
        assert!((c.2.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for j in 0..3 {
            if j != c.0 {
                let want = u.3[j] * (1.0 - c.1) / (1.0 - p);
                assert!((c.2[j] - want).abs() < 1e-12, "{j}: {} vs {want}", c.2[j]);
            }
        }
        // The map lowers an overconfident posterior here.
        assert!(c.1 < p, "{} >= {p}", c.1);
    }
    // A calibration fitted for other stream settings is flagged.
    let other = StreamConfig {
        hop_s: 0.05,
        ..StreamConfig::default()
    };
    let c = Calibrated {
        dim,
        n: 0,
        cal: Some(cal),
    };
    let s = StreamEstimator::new(c, &f, &other).unwrap();
    assert!(s.calibration_mismatch());
    let s = StreamEstimator::new(Centroid::new(&f), &f, &other).unwrap();
    assert!(!s.calibration_mismatch() && s.calibration().is_none());
}
