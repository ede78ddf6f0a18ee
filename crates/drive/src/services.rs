//! The five services and their command lines, in one place: `grip drive`
//! starts them with these, and the systemd units in `config/systemd/` carry
//! the same `ExecStart=` (a test compares them).
//!
//! The base command line of every service is `<bin> --config-dir <dir>`
//! (the conventions of `services/README.md`); the systemd units use
//! `/usr/lib/grip/bin/<bin> --config-dir /etc/grip`. `grip drive` appends
//! the drive's overrides (scenario, seed, controller, ARTE, output file).

use grip_msgs::topics::node;

/// Where the units expect the service binaries.
pub const UNIT_BIN_DIR: &str = "/usr/lib/grip/bin";
/// The configuration directory of the units.
pub const UNIT_CONFIG_DIR: &str = "/etc/grip";

/// One grip service.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Service {
    /// Every topic to MCAP.
    Recorder,
    /// Inverter + vehicle + road on the CAN bus (tests, demos, HIL rigs).
    PlantSim,
    /// Microphone (or synthetic) audio.
    AudioAcq,
    /// Acoustic road-type estimator.
    Arte,
    /// The 1 kHz traction-control loop.
    TcsLoop,
}

impl Service {
    /// Start order of a drive (the units' `After=` order): the recorder
    /// first so it misses nothing, the plant before the loop that needs
    /// its frames, the loop last.
    pub const START_ORDER: [Service; 5] = [
        Service::Recorder,
        Service::PlantSim,
        Service::AudioAcq,
        Service::Arte,
        Service::TcsLoop,
    ];
    /// Stop order after plant-sim ended: the recorder last.
    pub const STOP_ORDER: [Service; 5] = [
        Service::PlantSim,
        Service::TcsLoop,
        Service::Arte,
        Service::AudioAcq,
        Service::Recorder,
    ];

    /// Service (and iceoryx2 node) name.
    pub fn name(self) -> &'static str {
        match self {
            Service::Recorder => node::RECORDER,
            Service::PlantSim => node::PLANT_SIM,
            Service::AudioAcq => node::AUDIO_ACQ,
            Service::Arte => node::ARTE,
            Service::TcsLoop => node::TCS_LOOP,
        }
    }

    /// Executable file name (the `[[bin]]` of the service's package).
    pub fn binary(self) -> &'static str {
        self.name()
    }

    /// systemd unit file name.
    pub fn unit(self) -> String {
        format!("grip-{}.service", self.name())
    }

    /// The base arguments every start of the service uses.
    pub fn base_args(self, config_dir: &str) -> Vec<String> {
        vec!["--config-dir".to_owned(), config_dir.to_owned()]
    }

    /// The unit's `ExecStart=` value.
    pub fn exec_start(self) -> String {
        let mut parts = vec![format!("{UNIT_BIN_DIR}/{}", self.binary())];
        parts.extend(self.base_args(UNIT_CONFIG_DIR));
        parts.join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn unit_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/systemd")
    }

    /// The shipped units start the services with exactly the command line
    /// `grip drive` uses (with the units' directories).
    #[test]
    fn unit_exec_start_equals_drive_command_line() {
        for s in Service::START_ORDER {
            let path = unit_dir().join(s.unit());
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let lines: Vec<&str> = text
                .lines()
                .filter_map(|l| l.trim().strip_prefix("ExecStart="))
                .collect();
            assert_eq!(
                lines.len(),
                1,
                "{}: one ExecStart= expected",
                path.display()
            );
            assert_eq!(lines[0].trim(), s.exec_start(), "{}", path.display());
        }
    }

    #[test]
    fn binaries_are_the_service_packages_bins() {
        for s in Service::START_ORDER {
            let dir = match s {
                Service::Recorder => "recorder",
                Service::PlantSim => "plant-sim",
                Service::AudioAcq => "audio-acq",
                Service::Arte => "arte",
                Service::TcsLoop => "tcs-loop",
            };
            let manifest = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../services")
                .join(dir)
                .join("Cargo.toml");
            let text = std::fs::read_to_string(&manifest).unwrap();
            let v: toml::Value = toml::from_str(&text).unwrap();
            let bins = v["bin"].as_array().unwrap();
            assert!(
                bins.iter().any(|b| b["name"].as_str() == Some(s.binary())),
                "{}: no [[bin]] named {}",
                manifest.display(),
                s.binary()
            );
        }
    }
}
