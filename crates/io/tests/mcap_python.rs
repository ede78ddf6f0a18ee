//! The official Python MCAP reader (`pip install mcap`, imported as `mcap`)
//! must read grip's logs: summary statistics, schemas, channels, and every
//! message's JSON. This test needs `python3` with the `mcap` package; the
//! project's CI script installs it (`pip install mcap`). Without it the test
//! FAILS with that instruction — it never passes silently.

use std::process::Command;

use grip_io::mcaplog::*;
use grip_msgs::*;

#[test]
fn official_python_reader_reads_grip_logs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("py.mcap");
    let mut w = McapWriter::create(&path, McapWriterOptions::default()).unwrap();
    for i in 0..1000u64 {
        let mut c = CycleRecord::zeroed();
        c.seq = i;
        c.stamp_ns = 1_000_000 * (i + 1);
        c.torque_cmd = i as f64 * 0.5;
        w.write(topics::CYCLE, &c).unwrap();
        let mut f = CanFrame::new(0x120, &[i as u8; 8]);
        f.stamp_ns = c.stamp_ns;
        w.write(topics::CAN_LOG, &f).unwrap();
    }
    let mut a = AudioBlock::zeroed();
    a.n_samples = 4096;
    a.samples[4095] = -32768;
    a.stamp_ns = 5;
    w.write(topics::AUDIO, &a).unwrap();
    // the recorder's bus log: its own schema on grip/can/bus
    for i in 0..10u32 {
        let b = BusFrame {
            stamp_ns: 2_000_000 + u64::from(i),
            id: 0x18DA_F110,
            dlc: 3,
            bus: 0,
            flags: can_flags::EXTENDED,
            _reserved: 0,
            data: [i as u8, 0xAB, 0xCD, 0, 0, 0, 0, 0],
        };
        w.write(topics::BUS, &b).unwrap();
    }
    w.write_run_info(&RunInfo {
        version: "0.1.0".into(),
        git_revision: "deadbeef".into(),
        ..RunInfo::default()
    })
    .unwrap();
    w.finish().unwrap();

    let script = r#"
import sys, json
try:
    from mcap.reader import make_reader
except ImportError:
    print("python package 'mcap' missing: run `pip install mcap` (the CI script does)")
    sys.exit(3)
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    s = r.get_summary()
    st = s.statistics
    counts = {}
    torque_sum = 0.0
    last_audio = None
    bus_ids = set()
    bus_bytes = 0
    for schema, channel, message in r.iter_messages():
        assert channel.message_encoding == "json"
        assert schema.encoding == "jsonschema"
        json.loads(schema.data)
        d = json.loads(message.data)
        counts[channel.topic] = counts.get(channel.topic, 0) + 1
        if schema.name == "grip::CycleRecord::v2":
            torque_sum += d["torque_cmd"]
        if schema.name == "grip::AudioBlock::v1":
            last_audio = d["samples"][-1]
        if schema.name == "grip::BusFrame::v1":
            import jsonschema
            jsonschema.validate(d, json.loads(schema.data))
            bus_ids.add((d["id"], d["flags"]))
            bus_bytes += sum(d["data"][:d["dlc"]])
    md = {m.name: m.metadata for m in r.iter_metadata()}
    print(json.dumps({"messages": st.message_count, "channels": st.channel_count,
                      "counts": counts, "torque_sum": torque_sum, "last_audio": last_audio,
                      "bus_ids": sorted(bus_ids), "bus_bytes": bus_bytes,
                      "git": md["grip.run"]["git_revision"]}))
"#;
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .arg(&path)
        .output()
        .expect("python3 must be installed to run this test");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "python reader failed ({}): {stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["messages"], 2011);
    assert_eq!(v["channels"], 4);
    assert_eq!(v["counts"][topics::BUS], 10);
    assert_eq!(v["bus_ids"], serde_json::json!([[0x18DA_F110u32, 1]]));
    assert_eq!(v["bus_bytes"], 45 + 10 * (0xAB + 0xCD));
    assert_eq!(v["counts"][topics::CYCLE], 1000);
    assert_eq!(v["counts"][topics::CAN_LOG], 1000);
    assert_eq!(
        v["torque_sum"].as_f64().unwrap(),
        0.5 * 999.0 * 1000.0 / 2.0
    );
    assert_eq!(v["last_audio"], -32768);
    assert_eq!(v["git"], "deadbeef");
}
