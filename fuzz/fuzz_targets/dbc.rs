//! The DBC loader: `Protocol::from_dbc` (what a service runs at start-up on
//! `can.toml`'s `dbc`), then the protocol it builds through the encoder,
//! the decoders and the E2E receiver.
//!
//! Input: one set-up byte (bit 0: use the name map `tests/data/own-bus.dbc`
//! needs, as its `can.toml [dbc_names]` would give it; otherwise none; bit
//! 1: a `[dbc_valid]` of `WheelSpeeds.DrivenValid` = 0 and
//! `VehicleSpeed.Valid` = bits 2-3; bit 4: the wheels' radii given, 0.3 m
//! and 0.29 m, so wheel speeds in km/h or m/s load), then the DBC's text
//! (UTF-8, else read byte by byte as Latin-1, as `Protocol::load_dbc`
//! does). The values encoded are drawn from a hash of the whole input.
//!
//! Checked besides "no panic":
//! - a refusal's `Display` starts with the file name given (`fuzz.dbc: `),
//!   or, for a `[dbc_valid]` value the DBC's field cannot carry, with
//!   `can.toml: [dbc_valid] `;
//! - an accepted protocol has grip's five messages in `MsgKind` order, with
//!   distinct 11-bit ids (≤ 0x7FF), DLC 8, grip's signals in grip's order,
//!   the CRC in one whole byte and a 4-bit counter; `spec`/`spec_for_id`
//!   agree with `messages()`;
//! - every scalar signal's range (raw minimum and maximum, scaled) is
//!   finite, and any payload decodes (`decode_as`) to finite values;
//! - for each message, a few messages with values from the input, encoded
//!   with `encode_in`, decode back (`read_signals_in`, `decode_as`): flags
//!   exactly (each in its sense: `[dbc_valid]`, the DBC's `VAL_`, else
//!   non-zero), the fault code as its bit field holds it, a value in the
//!   signal's range to within half its resolution (plus rounding), one
//!   beyond the range to the nearer end, a non-finite one as the physical
//!   value 0 (saturated at the range like any other); the
//!   frame's counter and CRC byte are the ones the spec says, and an
//!   `E2eReceiver` for the spec accepts the frames in counter order and
//!   rejects a frame with one bit flipped or its counter repeated.
#![no_main]

use std::collections::BTreeMap;
use std::sync::{Mutex, OnceLock};

use grip_io::can::DbcSettings;
use grip_io::can::protocol::{
    DriverDemand, E2eError, E2eReceiver, InverterMsg, MessageSpec, MotorStatus, MsgKind, Protocol,
    ProtocolMessage, SignalSpec, TorqueCommand, VehicleSpeed, WheelRadii, WheelSpeeds, e2e_crc_at,
    encode_in,
};
use libfuzzer_sys::fuzz_target;

const FILE: &str = "fuzz.dbc";

/// The `[dbc_names]` of `tests/data/own-bus.dbc`.
fn own_bus_names() -> &'static BTreeMap<String, String> {
    static NAMES: OnceLock<BTreeMap<String, String>> = OnceLock::new();
    NAMES.get_or_init(|| {
        [
            ("TorqueCommand", "MCU_TrqCmd"),
            ("TorqueCommand.TorqueRequest", "TrqReq"),
            ("DriverDemand", "VCU_Demand"),
            ("DriverDemand.TorqueDemand", "TrqDmd"),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect()
    })
}

/// The harness itself: both repository DBCs load (the built-in one to the
/// built-in protocol). Once per process.
fn check_repository_dbcs() {
    static DONE: OnceLock<()> = OnceLock::new();
    DONE.get_or_init(|| {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let p = Protocol::load_dbc(&root.join("config/inverter.dbc"), &BTreeMap::new())
            .expect("config/inverter.dbc");
        assert_eq!(&p, Protocol::builtin(), "config/inverter.dbc != built-in");
        let with_radii = DbcSettings {
            radii: Some(RADII),
            ..DbcSettings::default()
        };
        let p = Protocol::load_dbc_with(&root.join("config/inverter.dbc"), &with_radii)
            .expect("config/inverter.dbc with radii");
        assert_eq!(
            &p,
            Protocol::builtin(),
            "config/inverter.dbc with radii != built-in"
        );
        Protocol::load_dbc(&root.join("tests/data/own-bus.dbc"), own_bus_names())
            .expect("tests/data/own-bus.dbc");
    });
}

/// The radii given with set-up bit 4.
const RADII: WheelRadii = WheelRadii {
    driven_m: 0.3,
    reference_m: 0.29,
};

/// `&'static` specifications for `E2eReceiver`: accepted protocols are
/// leaked once each (most accepted inputs give one already seen).
fn leak(p: Protocol) -> &'static Protocol {
    static SEEN: Mutex<Vec<&'static Protocol>> = Mutex::new(Vec::new());
    let mut seen = SEEN.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(&q) = seen.iter().find(|&&q| *q == p) {
        return q;
    }
    let q: &'static Protocol = Box::leak(Box::new(p));
    if seen.len() >= 256 {
        seen.remove(0);
    }
    seen.push(q);
    q
}

/// splitmix64: the values to encode, from the input's hash.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn bool(&mut self) -> bool {
        self.next() & 1 == 1
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn fnv1a(data: &[u8]) -> u64 {
    data.iter().fold(0xCBF2_9CE4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01B3)
    })
}

/// The physical ends of what a scalar signal sends (its DBC range where
/// it gives one, within its bit field): (lower, upper).
fn range(s: &SignalSpec) -> (f64, f64) {
    let a = s.to_phys(s.raw_min());
    let b = s.to_phys(s.raw_max());
    assert!(
        a.is_finite() && b.is_finite(),
        "signal {}: raw range {}..={} scales to {a}..={b} (factor {}, offset {})",
        s.name,
        s.raw_min(),
        s.raw_max(),
        s.factor,
        s.offset
    );
    (a.min(b), a.max(b))
}

/// A value to encode in `s`: mostly in range, sometimes an end, beyond the
/// range or not finite.
fn value(s: &SignalSpec, rng: &mut Rng) -> f64 {
    let (lo, hi) = range(s);
    match rng.next() % 16 {
        0 => lo,
        1 => hi,
        2 => s.to_phys(0),
        3 => hi + (hi - lo).abs().max(1.0) * (1.0 + rng.unit()),
        4 => lo - (hi - lo).abs().max(1.0) * (1.0 + rng.unit()),
        5 => [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][(rng.next() % 3) as usize],
        // an exact step
        6 => s.to_phys(s.raw_min() + (rng.next() % (s.raw_max() - s.raw_min()) as u64) as i64),
        _ => {
            let u = rng.unit();
            (lo * (1.0 - u) + hi * u).clamp(lo, hi)
        }
    }
}

/// `got` is what `sent` becomes in `s`: within half a step in range, the
/// nearer end beyond it, the physical value 0 (saturated) if not finite.
fn check_value(m: &MessageSpec, s: &SignalSpec, sent: f64, got: f64) {
    assert!(got.is_finite(), "{}.{}: decoded {got}", m.name, s.name);
    let (lo, hi) = range(s);
    let want = if !sent.is_finite() {
        // sent as the physical value 0 (no torque), saturated as any value
        0.0f64.clamp(lo, hi)
    } else if sent > hi {
        hi
    } else if sent < lo {
        lo
    } else {
        sent
    };
    // half a step, and the rounding of (phys - offset) / factor and back
    let tol = 0.5 * s.factor.abs() * (1.0 + 1e-9)
        + 1e-12 * (want.abs() + s.offset.abs() + lo.abs() + hi.abs());
    assert!(
        (got - want).abs() <= tol,
        "{}.{}: sent {sent}, decoded {got}, expected {want} ± {tol} (factor {}, offset {}, {} bits{})",
        m.name,
        s.name,
        s.factor,
        s.offset,
        s.len,
        if s.signed { ", signed" } else { "" },
    );
}

/// What a raw `u8` written into `s` reads back as (as `MotorStatus`'s
/// fault code reads it).
fn code_as_read(s: &SignalSpec, code: u8) -> u8 {
    let mask = (1u64 << s.len) - 1;
    let v = u64::from(code) & mask;
    let v = if s.signed && (v >> (s.len - 1)) & 1 == 1 {
        v | !mask
    } else {
        v
    };
    v as i64 as u8
}

fn all_finite(m: &InverterMsg) -> bool {
    match m {
        InverterMsg::TorqueCommand(c) => c.torque_request.is_finite(),
        InverterMsg::MotorStatus(s) => s.torque_actual.is_finite() && s.motor_speed.is_finite(),
        InverterMsg::WheelSpeeds(w) => w.omega_driven.is_finite() && w.omega_ref.is_finite(),
        InverterMsg::VehicleSpeed(v) => v.speed.is_finite() && v.long_accel.is_finite(),
        InverterMsg::DriverDemand(d) => d.torque_demand.is_finite() && d.pedal_position.is_finite(),
    }
}

/// Encodes `msg` with `counter`, checks the frame's E2E fields, the
/// receiver's verdict and the decoded message; returns the decoded message.
fn round_trip<M: ProtocolMessage + std::fmt::Debug>(
    spec: &'static MessageSpec,
    rx: &mut E2eReceiver,
    msg: &M,
    counter: u8,
    now: u64,
) -> M {
    let f = encode_in(spec, msg, counter, now);
    assert_eq!((f.id, f.dlc), (spec.id, spec.dlc));
    assert_eq!(
        spec.counter(&f.data),
        counter & 0x0F,
        "{}: counter",
        spec.name
    );
    let crc = spec.crc_byte();
    assert_eq!(
        f.data[crc],
        e2e_crc_at(spec.data_id, &f.data, crc),
        "{}: CRC byte",
        spec.name
    );
    assert_eq!(
        spec.signals[0].get_raw(&f.data) & 0xFF,
        i64::from(f.data[crc])
    );
    rx.check(&f, now)
        .unwrap_or_else(|e| panic!("{}: receiver refused {msg:?}: {e}", spec.name));
    let back = M::read_signals_in(spec, &f.data);
    let any = InverterMsg::decode_as(spec, &f.data);
    assert!(all_finite(&any), "{}: decoded {any:?}", spec.name);
    back
}

/// The E2E receiver rejects a damaged frame and a repeated counter.
fn rejects(spec: &'static MessageSpec, rx: &mut E2eReceiver, last: &[u8; 8], bit: u64, now: u64) {
    let mut f = grip_io::can::CanFrame {
        stamp_ns: now,
        id: spec.id,
        dlc: spec.dlc,
        direction: 0,
        bus: 0,
        flags: 0,
        data: *last,
    };
    let bit = (bit % 64) as usize;
    f.data[bit / 8] ^= 1 << (bit % 8);
    assert!(
        matches!(rx.check(&f, now), Err(E2eError::Crc { .. })),
        "{}: a frame with bit {bit} flipped was not refused for its CRC",
        spec.name
    );
    f.data = *last;
    assert!(
        matches!(rx.check(&f, now), Err(E2eError::CounterRepeated { .. })),
        "{}: a repeated counter was not refused",
        spec.name
    );
}

fn check_protocol(p: &'static Protocol, rng: &mut Rng, payload: &[u8]) {
    let mut ids = Vec::with_capacity(5);
    for (i, (m, kind)) in p.messages().iter().zip(MsgKind::ALL).enumerate() {
        let b = kind.builtin();
        assert_eq!(m.kind, kind, "message {i}");
        assert_eq!(m.name, b.name);
        assert!(
            m.id <= 0x7FF,
            "{}: id 0x{:X} is not an 11-bit id",
            m.name,
            m.id
        );
        assert!(!ids.contains(&m.id), "{}: id 0x{:X} twice", m.name, m.id);
        ids.push(m.id);
        assert_eq!(m.dlc, 8, "{}: DLC", m.name);
        assert_eq!(m.receiver, b.receiver);
        assert_eq!(m.signals.len(), b.signals.len(), "{}: signals", m.name);
        for (s, bs) in m.signals.iter().zip(b.signals.iter()) {
            assert_eq!((s.name, s.unit), (bs.name, bs.unit));
            assert!(
                (1..=32).contains(&s.len),
                "{}.{}: {} bits",
                m.name,
                s.name,
                s.len
            );
        }
        assert_eq!(m.signals[0].len, 8, "{}: CRC length", m.name);
        assert_eq!(m.signals[0].bits().count_ones(), 8, "{}: CRC bits", m.name);
        assert_eq!(
            m.signals[0].bits(),
            0xFFu64 << (8 * m.crc_byte()),
            "{}: the CRC is not byte {}",
            m.name,
            m.crc_byte()
        );
        assert_eq!(m.signals[1].len, 4, "{}: counter length", m.name);
        assert_eq!(p.spec(kind), m);
        assert_eq!(p.spec_for_id(m.id), Some(m));
        // any payload decodes to finite values
        for d in [[0u8; 8], [0xFF; 8], rng.next().to_le_bytes()] {
            let got = InverterMsg::decode_as(m, &d);
            assert!(all_finite(&got), "{}: {d:02X?} decoded {got:?}", m.name);
        }
        if let Some(d) = payload.get(i * 8..i * 8 + 8) {
            let d: [u8; 8] = d.try_into().expect("8 bytes");
            let got = InverterMsg::decode_as(m, &d);
            assert!(all_finite(&got), "{}: {d:02X?} decoded {got:?}", m.name);
        }
    }

    let now0 = 1_000_000_000u64;
    for kind in MsgKind::ALL {
        let spec: &'static MessageSpec = p.spec(kind);
        let s = |i: usize| &spec.signals[i];
        let mut rx = E2eReceiver::new(spec);
        let start = (rng.next() % 16) as u8;
        let mut last = [0u8; 8];
        for k in 0..4u8 {
            let counter = start.wrapping_add(k) & 0x0F;
            let now = now0 + u64::from(k) * 100_000;
            match kind {
                MsgKind::TorqueCommand => {
                    let m = TorqueCommand {
                        torque_request: value(s(3), rng),
                        enable: rng.bool(),
                    };
                    let r = round_trip(spec, &mut rx, &m, counter, now);
                    assert_eq!(r.enable, m.enable, "TorqueCommand.Enable");
                    check_value(spec, s(3), m.torque_request, r.torque_request);
                    last = encode_in(spec, &m, counter, now).data;
                }
                MsgKind::MotorStatus => {
                    let m = MotorStatus {
                        ready: rng.bool(),
                        fault: rng.bool(),
                        derating: rng.bool(),
                        cmd_timeout: rng.bool(),
                        torque_actual: value(s(6), rng),
                        motor_speed: value(s(7), rng),
                        fault_code: rng.next() as u8,
                    };
                    let r = round_trip(spec, &mut rx, &m, counter, now);
                    assert_eq!(
                        (r.ready, r.fault, r.derating, r.cmd_timeout),
                        (m.ready, m.fault, m.derating, m.cmd_timeout),
                        "MotorStatus flags"
                    );
                    check_value(spec, s(6), m.torque_actual, r.torque_actual);
                    check_value(spec, s(7), m.motor_speed, r.motor_speed);
                    assert_eq!(
                        r.fault_code,
                        code_as_read(s(8), m.fault_code),
                        "MotorStatus.FaultCode {} in {} bits",
                        m.fault_code,
                        s(8).len
                    );
                    last = encode_in(spec, &m, counter, now).data;
                }
                MsgKind::WheelSpeeds => {
                    let m = WheelSpeeds {
                        driven_valid: rng.bool(),
                        ref_valid: rng.bool(),
                        omega_driven: value(s(4), rng),
                        omega_ref: value(s(5), rng),
                    };
                    let r = round_trip(spec, &mut rx, &m, counter, now);
                    assert_eq!(
                        (r.driven_valid, r.ref_valid),
                        (m.driven_valid, m.ref_valid),
                        "WheelSpeeds flags"
                    );
                    check_value(spec, s(4), m.omega_driven, r.omega_driven);
                    check_value(spec, s(5), m.omega_ref, r.omega_ref);
                    last = encode_in(spec, &m, counter, now).data;
                }
                MsgKind::VehicleSpeed => {
                    let m = VehicleSpeed {
                        valid: rng.bool(),
                        speed: value(s(3), rng),
                        long_accel: value(s(4), rng),
                    };
                    let r = round_trip(spec, &mut rx, &m, counter, now);
                    assert_eq!(r.valid, m.valid, "VehicleSpeed.Valid");
                    check_value(spec, s(3), m.speed, r.speed);
                    check_value(spec, s(4), m.long_accel, r.long_accel);
                    last = encode_in(spec, &m, counter, now).data;
                }
                MsgKind::DriverDemand => {
                    let m = DriverDemand {
                        brake_pressed: rng.bool(),
                        tcs_enable: rng.bool(),
                        torque_demand: value(s(4), rng),
                        pedal_position: value(s(5), rng),
                    };
                    let r = round_trip(spec, &mut rx, &m, counter, now);
                    assert_eq!(
                        (r.brake_pressed, r.tcs_enable),
                        (m.brake_pressed, m.tcs_enable),
                        "DriverDemand flags"
                    );
                    check_value(spec, s(4), m.torque_demand, r.torque_demand);
                    check_value(spec, s(5), m.pedal_position, r.pedal_position);
                    last = encode_in(spec, &m, counter, now).data;
                }
            }
        }
        assert_eq!(rx.accepted(), 4, "{}: frames accepted", spec.name);
        rejects(spec, &mut rx, &last, rng.next(), now0 + 400_000);
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&setup, text)) = data.split_first() else {
        return;
    };
    check_repository_dbcs();
    let mut settings = DbcSettings::default();
    if setup & 1 == 1 {
        settings.names = own_bus_names().clone();
    }
    if setup & 2 == 2 {
        settings.valid = [
            ("WheelSpeeds.DrivenValid".to_owned(), 0),
            ("VehicleSpeed.Valid".to_owned(), i64::from(setup >> 2 & 3)),
        ]
        .into();
    }
    if setup & 16 == 16 {
        settings.radii = Some(RADII);
    }
    // as Protocol::load_dbc reads a file
    let text = match std::str::from_utf8(text) {
        Ok(t) => t.to_owned(),
        Err(_) => text.iter().map(|&b| char::from(b)).collect(),
    };
    match Protocol::from_dbc_with(&text, FILE, &settings) {
        Err(e) => {
            let msg = e.to_string();
            if e.file == "can.toml" {
                assert!(
                    !settings.valid.is_empty() && msg.starts_with("can.toml: [dbc_valid] "),
                    "a refusal of can.toml that is not its [dbc_valid]: {msg}"
                );
            } else {
                assert!(
                    msg.starts_with(&format!("{FILE}: ")),
                    "refusal does not start with the file name: {msg}"
                );
                assert_eq!(e.file, FILE);
            }
        }
        Ok(p) => {
            let p = leak(p);
            let mut rng = Rng(fnv1a(data) ^ u64::from(setup));
            check_protocol(p, &mut rng, text.as_bytes());
        }
    }
});
