//! `grip inspect`'s section "measured by the loop" (`summary::measured`:
//! tcs-loop's cycle records only, no ground truth):
//!
//! - on a log from the car (cycle records and CAN frames, no ground truth,
//!   written with grip-io's MCAP writer as the recorder writes them) the
//!   section is printed, `--json` carries its fields, and a constructed
//!   spin (λ 0.3 for 80 ms) is exactly one event with its start, length
//!   and peak; `grip inspect A B` puts the measured figures side by side;
//! - on generated drives with ground truth (`grip generate`, MFC and
//!   MTTE without ARTE: much slip, spins) the measured mean |λ_m| and
//!   acceleration agree with the ground-truth metrics within the
//!   tolerances `crates/drive/tests/measured_vs_truth.rs` derives from the
//!   sensor noise (ω σ 0.05 rad/s and its encoder step, V σ 0.02 m/s).

mod common;

use std::path::Path;

use grip_io::mcaplog::{McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{CycleRecord, topics};
use serde_json::Value;

const MS: u64 = 1_000_000;
/// The first cycle's stamp (the log's first message).
const T0: u64 = 5_000 * MS;
/// The driver presses the pedal at 0.5 s and releases it at 2.5 s.
const PRESS_MS: u64 = 500;
const RELEASE_MS: u64 = 2500;
/// The spin: λ 0.3 from 1.2 s for 80 ms.
const SPIN_MS: u64 = 1200;
const SPIN_LEN_MS: u64 = 80;
/// config/vehicle.toml's r (the log carries no vehicle: the configuration
/// directory's is used).
const R: f64 = 0.28;

/// A 3 s log from the car: V from 5 m/s, +1 m/s² while the pedal is
/// pressed (250 N m demanded, 200 N m commanded), r ω = V / (1 − λ) with λ
/// 0.02 but for the spin; V invalid for 30 ms at 2 s; belief snow
/// (catalogue index 2) from 1.0 s, asphalt (0) before.
fn write_car_log(path: &Path) {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    w.write_run_info(&RunInfo {
        version: "test".into(),
        git_revision: "unknown".into(),
        ..RunInfo::default()
    })
    .unwrap();
    let mut v = 5.0;
    for k in 0..3000u64 {
        let pressed = (PRESS_MS..RELEASE_MS).contains(&k);
        if pressed {
            v += 1e-3;
        }
        let lambda = if (SPIN_MS..SPIN_MS + SPIN_LEN_MS).contains(&k) {
            0.3
        } else {
            0.02
        };
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = T0 + k * MS;
        c.v = v;
        c.v_valid = 1;
        if (2000..2030).contains(&k) {
            c.v_valid = 0;
            c.v = f64::NAN;
        }
        c.omega = v / (1.0 - lambda) / R;
        c.demand = if pressed { 250.0 } else { 0.0 };
        c.torque_cmd = if pressed { 200.0 } else { 0.0 };
        c.torque = c.torque_cmd - 2.0;
        c.belief_road = if k >= 1000 { 2 } else { 0 };
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &Default::default())
        .unwrap();
    w.finish().unwrap();
}

fn json_of(path: &Path) -> Value {
    let (ok, out, err) = common::output(&["inspect".as_ref(), "--json".as_ref(), path.as_os_str()]);
    assert!(ok, "{out}{err}");
    serde_json::from_str(out.lines().next().unwrap()).unwrap()
}

#[test]
fn a_log_without_ground_truth_shows_what_the_loop_measured() {
    let d = tempfile::tempdir().unwrap();
    let car = d.path().join("car.mcap");
    write_car_log(&car);
    let (ok, out, err) = common::output(&["inspect".as_ref(), car.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("metrics: none (no ground truth in the log"),
        "{out}"
    );
    assert!(
        out.contains("measured by the loop (tcs-loop's cycle records")
            && out.contains("NOT ground truth"),
        "{out}"
    );
    assert!(
        out.contains("window: the time the driver demanded more than 10 N m (no scenario window in the log): 1 stretch, 2.000 s in all, 2000 cycles, first to last 0.500-2.500 s"),
        "{out}"
    );
    assert!(
        out.contains("left out: 30 without a valid V, 0 below 1 m/s"),
        "{out}"
    );
    assert!(
        out.contains(
            "spin events (|λ_m| above 0.2 for 20 ms or more; dips under 5 ms bridged): 1\n"
        ),
        "{out}"
    );
    assert!(
        out.contains("    at 1.200 s for 0.080 s, peak |λ_m| 0.300 at 1.2"),
        "{out}"
    );
    assert!(
        out.contains("command / demand                0.800"),
        "{out}"
    );
    // the belief named by the configuration's catalogue (the log has none)
    assert!(
        out.lines().any(|l| l.trim_start().starts_with("snow ")),
        "{out}"
    );

    let j = json_of(&car);
    assert_eq!(j["scenario_window"], "no_truth");
    assert!(j["metrics"].is_null());
    let m = &j["measured"];
    assert_eq!(m["window"], "demand", "{m}");
    assert_eq!(m["cycles"], 2000);
    assert_eq!(m["no_valid_v_cycles"], 30);
    assert_eq!(m["spin_events"], 1, "{m}");
    let e = &m["spins"][0];
    let close = |v: &Value, want: f64, tol: f64| (v.as_f64().unwrap() - want).abs() <= tol;
    assert!(close(&e["start_s"], 1.2, 1e-9), "{e}");
    assert!(close(&e["length_s"], 0.08, 1e-9), "{e}");
    assert!(close(&e["peak"], 0.3, 1e-9), "{e}");
    // 1940 cycles at 0.02, 80 at 0.3, time-weighted over 1970 with V
    let want = (1890.0 * 0.02 + 80.0 * 0.3) / 1970.0;
    assert!(close(&m["mean_abs_slip"], want, 1e-9), "{m}");
    assert!(close(&m["mean_accel_ms2"], 1.0, 1e-6), "{m}");
    assert!(close(&m["withheld_nms"], 100.0, 1e-6), "{m}");
    assert!(close(&m["cmd_over_demand"], 0.8, 1e-9), "{m}");
    let roads: Vec<&str> = m["per_belief"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["road"].as_str().unwrap())
        .collect();
    assert_eq!(roads, ["asphalt", "snow"], "{m}");

    // side by side with a drive with ground truth
    let reference =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
    let (ok, out, err) =
        common::output(&["inspect".as_ref(), car.as_os_str(), reference.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains(
            "measured by the loop (cycle records; NOT ground truth; window: A demand, B scenario)"
        ),
        "{out}"
    );
    assert!(
        out.lines()
            .any(|l| l.starts_with("spin events") && l.contains(" 1 ") && l.ends_with("1.000x")),
        "{out}"
    );
}

/// The tolerances of `crates/drive/tests/measured_vs_truth.rs` for a window
/// of `n` slip cycles at V ≥ `v_min`, and an acceleration span of `t` s.
fn tolerances(n: f64, v_min: f64, accel: f64, t: f64) -> (f64, f64) {
    let q = 2.0 * std::f64::consts::PI / (65536.0 * 1e-3);
    let sig = ((R * 0.05f64).powi(2) + (R * q).powi(2) / 6.0 + 0.02f64.powi(2)).sqrt();
    let sl = sig / v_min;
    (
        sl * (2.0 / std::f64::consts::PI).sqrt() + 4.0 * sl / n.sqrt(),
        4.0 * 2f64.sqrt() * 0.02 / t + 2.0 * accel.abs() * 1e-3 / t,
    )
}

#[test]
fn measured_figures_agree_with_the_ground_truth_of_generated_drives() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("logs");
    let (ok, so, se) = common::output(&[
        "generate".as_ref(),
        "--count".as_ref(),
        "2".as_ref(),
        "--seed0".as_ref(),
        "1".as_ref(),
        "--scenario".as_ref(),
        "paper".as_ref(),
        "--controllers".as_ref(),
        "mfc,mtte".as_ref(),
        "--arte".as_ref(),
        "off".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(ok, "{so}{se}");
    let mut logs: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    logs.sort();
    assert_eq!(logs.len(), 2);
    for p in &logs {
        let j = json_of(p);
        let (t, m) = (&j["metrics"], &j["measured"]);
        assert_eq!(m["window"], "scenario", "{m}");
        let f = |v: &Value| v.as_f64().unwrap();
        // the paper scenario starts at 10 km/h and only speeds up
        let (tol_slip, tol_accel) = tolerances(
            f(&m["slip_cycles"]),
            10.0 / 3.6,
            f(&t["mean_accel_ms2"]),
            f(&m["accel_s"]),
        );
        let ds = f(&m["mean_abs_slip"]) - f(&t["slip_deviation"]);
        let da = f(&m["mean_accel_ms2"]) - f(&t["mean_accel_ms2"]);
        eprintln!(
            "{} ({}): mean |λ_m| {:.5} truth {:.5} ({ds:+.5}, tolerance {tol_slip:.5}); accel {:.4} truth {:.4} ({da:+.4}, tolerance {tol_accel:.4}); spin events {}",
            p.display(),
            j["controller"],
            f(&m["mean_abs_slip"]),
            f(&t["slip_deviation"]),
            f(&m["mean_accel_ms2"]),
            f(&t["mean_accel_ms2"]),
            m["spin_events"]
        );
        assert!(ds.abs() <= tol_slip, "{ds} > {tol_slip}");
        assert!(da.abs() <= tol_accel, "{da} > {tol_accel}");
        // without ARTE the wheel spins on snow: a large slip to agree on
        assert!(f(&t["slip_deviation"]) > 0.05, "{t}");
    }
}
