//! One `step` of each controller (with and without usable road knowledge),
//! and one `MetricsAccumulator::push`.

use criterion::{Criterion, criterion_group, criterion_main};
use grip_physics::VehicleParams;
use grip_tcs::{
    AnyController, Controller, ControllerKind, ControllersConfig, Measurement, MetricsAccumulator,
    RoadKnowledge, Sample,
};
use std::hint::black_box;

fn bench_controllers(c: &mut Criterion) {
    let cfg = ControllersConfig::default();
    let v = VehicleParams::default();
    let dt = cfg.loop_.dt();
    let road = RoadKnowledge {
        lambda_opt: 0.06,
        mu_peak: 0.19,
        alpha: 0.94,
        confidence: 0.9,
        age: 0.05,
    };
    for kind in ControllerKind::ALL {
        for (label, know) in [("no_arte", None), ("arte", Some(&road))] {
            let mut ctl = AnyController::new(kind, &cfg, &v, dt).unwrap();
            let mut k = 0u64;
            c.bench_function(&format!("{kind}_step_{label}"), |b| {
                b.iter(|| {
                    k += 1;
                    let t = k as f64 * dt;
                    // A slowly varying, slipping operating point.
                    let omega = 12.0 + (t * 3.0).sin();
                    let m = Measurement {
                        t,
                        omega,
                        v: Some(3.0),
                        torque: 200.0 + 20.0 * (t * 5.0).sin(),
                        demand: 300.0,
                    };
                    black_box(ctl.step(black_box(&m), black_box(know)))
                })
            });
        }
    }
    let mut acc = MetricsAccumulator::new(&v);
    c.bench_function("metrics_push", |b| {
        b.iter(|| {
            acc.push(black_box(&Sample {
                dt: 1e-3,
                lambda: 0.05,
                torque: 200.0,
                omega: 12.0,
                v: 3.2,
                torque_cmd: 199.0,
            }));
        })
    });
}

criterion_group!(benches, bench_controllers);
criterion_main!(benches);
