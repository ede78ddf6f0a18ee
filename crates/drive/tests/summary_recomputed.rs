//! Figures of the drive summary a reviewer recomputed independently, on
//! constructed logs: the command's figures start where the loop had the
//! driver's demand and ignore the cycles' timing jitter, holes in the
//! ground truth are held at most five plant periods, the acceleration from
//! V is not set by two noisy samples, a wheel spinning in reverse is a
//! spin, and a log without ground truth still says how often the road
//! belief was usable and how often road knowledge's cap bound the command.

use grip_drive::{DriveLog, summarize};
use grip_msgs::{CycleRecord, GroundTruth, name_to_bytes};
use grip_physics::{RoadCatalogue, VehicleParams};

const MS: u64 = 1_000_000;

/// A deterministic sequence in [-1, 1).
fn noise(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// Ground truth at 1 kHz: held 10 ms, then moving (3 mm a ms) to
/// `n_ms`; cycle records at 1 kHz stamped with up to ±20 µs of jitter.
/// The loop gets the driver's 300 N m demand 6 ms after the plant starts
/// (at 15 ms; the plant's start is the sample at 9 ms): before, demand and
/// command are 0, after the command is a constant 300 N m.
fn step_drive(n_ms: u64, duration_s: f64) -> DriveLog {
    let mut seed = 7;
    let truth = (0..n_ms)
        .map(|k| {
            let mut g = GroundTruth::zeroed();
            g.seq = k;
            g.stamp_ns = k * MS;
            g.x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
            g.v = if k < 10 {
                3.0
            } else {
                3.0 + (k - 9) as f64 * 1e-3
            };
            g.omega = 12.0;
            g.lambda = 0.02;
            g.torque = if k < 15 { 0.0 } else { 300.0 };
            g.road_name = name_to_bytes("asphalt");
            g.mic_road_name = g.road_name;
            g
        })
        .collect();
    let cycles = (0..n_ms)
        .map(|k| {
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            let j = (noise(&mut seed) * 20_000.0) as i64;
            c.stamp_ns = (k * MS + 100_000).saturating_add_signed(j);
            (c.demand, c.torque_cmd) = if k < 15 { (0.0, 0.0) } else { (300.0, 300.0) };
            c.v = 3.0;
            c.v_valid = 1;
            c.omega = 3.0 / VehicleParams::default().r;
            c
        })
        .collect();
    let mut log = DriveLog {
        path: "step.mcap".into(),
        truth,
        cycles,
        recorder: Some(Default::default()),
        ..DriveLog::default()
    };
    log.run.insert("scenario".into(), "test".into());
    log.run
        .insert("scenario_duration_s".into(), duration_s.to_string());
    log
}

/// The pedal's 0 -> 300 N m step before the loop had the demand is not the
/// controller's: a constant command after it gives a total variation and
/// a high-frequency content of exactly 0, in the ground-truth metrics and
/// in the measured section, however the cycles' stamps jitter.
#[test]
fn the_command_figures_start_with_the_drivers_demand() {
    let v = VehicleParams::default();
    let s = summarize(&step_drive(1010, 1.0), &v, "test", None);
    let m = s.metrics.unwrap();
    assert_eq!(
        (m.cmd_tv_per_s, m.cmd_hf_rms, m.cmd_hf_share),
        (0.0, 0.0, 0.0),
        "{m:?}"
    );
    // from the cycle stamped about 15.1 ms, 6.1 ms after the start
    let from = s.cmd_from_s.unwrap();
    assert!((from - 0.0061).abs() < 30e-6, "{from}");
    assert!((m.cmd_duration - (1.0 - from)).abs() < 2e-3, "{m:?}");
    let me = &s.measured;
    assert_eq!(
        (me.cmd_tv_per_s, me.cmd_hf_rms, me.cmd_hf_share),
        (0.0, 0.0, 0.0),
        "{me:?}"
    );
    let r = s.render();
    assert!(
        r.contains("command total variation Σ|ΔT*|/T 0 N m/s"),
        "{r}"
    );
    assert!(
        r.contains("the command's figures from 0.006 s: the first cycle in the window with the driver's demand above 10 N m"),
        "{r}"
    );
    // the mean command still covers the whole window
    assert!(
        me.mean_cmd < 300.0 && me.mean_cmd > 297.0,
        "{}",
        me.mean_cmd
    );
}

/// 0.3 s of the ground truth of a 2.4 s scenario cut out of a complete
/// log: the sample before the hole holds for five plant periods, no more,
/// so the metrics' duration is what the warning says they cover.
#[test]
fn a_hole_in_the_ground_truth_is_held_at_most_five_periods() {
    let v = VehicleParams::default();
    let mut log = step_drive(2420, 2.4);
    log.truth
        .retain(|g| !(1_000 * MS..1_300 * MS).contains(&g.stamp_ns));
    let s = summarize(&log, &v, "test", None);
    let m = s.metrics.unwrap();
    // 2.400 s less the hole's 301 ms beyond the 5 ms the sample before
    // holds: 2.104 s
    assert!((m.duration - 2.104).abs() < 1e-9, "{}", m.duration);
    let w = s.warnings.join("\n");
    assert!(
        w.contains(
            "metrics cover 2.104 of 2.400 s of the scenario: the ground truth has gaps of 0.296 s"
        ),
        "{w}"
    );
    match s.window_status {
        grip_drive::summary::WindowStatus::Partial { covered_s, .. } => {
            assert!((covered_s - m.duration).abs() < 1e-9, "{covered_s}")
        }
        o => panic!("{o:?}"),
    }
}

/// Cycles at 1 kHz for 1 s while the driver demands 200 N m (no ground
/// truth: the demand window); V rises at 1 m/s², the sensor's noise (±0.02
/// m/s) on it, and the first and last samples 0.03 m/s off. Two end
/// samples would give 0.94 m/s²; a line through 50 ms at each end is
/// within 0.01 (0.9946: the end samples' own error weighs 4/50 in it).
#[test]
fn the_acceleration_from_v_is_not_set_by_two_noisy_samples() {
    let mut seed = 3;
    let r = VehicleParams::default().r;
    let cycles: Vec<CycleRecord> = (0..1000u64)
        .map(|k| {
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            c.stamp_ns = 1_000 * MS + k * MS;
            let e = match k {
                0 => 0.03,
                999 => -0.03,
                _ => 0.02 * noise(&mut seed),
            };
            c.v = 5.0 + k as f64 * 1e-3 + e;
            c.v_valid = 1;
            c.omega = (5.0 + k as f64 * 1e-3) / r;
            c.demand = 200.0;
            c.torque_cmd = 200.0;
            c
        })
        .collect();
    let log = DriveLog {
        cycles,
        ..DriveLog::default()
    };
    let s = summarize(&log, &VehicleParams::default(), "test", None);
    let a = s.measured.mean_accel;
    assert!((a - 1.0).abs() < 0.01, "{a}");
    assert!(
        s.render()
            .contains("V at each end from a line through its first or last 50 ms"),
        "{}",
        s.render()
    );
}

/// A wheel spinning in reverse (reversing at 5 m/s, r ω −7 m/s: λ_m
/// −0.29 for 80 ms) is a spin event, and its road's largest |λ_m| shows
/// it; the cycles of the driver-demand window, with no ground truth, say
/// how often the road belief was usable and how often road knowledge's
/// cap held the command below the demand.
#[test]
fn a_reverse_spin_counts_and_a_car_log_says_how_often_arte_was_used() {
    let v = VehicleParams::default();
    let cycles: Vec<CycleRecord> = (0..1000u64)
        .map(|k| {
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            c.stamp_ns = 1_000 * MS + k * MS;
            c.v = -5.0;
            c.v_valid = 1;
            c.omega = if (300..380).contains(&k) { -7.0 } else { -5.0 } / v.r;
            c.demand = if k < 100 { 0.0 } else { 200.0 };
            c.torque_cmd = c.demand;
            c.belief_road = 0;
            c.used_arte = u8::from(k % 4 != 0);
            c.torque_cap = f64::NAN;
            // road knowledge's cap below the demand, gate passed or not:
            // binding in 100 cycles (the command at it); in 50 more the
            // command is above it (a cap lifted by the wheel), and in 50
            // more well below it (the controller's own command): not
            // binding
            if (500..650).contains(&k) {
                c.torque_cap = 150.0;
                if k < 600 {
                    c.torque_cmd = 150.05;
                }
            }
            if (650..700).contains(&k) {
                c.torque_cap = 180.0;
                c.torque_cmd = 120.0;
            }
            c
        })
        .collect();
    let mut log = DriveLog {
        cycles,
        ..DriveLog::default()
    };
    let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
    // the loop's gate, read from the log without a scenario window too,
    // also as a TOML integer (the loop takes `min_confidence = 1`)
    assert_eq!(
        summarize(&log, &v, "test", Some(&roads))
            .arte
            .min_confidence,
        (0.6, false)
    );
    log.attachments.insert(
        "controllers.toml".into(),
        b"[arte]\nmin_confidence = 1\n".to_vec(),
    );
    let s = summarize(&log, &v, "test", Some(&roads));
    assert_eq!(s.arte.min_confidence, (1.0, true));
    let m = &s.measured;
    assert_eq!(m.spins.len(), 1, "{:?}", m.spins);
    let lam = 2.0 / 7.0;
    assert!((m.spins[0].peak - lam).abs() < 1e-9, "{:?}", m.spins);
    assert!((m.spins[0].length_s - 0.080).abs() < 1e-9, "{:?}", m.spins);
    assert!((m.per_belief[0].max_slip - lam).abs() < 1e-9);
    // 900 cycles demanded, 3 in 4 using the estimate
    assert_eq!((s.arte.active_cycles, s.arte.used_cycles), (900, 675));
    assert_eq!(s.arte.capped_cycles, 100);
    assert!(s.arte.used_in_demand_window);
    let r = s.render();
    assert!(
        r.contains("of the active cycles of the time the driver demanded more than 10 N m (no scenario window; the measured section's window) (900):"),
        "{r}"
    );
    assert!(
        r.contains("the road belief was usable in 75.0 % (675; the cycle record's used_arte"),
        "{r}"
    );
    assert!(
        r.contains(
            "road knowledge's torque cap held the command below the driver's demand in 11.1 % (100;"
        ),
        "{r}"
    );
    assert!(r.contains("peak |λ_m| 0.286"), "{r}");
}
