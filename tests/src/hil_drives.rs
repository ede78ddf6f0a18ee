//! Shared pieces of the HIL drives (`tests/hil_drive.rs`,
//! `tests/hil_faults.rs`): the drive's set-up (the shipped configuration
//! with SocketCAN on `vcan0` and ALSA on the loopback, a short scenario),
//! the retry rule for drives that a stall of the emulated machine disturbed
//! ([`with_attempts`]), `grip drive` as a child, and the MCAP read-back
//! ([`read_complete`]). See `tools/hil/README.md`.
#![allow(missing_docs)]

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use anyhow::{Context, bail, ensure};
use grip_drive::{DriveLog, LoadOptions};
use grip_io::mcaplog::MetadataMap;
use grip_msgs::{CycleRecord, GroundTruth, topics};

use crate::hil::{
    self, CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_SFF_MASK, CanCapture, CaptureLog, Captured, Dbc,
    HilConfig, Proc, RawCanSocket, RoadAudioPlayer, StreamCheck,
};

/// The scenario of every HIL drive (written by [`setup`] next to the drive's
/// files): the e2e scenario's constant 300 N m from 10 km/h over asphalt,
/// snow and gravel, 1 s each instead of 0.5 s, so the emulated machine has
/// time to settle after each event.
pub const SCENARIO_TOML: &str = r#"name = "hil"
description = "HIL drive: constant 300 N m from 10 km/h, asphalt 1 s, snow 1 s, gravel 1 s"
v0_kmh = 10.0
segments_by = "time"
duration = 3.0

[demand]
kind = "constant"
torque = 300.0

[[segment]]
road = "asphalt"
duration = 1.0

[[segment]]
road = "snow"
duration = 1.0

[[segment]]
road = "gravel"
duration = 1.0
"#;
/// A drive of `secs` seconds on asphalt at a constant 300 N m from 10 km/h:
/// one road, so that every change the tests see is the fault's.
pub fn asphalt_scenario(secs: u32) -> String {
    format!(
        r#"name = "hil-asphalt"
description = "HIL drive: constant 300 N m from 10 km/h on asphalt, {secs} s"
v0_kmh = 10.0
segments_by = "time"
duration = {secs}.0

[demand]
kind = "constant"
torque = 300.0

[[segment]]
road = "asphalt"
duration = {secs}.0
"#
    )
}

/// Attempts of a drive whose preconditions a stall of the emulated machine
/// broke (see [`Attempt::Disturbed`]); each is reported.
pub const ATTEMPTS: usize = 3;
/// Where the player plays, and audio-acq captures (the loopback's two ends).
pub const PLAYBACK: &str = "hw:Loopback,0,0";
pub const CAPTURE: &str = "hw:Loopback,1,0";
/// Allowance for the emulated machine on top of every protocol time bound.
pub const VM_MARGIN_MS: f64 = 100.0;
/// The inverter's TorqueCommand timeout (DBC `GripTimeoutMs` of 0x100).
pub const INVERTER_TIMEOUT_MS: f64 = 20.0;
/// tcs-loop's sensor timeout (DBC `GripTimeoutMs` of 0x110/0x120).
pub const SENSOR_TIMEOUT_MS: f64 = 10.0;

pub static SERIAL: Mutex<()> = Mutex::new(());

pub fn serial() -> MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// Milliseconds as nanoseconds (the inverse of [`ms`]).
pub fn ns(ms: f64) -> u64 {
    (ms * 1e6) as u64
}

pub fn ms(ns: i128) -> f64 {
    ns as f64 / 1e6
}

/// A number from the configuration the services run with: `key` (a
/// dotted path, e.g. `"arte.max_age_s"`) of `file` in `config_dir`. The
/// tests' bounds read their figures here, so that a configuration change
/// cannot leave a copy behind.
pub fn config_number(config_dir: &Path, file: &str, key: &str) -> anyhow::Result<f64> {
    let path = config_dir.join(file);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let doc: toml::Table = text
        .parse()
        .with_context(|| format!("parsing {}", path.display()))?;
    let mut parts = key.split('.');
    let last = parts.next_back().unwrap_or(key);
    let mut table = &doc;
    for part in parts {
        table = table
            .get(part)
            .and_then(toml::Value::as_table)
            .with_context(|| format!("{}: no table [{part}] (for {key})", path.display()))?;
    }
    match table.get(last) {
        Some(toml::Value::Float(v)) => Ok(*v),
        Some(toml::Value::Integer(v)) => Ok(*v as f64),
        Some(v) => bail!("{}: {key} is {v}, not a number", path.display()),
        None => bail!("{}: no {key}", path.display()),
    }
}

/// A time setting of a systemd unit in `config_dir/systemd` (`key=` with
/// systemd's units: `1s`, `500ms`, `2min`, or plain seconds), in ms.
pub fn unit_setting_ms(config_dir: &Path, unit: &str, key: &str) -> anyhow::Result<f64> {
    let path = config_dir.join("systemd").join(unit);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let value = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix(key)?.strip_prefix('='))
        .next_back()
        .with_context(|| format!("{}: no {key}=", path.display()))?
        .trim();
    let split = value
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(value.len());
    let (number, unit_name) = value.split_at(split);
    let scale = match unit_name.trim() {
        "" | "s" | "sec" => 1e3,
        "ms" | "msec" => 1.0,
        "min" | "m" => 60e3,
        u => bail!(
            "{}: {key}={value}: unit {u:?} not understood",
            path.display()
        ),
    };
    let n: f64 = number
        .parse()
        .with_context(|| format!("{}: {key}={value}: not a time", path.display()))?;
    Ok(n * scale)
}

pub struct Setup {
    pub out: PathBuf,
    pub config: PathBuf,
    pub scenario: String,
    pub iface: String,
    pub dbc: Dbc,
}

/// The result of one drive: done (checked), or disturbed by the emulated
/// machine (a stall broke a precondition of the check, e.g. the loop was in
/// its sensor-timeout safe state when the road changed): then it is run again.
pub enum Attempt {
    Done,
    Disturbed(String),
}

/// Runs `drive` up to [`ATTEMPTS`] times while it reports a disturbance.
pub fn with_attempts(
    name: &str,
    drive: impl FnMut(&Setup) -> anyhow::Result<Attempt>,
) -> anyhow::Result<()> {
    with_attempts_in(name, SCENARIO_TOML, drive)
}

/// [`with_attempts`] with the scenario `scenario_toml` instead of [`SCENARIO_TOML`].
pub fn with_attempts_in(
    name: &str,
    scenario_toml: &str,
    drive: impl FnMut(&Setup) -> anyhow::Result<Attempt>,
) -> anyhow::Result<()> {
    with_attempts_prepared(name, scenario_toml, |_| Ok(()), drive)
}

/// [`with_attempts_in`], each attempt's [`Setup`] changed by `prepare`
/// before the drive (e.g. its configuration, [`hil::set_bus_dbc`], and
/// the decoder to match, [`Dbc::for_config`]).
pub fn with_attempts_prepared(
    name: &str,
    scenario_toml: &str,
    mut prepare: impl FnMut(&mut Setup) -> anyhow::Result<()>,
    mut drive: impl FnMut(&Setup) -> anyhow::Result<Attempt>,
) -> anyhow::Result<()> {
    let mut why = Vec::new();
    for k in 1..=ATTEMPTS {
        let mut s = setup_with(&format!("{name}-{k}"), scenario_toml)?;
        prepare(&mut s)?;
        match drive(&s)? {
            Attempt::Done => {
                println!("{name}: passed in attempt {k}");
                return Ok(());
            }
            Attempt::Disturbed(r) => {
                println!("{name}: attempt {k} disturbed by the machine: {r}");
                why.push(r);
            }
        }
    }
    bail!("{name}: every attempt was disturbed by stalls of the machine: {why:#?}")
}

/// The set-up of a drive named `name` with [`SCENARIO_TOML`].
pub fn setup(name: &str) -> anyhow::Result<Setup> {
    setup_with(name, SCENARIO_TOML)
}

/// The set-up of a drive named `name` with the scenario `scenario_toml`:
/// its output folder, the configuration overlay, the scenario file.
pub fn setup_with(name: &str, scenario_toml: &str) -> anyhow::Result<Setup> {
    let iface = hil::vcan_iface();
    hil::require_can_iface(&iface)?;
    hil::require_alsa_loopback()?;
    let out = hil::out_dir(name)?;
    let scenario_path = out.join("hil-scenario.toml");
    std::fs::write(&scenario_path, scenario_toml)?;
    let config = hil::hil_config_dir(
        &out.join("config"),
        &HilConfig {
            iface: iface.clone(),
            capture_device: CAPTURE.into(),
        },
    )?;
    Ok(Setup {
        out,
        config,
        scenario: scenario_path.display().to_string(),
        iface,
        dbc: Dbc::inverter()?,
    })
}

pub fn instance(tag: &str) -> String {
    format!(
        "hil-{tag}-{}-{:x}",
        std::process::id(),
        hil::mono_ns() & 0xffff_ffff
    )
}

/// A `grip drive` of `s` logging to `mcap`, with the road-audio player on
/// [`PLAYBACK`] and an independent capture of the bus around it. `during`
/// gets the running drive and must wait for its end (e.g. with
/// [`wait_success`]); the capture and the player are finished whatever it
/// returns. Gives what `during` returned, the capture and the finished
/// drive (its output for the report).
pub fn drive_with<T>(
    s: &Setup,
    mcap: &Path,
    during: impl FnOnce(&mut Proc) -> anyhow::Result<T>,
) -> anyhow::Result<(T, CaptureLog, Proc)> {
    let cap = CanCapture::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let mut drive = grip_drive(s, mcap)?;
    let res = during(&mut drive);
    let cap = cap.finish()?;
    player.finish()?;
    Ok((res?, cap, drive))
}

/// `grip --config-dir CONFIG drive --scenario e2e --out OUT` as a child.
pub fn grip_drive(s: &Setup, mcap: &Path) -> anyhow::Result<Proc> {
    let grip = hil::service_bin("grip")?;
    let cfg = s.config.display().to_string();
    let out = mcap.display().to_string();
    Proc::spawn_env(
        &grip,
        &[
            "--config-dir",
            &cfg,
            "drive",
            "--scenario",
            &s.scenario,
            "--out",
            &out,
        ],
        &[("NO_COLOR", "1")],
        "grip-drive",
        &s.out,
    )
}

/// Waits up to `limit` for `p` to exit and gives its exit status, whatever
/// it is (for a drive that must fail); not exiting in time is an error
/// with its output.
pub fn wait_exit(p: &mut Proc, what: &str, limit: Duration) -> anyhow::Result<ExitStatus> {
    match p.wait_timeout(limit)? {
        Some(st) => Ok(st),
        None => bail!("{what} did not finish within {limit:?}:\n{}", p.log_text()),
    }
}

/// [`wait_exit`], and the exit status must be success.
pub fn wait_success(p: &mut Proc, what: &str, limit: Duration) -> anyhow::Result<()> {
    let st = wait_exit(p, what, limit)?;
    ensure!(st.success(), "{what} failed ({st}):\n{}", p.log_text());
    Ok(())
}

/// A raw socket that sees only `ids` (standard frames).
pub fn raw_socket(iface: &str, ids: &[u32]) -> anyhow::Result<RawCanSocket> {
    let s = RawCanSocket::open(iface)?;
    let m = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
    s.set_filters(&ids.iter().map(|&i| (i, m)).collect::<Vec<_>>())?;
    Ok(s)
}

/// Waits until plant-sim runs the scenario (its DriverDemand carries a demand).
pub fn wait_scenario_start(s: &Setup) -> anyhow::Result<Captured> {
    let dd = s.dbc.by_name("DriverDemand")?.clone();
    let sock = raw_socket(&s.iface, &[dd.id])?;
    hil::wait_for_frame(&sock, dd.id, Duration::from_secs(120), |d| {
        dd.crc_ok(d) && dd.value("TorqueDemand", d) > 0.05
    })
    .context("the scenario did not start (no DriverDemand with a demand on the bus)")
}

// --- the MCAP --------------------------------------------------------------------

pub struct Log {
    pub cycles: Vec<CycleRecord>,
    pub truth: Vec<GroundTruth>,
    pub roads: Vec<grip_msgs::RoadEstimate>,
    pub audio: Vec<(u64, f64)>,
    pub recorder: MetadataMap,
    /// The CAN log (`grip/can/log`) in log order.
    pub can: Vec<grip_msgs::CanFrame>,
    /// The recorder's bus log (`grip/can/bus`) in log order.
    pub bus: Vec<grip_msgs::BusFrame>,
}

/// Reads a drive's MCAP and checks it is complete: not truncated, no bad
/// message, contiguous cycle and truth sequence numbers, the recorder's
/// summary written with nothing lost between the services and the file.
pub fn read_complete(path: &Path) -> anyhow::Result<Log> {
    read_checked(path, AudioGaps::No)
}

/// Which audio blocks the recorder may have missed (by sequence number).
#[derive(Debug, Clone, Copy)]
enum AudioGaps {
    No,
    IfXruns,
    Because(&'static str),
}

/// [`read_complete`], audio blocks the recorder missed allowed (printed)
/// for the reason `why`, e.g. a fault that stalls a peer of the audio topic.
pub fn read_complete_allowing_audio_gaps(path: &Path, why: &'static str) -> anyhow::Result<Log> {
    read_checked(path, AudioGaps::Because(why))
}

/// [`read_complete`], but audio blocks missing by sequence number are
/// allowed when the blocks report capture overruns (audio-acq drops the
/// block an overrun broke, and under emulation an overrun is a scheduling
/// event): for drives whose fault is not the audio's. Printed.
pub fn read_complete_allowing_xruns(path: &Path) -> anyhow::Result<Log> {
    read_checked(path, AudioGaps::IfXruns)
}

fn read_checked(path: &Path, audio_gaps: AudioGaps) -> anyhow::Result<Log> {
    let log = DriveLog::load_with(path, LoadOptions { audio: true })?;
    let rep = &log.report;
    ensure!(
        rep.truncated.is_none(),
        "{}: truncated: {rep:?}",
        path.display()
    );
    ensure!(
        rep.bad == 0,
        "{}: undecodable messages: {rep:?}",
        path.display()
    );
    let xruns = log.audio.xruns;
    let l = Log {
        audio: log
            .audio_blocks
            .iter()
            .map(|a| {
                let n = (a.n_samples as usize).min(a.samples.len());
                (a.stamp_ns, hil::rms(&a.samples[..n]))
            })
            .collect(),
        recorder: log
            .recorder
            .context("no grip.recorder summary: the recorder did not finish the log")?,
        cycles: log.cycles,
        can: log.can,
        bus: log.bus,
        truth: log.truth,
        roads: log.roads,
    };
    ensure!(!l.cycles.is_empty(), "no cycle records");
    ensure!(!l.truth.is_empty(), "no ground truth");
    for (what, seqs) in [
        ("cycle", l.cycles.iter().map(|c| c.seq).collect::<Vec<_>>()),
        ("truth", l.truth.iter().map(|t| t.seq).collect()),
    ] {
        if let Some(w) = seqs.windows(2).find(|w| w[1] != w[0] + 1) {
            bail!(
                "{}: {what} sequence not contiguous: {} then {}",
                path.display(),
                w[0],
                w[1]
            );
        }
    }
    let meta = |t: &str, k: &str| -> anyhow::Result<u64> {
        l.recorder
            .get(&format!("{t}.{k}"))
            .with_context(|| format!("recorder summary lacks {t}.{k}"))?
            .parse()
            .with_context(|| format!("{t}.{k}"))
    };
    for (t, _) in topics::ALL {
        ensure!(
            meta(t, "received")? == meta(t, "written")?,
            "{t}: the recorder received more than it wrote"
        );
        ensure!(meta(t, "queue_dropped")? == 0, "{t}: recorder queue drops");
        ensure!(
            meta(t, "receive_errors")? == 0,
            "{t}: recorder receive errors"
        );
    }
    for t in [topics::CYCLE, topics::TRUTH, topics::AUDIO] {
        let gaps = meta(t, "seq_gaps")?;
        if t == topics::AUDIO && gaps > 0 {
            match audio_gaps {
                AudioGaps::IfXruns if xruns > 0 => {
                    println!("{t}: {gaps} blocks missing, with {xruns} capture overruns reported");
                    continue;
                }
                AudioGaps::Because(why) => {
                    println!("{t}: the recorder missed {gaps} blocks ({why})");
                    continue;
                }
                _ => {}
            }
        }
        ensure!(gaps == 0, "{t}: {gaps} sequence gaps seen by the recorder");
    }
    println!(
        "{}: complete: {} cycles (seq {}..={}), {} truth, {} audio blocks, {} road estimates",
        path.display(),
        l.cycles.len(),
        l.cycles[0].seq,
        l.cycles[l.cycles.len() - 1].seq,
        l.truth.len(),
        l.audio.len(),
        l.roads.len()
    );
    Ok(l)
}

/// Every frame on the bus is known, of the DBC's length, with a valid CRC
/// and counter, and the capture lost nothing.
pub fn check_all_frames_valid(cap: &CaptureLog, dbc: &Dbc) -> anyhow::Result<StreamCheck> {
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );
    let c = StreamCheck::run(dbc, &cap.frames);
    println!(
        "frames on the bus: {:?} (frames, bad DLC, bad CRC, counter breaks)",
        c.per_message
    );
    ensure!(c.all_valid(), "invalid frames on the bus: {:#?}", c);
    Ok(c)
}

pub fn sig(dbc: &Dbc, msg: &str, name: &str, f: &Captured) -> f64 {
    dbc.by_name(msg)
        .map_or(f64::NAN, |m| m.value(name, &f.data8()))
}
pub fn cansend(iface: &str, id: u32, data: &[u8]) -> anyhow::Result<()> {
    let hex: String = data.iter().map(|b| format!("{b:02X}")).collect();
    let arg = format!("{id:03X}#{hex}");
    let st = Command::new(hil::tool("cansend")?)
        .args([iface, &arg])
        .status()?;
    ensure!(st.success(), "cansend {iface} {arg}: {st}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configuration_figures_are_read_with_their_units_and_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let c = dir.path();
        std::fs::write(
            c.join("a.toml"),
            "top = 7\n[arte]\nmax_age_s = 0.3\nname = \"x\"\n",
        )
        .unwrap();
        assert_eq!(config_number(c, "a.toml", "top").unwrap(), 7.0);
        assert_eq!(config_number(c, "a.toml", "arte.max_age_s").unwrap(), 0.3);
        let e = format!("{:#}", config_number(c, "a.toml", "arte.nope").unwrap_err());
        assert!(e.contains("a.toml") && e.contains("arte.nope"), "{e}");
        let e = format!("{:#}", config_number(c, "a.toml", "arte.name").unwrap_err());
        assert!(e.contains("not a number"), "{e}");
        assert!(config_number(c, "missing.toml", "top").is_err());

        std::fs::create_dir(c.join("systemd")).unwrap();
        for (value, want) in [
            ("1s", 1000.0),
            ("500ms", 500.0),
            ("2", 2000.0),
            ("1.5min", 90e3),
        ] {
            std::fs::write(
                c.join("systemd/u.service"),
                format!("[Service]\nRestart=always\nRestartSec={value}\n"),
            )
            .unwrap();
            assert_eq!(
                unit_setting_ms(c, "u.service", "RestartSec").unwrap(),
                want,
                "{value}"
            );
        }
        std::fs::write(c.join("systemd/u.service"), "RestartSec=3h\n").unwrap();
        let e = format!(
            "{:#}",
            unit_setting_ms(c, "u.service", "RestartSec").unwrap_err()
        );
        assert!(
            e.contains("u.service") && e.contains("not understood"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            unit_setting_ms(c, "u.service", "WatchdogSec").unwrap_err()
        );
        assert!(e.contains("no WatchdogSec="), "{e}");
    }

    #[test]
    fn the_shipped_configuration_has_every_figure_the_fault_matrix_reads() {
        let c = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        assert!(config_number(&c, "tcs-loop.toml", "safety.recover_ms").unwrap() > 0.0);
        assert!(config_number(&c, "controllers.toml", "arte.max_age_s").unwrap() > 0.0);
        assert!(config_number(&c, "recorder.toml", "flush_interval_ms").unwrap() > 0.0);
        assert!(unit_setting_ms(&c, "grip-recorder.service", "RestartSec").unwrap() > 0.0);
    }
}
