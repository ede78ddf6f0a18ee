//! The control loop judged from outside, on the wire: tcs-loop's
//! TorqueCommands and its inputs as a [`CaptureLog`] of `vcan0` holds them.
//! Used by the HIL fault matrix (`tests/hil_faults.rs`) to tell a fault that
//! reached the loop from a stall of the emulated machine, which silences
//! the loop's inputs first.

use anyhow::{Context, ensure};

use grip_msgs::{CanFrame, CycleRecord, can_dir, can_flags};

use crate::hil::{CaptureLog, Dbc};
use crate::hil_drives::{SENSOR_TIMEOUT_MS, VM_MARGIN_MS, ms, ns, sig};

/// The enabled (controlling) TorqueCommands of the capture, (time, Nm).
pub fn enabled_commands(cap: &CaptureLog, dbc: &Dbc) -> anyhow::Result<Vec<(u64, bool)>> {
    let id = dbc.by_name("TorqueCommand")?.id;
    Ok(cap
        .with_id(id)
        .map(|f| (f.t_ns, sig(dbc, "TorqueCommand", "Enable", f) == 1.0))
        .collect())
}

/// The times of the valid (DLC, CRC) frames of message `name` on the wire
/// in `[t0, t1]`.
fn valid_frame_times(
    cap: &CaptureLog,
    dbc: &Dbc,
    name: &str,
    t0: u64,
    t1: u64,
) -> anyhow::Result<Vec<u64>> {
    let m = dbc.by_name(name)?;
    Ok(cap
        .with_id(m.id)
        .filter(|f| f.t_ns >= t0 && f.t_ns <= t1)
        .filter(|f| f.frame.len == m.dlc && f.frame.data[0] == m.expected_crc(&f.data8()))
        .map(|f| f.t_ns)
        .collect())
}

/// The times of consecutive valid (DLC, CRC) frames of message `name` on
/// the wire in `[t0, t1]`, as (before, after) pairs.
pub fn frame_gaps(
    cap: &CaptureLog,
    dbc: &Dbc,
    name: &str,
    t0: u64,
    t1: u64,
) -> anyhow::Result<Vec<(u64, u64)>> {
    let t = valid_frame_times(cap, dbc, name, t0, t1)?;
    Ok(t.windows(2).map(|w| (w[0], w[1])).collect())
}

/// The first gap between consecutive `stamps` (ascending) that overlaps
/// `[t0, t1]` (its first stamp before `t1`, its second after `t0`), lasts
/// at least `min_ms` and passes `accept`: the one search of an input's
/// silence, on the wire ([`silence_overlapping`]) and as the loop read it
/// ([`late_delivery`]).
fn overlapping_gap(
    stamps: impl IntoIterator<Item = u64>,
    t0: u64,
    t1: u64,
    min_ms: f64,
    mut accept: impl FnMut(u64, u64) -> bool,
) -> Option<(u64, u64)> {
    let mut prev: Option<u64> = None;
    for b in stamps {
        if let Some(a) = prev.replace(b)
            && a <= t1
            && b >= t0
            && ms(b as i128 - a as i128) >= min_ms
            && accept(a, b)
        {
            return Some((a, b));
        }
    }
    None
}

/// Longest gap between consecutive valid (DLC, CRC) frames of message
/// `name` on the wire in `[t0, t1]`, ms.
pub fn frame_gap_ms(
    cap: &CaptureLog,
    dbc: &Dbc,
    name: &str,
    t0: u64,
    t1: u64,
) -> anyhow::Result<f64> {
    Ok(frame_gaps(cap, dbc, name, t0, t1)?
        .iter()
        .map(|&(a, b)| ms(b as i128 - a as i128))
        .fold(0.0, f64::max))
}

/// Longest gap between consecutive WheelSpeeds frames on the wire in
/// `[t0, t1]`, ms: a gap there is plant-sim (or the whole machine) stalled,
/// which no fault on tcs-loop's side explains.
pub fn sensor_gap_ms(cap: &CaptureLog, dbc: &Dbc, t0: u64, t1: u64) -> anyhow::Result<f64> {
    frame_gap_ms(cap, dbc, "WheelSpeeds", t0, t1)
}

/// tcs-loop's inputs and their timeouts (config/tcs-loop.toml `[safety]`):
/// WheelSpeeds and MotorStatus `sensor_timeout_ms`, DriverDemand
/// `demand_timeout_ms`.
pub const INPUTS: [(&str, f64); 3] = [
    ("WheelSpeeds", SENSOR_TIMEOUT_MS),
    ("MotorStatus", SENSOR_TIMEOUT_MS),
    ("DriverDemand", DEMAND_TIMEOUT_MS),
];
/// How far before a window of [`loop_unaffected`] an input's silence is
/// looked for: the safe state outlasts it by `RECOVER_MS` and more under
/// emulation.
pub const LEAD_IN_MS: f64 = 200.0;
/// tcs-loop's `[safety] demand_timeout_ms` (config/tcs-loop.toml).
pub const DEMAND_TIMEOUT_MS: f64 = 50.0;

/// Each of tcs-loop's [`INPUTS`] with its longest gap on the wire in
/// `[t0, t1]`, for the report.
pub fn input_gaps(cap: &CaptureLog, dbc: &Dbc, t0: u64, t1: u64) -> anyhow::Result<String> {
    let mut report = Vec::new();
    for (name, _) in INPUTS {
        let gap = frame_gap_ms(cap, dbc, name, t0, t1)?;
        report.push(format!("{name} {gap:.1} ms"));
    }
    Ok(report.join(", "))
}

/// The first of tcs-loop's [`INPUTS`] silent on the wire for at least its
/// timeout in a gap that overlaps `[t0, t1]`: what explains a safe state
/// or a pause of the loop there (a stall of plant-sim or of the machine).
pub fn silence_overlapping(
    cap: &CaptureLog,
    dbc: &Dbc,
    t0: u64,
    t1: u64,
) -> anyhow::Result<Option<String>> {
    // a gap that overlaps [t0, t1] has its first frame before t1 and its
    // second after t0; look a timeout's worth further out on each side
    let pad = ns(DEMAND_TIMEOUT_MS * 2.0);
    for (name, timeout) in INPUTS {
        let times = valid_frame_times(cap, dbc, name, t0.saturating_sub(pad), t1 + pad)?;
        if let Some((a, b)) = overlapping_gap(times, t0, t1, timeout, |_, _| true) {
            return Ok(Some(format!(
                "{name} silent {:.1} ms on the wire (timeout {timeout} ms)",
                ms(b as i128 - a as i128)
            )));
        }
    }
    Ok(None)
}

/// What tcs-loop itself saw, from its drive log: its CAN log (a received
/// frame's `stamp_ns` is its arrival, the kernel's receive time; each
/// cycle's received frames are logged before its command, whose stamp is
/// the cycle's clock read right after the drain: [`read_times`]) and its
/// cycle records.
#[derive(Debug, Clone, Copy)]
pub struct LoopLog<'a> {
    /// tcs-loop's `CAN_LOG` copies.
    pub can: &'a [CanFrame],
    /// tcs-loop's cycle records.
    pub cycles: &'a [CycleRecord],
}

/// When tcs-loop read each frame of its CAN log that it received, in log
/// order, with the frame: the stamp of the command its cycle sent next
/// (the cycle's clock, read right after its drain), or, past the last
/// command, the frame's own stamp. Since 2026-12-07 a received frame's own
/// stamp is its arrival (the kernel's receive time), which says nothing of
/// a kernel that delivered it late.
pub fn read_times<'a>(can: &'a [CanFrame]) -> impl Iterator<Item = (&'a CanFrame, u64)> + 'a {
    let commands: Vec<u64> = can
        .iter()
        .filter(|f| f.direction == can_dir::TX)
        .map(|f| f.stamp_ns)
        .collect();
    can.iter()
        .zip(grip_drive::log::commands_before(can))
        .filter(|(f, _)| f.direction == can_dir::RX)
        .map(move |(f, k)| (f, commands.get(k).copied().unwrap_or(f.stamp_ns)))
}

/// The first of tcs-loop's [`INPUTS`] that reached the loop ([`read_times`]
/// in its CAN log) at least its timeout apart, in a gap overlapping `[t0,
/// t1]`, while the loop's cycles kept running through the gap (at least
/// half of its 1 ms cycles have records there): the frames were on the
/// wire but the kernel delivered them late (its network processing
/// stalled), which no fault on the loop's side explains either. A loop
/// that itself stalled has no cycle records in the gap and is not excused.
pub fn late_delivery(log: &LoopLog, dbc: &Dbc, t0: u64, t1: u64) -> anyhow::Result<Option<String>> {
    let pad = ns(DEMAND_TIMEOUT_MS * 2.0);
    for (name, timeout) in INPUTS {
        let id = dbc.by_name(name)?.id;
        let received = read_times(log.can)
            .filter(|&(f, read)| {
                f.id == id
                    && f.flags & can_flags::E2E_REJECTED == 0
                    && read + pad >= t0
                    && read <= t1 + pad
            })
            .map(|(_, read)| read);
        let ran = |a: u64, b: u64| {
            log.cycles
                .iter()
                .filter(|c| c.stamp_ns > a && c.stamp_ns < b)
                .count()
        };
        // the loop ran through the gap: the frames were late, not absent
        let mut cycles = 0;
        if let Some((a, b)) = overlapping_gap(received, t0, t1, timeout, |a, b| {
            cycles = ran(a, b);
            cycles as f64 >= 0.5 * ms(b as i128 - a as i128)
        }) {
            let gap = ms(b as i128 - a as i128);
            return Ok(Some(format!(
                "{name} reached tcs-loop {gap:.1} ms apart (timeout {timeout} ms) while it ran {cycles} cycles: on the wire in time, delivered late by the kernel"
            )));
        }
    }
    Ok(None)
}

/// Share of a window's commands that must be enabled for the window to say
/// anything about the loop; below it, stalls of the machine (each one
/// explained) took too much of it and the drive counts as disturbed.
pub const MIN_ENABLED_SHARE: f64 = 0.8;

/// The loop from outside, over `[t0, t1]`: every command enabled (no safe
/// state) and none more than [`VM_MARGIN_MS`] after the one before, except
/// where tcs-loop's own inputs explain it. Each safe state (a run of
/// disabled commands) must follow one of [`INPUTS`] silent on the wire
/// for its timeout or more, in the [`LEAD_IN_MS`] before its first
/// disabled command (a stall of plant-sim or of the machine: the loop then
/// does what it must); each pause between commands longer than
/// [`VM_MARGIN_MS`] must overlap such a silence. With the loop's own
/// `log`, a safe state also counts as explained when its inputs reached
/// the loop late while it kept cycling ([`late_delivery`]). One that
/// nothing explains is a failure: the fault reached the loop. If explained
/// safe states leave less than [`MIN_ENABLED_SHARE`] of the window's
/// commands enabled, the drive is disturbed (retried).
pub fn loop_unaffected(
    cap: &CaptureLog,
    dbc: &Dbc,
    log: Option<&LoopLog>,
    t0: u64,
    t1: u64,
    what: &str,
) -> anyhow::Result<Option<String>> {
    let cmds: Vec<(u64, bool)> = enabled_commands(cap, dbc)?
        .into_iter()
        .filter(|&(t, _)| t >= t0 && t <= t1)
        .collect();
    ensure!(
        cmds.len() > 10,
        "{what}: only {} TorqueCommands on the wire in the {:.0} ms around it",
        cmds.len(),
        ms(t1 as i128 - t0 as i128)
    );
    let max_gap = cmds
        .windows(2)
        .map(|w| ms(w[1].0 as i128 - w[0].0 as i128))
        .fold(0.0, f64::max);
    let disabled = cmds.iter().filter(|c| !c.1).count();
    let gaps = input_gaps(cap, dbc, t0.saturating_sub(ns(LEAD_IN_MS)), t1)?;
    println!(
        "{what}: {} commands on the wire in {:.0} ms, longest gap {max_gap:.1} ms, {disabled} disabled (safe state); longest input gaps on the wire (from {LEAD_IN_MS} ms before): {gaps}",
        cmds.len(),
        ms(t1 as i128 - t0 as i128)
    );
    // each safe state: its first disabled command, explained or not
    let mut explained = Vec::new();
    for (k, &(t, on)) in cmds.iter().enumerate() {
        if on || (k > 0 && !cmds[k - 1].1) {
            continue;
        }
        // what tcs-loop saw before its safe state: the inputs over the
        // 100 ms before the first disabled command
        let before = input_gaps(cap, dbc, t.saturating_sub(100_000_000), t)?;
        let from = t.saturating_sub(ns(LEAD_IN_MS));
        let why = match silence_overlapping(cap, dbc, from, t)? {
            Some(w) => Some(w),
            None => match log {
                Some(l) => late_delivery(l, dbc, from, t)?,
                None => None,
            },
        };
        println!(
            "{what}: safe state from {:.1} ms into the window; input gaps in the 100 ms before it: {before}; {}",
            ms(t as i128 - t0 as i128),
            why.as_deref().unwrap_or("nothing on the wire explains it")
        );
        let why = why.with_context(|| {
            format!(
                "{what}: tcs-loop went to its safe state {:.1} ms into the window though none of its inputs was silent for its timeout in the {LEAD_IN_MS} ms before",
                ms(t as i128 - t0 as i128)
            )
        })?;
        explained.push(why);
    }
    for w in cmds.windows(2) {
        let g = ms(w[1].0 as i128 - w[0].0 as i128);
        if g <= VM_MARGIN_MS {
            continue;
        }
        let why = silence_overlapping(cap, dbc, w[0].0, w[1].0)?.with_context(|| {
            format!(
                "{what}: {g:.1} ms between two commands (bound {VM_MARGIN_MS} ms) and none of tcs-loop's inputs silent for its timeout meanwhile"
            )
        })?;
        println!("{what}: {g:.1} ms between two commands; {why}");
        explained.push(why);
    }
    let share = 1.0 - disabled as f64 / cmds.len() as f64;
    if share < MIN_ENABLED_SHARE {
        return Ok(Some(format!(
            "{what}: only {:.0} % of the commands enabled, each safe state explained by a stall of the machine ({})",
            share * 100.0,
            explained.join("; ")
        )));
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hil::{Captured, RawFrame};

    fn dbc() -> Dbc {
        Dbc::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/inverter.dbc"))
            .unwrap()
    }

    /// A 1 s capture as the DBC's cycle times make it: WheelSpeeds,
    /// MotorStatus and a TorqueCommand every 1 ms, DriverDemand every 10 ms (enabled unless `disabled`
    /// says so); WheelSpeeds left out over `ws_silent` (ms).
    fn capture(dbc: &Dbc, ws_silent: (u64, u64), disabled: (u64, u64)) -> CaptureLog {
        let frame = |name: &str, vals: &[(&str, f64)], k: u64, t_ms: u64| {
            let m = dbc.by_name(name).unwrap();
            let d = m.encode(vals, (k % 16) as u8).unwrap();
            Captured {
                t_ns: t_ms * 1_000_000,
                frame: RawFrame::new(m.id, &d[..m.dlc as usize]).unwrap(),
            }
        };
        let mut frames = Vec::new();
        for t in 0..1000u64 {
            if !(ws_silent.0..ws_silent.1).contains(&t) {
                frames.push(frame("WheelSpeeds", &[], t, t));
            }
            frames.push(frame("MotorStatus", &[], t, t));
            if t % 10 == 0 {
                frames.push(frame("DriverDemand", &[("TorqueDemand", 300.0)], t, t));
            }
            let on = !(disabled.0..disabled.1).contains(&t);
            frames.push(frame(
                "TorqueCommand",
                &[("Enable", if on { 1.0 } else { 0.0 })],
                t,
                t,
            ));
        }
        CaptureLog { frames, dropped: 0 }
    }

    const T1: u64 = 999_000_000;

    #[test]
    fn a_quiet_loop_is_unaffected() {
        let d = dbc();
        let cap = capture(&d, (0, 0), (0, 0));
        assert_eq!(loop_unaffected(&cap, &d, None, 0, T1, "t").unwrap(), None);
    }

    #[test]
    fn a_safe_state_after_silent_sensors_is_explained() {
        let d = dbc();
        // WheelSpeeds missing for 30 ms, safe state from 15 ms after it stopped
        let cap = capture(&d, (400, 430), (425, 480));
        assert_eq!(loop_unaffected(&cap, &d, None, 0, T1, "t").unwrap(), None);
    }

    #[test]
    fn a_safe_state_nothing_on_the_wire_explains_fails() {
        let d = dbc();
        let cap = capture(&d, (0, 0), (425, 480));
        let e = loop_unaffected(&cap, &d, None, 0, T1, "t").unwrap_err();
        assert!(e.to_string().contains("safe state"), "{e}");
    }

    #[test]
    fn a_silence_elsewhere_does_not_explain_a_safe_state() {
        let d = dbc();
        // sensors silent 300 ms before the safe state: more than LEAD_IN_MS
        let cap = capture(&d, (100, 130), (430, 480));
        assert!(loop_unaffected(&cap, &d, None, 0, T1, "t").is_err());
    }

    #[test]
    fn mostly_safe_state_is_a_disturbed_window() {
        let d = dbc();
        // explained, but 30 % of the window disabled
        let cap = capture(&d, (100, 130), (125, 425));
        let r = loop_unaffected(&cap, &d, None, 0, T1, "t").unwrap();
        assert!(r.is_some_and(|r| r.contains("enabled")));
    }

    #[test]
    fn a_pause_of_the_loop_needs_its_inputs_silent_too() {
        let d = dbc();
        let tc = d.by_name("TorqueCommand").unwrap().id;
        let pause = |mut cap: CaptureLog| {
            // no command for 150 ms (more than VM_MARGIN_MS)
            cap.frames
                .retain(|f| !(f.id() == tc && (400_000_000..550_000_000).contains(&f.t_ns)));
            cap
        };
        let alone = pause(capture(&d, (0, 0), (0, 0)));
        let e = loop_unaffected(&alone, &d, None, 0, T1, "t").unwrap_err();
        assert!(e.to_string().contains("between two commands"), "{e}");
        // the whole machine stalled: the sensors paused with it
        let stalled = pause(capture(&d, (400, 550), (0, 0)));
        assert_eq!(
            loop_unaffected(&stalled, &d, None, 0, T1, "t").unwrap(),
            None
        );
    }

    /// tcs-loop's log of the capture's input frames, as it writes it: each
    /// 1 ms cycle's received frames (stamped with their arrival on the
    /// wire) before its command (stamped with the cycle's time); frames
    /// that arrived over `late` (ms) are read at its end (the kernel held
    /// them), and no cycle runs over `stalled` (its frames are read by the
    /// first cycle after it).
    fn loop_log(
        cap: &CaptureLog,
        d: &Dbc,
        late: (u64, u64),
        stalled: (u64, u64),
    ) -> (Vec<CanFrame>, Vec<CycleRecord>) {
        let ids: Vec<u32> = INPUTS
            .iter()
            .map(|(n, _)| d.by_name(n).unwrap().id)
            .collect();
        let ran: Vec<u64> = (0..1000u64)
            .filter(|t| !(stalled.0..stalled.1).contains(t))
            .collect();
        // each cycle's received frames, by the cycle that read them
        let mut read_by: Vec<Vec<CanFrame>> = vec![Vec::new(); ran.len()];
        for f in cap.frames.iter().filter(|f| ids.contains(&f.id())) {
            let t_ms = f.t_ns / 1_000_000;
            // frames of the late stretch reach the loop at its end
            let reach_ns = if (late.0..late.1).contains(&t_ms) {
                late.1 * 1_000_000
            } else {
                f.t_ns
            };
            // drained by the first cycle whose drain (just before its
            // command) comes at or after that
            let k = ran.partition_point(|&c| c * 1_000_000 + 20_000 < reach_ns);
            if let Some(v) = read_by.get_mut(k) {
                v.push(CanFrame {
                    stamp_ns: f.t_ns,
                    id: f.id(),
                    dlc: 8,
                    direction: can_dir::RX,
                    ..CanFrame::default()
                });
            }
        }
        let tc = d.by_name("TorqueCommand").unwrap().id;
        let mut can = Vec::new();
        for (&t, rx) in ran.iter().zip(read_by) {
            can.extend(rx);
            can.push(CanFrame {
                stamp_ns: t * 1_000_000 + 20_000,
                id: tc,
                dlc: 8,
                direction: can_dir::TX,
                ..CanFrame::default()
            });
        }
        let cycles = ran
            .iter()
            .map(|&t| CycleRecord {
                stamp_ns: t * 1_000_000,
                ..CycleRecord::zeroed()
            })
            .collect();
        (can, cycles)
    }

    #[test]
    fn frames_the_kernel_delivered_late_explain_a_safe_state() {
        let d = dbc();
        // on the wire in time; the loop read them 15 ms late and went safe
        let cap = capture(&d, (0, 0), (425, 480));
        let (can, cycles) = loop_log(&cap, &d, (405, 420), (0, 0));
        let log = LoopLog {
            can: &can,
            cycles: &cycles,
        };
        assert!(loop_unaffected(&cap, &d, None, 0, T1, "t").is_err());
        assert_eq!(
            loop_unaffected(&cap, &d, Some(&log), 0, T1, "t").unwrap(),
            None
        );
        // the same gap while the loop itself did not cycle: not excused
        let (can, cycles) = loop_log(&cap, &d, (405, 420), (404, 421));
        let stalled = LoopLog {
            can: &can,
            cycles: &cycles,
        };
        assert!(loop_unaffected(&cap, &d, Some(&stalled), 0, T1, "t").is_err());
    }
}
