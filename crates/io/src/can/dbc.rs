//! A car's own bus: grip's five messages read from a DBC file
//! ([`Protocol::from_dbc`]) instead of the built-in `config/inverter.dbc`.
//!
//! What the DBC decides: each message's id, the position, length, byte
//! order (Intel or Motorola), sign, factor and offset of every signal grip
//! uses, the E2E data id (`GripE2eDataId`), the transmission period
//! (`GenMsgCycleTime`), the receive timeout (`GripTimeoutMs`), each scaled
//! signal's range (grip saturates what it sends there) and the bus's bit
//! rate (`Baudrate`, for the bus load: at most [`MAX_BUS_LOAD`](super::protocol::MAX_BUS_LOAD)). What it
//! cannot change: which five messages there are and what each signal means
//! (grip's names, looked up in the DBC, or mapped to the DBC's own names by
//! `[dbc_names]` in `can.toml`), the physical units the code computes in
//! (a DBC unit grip knows is converted: rpm to rad/s, km/h to m/s, g to
//! m/s²; a wheel speed in km/h or m/s to rad/s with the wheel's rolling
//! radius, ω = v ÷ r, given by the service from the vehicle file:
//! [`DbcSettings::radii`]), 8-byte classic CAN frames with 11-bit ids (a
//! message whose `VFrameFormat` is CAN FD or extended is refused), and the
//! E2E scheme (CRC-8 SAE J1850 over the data id and the other seven bytes,
//! in a whole byte; a 4-bit alive counter). The raw value that means
//! "valid" in grip's three validity flags is the DBC's to choose too
//! (`[dbc_valid]` in `can.toml`, or the DBC's `VAL_` table; default:
//! non-zero). Every refusal names the file, the message or signal, and the
//! reason.

use std::collections::BTreeMap;
use std::path::Path;

use can_dbc::{
    AttributeDefinition, AttributeValue, AttributeValueType, ByteOrder, Dbc, MessageId,
    MultiplexIndicator, ValueType,
};

use super::protocol::{
    BusTiming, MessageSpec, MsgKind, Protocol, SignalList, SignalSpec, WheelRadii,
};

/// What the DBC loader reads besides the DBC itself: `can.toml`'s
/// `[dbc_names]` and `[dbc_valid]`, and the wheels' rolling radii from the
/// vehicle file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DbcSettings {
    /// `[dbc_names]`: grip's names (`TorqueCommand`,
    /// `TorqueCommand.TorqueRequest`) mapped to the DBC's where they
    /// differ.
    pub names: BTreeMap<String, String>,
    /// `[dbc_valid]`: for grip's validity flags ([`VALID_FLAGS`]), the raw
    /// value that means valid (e.g. 0 for a bit that says *invalid* when
    /// set). It wins over the DBC's `VAL_` table; a flag in neither is
    /// valid when non-zero.
    pub valid: BTreeMap<String, i64>,
    /// The wheels' rolling radii (the vehicle file's `r` and `r_ref`): a
    /// DBC whose `OmegaDriven` or `OmegaRef` is in km/h or m/s (a wheel's
    /// circumferential speed) is converted with them, ω = v ÷ r, and
    /// refused without them.
    pub radii: Option<WheelRadii>,
    /// Leave the bus load to the caller: the services judge it at the bit
    /// rate their interface runs at ([`crate::service::resolve_protocol`]),
    /// a drive log's reader not at all (what was recorded was accepted
    /// then). `false` (the default): refused here at the DBC's `Baudrate`
    /// (else [`super::protocol::DEFAULT_BITRATE`]) when over
    /// [`MAX_BUS_LOAD`](super::protocol::MAX_BUS_LOAD).
    pub skip_bus_load: bool,
}

impl DbcSettings {
    /// Only a name map (no `[dbc_valid]`, no radii).
    pub fn with_names(names: &BTreeMap<String, String>) -> Self {
        Self {
            names: names.clone(),
            ..Self::default()
        }
    }
    /// `can`'s `[dbc_names]` and `[dbc_valid]`, and `radii` (`None`: no
    /// vehicle file at hand).
    pub fn from_can(can: &super::CanBusConfig, radii: Option<WheelRadii>) -> Self {
        Self {
            names: can.dbc_names.clone(),
            valid: can.dbc_valid.clone(),
            radii,
            skip_bus_load: false,
        }
    }
}

/// grip's validity flags, the keys `[dbc_valid]` takes: (message, signal
/// index in the built-in order, `Message.Signal`).
pub const VALID_FLAGS: [(MsgKind, usize, &str); 3] = [
    (MsgKind::WheelSpeeds, 2, "WheelSpeeds.DrivenValid"),
    (MsgKind::WheelSpeeds, 3, "WheelSpeeds.RefValid"),
    (MsgKind::VehicleSpeed, 2, "VehicleSpeed.Valid"),
];

/// The wheel whose rolling radius converts a linear speed in grip's
/// signal `signal` of `kind`, if it is a wheel speed: `Some(true)` the
/// driven wheel (`OmegaDriven`), `Some(false)` the reference wheel
/// (`OmegaRef`).
fn wheel_of(kind: MsgKind, signal: &str) -> Option<bool> {
    match (kind, signal) {
        (MsgKind::WheelSpeeds, "OmegaDriven") => Some(true),
        (MsgKind::WheelSpeeds, "OmegaRef") => Some(false),
        _ => None,
    }
}

/// Checks `[dbc_valid]`'s keys before the DBC is read: each must be one of
/// [`VALID_FLAGS`]; the reason names what the key is instead.
fn check_valid_keys(valid: &BTreeMap<String, i64>) -> Result<(), DbcError> {
    let flags: Vec<&str> = VALID_FLAGS.iter().map(|(_, _, k)| *k).collect();
    let list = flags
        .iter()
        .map(|k| format!("\"{k}\""))
        .collect::<Vec<_>>()
        .join(", ");
    for k in valid.keys() {
        if flags.contains(&k.as_str()) {
            continue;
        }
        // what the key is, if it is one of grip's names at all
        let signal = MsgKind::ALL.into_iter().find_map(|kind| {
            let b = kind.builtin();
            b.signals
                .iter()
                .enumerate()
                .find(|(_, s)| format!("{}.{}", b.name, s.name) == *k)
                .map(|(i, s)| (i, *s))
        });
        let reason = match signal {
            Some((i, s)) if i >= 2 && s.len == 1 => format!(
                "a flag, but not a validity flag: [dbc_valid] takes {list} (the raw value that means valid)"
            ),
            Some(_) => format!(
                "not a flag (a value grip reads as a number): [dbc_valid] takes {list} (the raw value that means valid)"
            ),
            None => match flags.iter().find(|g| g.eq_ignore_ascii_case(k)) {
                Some(g) => format!("not one of grip's validity flags (did you mean \"{g}\"?)"),
                None if MsgKind::ALL.iter().any(|m| m.builtin().name == k) => format!(
                    "a message, not a flag: [dbc_valid] takes {list} (the raw value that means valid)"
                ),
                None => format!(
                    "not one of grip's validity flags: [dbc_valid] takes {list}, with grip's names (map the DBC's in [dbc_names])"
                ),
            },
        };
        return Err(DbcError {
            file: "can.toml".into(),
            what: format!("[dbc_valid] {k}"),
            reason,
        });
    }
    Ok(())
}

/// The raw value the DBC's `VAL_` table names valid for a flag: the one
/// state whose description is `Valid` (case, spaces and punctuation
/// ignored; `"Invalid"`, `"Not valid"` are not). `None` when the table
/// names no such state, or more than one.
fn valid_from_val_table(dbc: &Dbc, id: MessageId, signal: &str) -> Option<i64> {
    let table = dbc.value_descriptions_for_signal(id, signal)?;
    let mut valid = table.iter().filter(|v| {
        let norm: String = v
            .description
            .chars()
            .filter(|c| c.is_alphanumeric())
            .collect::<String>()
            .to_lowercase();
        norm == "valid"
    });
    let first = valid.next()?;
    if valid.next().is_some() {
        return None;
    }
    Some(first.id)
}

/// A DBC that grip cannot speak: the file, what in it, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {what}: {reason}")]
pub struct DbcError {
    /// The DBC file (or `can.toml` for a name map entry).
    pub file: String,
    /// The message, signal or attribute concerned.
    pub what: String,
    /// Why it was refused.
    pub reason: String,
}

/// Physical units grip converts from, per unit grip computes in: (accepted
/// spellings, lower case; factor to grip's unit).
const UNITS: &[(&str, &[(&str, f64)])] = &[
    (
        "Nm",
        &[
            ("nm", 1.0),
            ("n m", 1.0),
            ("n.m", 1.0),
            ("n*m", 1.0),
            ("n·m", 1.0),
        ],
    ),
    (
        "rad/s",
        &[
            ("rad/s", 1.0),
            ("rpm", core::f64::consts::PI / 30.0),
            ("1/min", core::f64::consts::PI / 30.0),
            ("min-1", core::f64::consts::PI / 30.0),
            ("u/min", core::f64::consts::PI / 30.0),
        ],
    ),
    (
        "m/s",
        &[("m/s", 1.0), ("km/h", 1.0 / 3.6), ("kph", 1.0 / 3.6)],
    ),
    (
        "m/s2",
        &[
            ("m/s2", 1.0),
            ("m/s^2", 1.0),
            ("m/s²", 1.0),
            ("g", 9.806_65),
        ],
    ),
    ("%", &[("%", 1.0)]),
];

/// The factor from a DBC unit to grip's `unit`; `None` if not convertible.
/// A signal grip reads without a unit (flags, codes) takes any.
fn unit_factor(grip_unit: &str, dbc_unit: &str) -> Option<f64> {
    if grip_unit.is_empty() {
        return Some(1.0);
    }
    let u = dbc_unit.trim().to_lowercase();
    UNITS
        .iter()
        .find(|(g, _)| *g == grip_unit)
        .and_then(|(_, acc)| acc.iter().find(|(a, _)| *a == u).map(|(_, f)| *f))
}

fn accepted_units(grip_unit: &str) -> String {
    UNITS
        .iter()
        .find(|(g, _)| *g == grip_unit)
        .map(|(_, acc)| {
            acc.iter()
                .map(|(a, _)| format!("\"{a}\""))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default()
}

fn num(v: &can_dbc::NumericValue) -> f64 {
    match v {
        can_dbc::NumericValue::Uint(u) => *u as f64,
        can_dbc::NumericValue::Int(i) => *i as f64,
        can_dbc::NumericValue::Double(d) => *d,
    }
}

fn attr_num(v: &AttributeValue) -> Option<f64> {
    match v {
        AttributeValue::Uint(u) => Some(*u as f64),
        AttributeValue::Int(i) => Some(*i as f64),
        AttributeValue::Double(d) => Some(*d),
        AttributeValue::String(_) => None,
    }
}

/// A parse error on one line: the parser's position and what it expected
/// (its message spans several lines, with the source line and a caret),
/// then the line itself as the file has it (the parser's position can
/// lie before the real mistake: it names the last choice it could not
/// make, e.g. the byte order of a signal whose factor lacks its comma),
/// and for a signal line the form `SG_` takes.
fn parse_error(e: &can_dbc::DbcError, text: &str) -> String {
    let msg = e.to_string();
    let at = msg
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("--> "))
        .and_then(|p| p.split_once(':'));
    let what = msg
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("= "))
        .unwrap_or(msg.as_str());
    let Some((line, col)) = at else {
        return what.to_owned();
    };
    let mut out = format!("line {line}, column {}: {what}", col.trim());
    let source = line
        .trim()
        .parse::<usize>()
        .ok()
        .and_then(|n| text.lines().nth(n.checked_sub(1)?))
        .map(str::trim);
    if let Some(source) = source.filter(|s| !s.is_empty()) {
        const SHOWN: usize = 120;
        let shown: String = source.chars().take(SHOWN).collect();
        let cut = if source.chars().count() > SHOWN {
            "..."
        } else {
            ""
        };
        out.push_str(&format!("; the line reads `{shown}{cut}`"));
        if source.starts_with("SG_ ") {
            out.push_str(
                "; a signal is `SG_ Name : start|length@order sign (factor,offset) [min|max] \"unit\" Receivers` \
                 (order 1 Intel or 0 Motorola, sign + or -; e.g. `SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] \"rad/s\" TCS`)",
            );
        }
    }
    out
}

/// A DBC's network attribute (`BA_ "Name" value;`), else its
/// `BA_DEF_DEF_` default: the value and which of the two it is.
fn network_attr<'a>(dbc: &'a Dbc, name: &str) -> Option<(&'a AttributeValue, &'static str)> {
    dbc.attribute_values_database
        .iter()
        .find(|a| a.name.eq_ignore_ascii_case(name))
        .map(|a| (&a.value, "BA_"))
        .or_else(|| {
            dbc.attribute_defaults
                .iter()
                .find(|a| a.name.eq_ignore_ascii_case(name))
                .map(|a| (&a.value, "BA_DEF_DEF_ default"))
        })
}

/// The bus the DBC declares: `Baudrate` (bit/s; absent: 1 Mbit/s, grip's
/// bus) and `BusType` (`"CAN"` or `"CAN FD"`; absent: CAN).
fn bus_timing(dbc: &Dbc, err: &dyn Fn(String, String) -> DbcError) -> Result<BusTiming, DbcError> {
    let mut bus = BusTiming::ASSUMED;
    if let Some((v, from)) = network_attr(dbc, "Baudrate") {
        let what = || format!("attribute Baudrate ({from})");
        match attr_num(v) {
            // a template's default of 0 says "not set"
            Some(b) if b == 0.0 && from != "BA_" => {}
            Some(b) if (10_000.0..=1_000_000.0).contains(&b) && b.fract() == 0.0 => {
                bus.bitrate = b as u32;
                bus.dbc_bitrate = Some(b as u32);
            }
            Some(b) if b > 1_000_000.0 => {
                return Err(err(
                    what(),
                    format!(
                        "{b} bit/s: classic CAN runs at 1 Mbit/s at most; grip sends classic frames (a CAN FD data rate is not the bus's nominal rate)"
                    ),
                ));
            }
            Some(b) => {
                return Err(err(
                    what(),
                    format!(
                        "{b}: must be a whole number of bit/s in 10000..=1000000 (500 kbit/s is 500000)"
                    ),
                ));
            }
            None => return Err(err(what(), format!("{v:?} is not a number"))),
        }
    }
    if let Some((v, from)) = network_attr(dbc, "BusType") {
        let AttributeValue::String(t) = v else {
            return Err(err(
                format!("attribute BusType ({from})"),
                format!("{v:?} is not a string"),
            ));
        };
        let norm: String = t
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect::<String>()
            .to_ascii_uppercase();
        match norm.as_str() {
            "" | "CAN" => {}
            "CANFD" => bus.can_fd_bus = true,
            _ => {
                return Err(err(
                    format!("attribute BusType ({from})"),
                    format!("\"{t}\": grip speaks CAN (BusType \"CAN\" or \"CAN FD\")"),
                ));
            }
        }
    }
    Ok(bus)
}

/// Vector's `VFrameFormat` values (CANdb++): 0 StandardCAN, 1 ExtendedCAN,
/// 14 StandardCAN_FD, 15 ExtendedCAN_FD; the ones between are reserved
/// (3 is J1939PG in J1939 databases).
fn vector_frame_format(n: u64) -> &'static str {
    match n {
        0 => "StandardCAN",
        1 => "ExtendedCAN",
        3 => "J1939PG",
        14 => "StandardCAN_FD",
        15 => "ExtendedCAN_FD",
        _ => "reserved",
    }
}

/// A message's `VFrameFormat` (its `BA_`, else the `BA_DEF_DEF_` default):
/// `Ok` for a classic standard frame or none given; otherwise why grip
/// cannot send or receive it. A number is looked up in the DBC's own
/// `ENUM` definition of the attribute, else in Vector's convention.
fn check_frame_format(dbc: &Dbc, id: MessageId) -> Result<(), String> {
    let v = dbc
        .attribute_values_message
        .iter()
        .find(|a| a.name == "VFrameFormat" && a.message_id == id)
        .map(|a| &a.value)
        .or_else(|| {
            dbc.attribute_defaults
                .iter()
                .find(|a| a.name == "VFrameFormat")
                .map(|a| &a.value)
        });
    let Some(v) = v else { return Ok(()) };
    let list = dbc.attribute_definitions.iter().find_map(|d| match d {
        AttributeDefinition::Message(n, AttributeValueType::Enum(l)) if n == "VFrameFormat" => {
            Some(l)
        }
        _ => None,
    });
    let (name, shown) = match v {
        AttributeValue::String(s) => (s.clone(), format!("\"{s}\"")),
        v => {
            let n = attr_num(v).unwrap_or(-1.0);
            if !(n >= 0.0 && n.fract() == 0.0) {
                return Err(format!("VFrameFormat {n}: not a frame format"));
            }
            let n = n as u64;
            let name = list
                .and_then(|l| l.get(usize::try_from(n).ok()?))
                .cloned()
                .unwrap_or_else(|| vector_frame_format(n).to_owned());
            (name.clone(), format!("{n} ({name})"))
        }
    };
    let norm: String = name
        .chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_lowercase();
    if norm == "standardcan" {
        return Ok(());
    }
    Err(if norm.contains("fd") {
        format!(
            "VFrameFormat {shown}: a CAN FD frame; grip sends and receives classic CAN frames only (8 data bytes, one bit rate): declare the message StandardCAN (0) if the bus carries it as a classic frame, or put a gateway in between"
        )
    } else if norm.starts_with("extended") {
        format!(
            "VFrameFormat {shown}: a 29-bit frame; grip's messages are classic frames with 11-bit ids (StandardCAN, 0)"
        )
    } else {
        format!(
            "VFrameFormat {shown}: not a classic CAN frame with an 11-bit id (StandardCAN, 0), the only frame grip sends and receives"
        )
    })
}

/// Every key `[dbc_names]` may have: grip's message names and
/// `Message.Signal` for each signal.
pub fn name_keys() -> impl Iterator<Item = String> {
    MsgKind::ALL.into_iter().flat_map(|k| {
        let b = k.builtin();
        std::iter::once(b.name.to_owned()).chain(
            b.signals
                .iter()
                .map(move |s| format!("{}.{}", b.name, s.name)),
        )
    })
}

/// Every message a DBC defines, by identifier: `(id, extended)` → name,
/// grip's five and all the others (a car's full DBC names its brake,
/// steering and wheel-speed frames too). For naming the frames of a bus
/// log (`grip inspect`), not for speaking them: no signal is read. The
/// text as [`Protocol::from_dbc_bytes`] decodes it (UTF-8, else Latin-1).
/// A DBC that does not parse is an error naming the file and the line.
pub fn message_names(bytes: &[u8], file: &str) -> Result<BTreeMap<(u32, bool), String>, DbcError> {
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => std::borrow::Cow::Borrowed(t),
        Err(_) => std::borrow::Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let dbc = Dbc::try_from(text).map_err(|e| DbcError {
        file: file.to_owned(),
        what: "file".into(),
        reason: format!("not a DBC: {}", parse_error(&e, text)),
    })?;
    Ok(dbc
        .messages
        .iter()
        .map(|m| {
            let key = match m.id {
                MessageId::Standard(id) => (u32::from(id), false),
                MessageId::Extended(id) => (id, true),
            };
            (key, m.name.clone())
        })
        .collect())
}

impl Protocol {
    /// Reads grip's protocol from the DBC at `path`. `names` maps grip's
    /// names (`TorqueCommand`, `TorqueCommand.TorqueRequest`) to the DBC's
    /// where they differ.
    pub fn load_dbc(path: &Path, names: &BTreeMap<String, String>) -> Result<Self, DbcError> {
        Self::load_dbc_with(path, &DbcSettings::with_names(names))
    }

    /// [`load_dbc`](Self::load_dbc) with `can.toml`'s `[dbc_valid]` and the
    /// wheels' radii besides the names (what the services call).
    pub fn load_dbc_with(path: &Path, settings: &DbcSettings) -> Result<Self, DbcError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| DbcError {
            file: file.clone(),
            what: "file".into(),
            reason: format!("cannot be read (can.toml's dbc names it): {e}"),
        })?;
        Self::from_dbc_bytes_with(&bytes, &file, settings)
    }

    /// [`load_dbc`](Self::load_dbc) from the file's bytes (a drive log's
    /// attachment): UTF-8, else Latin-1 (DBC editors often write
    /// Windows-1252; only comments and names use non-ASCII bytes, and every
    /// byte is a character in Latin-1); a byte-order mark is skipped.
    pub fn from_dbc_bytes(
        bytes: &[u8],
        file: &str,
        names: &BTreeMap<String, String>,
    ) -> Result<Self, DbcError> {
        Self::from_dbc_bytes_with(bytes, file, &DbcSettings::with_names(names))
    }

    /// [`from_dbc_bytes`](Self::from_dbc_bytes) with `[dbc_valid]` and the
    /// wheels' radii ([`DbcSettings`]).
    pub fn from_dbc_bytes_with(
        bytes: &[u8],
        file: &str,
        settings: &DbcSettings,
    ) -> Result<Self, DbcError> {
        let text = match std::str::from_utf8(bytes) {
            Ok(t) => std::borrow::Cow::Borrowed(t),
            Err(_) => std::borrow::Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
        };
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        Self::from_dbc_with(text, file, settings)
    }

    /// [`load_dbc`](Self::load_dbc) from the file's text; `file` names it in
    /// errors. Without `[dbc_valid]` and without the wheels' radii: a DBC
    /// whose wheel speeds are in km/h or m/s is refused
    /// ([`from_dbc_with`](Self::from_dbc_with) takes them).
    pub fn from_dbc(
        text: &str,
        file: &str,
        names: &BTreeMap<String, String>,
    ) -> Result<Self, DbcError> {
        Self::from_dbc_with(text, file, &DbcSettings::with_names(names))
    }

    /// [`from_dbc`](Self::from_dbc) with `can.toml`'s `[dbc_valid]` (the raw
    /// value that means valid in grip's validity flags) and the wheels'
    /// rolling radii (for a wheel speed in km/h or m/s, ω = v ÷ r; folded
    /// into the signal's factor, so decoding costs what it did).
    pub fn from_dbc_with(text: &str, file: &str, settings: &DbcSettings) -> Result<Self, DbcError> {
        let names = &settings.names;
        let err = |what: String, reason: String| DbcError {
            file: file.to_owned(),
            what,
            reason,
        };
        let keys: Vec<String> = name_keys().collect();
        for k in names.keys() {
            if !keys.contains(k) {
                let hint = keys.iter().find(|g| g.eq_ignore_ascii_case(k)).map_or_else(
                    || {
                        "a message, e.g. \"TorqueCommand\", or \"Message.Signal\", e.g. \"TorqueCommand.TorqueRequest\"".to_owned()
                    },
                    |g| format!("did you mean \"{g}\"?"),
                );
                return Err(DbcError {
                    file: "can.toml".into(),
                    what: format!("[dbc_names] {k}"),
                    reason: format!("not one of grip's messages or signals ({hint})"),
                });
            }
        }
        check_valid_keys(&settings.valid)?;
        if let Some(r) = settings.radii {
            for (field, v) in [("r", r.driven_m), ("r_ref", r.reference_m)] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(DbcError {
                        file: "vehicle file".into(),
                        what: format!("vehicle.{field}"),
                        reason: format!(
                            "{v} m: a wheel's rolling radius must be a positive length (it converts a wheel speed in km/h or m/s to rad/s)"
                        ),
                    });
                }
            }
        }
        let mut radii_used = false;
        let dbc = Dbc::try_from(text).map_err(|e| {
            err(
                "file".into(),
                format!("not a DBC that can be parsed: {}", parse_error(&e, text)),
            )
        })?;
        let bus = bus_timing(&dbc, &err)?;
        let mut specs: Vec<MessageSpec> = Vec::with_capacity(5);
        for kind in MsgKind::ALL {
            let b = kind.builtin();
            let dbc_name = names.get(b.name).map_or(b.name, String::as_str);
            let label = if dbc_name == b.name {
                format!("message {}", b.name)
            } else {
                format!("message {dbc_name} (grip's {})", b.name)
            };
            let m = dbc
                .messages
                .iter()
                .find(|m| m.name == dbc_name)
                .ok_or_else(|| {
                    let there: Vec<&str> = dbc.messages.iter().map(|m| m.name.as_str()).collect();
                    err(
                        label.clone(),
                        format!(
                            "not in the DBC (its messages: {}; map grip's name to yours in can.toml [dbc_names])",
                            there.join(", ")
                        ),
                    )
                })?;
            let id = match m.id {
                MessageId::Standard(id) if id <= 0x7FF => u32::from(id),
                MessageId::Standard(id) => {
                    return Err(err(
                        label,
                        format!("id 0x{id:X} is not an 11-bit id (0x000-0x7FF)"),
                    ));
                }
                MessageId::Extended(id) => {
                    return Err(err(
                        label,
                        format!(
                            "29-bit id 0x{id:X}: grip's services send and receive 11-bit ids only"
                        ),
                    ));
                }
            };
            check_frame_format(&dbc, m.id)
                .map_err(|reason| err(format!("{label}, attribute VFrameFormat"), reason))?;
            if m.size != 8 {
                return Err(err(
                    label,
                    format!("DLC {}: grip's messages are 8 bytes", m.size),
                ));
            }
            let attr = |name: &str| -> Result<Option<f64>, DbcError> {
                let v = dbc
                    .attribute_values_message
                    .iter()
                    .find(|a| a.name == name && a.message_id == m.id)
                    .map(|a| &a.value);
                match v {
                    None => Ok(None),
                    Some(v) => attr_num(v).map(Some).ok_or_else(|| {
                        err(
                            format!("{label}, attribute {name}"),
                            format!("{v:?} is not a number"),
                        )
                    }),
                }
            };
            let default = |name: &str| {
                dbc.attribute_defaults
                    .iter()
                    .find(|a| a.name == name)
                    .and_then(|a| attr_num(&a.value))
            };
            let positive_ms = |name: &str, v: Option<f64>| -> Result<u32, DbcError> {
                match v {
                    Some(v) if (1.0..=60_000.0).contains(&v) && v.fract() == 0.0 => Ok(v as u32),
                    Some(v) => Err(err(
                        format!("{label}, attribute {name}"),
                        format!("{v}: must be a whole number of ms in 1..=60000"),
                    )),
                    None => Err(err(
                        format!("{label}, attribute {name}"),
                        format!("missing (BA_ \"{name}\" BO_ {id} <ms>;)"),
                    )),
                }
            };
            let cycle_ms = positive_ms(
                "GenMsgCycleTime",
                attr("GenMsgCycleTime")?.or_else(|| default("GenMsgCycleTime")),
            )?;
            let timeout_ms = positive_ms("GripTimeoutMs", attr("GripTimeoutMs")?)?;
            if timeout_ms < 2 * cycle_ms {
                return Err(err(
                    format!("{label}, attribute GripTimeoutMs"),
                    format!(
                        "{timeout_ms} ms is less than two periods (GenMsgCycleTime {cycle_ms} ms): one late frame would be a timeout"
                    ),
                ));
            }
            let data_id = match attr("GripE2eDataId")? {
                Some(v) if (0.0..=65535.0).contains(&v) && v.fract() == 0.0 => v as u16,
                Some(v) => {
                    return Err(err(
                        format!("{label}, attribute GripE2eDataId"),
                        format!("{v}: must be a whole number in 0..=65535"),
                    ));
                }
                None => {
                    return Err(err(
                        format!("{label}, attribute GripE2eDataId"),
                        format!(
                            "missing: the E2E data id the CRC covers (BA_ \"GripE2eDataId\" BO_ {id} <0..65535>;)"
                        ),
                    ));
                }
            };

            let mut signals = Vec::with_capacity(b.signals.len());
            let mut used = 0u64;
            for (i, bs) in b.signals.iter().enumerate() {
                let key = format!("{}.{}", b.name, bs.name);
                let sname = names.get(&key).map_or(bs.name, String::as_str);
                let what = if sname == bs.name {
                    format!("signal {}.{}", m.name, bs.name)
                } else {
                    format!("signal {}.{sname} (grip's {key})", m.name)
                };
                let d = m.signals.iter().find(|s| s.name == sname).ok_or_else(|| {
                    let there: Vec<&str> = m.signals.iter().map(|s| s.name.as_str()).collect();
                    err(
                        what.clone(),
                        format!(
                            "not in the message (its signals: {}; map grip's name to yours in can.toml [dbc_names])",
                            there.join(", ")
                        ),
                    )
                })?;
                if let Some(t) = dbc.extended_value_type_for_signal(m.id, &d.name)
                    && !matches!(t, can_dbc::SignalExtendedValueType::SignedOrUnsignedInteger)
                {
                    return Err(err(
                        what,
                        format!(
                            "{t:?} (SIG_VALTYPE_): grip reads and writes integer raw values only"
                        ),
                    ));
                }
                if !matches!(d.multiplexer_indicator, MultiplexIndicator::Plain) {
                    return Err(err(
                        what,
                        "multiplexed: grip reads plain signals only".into(),
                    ));
                }
                let len = d.size;
                let motorola = d.byte_order == ByteOrder::BigEndian;
                let (lo, hi) = match i {
                    0 => (8, 8), // CRC
                    1 => (4, 4), // alive counter
                    _ if bs.len == 1 => (1, 32),
                    _ => (2, 32),
                };
                if !(lo..=hi).contains(&len) {
                    let want = if lo == hi {
                        format!("{lo} bits")
                    } else {
                        format!("{lo}..={hi} bits")
                    };
                    return Err(err(
                        what,
                        format!("{len} bits long: grip's {} needs {want}", bs.name),
                    ));
                }
                if d.start_bit > 63 {
                    return Err(err(
                        what,
                        format!("start bit {} is past byte 7", d.start_bit),
                    ));
                }
                let start = d.start_bit as u8;
                let fits = if motorola {
                    u64::from(start / 8) * 8 + 7 - u64::from(start % 8) + len <= 64
                } else {
                    u64::from(start) + len <= 64
                };
                if !fits {
                    return Err(err(
                        what,
                        format!(
                            "start bit {start}, {len} bits ({}) runs past the 8th byte",
                            if motorola { "Motorola" } else { "Intel" }
                        ),
                    ));
                }
                if i == 0 && start % 8 != if motorola { 7 } else { 0 } {
                    return Err(err(
                        what,
                        format!("start bit {start}: the CRC must fill one whole byte"),
                    ));
                }
                if !d.factor.is_finite() || d.factor == 0.0 || !d.offset.is_finite() {
                    return Err(err(
                        what,
                        format!(
                            "factor {} offset {}: the factor must be non-zero and both finite",
                            d.factor, d.offset
                        ),
                    ));
                }
                let raw_only = i < 2 || bs.unit.is_empty();
                if raw_only && (d.factor != 1.0 || d.offset != 0.0) {
                    return Err(err(
                        what,
                        format!(
                            "factor {} offset {}: grip reads {} as a raw value (factor 1, offset 0)",
                            d.factor, d.offset, bs.name
                        ),
                    ));
                }
                let wheel = wheel_of(kind, bs.name);
                let k = match (unit_factor(bs.unit, &d.unit), wheel) {
                    (Some(k), _) => k,
                    // a wheel's circumferential speed: ω = v ÷ r
                    (None, Some(driven)) if unit_factor("m/s", &d.unit).is_some() => {
                        let to_mps = unit_factor("m/s", &d.unit).unwrap_or(1.0);
                        let (field, wheel_name) = if driven {
                            ("r", "the driven wheel's")
                        } else {
                            ("r_ref", "the reference wheel's")
                        };
                        let Some(radii) = settings.radii else {
                            return Err(err(
                                what,
                                format!(
                                    "unit \"{}\": a wheel's circumferential speed; grip computes {} in rad/s (ω = v ÷ r) and needs {wheel_name} rolling radius ({field} in the vehicle file) to convert it, which this reader was not given (tcs-loop and plant-sim give their vehicle file's): it is not read as rad/s",
                                    d.unit, bs.name
                                ),
                            ));
                        };
                        radii_used = true;
                        let r = if driven {
                            radii.driven_m
                        } else {
                            radii.reference_m
                        };
                        to_mps / r
                    }
                    (None, _) => {
                        let linear = if wheel.is_some() {
                            format!(
                                ", and, as the wheel's circumferential speed converted with its rolling radius (ω = v ÷ r), from {}",
                                accepted_units("m/s")
                            )
                        } else {
                            String::new()
                        };
                        return Err(err(
                            what,
                            format!(
                                "unit \"{}\": grip computes {} in {} and converts from {}{linear}",
                                d.unit,
                                bs.name,
                                bs.unit,
                                accepted_units(bs.unit)
                            ),
                        ));
                    }
                };
                // a validity flag's valid value: can.toml's [dbc_valid],
                // else the DBC's VAL_ table, else non-zero
                let valid_key = VALID_FLAGS
                    .iter()
                    .find(|(vk, vi, _)| *vk == kind && *vi == i)
                    .map(|(_, _, key)| *key);
                let set_raw = match valid_key {
                    None => None,
                    Some(key) => {
                        let (f_lo, f_hi) = if d.value_type == ValueType::Signed {
                            (-(1i64 << (len - 1)), (1i64 << (len - 1)) - 1)
                        } else {
                            (0, (1i64 << len) - 1)
                        };
                        let v = match settings.valid.get(key) {
                            Some(&v) if (f_lo..=f_hi).contains(&v) => Some(v),
                            Some(&v) => {
                                return Err(DbcError {
                                    file: "can.toml".into(),
                                    what: format!("[dbc_valid] {key}"),
                                    reason: format!(
                                        "{v}: the DBC's {what} is a {len}-bit {} field, which carries raw {f_lo}..={f_hi} only",
                                        if d.value_type == ValueType::Signed {
                                            "signed"
                                        } else {
                                            "unsigned"
                                        }
                                    ),
                                });
                            }
                            None => valid_from_val_table(&dbc, m.id, &d.name)
                                .filter(|v| (f_lo..=f_hi).contains(v)),
                        };
                        // a 1-bit field's non-zero value is "non-zero":
                        // the same flag as grip's default
                        v.filter(|&v| !(len == 1 && v != 0))
                    }
                };
                let spec = SignalSpec {
                    name: bs.name,
                    start,
                    len: len as u8,
                    signed: d.value_type == ValueType::Signed,
                    factor: d.factor * k,
                    offset: d.offset * k,
                    min: num(&d.min) * k,
                    max: num(&d.max) * k,
                    unit: bs.unit,
                    motorola,
                    set_raw,
                };
                // every raw value the field holds must decode to a number,
                // also beyond the range (what is received is decoded as it is)
                let (lo_phys, hi_phys) = (
                    spec.to_phys(spec.field_raw_min()),
                    spec.to_phys(spec.field_raw_max()),
                );
                if !(spec.factor.is_finite()
                    && spec.offset.is_finite()
                    && lo_phys.is_finite()
                    && hi_phys.is_finite())
                {
                    return Err(err(
                        what,
                        format!(
                            "factor {} offset {} (in {}): the field's values are not finite numbers",
                            spec.factor, spec.offset, bs.unit
                        ),
                    ));
                }
                if !raw_only {
                    check_range(&spec, d).map_err(|reason| err(what.clone(), reason))?;
                }
                let bits = spec.bits();
                if used & bits != 0 {
                    let other = signals
                        .iter()
                        .find(|o: &&SignalSpec| o.bits() & bits != 0)
                        .map_or("", |o| o.name);
                    return Err(err(what, format!("overlaps grip's {}.{other}", b.name)));
                }
                used |= bits;
                signals.push(spec);
            }
            if let Some(o) = specs.iter().find(|o| o.id == id) {
                return Err(err(
                    label,
                    format!("id 0x{id:03X} is also grip's {}", o.name),
                ));
            }
            specs.push(MessageSpec {
                kind,
                name: b.name,
                id,
                dlc: 8,
                data_id,
                cycle_ms,
                timeout_ms,
                // grip's node names: who sends and receives each message
                // is grip's, whatever the DBC calls its nodes
                sender: b.sender,
                receiver: b.receiver,
                signals: SignalList::new(&signals),
            });
        }
        let specs: [MessageSpec; 5] = specs
            .try_into()
            .unwrap_or_else(|_| unreachable!("five kinds, five specs"));
        let p = Self::from_specs(specs, bus, settings.radii.filter(|_| radii_used));
        if !settings.skip_bus_load
            && let Some((what, reason)) = p.bus_load_refusal()
        {
            return Err(err(what, reason));
        }
        Ok(p)
    }
}

/// A scaled signal's range `[min|max]` (grip's units in `spec`, the DBC's
/// as written in `d`): finite, min not above max, and, unless `[0|0]` (no
/// range), at least two of the bit field's values inside it.
fn check_range(spec: &SignalSpec, d: &can_dbc::Signal) -> Result<(), String> {
    let shown = format!("range [{}|{}] \"{}\"", num(&d.min), num(&d.max), d.unit);
    if !(spec.min.is_finite() && spec.max.is_finite()) {
        return Err(format!("{shown}: not finite numbers"));
    }
    if !spec.has_range() {
        return Ok(());
    }
    if spec.min > spec.max {
        return Err(format!("{shown}: its minimum is above its maximum"));
    }
    let (f_lo, f_hi) = (spec.field_raw_min(), spec.field_raw_max());
    match spec.range_raw() {
        Some((lo, hi)) if lo.max(f_lo) < hi.min(f_hi) => Ok(()),
        _ => Err(format!(
            "{shown}: fewer than two of the values the {}-bit field holds (raw {f_lo}..={f_hi}, factor {}, offset {}) lie in it",
            spec.len, d.factor, d.offset
        )),
    }
}
