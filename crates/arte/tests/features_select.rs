//! Feature pruning by least intra-class variance; KL separability report.

use grip_arte::features::{FeatureConfig, FeatureSet, N_PAPER20};
use grip_arte::select::{
    SelectError, kl_report, paper7_config, select_by_groups, select_paper7, variance_ratios,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn n(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

#[test]
fn variance_ratio_ranks_informative_columns_first() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..600 {
        let c = i % 3;
        // col 0: strongly class-dependent, col 1: weakly, col 2: pure noise.
        x.extend([
            c as f64 * 5.0 + n(&mut rng),
            c as f64 * 0.5 + n(&mut rng),
            n(&mut rng),
        ]);
        y.push(c);
    }
    let rho = variance_ratios(&x, 3, &y, 3).unwrap();
    assert!(
        rho[0] < 0.1 && rho[1] > 0.5 && rho[1] < 0.95 && rho[2] > 0.97,
        "{rho:?}"
    );
    assert_eq!(
        select_by_groups(&x, 3, &y, 3, &[(0..3, 2)]).unwrap(),
        vec![0, 1]
    );
}

#[test]
fn paper7_keeps_3_lpc_2_ps_2_cep_with_least_intra_class_variance() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let informative = [4usize, 7, 9, 12, 13, 16, 19];
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..400 {
        let c = i % 4;
        for j in 0..N_PAPER20 {
            let signal = if informative.contains(&j) {
                c as f64 * (1.0 + j as f64 * 0.1)
            } else {
                0.0
            };
            x.push(signal + n(&mut rng));
        }
        y.push(c);
    }
    let sel = select_paper7(&x, &y, 4).unwrap();
    assert_eq!(sel, informative);
    let cfg = paper7_config(&FeatureConfig::new(44_100, FeatureSet::Paper20), sel);
    assert_eq!(
        cfg.names(),
        ["lpc_5", "lpc_8", "lpc_10", "ps_3", "ps_4", "cep_2", "cep_5"]
    );
    cfg.validate().unwrap();
}

#[test]
fn kl_matches_the_closed_form_for_shifted_unit_gaussians() {
    // Two 1-D classes N(0, 1) and N(mu, 1): symmetric KL = mu².
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mu = 2.0;
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..40_000 {
        let c = i % 2;
        x.push(c as f64 * mu + n(&mut rng));
        y.push(c);
    }
    let r = kl_report(&x, 1, &y, 2).unwrap();
    assert!((r.get(0, 1) - mu * mu).abs() < 0.1, "{}", r.get(0, 1));
    assert_eq!(r.get(0, 1), r.get(1, 0));
    assert_eq!(r.get(0, 0), 0.0);
    assert_eq!(r.closest_pair().unwrap().0, 0);
    assert!(
        r.to_markdown(&["a".into(), "b".into()])
            .contains("| **a** |")
    );
}

#[test]
fn constant_columns_stay_finite_and_bad_input_is_an_error() {
    let x = vec![1.0, 0.0, 1.0, 0.1, 1.0, 5.0, 1.0, 5.2];
    let y = vec![0, 0, 1, 1];
    let r = kl_report(&x, 2, &y, 2).unwrap();
    assert!(r.divergence.iter().all(|v| v.is_finite()));
    assert_eq!(variance_ratios(&x, 2, &y, 2).unwrap()[0], 1.0);
    assert!(matches!(
        variance_ratios(&x, 3, &y, 2),
        Err(SelectError::Shape(_))
    ));
    assert!(matches!(
        variance_ratios(&x, 2, &[0, 0, 1, 5], 2),
        Err(SelectError::Label { row: 3, .. })
    ));
    assert!(matches!(
        kl_report(&x, 2, &[0, 0, 0, 1], 2),
        Err(SelectError::TooFew { class: 1, .. })
    ));
    let mut bad = x.clone();
    bad[3] = f64::NAN;
    assert!(matches!(
        variance_ratios(&bad, 2, &y, 2),
        Err(SelectError::NotFinite { row: 1, col: 1 })
    ));
}
