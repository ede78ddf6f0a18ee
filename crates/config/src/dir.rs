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

/// The scenarios' folder of a configuration directory.
const SCENARIOS: &str = "scenarios";

/// What a scenario argument names: a scenario of the configuration
/// directory by name, or a file by path. The one rule for `--scenario` of
/// `grip drive`, `grip sim` and `grip generate`, plant-sim's `scenario`
/// ([`ConfigDir::scenario_path`]), and a drive log's `grip.run` `scenario`
/// (the drive summary, `grip replay`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScenarioArg<'a> {
    /// A name under `<dir>/scenarios`: the file `<dir>/scenarios/<name>.toml`.
    Name(&'a str),
    /// A file, as given (a relative one is relative to the current directory).
    Path(&'a Path),
}

impl<'a> ScenarioArg<'a> {
    /// What `name_or_path` names here and now, as a command line takes it:
    /// a path when it names an existing file, else by its spelling
    /// ([`ScenarioArg::by_spelling`]).
    pub fn given(name_or_path: &'a str) -> Self {
        let p = Path::new(name_or_path);
        if p.is_file() {
            Self::Path(p)
        } else {
            Self::by_spelling(name_or_path)
        }
    }

    /// What `name_or_path` names by its spelling alone: a path when it
    /// contains a path separator or ends in `.toml`, else a name. How a
    /// drive log's `grip.run` `scenario` is read, away from the drive's
    /// files (a drive given an existing file attaches it as
    /// `drive/scenario.toml`, which the readers of the log take first).
    pub fn by_spelling(name_or_path: &'a str) -> Self {
        if name_or_path.chars().any(std::path::is_separator) || name_or_path.ends_with(".toml") {
            Self::Path(Path::new(name_or_path))
        } else {
            Self::Name(name_or_path)
        }
    }

    /// The name, for a name under `<dir>/scenarios`.
    pub fn name(self) -> Option<&'a str> {
        match self {
            Self::Name(n) => Some(n),
            Self::Path(_) => None,
        }
    }

    /// The file of a name, relative to the configuration directory:
    /// `scenarios/<name>.toml` (also the name the recorder attaches it
    /// under); `None` for a path.
    pub fn in_config_dir(self) -> Option<String> {
        self.name().map(Self::file_of_name)
    }

    /// `scenarios/<name>.toml`.
    fn file_of_name(name: &str) -> String {
        format!("{SCENARIOS}/{name}.toml")
    }
}

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
        self.file(SCENARIOS)
    }

    /// Where scenario `name_or_path` lives ([`ScenarioArg::given`]): a path
    /// as given when it names an existing file or contains a path separator
    /// or ends in `.toml`; otherwise `<dir>/scenarios/<name>.toml`.
    pub fn scenario_path(&self, name_or_path: &str) -> PathBuf {
        match ScenarioArg::given(name_or_path) {
            ScenarioArg::Path(p) => p.to_owned(),
            ScenarioArg::Name(n) => self.file(&ScenarioArg::file_of_name(n)),
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
            .map_err(|e| self.hint_file_here(name_or_path, e))
    }

    /// A scenario given by name that `<dir>/scenarios` does not have, while
    /// `./<name>.toml` exists where grip runs: the error says how to give
    /// that file (`--scenario myscen` read only `config/scenarios/myscen.toml`,
    /// and said so without a hint).
    fn hint_file_here(&self, name_or_path: &str, mut e: ConfigError) -> ConfigError {
        if let ScenarioArg::Name(n) = ScenarioArg::given(name_or_path) {
            let here = format!("{n}.toml");
            if e.file == self.scenario_path(name_or_path)
                && !e.file.is_file()
                && Path::new(&here).is_file()
            {
                e.reason.push_str(&format!(
                    " (a name is looked for in {}; the file {here} where grip runs is given as a path: --scenario {here})",
                    self.scenarios_path().display()
                ));
            }
        }
        e
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
            .map_err(|e| self.hint_file_here(name_or_path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One rule: a name, or a path by its spelling (or, given on a command
    /// line, because the file exists); `scenario_path` follows it.
    #[test]
    fn a_scenario_argument_is_a_name_or_a_path() {
        assert_eq!(ScenarioArg::given("paper"), ScenarioArg::Name("paper"));
        assert_eq!(
            ScenarioArg::given("scen/suv.toml"),
            ScenarioArg::Path(Path::new("scen/suv.toml"))
        );
        assert_eq!(
            ScenarioArg::by_spelling("suv.toml"),
            ScenarioArg::Path(Path::new("suv.toml"))
        );
        assert_eq!(
            ScenarioArg::by_spelling("/abs/suv"),
            ScenarioArg::Path(Path::new("/abs/suv"))
        );
        assert_eq!(
            ScenarioArg::by_spelling("paper").in_config_dir().as_deref(),
            Some("scenarios/paper.toml")
        );
        assert_eq!(ScenarioArg::by_spelling("a/b.toml").in_config_dir(), None);
        let dir = ConfigDir::new("cfg");
        assert_eq!(
            dir.scenario_path("paper"),
            Path::new("cfg/scenarios/paper.toml")
        );
        assert_eq!(dir.scenario_path("x/y.toml"), Path::new("x/y.toml"));
        assert_eq!(dir.scenario_path("y.toml"), Path::new("y.toml"));
    }
}
