//! Integrator convergence on the reference scenario: halving the plant's
//! internal step changes every metric of every variant by less than 1 %.

mod common;

use grip_sim::{Sim, Variant};

#[test]
fn halving_the_plant_substep_changes_every_metric_by_less_than_one_percent() {
    let (setup, est) = common::reference();
    let mut fine = setup.clone();
    fine.set_max_substep(setup.max_substep() / 2.0).unwrap();
    for v in Variant::ALL {
        let mut e1 = est.clone();
        let mut e2 = est.clone();
        let a = Sim::new(&setup, v, 1, &mut e1, false)
            .unwrap()
            .finish()
            .metrics;
        let b = Sim::new(&fine, v, 1, &mut e2, false)
            .unwrap()
            .finish()
            .metrics;
        for (name, x, y) in [
            ("slip_deviation", a.slip_deviation, b.slip_deviation),
            ("max_torque", a.max_torque, b.max_torque),
            ("torque_effort", a.torque_effort, b.torque_effort),
            ("mean_accel", a.mean_accel, b.mean_accel),
            ("distance", a.distance, b.distance),
            ("energy", a.energy, b.energy),
            (
                "kinetic_energy_gain",
                a.kinetic_energy_gain,
                b.kinetic_energy_gain,
            ),
        ] {
            assert!(x.is_finite() && y.is_finite(), "{v} {name}: {x} vs {y}");
            let rel = (x - y).abs() / y.abs().max(1e-12);
            assert!(
                rel < 0.01,
                "{v}: {name} changes by {:.3} % when the sub-step halves ({x} vs {y})",
                100.0 * rel
            );
        }
    }
}
