//! `grip replay` of a log with a value no drive logs (a damaged or
//! hand-made log): a cycle's compute time or wake-up latency of centuries,
//! a TorqueCommand stamped 2^63, ground-truth sequence numbers that do not
//! start near 0, every stamp at the clock's end. Each once panicked the
//! replay with an arithmetic overflow (debug builds) or made the closed
//! loop step the plant without end; now the log is refused before the
//! replay runs, with the log, the topic and message, the field and its
//! value named, or (where every value fits) replayed without overflow.

use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use grip_drive::{DriveLog, LoadOptions};
use grip_io::mcaplog::{McapWriter, McapWriterOptions};
use grip_msgs::{can_dir, topics};

mod common;

fn reference() -> DriveLog {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap");
    DriveLog::load_with(&p, LoadOptions { audio: true }).unwrap()
}

/// `log` written to `path`: every topic, metadata record and attachment.
fn write(path: &Path, log: &DriveLog) {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    for (name, map) in &log.metadata {
        if name != "grip.clock" && name != "grip.recorder" {
            w.write_metadata(name, map).unwrap();
        }
    }
    for (name, data) in &log.attachments {
        w.attach_bytes(name, "application/octet-stream", data)
            .unwrap();
    }
    // merged by stamp, each topic in its own order (a stamp out of order
    // stays where it was, as in a damaged log)
    let lens = [
        log.cycles.len(),
        log.can.len(),
        log.roads.len(),
        log.truth.len(),
        log.audio_blocks.len(),
    ];
    let stamp = |t: usize, i: usize| match t {
        0 => log.cycles[i].stamp_ns,
        1 => log.can[i].stamp_ns,
        2 => log.roads[i].stamp_ns,
        3 => log.truth[i].stamp_ns,
        _ => log.audio_blocks[i].stamp_ns,
    };
    let mut heads = [0usize; 5];
    while let Some(t) = (0..5)
        .filter(|&t| heads[t] < lens[t])
        .min_by_key(|&t| stamp(t, heads[t]))
    {
        let i = heads[t];
        match t {
            0 => w.write(topics::CYCLE, &log.cycles[i]).unwrap(),
            1 => w.write(topics::CAN_LOG, &log.can[i]).unwrap(),
            2 => w.write(topics::ROAD, &log.roads[i]).unwrap(),
            3 => w.write(topics::TRUTH, &log.truth[i]).unwrap(),
            _ => w.write(topics::AUDIO, &log.audio_blocks[i]).unwrap(),
        }
        heads[t] += 1;
    }
    w.finish().unwrap();
}

/// `grip replay LOG [--closed-loop]`: its exit code and stderr; a run that
/// takes over two minutes is killed and fails the test (the closed loop
/// once stepped the plant without end).
fn replay(log: &Path, closed: bool) -> (Option<i32>, String) {
    let dir = tempfile::tempdir().unwrap();
    let (out, err) = (dir.path().join("out"), dir.path().join("err"));
    let mut c = common::grip();
    c.arg("replay").arg(log);
    if closed {
        c.arg("--closed-loop");
    }
    let mut child = c
        .stdout(Stdio::from(std::fs::File::create(&out).unwrap()))
        .stderr(Stdio::from(std::fs::File::create(&err).unwrap()))
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!(
                "grip replay {} (closed loop: {closed}) ran over 120 s",
                log.display()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let err = std::fs::read_to_string(&err).unwrap();
    assert!(!err.contains("panicked"), "{}: {err}", log.display());
    (status.code(), err)
}

/// The log refused with `want` (the error's first line), open and closed
/// loop alike.
fn refused_both_ways(log: &Path, want: &str) {
    for closed in [false, true] {
        let (code, err) = replay(log, closed);
        assert_eq!(code, Some(1), "closed loop: {closed}: {err}");
        let first = err.lines().next().unwrap_or_default();
        assert_eq!(first, format!("error: {want}"), "closed loop: {closed}");
    }
}

#[test]
fn a_cycle_s_compute_time_or_latency_of_centuries_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let mut log = reference();
    let seq = log.cycles[100].seq;
    log.cycles[100].compute_ns = u64::MAX;
    let p = d.path().join("compute.mcap");
    write(&p, &log);
    refused_both_ways(
        &p,
        &format!(
            "{}: grip/tcs/cycle message 100 (seq {seq}): compute_ns = 18446744073709551615 (18446744073.710 s), more than the 3600.000 s a cycle of the loop can take: the log is damaged and cannot be replayed",
            p.display()
        ),
    );

    let mut log = reference();
    log.cycles[100].wakeup_latency_ns = i64::MAX;
    let p = d.path().join("latency.mcap");
    write(&p, &log);
    refused_both_ways(
        &p,
        &format!(
            "{}: grip/tcs/cycle message 100 (seq {seq}): wakeup_latency_ns = 9223372036854775807 (9223372036.855 s), more than 3600.000 s from its deadline, which no cycle of the loop wakes: the log is damaged and cannot be replayed",
            p.display()
        ),
    );
}

#[test]
fn a_command_stamped_2_to_the_63_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let mut log = reference();
    // the 101st command: cycle 100's
    let (i, prev) = {
        let tx: Vec<usize> = (0..log.can.len())
            .filter(|&i| log.can[i].direction == can_dir::TX)
            .collect();
        (tx[100], log.can[tx[99]].stamp_ns)
    };
    log.can[i].stamp_ns = 1 << 63;
    let seq = log.cycles[100].seq;
    let p = d.path().join("tx.mcap");
    write(&p, &log);
    let (code, err) = replay(&p, true);
    assert_eq!(code, Some(1), "{err}");
    let want = format!(
        "error: {}: grip/can/log message {i} (the TorqueCommand of cycle seq {seq}): stamp_ns = 9223372036854775808, ",
        p.display()
    );
    let first = err.lines().next().unwrap_or_default();
    assert!(
        first.starts_with(&want)
            && first.contains(&format!(
                "after the previous command's ({prev}), more than the 3600.000 s"
            )),
        "{first}"
    );
}

#[test]
fn ground_truth_seq_numbers_that_cannot_be_mapped_are_refused_in_closed_loop() {
    let d = tempfile::tempdir().unwrap();
    let mut log = reference();
    for g in &mut log.truth {
        g.seq += 1 << 50;
    }
    let t0 = log.truth[0].stamp_ns;
    let p = d.path().join("truth.mcap");
    write(&p, &log);
    let (code, err) = replay(&p, true);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(
        err.lines().next().unwrap_or_default(),
        format!(
            "error: {}: grip/plant/truth message 0: seq = 1125899906842624 at stamp_ns = {t0}: plant-sim (at most 100 kHz) would have started its cycle 0 before the clock's zero: its sequence numbers cannot be mapped to plant-sim's cycles, the log is damaged and --closed-loop cannot replay it",
            p.display()
        )
    );
    // open loop does not run the plant: replayed
    let (code, err) = replay(&p, false);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn every_stamp_at_the_clock_s_end_replays_without_overflow() {
    let d = tempfile::tempdir().unwrap();
    let mut log = reference();
    for c in &mut log.cycles {
        c.stamp_ns = u64::MAX;
    }
    for f in &mut log.can {
        f.stamp_ns = u64::MAX;
    }
    for e in &mut log.roads {
        e.stamp_ns = u64::MAX;
    }
    for g in &mut log.truth {
        g.stamp_ns = u64::MAX;
    }
    for b in &mut log.audio_blocks {
        b.stamp_ns = u64::MAX;
    }
    let p = d.path().join("end.mcap");
    write(&p, &log);
    for closed in [false, true] {
        let (code, err) = replay(&p, closed);
        assert_eq!(code, Some(0), "closed loop: {closed}: {err}");
    }
}
