//! Two things a car's own bus needs (2026-12-05): validity flags whose
//! sense is not grip's (a bit that says *invalid* when set, or one state of
//! a multi-bit status; `can.toml` `[dbc_valid]`, else the DBC's `VAL_`
//! table), and wheel speeds sent as the wheel's circumferential speed in
//! km/h or m/s, converted with the vehicle file's rolling radii (ω = v ÷ r).

use std::collections::BTreeMap;

use grip_io::can::DbcSettings;
use grip_io::can::protocol::*;

fn shipped() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/inverter.dbc");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The shipped DBC with each `from` replaced by its `to` (which must be
/// there).
fn edited(edits: &[(&str, &str)]) -> String {
    let mut s = shipped();
    for (from, to) in edits {
        assert!(s.contains(from), "{from}");
        s = s.replacen(from, to, 1);
    }
    s
}

fn valid(entries: &[(&str, i64)]) -> BTreeMap<String, i64> {
    entries.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect()
}

fn load(text: &str, settings: &DbcSettings) -> Result<Protocol, grip_io::can::DbcError> {
    Protocol::from_dbc_with(text, "car.dbc", settings)
}

const DRIVEN_VALID: &str = "DrivenValid : 12|1@1+ (1,0) [0|1] \"\"";
const OMEGA_DRIVEN: &str = "OmegaDriven : 16|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"";
const OMEGA_REF: &str = "OmegaRef : 32|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"";
const VS_VALID: &str = "SG_ Valid : 12|1@1+ (1,0) [0|1] \"\"";

/// A WheelSpeeds payload as the bus carries it, built bit by bit: the
/// DrivenValid bit (bit 12) and OmegaDriven's raw value (bits 16-31,
/// Intel).
fn wheel_payload(driven_bit: bool, omega_raw: i16) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[1] = u8::from(driven_bit) << 4;
    d[2..4].copy_from_slice(&omega_raw.to_le_bytes());
    d
}

/// A bus whose bit 12 says the driven wheel's speed is *invalid* when
/// set (`DrivenInvalid`, mapped by `[dbc_names]`), with `[dbc_valid]
/// "WheelSpeeds.DrivenValid" = 0`: bit 0 reads valid, bit 1 invalid;
/// grip sends valid as 0 and invalid as 1, and both round-trip through an
/// E2E receiver. The same DBC without the entry reads the bits as grip's
/// (the entry is what changes it).
#[test]
fn an_inverted_validity_bit_is_read_and_sent_in_its_sense() {
    let text = edited(&[(DRIVEN_VALID, "DrivenInvalid : 12|1@1+ (1,0) [0|1] \"\"")]);
    let names: BTreeMap<String, String> = [("WheelSpeeds.DrivenValid", "DrivenInvalid")]
        .into_iter()
        .map(|(a, b)| (a.to_owned(), b.to_owned()))
        .collect();
    let inverted = DbcSettings {
        names: names.clone(),
        valid: valid(&[("WheelSpeeds.DrivenValid", 0)]),
        radii: None,
        skip_bus_load: false,
    };
    let p: &'static Protocol = Box::leak(Box::new(load(&text, &inverted).unwrap()));
    let spec = p.spec(MsgKind::WheelSpeeds);
    assert_eq!(spec.signals[2].set_raw, Some(0));
    assert_eq!(spec.signals[3].set_raw, None, "RefValid keeps grip's sense");
    for (bit, want) in [(false, true), (true, false)] {
        let m = WheelSpeeds::read_signals_in(spec, &wheel_payload(bit, 1234));
        assert_eq!(m.driven_valid, want, "bit 12 = {bit}");
        assert!((m.omega_driven - 12.34).abs() < 1e-9);
    }
    // sent in the bus's sense, read back bit by bit and by grip's receiver
    let mut rx = E2eReceiver::new(spec);
    for (k, driven_valid) in [true, false, true].into_iter().enumerate() {
        let sent = WheelSpeeds {
            driven_valid,
            ref_valid: true,
            omega_driven: 10.0,
            omega_ref: 9.5,
        };
        let f = encode_in(spec, &sent, k as u8, 0);
        assert_eq!(f.data[1] >> 4 & 1, u8::from(!driven_valid), "{sent:?}");
        assert_eq!(f.data[1] >> 5 & 1, 1, "RefValid still 1 = valid");
        rx.check(&f, k as u64).unwrap();
        match InverterMsg::decode_as(spec, &f.data) {
            InverterMsg::WheelSpeeds(back) => assert_eq!(back, sent),
            other => panic!("{other:?}"),
        }
    }
    // without [dbc_valid] the very same bits mean grip's default
    let plain = load(&text, &DbcSettings::with_names(&names)).unwrap();
    let m = WheelSpeeds::read_signals_in(plain.spec(MsgKind::WheelSpeeds), &wheel_payload(true, 0));
    assert!(m.driven_valid);
    assert_ne!(plain, *p);
}

/// A multi-bit status where one value means valid: VehicleSpeed's 2-bit
/// `SpdStatus` with 2 = valid (0 init, 1 invalid, 3 error). Only 2 reads
/// valid; grip sends valid as 2 and invalid as 0.
#[test]
fn one_state_of_a_multi_bit_status_is_valid() {
    let text = edited(&[(VS_VALID, "SG_ Valid : 12|2@1+ (1,0) [0|3] \"\"")]);
    let settings = DbcSettings {
        valid: valid(&[("VehicleSpeed.Valid", 2)]),
        ..DbcSettings::default()
    };
    let p = load(&text, &settings).unwrap();
    let spec = p.spec(MsgKind::VehicleSpeed);
    for raw in 0..4u8 {
        let mut d = [0u8; 8];
        d[1] = raw << 4;
        assert_eq!(
            VehicleSpeed::read_signals_in(spec, &d).valid,
            raw == 2,
            "raw {raw}"
        );
    }
    for v in [true, false] {
        let m = VehicleSpeed {
            valid: v,
            speed: 12.5,
            long_accel: 0.5,
        };
        let f = encode_in(spec, &m, 0, 0);
        assert_eq!(f.data[1] >> 4 & 3, if v { 2 } else { 0 });
        assert_eq!(VehicleSpeed::read_signals_in(spec, &f.data), m);
    }
    // without the entry: non-zero, grip's default (1, 2 and 3 valid)
    let p = load(&text, &DbcSettings::default()).unwrap();
    let mut d = [0u8; 8];
    d[1] = 3 << 4;
    assert!(VehicleSpeed::read_signals_in(p.spec(MsgKind::VehicleSpeed), &d).valid);
}

/// The DBC's `VAL_` table, when one state is named `Valid`, gives the
/// sense; `[dbc_valid]` wins over it.
#[test]
fn the_val_table_names_the_valid_state_and_can_toml_wins() {
    let text = edited(&[(
        "VAL_ 272 Ready",
        "VAL_ 288 DrivenValid 0 \"Valid\" 1 \"Invalid\" ;\nVAL_ 272 Ready",
    )]);
    let p = load(&text, &DbcSettings::default()).unwrap();
    let spec = p.spec(MsgKind::WheelSpeeds);
    assert_eq!(spec.signals[2].set_raw, Some(0));
    assert!(WheelSpeeds::read_signals_in(spec, &wheel_payload(false, 0)).driven_valid);
    let set = DbcSettings {
        valid: valid(&[("WheelSpeeds.DrivenValid", 1)]),
        ..DbcSettings::default()
    };
    let p = load(&text, &set).unwrap();
    let spec = p.spec(MsgKind::WheelSpeeds);
    assert_eq!(spec.signals[2].set_raw, None, "1 on a 1-bit flag: non-zero");
    assert!(WheelSpeeds::read_signals_in(spec, &wheel_payload(true, 0)).driven_valid);
    // "Invalid", "Not valid" name no valid state
    let text = edited(&[(
        "VAL_ 272 Ready",
        "VAL_ 288 DrivenValid 0 \"Not valid\" 1 \"Invalid\" ;\nVAL_ 272 Ready",
    )]);
    let p = load(&text, &DbcSettings::default()).unwrap();
    assert_eq!(p.spec(MsgKind::WheelSpeeds).signals[2].set_raw, None);
}

/// The shipped DBC keeps the built-in protocol exactly, with the radii
/// given (its wheel speeds are angular: none is used) and with a
/// `[dbc_valid]` that says what the built-in protocol says.
#[test]
fn the_shipped_dbc_is_still_the_built_in_protocol() {
    let radii = Some(WheelRadii {
        driven_m: 0.3,
        reference_m: 0.29,
    });
    for settings in [
        DbcSettings::default(),
        DbcSettings {
            radii,
            ..DbcSettings::default()
        },
        DbcSettings {
            valid: valid(&[("WheelSpeeds.DrivenValid", 1), ("VehicleSpeed.Valid", 1)]),
            radii,
            ..DbcSettings::default()
        },
    ] {
        let p = load(&shipped(), &settings).unwrap();
        assert_eq!(&p, Protocol::builtin(), "{settings:?}");
        assert_eq!(p.wheel_radii(), None);
    }
    assert_eq!(
        Protocol::builtin().describe_speeds(),
        "wheel speeds angular; valid: WheelSpeeds.DrivenValid non-zero, WheelSpeeds.RefValid non-zero, VehicleSpeed.Valid non-zero"
    );
}

/// OmegaDriven in km/h (0.01 km/h per bit) at r = 0.3 m: 36 km/h on the
/// bus (raw 3600) is 33.33 rad/s; OmegaRef in m/s at r_ref = 0.29 m: 10
/// m/s is 34.48 rad/s. What grip sends converts back (within one step),
/// and the range is applied in rad/s.
#[test]
fn a_wheel_speed_in_km_h_is_converted_with_the_rolling_radius() {
    let text = edited(&[
        (
            OMEGA_DRIVEN,
            "OmegaDriven : 16|16@1- (0.01,0) [-300|300] \"km/h\"",
        ),
        (OMEGA_REF, "OmegaRef : 32|16@1+ (0.005,0) [0|0] \"m/s\""),
    ]);
    let radii = WheelRadii {
        driven_m: 0.3,
        reference_m: 0.29,
    };
    let settings = DbcSettings {
        radii: Some(radii),
        ..DbcSettings::default()
    };
    let p = load(&text, &settings).unwrap();
    assert_eq!(p.wheel_radii(), Some(radii));
    assert!(
        p.describe_speeds()
            .starts_with("wheel speeds converted from km/h or m/s with r = 0.3 m, r_ref = 0.29 m"),
        "{}",
        p.describe_speeds()
    );
    let spec = p.spec(MsgKind::WheelSpeeds);
    let mut d = wheel_payload(true, 3600);
    d[4..6].copy_from_slice(&2000u16.to_le_bytes()); // 10 m/s
    let m = WheelSpeeds::read_signals_in(spec, &d);
    assert!(
        (m.omega_driven - 36.0 / 3.6 / 0.3).abs() < 1e-9,
        "{}",
        m.omega_driven
    );
    assert!((m.omega_driven - 33.33).abs() < 0.01);
    assert!((m.omega_ref - 10.0 / 0.29).abs() < 1e-9, "{}", m.omega_ref);
    // V = r_ref · OmegaRef is the reference wheel's speed in m/s
    assert!((0.29 * m.omega_ref - 10.0).abs() < 1e-9);

    // one step in rad/s
    let lsb_driven = 0.01 / 3.6 / 0.3;
    let lsb_ref = 0.005 / 0.29;
    let os = &spec.signals[4];
    assert!((os.factor - lsb_driven).abs() < 1e-15, "{}", os.factor);
    for omega in [0.0, 1.0, 33.33, 100.0, 250.0, -42.1] {
        let sent = WheelSpeeds {
            driven_valid: true,
            ref_valid: true,
            omega_driven: omega,
            omega_ref: omega.abs(),
        };
        let f = encode_in(spec, &sent, 0, 0);
        // the frame carries km/h ÷ 0.01 and m/s ÷ 0.005, bit by bit
        let kmh = f64::from(i16::from_le_bytes([f.data[2], f.data[3]])) * 0.01;
        let mps = f64::from(u16::from_le_bytes([f.data[4], f.data[5]])) * 0.005;
        assert!(
            (kmh - omega * 0.3 * 3.6).abs() <= 0.005 + 1e-9,
            "{omega}: {kmh}"
        );
        assert!(
            (mps - omega.abs() * 0.29).abs() <= 0.0025 + 1e-9,
            "{omega}: {mps}"
        );
        let back = WheelSpeeds::read_signals_in(spec, &f.data);
        assert!((back.omega_driven - omega).abs() <= lsb_driven, "{omega}");
        assert!((back.omega_ref - omega.abs()).abs() <= lsb_ref, "{omega}");
    }
    // the range, [-300|300] km/h, in rad/s: 277.8 rad/s at r = 0.3 m
    let (lo, hi) = os.phys_limits();
    assert!((hi - 300.0 / 3.6 / 0.3).abs() < 1e-9 && (lo + hi).abs() < 1e-9);
    let f = encode_in(
        spec,
        &WheelSpeeds {
            omega_driven: 1e4,
            ..WheelSpeeds::default()
        },
        0,
        0,
    );
    assert_eq!(i16::from_le_bytes([f.data[2], f.data[3]]), 30000);
}

/// Without the radii a wheel speed in km/h is refused, naming the file,
/// the signal, the unit and the radius it needs, not read as rad/s;
/// so is one in a unit that is neither angular nor linear, and a linear
/// unit on a signal that is no wheel's (MotorSpeed).
#[test]
fn a_linear_wheel_speed_without_a_radius_is_refused() {
    let kmh = edited(&[(
        OMEGA_DRIVEN,
        "OmegaDriven : 16|16@1- (0.01,0) [-300|300] \"km/h\"",
    )]);
    for e in [
        load(&kmh, &DbcSettings::default()).unwrap_err(),
        Protocol::from_dbc(&kmh, "car.dbc", &BTreeMap::new()).unwrap_err(),
    ] {
        assert_eq!(e.file, "car.dbc");
        assert_eq!(e.what, "signal WheelSpeeds.OmegaDriven");
        for want in [
            "unit \"km/h\": a wheel's circumferential speed",
            "needs the driven wheel's rolling radius (r in the vehicle file)",
            "not read as rad/s",
        ] {
            assert!(e.reason.contains(want), "{e}\nwanted: {want}");
        }
    }
    let mps = edited(&[(OMEGA_REF, "OmegaRef : 32|16@1- (0.01,0) [0|0] \"m/s\"")]);
    let e = load(&mps, &DbcSettings::default()).unwrap_err();
    assert_eq!(e.what, "signal WheelSpeeds.OmegaRef");
    assert!(
        e.reason
            .contains("the reference wheel's rolling radius (r_ref in the vehicle file)"),
        "{e}"
    );
    let radii = DbcSettings {
        radii: Some(WheelRadii {
            driven_m: 0.3,
            reference_m: 0.3,
        }),
        ..DbcSettings::default()
    };
    let degs = edited(&[(
        OMEGA_DRIVEN,
        "OmegaDriven : 16|16@1- (0.01,0) [0|0] \"deg/s\"",
    )]);
    let e = load(&degs, &radii).unwrap_err();
    assert!(
        e.reason.contains("unit \"deg/s\"")
            && e.reason.contains("\"rpm\"")
            && e.reason.contains("\"km/h\""),
        "{e}"
    );
    let motor = edited(&[(
        "MotorSpeed : 32|16@1- (0.01,0) [-327.68|327.67] \"rad/s\"",
        "MotorSpeed : 32|16@1- (0.01,0) [0|0] \"km/h\"",
    )]);
    let e = load(&motor, &radii).unwrap_err();
    assert_eq!(e.what, "signal MotorStatus.MotorSpeed");
    assert!(
        e.reason
            .ends_with("converts from \"rad/s\", \"rpm\", \"1/min\", \"min-1\", \"u/min\""),
        "{e}"
    );
    // a radius that is no length is refused, not divided by
    let zero = DbcSettings {
        radii: Some(WheelRadii {
            driven_m: 0.0,
            reference_m: 0.3,
        }),
        ..DbcSettings::default()
    };
    let e = load(&kmh, &zero).unwrap_err();
    assert_eq!(e.what, "vehicle.r", "{e}");
}

/// A bad `[dbc_valid]` entry is refused naming can.toml, the key and the
/// reason: a key that is none of grip's names (in the wrong case: grip's
/// spelling offered), a value grip reads as a number, a flag that is no
/// validity flag, a message, and a value the signal's field cannot carry.
#[test]
fn a_bad_dbc_valid_entry_is_refused_naming_can_toml_the_key_and_why() {
    let cases: [(&str, i64, &str); 7] = [
        (
            "WheelSpeeds.DrivenOk",
            0,
            "not one of grip's validity flags: [dbc_valid] takes \"WheelSpeeds.DrivenValid\", \"WheelSpeeds.RefValid\", \"VehicleSpeed.Valid\"",
        ),
        (
            "wheelspeeds.drivenvalid",
            0,
            "did you mean \"WheelSpeeds.DrivenValid\"?",
        ),
        ("WheelSpeeds.OmegaDriven", 0, "not a flag"),
        ("MotorStatus.Fault", 0, "a flag, but not a validity flag"),
        ("WheelSpeeds", 0, "a message, not a flag"),
        (
            "WheelSpeeds.DrivenValid",
            2,
            "2: the DBC's signal WheelSpeeds.DrivenValid is a 1-bit unsigned field, which carries raw 0..=1 only",
        ),
        (
            "VehicleSpeed.Valid",
            -1,
            "-1: the DBC's signal VehicleSpeed.Valid is a 1-bit unsigned field",
        ),
    ];
    for (key, v, want) in cases {
        let settings = DbcSettings {
            valid: valid(&[(key, v)]),
            ..DbcSettings::default()
        };
        let e = load(&shipped(), &settings).unwrap_err();
        assert_eq!(e.file, "can.toml", "{key}: {e}");
        assert_eq!(e.what, format!("[dbc_valid] {key}"), "{e}");
        assert!(e.reason.contains(want), "{key}: {e}\nwanted: {want}");
    }
}

/// Through a service's start-up: the refusal names can.toml by its path;
/// `[dbc_valid]` without a DBC is refused; a km/h wheel speed without
/// radii (`install_protocol`, which no vehicle file backs) is refused
/// naming the DBC by its path.
#[test]
fn the_services_start_up_names_the_files() {
    use grip_config::ConfigDir;
    use grip_io::service::{install_protocol, install_protocol_with, load_can};
    let t = tempfile::tempdir().unwrap();
    let d = ConfigDir::new(t.path());
    let kmh = edited(&[(
        OMEGA_DRIVEN,
        "OmegaDriven : 16|16@1- (0.01,0) [-300|300] \"km/h\"",
    )]);
    std::fs::write(t.path().join("car.dbc"), &kmh).unwrap();
    std::fs::write(
        t.path().join("can.toml"),
        "interface = \"vcan0\"\ndbc = \"car.dbc\"\n[dbc_valid]\n\"WheelSpeeds.DrivenValid\" = 3\n",
    )
    .unwrap();
    let can = load_can(&d).unwrap();
    let radii = Some(WheelRadii {
        driven_m: 0.3,
        reference_m: 0.3,
    });
    let e = install_protocol_with(&d, &can, radii).unwrap_err();
    assert_eq!(e.file, t.path().join("can.toml"), "{e}");
    assert_eq!(e.field, "[dbc_valid] WheelSpeeds.DrivenValid", "{e}");
    assert!(e.to_string().contains("carries raw 0..=1 only"), "{e}");

    std::fs::write(
        t.path().join("can.toml"),
        "interface = \"vcan0\"\ndbc = \"car.dbc\"\n",
    )
    .unwrap();
    let e = install_protocol(&d, &load_can(&d).unwrap()).unwrap_err();
    assert_eq!(e.file, t.path().join("car.dbc"), "{e}");
    assert_eq!(e.field, "signal WheelSpeeds.OmegaDriven", "{e}");

    std::fs::write(
        t.path().join("can.toml"),
        "interface = \"vcan0\"\n[dbc_valid]\n\"WheelSpeeds.DrivenValid\" = 0\n",
    )
    .unwrap();
    let e = install_protocol_with(&d, &load_can(&d).unwrap(), radii).unwrap_err();
    assert_eq!(e.field, "dbc_valid", "{e}");
    assert!(e.reason.contains("no dbc = \"FILE\""), "{e}");
}
