//! HIL drive on a car's own bus: the services read their CAN protocol from
//! a DBC that is not grip's (`tests/data/own-bus.dbc`: ids 0x191-0x195,
//! other message and signal names mapped in `can.toml` `[dbc_names]`,
//! Motorola byte order in MotorStatus, the CRC in WheelSpeeds' last byte,
//! rpm, km/h and g), on a real kernel's `vcan0`. Run by `tools/hil/run`
//! (natively or in its VM): `tools/hil/run --test own_bus`.
//!
//! 1. `drive_on_a_cars_own_bus`: `grip drive` of the HIL's e2e scenario
//!    ([`SCENARIO_TOML`]) with the HIL configuration plus `own-bus.dbc`
//!    and its name map. From an independent raw-socket [`CanCapture`],
//!    decoded by the HIL's own decoder ([`Dbc`], written from the DBC's
//!    text): every frame has one of the DBC's ids and none of the built-in
//!    ones, decodes with a valid CRC (wherever the DBC puts it) and counter;
//!    the torque command carries the controller's torque (the same as its
//!    cycle records, to the signal's resolution); the wheel, motor and
//!    vehicle speeds agree with the plant's ground truth and with each other
//!    in SI units, and LongAccel (g) integrates to the change of Speed
//!    (km/h). tcs-loop counted no E2E fault during the scenario and never
//!    entered its safe state; the MCAP reads back complete, its CAN log
//!    holds the DBC's ids only, and `grip inspect` names the frames by
//!    grip's names (TorqueCommand, not 0x191). The car's own traffic:
//!    foreign frames another process ([`Injector`]) puts on `vcan0` during
//!    the drive (11-bit 0x3E9, 29-bit 0x18DAF110, and 0x100, the built-in
//!    TorqueCommand's id, foreign on this bus) are in the recorder's bus log
//!    (`grip/can/bus`, `bus = "foreign"`) byte for byte, in order, none
//!    missing from its first to its last (against the capture), over the
//!    whole scenario, each stamped with the kernel's receive time (the
//!    capture's own kernel stamp of the same frame, within 0.25 ms); the
//!    own bus's ids are left out (grip's by the *active* DBC; by the
//!    monitor's kernel filter, so they are not even read), and `grip
//!    inspect --candump` writes them in candump's format.
//! 2. `a_dbc_without_a_message_stops_the_drive_before_its_scenario`: a
//!    `can.toml` naming a DBC without MotorStatus makes `grip drive` fail,
//!    naming the file and the message, with no frame on the bus.
//!
//! The drives share `vcan0` and the loopback with the other HIL drives, so
//! they take the same lock.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context, ensure};
use grip_tests::hil::{
    self, CAN_EFF_FLAG, CanCapture, Captured, Dbc, RawCanSocket, RawFrame, RoadAudioPlayer,
};
use grip_tests::hil_drives::{
    Attempt, PLAYBACK, SCENARIO_TOML, SENSOR_TIMEOUT_MS, Setup, check_all_frames_valid, grip_drive,
    ms, read_complete, serial, setup, sig, wait_success, with_attempts_prepared,
};

/// `can.toml`'s name map for own-bus.dbc: grip's names → the DBC's.
const OWN_BUS_NAMES: &str = r#"[dbc_names]
TorqueCommand = "MCU_TrqCmd"
"TorqueCommand.TorqueRequest" = "TrqReq"
DriverDemand = "VCU_Demand"
"DriverDemand.TorqueDemand" = "TrqDmd"
"#;
/// The own bus's ids (TorqueCommand, MotorStatus, WheelSpeeds,
/// VehicleSpeed, DriverDemand).
const OWN_IDS: [u32; 5] = [0x191, 0x192, 0x193, 0x194, 0x195];
/// The built-in protocol's ids (config/inverter.dbc), which must not appear.
const BUILTIN_IDS: [u32; 5] = [0x100, 0x110, 0x120, 0x130, 0x140];

fn own_bus_dbc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/own-bus.dbc")
}

/// The HIL configuration with own-bus.dbc and its name map; the capture
/// decoded per the same files.
fn on_own_bus(s: &mut Setup) -> anyhow::Result<()> {
    hil::set_bus_dbc(&s.config, &own_bus_dbc(), OWN_BUS_NAMES)?;
    s.dbc = Dbc::for_config(&s.config)?;
    let ids: Vec<u32> = s.dbc.messages.iter().map(|m| m.id).collect();
    ensure!(ids == OWN_IDS, "own-bus.dbc has the ids {ids:x?}");
    Ok(())
}

/// What [`Injector`] puts on the bus, as identifier words: a foreign
/// 11-bit id, a 29-bit one (J1939/UDS-like), and 0x100, which is grip's
/// TorqueCommand in the built-in protocol but foreign on the own bus.
const INJECTED: [u32; 3] = [0x3E9, CAN_EFF_FLAG | 0x18DA_F110, 0x100];

/// Another ECU on the bus: a thread sending [`INJECTED`] in turn, one
/// frame every 2 ms, each with its number in the first two bytes.
struct Injector {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    handle: std::thread::JoinHandle<anyhow::Result<u64>>,
}

impl Injector {
    fn start(iface: &str) -> anyhow::Result<Self> {
        let sock = RawCanSocket::open(iface)?;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stop2 = std::sync::Arc::clone(&stop);
        let handle = std::thread::Builder::new()
            .name("foreign-ecu".into())
            .spawn(move || {
                let mut k = 0u64;
                while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
                    let word = INJECTED[(k % 3) as usize];
                    let n = (k as u16).to_le_bytes();
                    let len = 2 + (k % 7) as usize;
                    let payload = [n[0], n[1], 0xA5, 0x5A, 0xFF, 0x00, 0x77, 0x11];
                    sock.send(&RawFrame::new(word, &payload[..len])?)?;
                    k += 1;
                    std::thread::sleep(Duration::from_millis(2));
                }
                Ok(k)
            })?;
        Ok(Self { stop, handle })
    }

    fn finish(self) -> anyhow::Result<u64> {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("the injector thread panicked"))?
    }
}

/// The identifier word of a logged bus frame (as the kernel's can_id).
fn word(b: &grip_msgs::BusFrame) -> u32 {
    if b.is_extended() {
        b.id | CAN_EFF_FLAG
    } else {
        b.id
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

// --- 1. a drive on the own bus -------------------------------------------------------

#[test]
fn drive_on_a_cars_own_bus() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_prepared("own-bus", SCENARIO_TOML, on_own_bus, own_bus_drive)
}

fn own_bus_drive(s: &Setup) -> anyhow::Result<Attempt> {
    let started = Instant::now();
    let mcap = s.out.join("drive.mcap");
    let cap = CanCapture::start(&s.iface)?;
    let injector = Injector::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let mut drive = grip_drive(s, &mcap)?;
    let res = wait_success(&mut drive, "grip drive", Duration::from_secs(180));
    let drive_s = started.elapsed().as_secs_f64();
    let injected_n = injector.finish()?;
    let mut cap = cap.finish()?;
    // the foreign ECU's frames apart: the checks of grip's traffic below
    // see only grip's
    let injected: Vec<Captured> = cap
        .frames
        .iter()
        .filter(|f| INJECTED.contains(&f.frame.can_id))
        .copied()
        .collect();
    cap.frames.retain(|f| !INJECTED.contains(&f.frame.can_id));
    println!(
        "foreign ECU: {injected_n} frames sent, {} captured",
        injected.len()
    );
    let played = player.finish()?;
    res?;
    println!("grip drive output:\n{}", drive.log_text());
    println!("player: {played:?}");
    println!("grip drive took {drive_s:.1} s (guest clock)");

    // the ids on the wire: the DBC's, never the built-in ones
    let mut per_id: BTreeMap<u32, u64> = BTreeMap::new();
    for f in &cap.frames {
        *per_id.entry(f.id()).or_default() += 1;
    }
    let listed: Vec<String> = per_id
        .iter()
        .map(|(id, n)| format!("{id:#x}: {n}"))
        .collect();
    println!(
        "frames on {} per id: {} ({} in all)",
        s.iface,
        listed.join(", "),
        cap.frames.len()
    );
    let builtin: Vec<String> = BUILTIN_IDS
        .iter()
        .filter_map(|id| per_id.get(id).map(|n| format!("{n} x {id:#x}")))
        .collect();
    ensure!(
        builtin.is_empty(),
        "frames with the built-in protocol's ids on the own bus: {builtin:?}"
    );
    let foreign: Vec<&u32> = per_id.keys().filter(|id| !OWN_IDS.contains(id)).collect();
    ensure!(
        foreign.is_empty(),
        "frames with ids own-bus.dbc does not have: {foreign:x?}"
    );

    // every frame decodes per own-bus.dbc, CRCs and counters valid
    let check = check_all_frames_valid(&cap, &s.dbc)?;
    for (m, min) in [
        ("TorqueCommand", 500),
        ("MotorStatus", 500),
        ("WheelSpeeds", 500),
        ("VehicleSpeed", 50),
        ("DriverDemand", 50),
    ] {
        let n = check.per_message.get(m).map_or(0, |v| v[0]);
        ensure!(
            n >= min,
            "only {n} {m} frames on the bus for a 3 s drive (>= {min} expected)"
        );
    }
    let l = read_complete(&mcap)?;

    // the scenario on the wire: DriverDemand (VCU_Demand.TrqDmd) carries the demand
    let dd = s.dbc.by_name("DriverDemand")?;
    let demand: Vec<(u64, f64)> = cap
        .with_id(dd.id)
        .map(|f| (f.t_ns, sig(&s.dbc, "DriverDemand", "TorqueDemand", f)))
        .filter(|&(_, v)| v > 0.05)
        .collect();
    let (t0, t1) = match (demand.first(), demand.last()) {
        (Some(a), Some(b)) => (a.0, b.0),
        _ => anyhow::bail!("no DriverDemand with a demand on the bus: the scenario never ran"),
    };
    let peak_demand = demand.iter().fold(0.0f64, |a, &(_, v)| a.max(v));
    println!(
        "scenario on the wire: {:.3} s, demand up to {peak_demand:.1} N m",
        ms(i128::from(t1) - i128::from(t0)) / 1e3
    );
    ensure!(
        (peak_demand - 300.0).abs() < 0.15,
        "the scenario demands 300 N m, VCU_Demand.TrqDmd said {peak_demand}"
    );
    let during = |f: &&Captured| f.t_ns >= t0 && f.t_ns <= t1;

    // tcs-loop during the scenario: no E2E fault, no safe state
    let in_window: Vec<_> = l
        .cycles
        .iter()
        .filter(|c| c.stamp_ns >= t0 && c.stamp_ns <= t1)
        .collect();
    ensure!(
        in_window.len() > 1000,
        "only {} cycle records during the scenario",
        in_window.len()
    );
    // over the whole log no frame may fail the CRC, the length or the id
    // (the layout); the counters may break at start-up (tcs-loop reads a
    // backlog the kernel queued, and dropped from, while it started) and
    // time out after plant-sim ended: those the window below excludes
    let last = l.cycles.last().context("no cycle records")?.faults;
    ensure!(
        last.crc == 0 && last.length == 0 && last.unknown_id == 0,
        "tcs-loop rejected frames of the own bus: {last:?}"
    );
    let (f0, f1) = (in_window[0].faults, in_window[in_window.len() - 1].faults);
    let safe = in_window.iter().filter(|c| c.safe_state != 0).count();
    let stopped = drive
        .log_text()
        .lines()
        .find(|l| l.contains("tcs-loop stopped"))
        .map(|l| {
            l.split_whitespace()
                .filter(|w| w.starts_with("safe_entries=") || w.starts_with("e2e_faults="))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_default();
    println!(
        "tcs-loop: E2E faults over the whole log {last:?} (its stopped line: {stopped}); during the scenario: {f0:?} -> {f1:?}, {safe} safe-state cycles of {}",
        in_window.len()
    );
    ensure!(
        (
            f1.crc,
            f1.counter_repeated,
            f1.counter_skipped,
            f1.length,
            f1.unknown_id
        ) == (
            f0.crc,
            f0.counter_repeated,
            f0.counter_skipped,
            f0.length,
            f0.unknown_id
        ),
        "tcs-loop counted E2E faults during the scenario: {f0:?} -> {f1:?}"
    );
    if safe > 0 || f1.timeout != f0.timeout {
        // a stall of the emulated machine silences the inputs: then on
        // the wire (or in the loop's own cycle stamps) there is a gap of at
        // least the sensor timeout; without one it is a failure
        let mut worst = 0.0f64;
        for name in ["WheelSpeeds", "MotorStatus"] {
            let id = s.dbc.by_name(name)?.id;
            let t: Vec<u64> = cap.with_id(id).filter(during).map(|f| f.t_ns).collect();
            for w in t.windows(2) {
                worst = worst.max(ms(i128::from(w[1]) - i128::from(w[0])));
            }
        }
        for w in in_window.windows(2) {
            worst = worst.max(ms(i128::from(w[1].stamp_ns) - i128::from(w[0].stamp_ns)));
        }
        let why = format!(
            "tcs-loop timed out {} times and spent {safe} cycles in its safe state during the scenario; longest input or cycle gap {worst:.1} ms",
            f1.timeout - f0.timeout
        );
        ensure!(
            worst >= SENSOR_TIMEOUT_MS,
            "{why}, shorter than the {SENSOR_TIMEOUT_MS} ms sensor timeout: not a stall of the machine"
        );
        return Ok(Attempt::Disturbed(why));
    }

    // the torque command (MCU_TrqCmd.TrqReq): the controller's torque
    let tc = s.dbc.by_name("TorqueCommand")?;
    let enabled: Vec<(u64, f64)> = cap
        .with_id(tc.id)
        .filter(during)
        .filter(|f| sig(&s.dbc, "TorqueCommand", "Enable", f) == 1.0)
        .map(|f| (f.t_ns, sig(&s.dbc, "TorqueCommand", "TorqueRequest", f)))
        .collect();
    let mut first_s: Vec<f64> = enabled
        .iter()
        .filter(|&&(t, _)| t < t0 + 1_000_000_000)
        .map(|&(_, v)| v)
        .collect();
    ensure!(
        first_s.len() > 200,
        "only {} enabled TorqueCommands in the scenario's first second",
        first_s.len()
    );
    first_s.sort_by(f64::total_cmp);
    let level = first_s[first_s.len() / 2];
    let wire_max = enabled.iter().fold(f64::MIN, |a, &(_, v)| a.max(v));
    let cycle_max = in_window.iter().fold(f64::MIN, |a, c| a.max(c.torque_cmd));
    println!(
        "TorqueCommand on the wire: {} enabled during the scenario, median {level:.1} N m on asphalt, max {wire_max:.1} N m (tcs-loop's cycle records: max {cycle_max:.2} N m)",
        enabled.len()
    );
    ensure!(
        level > 250.0,
        "the command on asphalt was {level} N m on the wire, expected near the 300 N m demand"
    );
    ensure!(
        (wire_max - cycle_max).abs() <= 0.1,
        "the wire's largest command {wire_max} N m is not tcs-loop's {cycle_max} N m (resolution 0.1 N m)"
    );

    // speeds in SI units: the wheel (rad/s), the motor (rpm, Motorola),
    // the vehicle (km/h) against the plant's ground truth and each other
    let signal_mean = |msg: &str, name: &str| -> anyhow::Result<(f64, usize)> {
        let m = s.dbc.by_name(msg)?;
        let v: Vec<f64> = cap
            .with_id(m.id)
            .filter(during)
            .map(|f| m.si(name, &f.data8()))
            .collect();
        Ok((mean(&v), v.len()))
    };
    let (wheel, n_ws) = signal_mean("WheelSpeeds", "OmegaDriven")?;
    let (motor, n_ms) = signal_mean("MotorStatus", "MotorSpeed")?;
    let truth: Vec<_> = l
        .truth
        .iter()
        .filter(|t| t.stamp_ns >= t0 && t.stamp_ns <= t1)
        .collect();
    ensure!(!truth.is_empty(), "no ground truth during the scenario");
    let true_omega = mean(&truth.iter().map(|t| t.omega).collect::<Vec<_>>());
    let true_v = mean(&truth.iter().map(|t| t.v).collect::<Vec<_>>());
    let vs = s.dbc.by_name("VehicleSpeed")?;
    let speeds: Vec<(f64, f64)> = cap
        .with_id(vs.id)
        .filter(during)
        .filter(|f| vs.value("Valid", &f.data8()) == 1.0)
        .map(|f| (vs.si("Speed", &f.data8()), vs.si("LongAccel", &f.data8())))
        .collect();
    ensure!(
        speeds.len() > 20,
        "only {} valid VehicleSpeed frames",
        speeds.len()
    );
    let v_wire = mean(&speeds.iter().map(|s| s.0).collect::<Vec<_>>());
    let dv = speeds[speeds.len() - 1].0 - speeds[0].0;
    let dt_vs = f64::from(vs.cycle_ms) * 1e-3;
    let integrated: f64 = speeds[1..].iter().map(|s| s.1 * dt_vs).sum();
    println!(
        "speeds during the scenario (means, SI): wheel {wheel:.3} rad/s ({n_ws} WheelSpeeds), motor {motor:.3} rad/s ({n_ms} MotorStatus, rpm on the wire), ground truth omega {true_omega:.3} rad/s; vehicle {v_wire:.3} m/s (km/h on the wire), ground truth {true_v:.3} m/s; Speed changed {dv:.3} m/s, LongAccel (g on the wire) integrates to {integrated:.3} m/s"
    );
    ensure!(
        wheel > 5.0,
        "the driven wheel turned at {wheel} rad/s on average: not moving"
    );
    let close = |a: f64, b: f64, rel: f64, abs: f64| (a - b).abs() <= rel * b.abs() + abs;
    ensure!(
        close(wheel, true_omega, 0.05, 0.3),
        "WheelSpeeds.OmegaDriven {wheel} rad/s, the plant's omega {true_omega} rad/s"
    );
    ensure!(
        close(motor, wheel, 0.03, 0.2),
        "MotorStatus.MotorSpeed {motor} rad/s (from rpm), the wheel {wheel} rad/s"
    );
    ensure!(
        close(v_wire, true_v, 0.05, 0.1),
        "VehicleSpeed.Speed {v_wire} m/s (from km/h), the plant's v {true_v} m/s"
    );
    ensure!(dv > 0.5, "the car gained only {dv} m/s under 300 N m");
    ensure!(
        close(integrated, dv, 0.1, 0.1),
        "VehicleSpeed.LongAccel integrates to {integrated} m/s, Speed changed {dv} m/s"
    );

    // the drive's log: its CAN log holds the own bus's ids; grip inspect
    // names them by grip's names
    let mut logged: BTreeMap<u32, usize> = BTreeMap::new();
    // alive-counter breaks in the log, per (id, direction), the counter
    // read where own-bus.dbc puts it (WheelSpeeds: bits 0-3 of byte 0)
    let mut last_ctr: BTreeMap<(u32, u8), u8> = BTreeMap::new();
    let mut breaks = 0u64;
    for f in &l.can {
        *logged.entry(f.id).or_default() += 1;
        if let Some(m) = s.dbc.by_id(f.id) {
            let c = m.counter(&f.data);
            if let Some(p) = last_ctr.insert((f.id, f.direction), c)
                && c != (p + 1) & 0x0F
            {
                breaks += 1;
            }
        }
    }
    let listed: Vec<String> = logged
        .iter()
        .map(|(id, n)| format!("{id:#x}: {n}"))
        .collect();
    let recorder_gaps = l
        .recorder
        .get(&format!("{}.counter_gaps", grip_msgs::topics::CAN_LOG))
        .cloned()
        .unwrap_or_default();
    println!(
        "CAN log in the MCAP per id: {}; alive-counter breaks per own-bus.dbc: {breaks} (tcs-loop's counter faults: {} skipped, {} repeated); the recorder's counter_gaps: {recorder_gaps}",
        listed.join(", "),
        last.counter_skipped,
        last.counter_repeated
    );
    ensure!(
        !logged.is_empty() && logged.keys().all(|id| OWN_IDS.contains(id)),
        "the MCAP's CAN log has ids {:x?}",
        logged.keys().collect::<Vec<_>>()
    );
    ensure!(
        breaks <= u64::from(last.counter_skipped + last.counter_repeated),
        "{breaks} alive-counter breaks in the logged frames, more than tcs-loop counted"
    );
    // the recorder reads the counters where the DBC puts them too (it read
    // byte 1 whatever the bus: ~21 300 "gaps" on this one, 2026-12-05)
    let recorder_gaps: u64 = recorder_gaps
        .parse()
        .with_context(|| format!("the recorder's counter_gaps {recorder_gaps:?}"))?;
    ensure!(
        (recorder_gaps == 0) == (breaks == 0) && recorder_gaps <= 15 * breaks,
        "the recorder counted {recorder_gaps} CAN frames missing by alive counter; the log's frames break {breaks} times"
    );
    check_bus_log(&l, &injected, (t0, t1))?;
    let candump = s.out.join("bus.log");
    let o = Command::new(hil::service_bin("grip")?)
        .arg("inspect")
        .arg(&mcap)
        .arg("--candump")
        .arg(&candump)
        // the test's own output folder: a rerun replaces its file
        .arg("--force")
        .env("NO_COLOR", "1")
        .output()?;
    let text = String::from_utf8_lossy(&o.stdout);
    ensure!(
        o.status.success(),
        "grip inspect failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let can_lines: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("CAN frames"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty() && !l.contains("rejected"))
        .collect();
    println!("grip inspect, CAN section:\n{}", can_lines.join("\n"));
    let names: Vec<&str> = can_lines
        .iter()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    for want in [
        "TorqueCommand",
        "MotorStatus",
        "WheelSpeeds",
        "VehicleSpeed",
        "DriverDemand",
    ] {
        ensure!(
            names.contains(&want),
            "grip inspect's CAN section does not list {want}:\n{text}"
        );
    }
    ensure!(
        names.iter().all(|n| !n.starts_with("0x")),
        "grip inspect lists frames by id, not name: {names:?}"
    );
    ensure!(
        !text.contains("named by the built-in protocol"),
        "grip inspect fell back to the built-in protocol:\n{text}"
    );
    // its bus section lists the foreign ids; the candump file has every
    // frame of the bus log, the 29-bit one in 8 digits
    let bus_lines: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("bus ("))
        .take_while(|l| !l.trim().is_empty())
        .collect();
    println!("grip inspect, bus section:\n{}", bus_lines.join("\n"));
    for want in ["0x3E9", "0x18DAF110", "0x100"] {
        ensure!(
            bus_lines.iter().any(|l| l.trim_start().starts_with(want)),
            "grip inspect's bus section does not list {want}:\n{text}"
        );
    }
    let dump = std::fs::read_to_string(&candump)
        .with_context(|| format!("grip inspect --candump wrote no {}", candump.display()))?;
    let lines: Vec<&str> = dump.lines().collect();
    ensure!(
        lines.len() == l.bus.len(),
        "{} candump lines for {} frames of the bus log",
        lines.len(),
        l.bus.len()
    );
    ensure!(
        lines
            .iter()
            .any(|x| x.contains(&format!(" {} 18DAF110#", s.iface)))
            && lines
                .iter()
                .any(|x| x.contains(&format!(" {} 3E9#", s.iface))),
        "candump lines lack the foreign frames: {:?}",
        &lines[..lines.len().min(5)]
    );
    println!(
        "candump export: {} lines, e.g. {:?}",
        lines.len(),
        &lines[..lines.len().min(3)]
    );
    println!(
        "own-bus drive checked in {:.1} s (guest clock)",
        started.elapsed().as_secs_f64()
    );
    Ok(Attempt::Done)
}

/// The recorder's bus log against the foreign frames the capture saw: the
/// logged ones are a run of the captured ones without a hole, byte for
/// byte and in order, covering the scenario (`window`), each stamped with
/// the kernel's time of the same frame; none of the own bus's ids is in it
/// (`bus = "foreign"` by the active DBC), and the recorder counted them as
/// skipped, lost none and stamped every frame with the kernel's time.
fn check_bus_log(
    l: &grip_tests::hil_drives::Log,
    injected: &[Captured],
    window: (u64, u64),
) -> anyhow::Result<()> {
    let meta = |k: &str| -> anyhow::Result<u64> {
        let key = format!("{}.{k}", grip_msgs::topics::BUS);
        l.recorder
            .get(&key)
            .with_context(|| format!("recorder summary lacks {key}"))?
            .parse()
            .with_context(|| key.clone())
    };
    let mode = l
        .recorder
        .get(&format!("{}.mode", grip_msgs::topics::BUS))
        .cloned()
        .unwrap_or_default();
    let transport = l
        .recorder
        .get(&format!("{}.transport", grip_msgs::topics::BUS))
        .cloned()
        .unwrap_or_default();
    let (received, skipped, written) = (meta("received")?, meta("skipped_own")?, meta("written")?);
    let (kstamped, kdropped, qdropped, errors) = (
        meta("kernel_stamped")?,
        meta("kernel_dropped")?,
        meta("queue_dropped")?,
        meta("receive_errors")?,
    );
    println!(
        "bus log: mode {mode}, transport {transport}: {received} frames read, {skipped} of grip's skipped, {written} written ({} in the log), {kstamped} kernel-stamped, {kdropped} dropped by the kernel, {qdropped} by the queue, {errors} read errors",
        l.bus.len()
    );
    ensure!(
        mode == "foreign" && transport == "socketcan",
        "bus log mode {mode:?} on {transport:?}"
    );
    ensure!(
        kdropped == 0 && qdropped == 0 && errors == 0,
        "the bus log lost frames or failed reads"
    );
    ensure!(
        kstamped == received,
        "{kstamped} of {received} frames kernel-stamped"
    );
    ensure!(written == l.bus.len() as u64 && received == written + skipped);
    let own: Vec<&grip_msgs::BusFrame> = l
        .bus
        .iter()
        .filter(|b| !b.is_extended() && OWN_IDS.contains(&b.id))
        .collect();
    ensure!(
        own.is_empty(),
        "{} frames of the own bus's (grip's) ids in the foreign bus log, first {:x?}",
        own.len(),
        own.first()
    );
    // grip's frames never reach the monitor on SocketCAN: its kernel filter
    // drops them (only those queued in the instant before the filter was set)
    ensure!(
        skipped < 100,
        "{skipped} of grip's frames reached the recorder's monitor through its kernel filter"
    );
    let logged: Vec<&grip_msgs::BusFrame> = l
        .bus
        .iter()
        .filter(|b| INJECTED.contains(&word(b)))
        .collect();
    ensure!(
        logged.len() == l.bus.len(),
        "the bus log holds frames nobody sent: {:x?}",
        l.bus.iter().find(|b| !INJECTED.contains(&word(b)))
    );
    let first = logged.first().context("no foreign frame in the bus log")?;
    let start = injected
        .iter()
        .position(|c| c.frame.can_id == word(first) && c.frame.payload() == first.payload())
        .context("the bus log's first foreign frame was never on the bus")?;
    ensure!(
        injected.len() >= start + logged.len(),
        "the bus log has {} foreign frames, the bus had {} from its first on",
        logged.len(),
        injected.len() - start
    );
    let mut worst_ns = 0i128;
    for (k, (b, c)) in logged.iter().zip(&injected[start..]).enumerate() {
        ensure!(
            word(b) == c.frame.can_id && b.payload() == c.frame.payload() && b.flags & 0b110 == 0,
            "foreign frame {k} of the bus log {b:x?} is not the bus's {:x?}",
            c.frame
        );
        let d = i128::from(b.stamp_ns) - i128::from(c.t_ns);
        worst_ns = worst_ns.max(d.abs());
    }
    let last = logged[logged.len() - 1];
    ensure!(
        first.stamp_ns <= window.0 && last.stamp_ns >= window.1,
        "the bus log ({}..{} ns) does not cover the scenario ({}..{} ns)",
        first.stamp_ns,
        last.stamp_ns,
        window.0,
        window.1
    );
    ensure!(
        logged.windows(2).all(|w| w[0].stamp_ns <= w[1].stamp_ns),
        "bus log stamps go backwards"
    );
    println!(
        "bus log: {} foreign frames, a run of the {} the capture saw (from #{start}), byte for byte; stamps within {:.3} ms of the capture's kernel stamps",
        logged.len(),
        injected.len(),
        worst_ns as f64 / 1e6
    );
    ensure!(
        worst_ns <= 250_000,
        "a bus-log stamp is {:.3} ms off the kernel's receive time of its frame",
        worst_ns as f64 / 1e6
    );
    Ok(())
}

// --- 2. a DBC that lacks one of grip's messages ---------------------------------------

/// `dbc` without message `id` (its `BO_` block and its `BA_` lines).
fn without_message(dbc: &str, id: u32) -> String {
    let bo = format!("BO_ {id} ");
    let mut out = String::new();
    let mut skipping = false;
    for line in dbc.lines() {
        if line.starts_with("BO_ ") {
            skipping = line.starts_with(&bo);
        } else if line.trim().is_empty() {
            skipping = false;
        }
        if skipping || (line.starts_with("BA_ ") && line.contains(&format!(" {bo}"))) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

#[test]
fn a_dbc_without_a_message_stops_the_drive_before_its_scenario() -> anyhow::Result<()> {
    let _g = serial();
    let s = setup("own-bus-missing-message")?;
    let full = std::fs::read_to_string(own_bus_dbc())?;
    let cut = without_message(&full, 0x192);
    ensure!(
        full.contains("BO_ 402 MotorStatus")
            && !cut.contains("BO_ 402 ")
            && !cut.contains("SG_ MotorSpeed")
            && cut.contains("BO_ 401 MCU_TrqCmd"),
        "cutting MotorStatus out of own-bus.dbc went wrong:\n{cut}"
    );
    let dbc = s.out.join("no-status.dbc");
    std::fs::write(&dbc, cut)?;
    hil::set_bus_dbc(&s.config, &dbc, OWN_BUS_NAMES)?;

    let mcap = s.out.join("drive.mcap");
    let cap = CanCapture::start(&s.iface)?;
    let started = Instant::now();
    let mut drive = grip_drive(&s, &mcap)?;
    let st = drive.wait_timeout(Duration::from_secs(120))?;
    let took = started.elapsed().as_secs_f64();
    let cap = cap.finish()?;
    let out = drive.log_text();
    println!("grip drive ({took:.1} s, {st:?}):\n{out}");
    let st = st.context("grip drive did not end within 120 s")?;
    ensure!(
        !st.success(),
        "grip drive succeeded with a DBC lacking MotorStatus"
    );
    ensure!(
        out.contains("no-status.dbc") && out.contains("MotorStatus"),
        "grip drive's error does not name the DBC file and the message:\n{out}"
    );
    ensure!(
        cap.frames.is_empty(),
        "{} frames on the bus: a service got past its configuration (first id {:#x})",
        cap.frames.len(),
        cap.frames[0].id()
    );
    Ok(())
}
