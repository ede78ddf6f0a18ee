//! `grip replay LOG.mcap [--out NEW.mcap]`: the drive's logged inputs
//! through the services' own code (arte's `ArteLoop::on_block`, tcs-loop's
//! `TcsLoop::cycle`), with the drive's own configuration from the log, or
//! a what-if change; a per-topic comparison with the logged outputs, the
//! first divergence, and the controller's figures old against new. See
//! `replay/` for how the inputs are fed.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use grip_drive::summary::Measured;
use grip_drive::{DriveLog, LoadOptions, summarize};
use grip_io::service::ConfigArgs;
use grip_msgs::{CanFrame, CycleRecord, can_dir, topics};
use grip_physics::VehicleParams;

use super::Ctx;
use super::drive::{Controller, OnOff};
use crate::replay::compare::{self, TopicDiff};
use crate::replay::config::{ReplayConfig, WhatIf};
use crate::replay::{RoadMatch, ScriptClock, SpeedMatch, replay_arte, replay_tcs, split_can};

/// The text every report carries.
pub const OPEN_LOOP: &str = "open loop: the logged wheel speeds, vehicle speed and motor torque are replayed as recorded; they do not react to a replayed torque command";

/// The text of a closed-loop report.
pub const CLOSED_LOOP: &str = "closed loop: plant-sim's loop re-simulates the vehicle from the drive's scenario, seed and vehicle beside tcs-loop's, each cycle run when, and with the frames, the logged drive's ran (the plant from its first cycle and started when the live one started; each loop cycle drains what the logged one drained; in-memory bus, the logged clocks); ARTE's estimates are the drive's (what the microphone heard on the logged drive), handed over in the cycle the drive took them";

/// Fields carried over from the log, not recomputed: they measure the
/// machine, and the replay feeds them to the loop as inputs.
pub const CARRIED_OVER: &str = "carried over from the log as inputs (machine timing): CycleRecord.wakeup_latency_ns, compute_ns and deadline_misses (the tick and the clock's second reading), the TorqueCommand's stamp_ns (the loop's clock), RoadEstimate.stamp_ns (arte's clock)";

#[derive(clap::Args)]
pub struct Args {
    /// The drive log (from `grip drive` or the recorder service), or a
    /// directory of them.
    log: PathBuf,
    /// Write the replayed drive here (the same topics; ground truth and
    /// audio copied), a file in a folder that exists; with a directory of
    /// logs, a directory for them (created). An existing file is not
    /// overwritten unless `--force` is given (refused before any replay).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Overwrite existing `--out` files.
    #[arg(long)]
    force: bool,
    /// With a directory of logs: replays run in parallel (at least 1).
    #[arg(long, default_value_t = 1, value_parser = super::at_least_one())]
    jobs: usize,
    /// What if: tcs-loop runs this controller.
    #[arg(long, value_enum)]
    controller: Option<Controller>,
    /// What if: the controller uses ARTE's estimates (on) or not (off).
    #[arg(long, value_enum)]
    arte: Option<OnOff>,
    /// What if: a vehicle TOML for tcs-loop (the drive's, from the log, by default).
    #[arg(long)]
    vehicle: Option<PathBuf>,
    /// What if: arte runs this model file.
    #[arg(long)]
    model: Option<PathBuf>,
    /// What if: one parameter, `[FILE:]SECTION.KEY=VALUE` (e.g. `mfc.k_mfc=150`,
    /// `roads.toml:road[snow].c1=0.15`), or `[FILE:]KEY=VALUE` for a key outside
    /// any table (`tcs-loop.toml:controller=src`); the value keeps the key's TOML
    /// type; a file or key the replay does not read is refused; repeatable, once
    /// per key.
    #[arg(long = "set", value_name = "[FILE:]SECTION.KEY=VALUE")]
    set: Vec<String>,
    /// Exit with status 1 unless every replayed topic is identical to the log.
    #[arg(long)]
    check: bool,
    /// Re-simulate the plant (plant-sim's own loop, from the drive's
    /// scenario, seed and vehicle) in closed loop with tcs-loop, so that a
    /// what-if controller meets the consequences of its own torque.
    #[arg(long)]
    closed_loop: bool,
    /// Print one JSON object per log (JSON Lines) instead of the report:
    /// per-topic comparison, first divergence, old and new figures
    /// (`tools/grip/README.md`, "grip replay --json"); a log that cannot be
    /// replayed gives `status = "error"` and the reason.
    #[arg(long)]
    json: bool,
}

fn controller_name(c: Controller) -> &'static str {
    match c {
        Controller::Mfc => "mfc",
        Controller::Src => "src",
        Controller::Mtte => "mtte",
    }
}

/// The result of a replay.
pub struct Replayed {
    /// Per topic.
    pub diffs: Vec<TopicDiff>,
    /// The report.
    pub text: String,
    /// The machine-readable result (`--json`).
    pub json: serde_json::Value,
    /// arte's blocks not classified (refused for their rate, silent,
    /// clipped, at or after an overrun, stale), one line; `None` when every
    /// block was.
    pub not_classified: Option<String>,
}

/// The `--json` object of a log that could not be replayed.
fn error_json(path: &Path, e: &anyhow::Error) -> serde_json::Value {
    serde_json::json!({
        "file": path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned()),
        "path": path.display().to_string(),
        "status": "error",
        "reason": format!("{e:#}"),
    })
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    let what = WhatIf {
        controller: args.controller.map(|c| controller_name(c).to_owned()),
        arte: args.arte.map(|a| a == OnOff::On),
        config_dir: ctx.config_dir_given.then(|| ctx.config_dir.clone()),
        vehicle: args.vehicle.clone(),
        model: args.model.clone(),
        set: args.set.clone(),
        closed_loop: args.closed_loop,
    };
    if args.log.is_dir() {
        return replay_dir(&args, &what);
    }
    // an existing --out is refused before the replay (the log itself is
    // refused by `replay`, with or without --force)
    if let Some(o) = &args.out
        && !same_path(&args.log, o)
    {
        super::train::check_output_file("--out", o, args.force)?;
    }
    let r = match replay(&args.log, &what, args.out.as_deref(), args.closed_loop) {
        Ok(r) => r,
        Err(e) => {
            if args.json {
                println!("{}", error_json(&args.log, &e));
            }
            return Err(e);
        }
    };
    if args.json {
        println!("{}", r.json);
    } else {
        print!("{}", r.text);
    }
    if args.check && r.diffs.iter().any(|d| !d.identical()) {
        let first = r
            .diffs
            .iter()
            .find_map(|d| d.first.as_ref())
            .map_or_else(String::new, ToString::to_string);
        bail!("the replay differs from the log; first divergence: {first}");
    }
    Ok(())
}

/// `grip replay DIR [--jobs N]`: one line per log; a bad log is named with
/// its reason and does not stop the others.
fn replay_dir(args: &Args, what: &WhatIf) -> anyhow::Result<()> {
    let logs = crate::drive::many::logs_in(&args.log)?;
    if let Some(o) = &args.out {
        if same_path(&args.log, o) {
            bail!(
                "--out {} is the directory being replayed ({}): the replayed logs would overwrite the logs themselves; choose another directory",
                o.display(),
                args.log.display()
            );
        }
        if o.exists() && !o.is_dir() {
            bail!(
                "--out {}: is a file, not a directory; with a directory of logs, --out names a directory for the replayed logs",
                o.display()
            );
        }
        // the logs a replay would replace, refused before any replay
        let there: Vec<PathBuf> = logs
            .iter()
            .filter_map(|p| p.file_name().map(|n| o.join(n)))
            .filter(|p| std::fs::symlink_metadata(p).is_ok())
            .collect();
        if let Some(first) = there.first()
            && !args.force
        {
            bail!(
                "--out {}: {} of the {} replayed logs would replace a file already there (the first: {}); pass --force to overwrite them, or name another directory",
                o.display(),
                there.len(),
                logs.len(),
                first.display()
            );
        }
        std::fs::create_dir_all(o).with_context(|| format!("creating {}", o.display()))?;
    }
    let pb = crate::drive::many::bar(logs.len(), "replays");
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(vec![String::new(); logs.len()]);
    let failed = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|sc| {
        for _ in 0..args.jobs.clamp(1, logs.len()) {
            sc.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(p) = logs.get(i) else { break };
                    let name = p
                        .file_name()
                        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                    let out = args.out.as_ref().map(|o| o.join(&name));
                    let line = match replay(p, what, out.as_deref(), args.closed_loop) {
                        Ok(r) if args.json => {
                            if r.diffs.iter().any(|d| !d.identical()) {
                                failed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            }
                            r.json.to_string()
                        }
                        Err(e) if args.json => {
                            failed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            error_json(p, &e).to_string()
                        }
                        Ok(r) => {
                            let line = match r.diffs.iter().find_map(|d| d.first.as_ref()) {
                                None => format!("{name}: identical"),
                                Some(d) => {
                                    failed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                                    format!("{name}: DIFFERENT, first divergence: {d}")
                                }
                            };
                            match &r.not_classified {
                                Some(n) => format!("{line}; {n}"),
                                None => line,
                            }
                        }
                        Err(e) => {
                            failed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            pb.suspend(|| eprintln!("bad log {name}: {e:#}"));
                            format!("{name}: not replayed: {e:#}")
                        }
                    };
                    if let Ok(mut r) = results.lock() {
                        r[i] = line;
                    }
                    pb.inc(1);
                }
            });
        }
    });
    pb.finish_and_clear();
    let results = results.into_inner().unwrap_or_default();
    for l in &results {
        println!("{l}");
    }
    let n = failed.load(std::sync::atomic::Ordering::Relaxed);
    if args.json {
        if args.check && n > 0 {
            bail!("{n} of {} logs did not replay identically", results.len());
        }
        return Ok(());
    }
    println!(
        "{} logs, {n} not identical or not replayed ({OPEN_LOOP})",
        results.len()
    );
    if args.check && n > 0 {
        bail!("{n} of {} logs did not replay identically", results.len());
    }
    Ok(())
}

fn tx(frames: &[CanFrame]) -> Vec<CanFrame> {
    frames
        .iter()
        .copied()
        .filter(|f| f.direction == can_dir::TX)
        .collect()
}

/// The replayed sent frames as the log would have them: a log from before
/// 2026-12-07 wrote its sent frames on bus 0 whatever `can.toml`'s
/// `bus_id`, which the replayed loop now writes; when every logged sent
/// frame says 0 and a replayed one does not, the replayed ones are
/// compared at 0 (true: so done).
fn tx_as_logged(logged: &[CanFrame], replayed: &mut [CanFrame]) -> bool {
    let old = !logged.is_empty()
        && logged.iter().all(|f| f.bus == 0)
        && replayed.iter().any(|f| f.bus != 0);
    if old {
        for f in replayed.iter_mut() {
            f.bus = 0;
        }
    }
    old
}

fn rx(frames: &[CanFrame]) -> Vec<CanFrame> {
    frames
        .iter()
        .copied()
        .filter(|f| f.direction != can_dir::TX)
        .collect()
}

/// The `--json` keys of [`command_figures`], in its order.
const FIGURE_KEYS: [&str; 5] = [
    "mean_torque_cmd_nm",
    "max_torque_cmd_nm",
    "mean_torque_cut_nm",
    "arte_used_pct",
    "safe_cycles",
];

/// A finite number, else `null`.
fn json_num(x: f64) -> serde_json::Value {
    if x.is_finite() {
        serde_json::json!(x)
    } else {
        serde_json::Value::Null
    }
}

/// The cycles stamped in the scenario window `window` ([start, end) ns,
/// the summary's), or every cycle without one.
fn in_window(cycles: &[CycleRecord], window: Option<(u64, u64)>) -> Vec<CycleRecord> {
    match window {
        Some((a, b)) => cycles
            .iter()
            .filter(|c| (a..b).contains(&c.stamp_ns))
            .copied()
            .collect(),
        None => cycles.to_vec(),
    }
}

/// The summary's measured figures ([`grip_drive::summary::measured()`], what
/// `grip inspect` prints) of `cycles`, all of them counted (the caller
/// picks the window's).
fn measured_of(cycles: &[CycleRecord], vehicle: &VehicleParams) -> Measured {
    let log = DriveLog {
        cycles: cycles.to_vec(),
        ..DriveLog::default()
    };
    grip_drive::summary::measured(&log, vehicle, Some((0, u64::MAX)), None)
}

/// The controller's own figures of a set of cycles (open loop: the plant's
/// metrics cannot change). The mean command and the torque taken off the
/// demand are the summary's ([`Measured`]: time-weighted over the cycles,
/// each standing for the time to the next record, at most five periods,
/// the safe state's included; the cut is the mean of demand − command,
/// negative where the command exceeded the demand), so `grip replay` and
/// `grip inspect` give the same figure for the same log; `m` must be the
/// measured figures of `cycles`. NaN (none) where there is nothing to
/// compute from.
fn command_figures(cycles: &[CycleRecord], m: &Measured) -> Vec<(&'static str, f64)> {
    let max = cycles
        .iter()
        .filter(|c| c.safe_state == 0)
        .map(|c| c.torque_cmd)
        .fold(f64::NAN, f64::max);
    let used = if m.active_cycles > 0 {
        m.used_arte_cycles as f64 / m.active_cycles as f64
    } else {
        f64::NAN
    };
    vec![
        ("mean torque command, N m (time-weighted)", m.mean_cmd),
        ("max torque command, N m (active cycles)", max),
        (
            "mean torque taken off the demand, N m (time-weighted)",
            m.mean_withheld,
        ),
        ("cycles using ARTE, % (active cycles)", 100.0 * used),
        (
            "cycles in the safe state",
            cycles.iter().filter(|c| c.safe_state != 0).count() as f64,
        ),
    ]
}

/// `p` resolved (symbolic links, `..`) as far as it exists: a path that does
/// not exist yet (an output) is its parent's canonical path plus its name.
fn resolved(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            dir.canonicalize()
                .map_or_else(|_| p.to_path_buf(), |d| d.join(name))
        }
        _ => p.to_path_buf(),
    }
}

/// Whether `a` and `b` name the same file or directory (also through a
/// symbolic or hard link).
fn same_path(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt as _;
    if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b))
        && (x.dev(), x.ino()) == (y.dev(), y.ino())
    {
        return true;
    }
    resolved(a) == resolved(b)
}

/// The time the cycle records span, s: from the earliest stamp to the
/// latest (a log whose messages are out of time order gives its span, not
/// a wrapped difference of its first and last).
fn stamp_span_s(cycles: &[CycleRecord]) -> f64 {
    let lo = cycles.iter().map(|c| c.stamp_ns).min();
    let hi = cycles.iter().map(|c| c.stamp_ns).max();
    match (lo, hi) {
        (Some(a), Some(b)) => (b - a) as f64 * 1e-9,
        _ => 0.0,
    }
}

/// The report's ARTE accuracy row, old and new; `-` where nothing was
/// judged (a log without ground truth).
fn accuracy_row(
    old: &grip_drive::summary::ArteEval,
    new: &grip_drive::summary::ArteEval,
) -> String {
    let pct = |a: &grip_drive::summary::ArteEval| {
        if a.judged == 0 {
            "-".to_owned()
        } else {
            format!("{:.1}", 100.0 * a.accuracy())
        }
    };
    let whole = |a: &grip_drive::summary::ArteEval| {
        if a.log_judged == 0 {
            "-".to_owned()
        } else {
            format!("{:.1}", 100.0 * a.accuracy_whole_log())
        }
    };
    format!(
        "  {:<52} {:>12} {:>12}\n  {:<52} {:>12} {:>12}",
        "ARTE accuracy vs ground truth, % (scenario)",
        pct(old),
        pct(new),
        "ARTE accuracy vs ground truth, % (whole log)",
        whole(old),
        whole(new)
    )
}

/// tcs-loop's configuration as `cfg` makes it; an error names the file as
/// in the log's configuration, and the `--set` that made it, not the
/// replay's temporary copy.
fn tcs_config_of(cfg: &ReplayConfig) -> anyhow::Result<grip_tcs_loop::LoadedConfig> {
    let opts = grip_tcs_loop::Options {
        config: ConfigArgs::in_dir(&cfg.dir),
        controller: Some(
            cfg.controller
                .parse()
                .map_err(|e| anyhow::anyhow!("controller {}: {e}", cfg.controller))?,
        ),
        arte: Some(cfg.arte),
        run_for_s: None,
        vehicle: cfg.vehicle.clone(),
    };
    grip_tcs_loop::load(&opts)
        .context("tcs-loop's configuration")
        .map_err(|e| cfg.explain(e))
}

/// What the replay's tcs-loop ran with, into its `grip.replay` record
/// `meta`: `min_confidence` (its `[arte]` gate) and `vehicle` (the file
/// as given: `--vehicle`'s path, else the source's attachment, or
/// `--config-dir`'s `vehicle.toml`) with its `vehicle_sha256`, a `--set`
/// on it applied (and named in `vehicle_set`). Returns the vehicle file as an attachment
/// ([`grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT`]) when it is not the
/// source's (the log's other attachments are the source's). Nothing when
/// the configuration does not load (the replay has loaded it already).
fn ran_with(
    log: &DriveLog,
    what: &WhatIf,
    cfg: &ReplayConfig,
    meta: &mut BTreeMap<String, String>,
) -> Vec<(String, Vec<u8>)> {
    let Ok(loaded) = tcs_config_of(cfg) else {
        return Vec::new();
    };
    meta.insert(
        "min_confidence".into(),
        loaded.controllers.arte.min_confidence.to_string(),
    );
    let Ok(bytes) = std::fs::read(&loaded.vehicle_path) else {
        return Vec::new();
    };
    let shown = match (&what.vehicle, loaded.vehicle_path.strip_prefix(&cfg.dir)) {
        (Some(v), _) => v.display().to_string(),
        (None, Ok(rel)) => match &what.config_dir {
            Some(d) if rel == Path::new("vehicle.toml") => d.join(rel).display().to_string(),
            _ => rel.display().to_string(),
        },
        (None, Err(_)) => loaded.vehicle_path.display().to_string(),
    };
    // a `--set` on it: the file as given is not what ran
    let rel = loaded
        .vehicle_path
        .strip_prefix(&cfg.dir)
        .map(|r| r.display().to_string());
    let sets: Vec<&str> = cfg
        .applied
        .iter()
        .filter(|a| rel.as_deref() == Ok(a.rel.as_str()))
        .map(|a| a.spec.as_str())
        .collect();
    meta.insert("vehicle".into(), shown);
    if !sets.is_empty() {
        meta.insert(
            "vehicle_set".into(),
            format!("--set {}", sets.join(", --set ")),
        );
    }
    meta.insert("vehicle_sha256".into(), grip_digest::sha256_hex(&bytes));
    // the file the source drive's loop read (the replay's default)
    let source = log
        .attachments
        .get(grip_drive::plan::VEHICLE_ATTACHMENT)
        .or_else(|| log.attachments.get("vehicle.toml"));
    if source == Some(&bytes) {
        Vec::new()
    } else {
        vec![(
            grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT.to_owned(),
            bytes,
        )]
    }
}

/// tcs-loop as `cfg` makes it, and its loop period, ns.
fn tcs_loop_of(cfg: &ReplayConfig) -> anyhow::Result<(grip_tcs_loop::TcsLoop, u64)> {
    tcs_loop_with(cfg).map(|(lp, period, _)| (lp, period))
}

/// [`tcs_loop_of`], and the configuration it was built from.
fn tcs_loop_with(
    cfg: &ReplayConfig,
) -> anyhow::Result<(grip_tcs_loop::TcsLoop, u64, grip_tcs_loop::LoadedConfig)> {
    let loaded = tcs_config_of(cfg)?;
    let lp = grip_tcs_loop::build(&loaded)
        .context("tcs-loop's start-up")
        .map_err(|e| cfg.explain(e))?;
    let period_ns = (1e9 / loaded.controllers.loop_.rate_hz).round() as u64;
    Ok((lp, period_ns, loaded))
}

/// The warnings tcs-loop logs at its start about settings that do not
/// suit the vehicle ([`grip_tcs_loop::start_warnings`]: the controller's
/// gains, the ARTE variants' slip noise), with `grip sim`'s `warning: `
/// before each, for the loop the replay runs: the files as the log's
/// configuration names them (or `--vehicle` as given), never the replay's
/// temporary copy, and the `--set`s on the files they read after it.
fn start_warnings(
    cfg: &ReplayConfig,
    loaded: &grip_tcs_loop::LoadedConfig,
    lp: &grip_tcs_loop::TcsLoop,
) -> Vec<String> {
    let warnings = grip_tcs_loop::start_warnings(loaded, lp);
    if warnings.is_empty() {
        return warnings;
    }
    // the --sets on the files they read (MFC's bound also the roads'): the
    // files as the log names them are not what the replay ran
    let on = |p: &Path| p.strip_prefix(&cfg.dir).ok().map(Path::to_path_buf);
    let files = [
        on(&loaded.vehicle_path),
        on(&loaded.controllers_path),
        (lp.controller_kind() == grip_tcs::ControllerKind::Mfc)
            .then(|| PathBuf::from("roads.toml")),
    ];
    let sets: Vec<String> = cfg
        .applied
        .iter()
        .filter(|a| files.iter().flatten().any(|f| f == Path::new(&a.rel)))
        .map(|a| format!("--set {}", a.spec))
        .collect();
    let with = if sets.is_empty() {
        String::new()
    } else {
        format!(" (the replay's, with {})", sets.join(", "))
    };
    warnings
        .iter()
        .map(|w| format!("warning: {}{with}", cfg.user_paths(w)))
        .collect()
}

/// The configuration the search for a drive's start runs
/// (`grip_replay::plant_start`): the drive's own, from the log; where the
/// log does not hold all of it, with the `--config-dir`, `--vehicle` and
/// `--model` given (said in the report), never the other what-ifs.
fn own_config(log: &DriveLog, what: &WhatIf) -> anyhow::Result<(ReplayConfig, &'static str)> {
    let own = WhatIf {
        closed_loop: true,
        ..WhatIf::default()
    };
    match crate::replay::config::prepare(log, &own) {
        Ok(c) => Ok((c, "")),
        Err(e) if what.config_dir.is_some() || what.vehicle.is_some() || what.model.is_some() => {
            let given = WhatIf {
                config_dir: what.config_dir.clone(),
                vehicle: what.vehicle.clone(),
                model: what.model.clone(),
                ..own
            };
            crate::replay::config::prepare(log, &given)
                .map(|c| {
                    (
                        c,
                        " (the log does not hold all of the drive's configuration: tried with the --config-dir, --vehicle and --model given)",
                    )
                })
                .map_err(|e2| e2.context(format!("{e:#}")))
        }
        Err(e) => Err(e),
    }
}

/// Replays `log` with `what` changed (in closed loop with the plant if
/// `closed`); writes `out` if given.
pub fn replay(
    path: &Path,
    what: &WhatIf,
    out: Option<&Path>,
    closed: bool,
) -> anyhow::Result<Replayed> {
    if let Some(out) = out
        && same_path(path, out)
    {
        // the writer would truncate the log being replayed (its recorder
        // metadata is not rewritten: lost for good)
        bail!(
            "--out {} is the log being replayed ({}): writing it would destroy the original; choose another file",
            out.display(),
            path.display()
        );
    }
    let t0 = Instant::now();
    let log = crate::drive::load_log(path, LoadOptions { audio: true })?;
    if let Some(t) = &log.report.truncated {
        bail!(
            "{}: the log is incomplete ({t}); a replay needs every cycle",
            path.display()
        );
    }
    if log.cycles.is_empty() {
        bail!("{}: no cycle records: nothing to replay", path.display());
    }
    // a replay's output carries the source drive's configuration
    // (grip.run) beside the what-if it ran (grip.replay): replayed, it
    // would run the source's settings and report their difference as a
    // divergence
    if let Some(r) = grip_drive::summary::replay_of(&log) {
        let ran = [
            r.controller.as_deref().map(|c| format!("controller {c}")),
            r.arte.as_deref().map(|a| format!("ARTE {a}")),
            (!r.changes.is_empty()).then(|| format!("changes: {}", r.changes)),
        ]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join("; ");
        bail!(
            "{}: the output of `grip replay`, a {}{}: a replay runs a log's recorded configuration, which here is the source drive's, not the what-if it ran; replay the source drive {} with the same options instead",
            path.display(),
            r.headline(),
            if ran.is_empty() {
                String::new()
            } else {
                format!(" ({ran})")
            },
            r.source
        );
    }
    let t_load = t0.elapsed().as_secs_f64();
    let cfg: ReplayConfig = crate::replay::config::prepare(&log, what)?;
    let config = ConfigArgs::in_dir(&cfg.dir);

    // arte
    let t_setup = Instant::now();
    let clock = ScriptClock::default();
    let mut speed = SpeedMatch::default();
    let mut prepared = grip_arte_svc::prepare_with_clock(
        &grip_arte_svc::Options {
            config: config.clone(),
            model: cfg.model.clone(),
            run_for: None,
        },
        &clock,
    )
    .context("arte's start-up on the replay configuration")
    .map_err(|e| cfg.explain(e))?;
    if let Some(e) = prepared.calibration_mismatch.take() {
        eprintln!("{}", cfg.calibration_warning(&e));
    }
    let mut setup_s = t_setup.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let roads = replay_arte(&mut prepared.lp, &clock, &log, &mut speed);
    let t_arte = t1.elapsed().as_secs_f64();
    // arte's blocks not classified (its counters), for the report
    let (first, last) = crate::replay::arte_window(&log);
    let model_rate = prepared.lp.sample_rate();
    let not_classified = speed.blocks.line(last - first, Some(model_rate));

    // tcs-loop
    let t_setup = Instant::now();
    let (mut lp, period_ns, loaded) = tcs_loop_with(&cfg)?;
    // the loop's settings against the vehicle, as tcs-loop says them at
    // its start (the drive's forwards it; the candidates of the plant's
    // start below run the drive's own configuration and say nothing)
    for w in start_warnings(&cfg, &loaded, &lp) {
        eprintln!("{w}");
    }
    let mut start_line = None;
    let mut races_line = None;
    let mut races_json = serde_json::Value::Null;
    let can = split_can(&log)?;
    setup_s += t_setup.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let mut roadm = RoadMatch::default();
    let (outs, truth) = if closed {
        let scenario = log.run.get("scenario").cloned().with_context(|| {
            format!(
                "{}: no scenario in grip.run: --closed-loop needs a drive against plant-sim",
                path.display()
            )
        })?;
        // the plant's schedule (its cycles' stamps) is read from the ground
        // truth: without it there is no time line to replay the plant on
        anyhow::ensure!(
            !log.truth.is_empty(),
            "{}: no ground truth (grip/plant/truth) in the log: --closed-loop replays plant-sim's cycles as the drive ran them, which the ground truth records (a drive on a car has none: replay it open loop)",
            path.display()
        );
        let seed = log.run.get("seed").and_then(|s| s.parse().ok());
        let plant_of = |cfg: &ReplayConfig| {
            grip_plant_sim::run::load(&grip_plant_sim::Options {
                config: ConfigArgs::in_dir(&cfg.dir),
                scenario: Some(
                    cfg.scenario_file
                        .as_ref()
                        .map_or_else(|| scenario.clone(), |f| f.display().to_string()),
                ),
                seed,
                exit_at_end: true,
                start_on: Some(grip_plant_sim::StartOn::Signal),
                vehicle: cfg.vehicle.clone(),
            })
            .map(|(_, plant, _)| plant)
            .context("plant-sim's start-up on the replay configuration")
            .map_err(|e| cfg.explain(e))
        };
        let mut plant = plant_of(&cfg)?;
        // where the live plant started: from rest, found by trying the
        // candidates with the drive's own configuration and estimates (made
        // only when there is a search)
        let mut own: Option<(ReplayConfig, &str)> = None;
        // the plant cycles from the scenario's start to its first demand
        let sc = plant.scenario();
        let dt = period_ns as f64 * 1e-9;
        let demand_after = sc
            .demand
            .begins(sc.duration, dt)
            .map_or(0, |t| (t / dt).round() as u64);
        // each candidate is a closed loop over the drive: a spinner with
        // the count and the time (nothing is drawn when stderr is not a
        // terminal); made on the first probe, gone with the search
        let mut bar: Option<indicatif::ProgressBar> = None;
        // the drive's own closed loop from plant cycle `start` with the
        // commands `early` placed in the plant cycle they raced, stopped at
        // the first truth sample that differs: what both searches run (the
        // drive's own configuration made at the first call, only when
        // there is a search)
        let mut probe = |start: Option<u64>, early: &BTreeSet<usize>| {
            if own.is_none() {
                own = Some(own_config(&log, what)?);
            }
            let Some((own, _)) = &own else {
                anyhow::bail!("the drive's own configuration was not made")
            };
            let (mut lp, own_period) = tcs_loop_of(own)?;
            let mut plant = plant_of(own)?;
            Ok(crate::replay::closed_loop(
                &mut lp, &mut plant, &log, &log.roads, own_period, start, true, early,
            ))
        };
        let start = crate::replay::plant_start(&log, demand_after, |c| {
            let b = bar.get_or_insert_with(|| {
                let b = indicatif::ProgressBar::new_spinner();
                b.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{spinner} plant start from rest: {pos} candidates tried ({msg}) {elapsed}",
                    )
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
                );
                b.enable_steady_tick(std::time::Duration::from_millis(200));
                b
            });
            b.set_message(format!("cycle {c}"));
            b.inc(1);
            Ok(probe(Some(c), &BTreeSet::new())?.agreed)
        });
        if let Some(b) = bar.take() {
            b.finish_and_clear();
        }
        // the commands that went out while the plant drained: placed by
        // the drive's own closed loop from the plant's start (only where
        // a command raced a drain)
        let races = crate::replay::command_races(&log, |early| probe(start.seq(), early));
        let with = own.as_ref().map_or("", |(_, w)| *w);
        start_line = Some((start.seq(), format!("{}{with}", start.line(period_ns))));
        races_line = races.line();
        races_json = serde_json::json!({
            "racing": races.racing,
            "early": races.early,
            "runs": races.runs,
            "not_placed": races.not_placed,
        });
        let cl = crate::replay::closed_loop(
            &mut lp,
            &mut plant,
            &log,
            &roads,
            period_ns,
            start.seq(),
            false,
            &races.early,
        );
        roadm = crate::replay::taken_per_cycle(&log).matched;
        (cl.outs, cl.truth)
    } else {
        (
            replay_tcs(&mut lp, &log, &can, &roads, &mut roadm),
            log.truth.clone(),
        )
    };
    let t_tcs = t2.elapsed().as_secs_f64();

    // compare
    // a log from before CycleRecord.road_taken carries 0 there, one from
    // before roads_taken 0 in that
    let ignore: &[&str] = if roadm.inferred > 0 {
        &["road_taken", "roads_taken"]
    } else if crate::replay::Taken::predates_count(&log) {
        &["roads_taken"]
    } else {
        &[]
    };
    let logged_tx = tx(&log.can);
    let mut replayed_tx = tx(&outs.can);
    let tx_bus_0 = tx_as_logged(&logged_tx, &mut replayed_tx);
    let diffs = vec![
        compare::compare(topics::ROAD, &log.roads, &roads),
        compare::compare_except(topics::CYCLE, &log.cycles, &outs.cycles, ignore),
        compare::compare("grip/can/log (tx)", &logged_tx, &replayed_tx),
        compare::compare("grip/can/log (rx)", &rx(&log.can), &rx(&outs.can)),
    ];
    let span_s = stamp_span_s(&log.cycles);

    let mut o = String::new();
    let _ = writeln!(o, "replay of {}", path.display());
    if closed {
        let _ = writeln!(o, "  {CLOSED_LOOP}");
        if let Some((_, l)) = &start_line {
            let _ = writeln!(o, "  {l}");
        }
        if let Some(l) = &races_line {
            let _ = writeln!(o, "  {l}");
        }
    } else {
        let _ = writeln!(o, "  {OPEN_LOOP}");
    }
    let _ = writeln!(o, "  configuration: {}", cfg.source);
    let _ = writeln!(
        o,
        "  tcs-loop: {} cycles through TcsLoop::cycle, controller {}, ARTE {}; arte: {} audio blocks through ArteLoop::on_block (of the log's {}: the recorder starts before arte and stops after it, so the blocks before arte's first frame and after its last estimate are not replayed)",
        log.cycles.len(),
        cfg.controller,
        if cfg.arte { "on" } else { "off" },
        last - first,
        log.audio_blocks.len()
    );
    if tx_bus_0 {
        let _ = writeln!(
            o,
            "  sent frames compared on bus 0: the log wrote them so (before 2026-12-07 tcs-loop logged its sent frames on bus 0 whatever can.toml's bus_id)"
        );
    }
    if cfg.changes.is_empty() {
        let _ = writeln!(o, "  changes: none (the drive's own configuration)");
    } else {
        for c in &cfg.changes {
            let _ = writeln!(o, "  change: {c}");
        }
    }
    let _ = writeln!(
        o,
        "  arte's speed input per block: {} found exactly, {} without speed, {} approximated",
        speed.exact, speed.none, speed.approximated
    );
    let _ = writeln!(
        o,
        "  tcs-loop's road input: {} estimates as the cycles recorded taking them (road_taken, roads_taken), {} inferred from stamps, {} not found",
        roadm.recorded, roadm.inferred, roadm.missing
    );
    let _ = writeln!(
        o,
        "  {}",
        not_classified
            .clone()
            .unwrap_or_else(|| format!("arte's blocks not classified, of {}: none", last - first))
    );
    if !closed {
        let _ = writeln!(o, "  {CARRIED_OVER}");
    }
    if !ignore.is_empty() {
        let _ = writeln!(
            o,
            "  the log predates CycleRecord.road_taken: not compared; which cycle took each estimate was inferred from the stamps (the live poll can race a stamp: a difference here may be the inference's)"
        );
    }
    if closed {
        let _ = writeln!(
            o,
            "\nper topic (field by field; in closed loop, with nothing changed, the drive's own cycles and frames are reproduced: a difference is the change's, or a schedule the log did not fully tell):"
        );
    } else {
        let _ = writeln!(o, "\nper topic (field by field, no tolerance):");
    }
    o.push_str(&compare::render(&diffs));
    match diffs.iter().find_map(|d| d.first.as_ref()) {
        None => {
            let _ = writeln!(
                o,
                "  first divergence: none; every replayed topic is identical"
            );
        }
        Some(d) => {
            let _ = writeln!(o, "  first divergence: {d}");
        }
    }

    // old vs new
    let mut new_log = DriveLog {
        cycles: outs.cycles.clone(),
        roads: roads.clone(),
        can: outs.can.clone(),
        truth: truth.clone(),
        ..log.clone()
    };
    new_log.audio_blocks.clear();
    let (vehicle, from, _) = grip_drive::vehicle_for(&log, &cfg.dir);
    let (s_old, s_new) = (
        summarize(&log, &vehicle, &from, None),
        summarize(&new_log, &vehicle, &from, None),
    );
    // every row over the scenario window (the summary's, as `grip inspect`
    // defines it), the whole log's labelled so
    let window_words = match (s_old.window, s_new.window) {
        (Some((a, b)), Some((c, d))) if closed => format!(
            "scenario: the cycles stamped in the scenario window, old {a:.3}-{b:.3} s, new {c:.3}-{d:.3} s of the truth stream, as grip inspect gives it"
        ),
        (Some((a, b)), _) => format!(
            "scenario: the cycles stamped in the scenario window, {a:.3}-{b:.3} s of the truth stream, as grip inspect gives it"
        ),
        _ => format!(
            "whole log: this log has no scenario window ({})",
            s_old
                .window_status
                .no_window_reason()
                .unwrap_or("no scenario window")
        ),
    };
    let scope = if s_old.window_ns.is_some() {
        "scenario"
    } else {
        "whole log"
    };
    let _ = writeln!(
        o,
        "\nold (logged) vs new (replayed), each row labelled with its window ({window_words}; whole log: start-up before the scenario and the stop after it included):"
    );
    let _ = writeln!(o, "  {:<52} {:>12} {:>12}", "figure", "old", "new");
    // the scenario's figures are the summary's measured ones (its window);
    // without a scenario window, those of every cycle
    let figures_in = |cycles: &[CycleRecord], s: &grip_drive::Summary| {
        let inw = in_window(cycles, s.window_ns);
        if s.window_ns.is_some() {
            command_figures(&inw, &s.measured)
        } else {
            command_figures(&inw, &measured_of(&inw, &vehicle))
        }
    };
    let num = |x: f64| {
        if x.is_finite() {
            format!("{x:.3}")
        } else {
            "-".to_owned()
        }
    };
    for ((name, a), (_, b)) in figures_in(&log.cycles, &s_old)
        .into_iter()
        .zip(figures_in(&outs.cycles, &s_new))
    {
        let name = match name.strip_suffix(')') {
            Some(n) => format!("{n}, {scope})"),
            None => format!("{name} ({scope})"),
        };
        let _ = writeln!(o, "  {name:<52} {:>12} {:>12}", num(a), num(b));
    }
    if s_old.window_ns.is_some() {
        let safe = |cycles: &[CycleRecord]| cycles.iter().filter(|c| c.safe_state != 0).count();
        let (a, b) = (safe(&log.cycles) as f64, safe(&outs.cycles) as f64);
        let _ = writeln!(
            o,
            "  {:<52} {a:>12.3} {b:>12.3}",
            "cycles in the safe state (whole log)"
        );
    }
    let _ = writeln!(o, "{}", accuracy_row(&s_old.arte, &s_new.arte));
    for (a, b) in s_old.arte.changes.iter().zip(&s_new.arte.changes) {
        let d = |x: Option<f64>| x.map_or("missed".to_owned(), |v| format!("{v:.3}"));
        let _ = writeln!(
            o,
            "  {:<52} {:>12} {:>12}",
            format!("detection delay {} -> {}, s", a.from, a.to),
            d(a.delay),
            d(b.delay)
        );
    }
    match (&s_old.metrics, &s_new.metrics) {
        (Some(a), Some(b)) if closed => {
            for (name, x, y) in [
                (
                    "slip deviation (1/T)∫|λ|dt",
                    a.slip_deviation,
                    b.slip_deviation,
                ),
                ("max torque, N m", a.max_torque, b.max_torque),
                ("torque effort, N m", a.torque_effort, b.torque_effort),
                ("mean acceleration, m/s²", a.mean_accel, b.mean_accel),
                ("distance, m", a.distance, b.distance),
                ("energy ∫Tω dt, J", a.energy, b.energy),
            ] {
                let rel = if x != 0.0 {
                    100.0 * (y - x) / x.abs()
                } else {
                    0.0
                };
                let _ = writeln!(o, "  {name:<52} {x:>12.4} {y:>12.4}  ({rel:+.1} %)");
            }
        }
        (Some(m), _) => {
            let _ = writeln!(
                o,
                "  plant metrics (ground truth) are the logged ones in open loop: slip deviation {:.4}, torque effort {:.2} N m, distance {:.2} m",
                m.slip_deviation, m.torque_effort, m.distance
            );
        }
        _ => {}
    }
    let replay_s = t_arte + t_tcs;
    let _ = writeln!(
        o,
        "\nspeed: {span_s:.2} s of drive; tcs-loop {t_tcs:.3} s ({:.0}x real time), arte {t_arte:.3} s ({:.0}x), together {:.0}x; log read in {t_load:.3} s, start-up (configuration, model) {setup_s:.3} s",
        span_s / t_tcs.max(1e-9),
        span_s / t_arte.max(1e-9),
        span_s / replay_s.max(1e-9)
    );

    let figures = |cycles: &[CycleRecord], s: &grip_drive::Summary| {
        let mut m = serde_json::Map::new();
        // without a suffix: the whole log (as `grip inspect --json`'s loop
        // figures); `_in_scenario`: the scenario window (null without one)
        for ((_, v), key) in command_figures(cycles, &measured_of(cycles, &vehicle))
            .into_iter()
            .zip(FIGURE_KEYS)
        {
            m.insert(key.into(), json_num(v));
        }
        for ((_, v), key) in figures_in(cycles, s).into_iter().zip(FIGURE_KEYS) {
            m.insert(
                format!("{key}_in_scenario"),
                if s.window_ns.is_some() {
                    json_num(v)
                } else {
                    serde_json::Value::Null
                },
            );
        }
        m.insert("arte_accuracy".into(), json_num(s.arte.accuracy()));
        m.insert(
            "arte_accuracy_whole_log".into(),
            json_num(s.arte.accuracy_whole_log()),
        );
        m.insert(
            "metrics".into(),
            s.metrics.as_ref().map_or(serde_json::Value::Null, |x| {
                serde_json::json!({
                    "slip_deviation": json_num(x.slip_deviation),
                    "max_torque_nm": json_num(x.max_torque),
                    "torque_effort_nm": json_num(x.torque_effort),
                    "mean_accel_ms2": json_num(x.mean_accel),
                    "distance_m": json_num(x.distance),
                    "energy_j": json_num(x.energy),
                })
            }),
        );
        serde_json::Value::Object(m)
    };
    let json = serde_json::json!({
        "file": path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned()),
        "path": path.display().to_string(),
        "status": "replayed",
        "mode": if closed { "closed loop" } else { "open loop" },
        "plant_metrics_replayed": closed,
        "plant_start": start_line.as_ref().map(|(seq, how)| serde_json::json!({"seq": seq, "how": how})),
        "command_races": races_json,
        "configuration": cfg.source,
        "controller": cfg.controller,
        "arte": if cfg.arte { "on" } else { "off" },
        "changes": cfg.changes,
        "identical": diffs.iter().all(TopicDiff::identical),
        "differing_messages": diffs.iter().map(|d| d.differing).sum::<usize>(),
        "first_divergence": diffs.iter().find_map(|d| d.first.as_ref()).map(ToString::to_string),
        "topics": diffs.iter().map(|d| serde_json::json!({
            "topic": d.topic,
            "logged": d.logged,
            "replayed": d.replayed,
            "differing": d.differing,
            "fields": d.fields.iter().map(|(f, n)| (f.clone(), serde_json::json!(n))).collect::<serde_json::Map<_, _>>(),
        })).collect::<Vec<_>>(),
        "speed_match": {"exact": speed.exact, "none": speed.none, "approximated": speed.approximated},
        "road_match": {"recorded": roadm.recorded, "inferred": roadm.inferred, "missing": roadm.missing},
        "blocks_not_classified": speed.blocks.json(last - first, model_rate),
        "old": figures(&log.cycles, &s_old),
        "new": figures(&outs.cycles, &s_new),
        "detection_delays": s_old.arte.changes.iter().zip(&s_new.arte.changes).map(|(a, b)| serde_json::json!({
            "from": a.from, "to": a.to,
            "old_s": a.delay.map_or(serde_json::Value::Null, json_num),
            "new_s": b.delay.map_or(serde_json::Value::Null, json_num),
        })).collect::<Vec<_>>(),
        "drive_s": json_num(span_s),
        "replay_s": json_num(replay_s),
    });

    if let Some(out) = out {
        let mut meta = BTreeMap::new();
        meta.insert("source".into(), path.display().to_string());
        meta.insert("configuration".into(), cfg.source.clone());
        meta.insert("changes".into(), cfg.changes.join("; "));
        meta.insert(
            "mode".into(),
            if closed { "closed loop" } else { "open loop" }.into(),
        );
        // what the replay ran (`grip.run`, copied, is the source's), and
        // whether the source was finished by its recorder
        meta.insert("controller".into(), cfg.controller.clone());
        meta.insert("arte".into(), if cfg.arte { "on" } else { "off" }.into());
        meta.insert(
            "source_recorder_finished".into(),
            log.recorder.is_some().to_string(),
        );
        // the model arte ran in the replay (`grip inspect` names it)
        if let Ok(m) = crate::drive::rates::arte_model(&cfg.dir, cfg.model.as_deref()) {
            let name = match m.path.strip_prefix(&cfg.dir) {
                Ok(rel) => rel.display().to_string(),
                Err(_) => m.path.display().to_string(),
            };
            meta.insert("model".into(), name);
            if let Ok(bytes) = std::fs::read(&m.path) {
                meta.insert("model_sha256".into(), grip_digest::sha256_hex(&bytes));
            }
        }
        meta.insert(
            "arte_blocks_not_classified".into(),
            not_classified.clone().unwrap_or_else(|| "none".into()),
        );
        // what the replay's tcs-loop ran with, which `grip.run` and the
        // attachments (the source's, copied) do not say when a `--set`,
        // `--vehicle` or `--config-dir` changed it: its confidence gate and
        // its vehicle file (attached when it is not the source's); `grip
        // inspect` reports these (`summary::gate_of`, `vehicle_for`)
        let extra = ran_with(&log, what, &cfg, &mut meta);
        crate::replay::write_log_with(
            out,
            &log,
            (&truth, &outs.cycles, &outs.can, &roads),
            &meta,
            &extra,
        )?;
        let _ = writeln!(o, "wrote {}", out.display());
    }
    Ok(Replayed {
        diffs,
        text: o,
        json,
        not_classified,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_drive::summary::ArteEval;

    /// A log whose sent frames all say bus 0 (before 2026-12-07, whatever
    /// `bus_id`) is compared with the replayed frames at 0; a log that
    /// carries the bus, or replayed frames on 0, are compared as they are.
    #[test]
    fn sent_frames_of_an_old_log_are_compared_on_bus_0() {
        let frame = |bus: u8| CanFrame {
            direction: can_dir::TX,
            bus,
            ..CanFrame::default()
        };
        let mut replayed = vec![frame(3), frame(3)];
        assert!(tx_as_logged(&[frame(0), frame(0)], &mut replayed));
        assert!(replayed.iter().all(|f| f.bus == 0));
        let mut replayed = vec![frame(3), frame(3)];
        assert!(!tx_as_logged(&[frame(3), frame(3)], &mut replayed));
        assert!(
            replayed.iter().all(|f| f.bus == 3),
            "a new log: as they are"
        );
        let mut replayed = vec![frame(0)];
        assert!(!tx_as_logged(&[frame(0)], &mut replayed));
        assert!(!tx_as_logged(&[], &mut [frame(3)]));
    }

    /// Blocks arte did not classify are in the report, not only on
    /// stderr: the text report, `--json` and the written log's
    /// `grip.replay` record count them (the reference drive with three
    /// blocks made silent and a capture overrun reported later on).
    #[test]
    fn blocks_arte_did_not_classify_are_in_the_report() {
        let reference =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
        let mut log = DriveLog::load_with(&reference, LoadOptions { audio: true }).unwrap();
        let (first, last) = crate::replay::arte_window(&log);
        assert!(last - first > 60, "{first}..{last}");
        for b in &mut log.audio_blocks[first + 10..first + 13] {
            b.samples.fill(0);
        }
        for b in &mut log.audio_blocks[first + 40..] {
            b.xruns += 1;
        }
        let d = tempfile::tempdir().unwrap();
        let bad = d.path().join("bad.mcap");
        crate::replay::write_log(
            &bad,
            &log,
            &log.truth,
            &log.cycles,
            &log.can,
            &log.roads,
            &BTreeMap::new(),
        )
        .unwrap();
        let out = d.path().join("replayed.mcap");
        let r = replay(&bad, &WhatIf::default(), Some(&out), false).unwrap();
        let j = &r.json["blocks_not_classified"];
        assert_eq!(j["blocks"], last - first, "{j}");
        assert_eq!(j["silent"], 3, "{j}");
        assert_eq!(j["clipped"], 0, "{j}");
        assert_eq!(j["rate_mismatch"], 0, "{j}");
        assert_eq!(j["model_rate_hz"], 44_100, "{j}");
        let xrun = j["xrun"].as_u64().unwrap();
        assert!(xrun > 5, "{j}");
        let line = format!(
            "arte's blocks not classified, of {}: 3 silent, {xrun} at or after a capture overrun",
            last - first
        );
        assert!(r.text.contains(&format!("\n  {line}\n")), "{}", r.text);
        assert_eq!(r.not_classified.as_deref(), Some(line.as_str()));
        let written = DriveLog::load(&out).unwrap();
        assert_eq!(
            written.metadata["grip.replay"]
                .get("arte_blocks_not_classified")
                .map(String::as_str),
            Some(line.as_str())
        );

        // the log as recorded: every block classified, said as such
        let r = replay(&reference, &WhatIf::default(), None, false).unwrap();
        assert!(
            r.text.contains(&format!(
                "\n  arte's blocks not classified, of {}: none\n",
                last - first
            )),
            "{}",
            r.text
        );
        assert_eq!(r.json["blocks_not_classified"]["silent"], 0);
        assert!(r.not_classified.is_none());
    }

    /// A log without ground truth judges nothing: the row says `-`, not NaN.
    #[test]
    fn accuracy_row_is_a_dash_when_nothing_was_judged() {
        let none = ArteEval {
            estimates: 12,
            ..ArteEval::default()
        };
        let row = accuracy_row(&none, &none);
        assert!(!row.contains("NaN"), "{row}");
        assert!(row.trim_end().ends_with("-            -"), "{row}");
        let judged = ArteEval {
            judged: 4,
            correct: 3,
            ..ArteEval::default()
        };
        let row = accuracy_row(&judged, &none);
        assert!(
            row.contains("75.0") && row.trim_end().ends_with('-'),
            "{row}"
        );
    }

    /// Cycle records out of time order: the span from the earliest to the
    /// latest stamp, not a wrapped (or, in debug, panicking) difference.
    #[test]
    fn the_span_of_cycles_out_of_time_order() {
        let c = |ms: u64| {
            let mut r = CycleRecord::zeroed();
            r.stamp_ns = ms * 1_000_000;
            r
        };
        let span = stamp_span_s(&[c(5), c(1), c(9), c(3)]);
        assert!((span - 0.008).abs() < 1e-12, "{span}");
        assert_eq!(stamp_span_s(&[]), 0.0);
    }

    /// An output that is the input, by another spelling, a symbolic link or
    /// a hard link, or in a directory given as `DIR/..`; one that does not
    /// exist yet is not.
    #[test]
    fn an_output_that_is_the_input_is_recognised() {
        let d = tempfile::tempdir().unwrap();
        let log = d.path().join("d.mcap");
        std::fs::write(&log, b"log").unwrap();
        std::fs::create_dir(d.path().join("sub")).unwrap();
        std::os::unix::fs::symlink(&log, d.path().join("link.mcap")).unwrap();
        std::fs::hard_link(&log, d.path().join("hard.mcap")).unwrap();
        for same in [
            "d.mcap",
            "sub/../d.mcap",
            "./d.mcap",
            "link.mcap",
            "hard.mcap",
        ] {
            assert!(same_path(&log, &d.path().join(same)), "{same}");
        }
        assert!(!same_path(&log, &d.path().join("new.mcap")));
        assert!(!same_path(&log, &d.path().join("sub/d.mcap")));
        assert!(same_path(d.path(), &d.path().join("sub/..")));
        assert!(!same_path(d.path(), &d.path().join("sub")));
    }
}
