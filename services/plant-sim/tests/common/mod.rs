//! Test doubles: the in-process CAN bus (`grip_io::can::MemBus`), a truth
//! recorder, and the shipped configuration.

#![allow(dead_code, unused_imports)]

use std::path::PathBuf;

use grip_config::ConfigDir;
pub use grip_io::can::MemBus;
use grip_msgs::GroundTruth;
use grip_plant_sim::{PlantSim, PlantSimConfig, TruthSink};

/// Keeps the last truth sample and counts them; while `failing`, each
/// sample counts as a failed publish instead.
#[derive(Default)]
pub struct LastTruth {
    pub last: Option<GroundTruth>,
    pub n: u64,
    pub failing: bool,
    pub failed: u64,
}

impl TruthSink for LastTruth {
    fn truth(&mut self, g: &GroundTruth) {
        if self.failing {
            self.failed += 1;
            return;
        }
        self.last = Some(*g);
        self.n += 1;
    }

    fn errors(&self) -> u64 {
        self.failed
    }
}

pub fn config_dir() -> ConfigDir {
    ConfigDir::new(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config"))
}

/// A simulator of the shipped `scenario` with the shipped vehicle and sensors.
pub fn sim(cfg: &PlantSimConfig) -> PlantSim {
    let dir = config_dir();
    let roads = dir.roads().unwrap();
    let scenario = dir.scenario_with(&cfg.scenario, &roads).unwrap();
    let (vehicle, sensors) = dir.vehicle().unwrap();
    PlantSim::new(cfg, scenario, roads, &vehicle, &sensors).unwrap()
}

/// A simulator of the shipped paper scenario, started at once, with
/// `vehicle` and ideal sensors.
pub fn paper_now_with(vehicle: &grip_physics::VehicleParams) -> PlantSim {
    let cfg = PlantSimConfig {
        start_on: grip_plant_sim::StartOn::Immediate,
        ..PlantSimConfig::with_scenario("paper")
    };
    let dir = config_dir();
    let roads = dir.roads().unwrap();
    let scenario = dir.scenario_with(&cfg.scenario, &roads).unwrap();
    PlantSim::new(
        &cfg,
        scenario,
        roads,
        vehicle,
        &grip_physics::SensorParams::ideal(),
    )
    .unwrap()
}

/// A simulator of the shipped `scenario` with the vehicle of `vehicle`
/// (a path relative to the shipped configuration directory).
pub fn sim_with_vehicle(
    cfg: &PlantSimConfig,
    vehicle: &str,
) -> Result<PlantSim, grip_plant_sim::cycle::PlantSimError> {
    let dir = config_dir();
    let roads = dir.roads().unwrap();
    let scenario = dir.scenario_with(&cfg.scenario, &roads).unwrap();
    let (vehicle, sensors) = grip_config::load_vehicle(dir.file(vehicle)).unwrap();
    PlantSim::new(cfg, scenario, roads, &vehicle, &sensors)
}

/// The shipped configuration plant-sim reads, copied, without the
/// real-time set-up (for tests that run the binary).
pub fn copy_config() -> tempfile::TempDir {
    let t = grip_testkit::svc::copy_config(&[
        "vehicle.toml",
        "can.toml",
        "inverter.dbc",
        "roads.toml",
        "roads",
        "scenarios/paper.toml",
        "plant-sim.toml",
    ]);
    grip_testkit::svc::strip_rt(&t.path().join("plant-sim.toml"));
    t
}
