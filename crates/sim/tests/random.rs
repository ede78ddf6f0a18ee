//! `grip sim --scenario random`: one road sequence per seed, reproducible,
//! only roads with a sound, lengths in the documented range; a batch with a
//! setup per seed gives each seed's runs exactly what a single-setup batch
//! on that seed's scenario gives.

mod common;

use grip_config::ConfigDir;
use grip_physics::SegmentMode;
use grip_sim::{
    Job, RandomSpec, RoadEstimator, SCENARIO_STREAM, SimSetup, Variant, run_batch, run_batch_with,
    sounding_roads,
};

fn roads() -> grip_physics::RoadCatalogue {
    ConfigDir::new(common::config_dir()).roads().unwrap()
}

fn roads_of(s: &grip_physics::Scenario) -> Vec<(String, f64)> {
    s.segments
        .iter()
        .map(|g| (g.road_name.clone(), g.span))
        .collect()
}

#[test]
fn same_seed_gives_the_same_scenario() {
    let roads = roads();
    let spec = RandomSpec::default();
    for seed in [0, 1, 1000, 1019, u64::MAX] {
        let a = spec.scenario(seed, &roads).unwrap();
        let b = spec.scenario(seed, &roads).unwrap();
        assert_eq!(a, b, "seed {seed}");
    }
    assert_eq!(SCENARIO_STREAM, 3, "documented in the README and random.rs");
}

#[test]
fn the_twenty_evaluation_seeds_give_twenty_different_sequences() {
    let roads = roads();
    let spec = RandomSpec::default();
    let all: Vec<_> = (1000..1020)
        .map(|s| roads_of(&spec.scenario(s, &roads).unwrap()))
        .collect();
    for i in 0..all.len() {
        for j in i + 1..all.len() {
            assert_ne!(all[i], all[j], "seeds {} and {}", 1000 + i, 1000 + j);
        }
    }
}

#[test]
fn only_roads_with_a_sound_lengths_in_range_and_every_boundary_a_change() {
    let roads = roads();
    let pool = sounding_roads(&roads);
    let names: Vec<&str> = pool
        .iter()
        .map(|&i| roads.by_index(i).unwrap().name())
        .collect();
    assert_eq!(
        names,
        [
            "asphalt",
            "gravel",
            "snow",
            "stone",
            "wet_asphalt",
            "wet_stone"
        ]
        .iter()
        .filter(|n| roads.index_of(n).is_some())
        .copied()
        .collect::<Vec<_>>()
    );
    assert!(
        roads.index_of("ice").is_some(),
        "the catalogue has a silent road"
    );
    let spec = RandomSpec::default();
    let mut seen = vec![false; roads.len()];
    for seed in 0..200 {
        let s = spec.scenario(seed, &roads).unwrap();
        assert_eq!(s.segments_by, SegmentMode::Distance);
        assert_eq!(s.duration, 2.4);
        assert!((s.v0 - 10.0 / 3.6).abs() < 1e-12);
        let total: f64 = s.segments.iter().map(|g| g.span).sum();
        assert!(total >= spec.cover_m, "seed {seed}: covers {total} m");
        for (k, g) in s.segments.iter().enumerate() {
            assert!(
                grip_arte::synth::road_index(&g.road_name).is_some(),
                "seed {seed}: `{}` has no sound",
                g.road_name
            );
            assert!(
                (spec.min_len_m..=spec.max_len_m).contains(&g.span),
                "seed {seed}: length {}",
                g.span
            );
            if k > 0 {
                assert_ne!(g.road, s.segments[k - 1].road, "seed {seed}: no change");
            }
            seen[g.road] = true;
        }
    }
    for &i in &pool {
        assert!(
            seen[i],
            "road {} never drawn",
            roads.by_index(i).unwrap().name()
        );
    }
}

#[test]
fn a_setup_per_seed_gives_what_each_seed_alone_gives() {
    let (base, est) = common::reference();
    let spec = RandomSpec::default();
    let seeds = [1000u64, 1001];
    let setups: Vec<SimSetup> = seeds
        .iter()
        .map(|&s| {
            base.with_scenario(spec.scenario(s, base.roads()).unwrap())
                .unwrap()
        })
        .collect();
    let make =
        move || -> Result<Box<dyn RoadEstimator>, grip_sim::SimError> { Ok(Box::new(est.clone())) };
    let jobs = Job::grid(&Variant::ALL, &seeds, false);
    let setup_of = |j: &Job| &setups[seeds.iter().position(|&s| s == j.seed).unwrap()];
    let mixed = run_batch_with(&setup_of, &jobs, 2, &make, &|_| {}).unwrap();
    for (k, &seed) in seeds.iter().enumerate() {
        let alone = run_batch(
            &setups[k],
            &Job::grid(&Variant::ALL, &[seed], false),
            1,
            &make,
            &|_| {},
        )
        .unwrap();
        let got: Vec<_> = mixed.iter().filter(|r| r.seed == seed).collect();
        assert_eq!(got.len(), alone.len());
        for (a, b) in got.iter().zip(&alone) {
            assert_eq!(a.variant, b.variant);
            assert_eq!(a.metrics, b.metrics, "seed {seed} {}", a.variant.name());
        }
    }
    // The two seeds' roads differ, so their runs do.
    assert_ne!(mixed[0].metrics, mixed[Variant::ALL.len()].metrics);
}

/// A launch at 200 N m from 10 km/h on the front-mic car (seeds 5 and 15 of
/// `--random torque=200`, confusion matrix; both begin on or soon meet a
/// road where 200 N m needs 1-3 % slip): before the slip was filtered like
/// μ̂ (`[fusion] tau_slip_s`), the measured slip's noise at that speed put
/// the belief under the wheel on ice, whose 48 N m cap then held the wheel
/// where it could show nothing else (MTTE-ARTE: 2 % of all cycles of the
/// tuning seeds, seed 19 with acoustic estimates 21 % slower). No ARTE
/// variant may act on an ice belief on roads without ice.
#[test]
fn slip_noise_at_a_launch_does_not_make_a_road_ice() {
    let (base, est) = common::reference();
    let (vehicle, sensors) =
        grip_config::load_vehicle(common::config_dir().join("vehicles/front-mic.toml")).unwrap();
    let front_mic = base.with_vehicle(vehicle, sensors).unwrap();
    let ice = front_mic.roads().index_of("ice").unwrap() as u32;
    let spec = RandomSpec::parse("torque=200").unwrap().covering_travel();
    for seed in [5u64, 15] {
        let scenario = spec.scenario(seed, front_mic.roads()).unwrap();
        let setup = front_mic.with_scenario(scenario).unwrap();
        for kind in grip_tcs::ControllerKind::ALL {
            let mut e = est.clone();
            let r = grip_sim::run(&setup, Variant::new(kind, true), seed, &mut e).unwrap();
            let tr = r.trace.unwrap();
            let on_ice = (0..tr.t.len())
                .filter(|&k| {
                    tr.used_arte[k] && tr.est_road[k] == Some(ice) && tr.true_road[k] != ice
                })
                .count();
            assert_eq!(
                on_ice, 0,
                "seed {seed} {kind}-ARTE: {on_ice} cycles capped as ice"
            );
        }
    }
}
