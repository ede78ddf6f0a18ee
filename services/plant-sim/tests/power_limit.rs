//! The vehicle file's power limit (`power_max`) at the simulated inverter:
//! above the drive's base speed the torque it gives falls as power_max / ω,
//! and its `MotorStatus` says `Derating` while it cuts the command (a real
//! inverter's field-weakening limit); without a power limit it never does.

mod common;

use std::path::Path;

use common::{LastTruth, MemBus, paper_now_with};
use grip_io::can::protocol::{E2eSender, InverterMsg, ProtocolRx, TorqueCommand};
use grip_io::clock::{Clock, ManualClock};
use grip_physics::VehicleParams;
use grip_plant_sim::PlantTick;

const MS: u64 = 1_000_000;

/// (Derating flags of the MotorStatus frames, the last truth's torque and ω)
/// over 300 ms of 300 N m commands on the paper scenario (10 km/h: ω about
/// 9.9 rad/s, 3 kW at 300 N m).
fn drive(vehicle: &VehicleParams) -> (Vec<bool>, f64, f64) {
    let mut sim = paper_now_with(vehicle);
    let clock = ManualClock::new(5_000 * MS);
    let mut bus = MemBus::new();
    let mut truth = LastTruth::default();
    let mut tx = E2eSender::<TorqueCommand>::new();
    let mut rx = ProtocolRx::for_tcs();
    let mut derating = Vec::new();
    for _ in 0..300 {
        let now = clock.now_ns();
        bus.inject(tx.encode(
            &TorqueCommand {
                torque_request: 300.0,
                enable: true,
            },
            now,
        ));
        sim.cycle(&PlantTick::at(now), &clock, &mut bus, &mut truth);
        for f in bus.take_sent() {
            if let Ok(Some(InverterMsg::MotorStatus(m))) = rx.receive(&f, now) {
                derating.push(m.derating);
            }
        }
        clock.advance_ns(MS);
    }
    let last = truth.last.unwrap();
    (derating, last.torque, last.omega)
}

#[test]
fn the_inverter_derates_above_the_base_speed_and_says_so() {
    let (limited, _) = grip_config::parse_vehicle(
        Path::new("small-motor.toml"),
        "[vehicle]\npower_max = 2000.0\n",
    )
    .unwrap();
    assert_eq!(limited.power_max, Some(2000.0));
    let (flags, torque, omega) = drive(&limited);
    assert!(flags.len() >= 30, "{} MotorStatus frames", flags.len());
    assert!(
        flags.iter().skip(1).all(|&d| d),
        "Derating while 300 N m is asked at 3 kW: {flags:?}"
    );
    // after 6 motor time constants the torque sits at the power limit (a
    // little above: the motor's lag follows a limit that falls as ω rises)
    assert!(
        (torque * omega - 2000.0).abs() < 60.0,
        "P = {} W (T {torque} N m, ω {omega} rad/s)",
        torque * omega
    );

    let (free, _) = grip_config::parse_vehicle(Path::new("free.toml"), "[vehicle]\n").unwrap();
    assert_eq!(free.power_max, None);
    let (flags, torque, _) = drive(&free);
    assert!(flags.iter().all(|&d| !d), "no power limit, no derating");
    assert!(torque > 295.0, "{torque}");
}
