//! Refusal of a log whose timing no drive could have logged, before any of
//! it is replayed: a replay runs the services' own code on the logged
//! stamps, compute times and sequence numbers, so one impossible value
//! (a damaged or hand-made log) would otherwise overflow the arithmetic
//! of a scripted clock or make the closed loop step the plant towards a
//! time no drive reaches. Each refusal names the log, the topic and
//! message (0-based, as the replay's comparison counts them), the field
//! and its value, and why no drive logs it.

use anyhow::bail;
use grip_drive::DriveLog;
use grip_msgs::{CanFrame, topics};

use super::CanPerCycle;

/// The longest compute time and wake-up latency (either way) a cycle
/// record may carry: an hour. A stalled process (stopped, swapped out, a
/// machine that slept) wakes seconds late, and such a drive is one to
/// replay; an hour is no cycle of a drive (a damaged or hand-made log: the
/// audit's u64::MAX overflowed the replay's clock readings).
pub const MAX_CYCLE_TIME_NS: u64 = 3_600_000_000_000;

/// How far a TorqueCommand's stamp (its cycle's "now") may lie after the
/// previous command's, or from its own cycle's deadline: an hour, as
/// [`MAX_CYCLE_TIME_NS`] (a loop stopped for seconds and resumed is a
/// drive; a command stamped 2^63 ns made the closed loop step the plant
/// towards it without end).
pub const MAX_COMMAND_GAP_NS: u64 = 3_600_000_000_000;

/// The shortest period plant-sim runs at, ns: its `rate_hz` is at most
/// 100 kHz (and tcs-loop's too).
pub const MIN_PLANT_PERIOD_NS: u64 = 10_000;

/// Seconds of `ns` for a message.
fn secs(ns: u64) -> String {
    format!("{:.3} s", ns as f64 * 1e-9)
}

/// The cycle records' compute times and wake-up latencies: each within
/// [`MAX_CYCLE_TIME_NS`].
pub fn cycles(log: &DriveLog) -> anyhow::Result<()> {
    for (i, c) in log.cycles.iter().enumerate() {
        if c.compute_ns > MAX_CYCLE_TIME_NS {
            bail!(
                "{}: {} message {i} (seq {}): compute_ns = {} ({}), more than the {} a cycle of the loop can take: the log is damaged and cannot be replayed",
                log.path.display(),
                topics::CYCLE,
                c.seq,
                c.compute_ns,
                secs(c.compute_ns),
                secs(MAX_CYCLE_TIME_NS)
            );
        }
        if c.wakeup_latency_ns.unsigned_abs() > MAX_CYCLE_TIME_NS {
            bail!(
                "{}: {} message {i} (seq {}): wakeup_latency_ns = {} ({}{}), more than {} from its deadline, which no cycle of the loop wakes: the log is damaged and cannot be replayed",
                log.path.display(),
                topics::CYCLE,
                c.seq,
                c.wakeup_latency_ns,
                if c.wakeup_latency_ns < 0 { "-" } else { "" },
                secs(c.wakeup_latency_ns.unsigned_abs()),
                secs(MAX_CYCLE_TIME_NS)
            );
        }
    }
    Ok(())
}

/// The TorqueCommands' stamps (each cycle's "now", then the shutdown
/// command's) of a log split per cycle (`can`, from `log`): in order, none
/// before the previous one or more than [`MAX_COMMAND_GAP_NS`] after it,
/// and each cycle's within as much of its deadline.
pub fn commands(log: &DriveLog, can: &CanPerCycle) -> anyhow::Result<()> {
    // the CAN log's message index of every command, in order
    let index: Vec<usize> = log
        .can
        .iter()
        .enumerate()
        .filter(|(_, f)| f.direction == grip_msgs::can_dir::TX)
        .map(|(i, _)| i)
        .collect();
    let what = |k: usize| match log.cycles.get(k) {
        Some(c) => format!("the TorqueCommand of cycle seq {}", c.seq),
        None => "the shutdown command".to_owned(),
    };
    let mut prev: Option<&CanFrame> = None;
    for (k, f) in can.tx.iter().chain(&can.tail_tx).enumerate() {
        let at = format!(
            "{}: {} message {} ({})",
            log.path.display(),
            topics::CAN_LOG,
            index.get(k).copied().unwrap_or(k),
            what(k)
        );
        if let Some(p) = prev {
            if f.stamp_ns < p.stamp_ns {
                bail!(
                    "{at}: stamp_ns = {}, {} before the previous command's ({}): the loop's clock does not go back, the log is damaged and cannot be replayed",
                    f.stamp_ns,
                    secs(p.stamp_ns - f.stamp_ns),
                    p.stamp_ns
                );
            }
            if f.stamp_ns - p.stamp_ns > MAX_COMMAND_GAP_NS {
                bail!(
                    "{at}: stamp_ns = {}, {} after the previous command's ({}), more than the {} a cycle can lie after the one before it: the log is damaged and cannot be replayed",
                    f.stamp_ns,
                    secs(f.stamp_ns - p.stamp_ns),
                    p.stamp_ns,
                    secs(MAX_COMMAND_GAP_NS)
                );
            }
        }
        if let Some(c) = log.cycles.get(k)
            && f.stamp_ns.abs_diff(c.stamp_ns) > MAX_COMMAND_GAP_NS
        {
            bail!(
                "{at}: stamp_ns = {}, {} {} its cycle's deadline (stamp_ns {}), more than the {} a cycle's \"now\" can lie from it: the log is damaged and cannot be replayed",
                f.stamp_ns,
                secs(f.stamp_ns.abs_diff(c.stamp_ns)),
                if f.stamp_ns < c.stamp_ns {
                    "before"
                } else {
                    "after"
                },
                c.stamp_ns,
                secs(MAX_COMMAND_GAP_NS)
            );
        }
        prev = Some(f);
    }
    Ok(())
}

/// The ground truth's sequence numbers, as the closed loop maps them to
/// plant-sim's cycles (its cycle `seq` from cycle 0, a period apiece): the
/// first sample's cycle 0 no earlier than the clock's zero, and no more
/// cycles between two samples than plant-sim (at most 100 kHz) runs in
/// the time between their stamps.
pub fn truth(log: &DriveLog) -> anyhow::Result<()> {
    let truth = super::closed::rising(&log.truth);
    let refuse = |i: usize, why: String| -> anyhow::Result<()> {
        bail!(
            "{}: {} message {i}: {why}: its sequence numbers cannot be mapped to plant-sim's cycles, the log is damaged and --closed-loop cannot replay it",
            log.path.display(),
            topics::TRUTH,
        )
    };
    let Some(g0) = truth.first() else {
        return Ok(());
    };
    if g0
        .seq
        .checked_mul(MIN_PLANT_PERIOD_NS)
        .is_none_or(|t| t > g0.stamp_ns)
    {
        refuse(
            0,
            format!(
                "seq = {} at stamp_ns = {}: plant-sim (at most 100 kHz) would have started its cycle 0 before the clock's zero",
                g0.seq, g0.stamp_ns
            ),
        )?;
    }
    for (i, w) in truth.windows(2).enumerate() {
        let (p, g) = (&w[0], &w[1]);
        let dt = g.stamp_ns.saturating_sub(p.stamp_ns);
        // the cycles between them (rising: g.seq > p.seq)
        if g.seq - p.seq - 1 > dt / MIN_PLANT_PERIOD_NS {
            refuse(
                i + 1,
                format!(
                    "seq = {} at stamp_ns = {}, {} cycles after the previous sample's seq {} (stamp_ns {}): more than plant-sim (at most 100 kHz) runs in {}",
                    g.seq,
                    g.stamp_ns,
                    g.seq - p.seq,
                    p.seq,
                    p.stamp_ns,
                    secs(dt)
                ),
            )?;
        }
    }
    Ok(())
}

/// Everything a replay of `log` (in closed loop: `closed_loop`) takes from
/// its timing: the cycle records and commands ([`super::split_can`]), and
/// in closed loop the ground truth's sequence numbers ([`truth`]).
pub fn log(log: &DriveLog, closed_loop: bool) -> anyhow::Result<()> {
    super::split_can(log)?;
    if closed_loop {
        truth(log)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_msgs::{CycleRecord, GroundTruth, can_dir};

    const MS: u64 = 1_000_000;
    const T0: u64 = 1_000_000_000;

    /// A drive of `n` 1 ms cycles as tcs-loop logs it: each cycle's
    /// received frame and command (its "now", 30 µs after its deadline),
    /// the shutdown command, and plant-sim's ground truth from its cycle 0.
    fn drive(n: u64) -> DriveLog {
        let mut can = Vec::new();
        let cycles = (0..n)
            .map(|k| {
                let stamp_ns = T0 + k * MS;
                let mut rx = CanFrame::new(0x120, &[1, 2, 3]);
                rx.stamp_ns = stamp_ns + 25_000;
                let mut tx = CanFrame::new(0x100, &[4, 5]);
                tx.direction = can_dir::TX;
                tx.stamp_ns = stamp_ns + 30_000;
                can.extend([rx, tx]);
                CycleRecord {
                    seq: k,
                    stamp_ns,
                    wakeup_latency_ns: 20_000,
                    compute_ns: 40_000,
                    ..CycleRecord::zeroed()
                }
            })
            .collect();
        let mut stop = CanFrame::new(0x100, &[0, 0]);
        stop.direction = can_dir::TX;
        stop.stamp_ns = T0 + n * MS;
        can.push(stop);
        DriveLog {
            path: "wild.mcap".into(),
            cycles,
            can,
            truth: (0..n + 50)
                .map(|q| GroundTruth {
                    seq: q,
                    stamp_ns: T0 - 50 * MS + q * MS + 10_000,
                    ..GroundTruth::zeroed()
                })
                .collect(),
            ..DriveLog::default()
        }
    }

    fn refused(log: &DriveLog, closed_loop: bool) -> String {
        match log_check(log, closed_loop) {
            Ok(()) => panic!("accepted"),
            Err(e) => format!("{e:#}"),
        }
    }

    fn log_check(log: &DriveLog, closed_loop: bool) -> anyhow::Result<()> {
        super::log(log, closed_loop)
    }

    /// The drive as logged is accepted, open and closed loop.
    #[test]
    fn a_drive_s_timing_is_accepted() {
        let log = drive(200);
        log_check(&log, false).unwrap();
        log_check(&log, true).unwrap();
        // a cycle that woke 3 s late, computed 2 s, and the loop's next
        // command 5 s later: a stall, not damage
        let mut log = drive(200);
        log.cycles[100].wakeup_latency_ns = 3_000 * MS as i64;
        log.cycles[100].compute_ns = 2_000 * MS;
        log_check(&log, true).unwrap();
    }

    /// A cycle record's compute time or wake-up latency over an hour (the
    /// audit's u64::MAX and i64::MAX, which overflowed the replay's clock
    /// readings and tcs-loop's latency) is refused by `split_can`, which
    /// every replay takes its cycles from, naming the log, the record, the
    /// field and its value.
    #[test]
    fn a_cycle_s_impossible_compute_time_or_latency_is_refused() {
        let mut log = drive(200);
        log.cycles[100].compute_ns = u64::MAX;
        let e = format!("{:#}", super::super::split_can(&log).unwrap_err());
        assert_eq!(
            e,
            "wild.mcap: grip/tcs/cycle message 100 (seq 100): compute_ns = 18446744073709551615 (18446744073.710 s), more than the 3600.000 s a cycle of the loop can take: the log is damaged and cannot be replayed"
        );
        let mut log = drive(200);
        log.cycles[100].compute_ns = MAX_CYCLE_TIME_NS + 1;
        assert!(refused(&log, false).contains("compute_ns = 3600000000001 (3600.000 s)"));
        for (v, shown) in [
            (i64::MAX, "9223372036854775807 (9223372036.855 s)"),
            (i64::MIN, "-9223372036854775808 (-9223372036.855 s)"),
            (-3_700_000_000_000, "-3700000000000 (-3700.000 s)"),
        ] {
            let mut log = drive(200);
            log.cycles[7].wakeup_latency_ns = v;
            let e = format!("{:#}", super::super::split_can(&log).unwrap_err());
            assert_eq!(
                e,
                format!(
                    "wild.mcap: grip/tcs/cycle message 7 (seq 7): wakeup_latency_ns = {shown}, more than 3600.000 s from its deadline, which no cycle of the loop wakes: the log is damaged and cannot be replayed"
                )
            );
        }
    }

    /// A command stamped 2^63 (the audit's: the closed loop stepped the
    /// plant towards it without end), one that goes back, and one far from
    /// its cycle's deadline are refused, naming the CAN log's message.
    #[test]
    fn a_command_stamp_that_jumps_or_goes_back_is_refused() {
        let mut log = drive(200);
        // message 2k + 1 is cycle k's command
        log.can[2 * 30 + 1].stamp_ns = 1 << 63;
        assert_eq!(
            format!("{:#}", super::super::split_can(&log).unwrap_err()),
            "wild.mcap: grip/can/log message 61 (the TorqueCommand of cycle seq 30): stamp_ns = 9223372036854775808, 9223372035.826 s after the previous command's (1029030000), more than the 3600.000 s a cycle can lie after the one before it: the log is damaged and cannot be replayed"
        );
        let mut log = drive(200);
        log.can[2 * 30 + 1].stamp_ns = 5;
        assert_eq!(
            refused(&log, false),
            "wild.mcap: grip/can/log message 61 (the TorqueCommand of cycle seq 30): stamp_ns = 5, 1.029 s before the previous command's (1029030000): the loop's clock does not go back, the log is damaged and cannot be replayed"
        );
        // the shutdown command
        let mut log = drive(200);
        let last = log.can.len() - 1;
        log.can[last].stamp_ns = u64::MAX;
        let e = refused(&log, true);
        assert!(
            e.starts_with(
                "wild.mcap: grip/can/log message 400 (the shutdown command): stamp_ns = 18446744073709551615, "
            ),
            "{e}"
        );
        // every command 3000 s after the one before, far from its deadline
        let mut log = drive(200);
        let mut t = T0;
        for f in log.can.iter_mut().filter(|f| f.direction == can_dir::TX) {
            f.stamp_ns = t;
            t += 3_000_000 * MS;
        }
        assert_eq!(
            refused(&log, false),
            "wild.mcap: grip/can/log message 5 (the TorqueCommand of cycle seq 2): stamp_ns = 6001000000000, 5999.998 s after its cycle's deadline (stamp_ns 1002000000), more than the 3600.000 s a cycle's \"now\" can lie from it: the log is damaged and cannot be replayed"
        );
    }

    /// Ground-truth sequence numbers the closed loop cannot map to
    /// plant-sim's cycles (the audit's: every seq + 2^50, every seq
    /// u64::MAX, one seq jumping ahead) are refused in closed loop only
    /// (open loop does not run the plant).
    #[test]
    fn ground_truth_seq_numbers_that_cannot_be_mapped_are_refused_in_closed_loop() {
        let mut log = drive(200);
        for g in &mut log.truth {
            g.seq += 1 << 50;
        }
        log_check(&log, false).unwrap();
        assert_eq!(
            refused(&log, true),
            "wild.mcap: grip/plant/truth message 0: seq = 1125899906842624 at stamp_ns = 950010000: plant-sim (at most 100 kHz) would have started its cycle 0 before the clock's zero: its sequence numbers cannot be mapped to plant-sim's cycles, the log is damaged and --closed-loop cannot replay it"
        );
        for g in &mut log.truth {
            g.seq = u64::MAX;
        }
        assert!(
            refused(&log, true)
                .contains("message 0: seq = 18446744073709551615 at stamp_ns = 950010000: "),
            "{}",
            refused(&log, true)
        );
        // a seq jumping ahead mid-log, then back (a restarted plant: the
        // replay runs the samples before it)
        let mut log = drive(200);
        log.truth[100].seq = u64::MAX;
        assert_eq!(
            refused(&log, true),
            "wild.mcap: grip/plant/truth message 100: seq = 18446744073709551615 at stamp_ns = 1050010000, 18446744073709551516 cycles after the previous sample's seq 99 (stamp_ns 1049010000): more than plant-sim (at most 100 kHz) runs in 0.001 s: its sequence numbers cannot be mapped to plant-sim's cycles, the log is damaged and --closed-loop cannot replay it"
        );
        // a plant that started before the recorder, and a lost sample: mapped
        let mut log = drive(200);
        log.truth.drain(..20);
        log.truth.remove(50);
        log_check(&log, true).unwrap();
    }
}
