//! SMO solver and one-vs-one SVM.

use grip_arte::svm::{Kernel, Svm, SvmConfig, sigmoid_train, smo};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn blobs(centres: &[[f64; 2]], per_class: usize, sd: f64, seed: u64) -> (Vec<f64>, Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nd = Normal::new(0.0, sd).unwrap();
    let mut x = Vec::new();
    let mut y = Vec::new();
    for (c, centre) in centres.iter().enumerate() {
        for _ in 0..per_class {
            x.push(centre[0] + nd.sample(&mut rng));
            x.push(centre[1] + nd.sample(&mut rng));
            y.push(c);
        }
    }
    (x, y)
}

/// Hand-checked: two support vectors at (±1, 0), two points far outside
/// the margin. The maximum-margin line is x₁ = 0 with w = (1, 0), so
/// a = (½, ½, 0, 0), rho = 0, margin 2, dual objective ½|w|² − Σa = −½.
#[test]
fn smo_matches_hand_solution() {
    let x = [1.0, 0.0, -1.0, 0.0, 3.0, 1.0, -2.0, -1.0];
    let y = [1.0, -1.0, 1.0, -1.0];
    let sol = smo(&x, 2, &y, 1000.0, Kernel::Linear, 1e-9, 100_000, 1);
    let want = [0.5, 0.5, 0.0, 0.0];
    for (a, w) in sol.alpha.iter().zip(want) {
        assert!((a - w).abs() < 1e-9, "alpha {:?}", sol.alpha);
    }
    assert!(sol.rho.abs() < 1e-9, "rho {}", sol.rho);
    assert!(
        (sol.objective + 0.5).abs() < 1e-9,
        "objective {}",
        sol.objective
    );
    let w: [f64; 2] = [0, 1].map(|d| (0..4).map(|i| sol.alpha[i] * y[i] * x[2 * i + d]).sum());
    let margin = 2.0 / (w[0] * w[0] + w[1] * w[1]).sqrt();
    assert!((margin - 2.0).abs() < 1e-9, "margin {margin}");
}

#[test]
fn smo_satisfies_kkt_on_separable_rbf_problem() {
    let (x, labels) = blobs(&[[0.0, 0.0], [2.5, 2.5]], 40, 0.6, 7);
    let y: Vec<f64> = labels
        .iter()
        .map(|&c| if c == 0 { 1.0 } else { -1.0 })
        .collect();
    let c = 100.0;
    let kernel = Kernel::Rbf { gamma: 0.5 };
    let tol = 1e-6;
    let sol = smo(&x, 2, &y, c, kernel, tol, 1_000_000, 4);
    assert!(!sol.hit_max_iter);
    assert!(sol.gap < tol);
    let sum: f64 = sol.alpha.iter().zip(&y).map(|(a, yi)| a * yi).sum();
    assert!(sum.abs() < 1e-9, "yᵀa = {sum}");
    let n = y.len();
    let f = |i: usize| -> f64 {
        (0..n)
            .map(|j| sol.alpha[j] * y[j] * kernel.eval(&x[2 * j..2 * j + 2], &x[2 * i..2 * i + 2]))
            .sum::<f64>()
            - sol.rho
    };
    let mut n_sv = 0;
    for i in 0..n {
        let m = y[i] * f(i);
        let a = sol.alpha[i];
        assert!((0.0..=c).contains(&a));
        if a == 0.0 {
            assert!(m >= 1.0 - 1e-4, "non-SV {i} inside margin: {m}");
        } else if a < c {
            n_sv += 1;
            assert!((m - 1.0).abs() < 1e-4, "free SV {i} off the margin: {m}");
        } else {
            assert!(m <= 1.0 + 1e-4, "bounded SV {i}: {m}");
        }
    }
    assert!(n_sv >= 2 && n_sv < n / 2, "{n_sv} free SVs");
}

#[test]
fn one_vs_one_on_four_blobs() {
    let centres = [[0.0, 0.0], [3.0, 0.0], [0.0, 3.0], [3.0, 3.0]];
    let (x, y) = blobs(&centres, 80, 0.7, 1);
    let (tx, ty) = blobs(&centres, 250, 0.7, 2);
    let cfg = SvmConfig {
        c: 10.0,
        kernel: Kernel::Rbf { gamma: 0.5 },
        ..Default::default()
    };
    let (svm, rep) = Svm::train(&cfg, 4, 2, &x, &y).unwrap();
    svm.validate().unwrap();
    assert_eq!(svm.pairs().len(), 6);
    assert_eq!(rep.n_sv, svm.n_sv());
    assert!(rep.n_sv < x.len() / 2, "{} SVs of {}", rep.n_sv, y.len());
    let mut s = svm.scratch();
    let mut p = [0.0; 4];
    let (mut ok_vote, mut ok_prob, mut agree) = (0, 0, 0);
    for (n, &label) in ty.iter().enumerate() {
        let q = &tx[2 * n..2 * n + 2];
        let v = svm.predict_vote(q, &mut s);
        svm.predict_proba(q, &mut s, &mut p);
        let sum: f64 = p.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "probabilities sum to {sum}");
        assert!(p.iter().all(|&v| (0.0..=1.0).contains(&v)));
        let am = (0..4).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
        ok_vote += usize::from(v == label);
        ok_prob += usize::from(am == label);
        agree += usize::from(am == v);
    }
    let n = ty.len() as f64;
    assert!(
        ok_vote as f64 / n > 0.95,
        "vote accuracy {}",
        ok_vote as f64 / n
    );
    assert!(
        ok_prob as f64 / n > 0.95,
        "probability accuracy {}",
        ok_prob as f64 / n
    );
    assert!(agree as f64 / n > 0.97);
}

#[test]
fn training_is_deterministic_and_checks_input() {
    let (x, y) = blobs(&[[0.0, 0.0], [2.0, 0.0], [1.0, 2.0]], 30, 0.8, 5);
    let cfg = SvmConfig::default();
    let (a, _) = Svm::train(&cfg, 3, 2, &x, &y).unwrap();
    let (b, _) = Svm::train(&cfg, 3, 2, &x, &y).unwrap();
    assert_eq!(a, b);
    assert!(Svm::train(&cfg, 4, 2, &x, &y).is_err(), "class 3 is empty");
    assert!(Svm::train(&cfg, 1, 2, &x, &vec![0; y.len()]).is_err());
    let bad = SvmConfig {
        c: f64::NAN,
        ..Default::default()
    };
    assert!(Svm::train(&bad, 3, 2, &x, &y).is_err());
    let bad = SvmConfig {
        kernel: Kernel::Rbf { gamma: -1.0 },
        ..Default::default()
    };
    assert!(Svm::train(&bad, 3, 2, &x, &y).is_err());
}

#[test]
fn platt_sigmoid_is_monotone_and_calibrated_on_ordered_data() {
    // Decision values with overlap: P(+|f) must rise with f and be ~0.5 near 0.
    let dec: Vec<f64> = (0..200).map(|i| (i as f64 - 100.0) / 25.0).collect();
    let pos: Vec<bool> = (0..200).map(|i| (i * 7919 % 200) < i).collect();
    let (a, b) = sigmoid_train(&dec, &pos);
    assert!(a < 0.0, "A = {a} should be negative (P rises with f)");
    let p0 = 1.0 / (1.0 + b.exp());
    assert!((0.2..0.8).contains(&p0), "P(+|0) = {p0}");
}
