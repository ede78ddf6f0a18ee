//! Speed normalisation of the Rich features: the frequency axis is warped
//! by w = (v_ref / v)^exponent, so a recorded frequency f is read as f · w.

use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet, SpeedNorm};
use grip_arte::synth::{NoiseConfig, Segment, SynthConfig, render, road_index};

const NORM: SpeedNorm = SpeedNorm {
    ref_kmh: 20.0,
    exponent: 0.25,
};

fn cfg(speed_norm: Option<SpeedNorm>) -> FeatureConfig {
    FeatureConfig {
        speed_norm,
        ..FeatureConfig::new(44_100, FeatureSet::Rich)
    }
}

fn index(ex: &FeatureExtractor, name: &str) -> usize {
    ex.names().iter().position(|n| n == name).unwrap()
}

fn tone(f: f64, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| (0.3 * (2.0 * std::f64::consts::PI * f * i as f64 / 44_100.0).sin()) as f32)
        .collect()
}

#[test]
fn the_warp_law() {
    assert_eq!(NORM.warp(Some(20.0 / 3.6)), 1.0);
    assert!((NORM.warp(Some(40.0 / 3.6)) - 0.5f64.powf(0.25)).abs() < 1e-12);
    assert!((NORM.warp(Some(5.0 / 3.6)) - 4f64.powf(0.25)).abs() < 1e-12);
    // Unknown or invalid speeds: no warp; extreme ones are clamped.
    for v in [None, Some(f64::NAN), Some(-1.0), Some(f64::INFINITY)] {
        assert_eq!(NORM.warp(v), 1.0, "{v:?}");
    }
    assert_eq!(NORM.warp(Some(0.0)), NORM.warp(Some(1.0 / 3.6)));
    assert_eq!(NORM.warp(Some(1000.0)), NORM.warp(Some(250.0 / 3.6)));
}

#[test]
fn at_the_reference_speed_or_unknown_speed_the_features_are_the_plain_ones() {
    let x = render(
        &SynthConfig {
            sample_rate: 44_100,
            noise: Some(NoiseConfig {
                rain: true,
                car: true,
                snr_db: 10.0,
            }),
        },
        3,
        &[Segment {
            road: road_index("gravel").unwrap(),
            speed_mps: 7.0,
            duration_s: 0.2,
        }],
    )
    .unwrap();
    let mut plain = FeatureExtractor::new(&cfg(None)).unwrap();
    let mut normed = FeatureExtractor::new(&cfg(Some(NORM))).unwrap();
    let frame = &x[..plain.frame_len()];
    let (mut a, mut b) = (vec![0.0; plain.dim()], vec![0.0; plain.dim()]);
    plain.extract(frame, &mut a).unwrap();
    for speed in [None, Some(20.0 / 3.6)] {
        normed.set_speed(speed);
        normed.extract(frame, &mut b).unwrap();
        assert_eq!(a, b, "speed {speed:?}");
    }
    // Another speed changes them; back at the reference they are equal again.
    normed.set_speed(Some(40.0 / 3.6));
    normed.extract(frame, &mut b).unwrap();
    assert_ne!(a, b);
    normed.set_speed(Some(20.0 / 3.6));
    normed.extract(frame, &mut b).unwrap();
    assert_eq!(a, b);
    // A model without speed normalisation ignores the speed.
    plain.set_speed(Some(40.0 / 3.6));
    assert_eq!(plain.warp(), 1.0);
    plain.extract(frame, &mut b).unwrap();
    assert_eq!(a, b);
}

#[test]
fn a_tone_moves_to_its_warped_frequency() {
    // A 1 kHz tone heard at 80 km/h (warp (20/80)^0.25 = 0.707) must look
    // like a 707 Hz tone heard at the reference speed: same centroid,
    // roll-off and zero-crossing rate, nearly the same mel shape.
    let mut ex = FeatureExtractor::new(&cfg(Some(NORM))).unwrap();
    let n = ex.frame_len();
    let w = NORM.warp(Some(80.0 / 3.6));
    let (mut fast, mut slow) = (vec![0.0; ex.dim()], vec![0.0; ex.dim()]);
    ex.set_speed(Some(80.0 / 3.6));
    ex.extract(&tone(1000.0, n), &mut fast).unwrap();
    ex.set_speed(Some(20.0 / 3.6));
    ex.extract(&tone(1000.0 * w, n), &mut slow).unwrap();
    for name in ["centroid_khz", "zcr_khz"] {
        let i = index(&ex, name);
        assert!(
            (fast[i] - slow[i]).abs() < 0.02 * slow[i],
            "{name}: {} vs {}",
            fast[i],
            slow[i]
        );
    }
    let c = index(&ex, "centroid_khz");
    assert!((slow[c] - 0.707).abs() < 0.05, "centroid {}", slow[c]);
    // The loudest mel band is the same one.
    let argmax = |v: &[f64]| (0..24).max_by(|&i, &j| v[i].total_cmp(&v[j])).unwrap();
    assert_eq!(argmax(&fast), argmax(&slow));
}

#[test]
fn speed_norm_is_validated_and_only_for_the_rich_set() {
    let bad = |c: FeatureConfig, field: &str| {
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    };
    bad(
        FeatureConfig {
            speed_norm: Some(NORM),
            ..FeatureConfig::new(44_100, FeatureSet::Paper20)
        },
        "speed_norm",
    );
    bad(
        cfg(Some(SpeedNorm {
            ref_kmh: 0.0,
            exponent: 0.25,
        })),
        "speed_norm.ref_kmh",
    );
    bad(
        cfg(Some(SpeedNorm {
            ref_kmh: 20.0,
            exponent: 1.5,
        })),
        "speed_norm.exponent",
    );
    bad(
        cfg(Some(SpeedNorm {
            ref_kmh: 20.0,
            exponent: f64::NAN,
        })),
        "speed_norm.exponent",
    );
}
