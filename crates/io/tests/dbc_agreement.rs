//! Proves that `config/inverter.dbc` and `grip_io::can::protocol` agree:
//! the DBC is parsed with `can-dbc`, its messages, signals and attributes are
//! compared with the code's tables field by field, and random messages
//! encoded by the code are decoded with a generic decoder driven only by the
//! parsed DBC.

use can_dbc::{AttributeValue, ByteOrder, Dbc, MessageId, NumericValue, Signal, ValueType};
use grip_io::can::protocol::*;
use grip_msgs::CanFrame;
use proptest::prelude::*;

fn dbc() -> Dbc {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/inverter.dbc");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    Dbc::try_from(text.as_str()).unwrap_or_else(|e| panic!("{path}: DBC parse error: {e:?}"))
}

fn num(v: &NumericValue) -> f64 {
    match v {
        NumericValue::Uint(u) => *u as f64,
        NumericValue::Int(i) => *i as f64,
        NumericValue::Double(d) => *d,
    }
}

fn msg_attr(dbc: &Dbc, name: &str, id: u32) -> Option<i64> {
    dbc.attribute_values_message
        .iter()
        .find(|a| a.name == name && a.message_id.raw() == id)
        .map(|a| match &a.value {
            AttributeValue::Uint(u) => *u as i64,
            AttributeValue::Int(i) => *i,
            AttributeValue::Double(d) => *d as i64,
            AttributeValue::String(s) => panic!("attribute {name} is a string {s:?}"),
        })
}

/// Generic DBC decoder: raw value of `sig` in an 8-byte payload, per the
/// DBC's start bit, length, byte order and sign.
fn dbc_raw(sig: &Signal, data: &[u8; 8]) -> i64 {
    let len = sig.size as u32;
    let v: u64 = match sig.byte_order {
        ByteOrder::LittleEndian => {
            (u64::from_le_bytes(*data) >> sig.start_bit) & ((1u64 << len) - 1)
        }
        ByteOrder::BigEndian => {
            // Motorola: start bit is the MSB in "sawtooth" numbering
            let mut v = 0u64;
            let mut bit = sig.start_bit as i64;
            for _ in 0..len {
                let byte = (bit / 8) as usize;
                let b = (data[byte] >> (bit % 8)) & 1;
                v = (v << 1) | u64::from(b);
                bit = if bit % 8 == 0 { bit + 15 } else { bit - 1 };
            }
            v
        }
    };
    match sig.value_type {
        ValueType::Signed if (v >> (len - 1)) & 1 == 1 => (v | !((1u64 << len) - 1)) as i64,
        _ => v as i64,
    }
}

fn dbc_phys(sig: &Signal, data: &[u8; 8]) -> f64 {
    dbc_raw(sig, data) as f64 * sig.factor + sig.offset
}

#[test]
fn messages_and_signals_agree_field_by_field() {
    let dbc = dbc();
    assert_eq!(dbc.messages.len(), MESSAGES.len(), "message count");
    for spec in MESSAGES {
        let m = dbc
            .messages
            .iter()
            .find(|m| m.name == spec.name)
            .unwrap_or_else(|| panic!("{} missing from the DBC", spec.name));
        assert_eq!(
            m.id,
            MessageId::Standard(spec.id as u16),
            "{}: id",
            spec.name
        );
        assert_eq!(m.size, u64::from(spec.dlc), "{}: dlc", spec.name);
        match &m.transmitter {
            can_dbc::Transmitter::NodeName(n) => {
                assert_eq!(n, spec.sender, "{}: sender", spec.name)
            }
            other => panic!("{}: transmitter {other:?}", spec.name),
        }
        assert_eq!(
            msg_attr(&dbc, "GenMsgCycleTime", spec.id),
            Some(i64::from(spec.cycle_ms)),
            "{}: cycle",
            spec.name
        );
        assert_eq!(
            msg_attr(&dbc, "GripTimeoutMs", spec.id),
            Some(i64::from(spec.timeout_ms)),
            "{}: timeout",
            spec.name
        );
        assert_eq!(
            msg_attr(&dbc, "GripE2eDataId", spec.id),
            Some(i64::from(spec.data_id)),
            "{}: data id",
            spec.name
        );
        assert_eq!(
            m.signals.len(),
            spec.signals.len(),
            "{}: signal count",
            spec.name
        );
        for s in spec.signals {
            let d = m
                .signals
                .iter()
                .find(|d| d.name == s.name)
                .unwrap_or_else(|| panic!("{}.{} missing from the DBC", spec.name, s.name));
            let ctx = format!("{}.{}", spec.name, s.name);
            assert_eq!(d.start_bit, u64::from(s.start), "{ctx}: start bit");
            assert_eq!(d.size, u64::from(s.len), "{ctx}: length");
            assert_eq!(d.byte_order, ByteOrder::LittleEndian, "{ctx}: byte order");
            let vt = if s.signed {
                ValueType::Signed
            } else {
                ValueType::Unsigned
            };
            assert_eq!(d.value_type, vt, "{ctx}: sign");
            assert_eq!(d.factor, s.factor, "{ctx}: factor");
            assert_eq!(d.offset, s.offset, "{ctx}: offset");
            assert_eq!(num(&d.min), s.min, "{ctx}: min");
            assert_eq!(num(&d.max), s.max, "{ctx}: max");
            assert_eq!(d.unit, s.unit, "{ctx}: unit");
            // the receiver the code filters and listens by
            assert_eq!(d.receivers, [spec.receiver.node()], "{ctx}: receivers");
            // the DBC range is exactly what the bit field holds
            assert!(
                (s.to_phys(s.raw_min()) - s.min).abs() < 1e-9,
                "{ctx}: min vs bits"
            );
            assert!(
                (s.to_phys(s.raw_max()) - s.max).abs() < 1e-9 || s.name == "PedalPosition",
                "{ctx}: max vs bits"
            );
        }
        // signals do not overlap and fit the DLC
        let mut used = 0u64;
        for s in spec.signals {
            let mask = ((1u128 << s.len) - 1) as u64;
            assert!(u32::from(s.start) + u32::from(s.len) <= u32::from(spec.dlc) * 8);
            assert_eq!(
                used & (mask << s.start),
                0,
                "{}.{} overlaps",
                spec.name,
                s.name
            );
            used |= mask << s.start;
        }
    }
}

fn check_against_dbc<M: ProtocolMessage>(
    dbc: &Dbc,
    m: &M,
    counter: u8,
) -> Result<(), TestCaseError> {
    let f: CanFrame = encode(m, counter, 0);
    let dm = dbc
        .messages
        .iter()
        .find(|x| x.id.raw() == f.id)
        .expect("message in DBC");
    let typed = M::read_signals(&f.data);
    let mut n = 0;
    typed.for_each_signal(&mut |name, v| {
        let sig = dm
            .signals
            .iter()
            .find(|s| s.name == name)
            .expect("signal in DBC");
        let p = dbc_phys(sig, &f.data);
        assert!(
            (p - v).abs() < 1e-9,
            "{}.{name}: code {v} vs DBC {p}",
            dm.name
        );
        n += 1;
    });
    prop_assert_eq!(n + 2, dm.signals.len());
    let crc = dm.signals.iter().find(|s| s.name == "CRC").unwrap();
    let ctr = dm.signals.iter().find(|s| s.name == "Counter").unwrap();
    prop_assert_eq!(dbc_raw(ctr, &f.data), i64::from(counter & 15));
    prop_assert_eq!(
        dbc_raw(crc, &f.data),
        i64::from(e2e_crc(M::SPEC.data_id, &f.data))
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn code_frames_decode_identically_with_the_dbc(
        t in -4000.0f64..4000.0, w in -400.0f64..400.0, a in -40.0f64..40.0,
        p in -10.0f64..140.0, flags in any::<[bool; 4]>(), code in any::<u8>(), c in 0u8..16
    ) {
        let dbc = dbc();
        check_against_dbc(&dbc, &TorqueCommand { torque_request: t, enable: flags[0] }, c)?;
        check_against_dbc(&dbc, &MotorStatus { ready: flags[0], fault: flags[1], derating: flags[2],
            cmd_timeout: flags[3], torque_actual: t, motor_speed: w, fault_code: code }, c)?;
        check_against_dbc(&dbc, &WheelSpeeds { driven_valid: flags[1], ref_valid: flags[2],
            omega_driven: w, omega_ref: -w }, c)?;
        check_against_dbc(&dbc, &VehicleSpeed { valid: flags[3], speed: w, long_accel: a }, c)?;
        check_against_dbc(&dbc, &DriverDemand { brake_pressed: flags[0], tcs_enable: flags[1],
            torque_demand: t, pedal_position: p }, c)?;
    }
}
