//! The vehicle speed from the non-driven reference wheel: V = r_ref ·
//! OmegaRef with the reference wheel's own radius (`r_ref` in the vehicle
//! file), not the driven tyre's `r`. On staggered tyres (the driven rear
//! 4 % larger than the front) the driven tyre's radius read a rolling wheel
//! as a constant slip of about -0.04 (snow's λ_opt is 0.06).

mod common;

use std::path::Path;

use common::{LastSink, MemBus};
use grip_io::can::protocol::{E2eSender, WheelSpeeds};
use grip_io::clock::{Clock, ManualClock};
use grip_msgs::CycleRecord;
use grip_physics::VehicleParams;
use grip_tcs::{ControllerKind, ControllersConfig};
use grip_tcs_loop::{SafetyConfig, TcsLoop};

const MS: u64 = 1_000_000;

/// Staggered tyres: driven rear 0.3458 m, front (reference) 0.3325 m.
const STAGGERED: &str = "[vehicle]
mass = 1600.0
n_driven = 2.0
j_w = 0.9
r = 0.3458
r_ref = 0.3325
m_wheel = 20.0
tau_m = 0.02
c_rr = 0.012
rho = 1.2
c_d_a = 0.65
v_eps = 0.1
torque_max = 2500.0
driven_load_share = 0.55
mic_lead_m = 0.0
";

/// The last record after 100 cycles with both wheels rolling without slip
/// at `v` m/s on `vehicle`.
fn rolling(vehicle: &VehicleParams, v: f64) -> CycleRecord {
    let mut lp = TcsLoop::new(
        ControllerKind::Src,
        false,
        &ControllersConfig::default(),
        vehicle,
        &SafetyConfig::default(),
    )
    .unwrap();
    let clock = ManualClock::new(1_000 * MS);
    let mut bus = MemBus::new();
    let mut sink = LastSink::default();
    let mut ws = E2eSender::<WheelSpeeds>::new();
    let mut inverter = common::Inverter::new();
    let omega = v / vehicle.r;
    let mut last = None;
    for k in 0..100u64 {
        let now = clock.now_ns();
        bus.inject(ws.encode(
            &WheelSpeeds {
                driven_valid: true,
                ref_valid: true,
                omega_driven: omega,
                omega_ref: v / vehicle.ref_radius(),
            },
            now,
        ));
        inverter.send(&mut bus, k, now, omega);
        last = Some(common::step(&mut lp, &clock, &mut bus, &mut sink));
    }
    last.unwrap()
}

fn slip(vehicle: &VehicleParams, rec: &CycleRecord) -> f64 {
    let u = vehicle.r * rec.omega;
    (u - rec.v) / u.abs().max(rec.v.abs()).max(vehicle.v_eps)
}

#[test]
fn staggered_tyres_roll_without_a_slip_offset() {
    let (v, _) = grip_config::parse_vehicle(Path::new("staggered.toml"), STAGGERED).unwrap();
    assert_eq!(v.r_ref, Some(0.3325));
    let rec = rolling(&v, 10.0);
    assert_eq!(rec.safe_state, 0);
    assert_eq!(rec.v_valid, 1);
    // OmegaRef carries 0.01 rad/s: V to within 0.01 · r_ref
    assert!(
        (rec.v - 10.0).abs() < 0.004,
        "V = r_ref · OmegaRef: {}",
        rec.v
    );
    let s = slip(&v, &rec);
    assert!(s.abs() < 0.001, "a rolling wheel reads slip {s}");
    // with the driven tyre's radius for the reference wheel (the bug), the
    // same frames read V 4 % high: a slip of -0.04
    let v_wrong = v.r * (10.0 / v.ref_radius());
    let s_wrong = (10.0 - v_wrong) / v_wrong;
    assert!(s_wrong < -0.035, "{s_wrong}");
}

/// Without `r_ref` (every shipped file, every old log) the reference wheel
/// is the driven tyre's size: V = r · OmegaRef as before.
#[test]
fn without_r_ref_the_driven_radius_is_used() {
    let v = VehicleParams::default();
    assert_eq!(v.r_ref, None);
    let rec = rolling(&v, 10.0);
    let omega_ref = 10.0 / 0.28;
    // the CAN signal's 0.01 rad/s, times r
    assert!((rec.v - 10.0).abs() < 0.002, "{}", rec.v);
    assert!(
        (rec.v / 0.28 - omega_ref).abs() <= 0.005 + 1e-9,
        "{}",
        rec.v
    );
    assert!(slip(&v, &rec).abs() < 0.001);
}
