//! `grip inspect` of a drive log whose control loop lost control and never
//! regained it (its bus gone 1.5 s into a 3 s scenario, the safe state to
//! the end) says so in the summary and in `--json`, and exits 0 (inspecting
//! a bad drive is no error); a drive whose loop recovered after 80 ms says
//! it was in control at the end. The logs are written with grip-io's MCAP
//! writer, as the recorder writes them. (`grip drive` fails the first kind
//! by the same `ControlHealth::lost`: `crates/drive/tests/control_health.rs`.)

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use grip_io::can::protocol::{MsgKind, Protocol};
use grip_io::mcaplog::{McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{CanFrame, CycleRecord, GroundTruth, can_dir, name_to_bytes, topics};

const MS: u64 = 1_000_000;
/// The last held sample: the scenario start.
const START_MS: u64 = 9;

/// A 3 s drive: the bus gone at 1.5 s (no frame received after), the safe
/// state from 1.52 s, until `back_ms` (scenario time; None: to the end).
fn write_drive(path: &Path, back_ms: Option<u64>) {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    let mut extra = BTreeMap::new();
    extra.insert("scenario".to_owned(), "test".to_owned());
    extra.insert("scenario_duration_s".to_owned(), "3".to_owned());
    w.write_run_info(&RunInfo {
        version: "test".into(),
        git_revision: "unknown".into(),
        extra,
        ..RunInfo::default()
    })
    .unwrap();
    let p = Protocol::builtin();
    let safe = |t: u64| t >= START_MS + 1520 && back_ms.is_none_or(|b| t < START_MS + b);
    let mut timeouts = 0;
    for k in 0..3200u64 {
        if k < 3110 {
            let mut g = GroundTruth::zeroed();
            g.seq = k;
            g.stamp_ns = k * MS;
            g.x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            g.v = 3.0;
            g.omega = 10.0;
            g.road_index = 0;
            g.road_name = name_to_bytes("asphalt");
            g.mic_road_index = 0;
            g.mic_road_name = g.road_name;
            w.write(topics::TRUTH, &g).unwrap();
        }
        let gone = k >= START_MS + 1500 && back_ms.is_none_or(|b| k < START_MS + b - 60);
        if !gone {
            for kind in [
                MsgKind::WheelSpeeds,
                MsgKind::MotorStatus,
                MsgKind::DriverDemand,
            ] {
                let f = CanFrame {
                    stamp_ns: k * MS,
                    direction: can_dir::RX,
                    ..CanFrame::new(p.spec(kind).id, &[0; 8])
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
