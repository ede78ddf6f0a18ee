//! Vinnicombe ν-gap: literature and closed-form cases, the winding-number
//! condition, and metric properties.

use grip_tcs::analysis::nugap::{chordal, kappa};
use grip_tcs::analysis::{Tf, nu_gap};
use nalgebra::Complex;
use proptest::prelude::*;

fn tf(n: &[f64], d: &[f64]) -> Tf {
    Tf::from_coeffs(n, d).unwrap()
}

#[test]
fn gap_to_itself_is_zero() {
    for p in [
        tf(&[100.0], &[2.0, 1.0]),
        tf(&[100.0], &[2.0, -1.0]),
        tf(&[1.0, 2.0], &[1.0, 0.0, 4.0, 0.0]), // poles on the axis
        tf(&[3.0, -1.0, 2.0], &[1.0, 0.5, 2.0]), // proper, biproper
        tf(&[1.0], &[1.0, 0.0, 0.0]),           // double integrator
    ] {
        let g = nu_gap(&p, &p).unwrap();
        assert!(g.winding_ok, "{p:?}: {g:?}");
        assert!(g.delta < 1e-12, "{p:?}: {g:?}");
    }
}

/// Vinnicombe's example (Vinnicombe, "Frequency domain uncertainty and the
/// graph topology", IEEE TAC 38(9), 1993; also Zhou & Doyle, *Essentials of
/// Robust Control*, 1998, ch. 17): a stable and an unstable plant that are
/// close in the ν-gap although their difference is large.
/// κ(ω) = 200 / (10001 + 4 ω²), maximal at ω = 0: 200/10001.
#[test]
fn vinnicombe_example() {
    let p1 = tf(&[100.0], &[2.0, 1.0]);
    let p2 = tf(&[100.0], &[2.0, -1.0]);
    let g = nu_gap(&p1, &p2).unwrap();
    assert!(g.winding_ok);
    assert_eq!((g.eta1, g.eta2, g.eta0_2, g.wno), (0, 1, 0, 1));
    assert!((g.delta - 200.0 / 10001.0).abs() < 1e-12, "{g:?}");
    assert_eq!(g.omega_sup, 0.0);
    for w in [0.0, 0.3, 7.0, 100.0] {
        let want = 200.0 / (10001.0 + 4.0 * w * w);
        assert!((kappa(&p1, &p2, w) - want).abs() < 1e-14);
    }
}

/// k1/(s+1) vs k2/(s+1): with x = 1 + ω², κ² = (k1-k2)² x / ((x+k1²)(x+k2²)),
/// maximal at x = k1 k2 (if k1 k2 >= 1): κ = |k1-k2| / (k1+k2) at
/// ω = sqrt(k1 k2 - 1). k1 = 2, k2 = 5: 3/7 at ω = 3 (an interior maximum,
/// found by the golden-section refinement).
#[test]
fn two_first_order_lags_closed_form() {
    let g = nu_gap(&tf(&[2.0], &[1.0, 1.0]), &tf(&[5.0], &[1.0, 1.0])).unwrap();
    assert!(g.winding_ok);
    assert!((g.delta - 3.0 / 7.0).abs() < 1e-12, "{g:?}");
    assert!((g.omega_sup - 3.0).abs() < 1e-4, "{g:?}");
    // k1 k2 < 1: maximum at ω = 0, κ = |k1-k2| / sqrt((1+k1²)(1+k2²))
    let g = nu_gap(&tf(&[0.5], &[1.0, 1.0]), &tf(&[1.5], &[1.0, 1.0])).unwrap();
    let want = 1.0 / ((1.25f64) * (3.25)).sqrt();
    assert!((g.delta - want).abs() < 1e-12, "{g:?}");
}

/// 1/s vs 1/(s+a): κ(0) = a / sqrt(1 + a²) is the maximum; the integrator's
/// pole on the axis enters η₀ when it is P2.
#[test]
fn integrator_against_lag_both_orders() {
    let a = 0.3;
    let p1 = tf(&[1.0], &[1.0, 0.0]);
    let p2 = tf(&[1.0], &[1.0, a]);
    let want = a / (1.0 + a * a).sqrt();
    let g12 = nu_gap(&p1, &p2).unwrap();
    let g21 = nu_gap(&p2, &p1).unwrap();
    assert!(g12.winding_ok && g21.winding_ok, "{g12:?} {g21:?}");
    assert_eq!(g21.eta0_2, 1);
    assert!((g12.delta - want).abs() < 1e-12 && (g21.delta - want).abs() < 1e-12);
}

/// A pure gain change of a plant whose |P(jω)| sweeps (0, ∞) (integrator and
/// lag): P2 = (1+Δ) P1 gives δ_ν = Δ / (2 + Δ). This is the MFC case.
#[test]
fn gain_ratio_with_integrator() {
    let p1 = tf(&[4.0], &[0.05, 1.0, 0.0]);
    for d in [0.01, 0.2, 0.643, 3.0] {
        let p2 = p1.scale(1.0 + d);
        let g = nu_gap(&p1, &p2).unwrap();
        assert!(g.winding_ok);
        assert!((g.delta - d / (2.0 + d)).abs() < 1e-9, "Δ={d}: {g:?}");
    }
}

/// k/(s+1) vs k/(s-1) with k = 0.5: κ(ω) = 2k / (1 + k² + ω²) <= 0.8 < 1,
/// but 1 + P2~P1 = ((s+1)² - k²)/(s+1)² has no right-half-plane zero
/// (zeros -1 ± k), so wno = 0 while η(P1) - η(P2) = -1: the winding
/// condition fails and δ_ν = 1. (For k > 1 one zero, -1 + k, moves into the
/// right half plane and the condition holds: Vinnicombe's example is k = 50
/// after scaling by 2.)
#[test]
fn winding_condition_fails_without_touching_one() {
    let k = 0.5;
    let g = nu_gap(&tf(&[k], &[1.0, 1.0]), &tf(&[k], &[1.0, -1.0])).unwrap();
    assert!(!g.winding_ok && !g.vanishes_on_axis, "{g:?}");
    assert_eq!(g.wno, 0);
    assert!((g.kappa_sup - 0.8).abs() < 1e-12);
    assert_eq!(g.delta, 1.0);
    // and for k = 2 the condition holds: κ(0) = 4/5
    let g = nu_gap(&tf(&[2.0], &[1.0, 1.0]), &tf(&[2.0], &[1.0, -1.0])).unwrap();
    assert!(g.winding_ok);
    assert!((g.delta - 0.8).abs() < 1e-12);
}

/// 1/(s+1) vs -1/(s+1): 1 + P2~P1 = -s² / (1 - s²) vanishes at ω = 0, where
/// κ = 1: the first part of the condition fails.
#[test]
fn sign_flip_vanishes_on_axis() {
    let g = nu_gap(&tf(&[1.0], &[1.0, 1.0]), &tf(&[-1.0], &[1.0, 1.0])).unwrap();
    assert!(g.vanishes_on_axis && !g.winding_ok);
    assert_eq!(g.delta, 1.0);
    assert!((g.kappa_sup - 1.0).abs() < 1e-12);
    // static gains 1 and -1: 1 + P2 P1 = 0 at every frequency
    let g = nu_gap(&Tf::gain(1.0), &Tf::gain(-1.0)).unwrap();
    assert!(g.vanishes_on_axis);
    assert_eq!(g.delta, 1.0);
}

/// Common factors do not change the answer (P1 with a cancelling unstable
/// factor is the same plant).
#[test]
fn common_factors_are_cancelled() {
    let p = tf(&[100.0], &[2.0, 1.0]);
    let p_bloated = tf(&[100.0, -300.0], &[2.0, -5.0, -3.0]); // ×(s-3)/(s-3)
    let g = nu_gap(&p_bloated, &tf(&[100.0], &[2.0, -1.0])).unwrap();
    let g0 = nu_gap(&p, &tf(&[100.0], &[2.0, -1.0])).unwrap();
    assert_eq!(g.cancelled, 1);
    assert!((g.delta - g0.delta).abs() < 1e-9, "{g:?} {g0:?}");
}

/// 1 - κ² = |1 + conj(p2) p1|² / ((1+|p1|²)(1+|p2|²)) for any two numbers.
#[test]
fn chordal_identity() {
    let pts = [
        Complex::new(0.3, -2.0),
        Complex::new(-5.0, 0.1),
        Complex::new(0.0, 0.0),
        Complex::new(1e3, 1e3),
    ];
    let one = Complex::new(1.0, 0.0);
    for &a in &pts {
        for &b in &pts {
            let k = chordal(a, one, b, one);
            let rhs =
                (one + b.conj() * a).norm_sqr() / ((1.0 + a.norm_sqr()) * (1.0 + b.norm_sqr()));
            assert!((1.0 - k * k - rhs).abs() < 1e-12);
        }
    }
}

fn plant() -> impl Strategy<Value = Tf> {
    let c = || prop_oneof![-5.0f64..-0.05, 0.05f64..5.0];
    prop_oneof![
        (c(), c()).prop_map(|(k, a)| Tf::from_coeffs(&[k], &[1.0, a]).unwrap()),
        (c(), c(), c(), c()).prop_map(|(b1, b0, a1, a0)| Tf::from_coeffs(
            &[b1, b0],
            &[1.0, a1, a0]
        )
        .unwrap()),
        (c(), c(), c()).prop_map(|(k, a1, a0)| Tf::from_coeffs(&[k], &[1.0, a1, a0]).unwrap()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn gap_is_symmetric_and_bounded(p1 in plant(), p2 in plant()) {
        let a = nu_gap(&p1, &p2).unwrap();
        let b = nu_gap(&p2, &p1).unwrap();
        prop_assert!((0.0..=1.0).contains(&a.delta));
        prop_assert!((a.kappa_sup - b.kappa_sup).abs() < 1e-9, "{:?} {:?}", a, b);
        prop_assert_eq!(a.winding_ok, b.winding_ok, "{:?} {:?}", a, b);
        prop_assert!((a.delta - b.delta).abs() < 1e-9);
    }

    #[test]
    fn gap_to_self_is_zero(p in plant()) {
        let g = nu_gap(&p, &p).unwrap();
        prop_assert!(g.winding_ok, "{:?}", g);
        prop_assert!(g.delta < 1e-9);
    }

    /// The sup is at least κ at any frequency we probe.
    #[test]
    fn sup_dominates_samples(p1 in plant(), p2 in plant(), w in 0.0f64..100.0) {
        let g = nu_gap(&p1, &p2).unwrap();
        prop_assert!(g.kappa_sup >= kappa(&p1, &p2, w) - 1e-12);
    }
}
