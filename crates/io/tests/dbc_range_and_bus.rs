//! What a DBC says about a signal's range and about the bus, read and
//! acted on (found in the review of a user putting grip on their own car,
//! 2026-12-05): a signal's `[min|max]` bounds what grip sends; a message
//! declared CAN FD (`VFrameFormat`) is refused; the bus's `Baudrate` and
//! the messages' periods give a bus load that must stay under
//! `MAX_BUS_LOAD`.

use std::collections::BTreeMap;

use grip_io::can::protocol::*;

fn shipped() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/inverter.dbc");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn none() -> BTreeMap<String, String> {
    BTreeMap::new()
}

/// The shipped DBC with `from` replaced by `to` (which must be there).
fn edited(from: &str, to: &str) -> String {
    let s = shipped();
    assert!(s.contains(from), "{from}");
    s.replacen(from, to, 1)
}

fn load(text: &str) -> Result<Protocol, grip_io::can::DbcError> {
    Protocol::from_dbc(text, "car.dbc", &none())
}

const TRQ: &str = "TorqueRequest : 16|16@1- (0.1,0) [-3276.8|3276.7] \"Nm\"";

/// The review's repro: `TrqReq : 23|16@0- (0.5,0) [-250|250] "Nm"`. A
/// command of 300 N m went out as raw 600 (300 N m); it goes out as raw
/// 500, the range's end, read back bit by bit as the DBC lays it out.
#[test]
fn a_command_beyond_the_dbcs_range_is_sent_at_its_end() {
    let text = edited(TRQ, "TorqueRequest : 23|16@0- (0.5,0) [-250|250] \"Nm\"");
    let p = load(&text).unwrap();
    let spec = p.spec(MsgKind::TorqueCommand);
    for (sent, raw) in [(300.0, 500), (-300.0, -500), (249.5, 499), (f64::NAN, 0)] {
        let f = encode_in(
            spec,
            &TorqueCommand {
                torque_request: sent,
                enable: true,
            },
            0,
            0,
        );
        // Motorola, MSB at bit 23 (byte 2 bit 7): bytes 2-3 big-endian
        let got = i16::from_be_bytes([f.data[2], f.data[3]]);
        assert_eq!(i64::from(got), raw, "{sent} N m");
        // and grip's own receiver decodes it in range
        let back = TorqueCommand::read_signals_in(spec, &f.data);
        assert!(back.torque_request.abs() <= 250.0 || sent.is_nan());
    }
    assert_eq!(spec.signals[3].phys_limits(), (-250.0, 250.0));
}

/// A range in a unit grip converts is applied in grip's unit: MotorSpeed
/// in rpm, [-6000|6000] rpm, is about ±628.3 rad/s on the wire.
#[test]
fn a_range_in_a_converted_unit_is_applied_in_grips_unit() {
    let text = edited(
        "MotorSpeed : 32|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"",
        "MotorSpeed : 32|16@1- (1,0) [-6000|6000] \"rpm\"",
    );
    let p = load(&text).unwrap();
    let s = &p.spec(MsgKind::MotorStatus).signals[7];
    assert_eq!((s.raw_min(), s.raw_max()), (-6000, 6000));
    let mut d = [0u8; 8];
    s.put(&mut d, 1000.0); // rad/s, about 9549 rpm
    assert_eq!(s.get_raw(&d), 6000);
}

/// `[0|0]` says "no range" in a DBC: the bit field alone bounds it, and
/// such a DBC loads.
#[test]
fn a_zero_range_is_no_range() {
    let text = edited(TRQ, "TorqueRequest : 16|16@1- (0.1,0) [0|0] \"Nm\"");
    let p = load(&text).unwrap();
    let s = &p.spec(MsgKind::TorqueCommand).signals[3];
    assert!(!s.has_range());
    assert_eq!(s.to_raw(5000.0), 32767);
}

/// Ranges grip cannot keep are refused naming the signal and the range.
#[test]
fn a_range_grip_cannot_keep_is_refused() {
    for (to, reason) in [
        (
            "TorqueRequest : 16|16@1- (0.1,0) [250|-250] \"Nm\"",
            "range [250|-250] \"Nm\": its minimum is above its maximum",
        ),
        (
            "TorqueRequest : 16|16@1- (0.1,0) [5000|6000] \"Nm\"",
            "range [5000|6000] \"Nm\": fewer than two of the values the 16-bit field holds",
        ),
        (
            "TorqueRequest : 16|16@1- (0.1,0) [7|7] \"Nm\"",
            "range [7|7] \"Nm\": fewer than two",
        ),
    ] {
        let e = load(&edited(TRQ, to)).unwrap_err();
        assert_eq!(
            (e.file.as_str(), e.what.as_str()),
            ("car.dbc", "signal TorqueCommand.TorqueRequest"),
            "{e}"
        );
        assert!(e.reason.contains(reason), "{e}\nwanted: {reason}");
    }
}

const ATTR_DEFS: &str = "BA_DEF_DEF_ \"GenMsgCycleTime\" 0;";

/// A DBC with `extra` lines after its attribute definitions' defaults.
fn with(extra: &str) -> String {
    edited(ATTR_DEFS, &format!("{ATTR_DEFS}\n{extra}"))
}

/// The frame format the review found ignored: `VFrameFormat` 14
/// (StandardCAN_FD) and 15 (ExtendedCAN_FD) on one of grip's messages are
/// refused naming the file, the message and the attribute; 0 (StandardCAN)
/// loads; a number is read through the DBC's own ENUM where it has one; a
/// default of "StandardCAN_FD" applies to every message without a value.
#[test]
fn a_message_declared_can_fd_is_refused() {
    let def = "BA_DEF_ BO_ \"VFrameFormat\" ENUM \"StandardCAN\",\"ExtendedCAN\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"reserved\",\"StandardCAN_FD\",\"ExtendedCAN_FD\";";
    let cases: &[(String, &str, &str)] = &[
        (
            with("BA_ \"VFrameFormat\" BO_ 272 14;"),
            "message MotorStatus, attribute VFrameFormat",
            "VFrameFormat 14 (StandardCAN_FD): a CAN FD frame; grip sends and receives classic CAN frames only",
        ),
        (
            with(&format!("{def}\nBA_ \"VFrameFormat\" BO_ 256 15;")),
            "message TorqueCommand, attribute VFrameFormat",
            "VFrameFormat 15 (ExtendedCAN_FD): a CAN FD frame",
        ),
        (
            with("BA_ \"VFrameFormat\" BO_ 288 1;"),
            "message WheelSpeeds, attribute VFrameFormat",
            "VFrameFormat 1 (ExtendedCAN): a 29-bit frame",
        ),
        (
            with(&format!(
                "{}\nBA_DEF_DEF_ \"VFrameFormat\" \"StandardCAN_FD\";",
                def
            )),
            "message TorqueCommand, attribute VFrameFormat",
            "VFrameFormat \"StandardCAN_FD\": a CAN FD frame",
        ),
        (
            with("BA_ \"VFrameFormat\" BO_ 320 3;"),
            "message DriverDemand, attribute VFrameFormat",
            "VFrameFormat 3 (J1939PG): not a classic CAN frame with an 11-bit id",
        ),
    ];
    for (text, what, reason) in cases {
        let e = load(text).unwrap_err();
        assert_eq!(
            (e.file.as_str(), e.what.as_str()),
            ("car.dbc", *what),
            "{e}"
        );
        assert!(e.reason.contains(reason), "{e}\nwanted: {reason}");
        assert!(e.to_string().starts_with(&format!("car.dbc: {what}: ")));
    }
    // classic frames declared as such load, as the built-in protocol
    let ok = with(&format!(
        "{def}\nBA_DEF_DEF_ \"VFrameFormat\" \"StandardCAN\";\nBA_ \"VFrameFormat\" BO_ 256 0;"
    ));
    assert_eq!(&load(&ok).unwrap(), Protocol::builtin());
}

/// The bit rate the review found ignored: at `Baudrate` 500000 grip's
/// messages (three every 1 ms, two every 10 ms, 135 bits each at worst)
/// take 86.4 % of the bus, and the DBC is refused saying so; at 1000000
/// they take 43.2 % and it loads, as does a DBC that gives none (1 Mbit/s
/// assumed, said so).
#[test]
fn a_bus_too_slow_for_grips_messages_is_refused_with_its_load() {
    let e = load(&with("BA_ \"Baudrate\" 500000;")).unwrap_err();
    assert_eq!(e.what, "attribute Baudrate", "{e}");
    assert!(
        e.reason.contains(
            "grip's five messages would take 86.4 % of the DBC's 500 kbit/s at worst (135 bits per 8-byte frame"
        ) && e.reason.contains("TorqueCommand every 1 ms")
            && e.reason.contains("DriverDemand every 10 ms")
            && e.reason.contains("at most 50 %"),
        "{e}"
    );
    // the same from the attribute's default (a CANdb++ template's)
    let e = load(&with(
        "BA_DEF_ \"Baudrate\" INT 1000 1000000;\nBA_DEF_DEF_ \"Baudrate\" 500000;",
    ))
    .unwrap_err();
    assert!(e.reason.contains("86.4 % of the DBC's 500 kbit/s"), "{e}");

    let p = load(&with("BA_ \"Baudrate\" 1000000;")).unwrap();
    assert_eq!(
        *p.bus(),
        BusTiming {
            bitrate: 1_000_000,
            dbc_bitrate: Some(1_000_000),
            interface: None,
            can_fd_bus: false
        }
    );
    assert!((p.bus_load() - 0.432).abs() < 1e-12);
    assert!(
        p.describe_bus()
            .starts_with("1000 kbit/s (the DBC's Baudrate), grip's messages 43.2 % of it"),
        "{}",
        p.describe_bus()
    );
    let p = load(&shipped()).unwrap();
    assert!(
        p.describe_bus()
            .starts_with("1000 kbit/s (assumed: no Baudrate in the DBC)"),
        "{}",
        p.describe_bus()
    );

    // no Baudrate, but periods that do not fit 1 Mbit/s either
    let text = shipped()
        .replace(
            "BA_ \"GenMsgCycleTime\" BO_ 304 10;",
            "BA_ \"GenMsgCycleTime\" BO_ 304 1;",
        )
        .replace(
            "BA_ \"GenMsgCycleTime\" BO_ 320 10;",
            "BA_ \"GenMsgCycleTime\" BO_ 320 1;",
        )
        .replace(
            "BA_ \"GripTimeoutMs\" BO_ 304 50;",
            "BA_ \"GripTimeoutMs\" BO_ 304 5;",
        );
    let e = load(&text).unwrap_err();
    assert_eq!(e.what, "bus load", "{e}");
    assert!(
        e.reason
            .contains("67.5 % of 1000 kbit/s (no Baudrate in the DBC: grip's bus assumed)"),
        "{e}"
    );
}

/// Bit rates that are no classic CAN bus's, and bus types that are not
/// CAN, are refused; a CAN FD bus carrying grip's messages as classic
/// frames loads and says so.
#[test]
fn bit_rates_and_bus_types_grip_cannot_use_are_refused() {
    for (extra, what, reason) in [
        (
            "BA_ \"Baudrate\" 2000000;",
            "attribute Baudrate (BA_)",
            "2000000 bit/s: classic CAN runs at 1 Mbit/s at most",
        ),
        (
            "BA_ \"Baudrate\" 500;",
            "attribute Baudrate (BA_)",
            "500: must be a whole number of bit/s in 10000..=1000000",
        ),
        (
            "BA_ \"BusType\" \"LIN\";",
            "attribute BusType (BA_)",
            "\"LIN\": grip speaks CAN",
        ),
    ] {
        let e = load(&with(extra)).unwrap_err();
        assert_eq!(e.what, what, "{e}");
        assert!(e.reason.contains(reason), "{e}\nwanted: {reason}");
    }
    let p = load(&with(
        "BA_ \"BusType\" \"CAN FD\";\nBA_ \"Baudrate\" 1000000;",
    ))
    .unwrap();
    assert!(p.bus().can_fd_bus);
    assert!(
        p.describe_bus().contains("CAN FD bus"),
        "{}",
        p.describe_bus()
    );
    // a template's default of 0 is "not set"
    let p = load(&with(
        "BA_DEF_ \"Baudrate\" INT 0 1000000;\nBA_DEF_DEF_ \"Baudrate\" 0;",
    ))
    .unwrap();
    assert_eq!(*p.bus(), BusTiming::ASSUMED);
}

/// The test bus of the other tests still loads, with its own ranges equal
/// to its bit fields.
#[test]
fn own_bus_dbc_still_loads() {
    let p = Protocol::load_dbc(
        &grip_testkit::own_bus::dbc_path(),
        &grip_testkit::own_bus::names(),
    )
    .unwrap();
    assert!(p.bus_load() <= MAX_BUS_LOAD);
}
