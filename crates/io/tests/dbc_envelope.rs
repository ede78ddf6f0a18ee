//! A DBC whose speeds or torques cannot carry what grip controls with is
//! said at start (found in a bad-input trial, 2026-12-06: `OmegaDriven`
//! shortened to 8 bits, ±1.27 rad/s, gave a drive ten times the slip with
//! the loop "in control", and nothing said why): `Protocol::envelope_warnings`
//! names the DBC, message, signal, what it carries and what grip needs;
//! the built-in protocol and the shipped DBC with the shipped vehicles get
//! none.

use std::collections::BTreeMap;

use grip_io::can::protocol::*;
use grip_physics::VehicleParams;

fn shipped() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/inverter.dbc");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn edited(from: &str, to: &str) -> Protocol {
    let s = shipped();
    assert!(s.contains(from), "{from}");
    Protocol::from_dbc(&s.replacen(from, to, 1), "car.dbc", &BTreeMap::new()).unwrap()
}

/// The paper's quarter car (r = 0.28 m) with `torque_max`.
fn vehicle(torque_max: f64) -> VehicleParams {
    VehicleParams {
        torque_max,
        ..VehicleParams::default()
    }
}

#[test]
fn the_shipped_protocol_carries_what_grip_needs() {
    let p = Protocol::from_dbc(&shipped(), "inverter.dbc", &BTreeMap::new()).unwrap();
    for t in [300.0, 1000.0] {
        assert!(p.envelope_warnings("inverter.dbc", &vehicle(t)).is_empty());
        assert!(
            Protocol::builtin()
                .envelope_warnings("built-in", &vehicle(t))
                .is_empty()
        );
    }
}

#[test]
fn a_short_wheel_speed_is_named_with_what_it_carries() {
    // the trial's 8-bit OmegaDriven: ±1.27 rad/s
    let p = edited(
        "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67]",
        "OmegaDriven : 16|8@1- (0.01,0) [-1.28|1.27]",
    );
    let w = p.envelope_warnings("car.dbc", &vehicle(1000.0));
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("car.dbc: WheelSpeeds.OmegaDriven carries at most 1.27 rad/s (")
            && w[0].contains("grip needs up to 150 km/h"),
        "{}",
        w[0]
    );
    // a coarse one: 0.1 rad/s at r = 0.28 m is 1.0 % of 10 km/h
    let p = edited(
        "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67]",
        "OmegaDriven : 16|16@1- (0.1,0) [-3276.8|3276.7]",
    );
    let w = p.envelope_warnings("car.dbc", &vehicle(1000.0));
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("WheelSpeeds.OmegaDriven moves in steps of 0.1 rad/s"),
        "{}",
        w[0]
    );
}

#[test]
fn a_torque_under_the_vehicles_limit_is_named() {
    let p = edited(
        "TorqueActual : 16|16@1- (0.1,0) [-3276.8|3276.7]",
        "TorqueActual : 16|16@1- (0.1,0) [-250|250]",
    );
    assert!(p.envelope_warnings("car.dbc", &vehicle(200.0)).is_empty());
    let w = p.envelope_warnings("car.dbc", &vehicle(300.0));
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("MotorStatus.TorqueActual carries at most 250 Nm, under the vehicle's torque_max = 300 N m"),
        "{}",
        w[0]
    );
}
