//! Property tests of the inverter protocol: every frame round-trips;
//! corrupted frames are rejected and counted.

use grip_io::can::protocol::*;
use grip_msgs::CanFrame;
use proptest::prelude::*;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn arb_torque_command() -> impl Strategy<Value = TorqueCommand> {
    (-3276.8f64..3276.7, any::<bool>()).prop_map(|(t, e)| TorqueCommand {
        torque_request: t,
        enable: e,
    })
}
fn arb_motor_status() -> impl Strategy<Value = MotorStatus> {
    (
        -3276.8f64..3276.7,
        -327.68f64..327.67,
        any::<[bool; 4]>(),
        any::<u8>(),
    )
        .prop_map(|(t, w, b, c)| MotorStatus {
            ready: b[0],
            fault: b[1],
            derating: b[2],
            cmd_timeout: b[3],
            torque_actual: t,
            motor_speed: w,
            fault_code: c,
        })
}
fn arb_wheel_speeds() -> impl Strategy<Value = WheelSpeeds> {
    (-327.68f64..327.67, -327.68f64..327.67, any::<[bool; 2]>()).prop_map(|(a, r, b)| WheelSpeeds {
        driven_valid: b[0],
        ref_valid: b[1],
        omega_driven: a,
        omega_ref: r,
    })
}
fn arb_vehicle_speed() -> impl Strategy<Value = VehicleSpeed> {
    (-327.68f64..327.67, -32.768f64..32.767, any::<bool>()).prop_map(|(v, a, ok)| VehicleSpeed {
        valid: ok,
        speed: v,
        long_accel: a,
    })
}
fn arb_driver_demand() -> impl Strategy<Value = DriverDemand> {
    (-3276.8f64..3276.7, 0.0f64..127.5, any::<[bool; 2]>()).prop_map(|(t, p, b)| DriverDemand {
        brake_pressed: b[0],
        tcs_enable: b[1],
        torque_demand: t,
        pedal_position: p,
    })
}

/// Decoding an encoded message gives every signal back within half a
/// quantisation step, and re-encoding the decoded message gives the same bytes.
fn round_trip<M: ProtocolMessage + core::fmt::Debug>(
    m: M,
    counter: u8,
) -> Result<(), TestCaseError> {
    let f = encode(&m, counter, 7);
    prop_assert_eq!(f.id, M::spec().id);
    prop_assert_eq!(f.dlc, M::spec().dlc);
    prop_assert_eq!(counter_of(&f), counter & 0x0F);
    let mut rx = E2eReceiver::new(M::spec());
    prop_assert!(rx.check(&f, 0).is_ok());
    let d = M::read_signals(&f.data);
    let mut orig = Vec::new();
    m.for_each_signal(&mut |n, v| orig.push((n, v)));
    let mut back = Vec::new();
    d.for_each_signal(&mut |n, v| back.push((n, v)));
    prop_assert_eq!(orig.len(), back.len());
    for ((n, a), (n2, b)) in orig.iter().zip(&back) {
        prop_assert_eq!(n, n2);
        let s = M::spec().signals.iter().find(|s| s.name == *n).unwrap();
        prop_assert!(close(*a, *b, s.factor / 2.0 + 1e-9), "{n}: {a} -> {b}");
    }
    let again = encode(&d, counter, 7);
    prop_assert_eq!(again.data, f.data);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn torque_command_round_trips(m in arb_torque_command(), c in 0u8..16) { round_trip(m, c)?; }
    #[test]
    fn motor_status_round_trips(m in arb_motor_status(), c in 0u8..16) { round_trip(m, c)?; }
    #[test]
    fn wheel_speeds_round_trip(m in arb_wheel_speeds(), c in 0u8..16) { round_trip(m, c)?; }
    #[test]
    fn vehicle_speed_round_trips(m in arb_vehicle_speed(), c in 0u8..16) { round_trip(m, c)?; }
    #[test]
    fn driver_demand_round_trips(m in arb_driver_demand(), c in 0u8..16) { round_trip(m, c)?; }

    /// Out-of-range and non-finite requests saturate instead of wrapping.
    #[test]
    fn out_of_range_saturates(t in prop_oneof![-1e12f64..-3300.0, 3300.0f64..1e12]) {
        let f = encode(&TorqueCommand { torque_request: t, enable: true }, 0, 0);
        let d = TorqueCommand::read_signals(&f.data);
        prop_assert_eq!(d.torque_request.signum(), t.signum());
        prop_assert!(d.torque_request.abs() >= 3276.7 - 1e-9);
    }

    /// Any single-bit error in bytes 0..8 is caught (CRC or counter), and
    /// counted exactly once.
    #[test]
    fn any_bit_flip_is_rejected_and_counted(m in arb_wheel_speeds(), bit in 0usize..64, n in 1usize..20) {
        let mut tx = E2eSender::<WheelSpeeds>::new();
        let mut rx = E2eReceiver::new(&WHEEL_SPEEDS);
        for i in 0..n {
            prop_assert!(rx.check(&tx.encode(&m, 0), i as u64).is_ok());
        }
        let mut f = tx.encode(&m, 0);
        f.data[bit / 8] ^= 1 << (bit % 8);
        let e = rx.check(&f, n as u64);
        prop_assert!(e.is_err());
        let faults = rx.faults();
        prop_assert_eq!(faults.total(), 1);
        // CRC-8 detects every single-bit error
        prop_assert_eq!(faults.crc, 1);
        prop_assert!(matches!(e, Err(E2eError::Crc { .. })), "unexpected result");
    }

    /// A replayed frame (same counter) is rejected as repeated.
    #[test]
    fn repeated_counter_rejected(m in arb_motor_status(), n in 1usize..40) {
        let mut tx = E2eSender::<MotorStatus>::new();
        let mut rx = E2eReceiver::new(&MOTOR_STATUS);
        let mut last = tx.encode(&m, 0);
        prop_assert!(rx.check(&last, 0).is_ok());
        for i in 1..n {
            last = tx.encode(&m, 0);
            prop_assert!(rx.check(&last, i as u64).is_ok());
        }
        prop_assert!(matches!(rx.check(&last, n as u64), Err(E2eError::CounterRepeated { .. })), "unexpected result");
        prop_assert_eq!(rx.faults().counter_repeated, 1);
        prop_assert_eq!(rx.faults().total(), 1);
        // and the next good frame is accepted
        prop_assert!(rx.check(&tx.encode(&m, 0), n as u64 + 1).is_ok());
    }

    /// Losing 1..=14 frames is detected; the receiver resyncs so the frame
    /// after the jumped one is accepted again.
    #[test]
    fn skipped_counter_rejected_then_resynced(m in arb_driver_demand(), lost in 1usize..15) {
        let mut tx = E2eSender::<DriverDemand>::new();
        let mut rx = E2eReceiver::new(&DRIVER_DEMAND);
        prop_assert!(rx.check(&tx.encode(&m, 0), 0).is_ok());
        for _ in 0..lost { tx.encode(&m, 0); }
        let e = rx.check(&tx.encode(&m, 0), 1);
        prop_assert!(matches!(e, Err(E2eError::CounterSkipped { .. })), "{e:?}");
        prop_assert_eq!(rx.faults().counter_skipped, 1);
        prop_assert!(rx.check(&tx.encode(&m, 0), 2).is_ok());
        prop_assert_eq!(rx.faults().total(), 1);
    }

    /// A tolerant receiver (max_delta) accepts small gaps but still counts them.
    #[test]
    fn tolerated_gap_is_counted(lost in 1u8..4) {
        let m = VehicleSpeed::default();
        let mut tx = E2eSender::<VehicleSpeed>::new();
        let mut rx = E2eReceiver::new(&VEHICLE_SPEED).with_max_delta(4);
        prop_assert!(rx.check(&tx.encode(&m, 0), 0).is_ok());
        for _ in 0..lost { tx.encode(&m, 0); }
        prop_assert!(rx.check(&tx.encode(&m, 0), 1).is_ok());
        prop_assert_eq!(rx.faults().counter_skipped, 1);
    }

    /// Wrong DLC is rejected before anything else.
    #[test]
    fn wrong_length_rejected(m in arb_torque_command(), dlc in 0u8..8) {
        let mut f = encode(&m, 0, 0);
        f.dlc = dlc;
        let mut rx = E2eReceiver::new(&TORQUE_COMMAND);
        prop_assert!(matches!(rx.check(&f, 0), Err(E2eError::Length { .. })), "unexpected result");
        prop_assert_eq!(rx.faults().length, 1);
        prop_assert_eq!(rx.faults().total(), 1);
    }

    /// Ids outside the protocol are counted as unknown; protocol ids a node
    /// does not listen to are ignored without a fault.
    #[test]
    fn unknown_id_counted(id in 0u32..0x800, data in any::<[u8; 8]>()) {
        let mut rx = ProtocolRx::for_tcs();
        let f = CanFrame { id, dlc: 8, data, ..CanFrame::default() };
        let known = spec_for_id(id).is_some();
        let r = rx.receive(&f, 0);
        if !known {
            prop_assert!(matches!(r, Err(E2eError::UnknownId { .. })), "unexpected result");
            prop_assert_eq!(rx.faults().unknown_id, 1);
        } else if id == TORQUE_COMMAND.id {
            prop_assert_eq!(r, Ok(None));
            prop_assert_eq!(rx.faults().total(), 0);
        }
    }

    /// A frame sent under another message's id (masquerade) fails the CRC
    /// because the data id differs.
    #[test]
    fn masquerade_fails_crc(m in arb_motor_status()) {
        let mut f = encode(&m, 1, 0);
        f.id = WHEEL_SPEEDS.id;
        let mut rx = E2eReceiver::new(&WHEEL_SPEEDS);
        prop_assert!(matches!(rx.check(&f, 0), Err(E2eError::Crc { .. })), "unexpected result");
    }
}

#[test]
fn tcs_dispatch_decodes_and_sums_faults() {
    let mut rx = ProtocolRx::for_tcs();
    let mut ws = E2eSender::<WheelSpeeds>::new();
    let mut ms = E2eSender::<MotorStatus>::new();
    let w = WheelSpeeds {
        driven_valid: true,
        ref_valid: true,
        omega_driven: 30.0,
        omega_ref: 29.5,
    };
    match rx.receive(&ws.encode(&w, 0), 0) {
        Ok(Some(InverterMsg::WheelSpeeds(d))) => {
            assert!((d.omega_driven - 30.0).abs() < 0.006);
            assert!((d.omega_ref - 29.5).abs() < 0.006);
        }
        other => panic!("{other:?}"),
    }
    let mut bad = ms.encode(&MotorStatus::default(), 0);
    bad.data[3] ^= 0x40;
    assert!(rx.receive(&bad, 0).is_err());
    assert!(rx.receive(&CanFrame::new(0x7FF, &[0; 8]), 0).is_err());
    let f = rx.faults();
    assert_eq!((f.crc, f.unknown_id, f.total()), (1, 1, 2));
    // MotorStatus never accepted → link not OK
    assert!(rx.poll_timeouts(1_000_000));
    assert_eq!(
        rx.receiver(MOTOR_STATUS.id).unwrap().accepted(),
        0,
        "the corrupted status must not count as accepted"
    );
}
