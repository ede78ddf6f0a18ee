//! tcs-loop started on a car's own bus whose ABS sends the wheels'
//! circumferential speeds in km/h and an inverted validity bit (1 =
//! driven wheel speed *invalid*), configured as a user would: the DBC in
//! the configuration directory, `can.toml` naming it with `[dbc_valid]
//! "WheelSpeeds.DrivenValid" = 0`, and the vehicle file's `r` and `r_ref`.
//! The loop's start-up (`load`, which installs the protocol with the
//! vehicle's radii) reads 36 km/h as 36 / 3.6 / r rad/s, the vehicle speed
//! as r_ref · OmegaRef = 10 m/s, and a frame whose bit says invalid as no
//! wheel speed (the safe state follows its timeout).
//!
//! One test in this file: it installs the process's protocol.

mod common;

use common::{CONFIG, LastSink, MemBus};
use grip_io::can::protocol::{E2eSender, MsgKind, WheelSpeeds, active, e2e_crc_at};
use grip_io::clock::{Clock, ManualClock};
use grip_io::service::ConfigArgs;
use grip_msgs::{CanFrame, CycleRecord, can_dir};
use grip_tcs_loop::Options;

const MS: u64 = 1_000_000;

/// A WheelSpeeds frame as the car's ABS lays it out, byte by byte: bit 12
/// set when the driven wheel's speed is invalid, bit 13 (RefValid, grip's
/// sense) set, the two speeds in 0.01 km/h (bits 16-31 and 32-47, Intel),
/// the E2E CRC over the data id in byte 0.
fn abs_frame(
    counter: u8,
    driven_invalid: bool,
    driven_kmh: f64,
    ref_kmh: f64,
    now: u64,
) -> CanFrame {
    let spec = active().spec(MsgKind::WheelSpeeds);
    let mut data = [0u8; 8];
    data[1] = (counter & 0x0F) | u8::from(driven_invalid) << 4 | 1 << 5;
    data[2..4].copy_from_slice(&((driven_kmh / 0.01).round() as i16).to_le_bytes());
    data[4..6].copy_from_slice(&((ref_kmh / 0.01).round() as i16).to_le_bytes());
    data[0] = e2e_crc_at(spec.data_id, &data, 0);
    CanFrame {
        stamp_ns: now,
        id: spec.id,
        dlc: 8,
        direction: can_dir::RX,
        bus: 0,
        flags: 0,
        data,
    }
}

#[test]
fn a_bus_in_km_h_with_an_inverted_validity_bit_is_read_right() {
    let t = grip_testkit::svc::copy_config(&CONFIG);
    let dir = t.path();
    let shipped = std::fs::read_to_string(dir.join("inverter.dbc")).unwrap();
    let mut car = shipped.clone();
    for (from, to) in [
        (
            "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"",
            "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67] \"km/h\"",
        ),
        (
            "OmegaRef : 32|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"",
            "OmegaRef : 32|16@1- (0.01,0) [-327.68|327.67] \"km/h\"",
        ),
    ] {
        assert!(car.contains(from), "{from}");
        car = car.replacen(from, to, 1);
    }
    std::fs::write(dir.join("car.dbc"), car).unwrap();
    let can = std::fs::read_to_string(dir.join("can.toml")).unwrap();
    assert!(can.contains("\ndbc = \"inverter.dbc\"\n"));
    std::fs::write(
        dir.join("can.toml"),
        can.replace("\ndbc = \"inverter.dbc\"\n", "\ndbc = \"car.dbc\"\n")
            + "[dbc_valid]\n\"WheelSpeeds.DrivenValid\" = 0\n",
    )
    .unwrap();
    // the driven tyre 0.28 m (shipped), the reference wheel 0.30 m
    let vehicle = std::fs::read_to_string(dir.join("vehicle.toml")).unwrap();
    assert!(vehicle.contains("# r_ref = 0.28 "));
    std::fs::write(
        dir.join("vehicle.toml"),
        vehicle.replacen("# r_ref = 0.28 ", "r_ref = 0.30  ", 1),
    )
    .unwrap();

    let cfg = grip_tcs_loop::load(&Options {
        config: ConfigArgs::in_dir(dir),
        ..Options::default()
    })
    .unwrap();
    assert_eq!((cfg.vehicle.r, cfg.vehicle.ref_radius()), (0.28, 0.30));
    let p = active();
    assert_eq!(
        p.describe_speeds(),
        "wheel speeds converted from km/h or m/s with r = 0.28 m, r_ref = 0.3 m; valid: WheelSpeeds.DrivenValid = 0, WheelSpeeds.RefValid non-zero, VehicleSpeed.Valid non-zero"
    );
    let mut lp = grip_tcs_loop::build(&cfg).unwrap();

    let clock = ManualClock::new(1_000 * MS);
    let mut bus = MemBus::new();
    let mut sink = LastSink::default();
    let mut inverter = common::Inverter::new();
    let omega = 36.0 / 3.6 / 0.28; // 35.71 rad/s: 10 m/s at r = 0.28 m
    // the last record and the frames the E2E check rejected so far
    let mut run = |cycles: u64, driven_invalid: bool, k0: u64| -> (CycleRecord, u64) {
        let mut last = None;
        for k in k0..k0 + cycles {
            let now = clock.now_ns();
            bus.inject(abs_frame(k as u8, driven_invalid, 36.0, 36.0, now));
            inverter.send(&mut bus, k, now, omega);
            last = Some(common::step(&mut lp, &clock, &mut bus, &mut sink));
        }
        (last.unwrap(), sink.can_rejected)
    };

    // bit 12 clear: valid; 36 km/h read in rad/s with each wheel's radius
    let (rec, rejected) = run(100, false, 0);
    assert_eq!(rec.safe_state, 0, "{rec:?}");
    assert!((rec.omega - omega).abs() < 1e-6, "omega {}", rec.omega);
    assert!(
        (rec.v - 10.0).abs() < 1e-6,
        "V = r_ref · OmegaRef: {}",
        rec.v
    );
    assert_eq!(rec.v_valid, 1);
    assert_eq!(rejected, 0);

    // bit 12 set: the ABS says invalid; no wheel speed, the safe state
    // after sensor_timeout_ms (10 ms)
    let (rec, rejected) = run(30, true, 100);
    assert_ne!(rec.safe_state, 0, "{rec:?}");
    assert_eq!(rejected, 0, "whole frames, only their content invalid");

    // what grip itself sends (plant-sim's encoder, the same protocol): the
    // ABS's very bytes
    let mut ws = E2eSender::<WheelSpeeds>::new();
    let sent = ws.encode(
        &WheelSpeeds {
            driven_valid: true,
            ref_valid: true,
            omega_driven: omega,
            omega_ref: 10.0 / 0.30,
        },
        0,
    );
    assert_eq!(sent.data, abs_frame(0, false, 36.0, 36.0, 0).data);
    let sent = ws.encode(
        &WheelSpeeds {
            driven_valid: false,
            ref_valid: true,
            omega_driven: omega,
            omega_ref: 10.0 / 0.30,
        },
        0,
    );
    assert_eq!(sent.data, abs_frame(1, true, 36.0, 36.0, 0).data);
}
