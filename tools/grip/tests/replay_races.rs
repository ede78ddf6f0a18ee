//! `grip replay --closed-loop` of a drive where a command went out while
//! plant-sim drained the bus: tcs-loop sends its command after its "now"
//! (the TorqueCommand's stamp) and before the end of its compute (the log
//! copies and the record follow the send), and plant-sim drains just before
//! its own "now" (the ground truth's stamp). Where a plant "now" lies
//! between the two, the stamps cannot tell whether that plant cycle got the
//! command; the logged ground truth can (the torque the plant applied). A
//! live drive (`grip drive --vehicle heavy-fwd.toml`, 2026-12-06) had a
//! cycle woken 616 µs late whose command the plant received 7.6 µs before
//! the end of that cycle's compute: the replay, counting every command as
//! sent at the end of its compute, gave it to the next plant cycle, and 962
//! cycle records differed from there on (`grip/tcs/cycle message 1965:
//! field torque: logged 76.0, replayed 79.4`).
//!
//! Here a generated drive (lock step: each command reaches the next plant
//! cycle) is given such a cycle: one whose command changed the torque has
//! its compute made to end 0.5 µs after the next plant cycle's "now", as
//! if its log copies had taken that long; its command still reached that
//! plant cycle, as the generated ground truth says. The closed loop must
//! reproduce the log bit for bit, and say that it placed the command.

use std::path::Path;

use grip_drive::{DriveLog, LoadOptions};
use grip_io::mcaplog::{McapWriter, McapWriterOptions};
use grip_msgs::{can_dir, topics};
use serde_json::Value;

mod common;

/// `grip ARGS` on the repository's `config/`.
fn grip(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    common::output(args)
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

/// `log` with its cycle records `cycles` instead, every other topic,
/// metadata record and attachment as it is.
fn write_with_cycles(path: &Path, log: &DriveLog, cycles: &[grip_msgs::CycleRecord]) {
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
    let mut all: Vec<(u64, usize, usize)> = Vec::new();
    all.extend(cycles.iter().enumerate().map(|(i, c)| (c.stamp_ns, 0, i)));
    all.extend(log.can.iter().enumerate().map(|(i, f)| (f.stamp_ns, 1, i)));
    all.extend(
        log.roads
            .iter()
            .enumerate()
            .map(|(i, e)| (e.stamp_ns, 2, i)),
    );
    all.extend(
        log.truth
            .iter()
            .enumerate()
            .map(|(i, g)| (g.stamp_ns, 3, i)),
    );
    all.extend(
        log.audio_blocks
            .iter()
            .enumerate()
            .map(|(i, b)| (b.stamp_ns, 4, i)),
    );
    // by stamp, each topic in its own order
    all.sort_by_key(|&(t, topic, i)| (t, topic, i));
    for (_, topic, i) in all {
        match topic {
            0 => w.write(topics::CYCLE, &cycles[i]).unwrap(),
            1 => w.write(topics::CAN_LOG, &log.can[i]).unwrap(),
            2 => w.write(topics::ROAD, &log.roads[i]).unwrap(),
            3 => w.write(topics::TRUTH, &log.truth[i]).unwrap(),
            _ => w.write(topics::AUDIO, &log.audio_blocks[i]).unwrap(),
        }
    }
    w.finish().unwrap();
}

fn replay_json(log: &Path, closed: bool) -> Value {
    let mut args = vec![os("replay"), os("--json")];
    if closed {
        args.push(os("--closed-loop"));
    }
    args.push(log.as_os_str());
    let (_, stdout, stderr) = grip(&args);
    stdout
        .lines()
        .find(|l| l.starts_with('{'))
        .and_then(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("no JSON object:\n{stdout}\n{stderr}"))
}

#[test]
fn a_command_sent_while_the_plant_drained_is_placed_by_the_ground_truth() {
    let d = tempfile::tempdir().unwrap();
    let (ok, out, err) = grip(&[
        os("generate"),
        os("--out"),
        d.path().as_os_str(),
        os("--count"),
        os("1"),
        os("--scenario"),
        os("e2e"),
    ]);
    assert!(ok, "{out}{err}");
    let src = d.path().join("gen-00000-s1.mcap");
    let log = DriveLog::load_with(&src, LoadOptions { audio: true }).unwrap();
    let tx: Vec<u64> = log
        .can
        .iter()
        .filter(|f| f.direction == can_dir::TX)
        .map(|f| f.stamp_ns)
        .collect();
    assert!(tx.len() >= log.cycles.len());
    // a cycle in the drive whose command changed by more than 1 N m, the
    // car moving, its command reaching the next plant cycle
    let k = (1..log.cycles.len())
        .find(|&k| {
            let (c, p) = (&log.cycles[k], &log.cycles[k - 1]);
            let moving = log
                .truth
                .iter()
                .find(|g| g.stamp_ns > tx[k])
                .is_some_and(|g| g.v > 1.0);
            c.safe_state == 0 && moving && (c.torque_cmd - p.torque_cmd).abs() > 1.0
        })
        .expect("a cycle whose command changed");
    let next_plant = log
        .truth
        .iter()
        .find(|g| g.stamp_ns > tx[k])
        .unwrap()
        .stamp_ns;
    let mut cycles = log.cycles.clone();
    let c = &mut cycles[k];
    let woke = c.stamp_ns.wrapping_add_signed(c.wakeup_latency_ns);
    c.compute_ns = next_plant + 500 - woke;
    let raced = d.path().join("raced.mcap");
    write_with_cycles(&raced, &log, &cycles);

    // open loop: the compute time is carried over, nothing else changes
    let r = replay_json(&raced, false);
    assert_eq!(r["identical"], true, "open loop: {r}");

    // closed loop: the command is the plant cycle's it raced, as the
    // logged ground truth shows
    let r = replay_json(&raced, true);
    assert_eq!(r["status"], "replayed", "{r}");
    assert_eq!(r["identical"], true, "closed loop, cycle {k}: {r}");
    assert_eq!(r["differing_messages"], 0, "{r}");
    for m in ["slip_deviation", "distance_m", "energy_j"] {
        assert_eq!(r["old"]["metrics"][m], r["new"]["metrics"][m], "{m}: {r}");
    }
    let races = &r["command_races"];
    assert_eq!(races["racing"], 1, "{r}");
    assert_eq!(races["early"], serde_json::json!([k]), "{r}");
}
