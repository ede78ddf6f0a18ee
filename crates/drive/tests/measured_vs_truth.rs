//! The figures the loop measured (`summary::measured`: cycle records only)
//! agree with the ground truth's metrics on the reference drive
//! (`tests/data/reference-drive.mcap`: MTTE with ARTE, the e2e scenario,
//! `config/vehicle.toml`), within tolerances that follow from the sensor
//! noise of the drive's vehicle file; and the tolerance is tight enough
//! that a wrong wheel radius (5 % off) falls outside it. A measured figure
//! computed with ω and V swapped, or without r, is off by tens of times the
//! tolerance.
//!
//! The tolerances (`crates/drive/README.md`, "Measured by the loop"):
//! - mean |λ_m| against the slip deviation (1/T)∫|λ|dt: the noise n in
//!   λ_m has σ_λ = σ(r ω − V) / V at most, σ(r ω − V) = √((r σ_ω)² +
//!   (r q_ω)²/6 + σ_V²) with the encoder's step q_ω = 2π / (ppr · dt);
//!   E|λ + n| − |λ| lies in [0, σ_λ √(2/π)] (largest at λ = 0), and the
//!   mean of ~1500 independent draws adds σ_λ / √N; the bound is
//!   σ_λ √(2/π) + 4 σ_λ / √N at the window's lowest V;
//! - the mean acceleration: ΔV from two measured V with noise σ_V each,
//!   over the span T: 4 √2 σ_V / T, plus one cycle's change of V at both
//!   ends (the measurement's one-sample delay and the first cycle's offset
//!   from the truth window's start): 2 · a · dt / T.

use std::path::{Path, PathBuf};

use grip_drive::{DriveLog, summary};
use grip_physics::VehicleParams;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The reference drive, its vehicle and summary.
fn reference() -> (DriveLog, VehicleParams, summary::Summary) {
    let log = DriveLog::load(&root().join("tests/data/reference-drive.mcap")).unwrap();
    let cfg = root().join("config");
    let (v, from, _) = grip_drive::vehicle_for(&log, &cfg);
    let roads = log.road_catalogue(&cfg);
    let s = summary::summarize_with_roads(&log, &v, &from, &roads);
    (log, v, s)
}

/// σ of r ω − V, m/s, from the sensor section of the log's vehicle file.
fn sigma_num(log: &DriveLog, r: f64) -> f64 {
    let text = log
        .attachment_text("vehicle.toml")
        .expect("the reference drive carries its vehicle.toml");
    let (_, sensors) =
        grip_config::parse_vehicle(Path::new("vehicle.toml (attached)"), text).unwrap();
    assert_eq!(
        (sensors.omega_noise_std, sensors.v_noise_std),
        (0.05, 0.02),
        "the noise the tolerances are written for"
    );
    let q = if sensors.encoder_ppr > 0 {
        2.0 * std::f64::consts::PI
            / (f64::from(sensors.encoder_ppr) * f64::from(sensors.omega_window) * 1e-3)
    } else {
        0.0
    };
    ((r * sensors.omega_noise_std).powi(2) + (r * q).powi(2) / 6.0 + sensors.v_noise_std.powi(2))
        .sqrt()
}

#[test]
fn measured_slip_and_acceleration_agree_with_the_ground_truth() {
    let (log, v, s) = reference();
    let truth = s.metrics.expect("the reference drive has ground truth");
    let m = &s.measured;
    assert_eq!(m.window, summary::measured::MeasuredWindow::Scenario);
    assert_eq!(m.no_valid_v, 0);
    assert!(m.slip_cycles >= 1490, "{}", m.slip_cycles);

    let (ws, we) = s.window_ns.unwrap();
    let v_min = log
        .truth
        .iter()
        .filter(|g| (ws..we).contains(&g.stamp_ns))
        .map(|g| g.v)
        .fold(f64::INFINITY, f64::min);
    let sig_lambda = sigma_num(&log, v.r) / v_min;
    let n = m.slip_cycles as f64;
    let tol_slip = sig_lambda * (2.0 / std::f64::consts::PI).sqrt() + 4.0 * sig_lambda / n.sqrt();
    let d_slip = m.mean_abs_slip - truth.slip_deviation;
    eprintln!(
        "mean |λ_m| {:.5} against (1/T)∫|λ|dt {:.5}: {d_slip:+.5} (tolerance {tol_slip:.5}; V ≥ {v_min:.2} m/s)",
        m.mean_abs_slip, truth.slip_deviation
    );
    assert!(d_slip.abs() <= tol_slip, "{d_slip} > {tol_slip}");

    let dt = 1e-3;
    let tol_accel =
        4.0 * 2f64.sqrt() * 0.02 / m.accel_s + 2.0 * truth.mean_accel.abs() * dt / m.accel_s;
    let d_accel = m.mean_accel - truth.mean_accel;
    eprintln!(
        "mean acceleration from V {:.4} against the truth's {:.4} m/s²: {d_accel:+.4} (tolerance {tol_accel:.4})",
        m.mean_accel, truth.mean_accel
    );
    assert!(d_accel.abs() <= tol_accel, "{d_accel} > {tol_accel}");

    // the tolerance tells a 5 % wrong wheel radius: λ_m then moves by
    // about 0.05 at every cycle
    let mut wrong = v;
    wrong.r *= 1.05;
    let w = summary::measured(&log, &wrong, s.window_ns, None);
    let d = w.mean_abs_slip - truth.slip_deviation;
    assert!(d.abs() > 3.0 * tol_slip, "r 5 % off: {d} within {tol_slip}");
}

/// The one spin of the reference drive (the wheel reaching snow at 0.5 s
/// under MTTE's torque) is one measured spin event, where the ground truth
/// has λ above 0.2, as long, with the same peak within the noise.
#[test]
fn the_measured_spin_is_the_true_one() {
    let (log, _, s) = reference();
    let (ws, we) = s.window_ns.unwrap();
    let spins = &s.measured.spins;
    assert_eq!(spins.len(), 1, "{spins:?}");
    let e = spins[0];
    // the truth: λ above the same threshold
    let above: Vec<&grip_msgs::GroundTruth> = log
        .truth
        .iter()
        .filter(|g| (ws..we).contains(&g.stamp_ns) && g.lambda > summary::measured::SPIN_LAMBDA)
        .collect();
    let t0 = (above[0].stamp_ns - ws) as f64 * 1e-9;
    let t1 = (above[above.len() - 1].stamp_ns - ws) as f64 * 1e-9 + 1e-3;
    let peak = above.iter().map(|g| g.lambda).fold(f64::MIN, f64::max);
    eprintln!(
        "spin: measured {} ; truth λ > 0.2 from {t0:.3} s for {:.3} s, peak {peak:.3}",
        e.line(),
        t1 - t0
    );
    assert!((e.start_s - t0).abs() <= 0.003, "{e:?} against {t0}");
    assert!(
        (e.length_s - (t1 - t0)).abs() <= 0.005,
        "{e:?} against {}",
        t1 - t0
    );
    assert!((e.peak - peak).abs() <= 0.02, "{e:?} against {peak}");
}
