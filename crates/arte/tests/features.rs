//! Feature extraction: LPC, spectrum, cepstrum, robustness.

use grip_arte::features::lpc::{autocorrelation_biased, levinson_durbin};
use grip_arte::features::{
    FeatureConfig, FeatureError, FeatureExtractor, FeatureSet, Prefilter, real_cepstrum,
};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn cfg(set: FeatureSet) -> FeatureConfig {
    FeatureConfig::new(44_100, set)
}

#[test]
fn ar2_coefficients_recovered_by_lpc() {
    // x[n] = 1.3 x[n-1] - 0.6 x[n-2] + e[n]  (poles inside the unit circle)
    let (phi1, phi2) = (1.3, -0.6);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let n = 44_100;
    let mut x = vec![0f32; n];
    let (mut x1, mut x2) = (0.0f64, 0.0f64);
    for _ in 0..1000 {
        let e: f64 = rng.sample(StandardNormal);
        let v = phi1 * x1 + phi2 * x2 + e;
        x2 = x1;
        x1 = v;
    }
    for xi in x.iter_mut() {
        let e: f64 = rng.sample(StandardNormal);
        let v = phi1 * x1 + phi2 * x2 + e;
        x2 = x1;
        x1 = v;
        *xi = (v * 0.01) as f32;
    }
    let mut c = cfg(FeatureSet::Paper20);
    c.frame_s = 1.0;
    c.prefilter = Prefilter::NONE;
    let mut ex = FeatureExtractor::new(&c).unwrap();
    let mut out = vec![0.0; ex.dim()];
    ex.extract(&x, &mut out).unwrap();
    assert!(
        (out[0] + phi1).abs() < 0.03,
        "a1 = {} (expected {})",
        out[0],
        -phi1
    );
    assert!(
        (out[1] + phi2).abs() < 0.03,
        "a2 = {} (expected {})",
        out[1],
        -phi2
    );
    for (i, a) in out[2..10].iter().enumerate() {
        assert!(a.abs() < 0.03, "a{} = {a} should be ~0", i + 3);
    }
}

#[test]
fn levinson_matches_direct_toeplitz_solve() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for trial in 0..20 {
        let x: Vec<f64> = (0..500)
            .map(|_| rng.sample::<f64, _>(StandardNormal))
            .collect();
        // Colour it so the system is not trivial.
        let y: Vec<f64> = (0..x.len())
            .map(|i| {
                x[i] + if i > 0 { 0.8 * x[i - 1] } else { 0.0 }
                    + if i > 2 { -0.3 * x[i - 3] } else { 0.0 }
            })
            .collect();
        let p = 2 + trial % 9;
        let mut r = vec![0.0; p + 1];
        autocorrelation_biased(&y, &mut r);
        let mut a = vec![0.0; p + 1];
        let mut scratch = vec![0.0; p + 1];
        let err = levinson_durbin(&r, &mut a, &mut scratch);
        let t = DMatrix::from_fn(p, p, |i, j| r[i.abs_diff(j)]);
        let b = DVector::from_fn(p, |i, _| -r[i + 1]);
        let sol = t.lu().solve(&b).unwrap();
        for i in 0..p {
            assert!(
                (a[i + 1] - sol[i]).abs() < 1e-9,
                "p={p} a{} {} vs {}",
                i + 1,
                a[i + 1],
                sol[i]
            );
        }
        // Error power = r0 + sum a_k r_k.
        let e2 = r[0] + (1..=p).map(|k| a[k] * r[k]).sum::<f64>();
        assert!((err - e2).abs() < 1e-9 * r[0]);
    }
}

#[test]
fn pure_tone_peaks_at_its_bin() {
    for set in [FeatureSet::Paper20, FeatureSet::Rich] {
        let mut ex = FeatureExtractor::new(&cfg(set)).unwrap();
        let df = ex.bin_hz();
        for bin in [23usize, 40, 100, 300] {
            let f = bin as f64 * df;
            let x: Vec<f32> = (0..ex.frame_len())
                .map(|n| {
                    (0.5 * (2.0 * std::f64::consts::PI * f * n as f64 / 44_100.0).sin()) as f32
                })
                .collect();
            let mut out = vec![0.0; ex.dim()];
            ex.extract(&x, &mut out).unwrap();
            let p = ex.power_spectrum();
            let argmax = (0..p.len()).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
            assert_eq!(argmax, bin, "{set:?}: tone at {f} Hz");
        }
    }
}

#[test]
fn real_cepstrum_of_single_echo() {
    // x = δ[n] + a δ[n−d]: ln|1 + a e^{−jωd}| = Σ (−1)^{m+1} a^m/m cos(mωd),
    // so the real cepstrum has c[m d] = (−1)^{m+1} a^m / (2m) (the even part
    // of the complex cepstrum's a, −a²/2, a³/3 …), zero elsewhere.
    let (a, d) = (0.6, 7usize);
    let mut x = vec![0.0; 64];
    x[0] = 1.0;
    x[d] = a;
    let c = real_cepstrum(&x, 1024, 4 * d + 1);
    for (n, &cn) in c.iter().enumerate().skip(1) {
        let expected = if n % d == 0 {
            let m = (n / d) as i32;
            let sign = if m % 2 == 1 { 1.0 } else { -1.0 };
            sign * a.powi(m) / (2.0 * f64::from(m))
        } else {
            0.0
        };
        assert!(
            (cn - expected).abs() < 1e-6,
            "c[{n}] = {cn}, expected {expected}"
        );
    }
    assert!((c[d] - 0.3).abs() < 1e-6 && (c[2 * d] + 0.09).abs() < 1e-6);
}

#[test]
fn features_finite_for_edge_signals() {
    for set in [FeatureSet::Paper20, FeatureSet::Paper7, FeatureSet::Rich] {
        let mut ex = FeatureExtractor::new(&cfg(set)).unwrap();
        let l = ex.frame_len();
        let square = |period: usize| -> Vec<f32> {
            (0..l)
                .map(|n| {
                    if (n / period).is_multiple_of(2) {
                        1.0
                    } else {
                        -1.0
                    }
                })
                .collect()
        };
        let cases: Vec<(&str, Vec<f32>)> = vec![
            ("silence", vec![0.0; l]),
            ("square 2", square(1)),
            ("square 50", square(25)),
            ("square 1000", square(500)),
            ("dc", vec![1.0; l]),
            ("single sample", vec![0.7]),
            ("empty", vec![]),
            (
                "impulse",
                (0..l).map(|n| if n == l / 2 { 1.0 } else { 0.0 }).collect(),
            ),
            ("nan", vec![f32::NAN; l]),
            ("tiny", vec![1e-30; l]),
        ];
        for (name, x) in cases {
            let mut out = vec![f64::NAN; ex.dim()];
            ex.extract(&x, &mut out).unwrap();
            assert!(out.iter().all(|v| v.is_finite()), "{set:?} {name}: {out:?}");
        }
    }
}

#[test]
fn wrong_lengths_are_errors() {
    let mut ex = FeatureExtractor::new(&cfg(FeatureSet::Paper20)).unwrap();
    let mut out = vec![0.0; 20];
    let long = vec![0.0f32; ex.frame_len() + 1];
    assert!(matches!(
        ex.extract(&long, &mut out),
        Err(FeatureError::FrameTooLong { .. })
    ));
    let mut short_out = vec![0.0; 19];
    assert!(matches!(
        ex.extract(&[0.0], &mut short_out),
        Err(FeatureError::OutputLength {
            got: 19,
            expected: 20
        })
    ));
}

#[test]
fn invalid_configs_name_the_field() {
    let mut c = cfg(FeatureSet::Paper7);
    c.selection = vec![0, 1, 25];
    let e = FeatureExtractor::new(&c).unwrap_err();
    assert!(e.to_string().contains("selection"), "{e}");
    let mut c = cfg(FeatureSet::Rich);
    c.frame_s = f64::NAN;
    assert!(
        FeatureExtractor::new(&c)
            .unwrap_err()
            .to_string()
            .contains("frame_s")
    );
    let mut c = cfg(FeatureSet::Paper20);
    c.prefilter.lowpass_hz = Some(30_000.0);
    assert!(
        FeatureExtractor::new(&c)
            .unwrap_err()
            .to_string()
            .contains("lowpass_hz")
    );
    let mut c = cfg(FeatureSet::Rich);
    c.n_mel = 30;
    assert!(
        FeatureExtractor::new(&c)
            .unwrap_err()
            .to_string()
            .contains("n_mel")
    );
}

#[test]
fn names_match_dimensions() {
    for set in [FeatureSet::Paper20, FeatureSet::Paper7, FeatureSet::Rich] {
        let c = cfg(set);
        let ex = FeatureExtractor::new(&c).unwrap();
        assert_eq!(ex.names().len(), ex.dim());
        let mut sorted = ex.names();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), ex.dim(), "names unique");
    }
    assert_eq!(
        FeatureExtractor::new(&cfg(FeatureSet::Paper7))
            .unwrap()
            .names(),
        ["lpc_1", "lpc_2", "lpc_3", "ps_1", "ps_2", "cep_1", "cep_2"]
    );
}

#[test]
fn config_round_trips_through_json() {
    let c = cfg(FeatureSet::Paper7);
    let s = serde_json::to_string(&c).unwrap();
    let back: FeatureConfig = serde_json::from_str(&s).unwrap();
    assert_eq!(c, back);
    assert!(
        serde_json::from_str::<FeatureConfig>(
            r#"{"sample_rate":44100,"frame_s":0.1,"set":"rich","bogus":1}"#
        )
        .is_err()
    );
}

fn noise_frame(seed: u64, len: usize) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut y = 0.0f64;
    (0..len)
        .map(|_| {
            let e: f64 = rng.sample(StandardNormal);
            y = 0.7 * y + e;
            (0.05 * y
                + if rng.random::<f64>() < 0.002 {
                    0.5
                } else {
                    0.0
                }) as f32
        })
        .collect()
}

#[test]
fn all_sets_are_gain_invariant() {
    for set in [FeatureSet::Paper20, FeatureSet::Rich] {
        let mut ex = FeatureExtractor::new(&cfg(set)).unwrap();
        let x = noise_frame(11, ex.frame_len());
        let x2: Vec<f32> = x.iter().map(|v| v * 0.1).collect();
        let (mut a, mut b) = (vec![0.0; ex.dim()], vec![0.0; ex.dim()]);
        ex.extract(&x, &mut a).unwrap();
        ex.extract(&x2, &mut b).unwrap();
        for (i, (u, v)) in a.iter().zip(&b).enumerate() {
            assert!(
                (u - v).abs() < 1e-4 * (1.0 + u.abs()),
                "{set:?} feature {i}: {u} vs {v}"
            );
        }
    }
}

#[test]
fn extract_all_counts_frames() {
    let mut ex = FeatureExtractor::new(&cfg(FeatureSet::Paper20)).unwrap();
    let x = noise_frame(1, 44_100);
    let m = ex.extract_all(&x, 2205).unwrap();
    assert_eq!(m.len() / ex.dim(), (44_100 - 4410) / 2205 + 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn features_always_finite(seed in any::<u64>(), scale in -40.0f64..5.0, len in 1usize..4410) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = 10f64.powf(scale / 10.0);
        let x: Vec<f32> = (0..len).map(|_| (g * rng.sample::<f64, _>(StandardNormal)).clamp(-1.0, 1.0) as f32).collect();
        for set in [FeatureSet::Paper20, FeatureSet::Rich] {
            let mut ex = FeatureExtractor::new(&cfg(set)).unwrap();
            let mut out = vec![0.0; ex.dim()];
            ex.extract(&x, &mut out).unwrap();
            prop_assert!(out.iter().all(|v| v.is_finite()));
        }
    }
}
