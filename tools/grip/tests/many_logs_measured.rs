//! `grip inspect DIR`'s columns of what the loop measured and of the
//! control statement: a drive whose loop lost control 1.5 s into a 3 s
//! scenario and never regained it, and a log from the car (no ground
//! truth, so no scenario window), each with one constructed spin (λ 0.3
//! for 80 ms, after 40 ms at 0.15: no spin) and V rising at 1 m/s², written with grip-io's MCAP writer
//! as the recorder writes them; plus the reference drive (in control) and
//! a file that is not MCAP. The CSV carries every figure exactly as
//! `grip inspect --json` gives it (`control_lost` empty without a scenario
//! window, every new column empty for the unreadable file), and the
//! printed table shows them rounded, control lost as `LOST`.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use grip_io::mcaplog::{McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{CycleRecord, GroundTruth, name_to_bytes, topics};
use serde_json::Value;

const MS: u64 = 1_000_000;
/// The last held ground-truth sample: the scenario start, ms.
const START_MS: u64 = 9;
/// config/vehicle.toml's r (the logs carry no vehicle).
const R: f64 = 0.28;

/// 3.2 s of cycle records (V from 5 m/s at +1 m/s², demand 250 N m,
/// command 200 N m, λ 0.02 but 0.15 from 0.9 s for 40 ms and 0.3 from
/// 1.0 s for 80 ms); with `truth`, a
/// 3 s scenario's ground truth and the safe state from 1.52 s of it to
/// the end (control lost), else a log from the car.
fn write_log(path: &Path, truth: bool) {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    let mut extra = BTreeMap::new();
    if truth {
        extra.insert("scenario".to_owned(), "test".to_owned());
        extra.insert("scenario_duration_s".to_owned(), "3".to_owned());
    }
    w.write_run_info(&RunInfo {
        version: "test".into(),
        git_revision: "unknown".into(),
        extra,
        ..RunInfo::default()
    })
    .unwrap();
    let safe = |k: u64| truth && k >= START_MS + 1520;
    let mut v = 5.0;
    for k in 0..3200u64 {
        if truth && k < 3110 {
            let mut g = GroundTruth::zeroed();
            g.seq = k;
            g.stamp_ns = k * MS;
            g.x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            g.v = 3.0;
            g.omega = 10.0;
            g.road_name = name_to_bytes("asphalt");
            g.mic_road_name = g.road_name;
            w.write(topics::TRUTH, &g).unwrap();
        }
        v += 1e-3;
        let lambda = match k {
            900..940 => 0.15,
            1000..1080 => 0.3,
            _ => 0.02,
        };
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = k * MS;
        c.v = v;
        c.v_valid = 1;
        c.omega = v / (1.0 - lambda) / R;
        c.demand = 250.0;
        c.safe_state = u8::from(safe(k));
        c.torque_cmd = if safe(k) { 0.0 } else { 200.0 };
        c.torque = c.torque_cmd;
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &BTreeMap::new()).unwrap();
    w.finish().unwrap();
}

/// The mean |λ| of `n` cycles of a log's window (the spins all in it).
fn mean_slip(n: f64) -> f64 {
    ((n - 120.0) * 0.02 + 40.0 * 0.15 + 80.0 * 0.3) / n
}

fn json_of(path: &Path) -> Value {
    let (ok, out, err) = common::output(&["inspect".as_ref(), "--json".as_ref(), path.as_os_str()]);
    assert!(ok, "{out}{err}");
    serde_json::from_str(out.lines().next().unwrap()).unwrap()
}

/// The CSV's `col` of `row` as a number (it must be one).
fn number(header: &[&str], row: &[&str], col: &str) -> f64 {
    let i = header.iter().position(|h| *h == col).unwrap();
    row[i]
        .parse()
        .unwrap_or_else(|e| panic!("{col} = {:?}: {e}", row[i]))
}

#[test]
fn inspect_dir_has_the_measured_figures_and_control_lost() {
    let d = tempfile::tempdir().unwrap();
    let lost = d.path().join("lost.mcap");
    let car = d.path().join("car.mcap");
    write_log(&lost, true);
    write_log(&car, false);
    let reference =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
    std::os::unix::fs::symlink(&reference, d.path().join("reference.mcap")).unwrap();
    std::fs::write(d.path().join("text.mcap"), "not a log").unwrap();
    let (ok, out, err, csv) = common::inspect_dir(d.path());
    assert!(ok, "{out}{err}");

    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let new = [
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
    ];
    // the inverter's four columns follow them
    let first = header.len() - new.len() - 4;
    assert_eq!(header[first..first + new.len()], new, "{header:?}");
    // each row's fields from the end (the reason, third, may hold quoted
    // commas; none of the later fields does), file and status first
    let rows: BTreeMap<&str, Vec<&str>> = lines
        .map(|l| {
            let r: Vec<&str> = l.split(',').collect();
            let tail = r[r.len() + 3 - header.len()..].iter().copied();
            (r[0], [r[0], r[1], ""].into_iter().chain(tail).collect())
        })
        .collect();
    let col = |file: &str, c: &str| rows[file][header.iter().position(|h| *h == c).unwrap()];

    // the same figures as --json, to the last bit
    for (file, path) in [("lost.mcap", &lost), ("car.mcap", &car)] {
        let j = json_of(path);
        let m = &j["measured"];
        for (c, k) in [
            ("measured_mean_abs_slip", "mean_abs_slip"),
            ("measured_p95_abs_slip", "p95_abs_slip"),
            ("measured_max_abs_slip", "max_abs_slip"),
            ("measured_share_above_0_2", "share_above_0_2"),
            ("measured_mean_accel_ms2", "mean_accel_ms2"),
            ("measured_cmd_over_demand", "cmd_over_demand"),
            ("measured_withheld_nms", "withheld_nms"),
        ] {
            assert_eq!(
                number(&header, &rows[file], c),
                m[k].as_f64().unwrap(),
                "{file} {c}"
            );
        }
        assert_eq!(col(file, "measured_window"), m["window"].as_str().unwrap());
        assert_eq!(col(file, "spin_events"), m["spin_events"].to_string());
    }
    // and what the logs were written with
    assert_eq!(col("lost.mcap", "measured_window"), "scenario");
    assert_eq!(col("car.mcap", "measured_window"), "demand");
    for file in ["lost.mcap", "car.mcap"] {
        assert_eq!(col(file, "spin_events"), "1", "{file}");
        let close = |c: &str, want: f64, tol: f64| {
            let x = number(&header, &rows[file], c);
            assert!((x - want).abs() <= tol, "{file} {c} = {x}, want {want}");
        };
        close("measured_max_abs_slip", 0.3, 1e-9);
        close("measured_mean_accel_ms2", 1.0, 1e-6);
        // 80 cycles of the window at 0.3, 40 at 0.15, the others at 0.02;
        // the lost drive's 1480 cycles in the safe state (from 1.52 s of
        // its 3 s window) are left out of the slip
        let n = if file == "lost.mcap" { 1520.0 } else { 3200.0 };
        close("measured_mean_abs_slip", mean_slip(n), 1e-5);
        close("measured_share_above_0_2", 80.0 / n, 1e-9);
    }
    assert_eq!(col("lost.mcap", "control_lost"), "true");
    assert_eq!(json_of(&lost)["control_lost"], true);
    assert_eq!(col("car.mcap", "control_lost"), "", "no scenario window");
    assert_eq!(col("reference.mcap", "control_lost"), "false");
    assert_eq!(col("reference.mcap", "measured_window"), "scenario");
    assert!(number(&header, &rows["reference.mcap"], "measured_mean_abs_slip") > 0.0);
    // the inverter: the reference drive's start-up fault is before the
    // scenario; the constructed logs have no CAN frame (empty, not 0)
    assert_eq!(col("reference.mcap", "inverter_faults_in_scenario"), "0");
    assert_eq!(col("reference.mcap", "inverter_faults_whole_log"), "1");
    for file in ["lost.mcap", "car.mcap"] {
        assert_eq!(col(file, "inverter_faults_whole_log"), "", "{file}");
    }
    // an unreadable log: every new column empty
    assert_eq!(col("text.mcap", "status"), "unreadable");
    for c in new {
        assert_eq!(col("text.mcap", c), "", "{c}");
    }

    // the printed table: rounded, control lost as LOST, missing as -
    let head = out.lines().next().unwrap();
    let words: Vec<&str> = head.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "m_slip").unwrap();
    assert_eq!(
        words[at..],
        ["m_slip", "m_max", "spins", "m_accel", "control", "window"],
        "{out}"
    );
    let row = |file: &str| -> Vec<&str> {
        out.lines()
            .find(|l| l.starts_with(file))
            .unwrap_or_else(|| panic!("{file} not in\n{out}"))
            .split_whitespace()
            .collect()
    };
    let cols = |file: &str| row(file)[at..at + 5].to_vec();
    let slip = |n: f64| format!("{:.3}", mean_slip(n));
    assert_eq!(
        cols("lost.mcap"),
        [slip(1520.0).as_str(), "0.300", "1", "1.00", "LOST"],
        "{out}"
    );
    assert_eq!(
        cols("car.mcap"),
        [slip(3200.0).as_str(), "0.300", "1", "1.00", "-"],
        "{out}"
    );
    assert_eq!(row("reference.mcap")[at + 4], "ok", "{out}");
    let text_row = row("text.mcap");
    assert_eq!(
        text_row[text_row.len() - 5..],
        ["-", "-", "-", "-", "-"],
        "{out}"
    );
}
