//! The vehicle bus of a drive log (channel `grip/can/bus`, the recorder's
//! `bus` setting): per-identifier statistics named from the log's own DBC
//! ([`bus_ids`], [`render`]; `grip inspect`'s "bus" section) and the
//! export in candump's log format ([`write_candump`]; `grip inspect
//! --candump`), which can-utils' `canplayer`/`log2asc`, python-can and
//! SavvyCAN read.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use grip_msgs::{BusFrame, can_flags, topics};

use crate::DriveLog;

/// One identifier of the bus log.
#[derive(Debug, Clone, PartialEq)]
pub struct IdStats {
    /// Identifier.
    pub id: u32,
    /// 29-bit identifier.
    pub extended: bool,
    /// Error frames (the id is their error class).
    pub error: bool,
    /// Frames.
    pub frames: u64,
    /// Mean period, s (`None` below two frames).
    pub mean_period_s: Option<f64>,
    /// Largest gap between two frames, s.
    pub largest_gap_s: Option<f64>,
    /// The message's name in the log's DBC, if it names the id.
    pub name: Option<String>,
}

/// The message names of the DBC the drive's `can.toml` (attached) names,
/// by `(id, extended)`: every message of the file, grip's five and the
/// car's own. Empty (and why, as the error) when the log carries no such
/// DBC or it does not parse.
pub fn dbc_names(log: &DriveLog) -> Result<BTreeMap<(u32, bool), String>, String> {
    let text = log
        .attachment_text("can.toml")
        .ok_or("the log carries no can.toml")?;
    let can = grip_io::service::parse_can(Path::new("can.toml (attached)"), text)
        .map_err(|e| e.to_string())?;
    let dbc = can
        .dbc
        .ok_or("the attached can.toml names no dbc (the built-in protocol)")?;
    let bytes = log
        .attachments
        .get(&dbc)
        .ok_or_else(|| format!("the log does not carry {dbc}, which can.toml names"))?;
    grip_io::can::dbc_message_names(bytes, &format!("{dbc} (attached)")).map_err(|e| e.to_string())
}

/// True when the log has a bus log: frames on `grip/can/bus`, or the
/// recorder's counters of one (a bus log that stayed empty).
pub fn has_bus(log: &DriveLog) -> bool {
    !log.bus.is_empty()
        || log
            .recorder
            .as_ref()
            .is_some_and(|m| m.contains_key(&format!("{}.mode", topics::BUS)))
}

/// Per identifier (sorted: 11-bit, then 29-bit, then error frames, each by
/// number): frames, mean period, largest gap, the DBC's name.
pub fn bus_ids(frames: &[BusFrame], names: &BTreeMap<(u32, bool), String>) -> Vec<IdStats> {
    // (kind, id) → (frames, first, last, largest gap)
    let mut by: BTreeMap<(u8, u32), (u64, u64, u64, u64)> = BTreeMap::new();
    for f in frames {
        let kind = if f.flags & can_flags::ERROR != 0 {
            2
        } else {
            u8::from(f.is_extended())
        };
        let e = by
            .entry((kind, f.id))
            .or_insert((0, f.stamp_ns, f.stamp_ns, 0));
        if e.0 > 0 {
            e.3 = e.3.max(f.stamp_ns.saturating_sub(e.2));
        }
        e.0 += 1;
        e.2 = f.stamp_ns;
    }
    by.into_iter()
        .map(|((kind, id), (n, first, last, gap))| {
            let extended = kind == 1;
            IdStats {
                id,
                extended,
                error: kind == 2,
                frames: n,
                mean_period_s: (n > 1)
                    .then(|| last.saturating_sub(first) as f64 * 1e-9 / (n - 1) as f64),
                largest_gap_s: (n > 1).then_some(gap as f64 * 1e-9),
                name: (kind != 2)
                    .then(|| names.get(&(id, extended)).cloned())
                    .flatten(),
            }
        })
        .collect()
}

/// The "bus" section of `grip inspect`: `None` when the log has no bus
/// log ([`has_bus`]).
pub fn render(log: &DriveLog) -> Option<String> {
    if !has_bus(log) {
        return None;
    }
    let key = |k: &str| {
        log.recorder
            .as_ref()
            .and_then(|m| m.get(&format!("{}.{k}", topics::BUS)))
            .cloned()
    };
    let mut out = String::from("bus (the vehicle bus as the recorder read it, grip/can/bus");
    if let Some(m) = key("mode") {
        out.push_str(&format!(", bus = \"{m}\""));
    }
    if let Some(t) = key("transport") {
        out.push_str(&format!(", {t}"));
    }
    out.push_str("):\n");
    let (names, why) = match dbc_names(log) {
        Ok(n) => (n, None),
        Err(e) => (BTreeMap::new(), Some(e)),
    };
    let lost: Vec<String> = ["kernel_dropped", "queue_dropped", "receive_errors"]
        .iter()
        .filter_map(|k| key(k).map(|v| format!("{k} {v}")))
        .collect();
    out.push_str(&format!("  {} frames", log.bus.len()));
    if !lost.is_empty() {
        out.push_str(&format!(" ({})", lost.join(", ")));
    }
    if let Some(s) = key("stamps") {
        out.push_str(&format!("; stamps: {s}"));
    }
    out.push('\n');
    if let Some(why) = why {
        out.push_str(&format!("  no message names: {why}\n"));
    }
    if log.bus.is_empty() {
        return Some(out);
    }
    out.push_str(&format!(
        "  {:<12} {:>6} {:>9} {:>14} {:>14}  name\n",
        "id", "bits", "frames", "mean period ms", "largest gap ms"
    ));
    let ms = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |s| format!("{:.3}", s * 1e3));
    for s in bus_ids(&log.bus, &names) {
        let (id, bits) = if s.error {
            (format!("err {:#010X}", s.id), "error")
        } else if s.extended {
            (format!("0x{:08X}", s.id), "29")
        } else {
            (format!("0x{:03X}", s.id), "11")
        };
        let line = format!(
            "  {:<12} {:>6} {:>9} {:>14} {:>14}  {}",
            id,
            bits,
            s.frames,
            ms(s.mean_period_s),
            ms(s.largest_gap_s),
            s.name.as_deref().unwrap_or("")
        );
        out.push_str(line.trim_end());
        out.push('\n');
    }
    Some(out)
}

/// How [`write_candump`] placed the frames in wall time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WallClock {
    /// From the log's `grip.clock` record (CLOCK_MONOTONIC and
    /// CLOCK_REALTIME read together when the log was created): wall =
    /// stamp − monotonic_ns + realtime_ns.
    FromLog,
    /// The log has no `grip.clock`: the stamps are written as they are,
    /// seconds of CLOCK_MONOTONIC (since boot), not a date.
    Monotonic,
}

/// The offset that turns the log's CLOCK_MONOTONIC stamps into Unix time,
/// ns, from its `grip.clock` record (`None` if absent or unreadable).
pub fn wall_offset_ns(log: &DriveLog) -> Option<i128> {
    let c = log.metadata.get("grip.clock")?;
    let mono: i128 = c.get("monotonic_ns")?.parse().ok()?;
    let real: i128 = c.get("realtime_ns")?.parse().ok()?;
    Some(real - mono)
}

/// One frame as candump's log format writes it (`candump -L`, what
/// `canplayer` reads): `(seconds.micros) IFACE ID#DATA`; the id in 3 hex
/// digits (11-bit) or 8 (29-bit; an error frame: its class with
/// `CAN_ERR_FLAG` 0x20000000), the data in upper-case hex, a remote frame
/// `ID#R` and its DLC digit when not 0. `wall_ns` is the frame's time,
/// Unix ns (negative times are written as 0).
pub fn candump_line(f: &BusFrame, wall_ns: i128, iface: &str) -> String {
    let t = u128::try_from(wall_ns).unwrap_or(0);
    let (s, us) = (t / 1_000_000_000, (t % 1_000_000_000) / 1000);
    let id = if f.flags & can_flags::ERROR != 0 {
        format!("{:08X}", 0x2000_0000 | (f.id & 0x1FFF_FFFF))
    } else if f.is_extended() {
        format!("{:08X}", f.id & 0x1FFF_FFFF)
    } else {
        format!("{:03X}", f.id & 0x7FF)
    };
    let mut data = String::new();
    if f.flags & can_flags::RTR != 0 {
        data.push('R');
        if f.dlc > 0 {
            data.push(char::from(b'0' + f.dlc.min(8)));
        }
    } else {
        for b in f.payload() {
            data.push_str(&format!("{b:02X}"));
        }
    }
    format!("({s:010}.{us:06}) {iface} {id}#{data}")
}

/// The interface name for the candump file: the attached `can.toml`'s
/// `interface`, else `can0`.
pub fn candump_iface(log: &DriveLog) -> String {
    log.attachment_text("can.toml")
        .and_then(|t| grip_io::service::parse_can(Path::new("can.toml (attached)"), t).ok())
        .map_or_else(|| "can0".to_owned(), |c| c.interface)
}

/// Writes the bus log in candump's log format, one line per frame in log
/// order; returns how the times were placed.
pub fn write_candump(log: &DriveLog, out: &mut impl Write) -> std::io::Result<WallClock> {
    let iface = candump_iface(log);
    let (offset, clock) = match wall_offset_ns(log) {
        Some(o) => (o, WallClock::FromLog),
        None => (0, WallClock::Monotonic),
    };
    for f in &log.bus {
        writeln!(
            out,
            "{}",
            candump_line(f, i128::from(f.stamp_ns) + offset, &iface)
        )?;
    }
    Ok(clock)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: u32, flags: u8, data: &[u8], stamp_ns: u64) -> BusFrame {
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        BusFrame {
            stamp_ns,
            id,
            dlc: data.len() as u8,
            bus: 0,
            flags,
            _reserved: 0,
            data: d,
        }
    }

    /// candump -L's format, as can-utils' `lib.c` prints it and
    /// `canplayer` parses it: zero-padded seconds, 6 digits of
    /// microseconds, 3 or 8 upper-case hex digits of id, data in pairs.
    #[test]
    fn candump_lines_are_candumps_log_format() {
        let t = 1_764_950_400_123_456_789i128; // 2025-12-05T16:00:00.123456789Z
        assert_eq!(
            candump_line(&frame(0x3E9, 0, &[0xDE, 0xAD, 0x01], 0), t, "can0"),
            "(1764950400.123456) can0 3E9#DEAD01"
        );
        assert_eq!(
            candump_line(
                &frame(0x18DA_F110, can_flags::EXTENDED, &[0x02, 0x10, 0x03], 0),
                t,
                "vcan0"
            ),
            "(1764950400.123456) vcan0 18DAF110#021003"
        );
        // no data; early in the epoch: seconds zero-padded to 10 digits
        assert_eq!(
            candump_line(&frame(0x7FF, 0, &[], 0), 1_000_000_001_000, "can0"),
            "(0000001000.000001) can0 7FF#"
        );
        let mut rtr = frame(0x123, can_flags::RTR, &[], 0);
        rtr.dlc = 3;
        assert_eq!(
            candump_line(&rtr, t, "can0"),
            "(1764950400.123456) can0 123#R3"
        );
        let err = frame(
            0x0000_0004,
            can_flags::ERROR,
            &[0, 0x08, 0, 0, 0, 0, 0, 0],
            0,
        );
        assert_eq!(
            candump_line(&err, t, "can0"),
            "(1764950400.123456) can0 20000004#0008000000000000"
        );
        // before the epoch (a broken clock record): 0, never a panic
        assert!(candump_line(&frame(1, 0, &[], 0), -5, "can0").starts_with("(0000000000.000000)"));
    }

    /// A drive log carrying a car's full DBC (named by its attached
    /// `can.toml`), grip's messages and the car's own.
    fn car_log(frames: Vec<BusFrame>, clock: bool) -> DriveLog {
        let mut log = DriveLog::default();
        log.attachments.insert(
            "can.toml".into(),
            b"transport = \"socketcan\"\ninterface = \"can1\"\ndbc = \"car.dbc\"\n".to_vec(),
        );
        log.attachments.insert(
            "car.dbc".into(),
            b"VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: ABS GW\n\n\
BO_ 1001 BrakeStatus: 8 ABS\n SG_ Pressure : 0|16@1+ (0.1,0) [0|6553.5] \"bar\" GW\n\n\
BO_ 2564485392 DiagRequest: 8 GW\n SG_ B0 : 0|8@1+ (1,0) [0|255] \"\" ABS\n\n"
                .to_vec(),
        );
        let mut rec = grip_io::mcaplog::MetadataMap::new();
        rec.insert(format!("{}.mode", topics::BUS), "foreign".into());
        log.recorder = Some(rec);
        if clock {
            let mut c = grip_io::mcaplog::MetadataMap::new();
            c.insert("monotonic_ns".into(), "1000000000".into());
            c.insert("realtime_ns".into(), "1764950400000000000".into());
            log.metadata.insert("grip.clock".into(), c);
        }
        log.bus = frames;
        log
    }

    /// The bus section names foreign ids, 11- and 29-bit, from the car's
    /// DBC the log carries; an id it does not define stays unnamed.
    #[test]
    fn the_bus_section_names_the_cars_own_messages_from_the_logs_dbc() {
        let log = car_log(
            vec![
                frame(0x3E9, 0, &[1, 2], 1_000_000_000),
                frame(0x18DA_F110, can_flags::EXTENDED, &[3], 1_001_000_000),
                frame(0x3E9, 0, &[1, 3], 1_011_000_000),
                frame(0x555, 0, &[], 1_012_000_000),
            ],
            true,
        );
        let names = dbc_names(&log).unwrap();
        assert_eq!(
            names.get(&(0x3E9, false)).map(String::as_str),
            Some("BrakeStatus")
        );
        assert_eq!(
            names.get(&(0x18DA_F110, true)).map(String::as_str),
            Some("DiagRequest")
        );
        let text = render(&log).unwrap();
        let line = |id: &str| {
            text.lines()
                .find(|l| l.trim_start().starts_with(id))
                .unwrap_or_else(|| panic!("no {id} line in\n{text}"))
                .to_owned()
        };
        assert!(line("0x3E9").ends_with("BrakeStatus"), "{text}");
        assert!(
            line("0x3E9").contains(" 11 ") && line("0x3E9").contains("11.000"),
            "{text}"
        );
        assert!(line("0x18DAF110").ends_with("DiagRequest"), "{text}");
        assert!(line("0x18DAF110").contains(" 29 "), "{text}");
        assert!(line("0x555").trim_end().ends_with('-'), "unnamed: {text}");
        assert!(text.contains("4 frames"), "{text}");
        // no bus log: no section
        let mut none = car_log(Vec::new(), true);
        none.recorder = None;
        assert_eq!(render(&none), None);
    }

    /// The candump export: the interface of the attached can.toml, wall
    /// time by the log's grip.clock; without it the monotonic seconds, and
    /// the caller is told.
    #[test]
    fn candump_export_places_stamps_by_the_logs_clock() {
        let f = vec![
            frame(0x3E9, 0, &[0xAB], 1_000_000_000),
            frame(0x18DA_F110, can_flags::EXTENDED, &[1, 2], 3_500_250_000),
        ];
        let mut out = Vec::new();
        let clock = write_candump(&car_log(f.clone(), true), &mut out).unwrap();
        assert_eq!(clock, WallClock::FromLog);
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "(1764950400.000000) can1 3E9#AB\n(1764950402.500250) can1 18DAF110#0102\n"
        );
        let mut out = Vec::new();
        let clock = write_candump(&car_log(f, false), &mut out).unwrap();
        assert_eq!(clock, WallClock::Monotonic);
        assert!(
            String::from_utf8(out)
                .unwrap()
                .starts_with("(0000000001.000000) can1 3E9#AB\n"),
        );
    }

    /// Per id: frames, mean period and largest gap from the stamps, names
    /// for 11- and 29-bit ids kept apart (the same number, two messages).
    #[test]
    fn id_statistics_count_periods_and_gaps_per_id_and_width() {
        let ms = 1_000_000u64;
        let mut fs = Vec::new();
        for k in [0u64, 10, 20, 50] {
            fs.push(frame(0x200, 0, &[1], k * ms));
        }
        fs.push(frame(0x200, can_flags::EXTENDED, &[2], 5 * ms));
        let mut names = BTreeMap::new();
        names.insert((0x200, false), "Brake".to_owned());
        names.insert((0x200, true), "J1939Thing".to_owned());
        let s = bus_ids(&fs, &names);
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].id, s[0].extended, s[0].frames), (0x200, false, 4));
        assert!((s[0].mean_period_s.unwrap() - 50e-3 / 3.0).abs() < 1e-12);
        assert!((s[0].largest_gap_s.unwrap() - 30e-3).abs() < 1e-12);
        assert_eq!(s[0].name.as_deref(), Some("Brake"));
        assert_eq!((s[1].extended, s[1].frames), (true, 1));
        assert_eq!(s[1].mean_period_s, None);
        assert_eq!(s[1].name.as_deref(), Some("J1939Thing"));
    }
}
