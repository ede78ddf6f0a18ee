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
        for s in spec.signals.iter() {
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
        for s in spec.signals.iter() {
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
        i64::from(e2e_crc(M::spec().data_id, &f.data))
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

// ------------------------------------------------ a car's own bus (DBC) ----

fn shipped_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/inverter.dbc")
}

fn own_path() -> std::path::PathBuf {
    grip_testkit::own_bus::dbc_path()
}

/// The names `tests/data/own-bus.dbc` gives grip's messages and signals.
fn own_names() -> std::collections::BTreeMap<String, String> {
    grip_testkit::own_bus::names()
}

fn own_protocol() -> &'static Protocol {
    static P: std::sync::OnceLock<Protocol> = std::sync::OnceLock::new();
    P.get_or_init(|| Protocol::load_dbc(&own_path(), &own_names()).unwrap())
}

fn own_dbc() -> Dbc {
    let text = std::fs::read_to_string(own_path()).unwrap();
    Dbc::try_from(text.as_str()).unwrap()
}

/// grip's unit per DBC unit, written out here (not the loader's table).
fn to_grip_unit(dbc_unit: &str) -> f64 {
    match dbc_unit {
        "rpm" => 2.0 * std::f64::consts::PI / 60.0,
        "km/h" => 1.0 / 3.6,
        "g" => 9.806_65,
        _ => 1.0,
    }
}

#[test]
fn the_shipped_dbc_read_at_start_is_the_built_in_protocol() {
    let p = Protocol::load_dbc(&shipped_path(), &Default::default()).unwrap();
    assert_eq!(&p, Protocol::builtin());
}

#[test]
fn a_foreign_dbc_gives_its_ids_timing_and_data_ids() {
    let p = own_protocol();
    let ids: Vec<u32> = p.messages().iter().map(|m| m.id).collect();
    assert_eq!(ids, [0x191, 0x192, 0x193, 0x194, 0x195]);
    let data_ids: Vec<u16> = p.messages().iter().map(|m| m.data_id).collect();
    assert_eq!(data_ids, [11009, 11010, 11011, 11012, 11013]);
    assert_eq!(p.spec(MsgKind::VehicleSpeed).cycle_ms, 10);
    assert_eq!(p.spec(MsgKind::TorqueCommand).timeout_ms, 20);
    // grip's names and order, whatever the DBC calls and orders them
    let ws = p.spec(MsgKind::WheelSpeeds);
    assert_eq!(ws.signals[0].name, "CRC");
    assert_eq!(ws.crc_byte(), 7);
    assert_eq!(p.spec(MsgKind::MotorStatus).crc_byte(), 0);
    assert!(p.spec(MsgKind::MotorStatus).signals[7].motorola);
    // rpm read as rad/s
    let speed = &p.spec(MsgKind::MotorStatus).signals[7];
    assert_eq!(speed.unit, "rad/s");
    assert!((speed.factor - std::f64::consts::PI / 30.0).abs() < 1e-15);
    assert!(p.receives_id(Role::Tcs, 0x193) && !p.receives_id(Role::Tcs, 0x120));
    assert!(p.receives_id(Role::Inverter, 0x191) && !p.receives_id(Role::Inverter, 0x100));
}

fn check_own<M: ProtocolMessage>(dbc: &Dbc, m: &M, counter: u8) -> Result<(), TestCaseError> {
    let p = own_protocol();
    let spec = p.spec(M::KIND);
    let f = encode_in(spec, m, counter, 0);
    let dm = dbc
        .messages
        .iter()
        .find(|x| x.id.raw() == f.id)
        .expect("message in the DBC");
    let names = own_names();
    let typed = M::read_signals_in(spec, &f.data);
    let mut n = 0;
    typed.for_each_signal(&mut |name, v| {
        let key = format!("{}.{name}", spec.name);
        let dname = names.get(&key).map_or(name, String::as_str);
        let sig = dm
            .signals
            .iter()
            .find(|s| s.name == dname)
            .expect("signal in the DBC");
        let p = dbc_phys(sig, &f.data) * to_grip_unit(&sig.unit);
        assert!(
            (p - v).abs() < 1e-9 * v.abs().max(1.0),
            "{}.{dname}: code {v} vs DBC {p}",
            dm.name
        );
        n += 1;
    });
    // the DBC's extra signals (Mode, Spare) are left at zero
    prop_assert!(n + 2 <= dm.signals.len());
    for s in &dm.signals {
        if s.name == "Mode" || s.name == "Spare" {
            prop_assert_eq!(dbc_raw(s, &f.data), 0);
        }
    }
    let crc_sig = dm.signals.iter().find(|s| s.name == "CRC").unwrap();
    let ctr = dm.signals.iter().find(|s| s.name == "Counter").unwrap();
    prop_assert_eq!(dbc_raw(ctr, &f.data), i64::from(counter & 15));
    // the CRC over the data id and the seven other bytes, written out here
    let byte = (crc_sig.start_bit / 8) as usize;
    let mut covered = spec.data_id.to_le_bytes().to_vec();
    covered.extend(
        f.data
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != byte)
            .map(|(_, b)| *b),
    );
    prop_assert_eq!(dbc_raw(crc_sig, &f.data), i64::from(crc8_j1850(&covered)));
    // and grip's receiver for that protocol accepts it
    let spec: &'static MessageSpec = spec;
    let mut rx = E2eReceiver::new(spec);
    prop_assert!(rx.check(&f, 0).is_ok());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Frames grip encodes for `tests/data/own-bus.dbc` (Motorola, a CRC
    /// in the last byte, rpm, km/h and g, other names and ids) decode with
    /// the generic decoder above, driven by that DBC alone, to the values
    /// grip meant, in grip's units.
    #[test]
    fn frames_for_a_foreign_dbc_decode_identically_with_it(
        t in -3000.0f64..3000.0, w in -300.0f64..300.0, v in -90.0f64..90.0, a in -30.0f64..30.0,
        p in 0.0f64..100.0, flags in any::<[bool; 4]>(), code in any::<u8>(), c in 0u8..16
    ) {
        let dbc = own_dbc();
        check_own(&dbc, &TorqueCommand { torque_request: t, enable: flags[0] }, c)?;
        check_own(&dbc, &MotorStatus { ready: flags[0], fault: flags[1], derating: flags[2],
            cmd_timeout: flags[3], torque_actual: t, motor_speed: w, fault_code: code }, c)?;
        check_own(&dbc, &WheelSpeeds { driven_valid: flags[1], ref_valid: flags[2],
            omega_driven: w, omega_ref: -w }, c)?;
        check_own(&dbc, &VehicleSpeed { valid: flags[3], speed: v, long_accel: a }, c)?;
        check_own(&dbc, &DriverDemand { brake_pressed: flags[0], tcs_enable: flags[1],
            torque_demand: t, pedal_position: p }, c)?;
    }
}

/// A DBC grip cannot speak is refused with the file, the message or signal
/// and the reason: one edit of the shipped DBC per case.
#[test]
fn a_dbc_grip_cannot_speak_is_refused_naming_what_and_why() {
    let shipped = std::fs::read_to_string(shipped_path()).unwrap();
    let none = std::collections::BTreeMap::new();
    let cases: &[(&str, &str, &str, &str)] = &[
        // (text replaced, by, what, reason)
        (
            "BO_ 256 TorqueCommand",
            "BO_ 256 TorqueCmd",
            "message TorqueCommand",
            "not in the DBC (its messages: TorqueCmd,",
        ),
        (
            " SG_ OmegaRef :",
            " SG_ OmegaRight :",
            "signal WheelSpeeds.OmegaRef",
            "not in the message (its signals: CRC, Counter",
        ),
        (
            "BO_ 256 TorqueCommand",
            "BO_ 2147483904 TorqueCommand",
            "message TorqueCommand",
            "29-bit id 0x100",
        ),
        (
            "BO_ 304 VehicleSpeed: 8",
            "BO_ 304 VehicleSpeed: 6",
            "message VehicleSpeed",
            "DLC 6: grip's messages are 8 bytes",
        ),
        (
            " SG_ CRC : 0|8@1+ (1,0) [0|255] \"\" INV",
            " SG_ CRC : 4|8@1+ (1,0) [0|255] \"\" INV",
            "signal TorqueCommand.CRC",
            "the CRC must fill one whole byte",
        ),
        (
            " SG_ Counter : 8|4@1+ (1,0) [0|15] \"\" INV",
            " SG_ Counter : 8|3@1+ (1,0) [0|7] \"\" INV",
            "signal TorqueCommand.Counter",
            "3 bits long: grip's Counter needs 4 bits",
        ),
        (
            "[-327.68|327.67] \"rad/s\" TCS\n SG_ OmegaRef",
            "[-327.68|327.67] \"deg/s\" TCS\n SG_ OmegaRef",
            "signal WheelSpeeds.OmegaDriven",
            "unit \"deg/s\": grip computes OmegaDriven in rad/s and converts from \"rad/s\", \"rpm\"",
        ),
        (
            "BA_ \"GripE2eDataId\" BO_ 304 6660;",
            "",
            "message VehicleSpeed, attribute GripE2eDataId",
            "missing",
        ),
        (
            "BA_ \"GripTimeoutMs\" BO_ 320 50;",
            "BA_ \"GripTimeoutMs\" BO_ 320 0;",
            "message DriverDemand, attribute GripTimeoutMs",
            "0: must be a whole number of ms",
        ),
        (
            "TorqueRequest : 16|16@1-",
            "TorqueRequest : 12|16@1-",
            "signal TorqueCommand.TorqueRequest",
            "overlaps grip's TorqueCommand.Enable",
        ),
        (
            "TorqueActual : 16|16@1-",
            "TorqueActual : 56|16@1-",
            "signal MotorStatus.TorqueActual",
            "runs past the 8th byte",
        ),
        (
            "Enable : 12|1@1+ (1,0)",
            "Enable : 12|1@1+ (2,0)",
            "signal TorqueCommand.Enable",
            "grip reads Enable as a raw value",
        ),
        (
            "BO_ 272 MotorStatus",
            "BO_ 256 MotorStatus",
            "message MotorStatus",
            "id 0x100 is also grip's TorqueCommand",
        ),
        // found by the fuzz target (2026-12-05): a 16-bit "standard" id, and
        // a scaling whose values overflow to infinity
        (
            "BO_ 256 TorqueCommand",
            "BO_ 2304 TorqueCommand",
            "message TorqueCommand",
            "id 0x900 is not an 11-bit id",
        ),
        (
            "TorqueRequest : 16|16@1- (0.1,0)",
            "TorqueRequest : 16|16@1- (1e305,0)",
            "signal TorqueCommand.TorqueRequest",
            "the field's values are not finite numbers",
        ),
        // found in review (2026-12-05): a timeout under two periods, and a
        // float signal written as an integer
        (
            "BA_ \"GripTimeoutMs\" BO_ 272 10;",
            "BA_ \"GripTimeoutMs\" BO_ 272 1;",
            "message MotorStatus, attribute GripTimeoutMs",
            "1 ms is less than two periods (GenMsgCycleTime 1 ms)",
        ),
        (
            "VAL_ 256 Enable",
            "SIG_VALTYPE_ 256 TorqueRequest : 1;\nVAL_ 256 Enable",
            "signal TorqueCommand.TorqueRequest",
            "IEEEfloat32Bit (SIG_VALTYPE_): grip reads and writes integer raw values only",
        ),
    ];
    for (from, to, what, reason) in cases {
        assert!(shipped.contains(from), "{from}");
        let text = shipped.replacen(from, to, 1);
        let e = Protocol::from_dbc(&text, "bus.dbc", &none).unwrap_err();
        assert_eq!(e.file, "bus.dbc");
        assert_eq!(e.what, *what, "{e}");
        assert!(e.reason.contains(reason), "{e}\nwanted: {reason}");
        assert!(
            e.to_string().starts_with(&format!("bus.dbc: {what}: ")),
            "{e}"
        );
    }
    let e = Protocol::from_dbc("not a dbc at all", "bus.dbc", &none).unwrap_err();
    assert_eq!(
        (e.what.as_str(), e.reason.starts_with("not a DBC")),
        ("file", true),
        "{e}"
    );
    // on one line, with the position (it was the parser's Debug dump)
    assert!(
        e.reason
            .starts_with("not a DBC that can be parsed: line 1, column 1: ")
            && !e.reason.contains('\n'),
        "{e}"
    );
    // a signal line's mistake: the parser's position is where its last
    // choice failed (the byte order, before the factor's missing comma),
    // so the error quotes the line and the form a signal takes
    let text = shipped.replacen(
        "TorqueRequest : 16|16@1- (0.1,0)",
        "TorqueRequest : 16|16@1- (0.1 0)",
        1,
    );
    let e = Protocol::from_dbc(&text, "bus.dbc", &none).unwrap_err();
    assert!(
        e.reason.starts_with("not a DBC that can be parsed: line ")
            && e.reason
                .contains("; the line reads `SG_ TorqueRequest : 16|16@1- (0.1 0) [")
            && e.reason
                .contains("; a signal is `SG_ Name : start|length@order sign (factor,offset)")
            && !e.reason.contains('\n'),
        "{e}"
    );
    let line = text.lines().position(|l| l.contains("(0.1 0)")).unwrap() + 1;
    assert!(e.reason.contains(&format!("line {line}, ")), "{e}");
    // a line that is not a signal is quoted without the signal's form
    let text = shipped.replacen("BU_:", "BU_;", 1);
    let e = Protocol::from_dbc(&text, "bus.dbc", &none).unwrap_err();
    assert!(
        e.reason.contains("; the line reads `BU_;") && !e.reason.contains("a signal is"),
        "{e}"
    );
    // a byte-order mark and Windows-1252 bytes in a comment (as DBC
    // editors write them) read as the same protocol
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(
        shipped
            .replacen(
                "CM_ \"grip inverter bus",
                "CM_ \"grip inverter bus \u{00e9}",
                1,
            )
            .bytes(),
    );
    assert_eq!(
        &Protocol::from_dbc_bytes(&bytes, "bus.dbc", &none).unwrap(),
        Protocol::builtin()
    );
    let latin1: Vec<u8> = shipped
        .replacen(
            "CM_ \"grip inverter bus",
            "CM_ \"grip inverter bus \u{00e9}",
            1,
        )
        .chars()
        .map(|c| c as u32 as u8)
        .collect();
    assert!(std::str::from_utf8(&latin1).is_err());
    assert_eq!(
        &Protocol::from_dbc_bytes(&latin1, "bus.dbc", &none).unwrap(),
        Protocol::builtin()
    );
    // a name map entry that is not one of grip's names: a typo, not ignored
    let names = [("TorqueCommand.Torque".to_owned(), "TrqReq".to_owned())].into();
    let e = Protocol::from_dbc(&shipped, "bus.dbc", &names).unwrap_err();
    assert_eq!(
        (e.file.as_str(), e.what.as_str()),
        ("can.toml", "[dbc_names] TorqueCommand.Torque"),
        "{e}"
    );
    // a key in the wrong case: the right one suggested
    let names = [(
        "TorqueCommand.Torquerequest".to_owned(),
        "TrqReq".to_owned(),
    )]
    .into();
    let e = Protocol::from_dbc(&shipped, "bus.dbc", &names).unwrap_err();
    assert!(
        e.reason
            .contains("did you mean \"TorqueCommand.TorqueRequest\"?"),
        "{e}"
    );
    // a mapped name is named both ways
    let names = [("TorqueCommand".to_owned(), "MCU_TrqCmd".to_owned())].into();
    let e = Protocol::from_dbc(&shipped, "bus.dbc", &names).unwrap_err();
    assert_eq!(e.what, "message MCU_TrqCmd (grip's TorqueCommand)", "{e}");
    // an unreadable file
    let e = Protocol::load_dbc(std::path::Path::new("/nonexistent/bus.dbc"), &none).unwrap_err();
    assert_eq!(
        (e.file.as_str(), e.what.as_str()),
        ("/nonexistent/bus.dbc", "file"),
        "{e}"
    );
}
