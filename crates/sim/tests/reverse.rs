//! A hill start that rolls back (`tests/data/rollback.toml`): the car,
//! front-mic, stands on 12 % dry asphalt with no demand for 3 s and rolls
//! back, then the driver asks 400 N m. Every ARTE variant must stop the
//! roll-back as its baseline does: the road knowledge must neither take the
//! backwards-rolling wheel for a spinning one (the fusion's slip over
//! max(rω, V, v_eps) made it so: ice, the spin cut, 19-48 N m) nor keep a
//! queue placed on an odometer that stood while the car went back.

mod common;

use std::path::Path;

use grip_config::ConfigDir;
use grip_sim::{PerfectArte, SimSetup, Variant};
use grip_tcs::ControllerKind;

fn rollback_setup() -> SimSetup {
    setup_for("rollback.toml")
}

fn setup_for(file: &str) -> SimSetup {
    let dir = ConfigDir::new(common::config_dir());
    let (vehicle, sensors) =
        grip_config::load_vehicle(common::config_dir().join("vehicles/front-mic.toml")).unwrap();
    let roads = dir.roads().unwrap();
    let knowledge = dir.knowledge(&roads).unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(file);
    let scenario = dir.scenario_with(path.to_str().unwrap(), &roads).unwrap();
    let (controllers, _) = common::controllers_and_arte();
    SimSetup::new(vehicle, sensors, roads, scenario, controllers, &knowledge).unwrap()
}

/// How far the car rolled back, m (the lowest point of ∫ V dt), the time
/// from the demand's step (3 s) to the first cycle at V >= 0, s, and V at
/// the end, m/s.
fn roll_back(setup: &SimSetup, kind: ControllerKind, arte: bool) -> (f64, f64, f64) {
    let mut est = PerfectArte::new(0.1);
    let r = grip_sim::run(setup, Variant::new(kind, arte), 1, &mut est).unwrap();
    // the farthest the wheel got is where it started, not where it ended
    assert!(
        r.farthest_x == 0.0 && r.final_state.x < -1.0,
        "{kind}: farthest {} m, final {} m",
        r.farthest_x,
        r.final_state.x
    );
    let tr = r.trace.unwrap();
    let dt = setup.dt();
    let (mut x, mut lowest) = (0.0, 0.0f64);
    for &v in &tr.v {
        x += v * dt;
        lowest = lowest.min(x);
    }
    let step = tr.t.iter().position(|&t| t >= 3.0).unwrap();
    assert!(
        tr.v[step] < -3.0,
        "{kind}: rolling back at the step: {}",
        tr.v[step]
    );
    let back = tr.v[step..]
        .iter()
        .position(|&v| v >= 0.0)
        .map_or(f64::INFINITY, |k| k as f64 * dt);
    (-lowest, back, r.final_state.v)
}

#[test]
fn every_arte_variant_stops_a_roll_back_as_its_baseline_does() {
    let setup = rollback_setup();
    for kind in ControllerKind::ALL {
        let (base, base_back, base_end) = roll_back(&setup, kind, false);
        let (with, back, end) = roll_back(&setup, kind, true);
        assert!(
            base > 5.0 && base_back < 3.9,
            "{kind}: baseline {base} m, {base_back} s"
        );
        assert!(
            (with - base).abs() <= (0.05 * base).max(0.03),
            "{kind}-ARTE rolled back {with:.3} m, {kind} {base:.3} m"
        );
        assert!(
            back <= base_back + 0.05,
            "{kind}-ARTE back to V >= 0 after {back} s, {kind} after {base_back} s"
        );
        assert!(
            base_end > 0.0 && end > 0.0,
            "{kind}: V at the end {end}, baseline {base_end}"
        );
    }
}

/// A hill start on 12 % wet stone (`tests/data/hillstart.toml`, 0 -> 400 N m
/// over 1 s; the car first rolls back a little). The wheel breaks away at
/// about 100 % slip, where wet stone carries μ 0.28 against its peak 0.38.
/// The spin cut's early end ("landing") weighed the wheel's excess
/// momentum against the motor's return to the road's full cap, so at 98 %
/// slip it ended at once and the wheel spun up again every 0.24 s, for
/// seconds: MFC-ARTE's and MTTE-ARTE's slip 0.99x and 0.98x their
/// baselines', the car at walking pace. Weighed against what the tyre
/// carries at that slip, the cut holds until the wheel has come back.
#[test]
fn a_wheel_that_breaks_away_on_a_hill_start_is_brought_back() {
    let setup = setup_for("hillstart.toml");
    for kind in ControllerKind::ALL {
        let run = |arte: bool| {
            let mut est = PerfectArte::new(0.1);
            grip_sim::run(&setup, Variant::new(kind, arte), 1, &mut est)
                .unwrap()
                .metrics
        };
        let (base, with) = (run(false), run(true));
        assert!(
            with.mean_accel >= base.mean_accel,
            "{kind}-ARTE accel {} < {kind}'s {}",
            with.mean_accel,
            base.mean_accel
        );
        assert!(
            with.slip_deviation <= base.slip_deviation,
            "{kind}-ARTE slip {} > {kind}'s {}",
            with.slip_deviation,
            base.slip_deviation
        );
        if kind != ControllerKind::Src {
            // MFC and MTTE spin at about 100 % slip for seconds
            assert!(base.slip_deviation > 0.6, "{kind}: {}", base.slip_deviation);
            assert!(
                with.slip_deviation < 0.8 * base.slip_deviation,
                "{kind}-ARTE slip {} against {kind}'s {}: the spin not brought back",
                with.slip_deviation,
                base.slip_deviation
            );
        }
    }
}
