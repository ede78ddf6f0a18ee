//! `config/plant-sim.toml`: scenario, seed, rate, inverter command timeout,
//! start trigger, end behaviour and the real-time set-up. Vehicle and sensor
//! models come from `vehicle.toml`, roads from `roads.toml`, the bus from
//! `can.toml`.

use std::path::Path;

use grip_config::ConfigError;
use grip_io::rt::RtConfig;
use grip_io::service::{ServiceConfig, validate_rt};

/// What starts the scenario clock (the vehicle is held at its initial state
/// before).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum StartOn {
    /// SIGUSR1 received **and** at least `start_commands` consecutive valid
    /// `TorqueCommand` frames with `Enable` = 1 (i.e. tcs-loop is out of its
    /// safe state and in control). The default; `grip drive` sends SIGUSR1.
    Signal,
    /// `start_commands` consecutive valid enabled commands alone.
    Commands,
    /// At the first cycle.
    Immediate,
}

/// The service's own configuration file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantSimConfig {
    /// Scenario name (`<config_dir>/scenarios/<name>.toml`) or path (`--scenario`).
    pub scenario: String,
    /// Sensor-noise seed (`--seed`).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Plant/frame rate, Hz: the 1 ms messages go out once per cycle, the
    /// 10 ms ones every `round(cycle_ms · rate_hz / 1000)` cycles.
    #[serde(default = "default_rate")]
    pub rate_hz: f64,
    /// The inverter applies zero torque when no valid `TorqueCommand` came
    /// for longer than this, ms (DBC: 20).
    #[serde(default = "default_cmd_timeout")]
    pub cmd_timeout_ms: f64,
    /// Start trigger (`--start-on`).
    #[serde(default = "default_start_on")]
    pub start_on: StartOn,
    /// Consecutive valid enabled commands needed to start (`signal`, `commands`).
    #[serde(default = "default_start_commands")]
    pub start_commands: u32,
    /// Exit 0 after the scenario's end plus `end_hold_ms` (`--exit-at-end`).
    #[serde(default)]
    pub exit_at_end: bool,
    /// Zero torque and zero demand held after the scenario's end before
    /// exiting, ms.
    #[serde(default = "default_end_hold")]
    pub end_hold_ms: f64,
    /// Upper bound on the plant's internal integration step, s (default 1e-4).
    #[serde(default = "default_substep")]
    pub max_substep_s: f64,
    /// Whether plant-sim may open a CAN interface backed by a device (a real
    /// CAN controller). Off by default: plant-sim plays the inverter, the
    /// wheel-speed sensors and the driver, and on a car's bus its frames
    /// would reach the real ECUs (a bench bus with no inverter on it is
    /// the case for `true`).
    #[serde(default)]
    pub allow_physical_bus: bool,
    /// `[rt]`
    #[serde(default)]
    pub rt: RtConfig,
}

fn default_seed() -> u64 {
    1
}
fn default_rate() -> f64 {
    1000.0
}
fn default_cmd_timeout() -> f64 {
    20.0
}
fn default_start_on() -> StartOn {
    StartOn::Signal
}
fn default_start_commands() -> u32 {
    20
}
fn default_end_hold() -> f64 {
    100.0
}
fn default_substep() -> f64 {
    1e-4
}

impl PlantSimConfig {
    /// A configuration for `scenario` with every default (tests).
    pub fn with_scenario(scenario: &str) -> Self {
        Self {
            scenario: scenario.into(),
            seed: default_seed(),
            rate_hz: default_rate(),
            cmd_timeout_ms: default_cmd_timeout(),
            start_on: default_start_on(),
            start_commands: default_start_commands(),
            exit_at_end: false,
            end_hold_ms: default_end_hold(),
            max_substep_s: default_substep(),
            allow_physical_bus: false,
            rt: RtConfig::default(),
        }
    }
}

impl ServiceConfig for PlantSimConfig {
    const FILE_NAME: &'static str = "plant-sim.toml";

    /// Range checks (errors name `file` and the field).
    fn validate(&self, file: &Path) -> Result<(), ConfigError> {
        self.check()
            .map_err(|(field, reason)| ConfigError::new(file, field, reason))?;
        validate_rt(&self.rt, file)
    }
}

impl PlantSimConfig {
    /// The checks of the service's own fields: (field, reason).
    fn check(&self) -> Result<(), (String, String)> {
        let num = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err((
                    name.to_owned(),
                    format!("must be in [{lo}, {hi}] (got {v})"),
                ))
            }
        };
        if self.scenario.trim().is_empty() {
            return Err(("scenario".into(), "must name a scenario".into()));
        }
        num("rate_hz", self.rate_hz, 10.0, 100_000.0)?;
        num("cmd_timeout_ms", self.cmd_timeout_ms, 1.0, 10_000.0)?;
        num("end_hold_ms", self.end_hold_ms, 0.0, 60_000.0)?;
        num("max_substep_s", self.max_substep_s, 1e-7, 1e-2)?;
        if self.start_commands > 100_000 {
            return Err((
                "start_commands".into(),
                format!("must be <= 100000 (got {})", self.start_commands),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_file_loads() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/plant-sim.toml");
        let c = PlantSimConfig::load(&p).unwrap();
        assert_eq!(c.scenario, "paper");
        assert_eq!(c.start_on, StartOn::Signal);
        assert_eq!(c.cmd_timeout_ms, 20.0);
    }

    #[test]
    fn errors_name_field() {
        let f = Path::new("plant-sim.toml");
        let e = PlantSimConfig::parse(f, "scenario = \"paper\"\nrate_hz = -1.0\n").unwrap_err();
        assert_eq!(e.field, "rate_hz", "{e}");
        let e =
            PlantSimConfig::parse(f, "scenario = \"paper\"\nstart_on = \"never\"\n").unwrap_err();
        assert_eq!(e.field, "start_on", "{e}");
        let e =
            PlantSimConfig::parse(f, "scenario = \"paper\"\ncmd_timeout_ms = nan\n").unwrap_err();
        assert_eq!(e.field, "cmd_timeout_ms", "{e}");
        let e = PlantSimConfig::parse(f, "scenaro = \"paper\"\n").unwrap_err();
        assert!(e.reason.contains("unknown field"), "{e}");
    }
}
