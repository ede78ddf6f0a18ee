//! A drive: what it is asked to do ([`DrivePlan`]: each service's command
//! line, the unit's plus the drive's overrides) and running it
//! ([`run_services`]: start in order with readiness, SIGUSR1 to plant-sim,
//! watch for deaths until plant-sim ends the scenario, stop in order, the
//! recorder last).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use grip_config::ConfigDir;
use grip_physics::VehicleParams;

use crate::log::DriveLog;
use crate::services::Service;
use crate::supervisor::{Output, SuperviseError, Supervisor, describe_status};

/// The service binaries are not where they are looked for.
#[derive(Debug, thiserror::Error)]
#[error(
    "service binaries missing in {dir}: {missing}.\n  Build them with `{build}` (they land next to `grip` in target/<profile>/), or point GRIP_BIN_DIR at the directory that holds them."
)]
pub struct MissingBinaries {
    /// The directory searched.
    pub dir: String,
    /// The missing binaries, comma-separated.
    pub missing: String,
    /// The build command that makes them.
    pub build: &'static str,
}

/// Checks that every service binary exists in `dir`.
pub fn check_binaries(dir: &Path) -> Result<(), MissingBinaries> {
    let missing: Vec<&str> = Service::START_ORDER
        .iter()
        .map(|s| s.binary())
        .filter(|b| !dir.join(b).is_file())
        .collect();
    if !missing.is_empty() {
        let profile_hint = if dir.ends_with("debug") {
            "cargo build --workspace"
        } else {
            "cargo build --release --workspace"
        };
        return Err(MissingBinaries {
            dir: dir.display().to_string(),
            missing: missing.join(", "),
            build: profile_hint,
        });
    }
    Ok(())
}

/// How [`vehicle_for`] names a vehicle it took from the log's attachment
/// `name` (the summary finds the attachment, and its SHA-256, by it).
pub fn attached_label(name: &str) -> String {
    format!("{name} (attached to the log)")
}

/// How [`vehicle_for`] names the drive's `--vehicle` file it took from the
/// log ([`VEHICLE_ATTACHMENT`]): by the path the drive was given
/// (`grip.run` `vehicle`), attached; without that key, as
/// [`attached_label`] names any attachment.
pub fn drive_vehicle_label(log: &DriveLog) -> String {
    match log.run.get("vehicle") {
        Some(p) => {
            format!("{p} (grip drive --vehicle; attached to the log as {VEHICLE_ATTACHMENT})")
        }
        None => attached_label(VEHICLE_ATTACHMENT),
    }
}

/// How [`vehicle_for`] names the vehicle a closed-loop replay ran
/// ([`REPLAY_VEHICLE_ATTACHMENT`]): as its `grip.replay` record names it
/// (`vehicle`: the `--vehicle` file as given, or the source's file; the
/// `--set`s that changed it, `vehicle_set`).
pub fn replay_vehicle_label(log: &DriveLog) -> String {
    let record = log.metadata.get("grip.replay");
    let get = |k: &str| {
        record
            .and_then(|m| m.get(k))
            .filter(|v| !v.is_empty())
            .map(String::as_str)
    };
    format!(
        "{} (the vehicle the replay ran{}, not its source drive's; attached to the log as {REPLAY_VEHICLE_ATTACHMENT})",
        get("vehicle").unwrap_or(REPLAY_VEHICLE_ATTACHMENT),
        get("vehicle_set").map_or_else(String::new, |s| format!(" with {s}"))
    )
}

/// The vehicle a drive ran with, for the metrics (kinetic energy: M/n and
/// J_w) and the preview report (N · r): for a closed-loop replay that ran
/// another vehicle than its source (`grip replay --closed-loop --vehicle`,
/// or a `--set` on the vehicle: plant and loop both ran it), the file it
/// attached ([`REPLAY_VEHICLE_ATTACHMENT`]; an open-loop replay's ground
/// truth is its source's car's, so the source's vehicle stays, and the
/// summary names the one the replay's loop ran); else the drive's
/// `--vehicle` file as the
/// recorder attached it ([`VEHICLE_ATTACHMENT`]); else, with `grip.run`
/// `vehicle=PATH`, the attached copy of that profile (the recorder attaches
/// `vehicles/*.toml`; matched by the end of PATH), else PATH read from disk;
/// else the attached `vehicle.toml`, else the configuration directory's,
/// else the defaults. Returns the parameters, where they came from, and
/// the warnings to print (files that could not be used).
pub fn vehicle_for(log: &DriveLog, config_dir: &Path) -> (VehicleParams, String, Vec<String>) {
    let mut warnings = Vec::new();
    if let Some((v, from)) = vehicle_of_log(log, &mut warnings) {
        return (v, from, warnings);
    }
    let dir = ConfigDir::new(config_dir);
    match dir.vehicle() {
        Ok((v, _)) => (
            v,
            format!("{} (configuration directory)", dir.vehicle_path().display()),
            warnings,
        ),
        Err(e) => {
            warnings.push(format!(
                "warning: {e}; using the default vehicle for the energy metrics"
            ));
            (VehicleParams::default(), "defaults".into(), warnings)
        }
    }
}

/// The steps of [`vehicle_for`] that the log itself answers (its attached
/// vehicle files, or `grip.run`'s `vehicle=PATH` read from disk); `None`
/// when none gives a vehicle. Files that could not be used are added to
/// `warnings`. [`DriveLog::protocol`] takes the wheel radii from it, so a
/// bus whose wheel speeds are in km/h is read with the vehicle the summary
/// uses.
pub fn vehicle_of_log(
    log: &DriveLog,
    warnings: &mut Vec<String>,
) -> Option<(VehicleParams, String)> {
    let attached = |name: &str, warnings: &mut Vec<String>| {
        let text = log.attachment_text(name)?;
        match grip_config::parse_vehicle(Path::new(&format!("{name} (attached)")), text) {
            Ok((v, _)) => Some(v),
            Err(e) => {
                warnings.push(format!("warning: {e}"));
                None
            }
        }
    };
    let closed_replay = log
        .metadata
        .get("grip.replay")
        .is_some_and(|m| m.get("mode").is_some_and(|m| m == "closed loop"));
    if closed_replay && let Some(v) = attached(REPLAY_VEHICLE_ATTACHMENT, warnings) {
        return Some((v, replay_vehicle_label(log)));
    }
    if let Some(v) = attached(VEHICLE_ATTACHMENT, warnings) {
        return Some((v, drive_vehicle_label(log)));
    }
    if let Some(p) = log.run.get("vehicle") {
        let name = log
            .attachments
            .keys()
            .filter(|name| p.ends_with(&format!("/{name}")) || p == *name)
            .max_by_key(|name| name.len());
        if let Some(name) = name
            && let Some(v) = attached(name, warnings)
        {
            return Some((v, attached_label(name)));
        }
        match grip_config::load_vehicle(p) {
            Ok((v, _)) => {
                return Some((v, format!("{p} (read from disk: not attached to the log)")));
            }
            Err(e) => warnings.push(format!(
                "warning: the drive ran with vehicle {p}, which is neither attached to the log nor readable ({e}); using vehicle.toml instead"
            )),
        }
    }
    attached("vehicle.toml", warnings).map(|v| (v, attached_label("vehicle.toml")))
}

/// What a drive is asked to do.
#[derive(Debug, Clone)]
pub struct DrivePlan {
    /// Configuration directory (absolute).
    pub config_dir: PathBuf,
    /// Scenario name or path, as given (`grip.run` `scenario`).
    pub scenario: String,
    /// The scenario file when `scenario` is a path (absolute): plant-sim
    /// reads it, and the recorder attaches it as [`SCENARIO_ATTACHMENT`]
    /// (hashed in `grip.run` as `config.drive/scenario.toml`, its path as
    /// `scenario_file`), so that the log carries the scenario the drive ran
    /// as it carries the configuration directory's `scenarios/*.toml`.
    /// `None`: a name under `<config-dir>/scenarios` (attached with the
    /// directory).
    pub scenario_file: Option<PathBuf>,
    /// Scenario duration, s.
    pub duration_s: f64,
    /// Controller.
    pub controller: String,
    /// ARTE in the controller.
    pub arte: bool,
    /// Output log (absolute).
    pub out: PathBuf,
    /// Plant sensor-noise seed.
    pub seed: u64,
    /// `GRIP_INSTANCE`.
    pub instance: String,
    /// Readiness timeout per service.
    pub ready_timeout: Duration,
    /// `--vehicle FILE` for plant-sim and tcs-loop (absolute); `None`: the
    /// services' default `<config-dir>/vehicle.toml`.
    pub vehicle: Option<PathBuf>,
    /// The model file the user gave (`grip drive --model`; the services run
    /// a copy under the configuration's `model` name): recorded as
    /// `model_given` in `grip.run`, so that the log names the user's file.
    pub model: Option<PathBuf>,
}

/// The name under which the recorder attaches a drive's `--vehicle` file.
pub const VEHICLE_ATTACHMENT: &str = "drive/vehicle.toml";

/// The name under which `grip replay --out` attaches the vehicle file its
/// tcs-loop (and, in closed loop, its plant) ran, when that is not the
/// source drive's (`--vehicle`, or a `--set` on the vehicle): the log's
/// other attachments are the source's, copied.
pub const REPLAY_VEHICLE_ATTACHMENT: &str = "replay/vehicle.toml";

/// The name under which the recorder attaches a drive's `--scenario` file
/// when it was given as a path ([`DrivePlan::scenario_file`]).
pub const SCENARIO_ATTACHMENT: &str = "drive/scenario.toml";

/// The files a drive's recorder attaches (its `--attach NAME=FILE`): a
/// scenario given as a path ([`SCENARIO_ATTACHMENT`]) and a `--vehicle`
/// file ([`VEHICLE_ATTACHMENT`]). [`DrivePlan::args`] passes them, and
/// `grip drive` checks them with the recorder's start-up checks first.
pub fn recorder_attachments<'a>(
    scenario_file: Option<&'a Path>,
    vehicle: Option<&'a Path>,
) -> Vec<(&'static str, &'a Path)> {
    [
        (SCENARIO_ATTACHMENT, scenario_file),
        (VEHICLE_ATTACHMENT, vehicle),
    ]
    .into_iter()
    .filter_map(|(name, file)| Some((name, file?)))
    .collect()
}

/// `grip drive`'s default controller.
pub const DEFAULT_CONTROLLER: &str = "mtte";
/// `grip drive`'s default plant sensor-noise seed.
pub const DEFAULT_SEED: u64 = 1;
/// `grip drive`'s default readiness timeout per service, s.
pub const DEFAULT_READY_TIMEOUT_S: f64 = 30.0;

impl DrivePlan {
    /// A plan with `grip drive`'s defaults ([`DEFAULT_CONTROLLER`], ARTE on,
    /// [`DEFAULT_SEED`], [`DEFAULT_READY_TIMEOUT_S`], the configuration
    /// directory's vehicle).
    pub fn new(
        config_dir: &Path,
        scenario: &str,
        duration_s: f64,
        out: &Path,
        instance: &str,
    ) -> Self {
        Self {
            config_dir: config_dir.to_path_buf(),
            scenario: scenario.to_owned(),
            scenario_file: None,
            duration_s,
            controller: DEFAULT_CONTROLLER.to_owned(),
            arte: true,
            out: out.to_path_buf(),
            seed: DEFAULT_SEED,
            instance: instance.to_owned(),
            ready_timeout: Duration::from_secs_f64(DEFAULT_READY_TIMEOUT_S),
            vehicle: None,
            model: None,
        }
    }

    /// The full argument list of `svc` in this drive: the base command line
    /// (as in the systemd units) plus the drive's overrides.
    pub fn args(&self, svc: Service) -> Vec<String> {
        let mut a = svc.base_args(&self.config_dir.display().to_string());
        let s = |x: &str| x.to_owned();
        match svc {
            Service::Recorder => {
                a.extend([s("--out"), self.out.display().to_string()]);
                for (k, v) in [
                    ("scenario", self.scenario.clone()),
                    ("scenario_duration_s", format!("{}", self.duration_s)),
                    ("controller", self.controller.clone()),
                    ("arte", s(if self.arte { "on" } else { "off" })),
                    ("seed", self.seed.to_string()),
                    ("instance", self.instance.clone()),
                ] {
                    a.extend([s("--meta"), format!("{k}={v}")]);
                }
                if let Some(m) = &self.model {
                    a.extend([s("--meta"), format!("model_given={}", m.display())]);
                }
                if let Some(f) = &self.scenario_file {
                    a.extend([s("--meta"), format!("scenario_file={}", f.display())]);
                }
                if let Some(v) = &self.vehicle {
                    a.extend([s("--meta"), format!("vehicle={}", v.display())]);
                }
                for (name, file) in
                    recorder_attachments(self.scenario_file.as_deref(), self.vehicle.as_deref())
                {
                    a.extend([s("--attach"), format!("{name}={}", file.display())]);
                }
            }
            Service::PlantSim => {
                // the file the recorder attaches, whatever plant-sim's
                // working directory
                let scenario = self
                    .scenario_file
                    .as_ref()
                    .map_or_else(|| self.scenario.clone(), |f| f.display().to_string());
                a.extend([
                    s("--scenario"),
                    scenario,
                    s("--seed"),
                    self.seed.to_string(),
                    s("--start-on"),
                    s("signal"),
                    s("--exit-at-end"),
                ]);
                self.vehicle_args(&mut a);
            }
            Service::TcsLoop => {
                a.extend([
                    s("--controller"),
                    self.controller.clone(),
                    s("--arte"),
                    s(if self.arte { "on" } else { "off" }),
                ]);
                self.vehicle_args(&mut a);
            }
            Service::AudioAcq | Service::Arte => {}
        }
        a
    }

    fn vehicle_args(&self, a: &mut Vec<String>) {
        if let Some(v) = &self.vehicle {
            a.extend(["--vehicle".to_owned(), v.display().to_string()]);
        }
    }
}

/// How a drive ended.
#[derive(Debug)]
pub struct DriveOutcome {
    /// Error to report after the summary (a service died, timeout, ...).
    pub failure: Option<String>,
    /// Per service: final status line and exit description.
    pub services: Vec<(Service, String, Option<String>)>,
    /// Wall time of the scenario part, s.
    pub scenario_wall_s: f64,
}

/// Runs the drive: start in order with readiness, SIGUSR1 to plant-sim,
/// wait for its end (or a death, or `interrupt`), stop the rest (recorder
/// last). Returns once every child has ended; the log is then complete.
/// Progress lines (`drive: ...`) go to `progress`; with `verbose` every
/// line the services write is echoed (else only warnings and errors).
pub fn run_services(
    plan: &DrivePlan,
    bin: &Path,
    verbose: bool,
    interrupt: &Arc<AtomicBool>,
    progress: &mut dyn FnMut(String),
) -> Result<DriveOutcome, SuperviseError> {
    let mut sup = Supervisor::new(&plan.instance)?;
    let t_start = Instant::now();
    let mut failure: Option<String> = None;
    for svc in Service::START_ORDER {
        let spec = svc.spec(bin, &plan.args(svc)).output(Output::Pipe {
            keep: crate::supervisor::TAIL_LINES,
            echo_all: verbose,
        });
        if spec.placement.usable_cpus().len() < spec.placement.cpus.len() {
            progress(format!(
                "drive: {:<9} its unit pins it to CPUs {:?}, of which this machine lets it use {:?}",
                svc.name(),
                spec.placement.cpus,
                spec.placement.usable_cpus(),
            ));
        }
        match sup.start(&spec, plan.ready_timeout) {
            Ok(d) => {
                let pid = sup.get(svc.name()).map(|p| p.pid()).unwrap_or(0);
                progress(format!(
                    "drive: {:<9} ready after {:.2} s (pid {pid})",
                    svc.name(),
                    d.as_secs_f64(),
                ));
            }
            Err(e) => {
                failure = Some(e.to_string());
                break;
            }
        }
        if interrupt.load(Ordering::Relaxed) {
            failure = Some("interrupted".into());
            break;
        }
    }

    let mut scenario_wall_s = 0.0;
    let plant = Service::PlantSim.name();
    if failure.is_none() {
        progress(format!(
            "drive: all services ready in {:.2} s; starting scenario {} ({:.2} s, {} {}ARTE)",
            t_start.elapsed().as_secs_f64(),
            plan.scenario,
            plan.duration_s,
            plan.controller,
            if plan.arte { "with " } else { "without " }
        ));
        let t_scn = Instant::now();
        if let Ok(p) = sup.get(plant) {
            p.signal(libc::SIGUSR1);
        }
        // generous: the loop first leaves its safe state, then the scenario runs
        let limit = Duration::from_secs_f64(plan.duration_s + 60.0);
        let mut stopped = StoppedWatch::default();
        loop {
            std::thread::sleep(Duration::from_millis(20));
            for n in stopped.update(sup.stopped(), Instant::now()) {
                progress(format!(
                    "drive: {n} has been stopped for {:.0} s (process state T: SIGSTOP, Ctrl-Z or a debugger); the drive waits for it, at most {:.0} s from the scenario's start",
                    STOPPED_NOTE_AFTER.as_secs_f64(),
                    limit.as_secs_f64()
                ));
            }
            if interrupt.load(Ordering::Relaxed) {
                failure = Some("interrupted (SIGINT/SIGTERM): services stopped early".into());
                break;
            }
            let mut ended = false;
            for (name, st) in sup.ended() {
                if name == plant && st.success() {
                    ended = true;
                } else if failure.is_none() {
                    let p = sup.get(&name)?;
                    failure = Some(format!(
                        "{name} died during the drive ({}) after {:.2} s.\n  command: {}\n  last stderr lines:\n{}",
                        describe_status(&st),
                        p.started.elapsed().as_secs_f64(),
                        p.cmdline,
                        p.tail_text(15)
                    ));
                }
            }
            if failure.is_some() || ended {
                break;
            }
            if t_scn.elapsed() > limit {
                let stopped = stopped.names();
                failure = Some(format!(
                    "plant-sim did not finish the {:.2} s scenario within {:.0} s ({}).\n  plant-sim stderr:\n{}",
                    plan.duration_s,
                    limit.as_secs_f64(),
                    unfinished_cause(&stopped),
                    sup.get(plant).map(|p| p.tail_text(10)).unwrap_or_default()
                ));
                break;
            }
        }
        scenario_wall_s = t_scn.elapsed().as_secs_f64();
    }

    // stop: plant-sim (if still up), tcs-loop, arte, audio-acq, recorder last
    let mut services = Vec::new();
    for svc in Service::STOP_ORDER {
        let Ok(p) = sup.get(svc.name()) else {
            continue;
        };
        let grace = if svc == Service::Recorder {
            Duration::from_secs(60)
        } else {
            Duration::from_secs(10)
        };
        let (st, killed) = p.stop(grace);
        let desc = st.map(|s| describe_status(&s));
        if killed && failure.is_none() {
            failure = Some(format!(
                "{} did not stop within {:.0} s of SIGTERM and was killed.\n  last stderr lines:\n{}",
                svc.name(),
                grace.as_secs_f64(),
                p.tail_text(10)
            ));
        } else if let Some(s) = st
            && !s.success()
            && failure.is_none()
        {
            failure = Some(format!(
                "{} exited with {} on SIGTERM.\n  last stderr lines:\n{}",
                svc.name(),
                describe_status(&s),
                p.tail_text(10)
            ));
        }
        let last = p
            .tail(TAIL_FOR_REPORT)
            .into_iter()
            .rev()
            .find(|l| l.contains("stopped"))
            .unwrap_or_default();
        services.push((svc, last, desc));
    }
    Ok(DriveOutcome {
        failure,
        services,
        scenario_wall_s,
    })
}

/// How long a service must have been stopped (process state `T`) before
/// the drive says so: the fault-injection tests stop arte and plant-sim for
/// up to 2 s on purpose.
const STOPPED_NOTE_AFTER: Duration = Duration::from_secs(5);

/// The services seen stopped (process state `T`) during a drive, since
/// when, and whether the drive has said so.
#[derive(Debug, Default)]
struct StoppedWatch {
    seen: Vec<(String, Instant, bool)>,
}

impl StoppedWatch {
    /// Takes the services stopped `now`; returns those stopped for
    /// [`STOPPED_NOTE_AFTER`] and not yet said (each said once per stop:
    /// a service continued and stopped again is said again).
    fn update(&mut self, now_stopped: Vec<String>, now: Instant) -> Vec<String> {
        self.seen.retain(|(n, _, _)| now_stopped.contains(n));
        for n in now_stopped {
            if !self.seen.iter().any(|(m, _, _)| *m == n) {
                self.seen.push((n, now, false));
            }
        }
        let mut say = Vec::new();
        for (n, since, said) in &mut self.seen {
            if !*said && now.duration_since(*since) >= STOPPED_NOTE_AFTER {
                *said = true;
                say.push(n.clone());
            }
        }
        say
    }

    /// The services stopped at the last update.
    fn names(&self) -> Vec<String> {
        self.seen.iter().map(|(n, _, _)| n.clone()).collect()
    }
}

/// Why plant-sim may not have finished its scenario: the services that
/// were stopped (process state `T`) when the time ran out, else the usual
/// cause, a tcs-loop still in its safe state.
fn unfinished_cause(stopped: &[String]) -> String {
    if stopped.is_empty() {
        "did tcs-loop leave its safe state?".to_owned()
    } else {
        format!(
            "stopped (process state T: SIGSTOP, Ctrl-Z or a debugger), so making no progress: {}",
            stopped.join(", ")
        )
    }
}

const TAIL_FOR_REPORT: usize = 40;

/// A unique `GRIP_INSTANCE` value for a drive.
pub fn new_instance() -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!("drive-{}-{nanos:x}", std::process::id())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A service stopped for 5 s is said once; continued and stopped
    /// again, said again after 5 s more; the names are those stopped now.
    #[test]
    fn a_stopped_service_is_said_once_per_stop() {
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let v = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let mut w = StoppedWatch::default();
        assert!(w.update(v(&["plant-sim"]), at(0.0)).is_empty());
        assert!(w.update(v(&["plant-sim", "arte"]), at(2.0)).is_empty());
        assert_eq!(
            w.update(v(&["plant-sim", "arte"]), at(5.0)),
            v(&["plant-sim"])
        );
        assert!(w.update(v(&["plant-sim", "arte"]), at(6.0)).is_empty());
        assert_eq!(w.update(v(&["plant-sim", "arte"]), at(7.0)), v(&["arte"]));
        assert_eq!(w.names(), v(&["plant-sim", "arte"]));
        // plant-sim continued, then stopped again
        assert!(w.update(v(&["arte"]), at(8.0)).is_empty());
        assert_eq!(w.names(), v(&["arte"]));
        assert!(w.update(v(&["arte", "plant-sim"]), at(9.0)).is_empty());
        assert_eq!(
            w.update(v(&["arte", "plant-sim"]), at(14.0)),
            v(&["plant-sim"])
        );
    }

    /// A drive that ran out of time names the services that were stopped
    /// instead of guessing at tcs-loop's safe state.
    #[test]
    fn an_unfinished_drive_names_its_stopped_services() {
        assert_eq!(unfinished_cause(&[]), "did tcs-loop leave its safe state?");
        let c = unfinished_cause(&["plant-sim".to_owned(), "arte".to_owned()]);
        assert!(
            c.contains("stopped (process state T") && c.ends_with(": plant-sim, arte"),
            "{c}"
        );
        assert!(!c.contains("tcs-loop"), "{c}");
    }

    /// The vehicle a drive ran with: its attached `--vehicle` copy, or the
    /// attached profile named by `grip.run` `vehicle=PATH`, not the attached
    /// `vehicle.toml`; without either, `vehicle.toml`.
    #[test]
    fn vehicle_for_uses_the_profile_the_drive_ran_with() {
        let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let read = |f: &str| std::fs::read(cfg.join(f)).unwrap();
        let mut log = DriveLog::default();
        log.attachments
            .insert("vehicle.toml".into(), read("vehicle.toml"));
        log.attachments.insert(
            "vehicles/front-mic.toml".into(),
            read("vehicles/front-mic.toml"),
        );
        let (v, from, w) = vehicle_for(&log, &cfg);
        assert_eq!(v.mic_lead_m, 0.0);
        assert!(from.starts_with("vehicle.toml"), "{from}");
        assert!(w.is_empty(), "{w:?}");
        log.run.insert(
            "vehicle".into(),
            "/elsewhere/config/vehicles/front-mic.toml".into(),
        );
        let (v, from, _) = vehicle_for(&log, &cfg);
        assert_eq!(v.mic_lead_m, 2.77);
        assert_eq!(v.n_driven, 2.0);
        assert!(
            from.starts_with("vehicles/front-mic.toml (attached"),
            "{from}"
        );
        // not attached: read from the path
        log.attachments.remove("vehicles/front-mic.toml");
        let p = cfg.join("vehicles/front-mic.toml");
        log.run.insert("vehicle".into(), p.display().to_string());
        let (v, from, _) = vehicle_for(&log, &cfg);
        assert_eq!(v.mic_lead_m, 2.77);
        assert!(from.contains("read from disk"), "{from}");
        // the drive's own copy wins
        log.attachments
            .insert(VEHICLE_ATTACHMENT.into(), read("vehicles/front-mic.toml"));
        log.run.insert("vehicle".into(), "/nowhere/v.toml".into());
        let (v, from, w) = vehicle_for(&log, &cfg);
        assert_eq!(v.mic_lead_m, 2.77);
        // named by the path the drive was given (a trial's summary said
        // only `drive/vehicle.toml (attached to the log)`)
        assert_eq!(
            from,
            "/nowhere/v.toml (grip drive --vehicle; attached to the log as drive/vehicle.toml)"
        );
        assert!(w.is_empty(), "{w:?}");
        log.run.remove("vehicle");
        let (_, from, _) = vehicle_for(&log, &cfg);
        assert_eq!(from, "drive/vehicle.toml (attached to the log)");
    }

    /// Every service's drive command line is its unit's command line (base
    /// arguments) with the drive's overrides appended, never changed.
    #[test]
    fn drive_args_extend_the_unit_command_line() {
        let plan = DrivePlan {
            config_dir: PathBuf::from("/cfg"),
            scenario: "paper".into(),
            scenario_file: None,
            duration_s: 2.4,
            controller: "src".into(),
            arte: false,
            out: PathBuf::from("/tmp/x.mcap"),
            seed: 7,
            instance: "t".into(),
            ready_timeout: Duration::from_secs(1),
            vehicle: None,
            model: None,
        };
        for s in Service::START_ORDER {
            let a = plan.args(s);
            let base = s.base_args("/cfg");
            assert_eq!(&a[..base.len()], &base[..], "{}", s.name());
        }
        let p = plan.args(Service::PlantSim).join(" ");
        assert!(
            p.contains("--scenario paper") && p.contains("--seed 7") && p.contains("--exit-at-end")
        );
        assert!(
            plan.args(Service::TcsLoop)
                .join(" ")
                .ends_with("--controller src --arte off")
        );
        assert!(
            plan.args(Service::Recorder)
                .join(" ")
                .contains("--out /tmp/x.mcap")
        );
        // --model: the user's file recorded by the recorder (the services
        // run a copy under the configuration's name)
        let given = DrivePlan {
            model: Some(PathBuf::from("/srv/recordings/mine.model")),
            ..plan.clone()
        };
        assert!(
            given
                .args(Service::Recorder)
                .join(" ")
                .contains("--meta model_given=/srv/recordings/mine.model")
        );
        assert!(
            !plan
                .args(Service::Recorder)
                .join(" ")
                .contains("model_given")
        );
        // a scenario given as a path: plant-sim reads the file the recorder
        // attaches (a trial's `--scenario scen/suv.toml` was not in the log,
        // and a replay from another directory could not read it)
        assert!(!plan.args(Service::Recorder).join(" ").contains("--attach"));
        let own = DrivePlan {
            scenario: "scen/suv.toml".into(),
            scenario_file: Some(PathBuf::from("/drives/scen/suv.toml")),
            ..plan.clone()
        };
        let r = own.args(Service::Recorder).join(" ");
        assert!(
            r.contains("--meta scenario=scen/suv.toml")
                && r.contains("--meta scenario_file=/drives/scen/suv.toml")
                && r.contains("--attach drive/scenario.toml=/drives/scen/suv.toml"),
            "{r}"
        );
        assert!(
            own.args(Service::PlantSim)
                .join(" ")
                .contains("--scenario /drives/scen/suv.toml")
        );
        // --vehicle goes to the two services that read the vehicle, after
        // the unit's command line
        let plan = DrivePlan {
            vehicle: Some(PathBuf::from("/cfg/vehicles/front-mic.toml")),
            ..plan
        };
        for s in Service::START_ORDER {
            let a = plan.args(s);
            let base = s.base_args("/cfg");
            assert_eq!(&a[..base.len()], &base[..], "{}", s.name());
            let has = a
                .join(" ")
                .contains("--vehicle /cfg/vehicles/front-mic.toml");
            assert_eq!(
                has,
                matches!(s, Service::PlantSim | Service::TcsLoop),
                "{}",
                s.name()
            );
        }
    }

    #[test]
    fn missing_binaries_name_the_build_command() {
        let d = tempfile::tempdir().unwrap();
        let e = check_binaries(d.path()).unwrap_err().to_string();
        assert!(e.contains("recorder") && e.contains("tcs-loop"), "{e}");
        assert!(e.contains("cargo build --release --workspace"), "{e}");
    }

    #[test]
    fn instances_are_valid_and_unique() {
        let a = new_instance();
        assert!(a.len() <= 64);
        assert!(
            a.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
        );
        std::thread::sleep(Duration::from_millis(1));
        assert_ne!(a, new_instance());
    }
}
