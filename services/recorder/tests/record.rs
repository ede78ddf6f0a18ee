//! The recorder binary against real iceoryx2 publishers (this test process)
//! in an isolated `GRIP_INSTANCE`: everything published is in the file, in
//! order, holes in the sequence numbers are counted as gaps, SIGTERM drains
//! and finishes the file (exit 0), the run metadata and attachments are there.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::ipc::IpcNode;
use grip_io::mcaplog::{LogMessage, McapLog};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

fn config_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

#[test]
fn records_everything_counts_gaps_and_finishes_on_sigterm() {
    let instance = format!("rectest{}", std::process::id());
    // SAFETY: set before any thread of this test process reads the
    // environment (the first iceoryx2 call below reads it once).
    unsafe { std::env::set_var(grip_io::ipc::INSTANCE_ENV, &instance) };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.mcap");
    let mut child = Command::new(env!("CARGO_BIN_EXE_recorder"))
        .arg("--config-dir")
        .arg(config_dir())
        .arg("--out")
        .arg(&out)
        .args(["--meta", "scenario=unit-test"])
        .env(grip_io::ipc::INSTANCE_ENV, &instance)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();

    let node = IpcNode::create("rec-test-pub").unwrap();
    let cyc = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let can = node.publisher::<CanFrame>(topics::CAN_LOG).unwrap();
    let truth = node.publisher::<GroundTruth>(topics::TRUTH).unwrap();
    let road = node.publisher::<RoadEstimate>(topics::ROAD).unwrap();
    let audio = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    // wait until the recorder subscribed to every topic
    let t0 = Instant::now();
    while [
        cyc.peers().subscribers,
        can.peers().subscribers,
        truth.peers().subscribers,
        road.peers().subscribers,
        audio.peers().subscribers,
    ]
    .contains(&0)
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "recorder did not subscribe within 60 s"
        );
        if let Ok(Some(st)) = child.try_wait() {
            panic!("recorder exited early: {st}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }

    // 2000 cycle records at ~1 kHz with two holes (seq 500 and 1500..1502)
    let holes = |s: u64| s == 500 || (1500..1503).contains(&s);
    let mut sent_cycles = 0u64;
    for s in 0..2000u64 {
        if !holes(s) {
            let mut c = CycleRecord::zeroed();
            c.seq = s;
            c.stamp_ns = 1_000_000_000 + s * 1_000_000;
            c.omega = s as f64 * 0.5;
            cyc.publish(&c).unwrap();
            sent_cycles += 1;
        }
        let mut f = CanFrame::new(0x100, &[0, (s & 15) as u8, 0, 0, 0, 0, 0, 0]);
        f.direction = grip_msgs::can_dir::TX;
        f.stamp_ns = 1_000_000_000 + s * 1_000_000;
        can.publish(&f).unwrap();
        if s % 10 == 0 {
            let mut g = GroundTruth::zeroed();
            g.seq = s / 10;
            g.stamp_ns = 1_000_000_000 + s * 1_000_000;
            truth.publish(&g).unwrap();
        }
        if s % 100 == 0 {
            let mut r = RoadEstimate::zeroed();
            r.seq = s / 100;
            r.stamp_ns = 1_000_000_000 + s * 1_000_000;
            road.publish(&r).unwrap();
            let mut a = AudioBlock::zeroed();
            a.seq = s / 100;
            a.stamp_ns = 1_000_000_000 + s * 1_000_000;
            a.sample_rate = 44_100;
            a.n_samples = 16;
            a.samples[..16].copy_from_slice(&[7; 16]);
            audio.publish(&a).unwrap();
        }
        // at most ~1 kHz: the recorder's 1024-deep buffers then hold about
        // a second of what it has not taken yet (a loaded machine may stall it)
        if s % 2 == 1 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let st = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "recorder did not stop"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    use std::io::Read;
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(status.success(), "recorder exit {status}: {err}");

    let log = McapLog::open(&out).unwrap();
    let (msgs, rep) = log.messages().unwrap();
    assert!(rep.truncated.is_none(), "{rep:?}");
    assert_eq!(rep.bad, 0, "{rep:?}");
    let cycles: Vec<u64> = msgs
        .iter()
        .filter_map(|m| match &m.msg {
            LogMessage::Cycle(c) => Some(c.seq),
            _ => None,
        })
        .collect();
    let expected: Vec<u64> = (0..2000).filter(|s| !holes(*s)).collect();
    eprintln!(
        "first cycles {:?} last {:?}",
        &cycles[..cycles.len().min(10)],
        cycles.last()
    );
    assert_eq!(cycles.len() as u64, sent_cycles, "{err}");
    assert_eq!(cycles, expected, "cycle records missing or out of order");
    let n = |f: fn(&LogMessage) -> bool| msgs.iter().filter(|m| f(&m.msg)).count();
    assert_eq!(n(|m| matches!(m, LogMessage::Can(_))), 2000);
    assert_eq!(n(|m| matches!(m, LogMessage::Truth(_))), 200);
    assert_eq!(n(|m| matches!(m, LogMessage::Road(_))), 20);
    assert_eq!(n(|m| matches!(m, LogMessage::Audio(_))), 20);

    let meta = log.metadata().unwrap();
    let get = |name: &str| {
        meta.iter()
            .find(|(n, _)| n == name)
            .map(|(_, m)| m.clone())
            .unwrap_or_else(|| panic!("no {name} metadata"))
    };
    let rec = get("grip.recorder");
    assert_eq!(rec[&format!("{}.seq_gaps", topics::CYCLE)], "4");
    assert_eq!(rec[&format!("{}.seq_gap_events", topics::CYCLE)], "2");
    assert_eq!(
        rec[&format!("{}.written", topics::CYCLE)],
        sent_cycles.to_string()
    );
    assert_eq!(rec[&format!("{}.counter_gaps", topics::CAN_LOG)], "0");
    assert_eq!(rec[&format!("{}.queue_dropped", topics::CAN_LOG)], "0");
    let run = get("grip.run");
    assert_eq!(run["scenario"], "unit-test");
    assert!(!run["git_revision"].is_empty());
    assert_eq!(run["config.can.toml"].len(), 64);
    let att = log.attachments().unwrap();
    let names: Vec<&str> = att.iter().map(|a| a.name.as_str()).collect();
    for want in [
        "can.toml",
        "inverter.dbc",
        "recorder.toml",
        "scenarios/paper.toml",
        "vehicles/front-mic.toml",
    ] {
        assert!(
            names.contains(&want),
            "attachment {want} missing: {names:?}"
        );
    }
    let dbc = att.iter().find(|a| a.name == "inverter.dbc").unwrap();
    assert_eq!(
        dbc.data,
        std::fs::read(config_dir().join("inverter.dbc")).unwrap()
    );
}

/// An `--attach` file that cannot be read (missing, a directory) is one
/// error at start naming the attachment, the path and the OS's reason,
/// exit 1, and no log is created: it warned and recorded a log without it.
#[test]
fn an_unreadable_attachment_is_refused_before_recording() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.mcap");
    let missing = dir.path().join("nonexistent/vehicle.toml");
    for (file, reason) in [
        (missing.as_path(), "No such file or directory (os error 2)"),
        (dir.path(), "Is a directory (os error 21)"),
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_recorder"))
            .arg("--config-dir")
            .arg(config_dir())
            .arg("--out")
            .arg(&out)
            .arg("--attach")
            .arg(format!("drive/vehicle.toml={}", file.display()))
            .env(
                grip_io::ipc::INSTANCE_ENV,
                format!("recattach{}", std::process::id()),
            )
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > Duration::from_secs(30) {
                let _ = child.kill();
                let _ = child.wait();
                panic!("recorder recorded without --attach {}", file.display());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        use std::io::Read;
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        assert_eq!(status.code(), Some(1), "{err}");
        let want = format!(
            "error: --attach drive/vehicle.toml={}: cannot read: {reason}; nothing recorded",
            file.display()
        );
        assert_eq!(
            err.lines()
                .filter(|l| l.contains("error"))
                .collect::<Vec<_>>(),
            [want.as_str()],
            "{err}"
        );
        assert!(!out.exists(), "a log was created");
    }
}
