//! `grip inspect` of a drive log whose control loop lost control and never
//! regained it (its bus gone 1.5 s into a 3 s scenario, the safe state to
//! the end) says so in the summary and in `--json`, and exits 0 (inspecting
//! a bad drive is no error); a drive whose loop recovered after 80 ms says
//! it was in control at the end. The logs are written with grip-io's MCAP
//! writer, as the recorder writes them. (`grip drive` fails the first kind
//! by the same `ControlHealth::lost`: `crates/drive/tests/control_health.rs`.)
//! A drive whose inverter faults, derates and times out the commands: its
//! episodes in `grip inspect`, against a clean one in `grip inspect A B`,
//! and in `grip inspect DIR`'s table and CSV.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use grip_io::can::protocol::{MsgKind, Protocol};
use grip_io::mcaplog::{McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{CanFrame, CycleRecord, can_dir, topics};

const MS: u64 = 1_000_000;
/// The last held sample: the scenario start.
const START_MS: u64 = 9;

/// A log written as the recorder writes one, with its run info: scenario
/// `test` of `duration_s`.
fn create_log(path: &Path, duration_s: &str) -> McapWriter {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    let mut extra = BTreeMap::new();
    extra.insert("scenario".to_owned(), "test".to_owned());
    extra.insert("scenario_duration_s".to_owned(), duration_s.to_owned());
    w.write_run_info(&RunInfo {
        version: "test".into(),
        git_revision: "unknown".into(),
        extra,
        ..RunInfo::default()
    })
    .unwrap();
    w
}

/// A 3 s drive: the bus gone at 1.5 s (no frame received after), the safe
/// state from 1.52 s, until `back_ms` (scenario time; None: to the end).
fn write_drive(path: &Path, back_ms: Option<u64>) {
    let mut w = create_log(path, "3");
    let p = Protocol::builtin();
    let safe = |t: u64| t >= START_MS + 1520 && back_ms.is_none_or(|b| t < START_MS + b);
    let mut timeouts = 0;
    for k in 0..3200u64 {
        if k < 3110 {
            w.write(topics::TRUTH, &grip_testkit::drives::asphalt_truth(k))
                .unwrap();
        }
        let gone = k >= START_MS + 1500 && back_ms.is_none_or(|b| k < START_MS + b - 60);
        if !gone {
            for kind in [
                MsgKind::WheelSpeeds,
                MsgKind::MotorStatus,
                MsgKind::DriverDemand,
            ] {
                // a healthy inverter: MotorStatus with Ready (bit 12) set
                let mut data = [0u8; 8];
                if kind == MsgKind::MotorStatus {
                    data[1] = 0x10;
                }
                let f = CanFrame {
                    stamp_ns: k * MS,
                    direction: can_dir::RX,
                    ..CanFrame::new(p.spec(kind).id, &data)
                };
                w.write(topics::CAN_LOG, &f).unwrap();
            }
        }
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = k * MS;
        c.safe_state = u8::from(safe(k));
        timeouts += u32::from(k == START_MS + 1520);
        c.faults.timeout = timeouts;
        c.torque_cmd = if safe(k) { 0.0 } else { 200.0 };
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &BTreeMap::new()).unwrap();
    w.finish().unwrap();
}

#[test]
fn inspect_says_control_was_lost_and_exits_0() {
    let d = tempfile::tempdir().unwrap();
    let lost = d.path().join("lost.mcap");
    write_drive(&lost, None);
    let (ok, out, err) = common::output(&["inspect".as_ref(), lost.as_os_str()]);
    assert!(ok, "inspecting a bad drive is no error: {out}{err}");
    let want = "control: CONTROL LOST AND NOT REGAINED: in the safe state from 1.520 s to the scenario's end at 3.000 s (1.480 s;";
    assert!(out.contains(want), "{want:?} not in\n{out}");
    assert!(
        out.contains("WARNING: CONTROL LOST AND NOT REGAINED"),
        "{out}"
    );
    assert!(out.contains("input timeouts +1"), "{out}");
    assert!(
        out.contains("tcs-loop received no CAN frame from then to the scenario's end"),
        "{out}"
    );
    let (ok, json, err) =
        common::output(&["inspect".as_ref(), "--json".as_ref(), lost.as_os_str()]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert_eq!(v["control_lost"], true, "{v}");
    assert!((v["control_out_at_end_s"].as_f64().unwrap() - 1.48).abs() < 1e-9);

    let back = d.path().join("back.mcap");
    write_drive(&back, Some(1600));
    let (ok, out, err) = common::output(&["inspect".as_ref(), back.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("control: in control at the end of the scenario; 1 safe-state entry during it, all recovered (longest 0.080 s, from 1.520 s)"),
        "{out}"
    );
    assert!(!out.contains("CONTROL LOST"), "{out}");
    let (_, json, _) = common::output(&["inspect".as_ref(), "--json".as_ref(), back.as_os_str()]);
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    assert_eq!(v["control_lost"], false, "{v}");
}

/// A 1 s drive whose inverter faults with FaultCode 0x2A from 0.300 to
/// 0.400 s of the scenario (the loop in its safe state from the cycle after
/// the first fault frame to 50 ms after the fault cleared, as tcs-loop does
/// since it acts on Fault), derates from 0.600 to 0.700 s and times out the
/// commands from 0.800 to 0.820 s; as plant-sim does, it comes up in Fault
/// and CmdTimeout with FaultCode 0x01 (its first 3 frames) and is back in
/// them from 0.050 s after the scenario's end (the commands stopped).
/// Written as the recorder writes a log.
fn write_faulting_drive(path: &Path) {
    write_inverter_drive(path, true, true);
}

/// That drive, its fault, derating and timeout during the scenario only
/// when `faulty` (else the inverter reports them at start-up and after the
/// drive only, as on a clean live drive), its ground truth only
/// `with_truth` (else a log from the car: no scenario window).
fn write_inverter_drive(path: &Path, faulty: bool, with_truth: bool) {
    use grip_io::can::protocol::{MotorStatus, encode_in};
    let mut w = create_log(path, "1");
    let p = Protocol::builtin();
    // scenario time, ms
    let t = |k: u64| k as i64 - START_MS as i64;
    let during = |k: u64, ms: std::ops::Range<i64>| faulty && ms.contains(&t(k));
    for k in 0..1100u64 {
        if with_truth {
            w.write(topics::TRUTH, &grip_testkit::drives::asphalt_truth(k))
                .unwrap();
        }
        let timed_out = k < 3 || t(k) >= 1050;
        let m = MotorStatus {
            ready: true,
            fault: timed_out || during(k, 300..400),
            derating: during(k, 600..700),
            cmd_timeout: timed_out || during(k, 800..820),
            fault_code: if timed_out {
                0x01
            } else if during(k, 300..400) {
                0x2A
            } else {
                0
            },
            ..MotorStatus::default()
        };
        // stamped with its arrival, 50 µs after cycle k's deadline: cycle
        // k + 1 reads it
        let mut f = encode_in(
            p.spec(MsgKind::MotorStatus),
            &m,
            (k % 16) as u8,
            k * MS + 50_000,
        );
        f.direction = can_dir::RX;
        w.write(topics::CAN_LOG, &f).unwrap();
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = k * MS;
        // safe in the cycle that read the fault, as tcs-loop is (from its
        // start until its inputs are valid, too)
        let read = k.checked_sub(1);
        c.safe_state =
            u8::from(k < 20 || read.is_some_and(|r| during(r, 300..450) || t(r) >= 1050));
        c.torque_cmd = if c.safe_state != 0 { 0.0 } else { 200.0 };
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &BTreeMap::new()).unwrap();
    w.finish().unwrap();
}

/// `grip inspect` and `--json` of that drive: each flag's episodes during
/// the scenario and over the whole log, the fault codes with their first
/// time, and the loop's safe state during the fault.
#[test]
fn inspect_shows_the_inverters_episodes_and_the_loop_during_its_fault() {
    let d = tempfile::tempdir().unwrap();
    let log = d.path().join("fault.mcap");
    write_faulting_drive(&log);
    let (ok, out, err) = common::output(&["inspect".as_ref(), log.as_os_str()]);
    assert!(ok, "{out}{err}");
    // the start-up fault's frames are read by cycles 1-3 (the loop was in
    // its safe state from cycle 0); the last fault's 41st frame arrived
    // after the log's last cycle woke: 40 cycles read it
    for want in [
        "\ninverter (its MotorStatus frames tcs-loop received and the E2E check accepted: 1100, -0.009 to 1.090 s; t from the scenario start)\n",
        "  during the scenario (0.000-1.000 s, 1000 frames): fault 1 (0.100 s), derating 1 (0.100 s), command timeout 1 (0.020 s), not ready 0\n",
        "  whole log: fault 3 (0.144 s), derating 1 (0.100 s), command timeout 3 (0.064 s), not ready 0\n",
        "  fault: 3 episodes (1 before the scenario, 1 during the scenario, 1 after the scenario)\n",
        "    -0.009 to -0.006 s (0.003 s, 3 frames), before the scenario, from the inverter's first frame, FaultCode 0x01: the loop in its safe state throughout (3 cycles; in it already before the fault began)\n",
        "    0.300 to 0.400 s (0.100 s, 100 frames), during the scenario, FaultCode 0x2A: the loop in its safe state throughout (100 cycles)\n",
        "    1.050 s to the end of the MotorStatus frames (0.041 s, 41 frames; still set in the last one), after the scenario, FaultCode 0x01: the loop in its safe state throughout (40 cycles)\n",
        "  derating: 1 episode (1 during the scenario)\n    0.600 to 0.700 s (0.100 s, 100 frames), during the scenario\n",
        "    0.800 to 0.820 s (0.020 s, 20 frames), during the scenario\n",
        "  fault codes: 0x01 first at -0.009 s (44 frames), 0x2A first at 0.300 s (100 frames)\n",
    ] {
        assert!(out.contains(want), "{want:?} not in\n{out}");
    }
    let (ok, json, err) = common::output(&["inspect".as_ref(), "--json".as_ref(), log.as_os_str()]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
    let inv = &v["inverter"];
    assert_eq!(inv["fault"]["episodes"], 3, "{inv}");
    assert_eq!(inv["fault"]["entered"], 2, "{inv}");
    assert_eq!(inv["fault"]["episodes_in_scenario"], 1, "{inv}");
    let e = &inv["fault"]["listed"][1];
    assert_eq!(
        (e["safe_cycles"].as_u64(), e["cycles"].as_u64()),
        (Some(100), Some(100)),
        "{e}"
    );
    assert_eq!(e["fault_codes"], serde_json::json!([42]), "{e}");
    assert!((e["start_s"].as_f64().unwrap() - 0.3).abs() < 1e-4, "{e}");
    assert!(
        inv["fault"]["listed"][2]["end_s"].is_null(),
        "to the end: {inv}"
    );
    assert_eq!(inv["derating"]["episodes_in_scenario"], 1, "{inv}");
    assert_eq!(inv["cmd_timeout"]["after_scenario"], 1, "{inv}");
    // clear -> set: the scenario's timeout and the one after the drive
    assert_eq!(v["command_timeouts"], 2, "{v}");
}

/// A log without a CAN frame: the drive's ground truth and cycle records
/// (in control), nothing from the inverter.
fn write_drive_without_can(path: &Path) {
    let mut w = create_log(path, "1");
    for k in 0..1100u64 {
        w.write(topics::TRUTH, &grip_testkit::drives::asphalt_truth(k))
            .unwrap();
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = k * MS;
        c.safe_state = u8::from(!(20..START_MS + 1050).contains(&k));
        c.torque_cmd = 200.0;
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &BTreeMap::new()).unwrap();
    w.finish().unwrap();
}

/// `grip inspect A B` and `grip inspect DIR` show the inverter: the
/// faulting drive above against the same drive with a clean inverter
/// (faults at start-up and after the drive only), each flag's episodes and
/// the loop's cycles in the faults as "scenario / whole log", the
/// FaultCodes; a log without MotorStatus frames is `-` and named, not
/// zeros. The directory's table counts the fault and derating episodes
/// during the scenario (the whole log's for a log from the car, which has
/// no scenario window), the CSV both.
#[test]
fn inspect_a_b_and_a_directory_show_the_inverters_faults() {
    let d = tempfile::tempdir().unwrap();
    let (fault, clean, car, nocan) = (
        d.path().join("fault.mcap"),
        d.path().join("clean.mcap"),
        d.path().join("car.mcap"),
        d.path().join("nocan.mcap"),
    );
    write_inverter_drive(&fault, true, true);
    write_inverter_drive(&clean, false, true);
    write_inverter_drive(&car, true, false);
    write_drive_without_can(&nocan);
    let row = |name: &str, a: &str, b: &str| format!("\n{name:<34} {a:>12} {b:>12}\n");

    let (ok, out, err) =
        common::output(&["inspect".as_ref(), fault.as_os_str(), clean.as_os_str()]);
    assert!(ok, "{out}{err}");
    for want in [
        "\ninverter (MotorStatus frames tcs-loop received and the E2E check accepted; during the scenario / whole log)\n".to_owned(),
        row("MotorStatus frames", "1000 / 1100", "1000 / 1100"),
        row("fault episodes", "1 / 3", "0 / 2"),
        row("derating episodes", "1 / 1", "0 / 0"),
        row("command timeout episodes", "1 / 3", "0 / 2"),
        row("not ready episodes", "0 / 0", "0 / 0"),
        // the scenario's fault (100 cycles), start-up's (3), after (40:
        // the last frame arrived after the last cycle woke)
        row("loop cycles in fault episodes", "100 / 143", "0 / 43"),
        row("  of them in the safe state", "100 / 143", "0 / 43"),
        row("fault codes (whole log)", "0x01, 0x2A", "0x01"),
    ] {
        assert!(out.contains(&want), "{want:?} not in\n{out}");
    }
    assert!(!out.contains("no MotorStatus frames"), "{out}");
    // the two inverters faulted differently: the comparison says so
    assert!(
        out.contains("the inverters' fault episodes during the scenario differ: A 1, B 0"),
        "{out}"
    );
    assert!(
        out.contains("the inverters' derating episodes during the scenario differ: A 1, B 0"),
        "{out}"
    );

    let (ok, out, err) = common::output(&["inspect".as_ref(), car.as_os_str(), nocan.as_os_str()]);
    assert!(ok, "{out}{err}");
    for want in [
        row("fault episodes", "- / 3", "-"),
        row("derating episodes", "- / 1", "-"),
        row("fault codes (whole log)", "0x01, 0x2A", "-"),
        "\ninverter B: no MotorStatus frames in the log (no CAN frame logged)\n".to_owned(),
    ] {
        assert!(out.contains(&want), "{want:?} not in\n{out}");
    }

    let (ok, out, err, csv) = common::inspect_dir(d.path());
    assert!(ok, "{out}{err}");
    let head: Vec<&str> = out.lines().next().unwrap().split_whitespace().collect();
    let at = head.iter().position(|w| *w == "inv_faults").unwrap();
    assert_eq!(
        head[at - 1..at + 2],
        ["faults", "inv_faults", "inv_derate"],
        "{out}"
    );
    let cols = |file: &str| -> Vec<String> {
        let words: Vec<String> = out
            .lines()
            .find(|l| l.starts_with(file))
            .unwrap_or_else(|| panic!("{file} not in\n{out}"))
            .split_whitespace()
            .map(str::to_owned)
            .collect();
        words[at..at + 2].to_vec()
    };
    assert_eq!(cols("fault.mcap"), ["1", "1"], "{out}");
    assert_eq!(cols("clean.mcap"), ["0", "0"], "{out}");
    assert_eq!(cols("car.mcap"), ["3", "1"], "the whole log's: {out}");
    assert_eq!(cols("nocan.mcap"), ["-", "-"], "{out}");
    assert!(
        out.contains("inv_faults and inv_derate: the inverter's fault and derating episodes"),
        "{out}"
    );

    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let new = [
        "inverter_faults_in_scenario",
        "inverter_faults_whole_log",
        "inverter_derating_in_scenario",
        "inverter_derating_whole_log",
    ];
    let i = header.iter().position(|h| *h == new[0]).unwrap();
    assert_eq!(header[i..i + 4], new, "{header:?}");
    // no field of these logs holds a comma
    let csv_row = |file: &str| -> Vec<String> {
        let r: Vec<&str> = lines
            .clone()
            .find(|l| l.starts_with(file))
            .unwrap_or_else(|| panic!("{file} not in\n{text}"))
            .split(',')
            .collect();
        assert_eq!(r.len(), header.len(), "{r:?}");
        r[i..i + 4].iter().map(|x| (*x).to_owned()).collect()
    };
    assert_eq!(csv_row("fault.mcap"), ["1", "3", "1", "1"]);
    assert_eq!(csv_row("clean.mcap"), ["0", "2", "0", "0"]);
    assert_eq!(csv_row("car.mcap"), ["", "3", "", "1"]);
    assert_eq!(csv_row("nocan.mcap"), ["", "", "", ""]);
}
