//! The optional fixed-band features of the Rich set (`FeatureConfig::
//! fixed_bands`): energy shares of 2-4, 4-8 and 8-16 kHz of the recorded
//! spectrum, appended after the 43 Rich features and never warped.

use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet, SpeedNorm};

const NORM: SpeedNorm = SpeedNorm {
    ref_kmh: 20.0,
    exponent: 0.4,
};

fn cfg(fixed_bands: bool) -> FeatureConfig {
    FeatureConfig {
        speed_norm: Some(NORM),
        fixed_bands,
        ..FeatureConfig::new(44_100, FeatureSet::Rich)
    }
}

fn tone(f: f64, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| (0.3 * (2.0 * std::f64::consts::PI * f * i as f64 / 44_100.0).sin()) as f32)
        .collect()
}

/// A reproducible noise-plus-tones frame.
fn mixed(n: usize) -> Vec<f32> {
    let mut s = 0x2545_f491_4f6c_dd1d_u64;
    (0..n)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let t = i as f64 / 44_100.0;
            (0.1 * u
                + 0.2 * (2.0 * std::f64::consts::PI * 900.0 * t).sin()
                + 0.05 * (2.0 * std::f64::consts::PI * 9_000.0 * t).sin()) as f32
        })
        .collect()
}

#[test]
fn appended_after_the_rich_features_which_stay_bit_identical() {
    let (mut off, mut on) = (
        FeatureExtractor::new(&cfg(false)).unwrap(),
        FeatureExtractor::new(&cfg(true)).unwrap(),
    );
    assert_eq!(off.dim(), 43);
    assert_eq!(on.dim(), 46);
    let names = on.names();
    assert_eq!(names[..43], off.names()[..]);
    assert_eq!(
        names[43..],
        ["fixed_share_2_4k", "fixed_share_4_8k", "fixed_share_8_16k"]
    );
    let x = mixed(off.frame_len());
    for speed in [None, Some(5.0 / 3.6), Some(35.0 / 3.6)] {
        off.set_speed(speed);
        on.set_speed(speed);
        let (mut a, mut b) = (vec![0.0; 43], vec![0.0; 46]);
        off.extract(&x, &mut a).unwrap();
        on.extract(&x, &mut b).unwrap();
        assert_eq!(a[..], b[..43], "speed {speed:?}");
    }
}

#[test]
fn do_not_move_with_speed_and_find_a_tone_in_its_band() {
    let mut ex = FeatureExtractor::new(&cfg(true)).unwrap();
    let n = ex.frame_len();
    let mut first: Option<Vec<f64>> = None;
    for speed in [Some(4.0 / 3.6), Some(20.0 / 3.6), Some(40.0 / 3.6), None] {
        ex.set_speed(speed);
        let mut v = vec![0.0; ex.dim()];
        ex.extract(&mixed(n), &mut v).unwrap();
        let fixed = v[43..].to_vec();
        // ln of a share: at most 0, and the three shares sum to at most 1.
        assert!(fixed.iter().all(|&f| f <= 1e-12), "{fixed:?}");
        assert!(fixed.iter().map(|f| f.exp()).sum::<f64>() <= 1.0 + 1e-9);
        match &first {
            None => first = Some(fixed),
            Some(f0) => assert_eq!(f0, &fixed, "speed {speed:?}"),
        }
    }
    // A 5 kHz tone: nearly all of its energy in 4-8 kHz, almost none in the others.
    let mut v = vec![0.0; ex.dim()];
    ex.extract(&tone(5_000.0, n), &mut v).unwrap();
    assert!(v[44] > -0.01, "4-8 kHz share ln {}", v[44]);
    assert!(v[43] < -6.0 && v[45] < -6.0, "{:?}", &v[43..]);
}

#[test]
fn only_for_the_rich_set_and_kept_by_serde() {
    let e = FeatureConfig {
        fixed_bands: true,
        ..FeatureConfig::new(44_100, FeatureSet::Paper20)
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(e.contains("fixed_bands"), "{e}");
    let on = cfg(true);
    let json = serde_json::to_string(&on).unwrap();
    assert!(json.contains("\"fixed_bands\":true"), "{json}");
    assert_eq!(serde_json::from_str::<FeatureConfig>(&json).unwrap(), on);
    // Off is not written, and a config without the field reads as off.
    let off_json = serde_json::to_string(&cfg(false)).unwrap();
    assert!(!off_json.contains("fixed_bands"), "{off_json}");
    assert!(
        !serde_json::from_str::<FeatureConfig>(&off_json)
            .unwrap()
            .fixed_bands
    );
}
