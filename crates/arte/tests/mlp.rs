//! MLP + Levenberg-Marquardt: learning, monotone SSE, analytic Jacobian.

use grip_arte::mlp::{LmConfig, Mlp, OutputKind, StopReason, train_lm};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best
}

fn accuracy(net: &Mlp, x: &[f64], y: &[usize]) -> f64 {
    let dim = net.n_in();
    let mut s = net.scratch();
    let mut out = vec![0.0; net.n_out()];
    let mut ok = 0;
    for (n, &label) in y.iter().enumerate() {
        net.predict_proba(&x[n * dim..(n + 1) * dim], &mut s, &mut out);
        if argmax(&out) == label {
            ok += 1;
        }
    }
    ok as f64 / y.len() as f64
}

/// `per_class` samples around each centre, unit variance scaled by `sd`.
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

#[test]
fn learns_xor() {
    let x = [0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0];
    let y = [0, 1, 1, 0];
    for output in [OutputKind::Softmax, OutputKind::Logistic] {
        let cfg = LmConfig {
            hidden: vec![4],
            output,
            epochs: 300,
            goal: 1e-6,
            seed: 3,
            ..Default::default()
        };
        let (net, rep) = train_lm(&cfg, 2, 2, &x, &y, None).unwrap();
        assert_eq!(accuracy(&net, &x, &y), 1.0, "{output:?}: {rep:?}");
        assert!(
            *rep.train_mse.last().unwrap() < 0.01,
            "{output:?}: final MSE {:?}",
            rep.train_mse.last()
        );
    }
}

#[test]
fn learns_three_blobs_with_paper_architecture() {
    let centres = [[0.0, 0.0], [3.0, 0.0], [1.5, 2.6]];
    let (x, y) = blobs(&centres, 60, 0.5, 11);
    let (vx, vy) = blobs(&centres, 30, 0.5, 12);
    let (tx, ty) = blobs(&centres, 200, 0.5, 13);
    let cfg = LmConfig {
        hidden: vec![4, 3, 2],
        seed: 5,
        ..Default::default()
    };
    let (net, rep) = train_lm(&cfg, 3, 2, &x, &y, Some((&vx, &vy))).unwrap();
    let acc = accuracy(&net, &tx, &ty);
    assert!(acc > 0.95, "held-out accuracy {acc}, report {rep:?}");
    assert!(rep.epochs < 1000, "{rep:?}");
}

#[test]
fn accepted_steps_never_raise_sse() {
    let centres = [[0.0, 0.0], [2.0, 0.0], [1.0, 1.7], [1.0, -1.7]];
    let (x, y) = blobs(&centres, 40, 0.8, 21);
    let cfg = LmConfig {
        hidden: vec![6, 4],
        epochs: 60,
        seed: 9,
        ..Default::default()
    };
    let (_, rep) = train_lm(&cfg, 4, 2, &x, &y, None).unwrap();
    assert!(rep.train_mse.len() > 5);
    for w in rep.train_mse.windows(2) {
        assert!(w[1] <= w[0], "SSE rose: {} -> {}", w[0], w[1]);
    }
    assert!(rep.train_mse.last().unwrap() < &(rep.train_mse[0] * 0.5));
}

#[test]
fn validation_early_stop_returns_best_epoch() {
    // Overlapping classes + a big net: validation error must start rising.
    let centres = [[0.0, 0.0], [1.5, 0.0]];
    let (x, y) = blobs(&centres, 30, 1.0, 31);
    let (vx, vy) = blobs(&centres, 200, 1.0, 32);
    let cfg = LmConfig {
        hidden: vec![12, 8],
        seed: 2,
        ..Default::default()
    };
    let (net, rep) = train_lm(&cfg, 2, 2, &x, &y, Some((&vx, &vy))).unwrap();
    assert_eq!(rep.stop, StopReason::Validation, "{rep:?}");
    assert_eq!(rep.epochs, rep.best_epoch + 6);
    assert!(rep.best_epoch > 0, "validation never improved: {rep:?}");
    let best = rep.val_mse[rep.best_epoch];
    assert!(best < rep.val_mse[0]);
    let got = net.sse(&vx, &vy) / (vy.len() * 2) as f64;
    assert!(
        (got - best).abs() < 1e-12,
        "returned weights are not the best-validation ones"
    );
}

#[test]
fn training_is_deterministic() {
    let (x, y) = blobs(&[[0.0, 0.0], [2.0, 1.0], [0.0, 2.0]], 40, 0.7, 41);
    let cfg = LmConfig {
        seed: 77,
        epochs: 40,
        ..Default::default()
    };
    let (a, ra) = train_lm(&cfg, 3, 2, &x, &y, None).unwrap();
    let (b, rb) = train_lm(&cfg, 3, 2, &x, &y, None).unwrap();
    assert_eq!(a, b);
    assert_eq!(ra, rb);
    let (c, _) = train_lm(&LmConfig { seed: 78, ..cfg }, 3, 2, &x, &y, None).unwrap();
    assert_ne!(a.weights(), c.weights());
}

#[test]
fn bad_input_is_refused() {
    let cfg = LmConfig::default();
    assert!(train_lm(&cfg, 2, 2, &[0.0, 1.0, 2.0], &[0], None).is_err());
    assert!(train_lm(&cfg, 2, 2, &[0.0, 1.0], &[2], None).is_err());
    assert!(train_lm(&cfg, 2, 2, &[0.0, f64::NAN], &[0], None).is_err());
    assert!(train_lm(&cfg, 2, 2, &[], &[], None).is_err());
    assert!(Mlp::from_weights(vec![2, 0, 2], OutputKind::Softmax, vec![]).is_err());
    assert!(Mlp::from_weights(vec![2, 2], OutputKind::Softmax, vec![0.0; 5]).is_err());
}

fn check_jacobian(net: &Mlp, x: &[f64]) -> Result<(), TestCaseError> {
    let n_out = net.n_out();
    let w = net.n_weights();
    let mut s = net.scratch();
    let mut y = vec![0.0; n_out];
    let mut jac = vec![0.0; n_out * w];
    net.output_jacobian(x, &mut s, &mut y, &mut jac);
    let h = 1e-6;
    let mut yp = vec![0.0; n_out];
    let mut ym = vec![0.0; n_out];
    for i in 0..w {
        let mut wp = net.weights().to_vec();
        wp[i] += h;
        let np = Mlp::from_weights(net.sizes().to_vec(), net.output_kind(), wp).unwrap();
        np.forward(x, &mut s, &mut yp);
        let mut wm = net.weights().to_vec();
        wm[i] -= h;
        let nm = Mlp::from_weights(net.sizes().to_vec(), net.output_kind(), wm).unwrap();
        nm.forward(x, &mut s, &mut ym);
        for k in 0..n_out {
            let fd = (yp[k] - ym[k]) / (2.0 * h);
            let an = jac[k * w + i];
            prop_assert!(
                (fd - an).abs() < 1e-6 * (1.0 + fd.abs()),
                "k={k} w={i}: fd {fd} analytic {an}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]
    #[test]
    fn analytic_jacobian_matches_finite_differences(
        seed in 0u64..1000,
        logistic in any::<bool>(),
        x in prop::collection::vec(-2.0f64..2.0, 3),
        deep in any::<bool>(),
    ) {
        let output = if logistic { OutputKind::Logistic } else { OutputKind::Softmax };
        let hidden: &[usize] = if deep { &[4, 3, 2] } else { &[5] };
        let net = Mlp::init(3, hidden, 4, output, seed).unwrap();
        check_jacobian(&net, &x)?;
    }
}

/// A network too large for Levenberg-Marquardt (its step solves a
/// weights x weights system) is refused, naming its sizes, weights and
/// memory, before anything is allocated: `grip train --hidden 256,256`
/// aborted the process (a 37 GB allocation). The largest allowed trains.
#[test]
fn a_network_too_large_for_lm_is_refused() {
    let centres = [[0.0, 0.0], [2.0, 0.0]];
    let (x, y) = blobs(&centres, 10, 0.5, 5);
    let cfg = LmConfig {
        hidden: vec![256, 256],
        epochs: 1,
        ..Default::default()
    };
    let e = train_lm(&cfg, 2, 2, &x, &y, None).unwrap_err().to_string();
    assert!(
        e.contains("the network [2, 256, 256, 2] (input, hidden layers, output) has 67074 weights")
            && e.contains("at most 5000 weights"),
        "{e}"
    );
    // counts beyond a usize: said, not overflowed
    let cfg = LmConfig {
        hidden: vec![usize::MAX, usize::MAX],
        ..cfg
    };
    let e = train_lm(&cfg, 2, 2, &x, &y, None).unwrap_err().to_string();
    assert!(e.contains("needs more weights than can be counted"), "{e}");
    // the bound: 2 -> 1000 -> 2 has (3 * 1000) + (1001 * 2) = 5002
    // weights, refused; a small network trains
    let cfg = LmConfig {
        hidden: vec![1000],
        epochs: 1,
        ..Default::default()
    };
    let e = train_lm(&cfg, 2, 2, &x, &y, None).unwrap_err().to_string();
    assert!(e.contains("has 5002 weights"), "{e}");
    let cfg = LmConfig {
        hidden: vec![10],
        epochs: 1,
        ..Default::default()
    };
    assert!(train_lm(&cfg, 2, 2, &x, &y, None).is_ok());
}
