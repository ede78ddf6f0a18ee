//! The shipped configuration (`config/` at the repository root) loads, and the
//! scenarios behave as their comments say when driven by the physics plant:
//! plain open loop (T* = demand) and a rough ideal TCS (T* = min(demand,
//! 0.95 mu_peak N r), i.e. what a controller that knows the road can pass).

use std::path::PathBuf;

use grip_config::ConfigDir;
use grip_physics::{Plant, PlantState, Scenario, VehicleParams};

fn dir() -> ConfigDir {
    ConfigDir::new(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config"))
}

/// Run a scenario at 1 kHz; returns (min V, max V, final V) in km/h and the max slip.
fn drive(
    s: &Scenario,
    p: VehicleParams,
    roads: &grip_physics::RoadCatalogue,
    tcs: bool,
) -> (f64, f64, f64, f64) {
    let mut plant = Plant::new(p, PlantState::rolling(s.v0, p.r)).unwrap();
    let dt = 1e-3;
    let steps = (s.duration / dt).round() as usize;
    let (mut vmin, mut vmax, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for k in 0..steps {
        let t = k as f64 * dt;
        let st = *plant.state();
        let seg = &s.segments[s.road_at(t, st.x)];
        let road = &roads[seg.road];
        let grade = seg.grade_rad();
        let demand = s.demand_at(t);
        let cmd = if tcs {
            demand.min(0.95 * road.mu_peak() * p.normal_force() * grade.cos() * p.r)
        } else {
            demand
        };
        plant.step(dt, cmd, road, grade);
        let v = plant.state().v * 3.6;
        vmin = vmin.min(v);
        vmax = vmax.max(v);
        lmax = lmax.max(plant.lambda());
        assert!(v.is_finite() && plant.lambda().is_finite());
    }
    (vmin, vmax, plant.state().v * 3.6, lmax)
}

#[test]
fn shipped_config_loads() {
    let d = dir();
    let (v, s) = d.vehicle().unwrap();
    assert_eq!(v, VehicleParams::default());
    assert_eq!(s, grip_physics::SensorParams::default());
    let roads = d.roads().unwrap();
    for name in [
        "asphalt",
        "gravel",
        "snow",
        "stone",
        "wet_asphalt",
        "wet_stone",
        "ice",
        "asphalt_mf",
        "gravel_table",
    ] {
        assert!(roads.get(name).is_some(), "missing road {name}");
    }
    // the printed optima (crates/physics/README.md, "The catalogue").
    let a = roads.get("asphalt").unwrap();
    assert!((a.lambda_opt() - 0.170).abs() < 0.0015 && (a.mu_peak() - 1.17).abs() < 0.006);
    // The gravel fit reproduces what it was fitted to.
    let g = roads.get("gravel").unwrap();
    assert!((g.lambda_opt() - 0.25).abs() < 0.002, "{}", g.lambda_opt());
    assert!((g.mu_peak() - 0.60).abs() < 0.001, "{}", g.mu_peak());
    assert!((g.mu(1.0) - 0.55).abs() < 0.001, "{}", g.mu(1.0));
    let names = d.scenario_names();
    for n in ["paper", "stop-and-go", "incline", "winter"] {
        assert!(names.iter().any(|x| x == n), "missing scenario {n}");
        d.scenario_with(n, &roads).unwrap();
    }
}

#[test]
fn paper_scenario_stays_in_the_10_to_30_kmh_bracket() {
    let d = dir();
    let (p, _) = d.vehicle().unwrap();
    let roads = d.roads().unwrap();
    let s = d.scenario("paper").unwrap();
    assert_eq!(s.demand_at(1.0), 300.0);
    assert!((s.v0 * 3.6 - 10.0).abs() < 1e-9);
    let kinds: Vec<&str> = s.segments.iter().map(|x| x.road_name.as_str()).collect();
    for r in ["asphalt", "gravel", "snow", "stone"] {
        assert!(kinds.contains(&r), "paper scenario lacks {r}");
    }
    let (vmin, vmax, vend, lmax) = drive(&s, p, &roads, false);
    eprintln!("paper open loop: V {vmin:.1}..{vmax:.1} km/h, final {vend:.1}, max slip {lmax:.2}");
    let (tmin, tmax, tend, tlmax) = drive(&s, p, &roads, true);
    eprintln!("paper rough TCS: V {tmin:.1}..{tmax:.1} km/h, final {tend:.1}, max slip {tlmax:.2}");
    // Open loop: the wheel spins on snow and dumps its spin into the car on
    // the next grippy road, so it runs fastest; "roughly" 10-30 km/h.
    assert!(vmin >= 9.99 && vmax <= 32.0, "open loop {vmin}..{vmax}");
    assert!(
        lmax > 0.5,
        "300 N m should spin the wheel on snow (max slip {lmax})"
    );
    // A controller that holds each road's peak stays within the bracket.
    // (Its slip still peaks on entering snow: the motor lag of 50 ms keeps the
    // torque up for a while after the command drops.)
    assert!(
        tmin >= 9.99 && tmax <= 30.0,
        "rough TCS {tmin}..{tmax}, max slip {tlmax}"
    );
}

#[test]
fn other_scenarios_run_finite() {
    let d = dir();
    let (p, _) = d.vehicle().unwrap();
    let roads = d.roads().unwrap();
    for n in ["stop-and-go", "incline", "winter"] {
        let s = d.scenario(n).unwrap();
        for tcs in [false, true] {
            let (vmin, vmax, vend, lmax) = drive(&s, p, &roads, tcs);
            eprintln!(
                "{n} tcs={tcs}: V {vmin:.1}..{vmax:.1} km/h, final {vend:.1}, max slip {lmax:.2}"
            );
            assert!(vmin > -1.0, "{n}: rolled back to {vmin} km/h");
            assert!(vend > 0.0, "{n}: did not move");
        }
    }
}

/// The shipped controllers' gains suit the three shipped vehicles, loaded
/// as the services and `grip sim` load them: MFC's k_mfc is within bound
/// (4) on every road, and SRC's kp, ti and kp_recover are their derivation
/// from J_w and tau_m (kp = J_w/(2 tau_m) = 6, ti = 4 tau_m = 0.2,
/// kp_recover = 20 inside [6, (J_w + (M/n) r^2)/(2 tau_m)]): no start-up
/// warning for any controller.
#[test]
fn the_shipped_gains_suit_the_shipped_vehicles() {
    use grip_tcs::analysis::vehicle_tf::{gain_warning, src_gains, src_gains_off};
    let d = dir();
    let roads = d.roads().unwrap();
    let controllers_file = d.file("controllers.toml");
    let controllers = grip_config::load_controllers(&controllers_file).unwrap();
    for f in [
        "vehicle.toml",
        "vehicles/front-mic.toml",
        "vehicles/rear-mic.toml",
    ] {
        let vehicle_file = d.file(f);
        let (v, _) = grip_config::load_vehicle(&vehicle_file).unwrap();
        let g = src_gains(&v).unwrap();
        assert!(
            (controllers.src.kp / g.kp - 1.0).abs() < 1e-12,
            "{f}: {g:?}"
        );
        assert!(
            (controllers.src.ti / g.ti - 1.0).abs() < 1e-12,
            "{f}: {g:?}"
        );
        assert!(
            src_gains_off(&v, &controllers.src).unwrap().is_empty(),
            "{f}"
        );
        for kind in grip_tcs::ControllerKind::ALL {
            let w = gain_warning(
                kind,
                &v,
                &vehicle_file,
                &roads,
                &controllers,
                &controllers_file,
            );
            assert_eq!(w.unwrap(), None, "{f}, {kind}");
        }
    }
}

/// The shipped sensors suit the road belief: on the three shipped
/// vehicles the slip noise of their `[sensors]` at 10 km/h (after the
/// belief's filter) is within the tolerance of `fusion.sigma_lambda`, so no
/// start-up warning (`grip_tcs::analysis::sensors`).
#[test]
fn the_shipped_sensors_suit_the_road_belief() {
    use grip_tcs::analysis::sensors::{REF_SPEED_MPS, sensor_warning, slip_noise};
    let d = dir();
    let controllers_file = d.file("controllers.toml");
    let controllers = grip_config::load_controllers(&controllers_file).unwrap();
    let dt = 1.0 / controllers.loop_.rate_hz;
    for f in [
        "vehicle.toml",
        "vehicles/front-mic.toml",
        "vehicles/rear-mic.toml",
    ] {
        let vehicle_file = d.file(f);
        let (v, s) = grip_config::load_vehicle(&vehicle_file).unwrap();
        let n = slip_noise(&v, &s, controllers.fusion.tau_slip_s, dt, REF_SPEED_MPS).unwrap();
        assert!(
            n.filtered < 1.25 * controllers.fusion.sigma_lambda,
            "{f}: {n:?}"
        );
        assert_eq!(
            sensor_warning(
                &v,
                &s,
                &vehicle_file,
                &controllers.fusion,
                &controllers_file,
                dt
            ),
            None,
            "{f}"
        );
    }
}
