//! The control loop's health over the scenario window (`Summary::control`,
//! what `grip drive` fails a drive on and `grip inspect` prints): a drive
//! whose loop lost control and never regained it (its bus gone for good:
//! the safe state to the end, no frame received) against drives with
//! brief safe-state entries that recovered, as a loaded machine or a
//! bounded bus outage gives them. Built on constructed logs and the API
//! `grip drive` and `grip inspect` use (`summarize`, `Summary::render`).

use grip_drive::summary::{CONTROL_LOST_MIN_S, ControlHealth};
use grip_drive::{DriveLog, summarize};
use grip_io::can::protocol::{MsgKind, Protocol};
use grip_msgs::{CanFrame, CycleRecord, can_dir};
use grip_physics::VehicleParams;

const MS: u64 = 1_000_000;
/// The plant holds the car for 10 ms; the scenario starts at the last
/// held sample (9 ms) and lasts 3 s.
const START_MS: u64 = 9;
const DURATION_S: f64 = 3.0;

/// A drive: ground truth every ms from 0 to 3.1 s (held 10 ms, then
/// moving), a cycle record every ms to 3.2 s, in the safe state where
/// `safe(t_ms)` says (t from the scenario start, ms; its input-timeout
/// counter counts the entries), and the three messages the loop needs
/// received every ms where `rx(t_ms)` says.
fn drive(safe: impl Fn(i64) -> bool, rx: impl Fn(i64) -> bool) -> DriveLog {
    let truth = (0..3110u64)
        .map(grip_testkit::drives::asphalt_truth)
        .collect();
    let rel = |k: u64| k as i64 - START_MS as i64;
    let mut cycles = Vec::new();
    let mut timeouts = 0;
    let mut was_safe = false;
    for k in 0..3200u64 {
        let mut c = CycleRecord::zeroed();
        c.seq = k;
        c.stamp_ns = k * MS;
        let s = safe(rel(k));
        if s && !was_safe {
            timeouts += 1;
        }
        was_safe = s;
        c.safe_state = u8::from(s);
        c.torque_cmd = if s { 0.0 } else { 200.0 };
        c.faults.timeout = timeouts;
        cycles.push(c);
    }
    let p = Protocol::builtin();
    let mut can = Vec::new();
    for k in 0..3200u64 {
        if !rx(rel(k)) {
            continue;
        }
        for kind in [
            MsgKind::WheelSpeeds,
            MsgKind::MotorStatus,
            MsgKind::DriverDemand,
        ] {
            can.push(CanFrame {
                stamp_ns: k * MS,
                direction: can_dir::RX,
                ..CanFrame::new(p.spec(kind).id, &[0; 8])
            });
        }
    }
    let mut log = DriveLog {
        path: "control.mcap".into(),
        truth,
        cycles,
        can,
        recorder: Some(Default::default()),
        ..DriveLog::default()
    };
    log.run.insert("scenario".into(), "test".into());
    log.run
        .insert("scenario_duration_s".into(), DURATION_S.to_string());
    log
}

fn control(log: &DriveLog) -> (ControlHealth, String, Vec<String>) {
    let s = summarize(log, &VehicleParams::default(), "test", None);
    let r = s.render();
    (s.control.expect("a scenario window"), r, s.warnings)
}

/// The bus gone for good 1.5 s into the scenario (the socket-reopen bug
/// of 2026-12-05): no frame received from then on, the safe state from
/// 1.52 s (the input timeout) to the end: 1.48 s without control at the
/// end of the scenario. Control lost and not regained: said with when,
/// for how long and why, in the loop's section and as a warning.
#[test]
fn a_drive_ending_in_a_long_safe_state_lost_control() {
    let log = drive(|t| !(0..1520).contains(&t) && t >= 0, |t| t < 1500);
    let (c, r, w) = control(&log);
    assert!(c.lost(), "{c:?}");
    assert!(!c.never_in_control);
    let (since, d) = c.end_out.unwrap();
    assert!((since - 1.520).abs() < 1e-9, "{since}");
    assert!((d - 1.480).abs() < 1e-9, "{d}");
    let line = c.line();
    for want in [
        "CONTROL LOST AND NOT REGAINED: in the safe state from 1.520 s to the scenario's end at 3.000 s (1.480 s;",
        "input timeouts +1",
        "tcs-loop received no CAN frame from then to the scenario's end (its last one at 1.499 s",
    ] {
        assert!(line.contains(want), "{want:?} not in {line}");
    }
    assert!(r.contains(&format!("    control: {line}")), "{r}");
    assert!(w.contains(&line), "{w:?}");
}

/// Brief safe-state entries that recover (5 ms and 3 ms: a loaded
/// machine's stalls, frames late), and one that recovers 0.3 s after a
/// bus outage: not a lost control; the line counts them and names the
/// longest. The stop's safe state (after the scenario's end) is not in
/// the window.
#[test]
fn brief_entries_that_recover_are_not_a_lost_control() {
    let safe = |t: i64| {
        !(0..3050).contains(&t)
            || (1500..1505).contains(&t)
            || (2000..2003).contains(&t)
            || (2500..2800).contains(&t)
    };
    let log = drive(safe, |t| {
        !(1500..1504).contains(&t) && !(2480..2750).contains(&t)
    });
    let (c, r, w) = control(&log);
    assert!(!c.lost(), "{c:?}");
    assert_eq!(c.end_out, None);
    assert_eq!((c.entries, c.recovered), (3, 3));
    let line = c.line();
    assert_eq!(
        line,
        "in control at the end of the scenario; 3 safe-state entries during it, all recovered (longest 0.300 s, from 2.500 s)"
    );
    assert!(r.contains(&format!("    control: {line}")), "{r}");
    assert!(!w.iter().any(|w| w.contains("CONTROL")), "{w:?}");
    // no entry at all
    let (c, _, _) = control(&drive(|t| !(0..3050).contains(&t), |_| true));
    assert!(!c.lost());
    assert_eq!(
        c.line(),
        "in control at the end of the scenario; no safe-state entry during it"
    );
}

/// In the safe state at the end, but for less than the rule's second (an
/// entry 0.5 s before the end, frames still arriving): said, not a lost
/// control; from the rule's second on it is.
#[test]
fn a_safe_state_at_the_end_fails_from_the_rules_second_on() {
    let (c, _, _) = control(&drive(|t| !(0..2500).contains(&t), |_| true));
    assert!(!c.lost(), "{c:?}");
    let line = c.line();
    assert!(
        line.starts_with("in the safe state for the last 0.500 s of the scenario (from 2.500 s; under the 1 s that fails a drive)"),
        "{line}"
    );
    assert!(
        line.contains("tcs-loop received 1500 CAN frames in it (0 rejected by the E2E check)"),
        "{line}"
    );
    let at = 3000 - (CONTROL_LOST_MIN_S * 1e3) as i64;
    let (c, _, _) = control(&drive(|t| !(0..at).contains(&t), |_| true));
    assert!(c.lost(), "{c:?}");
}

/// Never in control during the scenario (the loop in its safe state
/// throughout, the bus gone before the start), and no cycle record in
/// the window at all: both are a lost control.
#[test]
fn never_in_control_or_no_record_is_a_lost_control() {
    let (c, r, _) = control(&drive(|_| true, |t| t < -5));
    assert!(c.lost() && c.never_in_control, "{c:?}");
    let line = c.line();
    assert!(
        line.starts_with(
            "CONTROL NEVER HELD: the loop was in its safe state for the whole scenario window (0.000-3.000 s, 3000 cycles)"
        ),
        "{line}"
    );
    assert!(line.contains("received no CAN frame"), "{line}");
    assert!(r.contains("CONTROL NEVER HELD"), "{r}");

    let mut log = drive(|t| t < 0, |_| true);
    log.cycles.retain(|c| c.stamp_ns < START_MS * MS);
    let (c, _, _) = control(&log);
    assert!(c.lost() && c.cycles == 0, "{c:?}");
    assert!(c.line().starts_with("CONTROL NOT SHOWN"), "{}", c.line());
}

/// The cycle records stop 2 s before the scenario's end, the last in
/// control (the loop hung, or its records lost): no cycle in control for
/// the last 2 s, a lost control; a record gap of a few ms at the very end
/// is not.
#[test]
fn records_that_stop_long_before_the_end_are_a_lost_control() {
    let mut log = drive(|t| t < 0, |_| true);
    log.cycles.retain(|c| c.stamp_ns < (START_MS + 1000) * MS);
    let (c, _, _) = control(&log);
    assert!(c.lost(), "{c:?}");
    assert!(
        c.line().starts_with(
            "CONTROL LOST AND NOT REGAINED: without a cycle in control (0 safe-state cycle records, then none) from 1.000 s"
        ),
        "{}",
        c.line()
    );
    let mut log = drive(|t| t < 0, |_| true);
    log.cycles.retain(|c| c.stamp_ns < (START_MS + 2996) * MS);
    let (c, _, _) = control(&log);
    assert!(!c.lost() && c.end_out.is_none(), "{c:?}");
}

/// `grip inspect A B`: a side that lost control heads the table with a
/// warning (its metrics are not those of a controlled drive); none when
/// both held control.
#[test]
fn compare_warns_about_a_side_that_lost_control() {
    let v = VehicleParams::default();
    let lost = summarize(
        &drive(|t| !(0..1520).contains(&t) && t >= 0, |t| t < 1500),
        &v,
        "test",
        None,
    );
    let held = summarize(&drive(|t| t < 0, |_| true), &v, "test", None);
    let c = grip_drive::summary::compare(&lost, &held);
    assert!(
        c.contains("A's control loop lost control and did not regain it: CONTROL LOST"),
        "{c}"
    );
    let c = grip_drive::summary::compare(&held, &held);
    assert!(!c.contains("lost control"), "{c}");
}

/// A damaged log's absurd stamps (0 next to 2^63 and u64::MAX) give a
/// summary, not an overflow panic in the loop timing's periods.
#[test]
fn absurd_cycle_stamps_do_not_panic_the_summary() {
    let cycles = [0, 1u64 << 63, 1, u64::MAX, 7]
        .into_iter()
        .enumerate()
        .map(|(k, t)| {
            let mut c = CycleRecord::zeroed();
            c.seq = k as u64;
            c.stamp_ns = t;
            c
        })
        .collect();
    let log = DriveLog {
        path: "absurd.mcap".into(),
        cycles,
        ..DriveLog::default()
    };
    let s = summarize(&log, &VehicleParams::default(), "test", None);
    assert_eq!(s.timing.cycles, 5);
    assert!(!s.render().is_empty());
}

/// A drive cut short (a service killed 1.2 s into the 3 s scenario: the
/// ground truth and the loop's records stop there), the loop in control
/// to its last record: said of the log's window, not of the scenario's
/// end (a fail-safe trial read "in control at the end of the scenario"
/// for a drive whose tcs-loop had been killed).
#[test]
fn a_drive_cut_short_is_not_said_in_control_at_the_scenario_s_end() {
    let mut log = drive(|t| !(0..3050).contains(&t), |_| true);
    log.truth.retain(|g| g.stamp_ns < 1_210 * MS);
    log.cycles.retain(|c| c.stamp_ns < 1_210 * MS);
    let (c, r, _) = control(&log);
    assert!(!c.lost(), "{c:?}");
    let (w, d) = c.cut_short.expect("a partial window");
    assert!((d - DURATION_S).abs() < 1e-9 && w < 1.21, "{w} {d}");
    let line = c.line();
    assert!(
        line.starts_with(&format!(
            "in control at the end of the log's scenario window, {w:.3} s of the 3.000 s scenario: the log ends there"
        )),
        "{line}"
    );
    assert!(!r.contains("in control at the end of the scenario;"), "{r}");
    // the whole drive: the scenario's end, as before
    let (c, _, _) = control(&drive(|t| !(0..3050).contains(&t), |_| true));
    assert_eq!(c.cut_short, None);
}
