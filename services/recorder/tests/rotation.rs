//! Rotation: the recorder binary in `out_dir` mode (as under systemd) with
//! `max_file_s = 1`, against real iceoryx2 publishers (this test process)
//! in an isolated `GRIP_INSTANCE`. Several parts, each a complete MCAP
//! file with the run's metadata and attachments and its place in the run,
//! and every message exactly once across them, in order.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::ipc::IpcNode;
use grip_io::mcaplog::{LogMessage, McapLog};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};
use grip_testkit::svc::{NotifySocket, Service, shipped_config_dir};

/// The shipped `recorder.toml` with `out_dir` and the given keys replaced
/// (keys the shipped file does not have are appended).
fn recorder_toml(out: &Path, keys: &[(&str, &str)]) -> String {
    let shipped = std::fs::read_to_string(shipped_config_dir().join("recorder.toml")).unwrap();
    let mut seen = Vec::new();
    let mut lines: Vec<String> = shipped
        .lines()
        .map(|l| {
            if l.starts_with("out_dir") {
                return format!("out_dir = {:?}", out.display().to_string());
            }
            for (k, v) in keys {
                if l.starts_with(&format!("{k} ")) {
                    seen.push(*k);
                    return format!("{k} = {v}");
                }
            }
            l.to_owned()
        })
        .collect();
    for (k, v) in keys {
        if !seen.contains(k) {
            lines.push(format!("{k} = {v}"));
        }
    }
    lines.join("\n") + "\n"
}

/// The recorder's own log files in `dir`, in their part order.
fn parts_of(dir: &Path) -> Vec<(u32, PathBuf, McapLog)> {
    let mut v: Vec<(u32, PathBuf, McapLog)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .map(|p| {
            let log = McapLog::open(&p).unwrap();
            let run =
                meta(&log, "grip.run").unwrap_or_else(|| panic!("{}: no grip.run", p.display()));
            let i: u32 = run["part"].parse().unwrap();
            (i, p, log)
        })
        .collect();
    v.sort_by_key(|(i, _, _)| *i);
    v
}

fn meta(log: &McapLog, name: &str) -> Option<std::collections::BTreeMap<String, String>> {
    log.metadata()
        .unwrap()
        .into_iter()
        .find(|(n, _)| n == name)
        .map(|(_, m)| m)
}

#[test]
fn out_dir_mode_rotates_into_standalone_parts_without_losing_a_message() {
    let instance = format!("rotation{}", std::process::id());
    // SAFETY: set before any thread of this test process reads the
    // environment (the first iceoryx2 call below reads it once).
    unsafe { std::env::set_var(grip_io::ipc::INSTANCE_ENV, &instance) };
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("logs");
    let cfg = t.path().join("recorder.toml");
    std::fs::write(
        &cfg,
        recorder_toml(
            &out,
            &[
                ("max_total_mib", "16"),
                ("min_free_mib", "0"),
                ("max_file_mib", "8"),
                ("max_file_s", "1"),
            ],
        ),
    )
    .unwrap();
    let sock = NotifySocket::bind(t.path());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_recorder"));
    cmd.arg("--config-dir")
        .arg(shipped_config_dir())
        .arg("--config")
        .arg(&cfg)
        .args(["--meta", "scenario=rotation-test"])
        .env("NOTIFY_SOCKET", sock.path())
        .env(grip_io::ipc::INSTANCE_ENV, &instance)
        .stderr(Stdio::piped());
    let mut child = Service::spawn(cmd);
    assert!(
        sock.wait_for("READY=1", Duration::from_secs(30)),
        "no READY=1 within 30 s"
    );

    let node = IpcNode::create("rotation-test-pub").unwrap();
    let cyc = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let can = node.publisher::<CanFrame>(topics::CAN_LOG).unwrap();
    let truth = node.publisher::<GroundTruth>(topics::TRUTH).unwrap();
    let road = node.publisher::<RoadEstimate>(topics::ROAD).unwrap();
    let audio = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
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
        std::thread::sleep(Duration::from_millis(20));
    }

    // about 4.5 s of traffic at ~1 kHz: four or more parts of 1 s
    const N: u64 = 4000;
    let start = Instant::now();
    for s in 0..N {
        let stamp = 1_000_000_000 + s * 1_000_000;
        let mut c = CycleRecord::zeroed();
        c.seq = s;
        c.stamp_ns = stamp;
        cyc.publish(&c).unwrap();
        let mut f = CanFrame::new(0x100, &[0, (s & 15) as u8, 0, 0, 0, 0, 0, 0]);
        f.direction = grip_msgs::can_dir::TX;
        f.stamp_ns = stamp;
        can.publish(&f).unwrap();
        if s % 10 == 0 {
            let mut g = GroundTruth::zeroed();
            g.seq = s / 10;
            g.stamp_ns = stamp;
            truth.publish(&g).unwrap();
        }
        if s % 100 == 0 {
            let mut r = RoadEstimate::zeroed();
            r.seq = s / 100;
            r.stamp_ns = stamp;
            road.publish(&r).unwrap();
            let mut a = AudioBlock::zeroed();
            a.seq = s / 100;
            a.stamp_ns = stamp;
            a.sample_rate = 44_100;
            a.n_samples = 16;
            a.samples[..16].copy_from_slice(&[7; 16]);
            audio.publish(&a).unwrap();
        }
        // at most ~1 kHz (the deep subscribers hold about a second)
        let due = start + Duration::from_micros(s * 1100);
        if let Some(d) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    child.signal(15);
    let (status, err) = child.wait();
    assert_eq!(status.code(), Some(0), "{err}");

    let parts = parts_of(&out);
    let n = parts.len();
    assert!(
        n >= 3,
        "only {n} parts in {:.1} s: {err}",
        start.elapsed().as_secs_f64()
    );
    let pid = child.0.id();
    let first = parts[0].1.file_name().unwrap().to_str().unwrap().to_owned();
    let run0 = meta(&parts[0].2, "grip.run").unwrap();
    let mut cycles = Vec::new();
    let mut cans = 0usize;
    let mut received = 0u64;
    for (k, (i, path, log)) in parts.iter().enumerate() {
        let name = path.file_name().unwrap().to_str().unwrap();
        // the recorder's own name scheme: retention treats finished parts
        // as any finished log
        let parsed = grip_recorder::parse_log_name(name).unwrap_or_else(|| panic!("{name}"));
        assert_eq!(parsed.pid, pid, "{name}");
        assert_eq!(*i as usize, k + 1, "parts numbered 1, 2, ...");
        let (msgs, rep) = log.messages().unwrap();
        assert!(rep.truncated.is_none() && rep.bad == 0, "{name}: {rep:?}");
        let run = meta(log, "grip.run").unwrap();
        assert_eq!(run["scenario"], "rotation-test", "{name}");
        assert_eq!(run["part.run_first"], first, "{name}");
        assert_eq!(run["part.run_started_ns"], run0["part.run_started_ns"]);
        if k > 0 {
            let prev = parts[k - 1].1.file_name().unwrap().to_str().unwrap();
            assert_eq!(run["part.previous"], prev, "{name}");
        } else {
            assert!(!run.contains_key("part.previous"));
        }
        // the same run description in every part
        for (key, v) in &run0 {
            if !key.starts_with("part") {
                assert_eq!(run.get(key), Some(v), "{name}: {key}");
            }
        }
        let att = log.attachments().unwrap();
        let dbc = att
            .iter()
            .find(|a| a.name == "inverter.dbc")
            .unwrap_or_else(|| panic!("{name}: no inverter.dbc"));
        assert_eq!(
            dbc.data,
            std::fs::read(shipped_config_dir().join("inverter.dbc")).unwrap()
        );
        let these: Vec<u64> = msgs
            .iter()
            .filter_map(|m| match &m.msg {
                LogMessage::Cycle(c) => Some(c.seq),
                _ => None,
            })
            .collect();
        let rec = meta(log, "grip.recorder").unwrap_or_else(|| panic!("{name}: no grip.recorder"));
        assert_eq!(rec["part"], i.to_string());
        assert_eq!(
            rec[&format!("{}.written", topics::CYCLE)],
            these.len().to_string(),
            "{name}: its own counters"
        );
        received += rec[&format!("{}.received", topics::CYCLE)]
            .parse::<u64>()
            .unwrap();
        cans += msgs
            .iter()
            .filter(|m| matches!(m.msg, LogMessage::Can(_)))
            .count();
        cycles.extend(these);
    }
    let want: Vec<u64> = (0..N).collect();
    assert_eq!(cycles.len(), want.len(), "{err}");
    assert_eq!(
        cycles, want,
        "every cycle record exactly once, in order, across the parts"
    );
    assert_eq!(cans as u64, N);
    assert_eq!(received, N, "the parts' receive counters add up to the run");
    let rotated = err
        .lines()
        .filter(|l| l.contains("log file rotated"))
        .count();
    assert_eq!(rotated, n - 1, "{err}");
    for l in err.lines().filter(|l| l.contains("log file rotated")) {
        eprintln!("> {l}");
    }
    assert!(err.contains(&format!("parts={n}")), "{err}");
}

/// A write error in `out_dir` mode stops recording only until a new file
/// can be written. The disk filling up is played by `RLIMIT_FSIZE` (an
/// unprivileged test cannot mount a small file system; the write then
/// fails with EFBIG instead of ENOSPC, through the same path; SIGXFSZ
/// ignored as a full disk sends no signal): the first part fails at
/// 256 KiB, the recorder keeps draining its queue and counting what it
/// cannot write, and at its next attempt (10 s later) opens a new part,
/// which says what was lost before it. Every cycle record in the files
/// is there once, in order; the hole between the parts is no longer than
/// the messages counted as not written plus the failed part's last chunk.
#[test]
fn after_a_write_error_recording_resumes_in_a_new_file() {
    use std::os::unix::process::CommandExt;
    let instance = format!("rotfail{}", std::process::id());
    // SAFETY: as above: before any thread of this process reads it.
    unsafe { std::env::set_var(grip_io::ipc::INSTANCE_ENV, &instance) };
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("logs");
    // a configuration folder of the recorder's file alone: a part's head
    // is a few KiB
    let cfg = t.path().join("config");
    std::fs::create_dir(&cfg).unwrap();
    std::fs::write(
        cfg.join("recorder.toml"),
        recorder_toml(
            &out,
            &[
                ("max_total_mib", "16"),
                ("min_free_mib", "0"),
                ("max_file_mib", "8"),
                ("max_file_s", "3600"),
            ],
        ),
    )
    .unwrap();
    const LIMIT: u64 = 256 << 10;
    let sock = NotifySocket::bind(t.path());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_recorder"));
    cmd.arg("--config-dir")
        .arg(&cfg)
        .env("NOTIFY_SOCKET", sock.path())
        .env(grip_io::ipc::INSTANCE_ENV, &instance);
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: LIMIT,
                rlim_max: LIMIT,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let mut child = Service::spawn(cmd);
    assert!(
        sock.wait_for("READY=1", Duration::from_secs(30)),
        "no READY=1 within 30 s"
    );
    let node = IpcNode::create("rotfail-test-pub").unwrap();
    let cyc = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let can = node.publisher::<CanFrame>(topics::CAN_LOG).unwrap();
    let t0 = Instant::now();
    while cyc.peers().subscribers == 0 || can.peers().subscribers == 0 {
        assert!(t0.elapsed() < Duration::from_secs(60), "no subscriber");
        std::thread::sleep(Duration::from_millis(20));
    }
    let mcaps = || {
        std::fs::read_dir(&out)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .path()
                    .extension()
                    .is_some_and(|x| x == "mcap")
            })
            .count()
    };
    // ~1 kHz until a second file is there and 500 more after it
    let start = Instant::now();
    let mut s = 0u64;
    let mut end = None;
    while end.is_none_or(|e| s < e) {
        let stamp = 1_000_000_000 + s * 1_000_000;
        let mut c = CycleRecord::zeroed();
        c.seq = s;
        c.stamp_ns = stamp;
        c.omega = s as f64 * 0.37;
        cyc.publish(&c).unwrap();
        let mut f = CanFrame::new(0x100, &[0, (s & 15) as u8, 0, 0, 0, 0, 0, 0]);
        f.direction = grip_msgs::can_dir::TX;
        f.stamp_ns = stamp;
        can.publish(&f).unwrap();
        s += 1;
        if end.is_none() && s.is_multiple_of(100) && mcaps() >= 2 {
            end = Some(s + 500);
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no second file within 60 s"
        );
        let due = start + Duration::from_micros(s * 1000);
        if let Some(d) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
    let n = s;
    child.signal(15);
    let (status, err) = child.wait();
    // a write failed during the run: exit 1 at the end (as before)
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.lines()
            .any(|l| l.contains("MCAP write failed") || l.contains("MCAP flush failed")),
        "{err}"
    );
    assert!(err.contains("recording resumed in a new log file"), "{err}");
    for l in err.lines().filter(|l| {
        [
            "failed",
            "could not be finished",
            "resumed",
            "not recording",
            "recorder stopped",
        ]
        .iter()
        .any(|w| l.contains(w))
    }) {
        eprintln!("> {l}");
    }

    let mut files: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort_by_key(|p| std::fs::metadata(p).unwrap().modified().unwrap());
    assert_eq!(files.len(), 2, "{files:?}\n{err}");
    let first = McapLog::open(&files[0]).unwrap();
    let (m1, rep1) = first.messages().unwrap();
    assert!(rep1.bad == 0, "{rep1:?}");
    let second = McapLog::open(&files[1]).unwrap();
    let (m2, rep2) = second.messages().unwrap();
    assert!(rep2.truncated.is_none() && rep2.bad == 0, "{rep2:?}");
    let cycles = |m: &[grip_io::mcaplog::LogEntry]| -> Vec<u64> {
        m.iter()
            .filter_map(|e| match &e.msg {
                LogMessage::Cycle(c) => Some(c.seq),
                _ => None,
            })
            .collect()
    };
    let (c1, c2) = (cycles(&m1), cycles(&m2));
    assert!(!c1.is_empty() && !c2.is_empty());
    assert_eq!(
        c1,
        (0..c1.len() as u64).collect::<Vec<_>>(),
        "part 1 in order from 0"
    );
    let b = c2[0];
    assert_eq!(c2, (b..n).collect::<Vec<_>>(), "part 2 in order to the end");
    let run = meta(&second, "grip.run").unwrap();
    assert_eq!(run["part"], "2");
    assert_eq!(
        run["part.previous"],
        files[0].file_name().unwrap().to_str().unwrap()
    );
    let lost: u64 = run[&format!("part.not_written_before.{}", topics::CYCLE)]
        .parse()
        .unwrap();
    let rec = meta(&second, "grip.recorder").unwrap();
    assert_eq!(
        rec[&format!("{}.not_written_before", topics::CYCLE)],
        lost.to_string()
    );
    // the hole: what was counted as not written, plus what sat in the
    // failed part's last chunk and buffer (written as far as the writer
    // knew, not on the disk)
    let hole = b - c1.len() as u64;
    eprintln!(
        "part 1: {} cycle records, hole {hole}, counted as not written {lost}, part 2 from {b} to {n}",
        c1.len()
    );
    assert!(lost > 1000, "about 10 s at 1 kHz not written: {lost}");
    assert!(lost <= hole, "{lost} > {hole}");
    assert!(
        hole - lost < 5000,
        "{hole} - {lost}: more lost than counted"
    );
}
