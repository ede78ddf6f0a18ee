//! Shared by the integration tests: the shipped configuration (`config/`).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use grip_config::{ConfigDir, parse_toml, read_file};
use grip_sim::{ArteConfig, ConfusionArte, SimSetup};
use grip_tcs::ControllersConfig;

/// The repository's `config/` directory.
pub fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// The shipped controllers and ARTE configuration.
pub fn controllers_and_arte() -> (ControllersConfig, ArteConfig) {
    let dir = ConfigDir::new(config_dir());
    let cpath = dir.file("controllers.toml");
    let controllers: ControllersConfig = parse_toml(&cpath, &read_file(&cpath).unwrap()).unwrap();
    controllers.validate().unwrap();
    let apath = dir.file("sim-confusion.toml");
    let arte: ArteConfig = parse_toml(&apath, &read_file(&apath).unwrap()).unwrap();
    (controllers, arte)
}

/// The reference scenario (`config/scenarios/paper.toml`) with the shipped
/// vehicle, sensors, roads, controllers and ARTE configuration.
pub fn reference() -> (SimSetup, ConfusionArte) {
    let dir = ConfigDir::new(config_dir());
    let (vehicle, sensors) = dir.vehicle().unwrap();
    let roads = dir.roads().unwrap();
    let scenario = dir.scenario_with("paper", &roads).unwrap();
    let (controllers, arte) = controllers_and_arte();
    let knowledge = dir.knowledge(&roads).unwrap();
    arte.validate(&roads).unwrap();
    let est = ConfusionArte::new(&arte.confusion, &roads).unwrap();
    let setup = SimSetup::new(vehicle, sensors, roads, scenario, controllers, &knowledge).unwrap();
    (setup, est)
}
