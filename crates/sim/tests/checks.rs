//! What a setup refuses and what a run reports about its own validity: a
//! demand above the motor's limit, a plant sub-step the plant would not
//! honour, a random road list sized to what the car can reach, a run past
//! the end of its roads, the confusion source's pass-through roads and the
//! time the estimator heard each road.

mod common;

use grip_config::ConfigDir;
use grip_physics::{Demand, Scenario};
use grip_sim::{InLoopProbe, RandomSpec, RoadEstimator, Variant};

/// `scenario` with another demand.
fn with_demand(s: &Scenario, demand: Demand, roads: usize) -> Scenario {
    Scenario::new(
        s.name.clone(),
        s.description.clone(),
        s.duration,
        s.v0,
        s.segments_by,
        s.segments.clone(),
        demand,
        roads,
    )
    .unwrap()
}

#[test]
fn a_demand_above_the_motor_limit_is_refused_naming_the_field() {
    let (setup, _) = common::reference();
    let limit = setup.vehicle().torque_max;
    let n = setup.roads().len();
    let sc = setup.scenario();
    let e = setup
        .with_scenario(with_demand(sc, Demand::Constant { torque: 1500.0 }, n))
        .unwrap_err();
    assert_eq!(e.field(), "scenario.demand.torque");
    let text = e.to_string();
    assert!(
        text.contains("1500") && text.contains(&format!("torque_max = {limit}")),
        "{text}"
    );
    let e = setup
        .with_scenario(with_demand(
            sc,
            Demand::Steps {
                times: vec![0.0, 1.0],
                torques: vec![300.0, 1e300],
            },
            n,
        ))
        .unwrap_err();
    assert_eq!(e.field(), "scenario.demand.torques[1]");
    let e = setup
        .with_scenario(with_demand(
            sc,
            Demand::Ramp {
                from: 0.0,
                to: 1000.5,
                start: 0.0,
                duration: 1.0,
            },
            n,
        ))
        .unwrap_err();
    assert_eq!(e.field(), "scenario.demand.to");
    // At the limit is accepted.
    setup
        .with_scenario(with_demand(sc, Demand::Constant { torque: limit }, n))
        .unwrap();
    // A vehicle with a lower limit refuses the shipped demand.
    let mut weak = *setup.vehicle();
    weak.torque_max = 250.0;
    let e = setup.with_vehicle(weak, *setup.sensors()).unwrap_err();
    assert_eq!(e.field(), "scenario.demand.torque");
}

#[test]
fn a_sub_step_the_plant_would_not_honour_is_refused() {
    let (mut setup, _) = common::reference();
    // 1 ms cycles, at most 100 000 sub-steps each: 1e-8 s is the smallest.
    let e = setup.set_max_substep(1e-9).unwrap_err();
    assert_eq!(e.field(), "max_substep");
    assert!(e.to_string().contains("100000"), "{e}");
    setup.set_max_substep(1e-8).unwrap();
    assert_eq!(setup.max_substep(), 1e-8);
    assert!(setup.set_max_substep(0.0).is_err());
    assert!(setup.set_max_substep(f64::NAN).is_err());
    // A slower loop raises the smallest honoured sub-step with it.
    let mut c = *setup.controllers();
    c.loop_.rate_hz = 100.0;
    let e = setup.with_controllers(c).unwrap_err();
    assert_eq!(e.field(), "max_substep");
}

#[test]
fn a_longer_random_run_is_sized_to_what_the_car_can_reach() {
    let (base, est) = common::reference();
    let dir = ConfigDir::new(common::config_dir());
    // The default recipe keeps its 24 m on the shipped vehicles (its seeds
    // keep their roads).
    for file in [
        "vehicle.toml",
        "vehicles/front-mic.toml",
        "vehicles/rear-mic.toml",
    ] {
        let (vehicle, _) = grip_config::load_vehicle(dir.file(file)).unwrap();
        let sized = RandomSpec::default().sized_for(&vehicle, base.roads());
        assert_eq!(sized, RandomSpec::default(), "{file}");
        let sized = RandomSpec::parse("v0_kmh=30").unwrap();
        assert_eq!(
            sized.clone().sized_for(&vehicle, base.roads()),
            sized,
            "{file}"
        );
    }
    // 10 s from 10 km/h: the car reaches about 155 m; the road list covers
    // more, and every variant ends on it.
    let spec = RandomSpec::parse("duration=10")
        .unwrap()
        .sized_for(base.vehicle(), base.roads());
    assert!(spec.cover_m > 160.0, "{spec:?}");
    let setup = base
        .with_scenario(spec.scenario(1, base.roads()).unwrap())
        .unwrap();
    for v in Variant::ALL {
        let mut e = est.clone();
        let r = grip_sim::run(&setup, v, 1, &mut e).unwrap();
        let span = setup.scenario().total_span();
        assert!(
            r.final_state.x < span,
            "{v}: {} m of {span} m",
            r.final_state.x
        );
        assert_eq!(setup.beyond_roads(r.final_state.x), None);
    }
    // The longer list only appends: the first segments are the unsized ones.
    let short = RandomSpec::parse("duration=10")
        .unwrap()
        .scenario(1, base.roads())
        .unwrap();
    assert_eq!(
        short.segments[..],
        setup.scenario().segments[..short.segments.len()]
    );
    // A given cover is kept as given.
    let given = RandomSpec::parse("duration=10,cover_m=30").unwrap();
    assert_eq!(
        given
            .clone()
            .sized_for(base.vehicle(), base.roads())
            .cover_m,
        30.0
    );
}

#[test]
fn a_run_past_the_end_of_its_roads_is_measured() {
    let (base, est) = common::reference();
    let spec = RandomSpec::parse("cover_m=5").unwrap();
    let setup = base
        .with_scenario(spec.scenario(1, base.roads()).unwrap())
        .unwrap();
    let mut e = est.clone();
    let r = grip_sim::run(&setup, Variant::ALL[0], 1, &mut e).unwrap();
    let span = setup.scenario().total_span();
    let past = setup.beyond_roads(r.final_state.x).unwrap();
    assert!((past - (r.final_state.x - span)).abs() < 1e-12 && past > 0.0);
    assert_eq!(setup.beyond_roads(span), None);
}

#[test]
fn the_confusion_source_names_its_pass_through_roads() {
    let (setup, est) = common::reference();
    let roads = setup.roads();
    let names: Vec<&str> = est
        .pass_through()
        .into_iter()
        .map(|i| roads[i].name())
        .collect();
    // The shipped matrix has asphalt, snow, stone, gravel; its map is empty.
    for n in ["wet_asphalt", "wet_stone", "ice"] {
        assert!(names.contains(&n), "{names:?}");
    }
    for n in ["asphalt", "snow", "stone", "gravel"] {
        assert!(!names.contains(&n), "{names:?}");
    }
    assert!((est.outside_confidence() - 0.858).abs() < 1e-3);
}

#[test]
fn the_probe_records_what_the_estimator_heard() {
    let (setup, est) = common::reference();
    let mut p = InLoopProbe::new(
        Box::new(est),
        0.1,
        setup.estimator_cycles(),
        0.2,
        setup.roads().len(),
    );
    let v = Variant::ALL.iter().copied().find(|v| v.arte).unwrap();
    let r = grip_sim::run(&setup, v, 3, &mut p as &mut dyn RoadEstimator).unwrap();
    let s = r.inloop.unwrap();
    let heard: f64 = s.heard_s.iter().sum();
    assert!((heard - setup.sim_time()).abs() < 1e-6, "{heard}");
    let snow = setup.roads().index_of("snow").unwrap();
    assert!(s.heard_s[snow] > 0.0);
    assert_eq!(
        InLoopProbe::bytes_for(1000),
        2 * 1000 * std::mem::size_of::<(f64, usize)>() as u64
            + (grip_sim::probe::SPEED_BINS * std::mem::size_of::<f64>()) as u64
    );
}

/// The user's trial (b): distance mode, 1 s from 20 km/h over asphalt 2 m,
/// snow 50 m, ice 100 m. The car gets past the asphalt (about 6 m) and
/// never to the ice: the run says how far it got, the setup names the
/// segment it never reached.
#[test]
fn the_distance_segments_a_run_never_reached_are_named() {
    let (base, est) = common::reference();
    let roads = base.roads();
    let seg = |name: &str, span: f64| grip_physics::Segment {
        road_name: name.to_owned(),
        road: roads.index_of(name).unwrap(),
        span,
        grade_pct: 0.0,
    };
    let sc = Scenario::new(
        "mine",
        "",
        1.0,
        20.0 / 3.6,
        grip_physics::SegmentMode::Distance,
        vec![seg("asphalt", 2.0), seg("snow", 50.0), seg("ice", 100.0)],
        Demand::Constant { torque: 250.0 },
        roads.len(),
    )
    .unwrap();
    assert!(sc.past_the_end().is_empty(), "known only after a run");
    let setup = base.with_scenario(sc).unwrap();
    let mut e = est.clone();
    let r = grip_sim::run(&setup, Variant::ALL[0], 1, &mut e).unwrap();
    assert!(
        r.farthest_x > 2.0 && r.farthest_x < 52.0,
        "{}",
        r.farthest_x
    );
    assert!(r.farthest_x <= r.final_state.x, "a car that drives on");
    assert_eq!(setup.unreached(r.farthest_x), [2]);
    assert_eq!(setup.unreached(1.0), [1, 2]);
    assert_eq!(setup.unreached(52.0), Vec::<usize>::new(), "at its start");
    assert_eq!(setup.unreached(f64::NAN), Vec::<usize>::new());
    // time segments: warned of before the run, not here
    let mut timed = setup.scenario().clone();
    timed.segments_by = grip_physics::SegmentMode::Time;
    let timed = base.with_scenario(timed).unwrap();
    assert_eq!(timed.unreached(0.0), Vec::<usize>::new());
}

/// `--scenario random`'s sequences have nothing past their end (distance
/// segments, a constant demand): loading one warns of nothing.
#[test]
fn random_scenarios_have_nothing_past_their_end() {
    let (base, _) = common::reference();
    let spec = RandomSpec::default().sized_for(base.vehicle(), base.roads());
    for seed in 0..50 {
        let sc = spec.scenario(seed, base.roads()).unwrap();
        assert!(sc.past_the_end().is_empty(), "seed {seed}");
    }
}
