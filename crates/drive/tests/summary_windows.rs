//! The drive summary over a constructed front-mic drive: a hold, a
//! pre-roll in which the microphone (ahead of the wheel) reaches snow
//! before the scenario clock starts, the scenario, the stop. What is
//! counted during the scenario and what over the whole log, and what a
//! truncated log, or two unlike logs side by side, say. Built on the API
//! `grip inspect` uses (`summarize`, `Summary::render`, `summary::compare`)
//! and its text, so each test also runs against an older summary.

use grip_drive::{DriveLog, summarize, summary};
use grip_msgs::{CycleRecord, GroundTruth, RoadEstimate, name_to_bytes};
use grip_physics::VehicleParams;

/// The microphone's lead ahead of the driven wheel, m.
const LEAD: f64 = 0.15;
/// ms per sample: 1 kHz, 3 mm per ms while moving.
const STEP_M: f64 = 0.003;
/// Where snow begins, m (asphalt before).
const SNOW_AT: f64 = 0.09;

fn road(x: f64) -> (u32, &'static str) {
    if x >= SNOW_AT {
        (2, "snow")
    } else {
        (0, "asphalt")
    }
}

/// The wheel's x at sample k: held at -LEAD for 50 ms, the pre-roll up to
/// x = 0 at 100 ms (the scenario start), then moving on.
fn x_at(k: u64) -> f64 {
    match k {
        0..50 => -LEAD,
        50..100 => -LEAD + STEP_M * (k - 50) as f64,
        _ => STEP_M * (k - 100) as f64,
    }
}

/// The road at the microphone at t_ms.
fn mic_at(t_ms: u64) -> &'static str {
    road(x_at(t_ms) + LEAD).1
}

/// 400 samples of ground truth (the scenario 100-300 ms, the stop to 400
/// ms); the microphone reaches snow at 80 ms (x = -0.06 m), the wheel at
/// 130 ms. The loop's cycles run to 420 ms: in the safe state until 20 ms
/// (start-up), 5 deadline misses and an 8 ms wake-up at 30 ms, the safe
/// state again from 405 ms (the stop: plant-sim has ended). Estimates on
/// 20 ms frames every 10 ms name the road at the microphone at their
/// midpoint, except during the hold (wrong: "gravel"); one more after the
/// ground truth ends.
fn front_mic_drive() -> DriveLog {
    let mut truth = Vec::new();
    for k in 0..400u64 {
        let mut g = GroundTruth::zeroed();
        g.seq = k;
        g.stamp_ns = k * 1_000_000;
        g.x = x_at(k);
        g.v = 3.0;
        g.omega = 10.0;
        let (r, n) = road(g.x);
        g.road_index = r;
        g.road_name = name_to_bytes(n);
        let (mr, mn) = road(g.x + LEAD);
        g.mic_road_index = mr;
        g.mic_road_name = name_to_bytes(mn);
        g.lambda = 0.02;
        g.torque = 150.0;
        truth.push(g);
    }
    let cycles = (0..420u64)
        .map(|k| {
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            c.stamp_ns = k * 1_000_000;
            c.wakeup_latency_ns = if k == 30 { 8_000_000 } else { 20_000 };
            c.deadline_misses = if k >= 30 { 5 } else { 0 };
            c.safe_state = u8::from(!(20..405).contains(&k));
            c.torque_cmd = 150.0;
            c.used_arte = 1;
            c
        })
        .collect();
    let mut roads = Vec::new();
    let mut est = |t1_ms: u64, name: &str| {
        let mut e = RoadEstimate::zeroed();
        e.seq = roads.len() as u64;
        e.frame_t0_ns = (t1_ms - 20) * 1_000_000;
        e.frame_t1_ns = t1_ms * 1_000_000;
        e.stamp_ns = (t1_ms + 5) * 1_000_000;
        e.class_index = 0;
        e.class_name = name_to_bytes(name);
        roads.push(e);
    };
    for t1 in (20..=390u64).step_by(10) {
        est(t1, if t1 <= 50 { "gravel" } else { mic_at(t1 - 10) });
    }
    // midpoint 410 ms: after the ground truth's end (its last sample 399 ms)
    est(420, "snow");
    let mut log = DriveLog {
        path: "front-mic.mcap".into(),
        truth,
        cycles,
        roads,
        recorder: Some(Default::default()),
        ..DriveLog::default()
    };
    log.run.insert("scenario".into(), "test".into());
    log.run.insert("scenario_duration_s".into(), "0.2".into());
    log
}

fn summary_of(log: &DriveLog) -> grip_drive::Summary {
    summarize(log, &VehicleParams::default(), "test", None)
}

/// A: the microphone reaches snow during the pre-roll, 20 ms before the
/// scenario clock starts: the change is listed, at -0.020 s, with its
/// detection delay (the first estimate naming snow is published at 95 ms).
#[test]
fn a_microphone_change_in_the_pre_roll_is_listed() {
    let s = summary_of(&front_mic_drive());
    let ch = &s.arte.changes;
    assert_eq!(ch.len(), 1, "{ch:?}");
    assert_eq!(
        (ch[0].from.as_str(), ch[0].to.as_str()),
        ("asphalt", "snow")
    );
    assert!((ch[0].t + 0.020).abs() < 1e-9, "{ch:?}");
    let d = ch[0].delay.unwrap();
    assert!((d - 0.015).abs() < 1e-9, "{d}");
    let r = s.render();
    assert!(
        r.contains("change at -0.020 s asphalt -> snow: detected after 0.015 s"),
        "{r}"
    );
}

/// B: the deadline misses and the 8 ms wake-up of the start-up, and the
/// safe-state entry of the stop, are not the scenario's: during it, 0
/// misses, a 20 µs wake-up, no entry; the whole-log figures stay, said so.
#[test]
fn b_start_up_misses_and_the_stops_safe_state_are_not_in_the_scenario() {
    let s = summary_of(&front_mic_drive());
    let r = s.render();
    let during = r
        .split("during the scenario (")
        .nth(1)
        .unwrap_or_else(|| panic!("no in-scenario timing:\n{r}"));
    let during = &during[..during.find("whole log").unwrap()];
    assert!(during.starts_with("200 cycles"), "{during}");
    assert!(
        during.contains("deadline misses 0   cycles in safe state 0   safe-state entries 0"),
        "{during}"
    );
    assert!(during.contains("wake-up latency  p50 20.0 µs"), "{during}");
    assert!(during.contains("max 20.0 µs"), "{during}");
    assert!(
        r.contains("deadline misses 5   cycles in safe state 35   safe-state entries 1"),
        "whole log:\n{r}"
    );
    assert_eq!(s.timing.deadline_misses, 5, "whole log");
    assert_eq!(s.safe_cycles_in_window, Some(0));
}

/// C: cut 100 ms into the 200 ms scenario, the metrics say they cover 0.100
/// of 0.200 s; cut before the start (in the pre-roll), there are no metrics
/// and the summary says the log ends before the scenario start, not that
/// the scenario never started.
#[test]
fn c_a_truncated_log_says_how_much_of_the_scenario_it_covers() {
    let full = front_mic_drive();
    let cut = |ms: u64| {
        let mut l = full.clone();
        l.truth.retain(|g| g.stamp_ns < ms * 1_000_000);
        l.cycles.retain(|c| c.stamp_ns < ms * 1_000_000);
        l.roads.retain(|e| e.stamp_ns < ms * 1_000_000);
        l.report.truncated = Some("read up to byte 1234: cut".into());
        l.recorder = None;
        l
    };
    let s = summary_of(&cut(200));
    let r = s.render();
    assert!(
        r.contains("WARNING: metrics cover 0.100 of 0.200 s of the scenario"),
        "{r}"
    );
    assert!(
        (s.metrics.as_ref().unwrap().duration - 0.100).abs() < 1e-9,
        "{r}"
    );

    let s = summary_of(&cut(90));
    let r = s.render();
    assert!(s.metrics.is_none(), "metrics of the held car:\n{r}");
    assert!(r.contains("the log ends before the scenario start"), "{r}");
    assert!(!r.contains("never started"), "{r}");
    assert!(r.contains("metrics: none"), "{r}");

    // a hole in the ground truth (a damaged part skipped): 50 ms of the
    // scenario missing, said so; the sample before it holds for 5 ms (five
    // plant periods, at most), so the metrics cover 0.154 s, and their
    // duration says the same
    let mut holed = full.clone();
    holed
        .truth
        .retain(|g| !(150_000_000..200_000_000).contains(&g.stamp_ns));
    holed.report.truncated = Some("1 damaged part skipped (1 chunk)".into());
    let s = summary_of(&holed);
    let r = s.render();
    assert!(
        r.contains("WARNING: metrics cover 0.154 of 0.200 s of the scenario: the ground truth has gaps of 0.046 s"),
        "{r}"
    );
    assert!(
        (s.metrics.as_ref().unwrap().duration - 0.154).abs() < 1e-9,
        "{r}"
    );
    // a complete live drive whose plant skipped 10 ms (a scheduling pause:
    // samples never made, nothing lost) is not partial; 60 ms are
    let mut paused = full.clone();
    paused
        .truth
        .retain(|g| !(150_000_000..160_000_000).contains(&g.stamp_ns));
    let r = summary_of(&paused).render();
    assert!(!r.contains("metrics cover"), "{r}");
    assert!(!r.contains("PARTIAL"), "{r}");
    let mut long = full.clone();
    long.truth
        .retain(|g| !(120_000_000..180_000_000).contains(&g.stamp_ns));
    let r = summary_of(&long).render();
    assert!(
        r.contains("WARNING: metrics cover 0.144 of 0.200 s of the scenario"),
        "{r}"
    );

    // a complete log whose plant never started says so (and no metrics)
    let mut held = full.clone();
    for g in &mut held.truth {
        g.x = -LEAD;
    }
    let s = summary_of(&held);
    let r = s.render();
    assert!(s.metrics.is_none(), "{r}");
    assert!(r.contains("the scenario never started"), "{r}");
}

/// D: ARTE's accuracy is judged on the estimates whose midpoint lies in the
/// scenario (100-300 ms: 20, all right), the wrong ones of the hold and the
/// one after the ground truth's end left out; the whole-log figure (38
/// judged, none after the truth's end) is labelled.
#[test]
fn d_arte_accuracy_is_the_scenarios_and_the_whole_log_is_labelled() {
    let s = summary_of(&front_mic_drive());
    assert_eq!((s.arte.judged, s.arte.correct), (20, 20));
    let per_road: u64 = s.arte.per_road.values().map(|(n, _)| n).sum();
    assert_eq!(per_road, 20);
    let r = s.render();
    assert!(
        r.contains("accuracy during the scenario 100.0 % (20/20"),
        "{r}"
    );
    assert!(
        r.contains("accuracy over the whole log 89.5 % (34/38"),
        "{r}"
    );
}

/// E: two drives of different scenarios, vehicles and lengths, and one
/// incomplete: `compare` warns before its ratios and names each reason and
/// side; one side without metrics is named with why; two sides without
/// MotorStatus frames are named instead of the inverter's rows.
#[test]
fn e_compare_warns_when_the_drives_are_not_comparable() {
    let a = front_mic_drive();
    let mut b = front_mic_drive();
    b.run.insert("scenario".into(), "other".into());
    b.run.insert("scenario_duration_s".into(), "0.15".into());
    let sa = summary_of(&a);
    let heavier = VehicleParams {
        mass: VehicleParams::default().mass * 2.0,
        ..VehicleParams::default()
    };
    let sb = summarize(&b, &heavier, "test", None);
    let c = summary::compare(&sa, &sb);
    assert!(c.contains("not comparable"), "{c}");
    assert!(c.contains("scenarios differ"), "{c}");
    assert!(c.contains("vehicles differ"), "{c}");
    assert!(c.contains("0.200 s in A and 0.150 s in B"), "{c}");
    // neither log has a CAN frame: the inverter's rows say so, no zeros
    assert!(
        c.contains(
            "\ninverter A: no MotorStatus frames in the log (no CAN frame logged)\ninverter B: no MotorStatus frames in the log (no CAN frame logged)\n"
        ),
        "{c}"
    );
    assert!(!c.contains("fault episodes"), "{c}");
    // the same drive twice: no warning
    let c = summary::compare(&sa, &summary_of(&a));
    assert!(!c.contains("WARNING"), "{c}");
    // B cut before the start: named, with the reason, and B's warnings shown
    let mut cut = a.clone();
    cut.truth.retain(|g| g.stamp_ns < 90_000_000);
    cut.report.truncated = Some("read up to byte 1234: cut".into());
    let c = summary::compare(&sa, &summary_of(&cut));
    assert!(
        c.contains("no ground-truth metrics in B (the log ends before the scenario start)"),
        "{c}"
    );
    assert!(c.contains("B is not a complete drive"), "{c}");
    assert!(c.contains("read up to byte 1234"), "{c}");
}

/// F: the preview report looks the roads up by name: with a catalogue in
/// another order than the plant's (snow is the plant's road 2, the
/// catalogue's road 1), the wheel reaching snow is reported with snow's
/// limit, not with that of the catalogue's road 2.
#[test]
fn f_the_preview_finds_roads_by_name() {
    let roads = grip_physics::RoadCatalogue::burckhardt(&["asphalt", "snow", "wet_stone"]).unwrap();
    let v = VehicleParams::default();
    let snow_limit = roads.get("snow").unwrap().mu_peak() * v.normal_force() * v.r;
    let s = summarize(&front_mic_drive(), &v, "test", Some(&roads));
    let p = s.preview.as_ref().unwrap();
    assert_eq!(p.len(), 1, "{p:?}");
    assert_eq!((p[0].from.as_str(), p[0].to.as_str()), ("asphalt", "snow"));
    assert!((p[0].limit - snow_limit).abs() < 1e-9, "{p:?}");
    assert!((p[0].t - 0.030).abs() < 1e-9, "{p:?}");
}
