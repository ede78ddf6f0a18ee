//! The configuration a replay runs with: by default the drive's own, from
//! the log (the recorder attaches every configuration file and model, with
//! their SHA-256 in `grip.run`; `grip drive` adds its `--vehicle` file as
//! `drive/vehicle.toml` and the controller and ARTE switch as metadata),
//! written to a temporary directory; the what-if options change it.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use grip_drive::DriveLog;
use grip_drive::plan::{SCENARIO_ATTACHMENT, VEHICLE_ATTACHMENT};
use grip_io::service::ServiceConfig;

/// What the caller changes.
#[derive(Debug, Clone, Default)]
pub struct WhatIf {
    /// `--controller`.
    pub controller: Option<String>,
    /// `--arte on|off`.
    pub arte: Option<bool>,
    /// `--config-dir`: this directory instead of the log's configuration.
    pub config_dir: Option<PathBuf>,
    /// `--vehicle`.
    pub vehicle: Option<PathBuf>,
    /// `--model`.
    pub model: Option<PathBuf>,
    /// `--set [FILE:]SECTION.KEY=VALUE` (or `[FILE:]KEY=VALUE`).
    pub set: Vec<String>,
    /// `--closed-loop`: plant-sim is re-run, so its files are read ([`Reads`]).
    pub closed_loop: bool,
}

/// The configuration directory and the service overrides of a replay.
#[derive(Debug)]
pub struct ReplayConfig {
    /// The directory the services' start-up reads.
    pub dir: PathBuf,
    _tmp: tempfile::TempDir,
    /// Where it came from, for the report.
    pub source: String,
    /// tcs-loop's controller.
    pub controller: String,
    /// tcs-loop's ARTE switch.
    pub arte: bool,
    /// `--vehicle` of tcs-loop.
    pub vehicle: Option<PathBuf>,
    /// arte's model override.
    pub model: Option<PathBuf>,
    /// The drive's scenario as the log carries it (`drive/scenario.toml`
    /// in `dir`: a drive given `--scenario PATH`); `None`: the scenario
    /// `grip.run` names, under `dir/scenarios`.
    pub scenario_file: Option<PathBuf>,
    /// The changes against the drive, one line each (empty: none).
    pub changes: Vec<String>,
    /// The `--set`s, as applied.
    pub applied: Vec<Applied>,
    /// Files of `dir` the user knows by another name (a copied `--vehicle`).
    shown_paths: Vec<(PathBuf, String)>,
}

fn safe_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('/')
        && Path::new(name)
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_)))
}

fn copy_dir(from: &Path, to: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(to).with_context(|| format!("creating {}", to.display()))?;
    for e in std::fs::read_dir(from).with_context(|| format!("reading {}", from.display()))? {
        let e = e?;
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()))?;
        } else {
            std::fs::copy(&p, to.join(e.file_name()))
                .with_context(|| format!("copying {}", p.display()))?;
        }
    }
    Ok(())
}

/// A `--set can.toml:dbc=FILE` (closed loop) naming a DBC the replay's
/// configuration does not have: the user's file, FILE as a path from the
/// current directory, is copied into the replay's configuration under its
/// file name (can.toml then names that); a FILE found in neither is an
/// error naming both places. (Until 2026-12-07 only a DBC the log carried
/// could be named, and any other failed at tcs-loop's start-up, "cannot be
/// read", without saying where it was looked for.)
fn bring_the_dbc(dir: &Path, applied: &mut [Applied]) -> anyhow::Result<()> {
    let Some(a) = applied
        .iter_mut()
        .find(|a| a.rel == "can.toml" && a.path == "dbc")
    else {
        return Ok(());
    };
    let Some(name) = a.value.as_str().map(str::to_owned) else {
        return Ok(());
    };
    if safe_name(&name) && dir.join(&name).is_file() {
        return Ok(());
    }
    let src = Path::new(&name);
    let Some(file_name) = src.file_name().filter(|_| src.is_file()) else {
        bail!(
            "--set {}: can.toml's dbc names {name:?}, which is neither a file of the replay's configuration nor a file from the current directory ({})",
            a.spec,
            std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string())
        );
    };
    let file_name = file_name.to_string_lossy().into_owned();
    std::fs::copy(src, dir.join(&file_name)).with_context(|| {
        format!(
            "--set {}: copying {name} into the replay's configuration",
            a.spec
        )
    })?;
    if file_name != name {
        let p = dir.join("can.toml");
        let mut doc: toml::Table = toml::from_str(&std::fs::read_to_string(&p)?)?;
        doc.insert("dbc".into(), toml::Value::String(file_name.clone()));
        std::fs::write(&p, toml::to_string(&doc)?)?;
        a.value = toml::Value::String(file_name.clone());
    }
    a.line.push_str(&format!(
        " (the DBC {name}, copied into the replay's configuration as {file_name})"
    ));
    Ok(())
}

/// The recorded frames are the drive's bus: whatever `--config-dir` says,
/// its `can.toml` and the DBC that names the frames are the log's (a log
/// from before the services read a DBC carries a `can.toml` without `dbc`:
/// the built-in protocol). Said among the changes when they differ.
fn keep_the_logs_bus(log: &DriveLog, dir: &Path, changes: &mut Vec<String>) -> anyhow::Result<()> {
    let Some(can) = log.attachments.get("can.toml") else {
        return Ok(());
    };
    let p = dir.join("can.toml");
    let given = std::fs::read(&p).unwrap_or_default();
    let mut files = vec![("can.toml".to_owned(), can)];
    let parsed = grip_io::service::parse_can(
        Path::new("can.toml (attached)"),
        &String::from_utf8_lossy(can),
    )
    .with_context(|| format!("{}: the attached can.toml", log.path.display()))?;
    if let Some(dbc) = &parsed.dbc {
        let data = log.attachments.get(dbc).with_context(|| {
            format!(
                "{}: the attached can.toml names dbc = {dbc:?}, which the log does not carry",
                log.path.display()
            )
        })?;
        files.push((dbc.clone(), data));
    }
    let differs = given != **can
        || files[1..]
            .iter()
            .any(|(n, d)| std::fs::read(dir.join(n)).ok().as_deref() != Some(&d[..]));
    for (name, data) in files {
        std::fs::write(dir.join(&name), data).with_context(|| format!("writing {name}"))?;
    }
    if differs {
        changes.push(
            "CAN bus: the log's can.toml and DBC, not --config-dir's (the recorded frames are read as they were sent)"
                .into(),
        );
    }
    Ok(())
}

/// The replay's word on keys its controllers file (in `dir`, the
/// temporary copy the services read) leaves out and which therefore take
/// the rule from before they existed (a log recorded before them): said
/// about `file` (the log's attachment, or `--config-dir`'s file), with
/// the `--set` that replays with the shipped value, instead of the
/// services' warning about the temporary copy, which is gone after the
/// replay (that line is marked as said). None when nothing is left out,
/// or the file does not load (the services report that).
fn old_rules_note(dir: &Path, file: &str) -> Option<String> {
    let path = dir.join("controllers.toml");
    let text = std::fs::read_to_string(&path).ok()?;
    let config = grip_config::parse_controllers(&path, &text).ok()?;
    let generic = grip_config::controllers::old_rule_warning(&path, &text, &config)?;
    grip_config::first_time(&generic);
    let left = grip_config::controllers::old_rule_keys_left_out(&text, &config);
    let list = |f: &dyn Fn(&(String, String, String)) -> String| {
        left.iter().map(f).collect::<Vec<_>>().join(", ")
    };
    Some(format!(
        "note: {file} leaves out {}: replayed with the rule from before {} existed ({}), as the drive ran; \
         to replay with the shipped value{}: {}",
        list(&|(k, _, _)| k.clone()),
        if left.len() == 1 { "it" } else { "each" },
        list(&|(k, t, _)| format!("{k} = {t}")),
        if left.len() == 1 { "" } else { "s" },
        list(&|(k, _, s)| format!("--set {k}={s}")),
    ))
}

/// Writes the log's configuration (or `--config-dir`'s) to a temporary
/// directory, checks it against the hashes in `grip.run`, and applies the
/// what-if options. A log whose timing the replay cannot run
/// ([`super::check::log`]: no drive logs it) is refused first, before
/// anything is written or replayed.
pub fn prepare(log: &DriveLog, w: &WhatIf) -> anyhow::Result<ReplayConfig> {
    super::check::log(log, w.closed_loop)?;
    let tmp = tempfile::tempdir().context("creating a temporary configuration directory")?;
    let dir = tmp.path().to_path_buf();
    let mut changes = Vec::new();
    let source = match &w.config_dir {
        Some(d) => {
            copy_dir(d, &dir)?;
            changes.push(format!("configuration directory {}", d.display()));
            // open loop: the recorded frames are read as they were sent;
            // closed loop: plant-sim sends them, with --config-dir's bus
            if !w.closed_loop {
                keep_the_logs_bus(log, &dir, &mut changes)?;
            }
            format!("{} (--config-dir)", d.display())
        }
        None => {
            let mut n = 0;
            for (name, data) in &log.attachments {
                if name.starts_with("drive/") {
                    continue;
                }
                if !safe_name(name) {
                    bail!(
                        "{}: attachment {name:?} is not a relative file name; not written",
                        log.path.display()
                    );
                }
                let want = log
                    .run
                    .get(&format!("config.{name}"))
                    .or_else(|| log.run.get(&format!("model.{name}")));
                if let Some(h) = want
                    && *h != grip_digest::sha256_hex(data)
                {
                    bail!(
                        "{}: attachment {name}: its SHA-256 is not the one grip.run records ({h}): the log is damaged",
                        log.path.display()
                    );
                }
                let p = dir.join(name);
                if let Some(parent) = p.parent() {
                    std::fs::create_dir_all(parent)?;
                }
                std::fs::write(&p, data).with_context(|| format!("writing {}", p.display()))?;
                n += 1;
            }
            if n == 0 {
                bail!(
                    "{}: the log carries no configuration files (attachments); pass --config-dir",
                    log.path.display()
                );
            }
            let missing: Vec<&str> = log
                .run
                .keys()
                .filter_map(|k| k.strip_prefix("not_attached."))
                .collect();
            if !missing.is_empty() && w.model.is_none() {
                bail!(
                    "{}: the recorder did not attach {} (too large); pass --config-dir or --model",
                    log.path.display(),
                    missing.join(", ")
                );
            }
            format!(
                "the log's attachments ({n} files, SHA-256 as recorded; recorded at git revision {})",
                log.run.get("git_revision").map_or("?", String::as_str)
            )
        }
    };

    // the vehicle first: a `--set` on the vehicle goes to the file the
    // replay reads
    let mut shown_paths = Vec::new();
    let mut vehicle_file = None;
    let vehicle = match &w.vehicle {
        Some(v) if !w.set.is_empty() => {
            // a copy: a `--set` must never rewrite the user's own file
            let name = v.file_name().map_or_else(
                || "vehicle.toml".into(),
                |n| n.to_string_lossy().into_owned(),
            );
            let rel = format!("what-if/{name}");
            let p = dir.join(&rel);
            std::fs::create_dir_all(dir.join("what-if"))?;
            std::fs::copy(v, &p)
                .with_context(|| format!("--vehicle {}: reading it", v.display()))?;
            shown_paths.push((p.clone(), v.display().to_string()));
            vehicle_file = Some(VehicleFile {
                rel,
                shown: format!("{name} (--vehicle {})", v.display()),
                names: vec![name],
            });
            Some(p)
        }
        Some(v) => Some(v.clone()),
        None => match (
            log.run.get("vehicle"),
            log.attachments.get(VEHICLE_ATTACHMENT),
        ) {
            (_, Some(data)) => {
                let p = dir.join(VEHICLE_ATTACHMENT);
                if let Some(parent) = p.parent() {
                    std::fs::create_dir_all(parent)?;
                }
                std::fs::write(&p, data)?;
                vehicle_file = Some(VehicleFile {
                    rel: VEHICLE_ATTACHMENT.to_owned(),
                    shown: format!("{VEHICLE_ATTACHMENT} (the drive's --vehicle, from the log)"),
                    names: vec![VEHICLE_ATTACHMENT.to_owned()],
                });
                Some(p)
            }
            (Some(v), None) => bail!(
                "{}: the drive ran with --vehicle {v}, which the log does not carry; pass --vehicle",
                log.path.display()
            ),
            (None, None) => None,
        },
    };
    // a scenario the drive was given by path: the log's copy, whatever the
    // file at that path holds now or wherever the replay runs
    let mut scenario_file = None;
    if let Some(data) = log.attachments.get(SCENARIO_ATTACHMENT) {
        if let Some(h) = log.run.get(&format!("config.{SCENARIO_ATTACHMENT}"))
            && *h != grip_digest::sha256_hex(data)
        {
            bail!(
                "{}: attachment {SCENARIO_ATTACHMENT}: its SHA-256 is not the one grip.run records ({h}): the log is damaged",
                log.path.display()
            );
        }
        let p = dir.join(SCENARIO_ATTACHMENT);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::write(&p, data).with_context(|| format!("writing {}", p.display()))?;
        scenario_file = Some(p);
    }
    let scenario = match &scenario_file {
        Some(_) => Some(SCENARIO_ATTACHMENT.to_owned()),
        // a name: its file in the log's configuration directory (by its
        // spelling, as the summary reads grip.run's scenario)
        None => log
            .run
            .get("scenario")
            .and_then(|s| grip_config::dir::ScenarioArg::by_spelling(s).in_config_dir()),
    };
    let reads = Reads {
        closed: w.closed_loop,
        vehicle: vehicle_file,
        scenario,
        logged_seed: log.run.contains_key("seed"),
    };
    let mut applied: Vec<Applied> = Vec::new();
    for s in &w.set {
        let a = set_key(&dir, s, &reads)?;
        if let Some(p) = applied.iter().find(|p| p.rel == a.rel && p.key == a.key) {
            bail!(
                "--set {} and --set {}: both set {} of {}; give it once",
                p.spec,
                a.spec,
                a.path,
                a.shown
            );
        }
        applied.push(a);
    }
    bring_the_dbc(&dir, &mut applied)?;
    // tcs-loop.toml's `controller` and `arte` are what --controller and
    // --arte set: the drive's (grip.run) would otherwise win over the file
    let own_set = |key: &str| {
        applied
            .iter()
            .position(|a| a.rel == "tcs-loop.toml" && a.path == key)
    };

    let own_controller = || -> Option<String> {
        let text = std::fs::read_to_string(dir.join("tcs-loop.toml")).ok()?;
        let v: toml::Value = toml::from_str(&text).ok()?;
        v.get("controller")?.as_str().map(str::to_owned)
    };
    let logged_controller = log.run.get("controller").cloned();
    let set_controller = own_set("controller").map(|i| {
        let a = &applied[i];
        (
            i,
            a.spec.clone(),
            a.value.as_str().unwrap_or_default().to_owned(),
        )
    });
    let set_arte = own_set("arte").map(|i| {
        (
            i,
            applied[i].spec.clone(),
            applied[i].value.as_bool() == Some(true),
        )
    });
    let controller = match (&w.controller, set_controller) {
        (Some(c), Some((_, spec, s))) if *c != s => {
            bail!("--controller {c} and --set {spec}: two controllers; give one")
        }
        (_, Some((i, spec, c))) => {
            if let Err(e) = c.parse::<grip_tcs::ControllerKind>() {
                bail!("--set {spec}: tcs-loop.toml: field `controller`: {e}");
            }
            applied[i].line = format!(
                "tcs-loop.toml: controller {} -> {c} (the replay's controller, as --controller {c})",
                logged_controller.as_deref().unwrap_or("?")
            );
            c
        }
        (Some(c), None) => {
            if logged_controller.as_deref() != Some(c.as_str()) {
                changes.push(format!(
                    "controller {} -> {c}",
                    logged_controller.as_deref().unwrap_or("?")
                ));
            }
            c.clone()
        }
        (None, None) => logged_controller
            .clone()
            .or_else(own_controller)
            .context("neither the log's grip.run nor tcs-loop.toml names the controller")?,
    };
    let logged_arte = log.run.get("arte").map(|a| a == "on");
    let on_off = |x: bool| if x { "on" } else { "off" };
    let arte = match (w.arte, set_arte) {
        (Some(a), Some((_, spec, s))) if a != s => bail!(
            "--arte {} and --set {spec}: two ARTE switches; give one",
            on_off(a)
        ),
        (_, Some((i, _, a))) => {
            applied[i].line = format!(
                "tcs-loop.toml: arte {} -> {a} (ARTE in the controller, as --arte {})",
                logged_arte.map_or("?", |x| if x { "true" } else { "false" }),
                on_off(a)
            );
            a
        }
        (Some(a), None) => {
            // the drive's own switch given again is no change (`--model`
            // asks for ARTE on: "on -> on" was listed as one)
            if logged_arte != Some(a) {
                changes.push(format!(
                    "ARTE in the controller {} -> {}",
                    logged_arte.map_or("?", on_off),
                    on_off(a)
                ));
            }
            a
        }
        (None, None) => match logged_arte {
            Some(a) => a,
            None => {
                let text = std::fs::read_to_string(dir.join("tcs-loop.toml")).unwrap_or_default();
                toml::from_str::<toml::Value>(&text)
                    .ok()
                    .and_then(|v| v.get("arte").and_then(toml::Value::as_bool))
                    .unwrap_or(true)
            }
        },
    };
    if let Some(v) = &w.vehicle {
        changes.push(format!("vehicle {}", v.display()));
    }
    if let Some(m) = &w.model {
        changes.push(format!("model {}", m.display()));
    }
    changes.extend(applied.iter().map(|a| a.line.clone()));
    check_model_rate(log, w, &dir, &changes)?;
    let file = match &w.config_dir {
        Some(d) => d.join("controllers.toml").display().to_string(),
        None => format!("{}'s controllers.toml", log.path.display()),
    };
    if let Some(note) = old_rules_note(&dir, &file) {
        eprintln!("{note}");
    }
    Ok(ReplayConfig {
        dir,
        _tmp: tmp,
        source,
        controller,
        arte,
        vehicle,
        model: w.model.clone(),
        scenario_file,
        changes,
        applied,
        shown_paths,
    })
}

/// The model file arte's start-up will load from `dir` (or `--model`), and
/// the sample rate it was trained for ([`crate::drive::rates::arte_model`]);
/// `None` when it cannot be read here (arte's start-up then says why).
fn model_rate(w: &WhatIf, dir: &Path) -> Option<(PathBuf, u32)> {
    let m = crate::drive::rates::arte_model(dir, w.model.as_deref()).ok()?;
    Some((m.path, m.hz))
}

/// Refuses a replay whose model was trained for another sample rate than
/// the log's audio blocks: arte refuses every such block (its
/// `rate_mismatch` counter), so the replay would publish no road estimate
/// and report a drive without ARTE as if it were the model's. The drive's
/// own model (no `--model`, `--config-dir` or `--set` on arte-svc.toml) is
/// replayed as recorded, with a warning: the drive had the same mismatch.
fn check_model_rate(
    log: &DriveLog,
    w: &WhatIf,
    dir: &Path,
    changes: &[String],
) -> anyhow::Result<()> {
    let mut rates: Vec<u32> = log.audio_blocks.iter().map(|b| b.sample_rate).collect();
    rates.sort_unstable();
    rates.dedup();
    let Some((path, fs)) = model_rate(w, dir) else {
        return Ok(());
    };
    let other: Vec<u32> = rates.iter().copied().filter(|&r| r != fs).collect();
    if other.is_empty() {
        return Ok(());
    }
    let refused = log
        .audio_blocks
        .iter()
        .filter(|b| b.sample_rate != fs)
        .count();
    let audio = other
        .iter()
        .map(|r| format!("{r} Hz"))
        .collect::<Vec<_>>()
        .join(" and ");
    // a `--set` line is `FILE: [SECTION] KEY ...` (`set_key`)
    let arte_file = <grip_arte_svc::ArteServiceConfig as ServiceConfig>::FILE_NAME;
    let own = w.model.is_none()
        && w.config_dir.is_none()
        && !changes
            .iter()
            .any(|c| c.split_once(':').is_some_and(|(f, _)| f == arte_file));
    let what = match &w.model {
        Some(m) => format!("--model {}", m.display()),
        None => match path.strip_prefix(dir) {
            Ok(rel) => format!("model {} (of the replay's configuration)", rel.display()),
            Err(_) => format!("model {}", path.display()),
        },
    };
    if own {
        eprintln!(
            "warning: {}: the drive's own {what} expects {fs} Hz audio, but {refused} of the log's {} audio blocks are at {audio}: arte refused them in the drive and refuses them in the replay (no road estimates from them)",
            log.path.display(),
            log.audio_blocks.len()
        );
        return Ok(());
    }
    let first = other[0];
    bail!(
        "{}: {what} expects {fs} Hz audio, but the log's audio blocks are at {audio} ({refused} of {} blocks): arte would refuse every one of them and the replay would publish no road estimate. Replay with a model trained at {first} Hz (`grip train --data` a dataset recorded at {first} Hz), or without --model to use the drive's own",
        log.path.display(),
        log.audio_blocks.len()
    )
}

/// The vehicle file a replay reads when it is not the configuration's
/// `vehicle.toml`: the drive's `--vehicle` (the log's `drive/vehicle.toml`)
/// or the replay's `--vehicle` (copied into the replay's configuration when
/// a `--set` may change it, so the user's file is never touched).
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleFile {
    /// Where it is, relative to the replay's configuration directory.
    pub rel: String,
    /// How the user knows it (in change lines and errors).
    pub shown: String,
    /// The names `--set FILE:` may give it.
    pub names: Vec<String>,
}

/// Which files, and which keys of them, a replay reads: a `--set`
/// anywhere else could have no effect and is refused, naming why.
#[derive(Debug, Clone, Default)]
pub struct Reads {
    /// `--closed-loop`: plant-sim is re-run (plant-sim.toml, the drive's
    /// scenario, the vehicle's `[sensors]`, the bus).
    pub closed: bool,
    /// The vehicle file, when not `vehicle.toml`.
    pub vehicle: Option<VehicleFile>,
    /// The drive's scenario file (relative), read by plant-sim in closed loop.
    pub scenario: Option<String>,
    /// `grip.run` records the seed (plant-sim.toml's `seed` is then not read).
    pub logged_seed: bool,
}

impl Reads {
    /// Why the replay does not read `path` of `file` (`None`: it does).
    fn unread(&self, file: &str, path: &[Seg]) -> Option<String> {
        let first = path[0].name.as_str();
        let rt = || {
            "[rt] sets up the live service's real-time thread (priority, memory lock, CPUs); a replay runs the loop on a scripted clock and reads none of it".to_owned()
        };
        let vehicle_rel = self.vehicle.as_ref().map_or("vehicle.toml", |v| &v.rel);
        if file == vehicle_rel {
            return (first == "sensors" && !self.closed).then(|| {
                "[sensors] of the vehicle are plant-sim's sensor models; in open loop the sensor readings are the log's (tcs-loop reads [vehicle] only): replay with --closed-loop".to_owned()
            });
        }
        if self.scenario.as_deref() == Some(file) && self.closed {
            return None;
        }
        let not_closed = |what: &str| {
            format!(
                "{what} plant-sim's, which an open-loop replay does not re-run: the wheel speeds, vehicle speed and ground truth are the log's (--closed-loop re-runs plant-sim)"
            )
        };
        match file {
            "controllers.toml" | "roads.toml" => None,
            "vehicle.toml" => Some(match &self.vehicle {
                Some(v) => format!(
                    "the replay's vehicle is {}, not vehicle.toml: name it (--set {}:...) or leave the file out",
                    v.shown, v.names[0]
                ),
                None => "the replay reads another vehicle file".into(),
            }),
            "tcs-loop.toml" => (first == "rt").then(rt),
            "arte-svc.toml" => match (first, path.get(1).map(|s| s.name.as_str())) {
                ("rt", _) => Some(rt()),
                ("input", Some("poll_interval_ms")) => Some(
                    "arte-svc.toml [input] poll_interval_ms is how often the live service polls the audio topic; a replay hands arte every block in turn".into(),
                ),
                _ => None,
            },
            "can.toml" if !self.closed => Some(
                "can.toml is the drive's bus: an open-loop replay reads the recorded frames as they were sent, with the log's can.toml and DBC (a what-if on the bus needs --closed-loop, where plant-sim sends the frames)".into(),
            ),
            "can.toml" => matches!(first, "transport" | "interface" | "sim_bus" | "bus_id").then(|| {
                format!("can.toml's {first} is the live bus's; a replay's bus is in memory")
            }),
            "plant-sim.toml" if !self.closed => Some(not_closed("plant-sim.toml is")),
            "plant-sim.toml" => match first {
                "scenario" => Some("the replay runs the drive's scenario (grip.run's `scenario`), not plant-sim.toml's".into()),
                "seed" if self.logged_seed => Some("the replay runs the drive's seed (grip.run's `seed`), not plant-sim.toml's".into()),
                "start_on" | "exit_at_end" => Some(format!(
                    "plant-sim.toml's {first} is replaced by the replay: the plant starts in the cycle the logged plant started and ends at the scenario's end"
                )),
                "allow_physical_bus" => Some("a replay's bus is in memory; plant-sim.toml's allow_physical_bus guards a live bus".into()),
                "rt" => Some(rt()),
                _ => None,
            },
            "audio-acq.toml" => Some(
                "audio-acq is not re-run: the replay feeds arte the log's audio blocks as recorded (a model for another sample rate: --model)".into(),
            ),
            "recorder.toml" => Some(
                "the recorder is not re-run: the replay compares and writes (--out) the replayed messages itself".into(),
            ),
            "sim-confusion.toml" => Some(
                "sim-confusion.toml is grip sim's confusion model of ARTE; no service of a replay reads it".into(),
            ),
            f if f.starts_with("scenarios/") => Some(if self.closed {
                format!(
                    "the replay runs the drive's scenario ({}), not this one",
                    self.scenario.as_deref().unwrap_or("?")
                )
            } else {
                not_closed("scenarios are")
            }),
            f if f.starts_with("vehicles/") || f.starts_with("drive/") => Some(format!(
                "the replay's vehicle is {}",
                self.vehicle.as_ref().map_or("vehicle.toml", |v| &v.shown)
            )),
            _ => Some("no service the replay runs reads this file".into()),
        }
    }

    /// The TOML files `--set` may name in `dir`: the directory's own, the
    /// vehicle file and (closed loop) the drive's scenario, relative.
    fn files(&self, dir: &Path) -> anyhow::Result<Vec<String>> {
        let mut files: Vec<String> = std::fs::read_dir(dir)?
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".toml") && dir.join(n).is_file())
            .collect();
        files.sort();
        if let Some(v) = &self.vehicle {
            files.push(v.rel.clone());
        }
        if let Some(s) = &self.scenario
            && self.closed
        {
            files.push(s.clone());
        }
        Ok(files)
    }

    /// How the user knows `rel`.
    fn shown(&self, rel: &str) -> String {
        match &self.vehicle {
            Some(v) if v.rel == rel => v.shown.clone(),
            _ => rel.to_owned(),
        }
    }
}

/// A `--set` as applied.
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    /// The `--set` value as typed.
    pub spec: String,
    /// The file, relative to the replay's configuration directory.
    pub rel: String,
    /// The file as the user knows it (`controllers.toml`, `drive/vehicle.toml
    /// (the drive's --vehicle, from the log)`).
    pub shown: String,
    /// The key's dotted path as typed (`mfc.k_mfc`, `controller`,
    /// `road[snow].c1`).
    pub path: String,
    /// The value written.
    pub value: toml::Value,
    /// The change, one line of the report (`FILE: [SECTION] KEY old -> new`).
    pub line: String,
    /// The key's dotted path with array elements by index (`road[2].c1`):
    /// the same key however `--set` named it.
    pub key: String,
}

/// One part of a `--set` key path: a key, and for an array of tables
/// (`[[road]]`) which element: `road[snow]` (its `name`) or `road[2]`.
#[derive(Debug, Clone, PartialEq)]
struct Seg {
    name: String,
    sel: Option<String>,
}

impl std::fmt::Display for Seg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.sel {
            Some(s) => write!(f, "{}[{s}]", self.name),
            None => f.write_str(&self.name),
        }
    }
}

fn parse_path(p: &str) -> Option<Vec<Seg>> {
    p.split('.')
        .map(|part| {
            let part = part.trim();
            let (name, sel) = match part.split_once('[') {
                Some((n, rest)) => (n, Some(rest.strip_suffix(']')?.trim().to_owned())),
                None => (part, None),
            };
            (!name.is_empty()
                && !name.contains([']', ' '])
                && sel.as_ref().is_none_or(|s| !s.is_empty()))
            .then(|| Seg {
                name: name.to_owned(),
                sel,
            })
        })
        .collect()
}

/// Which element of an array of tables `sel` names: an index, or the
/// element whose `name` it is (its index in the whole array, elements
/// without a name included, not among the named ones).
fn element_index(a: &[toml::Value], sel: &str) -> Option<usize> {
    match sel.parse::<usize>() {
        Ok(i) => Some(i).filter(|&i| i < a.len()),
        Err(_) => a
            .iter()
            .position(|e| e.get("name").and_then(toml::Value::as_str) == Some(sel)),
    }
}

/// `segs` with every array element by its index (`road[snow].c1` is
/// `road[2].c1` where snow is the third road): one key however it was
/// named, for `--set`'s once-per-key rule.
fn canonical_path(doc: &toml::Table, segs: &[Seg]) -> String {
    let mut t = Some(doc);
    let mut parts = Vec::new();
    for s in segs {
        let v = t.and_then(|t| t.get(&s.name));
        match (&s.sel, v) {
            (Some(sel), Some(toml::Value::Array(a))) => {
                let i = element_index(a, sel);
                parts.push(i.map_or_else(|| s.to_string(), |i| format!("{}[{i}]", s.name)));
                t = i.and_then(|i| a[i].as_table());
            }
            (_, v) => {
                parts.push(s.to_string());
                t = v.and_then(toml::Value::as_table);
            }
        }
    }
    parts.join(".")
}

/// The table `segs` leads to in `t`, or why there is none.
fn table_at<'a>(mut t: &'a mut toml::Table, segs: &[Seg]) -> Result<&'a mut toml::Table, String> {
    for s in segs {
        let v = t
            .get_mut(&s.name)
            .ok_or_else(|| format!("no [{}]", s.name))?;
        t = match (&s.sel, v) {
            (None, toml::Value::Table(x)) => x,
            (None, toml::Value::Array(_)) => {
                return Err(format!(
                    "{} is an array of tables: name the element, {}[NAME] or {}[INDEX]",
                    s.name, s.name, s.name
                ));
            }
            (Some(sel), toml::Value::Array(a)) => {
                let names: Vec<String> = a
                    .iter()
                    .filter_map(|e| e.get("name").and_then(toml::Value::as_str))
                    .map(str::to_owned)
                    .collect();
                let n = a.len();
                let i = element_index(a, sel);
                let Some(i) = i else {
                    return Err(if names.is_empty() {
                        format!(
                            "no {}[{sel}] ({n} of them, 0 to {})",
                            s.name,
                            n.saturating_sub(1)
                        )
                    } else {
                        format!("no {}[{sel}] (its names: {})", s.name, names.join(", "))
                    });
                };
                a[i].as_table_mut()
                    .ok_or_else(|| format!("{}[{sel}] is not a table", s.name))?
            }
            (_, v) => {
                return Err(format!("{s} is {}, not a table", type_name(v)));
            }
        };
    }
    Ok(t)
}

fn type_name(v: &toml::Value) -> &'static str {
    match v {
        toml::Value::String(_) => "a string",
        toml::Value::Integer(_) => "an integer",
        toml::Value::Float(_) => "a float",
        toml::Value::Boolean(_) => "a boolean",
        toml::Value::Datetime(_) => "a date-time",
        toml::Value::Array(_) => "an array",
        toml::Value::Table(_) => "a table",
    }
}

/// `raw` as a TOML value (`None`: TOML does not read it: a bare word, or a
/// number out of range).
fn toml_value(raw: &str) -> Option<toml::Value> {
    toml::from_str::<toml::Table>(&format!("v = {raw}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
}

/// Why `raw`, written as a number, is none a parameter can take: a float
/// that is not finite (`inf`, `nan`, or out of f64's range, `1e999`, which
/// TOML does not read at all), or an integer beyond i64's range; `None`
/// for anything else (`parsed`: [`toml_value`] of `raw`).
fn not_a_number(raw: &str, parsed: Option<&toml::Value>) -> Option<String> {
    match parsed {
        Some(toml::Value::Float(f)) if !f.is_finite() => {
            return Some(format!("{raw} is not a finite number"));
        }
        Some(_) => return None,
        None => {}
    }
    // written as a number: a sign, then a digit
    let digits = raw.trim_start_matches(['+', '-']);
    if !digits.starts_with(|c: char| c.is_ascii_digit()) {
        return None;
    }
    let plain: String = raw.chars().filter(|&c| c != '_').collect();
    let integer = !plain.contains(['.', 'e', 'E']);
    let digits_only = plain
        .trim_start_matches(['+', '-'])
        .chars()
        .all(|c| c.is_ascii_digit());
    if integer
        && digits_only
        && !plain
            .parse::<i128>()
            .is_ok_and(|i| i64::try_from(i).is_ok())
    {
        return Some(format!(
            "{raw} is out of the range of an integer ({} to {}); a float is written with a point or an exponent ({:e})",
            i64::MIN,
            i64::MAX,
            plain.parse::<f64>().unwrap_or(f64::NAN)
        ));
    }
    match plain.parse::<f64>() {
        Ok(f) if !f.is_finite() => Some(format!(
            "{raw} is out of f64's range (at most {:e} in magnitude): not a finite number",
            f64::MAX
        )),
        _ => None,
    }
}

/// `raw` as a value of `old`'s TOML type: a string key takes a bare word
/// (`controller=src`) or a quoted string; a float takes an integer
/// (`k_mfc=150` is 150.0); any other difference is refused, naming both
/// types.
fn typed(old: &toml::Value, raw: &str) -> Result<toml::Value, String> {
    let raw = raw.trim();
    let parsed = toml_value(raw);
    if let Some(why) = not_a_number(raw, parsed.as_ref())
        && !old.is_str()
    {
        return Err(why);
    }
    match (old, parsed) {
        (toml::Value::String(_), Some(v @ toml::Value::String(_))) => Ok(v),
        (toml::Value::String(_), _) => Ok(toml::Value::String(raw.to_owned())),
        (toml::Value::Float(_), Some(toml::Value::Integer(i))) => Ok(toml::Value::Float(i as f64)),
        (toml::Value::Table(_), _) => Err(
            "the key is a table: set its keys one by one (--set FILE:SECTION.TABLE.KEY=VALUE)"
                .into(),
        ),
        (o, Some(v)) if std::mem::discriminant(o) == std::mem::discriminant(&v) => Ok(v),
        (o, Some(v)) => Err(format!(
            "{raw} is {}, but the key is {} ({o} in the file)",
            type_name(&v),
            type_name(o)
        )),
        // a bare word (`on`) is a string to TOML's eyes
        (o, None) => Err(format!(
            "{raw} is a string (a bare word), but the key is {} ({o} in the file{})",
            type_name(o),
            if o.is_bool() { "; true or false" } else { "" }
        )),
    }
}

/// A key that `rel` (controllers.toml or the replay's vehicle file, named
/// by `--set FILE:`) leaves out, so its service's default: set to `raw`
/// (a TOML value; a bare word is a string) with the tables on the way
/// made, if the file as changed still parses as its service reads it
/// (both refuse a key they do not know, naming the ones they do; a file
/// that does not parse as logged is an error). `None`: another file, or a
/// section with an array element, where the key's type is not known here.
fn left_out(
    dir: &Path,
    spec: &str,
    rel: &str,
    section: &[Seg],
    key: &str,
    raw: &str,
    reads: &Reads,
) -> anyhow::Result<Option<Applied>> {
    let vehicle_rel = reads.vehicle.as_ref().map_or("vehicle.toml", |v| &v.rel);
    let is_vehicle = rel == vehicle_rel;
    if !(rel == "controllers.toml" || is_vehicle) || section.iter().any(|s| s.sel.is_some()) {
        return Ok(None);
    }
    let shown = reads.shown(rel);
    let path = dir.join(rel);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("--set {spec}: reading {shown}"))?;
    let mut doc: toml::Table =
        toml::from_str(&text).with_context(|| format!("--set {spec}: parsing {shown}"))?;
    let mut t = &mut doc;
    for s in section {
        let v = t
            .entry(s.name.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let kind = type_name(v);
        t = v
            .as_table_mut()
            .with_context(|| format!("--set {spec}: {shown}'s {s} is {kind}, not a table"))?;
    }
    let raw = raw.trim();
    let parsed = toml_value(raw);
    if let Some(why) = not_a_number(raw, parsed.as_ref()) {
        bail!("--set {spec}: {why}");
    }
    let new = parsed.unwrap_or_else(|| toml::Value::String(raw.to_owned()));
    if new.is_table() {
        // as for a key the file has (`typed`): one key, one --set
        bail!(
            "--set {spec}: {raw} is a table: set its keys one by one (--set FILE:SECTION.TABLE.KEY=VALUE)"
        );
    }
    t.insert(key.to_owned(), new.clone());
    let changed = toml::to_string(&doc)?;
    // parsed as the service reads it, under the name the user knows
    let named = Path::new(&shown);
    let parse = |text: &str| {
        if is_vehicle {
            grip_config::vehicle::parse_vehicle_file(named, text).map(|_| ())
        } else {
            grip_config::controllers::parse_controllers(named, text).map(|_| ())
        }
    };
    // a file its service would not read as it stands says nothing of
    // the new key
    if let Err(e) = parse(&text) {
        bail!(
            "--set {spec}: {shown} leaves it out, and a key a file leaves out is taken only from a file its service reads, which this one, as logged, is not: {e}"
        );
    }
    // the line numbers are those of the copy as rewritten (comments and
    // layout gone), not of the file the user knows: left out
    parse(&changed).map_err(|e| {
        anyhow::anyhow!(
            "--set {spec}: {} (the key as set; {shown} leaves it out)",
            without_line(&e.to_string())
        )
    })?;
    std::fs::write(&path, changed)
        .with_context(|| format!("--set {spec}: writing the replay's copy of {shown}"))?;
    let where_ = section
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(".");
    let where_ = if where_.is_empty() {
        key.to_owned()
    } else {
        format!("[{where_}] {key}")
    };
    let mut dotted: Vec<String> = section.iter().map(ToString::to_string).collect();
    dotted.push(key.to_owned());
    let dotted = dotted.join(".");
    Ok(Some(Applied {
        spec: spec.to_owned(),
        line: format!("{shown}: {where_} (left out: the default) -> {new}"),
        rel: rel.to_owned(),
        shown,
        key: dotted.clone(),
        path: dotted,
        value: new,
    }))
}

/// A configuration error's text without its `line N: ` (a line of a
/// rewritten copy, which would point the user at the wrong line).
fn without_line(e: &str) -> String {
    match e.find(": line ") {
        Some(i) => {
            let rest = &e[i + 2..];
            match rest.find(": ") {
                Some(j) if rest[5..j].trim().parse::<u64>().is_ok() => {
                    format!("{}{}", &e[..i + 2], &rest[j + 2..])
                }
                _ => e.to_owned(),
            }
        }
        None => e.to_owned(),
    }
}

/// Applies `[FILE:]SECTION.KEY=VALUE` (or `[FILE:]KEY=VALUE`, a key
/// outside any table) to the one file of `dir` the replay reads whose
/// table SECTION has KEY (or to FILE), keeping the key's TOML type. A file
/// or key the replay does not read is refused with the reason ([`Reads`]).
pub fn set_key(dir: &Path, spec: &str, reads: &Reads) -> anyhow::Result<Applied> {
    let (lhs, value) = spec
        .split_once('=')
        .with_context(|| format!("--set {spec}: expected [FILE:]SECTION.KEY=VALUE"))?;
    let (file, path) = match lhs.split_once(':') {
        Some((f, p)) => (Some(f.trim()), p.trim()),
        None => (None, lhs.trim()),
    };
    let segs = parse_path(path).with_context(|| {
        format!(
            "--set {spec}: expected [FILE:]SECTION.KEY=VALUE, or [FILE:]KEY=VALUE for a key outside any table (a part of {path:?} is empty)"
        )
    })?;
    let (key, section) = segs.split_last().context("empty key")?;
    if key.sel.is_some() {
        bail!(
            "--set {spec}: {key} is an element of an array of tables: set one of its keys ({key}.KEY=VALUE)"
        );
    }
    let key = key.name.as_str();
    let where_ = if section.is_empty() {
        key.to_owned()
    } else {
        format!(
            "[{}] {key}",
            section
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(".")
        )
    };
    let all = reads.files(dir)?;
    let files: Vec<String> = match file {
        Some(f) => {
            let named = reads
                .vehicle
                .as_ref()
                .filter(|v| v.names.iter().any(|n| n == f))
                .map(|v| v.rel.clone())
                .or_else(|| all.iter().find(|x| *x == f).cloned());
            match named {
                Some(r) => vec![r],
                // a relative name of a file of the replay's copy that the
                // replay does not read (vehicles/..., scenarios/...)
                None if safe_name(f) && dir.join(f).is_file() => vec![f.to_owned()],
                // a plain file name of the configuration directory: an
                // absolute path or one with `..` would rewrite a file outside
                // the copy the replay reads (the user's own, its comments and
                // layout lost)
                None if !safe_name(f) || f.contains(['/', '\\']) => bail!(
                    "--set {spec}: FILE {f:?} is not a file name of the configuration directory: the replay changes its own copy of the configuration, never a file elsewhere; name the file alone (--set {}:{path}={value})",
                    Path::new(f)
                        .file_name()
                        .map_or("controllers.toml".into(), |n| n.to_string_lossy())
                ),
                None => bail!(
                    "--set {spec}: the replay's configuration has no {f} (its files: {})",
                    all.iter()
                        .map(|x| reads.shown(x))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            }
        }
        None => all.clone(),
    };
    // every file with the key: those the replay reads, and those it does not, with why
    let mut hits = Vec::new();
    let mut unread = Vec::new();
    let mut missing: Vec<(bool, String)> = Vec::new();
    for f in &files {
        let p = dir.join(f);
        let shown = reads.shown(f);
        let text = std::fs::read_to_string(&p)
            .with_context(|| format!("--set {spec}: reading {shown}"))?;
        let mut doc: toml::Table =
            toml::from_str(&text).with_context(|| format!("--set {spec}: parsing {shown}"))?;
        // a named file the replay does not read is refused as such, the
        // key there or not
        if file.is_some()
            && let Some(why) = reads.unread(f, &segs)
        {
            unread.push((shown, why));
            continue;
        }
        // the file has the section's first table: how near it came
        let near = section.first().is_some_and(|s| doc.contains_key(&s.name));
        match table_at(&mut doc, section) {
            Ok(t) if t.contains_key(key) => {}
            Ok(_) => {
                missing.push((near, format!("{shown} has no {where_}")));
                continue;
            }
            Err(why) => {
                missing.push((near, format!("{shown}: {why}")));
                continue;
            }
        }
        match reads.unread(f, &segs) {
            Some(why) => unread.push((shown, why)),
            None => hits.push((f.clone(), doc)),
        }
    }
    match hits.len() {
        1 => {}
        0 if !unread.is_empty() => bail!(
            "--set {spec}: the replay does not read {where_} of {}, so the change could have no effect: {}",
            unread
                .iter()
                .map(|(f, _)| f.as_str())
                .collect::<Vec<_>>()
                .join(" or "),
            unread
                .iter()
                .map(|(f, w)| if unread.len() > 1 {
                    format!("{f}: {w}")
                } else {
                    w.clone()
                })
                .collect::<Vec<_>>()
                .join("; ")
        ),
        0 if file.is_some()
            && let Some(a) = left_out(dir, spec, &files[0], section, key, value, reads)? =>
        {
            return Ok(a);
        }
        0 if file.is_some() => bail!(
            "--set {spec}: {}. --set changes a key the file has (one it leaves out takes the service's default, whose type is not known here; controllers.toml and the vehicle file take one they leave out)",
            missing
                .iter()
                .map(|(_, m)| m.as_str())
                .collect::<Vec<_>>()
                .join("; ")
        ),
        0 => bail!(
            "--set {spec}: no configuration file has {where_} (searched {}){}",
            files
                .iter()
                .map(|f| reads.shown(f))
                .collect::<Vec<_>>()
                .join(", "),
            missing
                .iter()
                .filter(|(near, _)| *near)
                .map(|(_, m)| format!("; {m}"))
                .collect::<String>()
        ),
        _ => bail!(
            "--set {spec}: {where_} is in {}, all read by the replay; name the file: --set FILE:{path}={}",
            hits.iter()
                .map(|(f, _)| reads.shown(f))
                .collect::<Vec<_>>()
                .join(" and "),
            value.trim()
        ),
    }
    let (rel, mut doc) = hits.remove(0);
    let canonical = canonical_path(&doc, &segs);
    let shown = reads.shown(&rel);
    let t = table_at(&mut doc, section).map_err(anyhow::Error::msg)?;
    let old = t.get(key).cloned().context("key vanished")?;
    let new = typed(&old, value)
        .map_err(|why| anyhow::anyhow!("--set {spec}: {shown}'s {where_}: {why}"))?;
    t.insert(key.to_owned(), new.clone());
    std::fs::write(dir.join(&rel), toml::to_string(&doc)?)
        .with_context(|| format!("--set {spec}: writing the replay's copy of {shown}"))?;
    let same = if old == new { " (unchanged)" } else { "" };
    Ok(Applied {
        spec: spec.to_owned(),
        line: format!("{shown}: {where_} {old} -> {new}{same}"),
        rel,
        shown,
        path: segs
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("."),
        key: canonical,
        value: new,
    })
}

impl ReplayConfig {
    /// An error of a service's start-up on this configuration in the
    /// user's terms: the files as named in the log's configuration (not the
    /// replay's temporary copy), and, when a `--set` changed the file at
    /// fault, that `--set` as typed first (the one whose key the service
    /// names, else every one on that file).
    pub fn explain(&self, e: anyhow::Error) -> anyhow::Error {
        let ce = e.chain().find_map(|c| {
            c.downcast_ref::<grip_config::ConfigError>()
                .or_else(|| match c.downcast_ref::<grip_arte_svc::ArteError>() {
                    Some(grip_arte_svc::ArteError::Config(x)) => Some(x),
                    _ => None,
                })
                .or_else(|| match c.downcast_ref::<grip_plant_sim::RunError>() {
                    Some(grip_plant_sim::RunError::Config(x)) => Some(x),
                    _ => None,
                })
        });
        let rel = ce.and_then(|c| c.file.strip_prefix(&self.dir).ok());
        let rel = rel.map(|r| r.to_string_lossy().into_owned());
        let on_file: Vec<&Applied> = self
            .applied
            .iter()
            .filter(|a| Some(&a.rel) == rel.as_ref())
            .collect();
        let (Some(ce), false) = (ce, on_file.is_empty()) else {
            // no ConfigError to read (a service's own error type): the
            // `--set`s on a file the message names, the one whose field it
            // names first
            let text = self.user_paths(&format!("{e:#}"));
            let names = |a: &&Applied| {
                text.contains(&format!("{}: ", a.shown))
                    || text.contains(&format!("{}: ", a.rel))
                    || a.value
                        .as_str()
                        .is_some_and(|v| !v.is_empty() && text.contains(v))
            };
            let on_file: Vec<&Applied> = self.applied.iter().filter(names).collect();
            let exact: Vec<&Applied> = on_file
                .iter()
                .copied()
                .filter(|a| text.contains(&format!("field `{}`", a.path)))
                .collect();
            let blame = if exact.is_empty() { on_file } else { exact };
            if blame.is_empty() {
                return anyhow::anyhow!(text);
            }
            let sets = blame
                .iter()
                .map(|a| format!("--set {}", a.spec))
                .collect::<Vec<_>>()
                .join(", ");
            return anyhow::anyhow!("{sets}: {text}");
        };
        let field = ce.field.as_str();
        let exact: Vec<&Applied> = on_file
            .iter()
            .copied()
            .filter(|a| {
                a.path == field
                    || field
                        .strip_prefix(a.path.as_str())
                        .is_some_and(|r| r.starts_with(['.', '[']))
                    || a.path
                        .strip_prefix(field)
                        .is_some_and(|r| r.starts_with(['.', '[']))
            })
            .collect();
        let blame = if exact.is_empty() { on_file } else { exact };
        let sets = blame
            .iter()
            .map(|a| format!("--set {}", a.spec))
            .collect::<Vec<_>>()
            .join(", ");
        let shown = &blame[0].shown;
        let reason = self.user_paths(&ce.reason);
        let what = if field.is_empty() {
            format!("{shown}: {reason}")
        } else {
            format!("{shown}: field `{field}`: {reason}")
        };
        anyhow::anyhow!(
            "{sets}: {what} (refused by {})",
            self.user_paths(&e.to_string())
        )
    }

    /// arte's refusal of a confidence calibration fitted for other
    /// `[stream]` settings (`--set arte-svc.toml:stream...`), which a
    /// replay's what-if runs anyway, as a warning in the log's words: the
    /// replay's temporary copy of the configuration is not named (it was,
    /// in the file, the model and `grip calibrate --model` hint), and the
    /// model's origin is said: `--model`, a file of the replay's
    /// configuration (the log's attachments, or `--config-dir`'s), or the
    /// path `arte-svc.toml` names outside it.
    pub fn calibration_warning(&self, e: &grip_arte_svc::ArteError) -> String {
        let model_path = match e {
            grip_arte_svc::ArteError::CalibrationMismatch { model_path, .. } => Some(model_path),
            _ => None,
        };
        let origin = match (&self.model, model_path) {
            (Some(m), _) => format!("--model {}", m.display()),
            (None, Some(p)) => match p.strip_prefix(&self.dir) {
                Ok(rel) if self.source.ends_with("(--config-dir)") => format!(
                    "{} of the replay's configuration, copied from {}",
                    rel.display(),
                    self.source
                ),
                Ok(rel) => format!(
                    "{} of the replay's configuration, the log's attachment (the file of that name in the drive's configuration directory)",
                    rel.display()
                ),
                Err(_) => format!("{}, as arte-svc.toml names it", p.display()),
            },
            (None, None) => "arte-svc.toml's".to_owned(),
        };
        format!(
            "warning: {} (the replay runs anyway, the arte service refuses this; the model is {origin})",
            self.user_paths(&e.to_string()),
        )
    }

    /// `text` with the replay's temporary configuration directory taken
    /// out: its files as named in the log's configuration, a copied
    /// `--vehicle` as given.
    pub fn user_paths(&self, text: &str) -> String {
        let mut t = text.to_owned();
        for (p, shown) in &self.shown_paths {
            t = t.replace(&p.display().to_string(), shown);
        }
        let d = self.dir.display().to_string();
        t.replace(&format!("{d}/"), "")
            .replace(&d, "the replay's configuration")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A controllers file that leaves out a key with an older rule is
    /// named as the log's (not the temporary copy's) with the `--set` that
    /// replays with the shipped value, and the services' line about the
    /// copy is not said again; the shipped file gets no note.
    #[test]
    fn a_key_the_logs_controllers_leave_out_is_named_with_its_set() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/controllers.toml");
        let text = std::fs::read_to_string(&shipped).unwrap();
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("controllers.toml"), &text).unwrap();
        assert_eq!(
            old_rules_note(d.path(), "drive.mcap's controllers.toml"),
            None
        );
        let without: String = text
            .lines()
            .filter(|l| !l.trim_start().starts_with("approach_hold"))
            .map(|l| format!("{l}\n"))
            .collect();
        assert_ne!(without, text, "the shipped file sets approach_hold");
        let path = d.path().join("controllers.toml");
        std::fs::write(&path, &without).unwrap();
        let note = old_rules_note(d.path(), "drive.mcap's controllers.toml").unwrap();
        assert!(
            note.starts_with(
                "note: drive.mcap's controllers.toml leaves out preview.approach_hold:"
            ),
            "{note}"
        );
        assert!(note.contains("--set preview.approach_hold=1.1"), "{note}");
        assert!(!note.contains(&d.path().display().to_string()), "{note}");
        let c = grip_config::parse_controllers(&path, &without).unwrap();
        let generic = grip_config::controllers::old_rule_warning(&path, &without, &c).unwrap();
        assert!(
            !grip_config::first_time(&generic),
            "the copy's warning is marked as said"
        );
    }

    /// An element chosen by name is that element even where unnamed ones
    /// stand before it (the index was taken among the named ones).
    #[test]
    fn a_named_element_is_found_among_unnamed_ones() {
        let mut t: toml::Table =
            toml::from_str("[[road]]\nc1 = 1.0\n[[road]]\nname = \"snow\"\nc1 = 2.0\n").unwrap();
        let segs = parse_path("road[snow]").unwrap();
        let snow = table_at(&mut t, &segs).unwrap();
        assert_eq!(snow.get("c1").and_then(toml::Value::as_float), Some(2.0));
    }

    /// The drive's own model at another rate than the log's audio is
    /// replayed with a warning; a `--set` on arte's file (`arte-svc.toml`)
    /// makes it the replay's configuration, and the mismatch is refused.
    #[test]
    fn a_set_on_arte_svc_toml_is_not_the_drives_own_model() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let mut b = grip_msgs::AudioBlock::zeroed();
        b.sample_rate = 16_000;
        let log = DriveLog {
            path: "d.mcap".into(),
            audio_blocks: vec![b; 3],
            ..DriveLog::default()
        };
        let w = WhatIf::default();
        check_model_rate(&log, &w, &dir, &[]).unwrap();
        check_model_rate(
            &log,
            &w,
            &dir,
            &["controllers.toml: [mfc] k 1.0 -> 1.1".into()],
        )
        .unwrap();
        let e = check_model_rate(
            &log,
            &w,
            &dir,
            &["arte-svc.toml: [stream] hop_s 0.025 -> 0.05".into()],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("expects 44100 Hz audio") && e.contains("at 16000 Hz (3 of 3 blocks)"),
            "{e}"
        );
    }

    /// A key in one file the replay reads is found without naming the
    /// file; in two it must be named (the change says which file took it).
    #[test]
    fn set_finds_the_one_file_or_asks_for_it() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(
            d.path().join("controllers.toml"),
            "[mfc]\nk = 1.0\n[loop]\nrate_hz = 1000.0\n",
        )
        .unwrap();
        std::fs::write(d.path().join("roads.toml"), "[loop]\nrate_hz = 5.0\n").unwrap();
        let r = Reads::default();
        let c = set_key(d.path(), "mfc.k=1.01", &r).unwrap();
        assert_eq!(c.line, "controllers.toml: [mfc] k 1.0 -> 1.01");
        let t = std::fs::read_to_string(d.path().join("controllers.toml")).unwrap();
        assert!(t.contains("k = 1.01"), "{t}");
        let e = set_key(d.path(), "loop.rate_hz=500", &r)
            .unwrap_err()
            .to_string();
        assert!(e.contains("controllers.toml and roads.toml"), "{e}");
        set_key(d.path(), "roads.toml:loop.rate_hz=500", &r).unwrap();
        let e = set_key(d.path(), "mfc.nope=1", &r).unwrap_err().to_string();
        assert!(e.contains("no configuration file has [mfc] nope"), "{e}");
        let e = set_key(d.path(), "controllers.toml:mfc.nope=1", &r)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("controllers.toml leaves it out, and a key a file leaves out is taken only from a file its service reads, which this one, as logged, is not: "),
            "{e}"
        );
        assert!(set_key(d.path(), "mfc.k", &r).is_err());
    }

    /// The reference drive's log, without its audio (the configuration
    /// is all `prepare` needs).
    fn reference() -> DriveLog {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
        DriveLog::load(&p).unwrap()
    }

    fn with_sets(sets: &[&str], closed_loop: bool) -> anyhow::Result<ReplayConfig> {
        let w = WhatIf {
            set: sets.iter().map(|s| (*s).to_owned()).collect(),
            closed_loop,
            ..WhatIf::default()
        };
        prepare(&reference(), &w)
    }

    /// The drive's own controller and ARTE switch given again are no
    /// change (a replay with `--model`, which asks for ARTE on, listed
    /// "ARTE in the controller on -> on"); another one is.
    #[test]
    fn the_drive_s_own_switches_are_no_change() {
        let log = reference();
        let logged_c = log.run["controller"].clone();
        let logged_a = log.run["arte"] == "on";
        let w = WhatIf {
            controller: Some(logged_c.clone()),
            arte: Some(logged_a),
            ..WhatIf::default()
        };
        let rc = prepare(&log, &w).unwrap();
        assert!(rc.changes.is_empty(), "{:?}", rc.changes);
        let other = if logged_c == "src" { "mfc" } else { "src" };
        let w = WhatIf {
            controller: Some(other.into()),
            arte: Some(!logged_a),
            ..WhatIf::default()
        };
        let rc = prepare(&log, &w).unwrap();
        assert_eq!(rc.changes.len(), 2, "{:?}", rc.changes);
    }

    /// `--set can.toml:dbc=FILE` in closed loop with a DBC the log does not
    /// carry (a newcomer's trial: "cannot be read", and where it was looked
    /// for not said): the user's file is copied in under its name and
    /// can.toml names that; a FILE found nowhere is refused naming it.
    #[test]
    fn a_dbc_of_the_user_s_is_brought_into_a_closed_loop_replay() {
        let d = tempfile::tempdir().unwrap();
        let mine = d.path().join("car.dbc");
        let shipped = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/inverter.dbc"),
        )
        .unwrap();
        let own = shipped.replacen("BO_ 256 ", "BO_ 385 ", 1);
        assert_ne!(own, shipped);
        std::fs::write(&mine, &own).unwrap();
        let spec = format!("can.toml:dbc={}", mine.display());
        let rc = with_sets(&[&spec], true).unwrap();
        assert_eq!(
            std::fs::read_to_string(rc.dir.join("car.dbc")).unwrap(),
            own
        );
        let can: toml::Table =
            toml::from_str(&std::fs::read_to_string(rc.dir.join("can.toml")).unwrap()).unwrap();
        assert_eq!(can["dbc"].as_str(), Some("car.dbc"));
        let line = &rc.applied[0].line;
        assert!(
            line.contains(&format!(
                "(the DBC {}, copied into the replay's configuration as car.dbc)",
                mine.display()
            )),
            "{line}"
        );
        // a name found nowhere
        let e = with_sets(&["can.toml:dbc=no_such.dbc"], true)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("can.toml's dbc names \"no_such.dbc\", which is neither a file of the replay's configuration nor a file from the current directory"),
            "{e}"
        );
        // the log's own DBC by its name: as before, nothing copied
        let rc = with_sets(&["can.toml:dbc=inverter.dbc"], true).unwrap();
        assert!(
            !rc.applied[0].line.contains("copied"),
            "{}",
            rc.applied[0].line
        );
    }

    /// Item 1: a value the service refuses is told as the `--set` typed,
    /// with the file as named in the log's configuration, the field and
    /// the reason, never the replay's temporary copy.
    #[test]
    fn a_refused_set_is_named_as_typed_not_by_the_temporary_copy() {
        for (spec, file, field) in [
            ("mfc.k_mfc=-5", "controllers.toml", "mfc.k_mfc"),
            (
                "preview.cap_share=7",
                "controllers.toml",
                "preview.cap_share",
            ),
            (
                "controllers.toml:mtte.alpha=2",
                "controllers.toml",
                "mtte.alpha",
            ),
        ] {
            let cfg = with_sets(&[spec], false).unwrap();
            let e = grip_tcs_loop::load(&grip_tcs_loop::Options {
                config: grip_io::service::ConfigArgs::in_dir(&cfg.dir),
                controller: None,
                arte: None,
                run_for_s: None,
                vehicle: cfg.vehicle.clone(),
            })
            .context("tcs-loop's configuration")
            .unwrap_err();
            let raw = format!("{e:#}");
            assert!(raw.contains(&cfg.dir.display().to_string()), "{raw}");
            let e = cfg.explain(e).to_string();
            assert!(
                e.starts_with(&format!("--set {spec}: {file}: field `{field}`: ")),
                "{e}"
            );
            assert!(!e.contains(&cfg.dir.display().to_string()), "{e}");
            assert!(e.ends_with("(refused by tcs-loop's configuration)"), "{e}");
        }
        // arte's start-up (its own error type), and an error a service
        // gives without a ConfigError (the bus timing against the DBC)
        let cfg = with_sets(&["arte-svc.toml:stream.hop_s=-1"], false).unwrap();
        let e = grip_arte_svc::prepare_with_clock(
            &grip_arte_svc::Options {
                config: grip_io::service::ConfigArgs::in_dir(&cfg.dir),
                model: None,
                run_for: None,
            },
            &crate::replay::ScriptClock::default(),
        )
        .map(|_| ())
        .context("arte's start-up")
        .unwrap_err();
        let e = cfg.explain(e).to_string();
        assert!(
            e.starts_with(
                "--set arte-svc.toml:stream.hop_s=-1: arte-svc.toml: field `stream.hop_s`: "
            ),
            "{e}"
        );
        // a calibration fitted for other stream settings: a warning in the
        // log's words (it named the temporary copy's files and model)
        let cfg = with_sets(&["arte-svc.toml:stream.hop_s=0.05"], false).unwrap();
        let clock = crate::replay::ScriptClock::default();
        let mut p = grip_arte_svc::prepare_with_clock(
            &grip_arte_svc::Options {
                config: grip_io::service::ConfigArgs::in_dir(&cfg.dir),
                model: None,
                run_for: None,
            },
            &clock,
        )
        .unwrap();
        let w = cfg.calibration_warning(&p.calibration_mismatch.take().unwrap());
        assert!(!w.contains(&cfg.dir.display().to_string()), "{w}");
        // the model's origin: --config-dir's copy, --model
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let warn_for = |w: WhatIf| {
            let cfg = prepare(&reference(), &w).unwrap();
            let mut p = grip_arte_svc::prepare_with_clock(
                &grip_arte_svc::Options {
                    config: grip_io::service::ConfigArgs::in_dir(&cfg.dir),
                    model: cfg.model.clone(),
                    run_for: None,
                },
                &clock,
            )
            .unwrap();
            cfg.calibration_warning(&p.calibration_mismatch.take().unwrap())
        };
        let hop = vec!["arte-svc.toml:stream.hop_s=0.05".to_owned()];
        let c = warn_for(WhatIf {
            config_dir: Some(shipped.clone()),
            set: hop.clone(),
            ..WhatIf::default()
        });
        assert!(
            c.ends_with(&format!(
                "the model is models/default.model of the replay's configuration, copied from {} (--config-dir))",
                shipped.display()
            )),
            "{c}"
        );
        let m = shipped.join("models/default.model");
        let c = warn_for(WhatIf {
            model: Some(m.clone()),
            set: hop,
            ..WhatIf::default()
        });
        assert!(
            c.contains(&format!("--model {}", m.display()))
                && c.ends_with(&format!("the model is --model {})", m.display())),
            "{c}"
        );
        assert!(
            w.starts_with("warning: arte-svc.toml: field `stream.hop_s` = 0.05: ")
                && w.contains("`grip calibrate --model models/default.model ")
                && w.ends_with("the model is models/default.model of the replay's configuration, the log's attachment (the file of that name in the drive's configuration directory))"),
            "{w}"
        );
        let cfg = with_sets(&["loop.rate_hz=500"], false).unwrap();
        let e = anyhow::anyhow!(
            "{}: field `loop.rate_hz`: the DBC's period differs",
            cfg.dir.join("controllers.toml").display()
        );
        let e = cfg.explain(e).to_string();
        assert_eq!(
            e,
            "--set loop.rate_hz=500: controllers.toml: field `loop.rate_hz`: the DBC's period differs"
        );
    }

    /// Item 2: a file or key the replay does not read is refused with
    /// the reason; plant-sim's files and the vehicle's `[sensors]` are read
    /// in closed loop only.
    #[test]
    fn a_set_the_replay_cannot_read_is_refused_with_why() {
        for (spec, why) in [
            (
                "audio-acq.toml:audio.sample_rate=16000",
                "audio-acq is not re-run",
            ),
            (
                "recorder.toml:rt.fifo_priority=10",
                "the recorder is not re-run",
            ),
            (
                "tcs-loop.toml:rt.fifo_priority=10",
                "[rt] sets up the live service",
            ),
            (
                "arte-svc.toml:input.poll_interval_ms=1",
                "hands arte every block",
            ),
            (
                "plant-sim.toml:cmd_timeout_ms=30",
                "open-loop replay does not re-run",
            ),
            ("sensors.omega_noise_std=0.1", "plant-sim's sensor models"),
            ("can.toml:bus_id=1", "recorded frames as they were sent"),
            (
                "scenarios/e2e.toml:duration=2",
                "open-loop replay does not re-run",
            ),
        ] {
            let e = with_sets(&[spec], false).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("--set {spec}: the replay does not read "))
                    && e.contains(why),
                "{e}"
            );
        }
        // closed loop: plant-sim's own, but not what the replay decides
        let cfg = with_sets(
            &[
                "plant-sim.toml:cmd_timeout_ms=30",
                "sensors.omega_noise_std=0.1",
                "scenarios/e2e.toml:segment[1].road=ice",
            ],
            true,
        )
        .unwrap();
        assert!(
            cfg.changes
                .contains(&"scenarios/e2e.toml: [segment[1]] road \"snow\" -> \"ice\"".to_owned()),
            "{:?}",
            cfg.changes
        );
        for (spec, why) in [
            ("plant-sim.toml:seed=3", "the drive's seed"),
            ("plant-sim.toml:scenario=paper", "the drive's scenario"),
            ("can.toml:interface=can1", "in memory"),
            (
                "scenarios/paper.toml:duration=2",
                "the drive's scenario (scenarios/e2e.toml)",
            ),
        ] {
            let e = with_sets(&[spec], true).unwrap_err().to_string();
            assert!(e.contains("does not read") && e.contains(why), "{e}");
        }
    }

    /// A key controllers.toml or the vehicle file leaves out (its
    /// service's default) is set when the file is named, with the tables
    /// on the way made, if the file then parses as its service reads it:
    /// a typo or a bad value is refused naming the file and the field;
    /// without the file named it is still refused.
    #[test]
    fn a_left_out_key_of_controllers_or_the_vehicle_is_set_when_the_file_is_named() {
        let cfg = with_sets(
            &[
                "controllers.toml:preview.mfc.cap_share=0.9",
                "vehicle.toml:vehicle.r_ref=0.29",
            ],
            false,
        )
        .unwrap();
        let c: toml::Table =
            toml::from_str(&std::fs::read_to_string(cfg.dir.join("controllers.toml")).unwrap())
                .unwrap();
        assert_eq!(c["preview"]["mfc"]["cap_share"], toml::Value::Float(0.9));
        let v: toml::Table =
            toml::from_str(&std::fs::read_to_string(cfg.dir.join("vehicle.toml")).unwrap())
                .unwrap();
        assert_eq!(v["vehicle"]["r_ref"], toml::Value::Float(0.29));
        assert_eq!(
            cfg.changes,
            [
                "controllers.toml: [preview.mfc] cap_share (left out: the default) -> 0.9",
                "vehicle.toml: [vehicle] r_ref (left out: the default) -> 0.29",
            ]
        );
        for (spec, says) in [
            (
                "controllers.toml:preview.mfc.cap_shar=0.9",
                "--set controllers.toml:preview.mfc.cap_shar=0.9: controllers.toml: field `preview.mfc.cap_shar`",
            ),
            (
                "vehicle.toml:vehicle.r_ref=5",
                "--set vehicle.toml:vehicle.r_ref=5: vehicle.toml: field `vehicle.r_ref`",
            ),
            (
                "preview.mfc.cap_share=0.9",
                "--set preview.mfc.cap_share=0.9: no configuration file has [preview.mfc] cap_share",
            ),
            (
                "controllers.toml:preview.mfc={cap_share=0.9}",
                "--set controllers.toml:preview.mfc={cap_share=0.9}: {cap_share=0.9} is a table: set its keys one by one",
            ),
        ] {
            let e = format!("{:#}", with_sets(&[spec], false).unwrap_err());
            assert!(e.starts_with(says), "{spec}: {e}");
            // no line of the rewritten copy
            assert!(!e.contains(": line "), "{spec}: {e}");
        }
    }

    /// Item 3: a key outside any table (`FILE:KEY=VALUE`) keeps its TOML
    /// type; tcs-loop.toml's controller and arte are the replay's, as
    /// --controller and --arte; a value of another type is refused naming
    /// both types.
    #[test]
    fn a_top_level_key_is_set_with_its_type() {
        for spec in [
            "tcs-loop.toml:controller=src",
            "controller=src",
            "controller=\"src\"",
        ] {
            let cfg = with_sets(&[spec], false).unwrap();
            assert_eq!(cfg.controller, "src");
            let t = std::fs::read_to_string(cfg.dir.join("tcs-loop.toml")).unwrap();
            let v: toml::Table = toml::from_str(&t).unwrap();
            assert_eq!(v["controller"], toml::Value::String("src".into()), "{t}");
            assert_eq!(
                cfg.changes,
                [
                    "tcs-loop.toml: controller mtte -> src (the replay's controller, as --controller src)"
                ]
            );
        }
        let cfg = with_sets(&["tcs-loop.toml:arte=false"], false).unwrap();
        assert!(!cfg.arte);
        let e = with_sets(&["tcs-loop.toml:arte=on"], false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("on is a string (a bare word), but the key is a boolean"),
            "{e}"
        );
        let e = with_sets(&["tcs-loop.toml:controller=pid"], false)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "--set tcs-loop.toml:controller=pid: tcs-loop.toml: field `controller`: "
            ),
            "{e}"
        );
        let w = WhatIf {
            controller: Some("mfc".into()),
            set: vec!["controller=src".into()],
            ..WhatIf::default()
        };
        let e = prepare(&reference(), &w).unwrap_err().to_string();
        assert!(
            e.contains("--controller mfc and --set controller=src"),
            "{e}"
        );
        // an integer where the file has a float is that float
        let cfg = with_sets(&["mfc.k_mfc=150"], false).unwrap();
        assert_eq!(
            cfg.changes,
            ["controllers.toml: [mfc] k_mfc 177.0 -> 150.0"]
        );
        let f = |old: &str, raw: &str| {
            let t: toml::Table = toml::from_str(&format!("v = {old}")).unwrap();
            typed(&t["v"], raw)
        };
        assert_eq!(f("1.0", "2"), Ok(toml::Value::Float(2.0)));
        assert_eq!(f("\"a\"", "3"), Ok(toml::Value::String("3".into())));
        assert_eq!(
            f("[1]", "[0, 1]").unwrap().as_array().map(Vec::len),
            Some(2)
        );
        let e = f("2", "2.5").unwrap_err();
        assert_eq!(
            e,
            "2.5 is a float, but the key is an integer (2 in the file)"
        );
        let e = f("true", "1").unwrap_err();
        assert!(
            e.contains("1 is an integer, but the key is a boolean"),
            "{e}"
        );
        // numbers TOML does not read, or no parameter takes, said so (not
        // "a bare word"); a string key keeps them as text
        let e = f("1.0", "1e999").unwrap_err();
        assert!(
            e.contains("1e999 is out of f64's range") && e.contains("not a finite number"),
            "{e}"
        );
        assert!(
            f("1.0", "-inf")
                .unwrap_err()
                .contains("-inf is not a finite number")
        );
        assert!(
            f("1.0", "nan")
                .unwrap_err()
                .contains("nan is not a finite number")
        );
        let e = f("2", "99999999999999999999").unwrap_err();
        assert!(e.contains("out of the range of an integer"), "{e}");
        assert!(f("2", "007").unwrap_err().contains("bare word"));
        assert_eq!(f("\"a\"", "1e999"), Ok(toml::Value::String("1e999".into())));
        let e = f("1.0", "fast").unwrap_err();
        assert!(
            e.contains("fast is a string (a bare word), but the key is a float"),
            "{e}"
        );
        assert!(
            f("{a = 1}", "1")
                .unwrap_err()
                .contains("set its keys one by one")
        );
    }

    /// Item 4: a nested table (`preview.src`) is not its parent; a road of
    /// roads.toml's array by name or index; the same key twice is refused;
    /// the vehicle is the file the replay reads (the drive's --vehicle, a
    /// copy of the replay's own --vehicle: the user's file untouched).
    #[test]
    fn nested_tables_arrays_repeats_and_the_vehicle() {
        let cfg = with_sets(&["preview.src.cap_share=0.5"], false).unwrap();
        let t: toml::Table =
            toml::from_str(&std::fs::read_to_string(cfg.dir.join("controllers.toml")).unwrap())
                .unwrap();
        assert_eq!(t["preview"]["src"]["cap_share"].as_float(), Some(0.5));
        assert_eq!(t["preview"]["cap_share"].as_float(), Some(1.0));
        for (spec, sel) in [
            ("roads.toml:road[snow].c1=0.15", "snow"),
            ("road[2].c1=0.15", "2"),
        ] {
            let cfg = with_sets(&[spec], false).unwrap();
            assert_eq!(
                cfg.changes,
                [format!("roads.toml: [road[{sel}]] c1 0.1946 -> 0.15")]
            );
        }
        let e = with_sets(&["road[snw].c1=1"], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("its names: asphalt, gravel, snow"), "{e}");
        let e = with_sets(&["mfc.k_mfc=100", "controllers.toml:mfc.k_mfc=120"], false)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "--set mfc.k_mfc=100 and --set controllers.toml:mfc.k_mfc=120: both set mfc.k_mfc"
            ),
            "{e}"
        );
        // one road by its name and by its index is one key
        let e = with_sets(&["road[snow].c1=0.15", "road[2].c1=0.16"], false)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "--set road[snow].c1=0.15 and --set road[2].c1=0.16: both set road[2].c1"
            ),
            "{e}"
        );
        with_sets(&["road[snow].c1=0.15", "road[1].c1=0.5"], false).unwrap();

        let user = tempfile::tempdir().unwrap();
        let mine = user.path().join("mine.toml");
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/vehicles/front-mic.toml"),
        )
        .unwrap();
        std::fs::write(&mine, &text).unwrap();
        let w = |set: &str| WhatIf {
            vehicle: Some(mine.clone()),
            set: vec![set.into()],
            ..WhatIf::default()
        };
        for spec in ["vehicle.mass=1500", "mine.toml:vehicle.mass=1500"] {
            let cfg = prepare(&reference(), &w(spec)).unwrap();
            let used = std::fs::read_to_string(cfg.vehicle.as_ref().unwrap()).unwrap();
            assert!(used.contains("mass = 1500.0"), "{used}");
            assert!(
                cfg.changes[1].starts_with("mine.toml (--vehicle "),
                "{:?}",
                cfg.changes
            );
        }
        let e = prepare(&reference(), &w("vehicle.toml:vehicle.mass=1500"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("the replay's vehicle is mine.toml"), "{e}");
        assert_eq!(std::fs::read_to_string(&mine).unwrap(), text);
    }

    /// A drive given `--scenario PATH` carries that file as
    /// `drive/scenario.toml`: the replay's plant runs the log's copy
    /// (wherever the replay runs, whatever the path holds now), a closed-loop
    /// `--set` may name it, and a copy whose hash is not `grip.run`'s is
    /// refused as damage.
    #[test]
    fn a_scenario_given_by_path_is_replayed_from_the_log_s_copy() {
        let mut log = reference();
        let text = std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenarios/e2e.toml"),
        )
        .unwrap();
        log.run.insert("scenario".into(), "gone/mine.toml".into());
        log.run.insert(
            format!("config.{SCENARIO_ATTACHMENT}"),
            grip_digest::sha256_hex(&text),
        );
        log.attachments
            .insert(SCENARIO_ATTACHMENT.into(), text.clone());
        let closed = |set: &[&str]| WhatIf {
            closed_loop: true,
            set: set.iter().map(|s| (*s).to_owned()).collect(),
            ..WhatIf::default()
        };
        let cfg = prepare(&log, &closed(&[])).unwrap();
        let f = cfg.scenario_file.clone().unwrap();
        assert!(f.starts_with(&cfg.dir), "{}", f.display());
        assert_eq!(std::fs::read(&f).unwrap(), text);
        let cfg = prepare(&log, &closed(&["drive/scenario.toml:duration=2"])).unwrap();
        let used = std::fs::read_to_string(cfg.scenario_file.as_ref().unwrap()).unwrap();
        assert!(used.contains("duration = 2"), "{used}");
        // without the attachment: the scenario grip.run names, as before
        assert_eq!(
            prepare(&reference(), &closed(&[])).unwrap().scenario_file,
            None
        );
        log.attachments
            .insert(SCENARIO_ATTACHMENT.into(), b"duration = 9".to_vec());
        let e = prepare(&log, &closed(&[])).unwrap_err().to_string();
        assert!(
            e.contains("drive/scenario.toml") && e.contains("damaged"),
            "{e}"
        );
    }

    /// `--set FILE:...` names a file of the replay's own configuration copy:
    /// a path (absolute, with `..` or a directory) is refused, naming the
    /// `--set` value and why, and the file it points at is not touched.
    #[test]
    fn set_refuses_a_file_outside_the_configuration_directory() {
        let cfg = tempfile::tempdir().unwrap();
        std::fs::write(cfg.path().join("controllers.toml"), "[mfc]\nk = 1.0\n").unwrap();
        let user = tempfile::tempdir().unwrap();
        let real = user.path().join("controllers.toml");
        let text = "# the user's own comment\n[mfc]\nk   =   1.0   # tuned\n";
        std::fs::write(&real, text).unwrap();
        let abs = format!("{}:mfc.k=1.2", real.display());
        let rel = format!(
            "{}:mfc.k=1.2",
            Path::new("..")
                .join(user.path().file_name().unwrap())
                .join("controllers.toml")
                .display()
        );
        for spec in [abs.as_str(), rel.as_str(), "sub/controllers.toml:mfc.k=1.2"] {
            let e = set_key(cfg.path(), spec, &Reads::default())
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!("--set {spec}")) && e.contains("not a file name"),
                "{e}"
            );
        }
        assert_eq!(std::fs::read_to_string(&real).unwrap(), text);
        let own = std::fs::read_to_string(cfg.path().join("controllers.toml")).unwrap();
        assert_eq!(own, "[mfc]\nk = 1.0\n");
    }
}
