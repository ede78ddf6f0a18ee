//! The configuration a replay runs with: by default the drive's own, from
//! the log (the recorder attaches every configuration file and model, with
//! their SHA-256 in `grip.run`; `grip drive` adds its `--vehicle` file as
//! `drive/vehicle.toml` and the controller and ARTE switch as metadata),
//! written to a temporary directory; the what-if options change it.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use grip_drive::DriveLog;
use grip_drive::plan::VEHICLE_ATTACHMENT;
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
    /// `--set [FILE:]SECTION.KEY=VALUE`.
    pub set: Vec<String>,
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
    /// The changes against the drive, one line each (empty: none).
    pub changes: Vec<String>,
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

/// Writes the log's configuration (or `--config-dir`'s) to a temporary
/// directory, checks it against the hashes in `grip.run`, and applies the
/// what-if options.
pub fn prepare(log: &DriveLog, w: &WhatIf) -> anyhow::Result<ReplayConfig> {
    let tmp = tempfile::tempdir().context("creating a temporary configuration directory")?;
    let dir = tmp.path().to_path_buf();
    let mut changes = Vec::new();
    let source = match &w.config_dir {
        Some(d) => {
            copy_dir(d, &dir)?;
            changes.push(format!("configuration directory {}", d.display()));
            keep_the_logs_bus(log, &dir, &mut changes)?;
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

    let own_controller = || -> Option<String> {
        let text = std::fs::read_to_string(dir.join("tcs-loop.toml")).ok()?;
        let v: toml::Value = toml::from_str(&text).ok()?;
        v.get("controller")?.as_str().map(str::to_owned)
    };
    let logged_controller = log.run.get("controller").cloned();
    let controller = match &w.controller {
        Some(c) => {
            changes.push(format!(
                "controller {} -> {c}",
                logged_controller.as_deref().unwrap_or("?")
            ));
            c.clone()
        }
        None => logged_controller
            .or_else(own_controller)
            .context("neither the log's grip.run nor tcs-loop.toml names the controller")?,
    };
    let logged_arte = log.run.get("arte").map(|a| a == "on");
    let arte = match w.arte {
        Some(a) => {
            changes.push(format!(
                "ARTE in the controller {} -> {}",
                logged_arte.map_or("?", |x| if x { "on" } else { "off" }),
                if a { "on" } else { "off" }
            ));
            a
        }
        None => match logged_arte {
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
    let vehicle = match &w.vehicle {
        Some(v) => {
            changes.push(format!("vehicle {}", v.display()));
            Some(v.clone())
        }
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
                Some(p)
            }
            (Some(v), None) => bail!(
                "{}: the drive ran with --vehicle {v}, which the log does not carry; pass --vehicle",
                log.path.display()
            ),
            (None, None) => None,
        },
    };
    if let Some(m) = &w.model {
        changes.push(format!("model {}", m.display()));
    }
    for s in &w.set {
        changes.push(set_key(&dir, s)?);
    }
    check_model_rate(log, w, &dir, &changes)?;
    Ok(ReplayConfig {
        dir,
        _tmp: tmp,
        source,
        controller,
        arte,
        vehicle,
        model: w.model.clone(),
        changes,
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

/// Applies `[FILE:]SECTION.KEY=VALUE` to the one TOML file of `dir` whose
/// table SECTION has KEY (or to FILE); VALUE is a TOML value (a bare word
/// is taken as a string). Returns the change as a line.
pub fn set_key(dir: &Path, spec: &str) -> anyhow::Result<String> {
    let (lhs, value) = spec
        .split_once('=')
        .with_context(|| format!("--set {spec}: expected [FILE:]SECTION.KEY=VALUE"))?;
    let (file, path) = match lhs.split_once(':') {
        Some((f, p)) => (Some(f.trim()), p.trim()),
        None => (None, lhs.trim()),
    };
    let (section, key) = path
        .rsplit_once('.')
        .with_context(|| format!("--set {spec}: expected SECTION.KEY before '='"))?;
    let new: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
        Ok(t) => t["v"].clone(),
        Err(_) => toml::Value::String(value.to_owned()),
    };
    let mut files: Vec<PathBuf> = match file {
        // a plain file name of the configuration directory: an absolute
        // path or one with `..` would rewrite a file outside the copy the
        // replay reads (the user's own, its comments and layout lost)
        Some(f) if !safe_name(f) || f.contains(['/', '\\']) => bail!(
            "--set {spec}: FILE {f:?} is not a file name of the configuration directory: the replay changes its own copy of the configuration, never a file elsewhere; name the file alone (--set {}:{path}={value})",
            Path::new(f)
                .file_name()
                .map_or("controllers.toml".into(), |n| n.to_string_lossy())
        ),
        Some(f) => vec![dir.join(f)],
        None => std::fs::read_dir(dir)?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect(),
    };
    files.sort();
    let mut hits = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f)
            .with_context(|| format!("--set: reading {}", f.display()))?;
        let doc: toml::Table =
            toml::from_str(&text).with_context(|| format!("--set: parsing {}", f.display()))?;
        let mut t = &doc;
        let mut found = true;
        for part in section.split('.') {
            match t.get(part).and_then(toml::Value::as_table) {
                Some(x) => t = x,
                None => {
                    found = false;
                    break;
                }
            }
        }
        if !found || !t.contains_key(key) {
            continue;
        }
        hits.push((f.clone(), doc));
    }
    let name = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    match hits.len() {
        0 => bail!(
            "--set {spec}: no configuration file has [{section}] {key} (searched {})",
            files.iter().map(|f| name(f)).collect::<Vec<_>>().join(", ")
        ),
        1 => {}
        _ => bail!(
            "--set {spec}: [{section}] {key} is in {}; name the file: --set FILE:{path}={value}",
            hits.iter()
                .map(|(f, _)| name(f))
                .collect::<Vec<_>>()
                .join(" and ")
        ),
    }
    let (f, mut doc) = hits.remove(0);
    let mut t = &mut doc;
    for part in section.split('.') {
        t = t
            .get_mut(part)
            .and_then(toml::Value::as_table_mut)
            .context("section vanished")?;
    }
    let old = t.insert(key.to_owned(), new.clone());
    std::fs::write(&f, toml::to_string(&doc)?)?;
    Ok(format!(
        "{}: [{section}] {key} {} -> {new}",
        name(&f),
        old.map_or("(unset)".into(), |o| o.to_string())
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn set_finds_the_one_file_or_asks_for_it() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(
            d.path().join("controllers.toml"),
            "[mfc]\nk = 1.0\n[loop]\nrate_hz = 1000.0\n",
        )
        .unwrap();
        std::fs::write(d.path().join("other.toml"), "[loop]\nrate_hz = 5.0\n").unwrap();
        let c = set_key(d.path(), "mfc.k=1.01").unwrap();
        assert!(c.contains("controllers.toml: [mfc] k 1.0 -> 1.01"), "{c}");
        let t = std::fs::read_to_string(d.path().join("controllers.toml")).unwrap();
        assert!(t.contains("k = 1.01"), "{t}");
        let e = set_key(d.path(), "loop.rate_hz=500")
            .unwrap_err()
            .to_string();
        assert!(e.contains("controllers.toml and other.toml"), "{e}");
        set_key(d.path(), "other.toml:loop.rate_hz=500").unwrap();
        let e = set_key(d.path(), "mfc.nope=1").unwrap_err().to_string();
        assert!(e.contains("no configuration file has [mfc] nope"), "{e}");
        assert!(set_key(d.path(), "mfc.k").is_err());
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
            let e = set_key(cfg.path(), spec).unwrap_err().to_string();
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
