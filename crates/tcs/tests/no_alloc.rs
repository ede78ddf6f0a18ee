//! Allocation-free proof: a counting global allocator; 10 000 `step`s of each
//! controller (with and without road knowledge, through `AnyController`) and
//! 10 000 `MetricsAccumulator::push`es allocate nothing after construction,
//! nor does a preview queue that overflows (its farthest entries merged).
//! Counted on this (the only working) thread: the test harness's main thread
//! may allocate while the test runs and must not count.

use grip_physics::VehicleParams;
use grip_tcs::{
    AnyController, Controller, ControllerKind, ControllersConfig, Measurement, MetricsAccumulator,
    PREVIEW_CAPACITY, PreviewQueue, RoadKnowledge, Sample,
};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

#[test]
fn steps_allocate_nothing() {
    let cfg = ControllersConfig::default();
    // The MFC runs with its noise low-pass (its state is part of the proof).
    assert!(cfg.mfc.tau_noise > 0.0);
    let v = VehicleParams::default();
    let road = RoadKnowledge {
        lambda_opt: 0.17,
        mu_peak: 1.17,
        alpha: 0.83,
        confidence: 0.9,
        age: 0.1,
    };
    let mut controllers: [AnyController; 3] =
        ControllerKind::ALL.map(|k| AnyController::new(k, &cfg, &v, cfg.loop_.dt()).unwrap());
    let mut acc = MetricsAccumulator::new(&v);
    let mut sink = 0.0;

    let before = grip_testkit::thread_allocations();
    for c in controllers.iter_mut() {
        for k in 0..10_000 {
            let t = k as f64 * 1e-3;
            // Exercise every branch: with/without knowledge, with/without V,
            // positive and negative demand, a spinning wheel.
            let m = Measurement {
                t,
                omega: 10.0 + 30.0 * (t * 2.0).sin().abs(),
                v: if k % 1000 < 900 { Some(3.0) } else { None },
                torque: 150.0 + 100.0 * (t * 5.0).sin(),
                demand: if k % 2000 < 1800 { 300.0 } else { -50.0 },
            };
            let know = if k % 3 == 0 { None } else { Some(&road) };
            let out = c.step(&m, know);
            sink += out.torque_cmd;
            acc.push(&Sample {
                dt: if k % 7 == 0 { 1.1e-3 } else { 1e-3 },
                lambda: 0.05,
                torque: out.torque_cmd,
                omega: m.omega,
                v: 3.0,
                // every other cycle without a command, and the cycle length
                // changing (the high-pass is redesigned in place)
                torque_cmd: if k % 2 == 0 { out.torque_cmd } else { f64::NAN },
            });
        }
        c.reset();
    }
    let m = acc.finish();
    let after = grip_testkit::thread_allocations();
    assert_eq!(after - before, 0, "allocations during 30 000 steps");
    assert!(sink.is_finite() && m.samples == 30_000);
    assert!(m.cmd_tv_per_s > 0.0 && m.cmd_hf_rms > 0.0);
}

#[test]
fn a_full_preview_queue_allocates_nothing() {
    let mu = |i: usize| [1.0, 0.5, 0.2].get(i).copied().unwrap_or(f64::NAN);
    let mut q = PreviewQueue::new();
    let mut sink = 0.0;
    let before = grip_testkit::thread_allocations();
    for k in 0..10_000_u32 {
        // Confirmed pairs, alternating, 5 cm apart: far more than the
        // queue holds ahead of the wheel.
        let x = f64::from(k / 2) * 0.05;
        q.push(((k / 2) % 3) as usize, 0.9, x, x + 2.0, x + 2.05, mu);
        let v = q.view(x);
        sink += v.here.map_or(0.0, |h| h.x_start);
    }
    let after = grip_testkit::thread_allocations();
    assert_eq!(after - before, 0, "allocations during 10 000 decisions");
    assert!(
        q.overflows() > 0 && q.len() == PREVIEW_CAPACITY,
        "{}",
        q.len()
    );
    assert!(sink.is_finite());
}
