//! Every shipped scenario runs on every shipped vehicle: the check every
//! reader of a scenario makes (`ConfigDir::scenario_for`: the demand within
//! the vehicle's `torque_max`, 1 ..= 1e9 cycles) passes at the controller
//! loop's period (`controllers.toml [loop] rate_hz`, `grip sim`) and at
//! plant-sim's (`plant-sim.toml` `rate_hz`, `grip drive` and `grip
//! generate`), but for a scenario in time segments on a vehicle whose
//! microphone is ahead of the driven wheel, which is refused.

use std::path::{Path, PathBuf};

use grip_config::{ConfigDir, RunsOn};

fn config() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

fn vehicle_files() -> Vec<PathBuf> {
    let mut v = vec![config().join("vehicle.toml")];
    let mut more: Vec<PathBuf> = std::fs::read_dir(config().join("vehicles"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    more.sort();
    assert!(!more.is_empty(), "config/vehicles has no vehicle");
    v.extend(more);
    v
}

fn plant_sim_rate(dir: &Path) -> f64 {
    let text = std::fs::read_to_string(dir.join("plant-sim.toml")).unwrap();
    let t: toml::Table = text.parse().unwrap();
    t["rate_hz"].as_float().unwrap()
}

#[test]
fn every_shipped_scenario_runs_on_every_shipped_vehicle() {
    let d = ConfigDir::new(config());
    let roads = d.roads().unwrap();
    let controllers = grip_config::load_controllers(d.file("controllers.toml")).unwrap();
    let dts = [controllers.loop_.dt(), 1.0 / plant_sim_rate(d.path())];
    let names = d.scenario_names();
    assert!(names.len() >= 3, "{names:?}");
    let mut refused = 0;
    for v in vehicle_files() {
        let (vehicle, _) = grip_config::load_vehicle(&v).unwrap();
        for &dt in &dts {
            for n in &names {
                let on = RunsOn {
                    vehicle: &vehicle,
                    vehicle_file: &v,
                    dt,
                };
                let time = d.scenario_with(n, &roads).unwrap().segments_by
                    == grip_physics::SegmentMode::Time;
                if time && vehicle.mic_lead_m > 0.0 {
                    // a microphone ahead of the wheel needs distance
                    // segments: refused, naming both files and the field
                    let e = d.scenario_for(n, &roads, on).unwrap_err().to_string();
                    assert!(
                        e.contains(&*d.scenario_path(n).display().to_string())
                            && e.contains("field `segments_by`")
                            && e.contains(&*v.display().to_string()),
                        "{e}"
                    );
                    refused += 1;
                    continue;
                }
                let s = d
                    .scenario_for(n, &roads, on)
                    .unwrap_or_else(|e| panic!("{n} on {}: {e}", v.display()));
                assert_eq!(
                    grip_config::check_scenario(&d.scenario_path(n), &s, on),
                    Ok((s.duration / dt).round() as usize)
                );
            }
        }
    }
    // the shipped time-segment scenarios (e2e, incline) on the front-mic
    // car, at both periods
    assert!(refused >= 2, "{refused}");
}

/// No shipped scenario has anything at or after its end (a time segment
/// that begins there, a change of the demand there): loading one for a
/// run warns of nothing.
#[test]
fn no_shipped_scenario_has_anything_past_its_end() {
    let d = ConfigDir::new(config());
    let roads = d.roads().unwrap();
    for n in d.scenario_names() {
        let s = d.scenario_with(&n, &roads).unwrap();
        let w = grip_config::scenario::scenario_warnings(&d.scenario_path(&n), &s);
        assert!(w.is_empty(), "{n}: {w:?}");
    }
}
