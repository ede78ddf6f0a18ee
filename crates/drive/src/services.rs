//! The five services and their command lines, in one place: `grip drive`
//! starts them with these, and the systemd units in `config/systemd/` carry
//! the same `ExecStart=` (a test compares them).
//!
//! The base command line of every service is `<bin> --config-dir <dir>`
//! (the conventions of `services/README.md`); the systemd units use
//! `/usr/lib/grip/bin/<bin> --config-dir /etc/grip`. `grip drive` appends
//! the drive's overrides (scenario, seed, controller, ARTE, output file).

use grip_msgs::topics::node;

/// Where and how nicely the kernel runs a service's process, as its
/// systemd unit says (`CPUAffinity=`, `Nice=`, `IOSchedulingClass=` +
/// `IOSchedulingPriority=`): `grip drive`, the bench and the HIL
/// supervisor apply it at the start, so a drive runs as the car does (a
/// test compares it with the units). The services' own `[rt]` settings
/// (SCHED_FIFO, their threads' CPUs) come on top, from their config files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Placement {
    /// CPUs the process may run on (`CPUAffinity=`); empty: any.
    pub cpus: &'static [usize],
    /// Nice value (`Nice=`), 0 = the default.
    pub nice: i32,
    /// Best-effort I/O priority 0-7 (`IOSchedulingClass=best-effort`,
    /// `IOSchedulingPriority=`); `None`: the kernel's default.
    pub io_best_effort: Option<u8>,
}

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

impl Placement {
    /// Whether it asks for nothing (the kernel's defaults).
    pub fn is_default(&self) -> bool {
        *self == Placement::default()
    }

    /// The CPUs of [`Placement::cpus`] this process may run on now (a
    /// machine with fewer CPUs, or a caller itself pinned elsewhere, has
    /// fewer); empty when it asks for none.
    pub fn usable_cpus(&self) -> Vec<usize> {
        if self.cpus.is_empty() {
            return Vec::new();
        }
        // SAFETY: an all-zero cpu_set_t is a valid empty set.
        let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
        // SAFETY: sched_getaffinity(2) fills `set` for this process, told
        // its size.
        let rc =
            unsafe { libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) };
        let max = 8 * std::mem::size_of::<libc::cpu_set_t>();
        let allowed = |c: usize| {
            if c >= max {
                return false;
            }
            // SAFETY: `c < max` keeps the index inside the set.
            rc != 0 || unsafe { libc::CPU_ISSET(c, &set) }
        };
        self.cpus.iter().copied().filter(|&c| allowed(c)).collect()
    }
}

impl std::fmt::Display for Placement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        if !self.cpus.is_empty() {
            parts.push(format!("CPUs {:?}", self.cpus));
        }
        if self.nice != 0 {
            parts.push(format!("nice {}", self.nice));
        }
        if let Some(l) = self.io_best_effort {
            parts.push(format!("I/O best-effort {l}"));
        }
        if parts.is_empty() {
            parts.push("the kernel's defaults".into());
        }
        f.write_str(&parts.join(", "))
    }
}

impl Service {
    /// Start order of a drive, one by one (an order the units' `After=`
    /// allows; under systemd audio-acq and arte start beside tcs-loop, not
    /// before it): the recorder first so it misses nothing, the plant
    /// before the loop that needs its frames, the loop last.
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

    /// The unit's placement (see [`Placement`]): the recorder, which
    /// writes the log, runs on CPU 0 at nice 10 and the lowest best-effort
    /// I/O priority, away from tcs-loop's CPU 1 (on a kernel without
    /// PREEMPT_RT a process inside a long `write` holds its CPU until the
    /// call returns). tcs-loop's unit pins nothing: its loop thread pins
    /// itself to CPU 1 (`config/tcs-loop.toml` `[rt] cpus`) and its
    /// SCHED_OTHER watchdog helper may run on either CPU.
    pub fn placement(self) -> Placement {
        match self {
            Service::Recorder => Placement {
                cpus: &[0],
                nice: 10,
                io_best_effort: Some(7),
            },
            Service::TcsLoop | Service::PlantSim | Service::AudioAcq | Service::Arte => {
                Placement::default()
            }
        }
    }

    /// What starts the service from `bin_dir` with `args`, placed as its
    /// unit places it (the drive, the bench and the HIL tests use this).
    pub fn spec(self, bin_dir: &std::path::Path, args: &[String]) -> crate::ProcSpec {
        crate::ProcSpec::new(self.name(), &bin_dir.join(self.binary()), args)
            .placement(self.placement())
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

    /// Values of `key=` in a unit (comments and other keys skipped).
    fn unit_values(text: &str, key: &str) -> Vec<String> {
        text.lines()
            .filter_map(|l| l.trim().strip_prefix(key)?.strip_prefix('='))
            .map(|v| v.trim().to_owned())
            .collect()
    }

    /// Each service's unit file, read.
    fn units() -> impl Iterator<Item = (Service, String)> {
        Service::START_ORDER.into_iter().map(|s| {
            let path = unit_dir().join(s.unit());
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            (s, text)
        })
    }

    /// The shipped units start the services with exactly the command line
    /// `grip drive` uses (with the units' directories).
    #[test]
    fn unit_exec_start_equals_drive_command_line() {
        for (s, text) in units() {
            assert_eq!(
                unit_values(&text, "ExecStart"),
                [s.exec_start()],
                "{}",
                s.unit()
            );
        }
    }

    /// Every unit leaves a refused configuration failed (the services'
    /// exit code for it, `EXIT_CONFIG`) and restarts on anything else.
    #[test]
    fn units_do_not_restart_on_a_refused_configuration() {
        for (s, text) in units() {
            assert_eq!(
                unit_values(&text, "RestartPreventExitStatus"),
                [grip_io::service::EXIT_CONFIG.to_string()],
                "{}",
                s.unit()
            );
            assert_eq!(
                unit_values(&text, "Restart"),
                ["on-failure"],
                "{}",
                s.unit()
            );
        }
    }

    /// `grip drive` places every service as its unit does (CPUs, nice,
    /// I/O priority), and a unit sets nothing of this kind that
    /// [`Service::placement`] leaves out.
    #[test]
    fn placement_equals_the_units() {
        for (s, text) in units() {
            let p = s.placement();
            let cpus: Vec<String> = p.cpus.iter().map(|c| c.to_string()).collect();
            let want_cpus: Vec<String> = if cpus.is_empty() {
                vec![]
            } else {
                vec![cpus.join(" ")]
            };
            assert_eq!(unit_values(&text, "CPUAffinity"), want_cpus, "{}", s.unit());
            let want_nice: Vec<String> = if p.nice == 0 {
                vec![]
            } else {
                vec![p.nice.to_string()]
            };
            assert_eq!(unit_values(&text, "Nice"), want_nice, "{}", s.unit());
            let (class, prio): (Vec<String>, Vec<String>) = match p.io_best_effort {
                Some(l) => (vec!["best-effort".into()], vec![l.to_string()]),
                None => (vec![], vec![]),
            };
            assert_eq!(
                unit_values(&text, "IOSchedulingClass"),
                class,
                "{}",
                s.unit()
            );
            assert_eq!(
                unit_values(&text, "IOSchedulingPriority"),
                prio,
                "{}",
                s.unit()
            );
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
