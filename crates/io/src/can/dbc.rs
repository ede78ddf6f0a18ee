//! A car's own bus: grip's five messages read from a DBC file
//! ([`Protocol::from_dbc`]) instead of the built-in `config/inverter.dbc`.
//!
//! What the DBC decides: each message's id, the position, length, byte
//! order (Intel or Motorola), sign, factor and offset of every signal grip
//! uses, the E2E data id (`GripE2eDataId`), the transmission period
//! (`GenMsgCycleTime`) and the receive timeout (`GripTimeoutMs`). What it
//! cannot change: which five messages there are and what each signal means
//! (grip's names, looked up in the DBC, or mapped to the DBC's own names by
//! `[dbc_names]` in `can.toml`), the physical units the code computes in
//! (a DBC unit grip knows is converted: rpm to rad/s, km/h to m/s, g to
//! m/s²), 8-byte standard (11-bit) frames, and the E2E scheme (CRC-8 SAE
//! J1850 over the data id and the other seven bytes, in a whole byte; a
//! 4-bit alive counter). Every refusal names the file, the message or
//! signal, and the reason.

use std::collections::BTreeMap;
use std::path::Path;

use can_dbc::{AttributeValue, ByteOrder, Dbc, MessageId, MultiplexIndicator, ValueType};

use super::protocol::{MessageSpec, MsgKind, Protocol, SignalList, SignalSpec};

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
/// (its message spans several lines, with the source line and a caret).
fn parse_error(e: &can_dbc::DbcError) -> String {
    let text = e.to_string();
    let at = text
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("--> "))
        .and_then(|p| p.split_once(':'));
    let what = text
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("= "))
        .unwrap_or(text.as_str());
    match at {
        Some((line, col)) => format!("line {line}, column {}: {what}", col.trim()),
        None => what.to_owned(),
    }
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
        reason: format!("not a DBC: {}", parse_error(&e)),
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
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| DbcError {
            file: file.clone(),
            what: "file".into(),
            reason: format!("cannot be read (can.toml's dbc names it): {e}"),
        })?;
        Self::from_dbc_bytes(&bytes, &file, names)
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
        let text = match std::str::from_utf8(bytes) {
            Ok(t) => std::borrow::Cow::Borrowed(t),
            Err(_) => std::borrow::Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
        };
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        Self::from_dbc(text, file, names)
    }

    /// [`load_dbc`](Self::load_dbc) from the file's text; `file` names it in
    /// errors.
    pub fn from_dbc(
        text: &str,
        file: &str,
        names: &BTreeMap<String, String>,
    ) -> Result<Self, DbcError> {
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
        let dbc = Dbc::try_from(text).map_err(|e| {
            err(
                "file".into(),
                format!("not a DBC that can be parsed: {}", parse_error(&e)),
            )
        })?;
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
                let k = unit_factor(bs.unit, &d.unit).ok_or_else(|| {
                    err(
                        what.clone(),
                        format!(
                            "unit \"{}\": grip computes {} in {} and converts from {}",
                            d.unit,
                            bs.name,
                            bs.unit,
                            accepted_units(bs.unit)
                        ),
                    )
                })?;
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
                };
                let (lo_phys, hi_phys) =
                    (spec.to_phys(spec.raw_min()), spec.to_phys(spec.raw_max()));
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
        Ok(Self::from_specs(specs))
    }
}
