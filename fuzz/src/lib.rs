//! Shared set-up of the fuzz targets: the repository's own configuration,
//! loaded once per process, which the targets build the services' objects
//! from (the road catalogue a scenario is resolved against, the vehicle and
//! controllers a decoded CAN frame is fed to, ...).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use grip_arte::model::Model;
use grip_io::service::ServiceConfig;
use grip_physics::Scenario;
use grip_physics::{RoadCatalogue, SensorParams, VehicleParams};
use grip_plant_sim::PlantSimConfig;
use grip_tcs::{ControllersConfig, RoadTable};
use grip_tcs_loop::TcsLoopConfig;

/// The repository's `config/` directory.
pub fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config")
}

/// The shipped configuration, loaded and validated once.
pub struct Repo {
    /// `config/roads.toml`.
    pub roads: RoadCatalogue,
    /// `config/vehicle.toml` `[vehicle]`.
    pub vehicle: VehicleParams,
    /// `config/vehicle.toml` `[sensors]`.
    pub sensors: SensorParams,
    /// `config/controllers.toml`.
    pub controllers: ControllersConfig,
    /// `config/tcs-loop.toml`.
    pub tcs_loop: TcsLoopConfig,
    /// The road table of `roads` with the `[knowledge]` of `config/arte-svc.toml`.
    pub table: RoadTable,
    /// `config/plant-sim.toml`.
    pub plant_sim: PlantSimConfig,
    /// `config/scenarios/paper.toml`.
    pub scenario: Scenario,
    /// `config/models/paper.model` (the small one).
    pub model: Model,
}

/// The shipped configuration (panics if the repository's own files do not
/// load: that is a broken checkout, not a finding).
pub fn repo() -> &'static Repo {
    static REPO: OnceLock<Repo> = OnceLock::new();
    REPO.get_or_init(|| {
        let dir = grip_config::ConfigDir::new(config_dir());
        let roads = dir.roads().expect("config/roads.toml");
        let (vehicle, sensors) = dir.vehicle().expect("config/vehicle.toml");
        let controllers = grip_config::load_controllers(dir.file("controllers.toml"))
            .expect("config/controllers.toml");
        let tcs_loop =
            TcsLoopConfig::load(&dir.file(TcsLoopConfig::FILE_NAME)).expect("config/tcs-loop.toml");
        let table = dir
            .road_table(&roads)
            .expect("config/arte-svc.toml [knowledge]");
        let plant_sim = PlantSimConfig::load(&dir.file(PlantSimConfig::FILE_NAME))
            .expect("config/plant-sim.toml");
        let scenario = dir
            .scenario_with("paper", &roads)
            .expect("config/scenarios/paper.toml");
        let model = Model::from_bytes(
            &std::fs::read(dir.file("models/paper.model")).expect("config/models/paper.model"),
        )
        .expect("config/models/paper.model");
        Repo {
            roads,
            vehicle,
            sensors,
            controllers,
            tcs_loop,
            table,
            plant_sim,
            scenario,
            model,
        }
    })
}
