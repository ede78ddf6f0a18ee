//! `config/tcs-loop.toml`: which controller, ARTE on/off, the safe-state
//! timing and the real-time set-up. The controller *parameters* and the loop
//! rate live in `controllers.toml` (`[loop] rate_hz`, one place for the
//! offline simulator and the live loop); the CAN bus in `can.toml`.

use std::path::Path;
use std::str::FromStr;

use grip_config::ConfigError;
use grip_io::rt::RtConfig;
use grip_io::service::{ServiceConfig, validate_rt};
use grip_tcs::ControllerKind;

/// The service's own configuration file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TcsLoopConfig {
    /// `"mfc"`, `"src"` or `"mtte"` (overridden by `--controller`).
    pub controller: String,
    /// Use ARTE's road estimates (overridden by `--arte on|off`). Off: the
    /// controller always gets `None` and runs its no-ARTE behaviour.
    pub arte: bool,
    /// `[safety]`
    #[serde(default)]
    pub safety: SafetyConfig,
    /// `[rt]`: SCHED_FIFO priority, mlockall, CPUs, cpu_dma_latency.
    #[serde(default)]
    pub rt: RtConfig,
}

/// When the loop enters and leaves its safe state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyConfig {
    /// No valid `WheelSpeeds` (or `MotorStatus`) frame for longer than this
    /// → safe state, ms. Default 10 (the DBC's `GripTimeoutMs`).
    pub sensor_timeout_ms: f64,
    /// No valid `DriverDemand` frame for longer than this → safe state, ms.
    /// Default 50 (the DBC's timeout; the frame comes every 10 ms).
    pub demand_timeout_ms: f64,
    /// The safe state is left only after all inputs have been valid without
    /// interruption for this long, ms. Default 50.
    pub recover_ms: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            sensor_timeout_ms: 10.0,
            demand_timeout_ms: 50.0,
            recover_ms: 50.0,
        }
    }
}

impl SafetyConfig {
    /// Range checks (field names relative to `[safety]`).
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (name, v, lo, hi) in [
            ("sensor_timeout_ms", self.sensor_timeout_ms, 1.0, 10_000.0),
            ("demand_timeout_ms", self.demand_timeout_ms, 1.0, 10_000.0),
            ("recover_ms", self.recover_ms, 0.0, 60_000.0),
        ] {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err((
                    name.to_owned(),
                    format!("must be a number in [{lo}, {hi}] ms (got {v})"),
                ));
            }
        }
        Ok(())
    }

    /// Sensor timeout, ns.
    pub fn sensor_timeout_ns(&self) -> u64 {
        ms_to_ns(self.sensor_timeout_ms)
    }
    /// Demand timeout, ns.
    pub fn demand_timeout_ns(&self) -> u64 {
        ms_to_ns(self.demand_timeout_ms)
    }
    /// Recovery time, ns.
    pub fn recover_ns(&self) -> u64 {
        ms_to_ns(self.recover_ms)
    }
}

fn ms_to_ns(ms: f64) -> u64 {
    (ms * 1e6).round() as u64
}

impl TcsLoopConfig {
    /// The controller kind (errors name the field).
    pub fn controller_kind(&self) -> Result<ControllerKind, (String, String)> {
        ControllerKind::from_str(&self.controller)
            .map_err(|e| ("controller".to_owned(), e.to_string()))
    }
}

impl ServiceConfig for TcsLoopConfig {
    const FILE_NAME: &'static str = "tcs-loop.toml";

    /// Range checks: the controller, `[safety]`, `[rt]`.
    fn validate(&self, file: &Path) -> Result<(), ConfigError> {
        let named = |(field, reason): (String, String)| ConfigError::new(file, field, reason);
        self.controller_kind().map_err(named)?;
        self.safety
            .validate()
            .map_err(|(f, r)| named((format!("safety.{f}"), r)))?;
        validate_rt(&self.rt, file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/tcs-loop.toml")
    }

    #[test]
    fn shipped_file_loads() {
        let c = TcsLoopConfig::load(&shipped()).unwrap();
        assert_eq!(c.safety, SafetyConfig::default());
        assert!(c.controller_kind().is_ok());
    }

    #[test]
    fn errors_name_field() {
        let f = Path::new("tcs-loop.toml");
        let e = TcsLoopConfig::parse(f, "controller = \"pid\"\narte = true\n").unwrap_err();
        assert_eq!(e.field, "controller");
        assert!(e.reason.contains("pid"), "{e}");
        let e = TcsLoopConfig::parse(
            f,
            "controller = \"mtte\"\narte = true\n[safety]\nsensor_timeout_ms = nan\n",
        )
        .unwrap_err();
        assert_eq!(e.field, "safety.sensor_timeout_ms", "{e}");
        let e = TcsLoopConfig::parse(
            f,
            "controller = \"mtte\"\narte = true\n[rt]\nfifo_priority = 0\n",
        )
        .unwrap_err();
        assert_eq!(e.field, "rt.fifo_priority", "{e}");
        let e =
            TcsLoopConfig::parse(f, "controller = \"mtte\"\narte = true\nrate = 1\n").unwrap_err();
        assert!(e.reason.contains("unknown field"), "{e}");
    }
}
