//! Many drive logs at once: `grip inspect DIR` (one row per drive) and the
//! list of logs `grip replay DIR` works through. A log that cannot be read,
//! or is truncated or damaged, is a row that names it and the reason; it
//! never stops the others.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use grip_drive::DriveLog;
use grip_drive::summary::inverter::Flag;
use grip_drive::summary::measured::MeasuredWindow;
use grip_drive::summary::summarize_with_roads;

use crate::cmd::Ctx;

/// The `*.mcap` files of `dir`, sorted by name.
pub fn logs_in(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    v.sort();
    if v.is_empty() {
        bail!("{}: no .mcap files", dir.display());
    }
    Ok(v)
}

/// A progress bar over `n` logs on stderr.
pub fn bar(n: usize, what: &str) -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(n as u64);
    b.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{bar:40}} {{pos}}/{{len}} {what} {{elapsed_precise}}"
        ))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b
}

/// The table's columns (the loop's, the E2E and the ARTE figures are those
/// of the scenario window; `_whole_log` ones cover the whole log; the
/// run's controller, ARTE switch and seed are the summary's run entries,
/// as `grip inspect LOG` and `grip inspect A B` give them (`grip.run`, a
/// replay's own controller and ARTE switch), the vehicle what
/// [`grip_drive::vehicle_for`] found and the summary reports
/// ([`grip_drive::summary::Summary::vehicle`], `vehicle_sha256`,
/// `vehicle_params.mic_lead_m`), as `grip inspect --json` gives them; the
/// `measured_` ones and `spin_events` are what the loop measured, over
/// `measured_window`, [`grip_drive::summary::Measured`]; `control_lost` is
/// [`grip_drive::summary::ControlHealth::lost`], empty without a window;
/// the `inverter_` ones count the inverter's fault and derating episodes
/// from its `MotorStatus` frames, [`grip_drive::summary::Inverter`], those
/// overlapping the scenario window and over the whole log, empty without
/// `MotorStatus` frames; the `replay_` ones are a `grip replay --out`
/// log's source, mode and what-if changes, [`grip_drive::summary::ReplayInfo`],
/// empty for a drive's log). The vehicle, the seed and the replay come
/// after the whole log's figures, not beside the controller, and the
/// ground truth's mean acceleration, kinetic energy gain and command
/// variation (2026-12-08) after its energy: the first nine columns and the
/// last fourteen keep their places for readers that count them.
pub const COLUMNS: [&str; 51] = [
    "file",
    "status",
    "reason",
    "scenario",
    "controller",
    "arte",
    "cycles",
    "scenario_s",
    "slip_deviation",
    "max_torque_nm",
    "torque_effort_nm",
    "distance_m",
    "energy_j",
    "mean_accel_ms2",
    "kinetic_energy_gain_j",
    "cmd_tv_per_s",
    "arte_estimates",
    "arte_accuracy",
    "road_changes",
    "changes_missed",
    "mean_delay_s",
    "max_delay_s",
    "deadline_misses_in_scenario",
    "safe_cycles_in_scenario",
    "e2e_faults_in_scenario",
    "scenario_window",
    "safe_state_entries_in_scenario",
    "wakeup_max_ns_in_scenario",
    "deadline_misses_whole_log",
    "arte_accuracy_whole_log",
    "vehicle",
    "vehicle_sha256",
    "mic_lead_m",
    "seed",
    "replay_source",
    "replay_mode",
    "replay_changes",
    "measured_window",
    "measured_mean_abs_slip",
    "measured_p95_abs_slip",
    "measured_max_abs_slip",
    "measured_share_above_0_2",
    "spin_events",
    "measured_mean_accel_ms2",
    "measured_cmd_over_demand",
    "measured_withheld_nms",
    "control_lost",
    "inverter_faults_in_scenario",
    "inverter_faults_whole_log",
    "inverter_derating_in_scenario",
    "inverter_derating_whole_log",
];

/// The index of column `name` of [`COLUMNS`] (a name of this file's own:
/// panics on a typo, which every test that builds a row finds).
fn at(name: &str) -> usize {
    COLUMNS
        .iter()
        .position(|c| *c == name)
        .unwrap_or_else(|| panic!("no column {name}"))
}

/// Field `name` of a row.
fn field<'a>(r: &'a [String], name: &str) -> &'a str {
    &r[at(name)]
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        String::new()
    }
}

/// The file name of `path`, for the table.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// One row: the row and whether the log is good (a bad one's status and
/// reason say why).
pub fn row(path: &Path, config_dir: &Path) -> (Vec<String>, bool) {
    match DriveLog::load(path) {
        Ok(log) => row_of(file_name(path), &log, config_dir),
        Err(e) => {
            let mut r = vec![String::new(); COLUMNS.len()];
            r[at("file")] = file_name(path);
            r[at("status")] = "unreadable".into();
            r[at("reason")] = e.full();
            (r, false)
        }
    }
}

/// The row of a loaded log named `file`.
fn row_of(file: String, log: &DriveLog, config_dir: &Path) -> (Vec<String>, bool) {
    let mut r = vec![String::new(); COLUMNS.len()];
    let mut set = |name: &str, v: String| r[at(name)] = v;
    set("file", file);
    let (vehicle, from, _) = grip_drive::vehicle_for(log, config_dir);
    let roads = log.road_catalogue(config_dir);
    let s = summarize_with_roads(log, &vehicle, &from, &roads);
    let mut good = true;
    if let Some(t) = &log.report.truncated {
        set("status", "incomplete".into());
        set("reason", t.clone());
        good = false;
    } else if log.report.bad > 0 {
        set("status", "damaged".into());
        set(
            "reason",
            format!(
                "{} messages did not decode (first: {})",
                log.report.bad,
                log.report.first_error.as_deref().unwrap_or("?")
            ),
        );
        good = false;
    } else {
        set("status", "ok".into());
    }
    set(
        "scenario",
        log.run.get("scenario").cloned().unwrap_or_default(),
    );
    // the summary's run entries, as `grip inspect LOG` and `A B` show
    // them: a replay's own controller and ARTE switch (`grip.run` is its
    // source's)
    let run = |k: &str| {
        s.run
            .iter()
            .find(|(kk, _)| kk == k)
            .map_or_else(String::new, |(_, v)| v.clone())
    };
    set("controller", run("controller"));
    set("arte", run("arte"));
    set("seed", run("seed"));
    // the vehicle the summary used, as `grip inspect LOG` and `--json`
    // name it (`A B` compares them by SHA-256)
    set("vehicle", s.vehicle.clone());
    set(
        "vehicle_sha256",
        s.vehicle_sha256.clone().unwrap_or_default(),
    );
    set("mic_lead_m", num(s.vehicle_params.mic_lead_m));
    if let Some(rp) = &s.replay {
        set("replay_source", rp.source.clone());
        set("replay_mode", rp.mode.clone());
        set("replay_changes", rp.changes.clone());
    }
    set("cycles", s.timing.cycles.to_string());
    if let (Some(m), Some((a, b))) = (&s.metrics, s.window) {
        set("scenario_s", num(b - a));
        set("slip_deviation", num(m.slip_deviation));
        set("max_torque_nm", num(m.max_torque));
        set("torque_effort_nm", num(m.torque_effort));
        set("distance_m", num(m.distance));
        set("energy_j", num(m.energy));
        set("mean_accel_ms2", num(m.mean_accel));
        set("kinetic_energy_gain_j", num(m.kinetic_energy_gain));
        set("cmd_tv_per_s", num(m.cmd_tv_per_s));
    }
    set("arte_estimates", s.arte.estimates.to_string());
    set("arte_accuracy", num(s.arte.accuracy()));
    let delays: Vec<f64> = s.arte.changes.iter().filter_map(|c| c.delay).collect();
    set("road_changes", s.arte.changes.len().to_string());
    set(
        "changes_missed",
        (s.arte.changes.len() - delays.len()).to_string(),
    );
    if !delays.is_empty() {
        set(
            "mean_delay_s",
            num(delays.iter().sum::<f64>() / delays.len() as f64),
        );
        set(
            "max_delay_s",
            num(delays.iter().copied().fold(0.0, f64::max)),
        );
    }
    let in_scn = s.timing.in_scenario.as_ref();
    set(
        "deadline_misses_in_scenario",
        in_scn.map_or(String::new(), |w| w.deadline_misses.to_string()),
    );
    set(
        "safe_cycles_in_scenario",
        s.safe_cycles_in_window
            .map_or(String::new(), |n| n.to_string()),
    );
    set(
        "e2e_faults_in_scenario",
        s.can
            .faults_in_window
            .map_or(String::new(), |f| f.total().to_string()),
    );
    set("scenario_window", s.window_status.as_str().to_owned());
    set(
        "safe_state_entries_in_scenario",
        in_scn.map_or(String::new(), |w| w.safe_entries.to_string()),
    );
    set(
        "wakeup_max_ns_in_scenario",
        in_scn.map_or(String::new(), |w| w.wakeup.max.to_string()),
    );
    set(
        "deadline_misses_whole_log",
        s.timing.deadline_misses.to_string(),
    );
    set("arte_accuracy_whole_log", num(s.arte.accuracy_whole_log()));
    let m = &s.measured;
    set("measured_window", m.window.as_str().to_owned());
    if m.window != MeasuredWindow::NoCycles {
        set("measured_mean_abs_slip", num(m.mean_abs_slip));
        set("measured_p95_abs_slip", num(m.p95_abs_slip));
        set("measured_max_abs_slip", num(m.max_abs_slip));
        set("measured_share_above_0_2", num(m.share_above[1]));
        set("spin_events", m.spins.len().to_string());
        set("measured_mean_accel_ms2", num(m.mean_accel));
        set("measured_cmd_over_demand", num(m.delivered));
        set("measured_withheld_nms", num(m.withheld_nms));
    }
    set(
        "control_lost",
        s.control
            .as_ref()
            .map_or(String::new(), |c| c.lost().to_string()),
    );
    let inv = &s.inverter;
    if inv.frames > 0 {
        for (name, flag) in [("faults", Flag::Fault), ("derating", Flag::Derating)] {
            if let Some(f) = inv.flag(flag) {
                set(
                    &format!("inverter_{name}_in_scenario"),
                    f.in_scenario.map_or(String::new(), |(n, _)| n.to_string()),
                );
                set(&format!("inverter_{name}_whole_log"), f.count.to_string());
            }
        }
    }
    (r, good)
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// A CSV field as a number rounded to `decimals` for the text table (`-`
/// when empty); `scale` first (100 for a share printed as %).
fn rounded(field: &str, scale: f64, decimals: usize) -> String {
    match field.parse::<f64>() {
        Ok(x) if x.is_finite() => format!("{:.*}", decimals, x * scale),
        _ if field.is_empty() => "-".to_owned(),
        _ => field.to_owned(),
    }
}

/// `control_lost` in the text table: `LOST` (control lost and not
/// regained), `ok`, or `-` (no scenario window).
fn control(field: &str) -> &str {
    match field {
        "true" => "LOST",
        "false" => "ok",
        _ => "-",
    }
}

/// An empty field is `-` in the text table, and a field is one word
/// (the table's readers split rows at white space).
fn count(field: &str) -> String {
    if field.is_empty() {
        "-".to_owned()
    } else {
        field.split_whitespace().collect::<Vec<_>>().join("_")
    }
}

/// A file name as one cell of the text table: as it is, unless white
/// space, a quote or a character that does not print would make it
/// ambiguous (a space read as two cells by the table's readers, a tab or
/// a newline breaking the row's columns); then quoted (as `--csv` quotes
/// such a field), what is inside written with Rust's string escapes:
/// `"my drive.mcap"`, `"a\tb.mcap"`, `"say \"hi\".mcap"`. A name that is
/// not quoted never holds a quote, so the two cannot be confused.
pub fn file_cell(name: &str) -> String {
    let plain = !name.is_empty()
        && !name.chars().any(|c| {
            c.is_whitespace()
                || c == '"'
                || (c != '\\' && c != '\'' && c.escape_debug().nth(1).is_some())
        });
    if plain {
        name.to_owned()
    } else {
        format!("{name:?}")
    }
}

/// An inverter count in the text table: the scenario's, else (no scenario
/// window) the whole log's, else (no `MotorStatus` frames) `-`.
fn inverter_count(in_scenario: &str, whole_log: &str) -> String {
    if in_scenario.is_empty() {
        count(whole_log)
    } else {
        count(in_scenario)
    }
}

/// The vehicle in the text table: the file name of the vehicle file the
/// summary used (the `vehicle` column, [`grip_drive::vehicle_for`]'s
/// "PATH (where from)"; `defaults` for none), with `*` when the log does
/// not carry it (no `vehicle_sha256`: the configuration directory's, a
/// file read from disk, or the defaults); `-` for a log not read.
fn vehicle_name(vehicle: &str, sha256: &str) -> String {
    if vehicle.is_empty() {
        return "-".to_owned();
    }
    let path = vehicle.rsplit_once(" (").map_or(vehicle, |(p, _)| p);
    let name = count(path.rsplit(['/', '\\']).next().unwrap_or(path));
    if sha256.is_empty() {
        format!("{name}*")
    } else {
        name
    }
}

/// A column of the printed table: its head, whether it is aligned left,
/// and its cell of a row.
type TextColumn = (&'static str, bool, fn(&[String]) -> String);

/// The printed table's columns: the run (controller, ARTE, vehicle, seed)
/// beside the file and its status, then the figures.
const TEXT_COLUMNS: [TextColumn; 25] = [
    ("file", true, |r| file_cell(field(r, "file"))),
    ("status", true, |r| count(field(r, "status"))),
    ("ctrl", true, |r| count(field(r, "controller"))),
    ("arte", true, |r| count(field(r, "arte"))),
    ("vehicle", true, |r| {
        vehicle_name(field(r, "vehicle"), field(r, "vehicle_sha256"))
    }),
    ("seed", false, |r| count(field(r, "seed"))),
    ("cycles", false, |r| count(field(r, "cycles"))),
    ("slip_dev", false, |r| {
        rounded(field(r, "slip_deviation"), 1.0, 4)
    }),
    ("accel", false, |r| {
        rounded(field(r, "mean_accel_ms2"), 1.0, 3)
    }),
    ("effort", false, |r| {
        rounded(field(r, "torque_effort_nm"), 1.0, 1)
    }),
    ("cmd_tv", false, |r| {
        rounded(field(r, "cmd_tv_per_s"), 1.0, 0)
    }),
    ("dist_m", false, |r| rounded(field(r, "distance_m"), 1.0, 2)),
    ("arte_acc_%", false, |r| {
        rounded(field(r, "arte_accuracy"), 100.0, 1)
    }),
    ("delay_s", false, |r| {
        rounded(field(r, "mean_delay_s"), 1.0, 3)
    }),
    ("missed", false, |r| match field(r, "road_changes") {
        "" => "-".to_owned(),
        all => format!("{}/{all}", field(r, "changes_missed")),
    }),
    ("deadline_misses", false, |r| {
        count(field(r, "deadline_misses_in_scenario"))
    }),
    ("faults", false, |r| {
        count(field(r, "e2e_faults_in_scenario"))
    }),
    ("inv_faults", false, |r| {
        inverter_count(
            field(r, "inverter_faults_in_scenario"),
            field(r, "inverter_faults_whole_log"),
        )
    }),
    ("inv_derate", false, |r| {
        inverter_count(
            field(r, "inverter_derating_in_scenario"),
            field(r, "inverter_derating_whole_log"),
        )
    }),
    ("m_slip", false, |r| {
        rounded(field(r, "measured_mean_abs_slip"), 1.0, 3)
    }),
    ("m_max", false, |r| {
        rounded(field(r, "measured_max_abs_slip"), 1.0, 3)
    }),
    ("spins", false, |r| count(field(r, "spin_events"))),
    ("m_accel", false, |r| {
        rounded(field(r, "measured_mean_accel_ms2"), 1.0, 2)
    }),
    ("control", false, |r| {
        control(field(r, "control_lost")).to_owned()
    }),
    ("window", true, |r| field(r, "scenario_window").to_owned()),
];

/// The printed table's key, one entry each ([`wrap`]ped).
const KEY: [&str; 5] = [
    "ctrl, arte, seed: the controller, ARTE switch and seed the drive ran with, as grip inspect LOG and A B give them (grip.run; a replay's own controller and ARTE switch); vehicle: the vehicle file the summary used, * when the log does not carry it (the configuration directory's, read from disk, or the defaults); --csv adds where it came from, its SHA-256 and the microphone's lead",
    "during the scenario window: the metrics of the ground truth (slip_dev; accel, the mean acceleration, m/s^2; effort, N m; cmd_tv, the command's total variation, N m/s; dist_m), arte_acc_% (ARTE accuracy, %), delay_s (mean detection delay of the road changes detected), missed (road changes at the microphone not detected, of all), deadline_misses (the control loop's missed deadlines) and faults (E2E faults)",
    "inv_faults and inv_derate: the inverter's fault and derating episodes from its MotorStatus frames, during the scenario window (over the whole log when the log has none; - without MotorStatus frames)",
    "measured by the loop, NOT ground truth (over the scenario window, else the time the driver demanded torque): m_slip (mean |slip|), m_max (max |slip|), spins (spin events), m_accel (mean acceleration from V, m/s^2)",
    "control: LOST when control was lost and not regained in the scenario window; window: how much of the scenario the log covers; a missing figure is -; --csv FILE: every column at full precision",
];

/// Width of the printed table's key.
const KEY_WIDTH: usize = 100;

/// `text` in lines of at most `width` characters (a longer word alone),
/// the lines after the first indented by two spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let line = lines.last_mut().expect("one line at least");
        let len = line.chars().count();
        if len > 2 && len + 1 + word.chars().count() > width {
            lines.push(format!("  {word}"));
        } else {
            if !line.trim().is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
    }
    lines
}

/// The printed table of `grip inspect DIR` (the CSV has every column at
/// full precision): each row's run (controller, ARTE, vehicle file,
/// seed) beside its file, numbers rounded, ARTE accuracy in %, the road
/// changes ARTE missed beside the mean detection delay, the deadline
/// misses named as such, the inverter's fault and derating episodes, the
/// key figures the loop measured and whether control was lost; each
/// column as wide as its widest cell, the key wrapped to [`KEY_WIDTH`].
pub fn table(rows: &[Vec<String>]) -> String {
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| TEXT_COLUMNS.iter().map(|(_, _, f)| f(r)).collect())
        .collect();
    let heads: Vec<(&str, bool)> = TEXT_COLUMNS.iter().map(|(h, l, _)| (*h, *l)).collect();
    let mut text = aligned(&heads, &cells);
    for entry in KEY {
        for l in wrap(entry, KEY_WIDTH) {
            let _ = writeln!(text, "{l}");
        }
    }
    text
}

/// A text table: the heads (each with whether it is aligned left) and
/// the rows of cells, each column as wide as its widest cell, one space
/// between columns, no trailing space.
fn aligned(heads: &[(&str, bool)], cells: &[Vec<String>]) -> String {
    let widths: Vec<usize> = heads
        .iter()
        .enumerate()
        .map(|(i, (head, _))| {
            cells
                .iter()
                .map(|c| c[i].chars().count())
                .chain([head.chars().count()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: &mut dyn Iterator<Item = &str>| -> String {
        let mut l = String::new();
        for (i, c) in cells.enumerate() {
            let (w, left) = (widths[i], heads[i].1);
            if i > 0 {
                l.push(' ');
            }
            if left {
                let _ = write!(l, "{c:<w$}");
            } else {
                let _ = write!(l, "{c:>w$}");
            }
        }
        l.trim_end().to_owned()
    };
    let mut text = String::new();
    let _ = writeln!(text, "{}", line(&mut heads.iter().map(|(h, _)| *h)));
    for c in cells {
        let _ = writeln!(text, "{}", line(&mut c.iter().map(String::as_str)));
    }
    text
}

/// The key under `grip inspect DIR`'s pairs.
const PAIRS_KEY: &str = "ratios on/off per pair of the ground truth's figures over the scenario window, their mean [least, greatest]; accel>=1: pairs whose drive with ARTE had at least its partner's mean acceleration; vehicle@HEX: two vehicle files of one name told apart by their SHA-256; a pair whose drive without ARTE has a figure that is not positive is left out";

/// A row's vehicle as pairs compare it: the file's SHA-256, else (a log
/// that does not carry it) the name the table shows.
fn vehicle_key(r: &[String]) -> String {
    match field(r, "vehicle_sha256") {
        "" => vehicle_name(field(r, "vehicle"), ""),
        sha => sha.to_owned(),
    }
}

/// What pairs an `--arte on` drive with an `--arte off` one: the same
/// scenario, controller, vehicle (its SHA-256, else the name the summary
/// gives it) and seed.
type PairKey = (String, String, String, String);

/// `grip inspect DIR`'s "ARTE on against off" block, when DIR holds drives
/// that pair: per scenario, controller and vehicle, the pairs' ratios
/// on/off (slip deviation, mean acceleration, the command's total
/// variation per second: the ground truth's, over the scenario window),
/// their mean, least and greatest, and in how many pairs the drive with
/// ARTE had at least its partner's acceleration. Only logs read whole
/// (`ok`) that cover the scenario (`complete`), name their scenario,
/// controller and seed and are not `grip replay` logs pair; with more than
/// one drive on a side of a key they pair in file order; a pair whose
/// drive without ARTE has a figure that is not positive (no ratio to take:
/// a car that rolled back has a negative acceleration) is left out.
/// `None` when nothing pairs.
pub fn pairs(rows: &[Vec<String>]) -> Option<String> {
    let mut sides: std::collections::BTreeMap<PairKey, [Vec<&Vec<String>>; 2]> =
        std::collections::BTreeMap::new();
    let mut considered = 0;
    for r in rows {
        let side = match field(r, "arte") {
            "on" => 0,
            "off" => 1,
            _ => continue,
        };
        if field(r, "status") != "ok"
            || field(r, "scenario_window") != "complete"
            || !field(r, "replay_source").is_empty()
        {
            continue;
        }
        considered += 1;
        let (scenario, controller, seed) = (
            field(r, "scenario"),
            field(r, "controller"),
            field(r, "seed"),
        );
        if scenario.is_empty() || controller.is_empty() || seed.is_empty() {
            continue;
        }
        let key = (
            scenario.to_owned(),
            controller.to_owned(),
            vehicle_key(r),
            seed.to_owned(),
        );
        sides.entry(key).or_default()[side].push(r);
    }
    // a ratio on/off of figures whose baseline is positive
    let ratio = |on: &[String], off: &[String], col: &str| -> Option<f64> {
        let (a, b) = (
            field(on, col).parse::<f64>().ok()?,
            field(off, col).parse::<f64>().ok()?,
        );
        (a.is_finite() && b.is_finite() && b > 0.0).then_some(a / b)
    };
    // (scenario, controller, vehicle key) -> (vehicle shown, per pair
    // [slip, accel, tv] ratios)
    type Group = (String, Vec<[f64; 3]>);
    let mut groups: std::collections::BTreeMap<(String, String, String), Group> =
        std::collections::BTreeMap::new();
    let mut paired = 0;
    for ((scenario, controller, vehicle, _), [on, off]) in &sides {
        for (a, b) in on.iter().zip(off) {
            let (Some(s), Some(acc), Some(tv)) = (
                ratio(a, b, "slip_deviation"),
                ratio(a, b, "mean_accel_ms2"),
                ratio(a, b, "cmd_tv_per_s"),
            ) else {
                continue;
            };
            paired += 2;
            groups
                .entry((scenario.clone(), controller.clone(), vehicle.clone()))
                .or_insert_with(|| {
                    (
                        vehicle_name(field(a, "vehicle"), field(a, "vehicle_sha256")),
                        Vec::new(),
                    )
                })
                .1
                .push([s, acc, tv]);
        }
    }
    if groups.is_empty() {
        return None;
    }
    let spread = |v: &[[f64; 3]], k: usize, decimals: usize| -> String {
        let xs: Vec<f64> = v.iter().map(|p| p[k]).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let (lo, hi) = xs
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        format!("{mean:.decimals$}x [{lo:.decimals$}, {hi:.decimals$}]")
    };
    // two vehicle files of one name: each with the start of its SHA-256
    let shown = |(scenario, controller, key): &(String, String, String), name: &str| {
        let same_name = groups
            .iter()
            .filter(|((s, c, _), (n, _))| s == scenario && c == controller && n == name)
            .count();
        if same_name > 1 {
            format!("{name}@{}", key.chars().take(8).collect::<String>())
        } else {
            name.to_owned()
        }
    };
    let cells: Vec<Vec<String>> = groups
        .iter()
        .map(|(k, (vehicle, v))| {
            let (scenario, controller, _) = k;
            // the baseline's acceleration is positive: a ratio of at least
            // 1 is at least the partner's acceleration
            let at_least = v.iter().filter(|p| p[1] >= 1.0).count();
            vec![
                count(scenario),
                count(controller),
                shown(k, vehicle),
                v.len().to_string(),
                spread(v, 0, 3),
                spread(v, 1, 4),
                format!("{at_least}/{}", v.len()),
                spread(v, 2, 2),
            ]
        })
        .collect();
    let heads = [
        ("scenario", true),
        ("ctrl", true),
        ("vehicle", true),
        ("pairs", false),
        ("slip_dev", true),
        ("accel", true),
        ("accel>=1", false),
        ("cmd_tv", true),
    ];
    let mut text = String::from(
        "\nARTE on against off (drives of one scenario, controller, vehicle and seed, one with ARTE on and one off):\n",
    );
    text.push_str(&aligned(&heads, &cells));
    for l in wrap(PAIRS_KEY, KEY_WIDTH) {
        let _ = writeln!(text, "{l}");
    }
    let _ = writeln!(
        text,
        "{paired} of {considered} complete drives (not replays) paired"
    );
    Some(text)
}

/// `grip inspect DIR [--csv FILE] [--strict]`.
pub fn inspect_dir(ctx: &Ctx, dir: &Path, csv: Option<&Path>, strict: bool) -> anyhow::Result<()> {
    let logs = logs_in(dir)?;
    let pb = bar(logs.len(), "logs");
    let mut rows = Vec::with_capacity(logs.len());
    let mut bad = Vec::new();
    for p in &logs {
        let (r, good) = row(p, &ctx.config_dir);
        if !good {
            let f = |c: &str| field(&r, c).to_owned();
            let file = file_cell(field(&r, "file"));
            pb.suspend(|| eprintln!("bad log {file}: {}: {}", f("status"), f("reason")));
            bad.push(file);
        }
        rows.push(r);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let text = table(&rows);
    print!("{text}");
    if let Some(p) = pairs(&rows) {
        print!("{p}");
    }
    println!(
        "{} logs, {} bad{}",
        rows.len(),
        bad.len(),
        if bad.is_empty() {
            String::new()
        } else {
            format!(": {}", bad.join(", "))
        }
    );
    if let Some(f) = csv {
        let mut out = COLUMNS.join(",");
        out.push('\n');
        for r in &rows {
            out.push_str(&r.iter().map(|x| csv_field(x)).collect::<Vec<_>>().join(","));
            out.push('\n');
        }
        std::fs::write(f, out).with_context(|| format!("writing {}", f.display()))?;
        println!("wrote {}", f.display());
    }
    if strict && !bad.is_empty() {
        bail!("{} of {} logs are bad (--strict)", bad.len(), rows.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::export::test_log;

    fn config_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
    }

    /// The shipped front-mic vehicle file (its microphone 2.77 m ahead).
    fn front_mic() -> Vec<u8> {
        std::fs::read(config_dir().join("vehicles/front-mic.toml")).unwrap()
    }

    /// [`test_log::drive`] as `grip drive --vehicle .../front-mic.toml`
    /// records it: the file attached as `drive/vehicle.toml`.
    fn drive_with_vehicle() -> DriveLog {
        let mut log = test_log::drive();
        log.attachments
            .insert(grip_drive::plan::VEHICLE_ATTACHMENT.into(), front_mic());
        log
    }

    /// A row of [`COLUMNS`] with `fields` set and the rest empty.
    fn row_with(fields: &[(&str, &str)]) -> Vec<String> {
        let mut r = vec![String::new(); COLUMNS.len()];
        for (k, v) in fields {
            r[at(k)] = (*v).to_owned();
        }
        r
    }

    /// A complete drive's row: `arte` on or off, `seed`, the vehicle's
    /// SHA-256 `sha`, and its slip, acceleration and command variation.
    fn drive_row(arte: &str, seed: &str, sha: &str, figures: [&str; 3]) -> Vec<String> {
        row_with(&[
            ("file", "x.mcap"),
            ("status", "ok"),
            ("scenario", "paper"),
            ("controller", "mtte"),
            ("arte", arte),
            ("seed", seed),
            (
                "vehicle",
                "/cfg/vehicles/front-mic.toml (attached to the log)",
            ),
            ("vehicle_sha256", sha),
            ("scenario_window", "complete"),
            ("slip_deviation", figures[0]),
            ("mean_accel_ms2", figures[1]),
            ("cmd_tv_per_s", figures[2]),
        ])
    }

    /// `grip inspect DIR`'s pairs: one scenario, controller, vehicle and
    /// seed with ARTE on and off; the ratios' mean, least and greatest,
    /// and how many pairs kept their partner's acceleration; a replay, a
    /// partial log, another seed, another controller, another vehicle or a
    /// log without a seed does not pair, nor a pair whose drive without ARTE
    /// rolled back (a negative acceleration: no ratio); two vehicle files
    /// of one name are two rows, told apart by their SHA-256.
    #[test]
    fn on_and_off_drives_pair_by_run() {
        let mut rows = vec![
            drive_row("on", "1", "aa", ["0.02", "1.05", "300"]),
            drive_row("off", "1", "aa", ["0.2", "1.0", "250"]),
            drive_row("off", "2", "aa", ["0.1", "1.0", "200"]),
            drive_row("on", "2", "aa", ["0.03", "0.98", "100"]),
            // no partner: seed 3 only on, seed 4 on another vehicle's off
            drive_row("on", "3", "aa", ["0.02", "1.0", "1"]),
            drive_row("on", "4", "aa", ["0.02", "1.0", "1"]),
            drive_row("off", "4", "bb", ["0.2", "1.0", "1"]),
            // no seed: no pair
            drive_row("on", "", "aa", ["0.02", "1.0", "1"]),
            drive_row("off", "", "aa", ["0.2", "1.0", "1"]),
            // rolled back without ARTE: no ratio
            drive_row("on", "6", "aa", ["0.02", "0.1", "1"]),
            drive_row("off", "6", "aa", ["0.2", "-0.1", "1"]),
        ];
        // a replay and a partial drive of seed 5 never pair
        let mut replay = drive_row("on", "5", "aa", ["0.02", "1.0", "1"]);
        replay[at("replay_source")] = "drive.mcap".into();
        let mut partial = drive_row("off", "5", "aa", ["0.2", "1.0", "1"]);
        partial[at("scenario_window")] = "partial".into();
        // SRC, seed 1: its own row, not MTTE's
        let src = |arte: &str, slip: &str| {
            let mut r = drive_row(arte, "1", "aa", [slip, "1.0", "100"]);
            r[at("controller")] = "src".into();
            r
        };
        rows.extend([replay, partial, src("off", "0.08"), src("on", "0.04")]);
        let text = pairs(&rows).expect("pairs");
        let line = |ctrl: &str| -> Vec<&str> {
            text.lines()
                .find(|l| l.starts_with(&format!("paper    {ctrl} ")))
                .unwrap_or_else(|| panic!("{ctrl} in {text}"))
                .split_whitespace()
                .collect()
        };
        // slip 0.1x and 0.3x, accel 1.05x and 0.98x, command 1.2x and 0.5x
        assert_eq!(
            line("mtte"),
            [
                "paper",
                "mtte",
                "front-mic.toml",
                "2",
                "0.200x",
                "[0.100,",
                "0.300]",
                "1.0150x",
                "[0.9800,",
                "1.0500]",
                "1/2",
                "0.85x",
                "[0.50,",
                "1.20]"
            ],
            "{text}"
        );
        assert_eq!(line("src")[3..7], ["1", "0.500x", "[0.500,", "0.500]"]);
        assert_eq!(text.lines().filter(|l| l.starts_with("paper ")).count(), 2);
        // 13 complete drives (not replays) of which 6 paired
        assert!(
            text.lines()
                .any(|l| l == "6 of 13 complete drives (not replays) paired"),
            "{text}"
        );
        // nothing pairs: no block
        assert_eq!(pairs(&rows[4..9]), None);

        // two vehicle files named front-mic.toml: two rows
        let two = [
            drive_row("on", "1", "aa11aa11ff", ["0.02", "1.0", "1"]),
            drive_row("off", "1", "aa11aa11ff", ["0.2", "1.0", "1"]),
            drive_row("on", "1", "bb22bb22ff", ["0.02", "1.0", "1"]),
            drive_row("off", "1", "bb22bb22ff", ["0.2", "1.0", "1"]),
        ];
        let text = pairs(&two).unwrap();
        for name in ["front-mic.toml@aa11aa11", "front-mic.toml@bb22bb22"] {
            assert!(
                text.lines()
                    .any(|l| l.split_whitespace().nth(2) == Some(name)),
                "{name} in {text}"
            );
        }
    }

    /// A row's and the printed table's run: the controller, the ARTE
    /// switch and the seed the summary gives (a replay's own controller and
    /// ARTE switch, not its source's copied `grip.run`), and the vehicle
    /// file the summary used, with its SHA-256 and the microphone's lead;
    /// the table had no such column, so an ARTE-on and an ARTE-off drive
    /// differed only by file name.
    #[test]
    fn each_row_names_its_run() {
        let on = drive_with_vehicle();
        let (r, good) = row_of("on.mcap".into(), &on, &config_dir());
        assert!(good);
        let (v, from, _) = grip_drive::vehicle_for(&on, &config_dir());
        let s = summarize_with_roads(&on, &v, &from, &on.road_catalogue(&config_dir()));
        assert_eq!(field(&r, "controller"), "mtte");
        assert_eq!(field(&r, "arte"), "on");
        assert_eq!(field(&r, "seed"), "7");
        assert_eq!(field(&r, "vehicle"), s.vehicle);
        assert!(field(&r, "vehicle").starts_with("/somewhere/config/vehicles/front-mic.toml ("));
        assert_eq!(
            field(&r, "vehicle_sha256"),
            grip_digest::sha256_hex(&front_mic())
        );
        assert_eq!(field(&r, "mic_lead_m"), "2.77");

        // a replay of it with ARTE off and SRC: its own switch and controller
        let mut off = drive_with_vehicle();
        off.metadata.insert(
            "grip.replay".into(),
            [
                ("source", "on.mcap"),
                ("mode", "open loop"),
                ("controller", "src"),
                ("arte", "off"),
                ("changes", "controller src; ARTE off"),
            ]
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect(),
        );
        let (r_off, _) = row_of("off.mcap".into(), &off, &config_dir());
        assert_eq!(
            (field(&r_off, "controller"), field(&r_off, "arte")),
            ("src", "off")
        );
        // which log it replays and what it changed, as `--json`'s `replay`
        assert_eq!(
            [
                field(&r_off, "replay_source"),
                field(&r_off, "replay_mode"),
                field(&r_off, "replay_changes")
            ],
            ["on.mcap", "open loop", "controller src; ARTE off"]
        );
        // a drive's own log: empty
        assert!(
            ["replay_source", "replay_mode", "replay_changes"]
                .iter()
                .all(|c| field(&r, c).is_empty())
        );
        // a log that carries no vehicle: the configuration directory's
        let mut bare = test_log::drive();
        bare.run.remove("vehicle");
        let (r_bare, _) = row_of("bare.mcap".into(), &bare, &config_dir());
        assert_eq!(field(&r_bare, "vehicle_sha256"), "");
        assert!(
            field(&r_bare, "vehicle").ends_with("vehicle.toml (configuration directory)"),
            "{}",
            field(&r_bare, "vehicle")
        );

        let text = table(&[r, r_off, r_bare]);
        let lines: Vec<Vec<&str>> = text
            .lines()
            .take(4)
            .map(|l| l.split_whitespace().collect())
            .collect();
        assert_eq!(
            lines[0][..7],
            [
                "file", "status", "ctrl", "arte", "vehicle", "seed", "cycles"
            ],
            "{text}"
        );
        assert_eq!(
            lines[1][..6],
            ["on.mcap", "ok", "mtte", "on", "front-mic.toml", "7"]
        );
        assert_eq!(
            lines[2][..6],
            ["off.mcap", "ok", "src", "off", "front-mic.toml", "7"]
        );
        assert_eq!(lines[3][4], "vehicle.toml*", "{text}");
        // every row has a word per column
        for l in &lines {
            assert_eq!(l.len(), TEXT_COLUMNS.len(), "{text}");
        }
    }

    /// A file name with white space, a quote or a control character is
    /// one quoted cell (it was printed as it is: `my drive.mcap` read as
    /// two cells, a tab or a newline broke the row), and the columns after
    /// it keep their places; a plain name is as it was.
    #[test]
    fn a_file_name_with_white_space_is_one_cell() {
        let names = [
            "my drive.mcap",
            "tab\there.mcap",
            "new\nline.mcap",
            "say \"hi\".mcap",
            "plain\\drive.mcap",
        ];
        let rows: Vec<Vec<String>> = names
            .iter()
            .map(|n| row_of((*n).into(), &drive_with_vehicle(), &config_dir()).0)
            .collect();
        let text = table(&rows);
        let lines: Vec<&str> = text.lines().collect();
        let status = lines[0].find("status").unwrap();
        let want = [
            r#""my drive.mcap""#,
            r#""tab\there.mcap""#,
            r#""new\nline.mcap""#,
            r#""say \"hi\".mcap""#,
            r#"plain\drive.mcap"#,
        ];
        for (l, w) in lines[1..=names.len()].iter().zip(want) {
            assert!(l.starts_with(&format!("{w} ")), "{w}:\n{text}");
            assert!(l[status..].starts_with("ok     mtte on "), "{l}\n{text}");
            // one word per column but the file's
            assert_eq!(
                l[status..].split_whitespace().count(),
                TEXT_COLUMNS.len() - 1,
                "{l}"
            );
        }
        assert_eq!(file_cell("on.mcap"), "on.mcap");
        assert_eq!(file_cell("é-drive.mcap"), "é-drive.mcap");
        assert_eq!(file_cell("bell\u{7}.mcap"), r#""bell\u{7}.mcap""#);
        // the CSV quotes it its own way
        assert_eq!(csv_field("say \"hi\", ok"), r#""say ""hi"", ok""#);
    }

    /// The vehicle's name in the table, from each kind of
    /// [`grip_drive::vehicle_for`] label.
    #[test]
    fn the_vehicles_name_from_where_it_came_from() {
        let sha = "ab12";
        for (from, sha, want) in [
            (
                "/x/my cars (old)/rear.toml (grip drive --vehicle; attached to the log as drive/vehicle.toml)",
                sha,
                "rear.toml",
            ),
            (
                "vehicles/front-mic.toml (attached to the log)",
                sha,
                "front-mic.toml",
            ),
            ("vehicle.toml (attached to the log)", sha, "vehicle.toml"),
            (
                "/x/v2.toml (read from disk: not attached to the log)",
                "",
                "v2.toml*",
            ),
            (
                "/etc/grip/vehicle.toml (configuration directory)",
                "",
                "vehicle.toml*",
            ),
            ("defaults", "", "defaults*"),
            ("", "", "-"),
            ("my car.toml (attached to the log)", sha, "my_car.toml"),
        ] {
            assert_eq!(vehicle_name(from, sha), want, "{from}");
        }
    }

    /// The table's columns are each as wide as their widest cell, and its
    /// key keeps to [`KEY_WIDTH`] (it was one line of 900 characters).
    #[test]
    fn the_table_is_as_wide_as_its_cells_and_its_key_wraps() {
        let (r, _) = row_of("a.mcap".into(), &drive_with_vehicle(), &config_dir());
        let text = table(std::slice::from_ref(&r));
        let lines: Vec<&str> = text.lines().collect();
        assert!(
            lines[0].starts_with("file   status ctrl arte vehicle        seed "),
            "{text}"
        );
        assert!(
            lines[1].starts_with("a.mcap ok     mtte on   front-mic.toml    7 "),
            "{text}"
        );
        for l in &lines[2..] {
            assert!(l.chars().count() <= KEY_WIDTH, "{l}");
        }
        assert!(
            lines[2..]
                .iter()
                .any(|l| l.starts_with("inv_faults and inv_derate: the inverter's fault")),
            "{text}"
        );
        assert_eq!(
            wrap("aaa bbb ccc", 7),
            ["aaa bbb", "  ccc"],
            "a word that does not fit opens an indented line"
        );
    }
}
