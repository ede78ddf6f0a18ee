//! Closed-loop behaviour that must hold whatever the tuning: no slip at low
//! demand on asphalt, ARTE variants get and use the knowledge, and the
//! comparison's direction where it robustly holds.

mod common;

use grip_physics::{Demand, Scenario, Segment, SegmentMode};
use grip_sim::report::summarize;
use grip_sim::{Job, PerfectArte, RoadEstimator, SimSetup, Variant, run_batch};
use grip_tcs::ControllerKind;

/// 50 N m on dry asphalt needs mu = 50 / (0.28 m * 3434 N) = 0.05, far below
/// the peak 1.17: every variant keeps the slip near zero and still accelerates.
#[test]
fn no_variant_slips_on_asphalt_at_low_demand() {
    let (reference, est) = common::reference();
    let roads = reference.roads().clone();
    let asphalt = roads.index_of("asphalt").unwrap();
    let scenario = Scenario::new(
        "asphalt-low",
        "",
        2.0,
        20.0 / 3.6,
        SegmentMode::Time,
        vec![Segment {
            road_name: "asphalt".into(),
            road: asphalt,
            span: 2.0,
            grade_pct: 0.0,
        }],
        Demand::Constant { torque: 50.0 },
        roads.len(),
    )
    .unwrap();
    let (controllers, _) = common::controllers_and_arte();
    let setup = SimSetup::new(
        *reference.vehicle(),
        *reference.sensors(),
        roads,
        scenario,
        controllers,
        &grip_tcs::KnowledgeConfig::default(),
    )
    .unwrap();
    for v in Variant::ALL {
        let mut e = est.clone();
        let r = grip_sim::run(&setup, v, 1, &mut e).unwrap();
        let m = r.metrics;
        assert!(
            m.slip_deviation < 0.005,
            "{v}: slip deviation {} at 50 N m on asphalt",
            m.slip_deviation
        );
        assert!(m.mean_accel > 0.0, "{v}: no traction ({})", m.mean_accel);
        assert_eq!(r.non_finite_cycles, 0);
        let tr = r.trace.unwrap();
        if v.arte {
            // After the first frames the fused road belief is used most of
            // the time. Not always: at 50 N m the wheel cannot tell asphalt
            // from the roads whose curves start alike (wet asphalt, the
            // Pacejka asphalt), and a stray confusion-matrix frame then
            // leaves the belief below the 0.6 gate for a while.
            let used = tr.used_arte.iter().skip(200).filter(|&&u| u).count();
            let share = used as f64 / (tr.used_arte.len() - 200) as f64;
            assert!(share > 0.5, "{v}: knowledge used in {share} of the cycles");
            assert!(r.arte.frames >= 19);
        } else {
            assert!(tr.used_arte.iter().all(|&u| !u), "{v}");
            assert!(tr.est_road.iter().all(Option::is_none));
        }
    }
}

/// With a perfect road estimate the ARTE variants are told the true road
/// (checked on the reference scenario's trace).
#[test]
fn perfect_estimate_tracks_the_true_road() {
    let (setup, _) = common::reference();
    let mut e = PerfectArte::new(0.1);
    let r = grip_sim::run(&setup, Variant::ALL[4], 1, &mut e).unwrap();
    let tr = r.trace.unwrap();
    assert!(r.arte.frames >= 24);
    let mismatches = tr
        .est_road
        .iter()
        .zip(&tr.true_road)
        .filter(|(e, t)| e.is_some_and(|e| e != **t))
        .count();
    // Only during the <= 0.2 s after each road change.
    let changes = tr.true_road.windows(2).filter(|w| w[0] != w[1]).count();
    assert!(
        mismatches <= changes * 200,
        "{mismatches} cycles, {changes} changes"
    );
}

/// The oracle (`grip sim --arte oracle`) decides at every control cycle,
/// always for the road then at the microphone, and names itself so in
/// reports; the perfect classifier decides once per 0.1 s frame.
#[test]
fn oracle_decides_the_true_road_at_every_cycle() {
    let (setup, _) = common::reference();
    let mut oracle = PerfectArte::oracle(setup.dt());
    assert_eq!(RoadEstimator::name(&oracle), "oracle");
    assert_eq!(RoadEstimator::name(&PerfectArte::new(0.1)), "perfect");
    let o = grip_sim::run(&setup, Variant::ALL[4], 1, &mut oracle).unwrap();
    let p = grip_sim::run(&setup, Variant::ALL[4], 1, &mut PerfectArte::new(0.1)).unwrap();
    let cycles = setup.cycles() as u64;
    assert!(o.arte.frames + 1 >= cycles, "{} in {cycles}", o.arte.frames);
    assert_eq!(o.arte.correct, o.arte.frames);
    assert!(p.arte.frames * 50 < o.arte.frames, "{}", p.arte.frames);
}

/// The direction of the comparison that holds robustly on the reference
/// scenario over 20 seeds: ARTE raises SRC's traction (its fixed lower slip
/// reference on high-friction roads is replaced by the road's lambda_opt).
/// See the README's Results for why slip deviation is not asserted.
#[test]
fn arte_raises_src_traction_over_20_seeds() {
    let (setup, est) = common::reference();
    let seeds: Vec<u64> = (1..=20).collect();
    let variants = [Variant::ALL[1], Variant::ALL[4]];
    let jobs = Job::grid(&variants, &seeds, false);
    let make =
        move || -> Result<Box<dyn RoadEstimator>, grip_sim::SimError> { Ok(Box::new(est.clone())) };
    let results = run_batch(&setup, &jobs, 2, &make, &|_| {}).unwrap();
    let s = summarize(&results);
    let accel = |i: usize| s[i].stat("mean_accel").unwrap().mean;
    let dist = |i: usize| s[i].stat("distance").unwrap().mean;
    assert!(
        accel(1) > accel(0),
        "SRC {} vs SRC-ARTE {}",
        accel(0),
        accel(1)
    );
    assert!(dist(1) > dist(0), "SRC {} vs SRC-ARTE {}", dist(0), dist(1));
}

/// `SimSetup::with_controllers` (`grip sim --sweep`): the new parameters
/// are used, the cycle count follows the loop rate, a bad value is refused
/// naming the field.
#[test]
fn with_controllers_validates_and_follows_the_loop_rate() {
    let (reference, _) = common::reference();
    let mut c = *reference.controllers();
    c.preview.cap_share = 0.8;
    c.loop_.rate_hz = 500.0;
    let s = reference.with_controllers(c).unwrap();
    assert_eq!(s.controllers().preview.cap_share, 0.8);
    assert_eq!(s.cycles(), reference.cycles() / 2);
    c.preview.cap_share = 5.0;
    let e = reference.with_controllers(c).unwrap_err().to_string();
    assert!(e.contains("cap_share"), "{e}");
}

/// `SimSetup::with_vehicle` (`grip sim --sweep vehicle.KEY=...`): the new
/// vehicle is used and a bad one refused naming the field.
#[test]
fn with_vehicle_validates() {
    let (reference, _) = common::reference();
    let mut v = *reference.vehicle();
    v.mic_lead_m = 1.5;
    let s = reference.with_vehicle(v, *reference.sensors()).unwrap();
    assert_eq!(s.vehicle().mic_lead_m, 1.5);
    assert_eq!(s.cycles(), reference.cycles());
    v.mass = -1.0;
    let e = reference
        .with_vehicle(v, *reference.sensors())
        .unwrap_err()
        .to_string();
    assert!(e.contains("mass"), "{e}");
}

/// Pulling away from rest (`stop-and-go`: 220 N m for 1 s, 2 s off, from
/// standstill, on asphalt first), `config/vehicle.toml`, confusion matrix,
/// seeds 1-3: at a few cm/s the measured slip is mostly sensor noise,
/// where only ice's flat curve fits; before the speed gate of the road
/// belief (`[fusion] min_speed_evidence`) MFC-ARTE believed ice at every
/// pull-away, held the wheel at ice's 48 N m and the car never moved (MFC
/// alone reaches about 15 km/h). Now no cycle on asphalt is capped as ice
/// and MFC-ARTE gets at least 95 % of MFC's speed.
#[test]
fn mfc_arte_pulls_away_from_rest_without_believing_ice() {
    let (base, est) = common::reference();
    let dir = grip_config::ConfigDir::new(common::config_dir());
    let scenario = dir.scenario_with("stop-and-go", base.roads()).unwrap();
    let setup = base.with_scenario(scenario).unwrap();
    let ice = setup.roads().index_of("ice").unwrap() as u32;
    let asphalt = setup.roads().index_of("asphalt").unwrap() as u32;
    let mfc = |arte: bool, seed: u64| {
        let mut e = est.clone();
        grip_sim::run(
            &setup,
            Variant::new(ControllerKind::Mfc, arte),
            seed,
            &mut e,
        )
        .unwrap()
    };
    for seed in 1..=3u64 {
        let (with, without) = (mfc(true, seed), mfc(false, seed));
        let tr = with.trace.unwrap();
        let on_ice = (0..tr.t.len())
            .filter(|&k| {
                tr.used_arte[k] && tr.est_road[k] == Some(ice) && tr.true_road[k] == asphalt
            })
            .count();
        assert_eq!(
            on_ice, 0,
            "seed {seed}: {on_ice} cycles on asphalt capped as ice"
        );
        let (v_with, v_without) = (with.final_state.v * 3.6, without.final_state.v * 3.6);
        assert!(
            v_without > 10.0,
            "seed {seed}: MFC reaches {v_without} km/h"
        );
        assert!(
            v_with >= 0.95 * v_without,
            "seed {seed}: MFC-ARTE {v_with} km/h against MFC's {v_without}"
        );
    }
}

/// The baselines SRC and MTTE pull away from rest with the driver's ramped
/// pedal (`stop-and-go`: 0 -> 220 N m over 0.3 s, from standstill) and
/// climb the hill of `incline` (0 -> 400 N m over 1 s from 5 km/h), seeds
/// 1-2, `config/vehicle.toml`: each ends at no less than 90 % of MFC's
/// speed. Before the demand's rises passed into SRC's integrator and MTTE's
/// limit while the wheel grips (and SRC's slip had a launch speed), SRC
/// ended stop-and-go at 0 km/h (command at most 20 N m) and rolled back on
/// the hill, MTTE ended stop-and-go at 0.7 km/h (55 N m).
#[test]
fn src_and_mtte_pull_away_with_a_ramped_pedal() {
    let (base, est) = common::reference();
    let dir = grip_config::ConfigDir::new(common::config_dir());
    for name in ["stop-and-go", "incline"] {
        let scenario = dir.scenario_with(name, base.roads()).unwrap();
        let setup = base.with_scenario(scenario).unwrap();
        let speed = |kind, seed| {
            let mut e = est.clone();
            let r = grip_sim::run(&setup, Variant::new(kind, false), seed, &mut e).unwrap();
            r.final_state.v * 3.6
        };
        for seed in 1..=2u64 {
            let mfc = speed(ControllerKind::Mfc, seed);
            assert!(mfc > 10.0, "{name} seed {seed}: MFC ends at {mfc} km/h");
            for kind in [ControllerKind::Src, ControllerKind::Mtte] {
                let v = speed(kind, seed);
                assert!(
                    v >= 0.9 * mfc,
                    "{name} seed {seed}: {kind:?} ends at {v} km/h, MFC at {mfc}"
                );
            }
        }
    }
}
