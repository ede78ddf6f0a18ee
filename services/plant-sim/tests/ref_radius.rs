//! The reference wheel's speed on CAN: plant-sim, as the simulated vehicle,
//! sends OmegaRef = V / r_ref with the non-driven reference wheel's own
//! radius (`r_ref` in the vehicle file; without it the driven tyre's `r`,
//! as before), so that tcs-loop's V = r_ref · OmegaRef is the chassis speed.

mod common;

use std::path::Path;

use common::{LastTruth, MemBus, paper_now_with};
use grip_io::can::protocol::{ProtocolMessage, WheelSpeeds};
use grip_io::clock::{Clock, ManualClock};
use grip_physics::VehicleParams;
use grip_plant_sim::PlantTick;

const MS: u64 = 1_000_000;

/// (OmegaRef sent, true V) over 200 ms of the paper scenario, no torque.
fn omega_ref_and_v(vehicle: &VehicleParams) -> Vec<(f64, f64)> {
    let mut sim = paper_now_with(vehicle);
    let clock = ManualClock::new(5_000 * MS);
    let mut bus = MemBus::new();
    let mut truth = LastTruth::default();
    let mut out = Vec::new();
    for _ in 0..200 {
        sim.cycle(&PlantTick::at(clock.now_ns()), &clock, &mut bus, &mut truth);
        let v = truth.last.unwrap().v;
        for f in bus.take_sent() {
            if f.id == WheelSpeeds::spec().id {
                let w = WheelSpeeds::read_signals(&f.data);
                assert!(w.ref_valid);
                out.push((w.omega_ref, v));
            }
        }
        clock.advance_ns(MS);
    }
    assert!(out.len() >= 190, "{}", out.len());
    out
}

#[test]
fn omega_ref_is_v_over_the_reference_wheels_radius() {
    let (staggered, _) = grip_config::parse_vehicle(
        Path::new("staggered.toml"),
        "[vehicle]\nr = 0.3458\nr_ref = 0.3325\n",
    )
    .unwrap();
    for (omega_ref, v) in omega_ref_and_v(&staggered) {
        // the CAN signal's resolution is 0.01 rad/s
        assert!(
            (omega_ref - v / 0.3325).abs() <= 0.005 + 1e-9,
            "OmegaRef {omega_ref} for V {v}: V / r_ref = {}",
            v / 0.3325
        );
        assert!((omega_ref - v / 0.3458).abs() > 0.2, "not V / r");
    }
    // without r_ref: V / r, as every shipped file and old log had
    let (same, _) =
        grip_config::parse_vehicle(Path::new("same.toml"), "[vehicle]\nr = 0.3458\n").unwrap();
    for (omega_ref, v) in omega_ref_and_v(&same) {
        assert!((omega_ref - v / 0.3458).abs() <= 0.005 + 1e-9);
    }
}
