//! Invariants of every controller for any finite input sequence: the command
//! is finite, never above the demand, and never negative for a non-negative
//! demand; internal signals stay finite.

use grip_physics::VehicleParams;
use grip_tcs::{
    AnyController, Controller, ControllerKind, ControllersConfig, Measurement, RoadKnowledge,
};
use proptest::prelude::*;

/// Finite values across many orders of magnitude, with exact zeros.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        -1.0e3..1.0e3,
        -1.0e-6..1.0e-6,
        -1.0e9..1.0e9,
        prop::num::f64::NORMAL,
    ]
}

fn measurement() -> impl Strategy<Value = Measurement> {
    (
        value(),
        prop::option::of(value()),
        value(),
        value(),
        any::<bool>(),
    )
        .prop_map(|(omega, v, torque, demand, standstill)| {
            if standstill {
                Measurement {
                    t: 0.0,
                    omega: 0.0,
                    v: Some(0.0),
                    torque,
                    demand,
                }
            } else {
                Measurement {
                    t: 0.0,
                    omega,
                    v,
                    torque,
                    demand,
                }
            }
        })
}

fn knowledge() -> impl Strategy<Value = Option<RoadKnowledge>> {
    prop::option::of((value(), value(), value(), value(), value()).prop_map(
        |(lambda_opt, mu_peak, alpha, confidence, age)| RoadKnowledge {
            lambda_opt,
            mu_peak,
            alpha,
            confidence,
            age,
        },
    ))
}

/// Plausible knowledge (used most of the time so that the ARTE branches run).
fn plausible_knowledge() -> impl Strategy<Value = Option<RoadKnowledge>> {
    prop::option::of(
        (
            0.005..0.6f64,
            0.05..1.3f64,
            0.01..1.0f64,
            0.0..1.0f64,
            0.0..0.5f64,
        )
            .prop_map(
                |(lambda_opt, mu_peak, alpha, confidence, age)| RoadKnowledge {
                    lambda_opt,
                    mu_peak,
                    alpha,
                    confidence,
                    age,
                },
            ),
    )
}

fn check(
    kind: ControllerKind,
    seq: &[(Measurement, Option<RoadKnowledge>)],
) -> Result<(), TestCaseError> {
    let cfg = ControllersConfig::default();
    let v = VehicleParams::default();
    let mut c = AnyController::new(kind, &cfg, &v, cfg.loop_.dt()).unwrap();
    for (k, (m, road)) in seq.iter().enumerate() {
        let m = Measurement {
            t: k as f64 * 1e-3,
            ..*m
        };
        let out = c.step(&m, road.as_ref());
        prop_assert!(
            out.torque_cmd.is_finite(),
            "{kind} step {k}: {out:?} for {m:?}"
        );
        prop_assert!(
            out.torque_cmd <= m.demand,
            "{kind} step {k}: {} > demand {}",
            out.torque_cmd,
            m.demand
        );
        if m.demand >= 0.0 {
            prop_assert!(
                out.torque_cmd >= 0.0,
                "{kind} step {k}: negative {}",
                out.torque_cmd
            );
        }
        prop_assert!(
            out.internal.is_finite(),
            "{kind} step {k}: internal {out:?}"
        );
        if kind != ControllerKind::Mfc {
            prop_assert!(out.mu_hat.is_finite(), "{kind} step {k}: mu_hat {out:?}");
        }
        if out.used_arte {
            prop_assert!(road.is_some());
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_finite_sequence_any_knowledge(
        seq in prop::collection::vec((measurement(), knowledge()), 1..80)
    ) {
        for kind in ControllerKind::ALL {
            check(kind, &seq)?;
        }
    }

    #[test]
    fn any_finite_sequence_plausible_knowledge(
        seq in prop::collection::vec((measurement(), plausible_knowledge()), 1..80)
    ) {
        for kind in ControllerKind::ALL {
            check(kind, &seq)?;
        }
    }

    /// Realistic ranges, long sequences (the filters and integrators get to
    /// evolve): the invariants still hold.
    #[test]
    fn realistic_long_sequences(
        seq in prop::collection::vec(
            ((0.0..120.0f64, prop::option::of(0.0..35.0f64), -50.0..1000.0f64, -200.0..1000.0f64)
                .prop_map(|(omega, v, torque, demand)| Measurement { t: 0.0, omega, v, torque, demand }),
             plausible_knowledge()),
            100..600)
    ) {
        for kind in ControllerKind::ALL {
            check(kind, &seq)?;
        }
    }
}
