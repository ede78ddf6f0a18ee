//! Every configuration loader, on the same text: the input is handed to
//! each loader as the contents of the file it reads (so a mutation of one
//! shipped file also tries every other loader), and whatever a loader
//! accepts is given to the code that consumes it in the services and `grip
//! sim` (controllers and road knowledge built from a vehicle or controllers
//! file, the plant from a scenario, the confusion estimator from
//! `sim-confusion.toml`, the streaming estimator from `arte-svc.toml`, ...).
//! A validated configuration must build without a panic; a refused one must
//! say which file.
#![no_main]

use std::path::PathBuf;

use grip_arte::stream::StreamEstimator;
use grip_arte_svc::ArteServiceConfig;
use grip_audio_acq::AcqConfig;
use grip_config::controllers::parse_controllers;
use grip_config::{
    ConfigError, parse_knowledge, parse_roads, parse_scenario, parse_toml, parse_vehicle,
};
use grip_io::service::{ServiceConfig, parse_can};
use grip_physics::{RoadCatalogue, SensorParams, VehicleParams};
use grip_plant_sim::{PlantSim, PlantSimConfig};
use grip_recorder::RecorderConfig;
use grip_sim::{ArteConfig, ConfusionArte};
use grip_tcs::{ControllerKind, ControllersConfig, RoadTable};
use grip_tcs_loop::{TcsLoop, TcsLoopConfig};
use libfuzzer_sys::fuzz_target;

/// `name` in the repository's `config/` (so that `roads.toml`'s tables
/// resolve as they do for the shipped file).
fn at(name: &str) -> PathBuf {
    grip_fuzz::config_dir().join(name)
}

fn named<T>(r: Result<T, ConfigError>, file: &str) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains(file), "error does not name {file}: {msg}");
            None
        }
    }
}

/// What tcs-loop builds at start-up (each controller, with ARTE).
fn build_loops(c: &ControllersConfig, v: &VehicleParams, roads: &RoadCatalogue, t: &RoadTable) {
    let repo = grip_fuzz::repo();
    for kind in [
        ControllerKind::Mfc,
        ControllerKind::Src,
        ControllerKind::Mtte,
    ] {
        if let Ok(lp) = TcsLoop::new(kind, true, c, v, &repo.tcs_loop.safety) {
            let _ = lp.with_road_aware(roads, t.clone(), c, v);
        }
    }
}

/// What plant-sim builds at start-up.
fn build_plant(
    cfg: &PlantSimConfig,
    scenario: grip_physics::Scenario,
    v: &VehicleParams,
    s: &SensorParams,
) {
    let repo = grip_fuzz::repo();
    let _ = PlantSim::new(cfg, scenario, repo.roads.clone(), v, s);
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let repo = grip_fuzz::repo();

    if let Some((v, s)) = named(parse_vehicle(&at("vehicle.toml"), text), "vehicle.toml") {
        build_loops(&repo.controllers, &v, &repo.roads, &repo.table);
        build_plant(&repo.plant_sim, repo.scenario.clone(), &v, &s);
    }
    if let Some(roads) = named(parse_roads(&at("roads.toml"), text), "roads.toml")
        && let Ok(t) = RoadTable::new(&roads, &grip_tcs::KnowledgeConfig::default())
    {
        build_loops(&repo.controllers, &repo.vehicle, &roads, &t);
    }
    if let Some(sc) = named(
        parse_scenario(&at("scenario.toml"), text, &repo.roads),
        "scenario.toml",
    ) {
        build_plant(&repo.plant_sim, sc, &repo.vehicle, &repo.sensors);
    }
    if let Some(c) = named(
        parse_controllers(&at("controllers.toml"), text),
        "controllers.toml",
    ) {
        build_loops(&c, &repo.vehicle, &repo.roads, &repo.table);
    }
    if let Some(k) = named(
        parse_knowledge(&at("arte-svc.toml"), text, &repo.roads),
        "arte-svc.toml",
    ) {
        let t = RoadTable::new(&repo.roads, &k).expect("validated [knowledge] builds its table");
        build_loops(&repo.controllers, &repo.vehicle, &repo.roads, &t);
    }
    if let Some(a) = named(
        parse_toml::<ArteConfig>(&at("sim-confusion.toml"), text),
        "sim-confusion.toml",
    ) {
        let _ = ConfusionArte::new(&a.confusion, &repo.roads);
    }
    let _ = named(parse_can(&at("can.toml"), text), "can.toml");
    if let Some(c) = named(
        TcsLoopConfig::parse(&at("tcs-loop.toml"), text),
        "tcs-loop.toml",
    ) && let Ok(kind) = c.controller_kind()
    {
        let _ = TcsLoop::new(kind, c.arte, &repo.controllers, &repo.vehicle, &c.safety);
    }
    let _ = named(
        AcqConfig::parse(&at("audio-acq.toml"), text),
        "audio-acq.toml",
    );
    if let Some(c) = named(
        ArteServiceConfig::parse(&at("arte-svc.toml"), text),
        "arte-svc.toml",
    ) {
        let m = &repo.model;
        let _ = StreamEstimator::new(m.predictor(), m.feature_config(), &c.stream);
    }
    if let Some(c) = named(
        RecorderConfig::parse(&at("recorder.toml"), text),
        "recorder.toml",
    ) {
        let _ = (c.writer_options(), c.poll_interval());
    }
    if let Some(c) = named(
        PlantSimConfig::parse(&at("plant-sim.toml"), text),
        "plant-sim.toml",
    ) {
        build_plant(&c, repo.scenario.clone(), &repo.vehicle, &repo.sensors);
    }
});
