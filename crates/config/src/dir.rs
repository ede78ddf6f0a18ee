//! [`ConfigDir`]: the standard layout of grip's configuration directory.
//!
//! ```text
//! <dir>/vehicle.toml           vehicle + sensors
//! <dir>/roads.toml             road catalogue (CSV tables under <dir>/roads/)
//! <dir>/scenarios/<name>.toml  scenarios
//! ```

use std::path::{Path, PathBuf};

use grip_physics::{RoadCatalogue, Scenario, SensorParams, VehicleParams};

use crate::error::ConfigError;

/// A configuration directory (default `config/`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigDir {
    root: PathBuf,
}

impl ConfigDir {
    /// The configuration directory at `path`.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self { root: path.into() }
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.root
    }

    /// `<dir>/<name>` for any other file in the directory (e.g. `controllers.toml`).
    pub fn file(&self, name: &str) -> PathBuf {
        self.root.join(name)
    }

    /// `<dir>/vehicle.toml`.
    pub fn vehicle_path(&self) -> PathBuf {
        self.file("vehicle.toml")
    }

    /// `<dir>/roads.toml`.
    pub fn roads_path(&self) -> PathBuf {
        self.file("roads.toml")
    }

    /// `<dir>/scenarios`.
    pub fn scenarios_path(&self) -> PathBuf {
        self.file("scenarios")
    }

    /// Where scenario `name_or_path` lives: a path as given when it names an
    /// existing file or contains a path separator or ends in `.toml`;
    /// otherwise `<dir>/scenarios/<name>.toml`.
    pub fn scenario_path(&self, name_or_path: &str) -> PathBuf {
        let p = Path::new(name_or_path);
        if p.is_file()
            || name_or_path.contains(std::path::MAIN_SEPARATOR)
            || name_or_path.ends_with(".toml")
        {
            p.to_owned()
        } else {
            self.scenarios_path().join(format!("{name_or_path}.toml"))
        }
    }

    /// Names of the scenarios in `<dir>/scenarios` (sorted; empty when the
    /// directory is missing).
    pub fn scenario_names(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.scenarios_path())
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| {
                let p = e.path();
                (p.extension()? == "toml").then(|| p.file_stem()?.to_str().map(str::to_owned))?
            })
            .collect();
        names.sort();
        names
    }

    /// Load `vehicle.toml`.
    pub fn vehicle(&self) -> Result<(VehicleParams, SensorParams), ConfigError> {
        crate::load_vehicle(self.vehicle_path())
    }

    /// Load `roads.toml`.
    pub fn roads(&self) -> Result<RoadCatalogue, ConfigError> {
        crate::load_roads(self.roads_path())
    }

    /// The file holding the road-knowledge overrides (`[knowledge]` of the
    /// arte service's configuration).
    pub fn knowledge_path(&self) -> PathBuf {
        self.file(crate::knowledge::KNOWLEDGE_FILE)
    }

    /// The road-knowledge rule of this directory: `roads` with the
    /// `[knowledge]` overrides of [`ConfigDir::knowledge_path`].
    pub fn road_table(&self, roads: &RoadCatalogue) -> Result<grip_tcs::RoadTable, ConfigError> {
        crate::load_road_table(self.knowledge_path(), roads)
    }

    /// The `[knowledge]` overrides of this directory, validated against `roads`.
    pub fn knowledge(
        &self,
        roads: &RoadCatalogue,
    ) -> Result<grip_tcs::KnowledgeConfig, ConfigError> {
        crate::load_knowledge(self.knowledge_path(), roads)
    }

    /// Load scenario `name_or_path` (see [`ConfigDir::scenario_path`]),
    /// resolving road names against `roads.toml` of this directory.
    pub fn scenario(&self, name_or_path: &str) -> Result<Scenario, ConfigError> {
        let roads = self.roads()?;
        self.scenario_with(name_or_path, &roads)
    }

    /// Load scenario `name_or_path` against an already loaded catalogue.
    pub fn scenario_with(
        &self,
        name_or_path: &str,
        roads: &RoadCatalogue,
    ) -> Result<Scenario, ConfigError> {
        crate::load_scenario(self.scenario_path(name_or_path), roads)
    }

    /// Load scenario `name_or_path` against an already loaded catalogue and
    /// check it against where it is to run (the vehicle's motor limit, the
    /// loop's cycle count: [`crate::check_scenario`]); the errors name the
    /// scenario's file.
    pub fn scenario_for(
        &self,
        name_or_path: &str,
        roads: &RoadCatalogue,
        on: crate::RunsOn,
    ) -> Result<Scenario, ConfigError> {
        crate::load_scenario_for(self.scenario_path(name_or_path), roads, on)
    }
}
