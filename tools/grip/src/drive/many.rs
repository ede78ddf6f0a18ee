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
/// `measured_` ones and `spin_events` are what the loop measured, over
/// `measured_window`, [`grip_drive::summary::Measured`]; `control_lost` is
/// [`grip_drive::summary::ControlHealth::lost`], empty without a window;
/// the `inverter_` ones count the inverter's fault and derating episodes
/// from its `MotorStatus` frames, [`grip_drive::summary::Inverter`], those
/// overlapping the scenario window and over the whole log, empty without
/// `MotorStatus` frames).
pub const COLUMNS: [&str; 41] = [
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

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        String::new()
    }
}

/// One row: `Ok` for a complete log, `Err` (status, reason) when it is bad.
pub fn row(path: &Path, config_dir: &Path) -> (Vec<String>, bool) {
    let file = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut r = vec![String::new(); COLUMNS.len()];
    r[0] = file;
    let log = match DriveLog::load(path) {
        Ok(l) => l,
        Err(e) => {
            r[1] = "unreadable".into();
            r[2] = e.full();
            return (r, false);
        }
    };
    let (vehicle, from, _) = grip_drive::vehicle_for(&log, config_dir);
    let roads = log.road_catalogue(config_dir);
    let s = summarize_with_roads(&log, &vehicle, &from, &roads);
    let mut good = true;
    if let Some(t) = &log.report.truncated {
        r[1] = "incomplete".into();
        r[2] = t.clone();
        good = false;
    } else if log.report.bad > 0 {
        r[1] = "damaged".into();
        r[2] = format!(
            "{} messages did not decode (first: {})",
            log.report.bad,
            log.report.first_error.as_deref().unwrap_or("?")
        );
        good = false;
    } else {
        r[1] = "ok".into();
    }
    r[3] = log.run.get("scenario").cloned().unwrap_or_default();
    // a replay's own controller and ARTE switch (`grip.run` is its source's)
    let run = |k: &str| {
        s.run
            .iter()
            .find(|(kk, _)| kk == k)
            .map_or_else(String::new, |(_, v)| v.clone())
    };
    r[4] = run("controller");
    r[5] = run("arte");
    r[6] = s.timing.cycles.to_string();
    if let (Some(m), Some((a, b))) = (&s.metrics, s.window) {
        r[7] = num(b - a);
        r[8] = num(m.slip_deviation);
        r[9] = num(m.max_torque);
        r[10] = num(m.torque_effort);
        r[11] = num(m.distance);
        r[12] = num(m.energy);
    }
    r[13] = s.arte.estimates.to_string();
    r[14] = num(s.arte.accuracy());
    let delays: Vec<f64> = s.arte.changes.iter().filter_map(|c| c.delay).collect();
    r[15] = s.arte.changes.len().to_string();
    r[16] = (s.arte.changes.len() - delays.len()).to_string();
    if !delays.is_empty() {
        r[17] = num(delays.iter().sum::<f64>() / delays.len() as f64);
        r[18] = num(delays.iter().copied().fold(0.0, f64::max));
    }
    let in_scn = s.timing.in_scenario.as_ref();
    r[19] = in_scn.map_or(String::new(), |w| w.deadline_misses.to_string());
    r[20] = s
        .safe_cycles_in_window
        .map_or(String::new(), |n| n.to_string());
    r[21] = s
        .can
        .faults_in_window
        .map_or(String::new(), |f| f.total().to_string());
    r[22] = s.window_status.as_str().to_owned();
    r[23] = in_scn.map_or(String::new(), |w| w.safe_entries.to_string());
    r[24] = in_scn.map_or(String::new(), |w| w.wakeup.max.to_string());
    r[25] = s.timing.deadline_misses.to_string();
    r[26] = num(s.arte.accuracy_whole_log());
    let m = &s.measured;
    r[27] = m.window.as_str().to_owned();
    if m.window != MeasuredWindow::NoCycles {
        r[28] = num(m.mean_abs_slip);
        r[29] = num(m.p95_abs_slip);
        r[30] = num(m.max_abs_slip);
        r[31] = num(m.share_above[1]);
        r[32] = m.spins.len().to_string();
        r[33] = num(m.mean_accel);
        r[34] = num(m.delivered);
        r[35] = num(m.withheld_nms);
    }
    r[36] = s
        .control
        .as_ref()
        .map_or(String::new(), |c| c.lost().to_string());
    let inv = &s.inverter;
    if inv.frames > 0 {
        for (i, flag) in [(37, Flag::Fault), (39, Flag::Derating)] {
            if let Some(f) = inv.flag(flag) {
                r[i] = f.in_scenario.map_or(String::new(), |(n, _)| n.to_string());
                r[i + 1] = f.count.to_string();
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

/// An empty count is `-` in the text table.
fn count(field: &str) -> &str {
    if field.is_empty() { "-" } else { field }
}

/// An inverter count in the text table: the scenario's, else (no scenario
/// window) the whole log's, else (no `MotorStatus` frames) `-`.
fn inverter_count<'a>(in_scenario: &'a str, whole_log: &'a str) -> &'a str {
    if in_scenario.is_empty() {
        count(whole_log)
    } else {
        in_scenario
    }
}

/// The printed table of `grip inspect DIR` (the CSV has every column at
/// full precision): numbers rounded, ARTE accuracy in %, the road changes
/// ARTE missed beside the mean detection delay, the deadline misses
/// named as such, the inverter's fault and derating episodes, the key
/// figures the loop measured and whether control was lost.
pub fn table(rows: &[Vec<String>]) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{:<28} {:<11} {:>8} {:>9} {:>8} {:>8} {:>10} {:>8} {:>7} {:>15} {:>6} {:>10} {:>10} {:>6} {:>6} {:>5} {:>7} {:>7}  window",
        "file",
        "status",
        "cycles",
        "slip_dev",
        "effort",
        "dist_m",
        "arte_acc_%",
        "delay_s",
        "missed",
        "deadline_misses",
        "faults",
        "inv_faults",
        "inv_derate",
        "m_slip",
        "m_max",
        "spins",
        "m_accel",
        "control"
    );
    for r in rows {
        let _ = writeln!(
            text,
            "{:<28} {:<11} {:>8} {:>9} {:>8} {:>8} {:>10} {:>8} {:>7} {:>15} {:>6} {:>10} {:>10} {:>6} {:>6} {:>5} {:>7} {:>7}  {}",
            r[0],
            r[1],
            count(&r[6]),
            rounded(&r[8], 1.0, 4),
            rounded(&r[10], 1.0, 1),
            rounded(&r[11], 1.0, 2),
            rounded(&r[14], 100.0, 1),
            rounded(&r[17], 1.0, 3),
            if r[15].is_empty() {
                "-".to_owned()
            } else {
                format!("{}/{}", r[16], r[15])
            },
            count(&r[19]),
            count(&r[21]),
            inverter_count(&r[37], &r[38]),
            inverter_count(&r[39], &r[40]),
            rounded(&r[28], 1.0, 3),
            rounded(&r[30], 1.0, 3),
            count(&r[32]),
            rounded(&r[33], 1.0, 2),
            control(&r[36]),
            r[22]
        );
    }
    let _ = writeln!(
        text,
        "(during the scenario window: the metrics (slip_dev, effort N m, dist_m), arte_acc_% (ARTE accuracy, %), delay_s (mean detection delay of the road changes detected), missed (road changes at the microphone not detected, of all), deadline_misses (the control loop's missed deadlines) and faults (E2E faults); inv_faults and inv_derate: the inverter's fault and derating episodes from its MotorStatus frames, during the scenario window (over the whole log when the log has none; - without MotorStatus frames); measured by the loop, NOT ground truth (over the scenario window, else the time the driver demanded torque): m_slip (mean |slip|), m_max (max |slip|), spins (spin events), m_accel (mean acceleration from V, m/s^2); control: LOST when control was lost and not regained in the scenario window; window: how much of the scenario the log covers; --csv FILE: every column at full precision)"
    );
    text
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
            pb.suspend(|| eprintln!("bad log {}: {}: {}", r[0], r[1], r[2]));
            bad.push(r[0].clone());
        }
        rows.push(r);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let text = table(&rows);
    print!("{text}");
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
