//! The HIL fault matrix: one fault during a drive of all five services on
//! the kernel's `vcan0` with ALSA-loopback audio, each with an assertion of
//! its outcome. Run by `tools/hil/run` (natively or in its VM); the set-up,
//! the retry rule for drives a stall of the emulated machine disturbed and
//! the MCAP read-back are `grip_tests::hil_drives`, shared with
//! `tests/hil_drive.rs`.
//!
//! 1. `bus_flood_keeps_the_loop_on_time`: `cangen` at full rate on `vcan0`,
//!    first with a foreign id (filtered out below tcs-loop: not one
//!    reaches it), then with WheelSpeeds' id and a bad CRC (counted).
//! 2. `bus_down_and_up_gives_safe_state_and_recovery`: `vcan0` set down for
//!    300 ms and up again.
//!    `bus_deleted_and_recreated_recovers`: `vcan0` deleted for 300 ms
//!    and re-created (an adapter unplugged and plugged back): the
//!    services' sockets reopen on the new interface.
//!    `bus_deleted_for_good_fails_the_drive`: `vcan0` deleted and not
//!    re-created until `grip drive` has ended: the loop in its safe state
//!    to the end, and `grip drive` exits non-zero for the lost control
//!    (`grip inspect` prints the same statement and exits 0).
//! 3. `killed_recorder_loses_at_most_a_second`: `kill -9` of the recorder,
//!    then a new recorder writing a new file.
//! 4. `full_disk_stops_the_recorder_not_the_loop`: the recorder's file on a
//!    small tmpfs that fills mid-drive.
//! 5. `microphone_faults_make_the_controller_fall_back`: silence, clipping
//!    and an xrun storm on the loopback.
//! 6. `stalled_arte_ages_out_and_returns`: arte `SIGSTOP`ped for 2 s.
//!
//! Bounds are the protocol's or the configuration's figures plus the
//! suite's [`VM_MARGIN_MS`] (the VM is for function, not deadlines); the
//! measured figures are printed (`--nocapture`) and `tools/hil/README.md`
//! lists them ("Fault matrix").

use std::path::Path;
use std::process::{Command, ExitStatus};
use std::time::Duration;

use anyhow::{Context, bail, ensure};
use grip_drive::summary::CONTROL_LOST_MIN_S;
use grip_drive::{DriveLog, LoadOptions, Supervisor};
use grip_msgs::{CycleRecord, NO_CLASS, can_dir};
use grip_tests::hil::{
    self, CAN_EFF_FLAG, CAN_INV_FILTER, CAN_RTR_FLAG, CAN_SFF_MASK, CanCapture, CaptureLog,
    FrameCounter, MicFault, MicFaultKind, Proc, RoadAudioPlayer, StreamCheck,
};
use grip_tests::hil_drives::{
    Attempt, PLAYBACK, SENSOR_TIMEOUT_MS, Setup, VM_MARGIN_MS, asphalt_scenario, config_number,
    drive_with, grip_drive, instance, ms, ns, read_complete_allowing_audio_gaps,
    read_complete_allowing_xruns, serial, unit_setting_ms, wait_exit, wait_scenario_start,
    wait_success, with_attempts_in,
};
use grip_tests::wire_check::{
    LoopLog, enabled_commands, input_gaps, loop_unaffected, sensor_gap_ms,
};

/// Figures of the configuration the services run with, read from it (not
/// copied: a configuration change moves the bounds with it).
struct Figures {
    /// tcs-loop's `[safety] recover_ms` (tcs-loop.toml): valid inputs for
    /// this long before it leaves the safe state.
    recover_ms: f64,
    /// `[arte] max_age_s` of controllers.toml, in ms: older road knowledge
    /// is not used.
    max_age_ms: f64,
    /// The recorder unit's `RestartSec=` (systemd/grip-recorder.service):
    /// when the test starts the new recorder after the kill, ms.
    restart_ms: f64,
    /// The recorder's `flush_interval_ms` (recorder.toml).
    flush_ms: f64,
}

impl Figures {
    fn of(s: &Setup) -> anyhow::Result<Self> {
        let c = &s.config;
        Ok(Self {
            recover_ms: config_number(c, "tcs-loop.toml", "safety.recover_ms")?,
            max_age_ms: 1e3 * config_number(c, "controllers.toml", "arte.max_age_s")?,
            restart_ms: unit_setting_ms(c, "grip-recorder.service", "RestartSec")?,
            flush_ms: config_number(c, "recorder.toml", "flush_interval_ms")?,
        })
    }
}

/// What a recorder crash may lose at most (issue 13: "at most 1 s of
/// messages lost"): the flush interval plus the writer's lag behind the
/// loops.
const LOST_MAX_MS: f64 = 1000.0;

fn sd_mask() -> u32 {
    CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK
}

/// `key=N` from a service's log text (its stop line), the last one.
fn log_value(text: &str, key: &str) -> Option<u64> {
    let pat = format!("{key}=");
    text.split_whitespace()
        .filter_map(|w| w.strip_prefix(&pat))
        .filter_map(|v| v.trim_end_matches(',').parse().ok())
        .next_back()
}

/// Cycles with stamps in `[t0, t1)`.
fn cycles_in(cycles: &[CycleRecord], t0: u64, t1: u64) -> Vec<&CycleRecord> {
    cycles
        .iter()
        .filter(|c| c.stamp_ns >= t0 && c.stamp_ns < t1)
        .collect()
}

/// Each stopped service's name and exit status.
type Statuses = Vec<(String, ExitStatus)>;
/// A captured audio block: start and end (ns), silent, clipped, its xruns.
type Block = (u64, u64, bool, bool, u32);

// --- 1. bus flood ------------------------------------------------------------------------

/// A foreign id for the flood: not in the DBC.
const FOREIGN_ID: u32 = 0x5A5;
/// How long each flood lasts.
const FLOOD_MS: u64 = 1000;
/// The window before each flood its deadline misses are compared with.
const QUIET_MS: f64 = 700.0;

#[test]
fn bus_flood_keeps_the_loop_on_time() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("flood", &asphalt_scenario(5), flood)
}

/// `cangen IFACE -g 0 -I ID -L 8 -D DATA -p 10` (full rate: no gap; on
/// `ENOBUFS`, a full socket send buffer, it waits up to 10 ms for room
/// instead of exiting) for `len`.
fn cangen(s: &Setup, id: u32, data: &[u8; 8], len: Duration) -> anyhow::Result<(u64, u64)> {
    let hex: String = data.iter().map(|b| format!("{b:02X}")).collect();
    let idh = format!("{id:03X}");
    let mut p = Proc::spawn(
        &hil::tool("cangen")?,
        &[
            &s.iface, "-g", "0", "-I", &idh, "-L", "8", "-D", &hex, "-p", "10",
        ],
        &format!("cangen-{idh}"),
        &s.out,
    )?;
    let t0 = hil::mono_ns();
    std::thread::sleep(len);
    p.signal(libc::SIGINT)?;
    let t1 = hil::mono_ns();
    match p.wait_timeout(Duration::from_secs(10))? {
        Some(_) => {}
        None => bail!("cangen did not stop on SIGINT:\n{}", p.log_text()),
    }
    Ok((t0, t1))
}

fn flood(s: &Setup) -> anyhow::Result<Attempt> {
    ensure!(
        s.dbc.by_id(FOREIGN_ID).is_none(),
        "{FOREIGN_ID:#x} is in the DBC"
    );
    let mcap = s.out.join("drive.mcap");
    let ws = s.dbc.by_name("WheelSpeeds")?.clone();
    // a WheelSpeeds payload with a wrong CRC (every flood frame the same)
    let mut bad = ws.encode(
        &[
            ("DrivenValid", 1.0),
            ("RefValid", 1.0),
            ("OmegaDriven", 300.0),
            ("OmegaRef", 300.0),
        ],
        0,
    )?;
    bad[0] = ws.expected_crc(&bad) ^ 0x5A;
    ensure!(bad[0] != ws.expected_crc(&bad), "bad CRC is good");
    // everything but the foreign flood is recorded; the foreign one counted
    let cap = CanCapture::start_filtered(&s.iface, &[(FOREIGN_ID | CAN_INV_FILTER, sd_mask())])?;
    let foreign = FrameCounter::start(&s.iface, &[(FOREIGN_ID, sd_mask())])?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let mut drive = grip_drive(s, &mcap)?;
    let run = |drive: &mut Proc| -> anyhow::Result<[(u64, u64); 2]> {
        wait_scenario_start(s)?;
        std::thread::sleep(Duration::from_millis(800));
        let a = cangen(
            s,
            FOREIGN_ID,
            &[0xF0, 0x0D, 0, 1, 2, 3, 4, 5],
            Duration::from_millis(FLOOD_MS),
        )?;
        std::thread::sleep(Duration::from_millis(800));
        let b = cangen(s, ws.id, &bad, Duration::from_millis(FLOOD_MS))?;
        wait_success(drive, "grip drive", Duration::from_secs(180))?;
        Ok([a, b])
    };
    let res = run(&mut drive);
    let cap = cap.finish()?;
    let foreign = foreign.finish()?;
    player.finish()?;
    let [fa, fb] = res?;
    println!("grip drive output:\n{}", drive.log_text());
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );

    // the floods: how many frames, how fast
    let n_bad = cap.with_id(ws.id).filter(|f| f.frame.data == bad).count() as u64;
    let rate = |n: u64, (t0, t1): (u64, u64)| n as f64 / ((t1 - t0) as f64 * 1e-9);
    println!(
        "flood 1: {} frames of foreign id {FOREIGN_ID:#x} ({} read, {} dropped by the counting socket), {:.0} frames/s",
        foreign.total(),
        foreign.received,
        foreign.dropped,
        rate(foreign.total(), fa)
    );
    println!(
        "flood 2: {n_bad} WheelSpeeds with a bad CRC, {:.0} frames/s (the bus's own traffic: 3200 frames/s)",
        rate(n_bad, fb)
    );
    // "full rate" is what cangen manages with no gap: under emulation a
    // few hundred to a few thousand frames/s (printed above)
    for (what, n) in [("foreign", foreign.total()), ("bad-CRC", n_bad)] {
        ensure!(n >= 100, "the {what} flood put only {n} frames on the bus");
    }

    let l = read_complete_allowing_xruns(&mcap)?;
    // every frame on the wire but the injected ones is valid
    let c = StreamCheck::run(&s.dbc, &cap.frames);
    println!(
        "frames on the bus: {:?} (frames, bad DLC, bad CRC, counter breaks)",
        c.per_message
    );
    let get = |m: &str| c.per_message.get(m).copied().unwrap_or_default();
    ensure!(get("WheelSpeeds")[2] == n_bad, "{:?}", get("WheelSpeeds"));
    for m in [
        "TorqueCommand",
        "MotorStatus",
        "VehicleSpeed",
        "DriverDemand",
    ] {
        ensure!(get(m)[1..].iter().all(|&x| x == 0), "{m}: {:?}", get(m));
    }
    // no command lost: one TorqueCommand per cycle record (+ the shutdown
    // frame), their alive counters without a break
    let n_cmd = get("TorqueCommand")[0];
    ensure!(
        l.cycles[0].seq == 0,
        "the log starts at cycle {}",
        l.cycles[0].seq
    );
    println!(
        "TorqueCommands on the wire {n_cmd}, cycle records {} (+1 shutdown frame)",
        l.cycles.len()
    );
    ensure!(
        n_cmd == l.cycles.len() as u64 + 1,
        "{n_cmd} TorqueCommands on the wire for {} cycles: commands lost",
        l.cycles.len()
    );

    // faults counted, cycles on time, the loop controlling
    for (what, (t0, t1), field) in [("foreign", fa, 0usize), ("bad-CRC", fb, 1)] {
        let before = l
            .cycles
            .iter()
            .rev()
            .find(|c| c.stamp_ns < t0)
            .context("no cycle before the flood")?;
        let after = l
            .cycles
            .iter()
            .find(|c| c.stamp_ns > t1 + 200_000_000)
            .context("no cycle 200 ms after the flood")?;
        let (b, a) = (before.faults, after.faults);
        let (counted, injected) = if field == 0 {
            (a.unknown_id - b.unknown_id, foreign.total())
        } else {
            (a.crc - b.crc, n_bad)
        };
        let win = cycles_in(&l.cycles, t0, t1 + 50_000_000);
        ensure!(
            win.len() > 10,
            "{what} flood: only {} cycle records in it",
            win.len()
        );
        let misses = win[win.len() - 1].deadline_misses - win[0].deadline_misses;
        let late = win.iter().map(|c| c.wakeup_latency_ns).max().unwrap_or(0) as f64 / 1e6;
        // the same drive without a flood: the QUIET_MS before it
        let quiet = cycles_in(&l.cycles, t0.saturating_sub(ns(QUIET_MS)), t0);
        ensure!(
            quiet.len() > 10,
            "{what} flood: only {} cycle records before it",
            quiet.len()
        );
        let quiet_misses = quiet[quiet.len() - 1].deadline_misses - quiet[0].deadline_misses;
        let share = misses as f64 / win.len() as f64;
        let quiet_share = quiet_misses as f64 / quiet.len() as f64;
        let bound = (2.0 * quiet_share + 0.05).max(0.10);
        println!(
            "{what} flood: tcs-loop counted {counted} of {injected} frames as faults ({:.1} %); {} cycles, {misses} deadline misses ({:.1} %; {:.1} % in the {QUIET_MS} ms before it, bound {:.1} %), latest wake-up {late:.2} ms",
            100.0 * counted as f64 / injected.max(1) as f64,
            win.len(),
            100.0 * share,
            100.0 * quiet_share,
            100.0 * bound
        );
        if field == 0 {
            // tcs-loop's bus receives only the ids it consumes (the
            // kernel's CAN_RAW_FILTER): the foreign flood never reaches it
            ensure!(
                counted == 0,
                "{what} flood: {counted} of {injected} foreign frames reached tcs-loop through its receive filter"
            );
        } else {
            ensure!(counted > 0, "{what} flood: no fault counted");
            ensure!(
                u64::from(counted) <= injected,
                "{what} flood: {counted} faults counted for {injected} frames"
            );
        }
        ensure!(
            late <= VM_MARGIN_MS,
            "{what} flood: a cycle woke {late:.1} ms late, bound {VM_MARGIN_MS} ms"
        );
        // under emulation the loop misses deadlines without a flood too (a
        // 1 kHz SCHED_FIFO loop on a TCG vCPU): the flood may not make that
        // more than twice as frequent (+5 points), nor above 10 % where the
        // loop kept its deadlines before. The share before a flood ranges
        // 10-47 % between drives on one quiet host, so a drive over the
        // bound is run again (up to ATTEMPTS); one within it must be found
        if share > bound {
            return Ok(Attempt::Disturbed(format!(
                "{what} flood: {misses} deadline misses in {} cycles ({:.1} %), bound {:.1} % (twice the {:.1} % of the {QUIET_MS} ms before it + 5 points, at least 10 %)",
                win.len(),
                100.0 * share,
                100.0 * bound,
                100.0 * quiet_share
            )));
        }
        // the drive's whole log: what tcs-loop read and when (a flood loads
        // the kernel's network processing, which may deliver frames late)
        let own = LoopLog {
            can: &l.can,
            cycles: &l.cycles,
        };
        if let Some(r) =
            loop_unaffected(&cap, &s.dbc, Some(&own), t0, t1, &format!("{what} flood"))?
        {
            return Ok(Attempt::Disturbed(r));
        }
    }
    Ok(Attempt::Done)
}

// --- 2. bus down and up --------------------------------------------------------------------

/// How long `vcan0` stays down.
const DOWN_MS: u64 = 300;

#[test]
fn bus_down_and_up_gives_safe_state_and_recovery() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("bus-down", &asphalt_scenario(4), bus_down)
}

fn bus_down(s: &Setup) -> anyhow::Result<Attempt> {
    let fig = Figures::of(s)?;
    let mcap = s.out.join("drive.mcap");
    let ((t_down, t_up), cap, drive) =
        drive_with(s, &mcap, |drive| -> anyhow::Result<(u64, u64)> {
            wait_scenario_start(s)?;
            std::thread::sleep(Duration::from_millis(1000));
            let r = hil::set_link_up(&s.iface, false);
            // once the interface is down (the ioctl may take a while under emulation)
            let t_down = hil::mono_ns();
            std::thread::sleep(Duration::from_millis(DOWN_MS));
            let t_up = hil::mono_ns();
            // up again whatever happened
            hil::set_link_up(&s.iface, true)?;
            r?;
            wait_success(drive, "grip drive", Duration::from_secs(180))?;
            Ok((t_down, t_up))
        })?;
    println!("grip drive output:\n{}", drive.log_text());
    hil::require_can_iface(&s.iface)?;
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );

    // the wire: nothing while down, every frame valid; each message's alive
    // counter breaks at most once (the frames its sender could not send)
    ensure!(
        !cap.frames
            .iter()
            .any(|f| f.t_ns > t_down + 1_000_000 && f.t_ns < t_up),
        "frames on the wire while {} was down",
        s.iface
    );
    let c = StreamCheck::run(&s.dbc, &cap.frames);
    println!(
        "frames on the bus: {:?} (frames, bad DLC, bad CRC, counter breaks)",
        c.per_message
    );
    ensure!(c.unknown == 0, "unknown ids on the wire: {}", c.unknown);
    for (m, v) in &c.per_message {
        ensure!(v[1] == 0 && v[2] == 0 && v[3] <= 1, "{m}: {v:?}");
    }

    let l = read_complete_allowing_xruns(&mcap)?;
    let ws_id = s.dbc.by_name("WheelSpeeds")?.id;
    // precondition: the loop was controlling just before
    let before = cycles_in(&l.cycles, t_down - 30_000_000, t_down);
    if before.is_empty() || before.iter().any(|c| c.safe_state == 1) {
        return Ok(Attempt::Disturbed(format!(
            "tcs-loop was not controlling in the 30 ms before the bus went down ({} cycles)",
            before.len()
        )));
    }
    // the gap in the log: tcs-loop's received frames (CAN log, RX) stop
    let rx_ws: Vec<u64> = l
        .can
        .iter()
        .filter(|f| f.direction == can_dir::RX && f.id == ws_id)
        .map(|f| f.stamp_ns)
        .collect();
    // The CAN log stamps a received frame with the kernel's receive time
    // (since 2026-12-07; before, with the time tcs-loop read it, so that a
    // frame already in its socket when the link went down was stamped up to
    // the suite's margin later): the last one before the down arrived
    // before `t_down`, read after the ioctl returned; 1 ms allowed, as for
    // the wire above, for the stamp's move from CLOCK_REALTIME.
    let arrived_by = t_down + 1_000_000;
    let last_rx = rx_ws
        .iter()
        .copied()
        .filter(|&t| t <= arrived_by)
        .max()
        .context("no WheelSpeeds received before the bus went down")?;
    let back_rx = rx_ws
        .iter()
        .copied()
        .find(|&t| t > last_rx)
        .context("tcs-loop never received WheelSpeeds again after the bus came up")?;
    let gap = ms(back_rx as i128 - last_rx as i128);
    println!(
        "bus down {:.0} ms; the CAN log's received WheelSpeeds pause {gap:.0} ms ({:.1} ms before the down .. {:.1} ms after the up)",
        ms(t_up as i128 - t_down as i128),
        ms(t_down as i128 - last_rx as i128),
        ms(back_rx as i128 - t_up as i128)
    );
    ensure!(
        back_rx >= t_up,
        "tcs-loop received WheelSpeeds while the bus was down"
    );
    // the cycles went on through the gap, in the safe state: at least half
    // as often as in the second before it (under emulation the loop runs
    // well below its 1 kHz: a ratio within the drive, not a rate)
    let during = cycles_in(&l.cycles, last_rx, back_rx);
    let before = cycles_in(&l.cycles, last_rx.saturating_sub(1_000_000_000), last_rx);
    let rate_before = before.len() as f64 / 1000.0;
    println!(
        "{} cycle records during the {gap:.0} ms gap ({:.2} per ms; {:.2} per ms in the second before it)",
        during.len(),
        during.len() as f64 / gap,
        rate_before
    );
    ensure!(
        during.len() as f64 >= 0.5 * rate_before * gap,
        "only {} cycle records during the {gap:.0} ms gap: under half the loop's rate of the second before it ({rate_before:.2} per ms)",
        during.len()
    );
    let first_safe = during
        .iter()
        .find(|c| c.safe_state == 1)
        .context("tcs-loop never entered its safe state while the bus was down")?;
    let safe_ms = ms(first_safe.stamp_ns as i128 - last_rx as i128);
    let bound = SENSOR_TIMEOUT_MS + VM_MARGIN_MS;
    println!(
        "safe state {safe_ms:.1} ms after the last WheelSpeeds (timeout {SENSOR_TIMEOUT_MS} ms, bound {bound} ms)"
    );
    ensure!(
        safe_ms <= bound,
        "safe state {safe_ms:.1} ms after the last frame, bound {bound} ms"
    );
    ensure!(
        during
            .iter()
            .filter(|c| c.stamp_ns >= first_safe.stamp_ns)
            .all(|c| c.safe_state == 1 && c.torque_cmd == 0.0),
        "a cycle left the safe state or commanded torque while the bus was down"
    );
    ensure!(
        first_safe.faults.timeout >= 1,
        "the sensor timeout was not counted"
    );
    // recovery: recover_ms of valid inputs after the frames came back
    let Some(rec) = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns > back_rx && c.safe_state == 0)
    else {
        let clean = sensor_gap_ms(&cap, &s.dbc, t_up, t_up + 500_000_000)?;
        if clean >= SENSOR_TIMEOUT_MS {
            return Ok(Attempt::Disturbed(format!(
                "after the bus came up the sensor frames paused {clean:.1} ms (a stall)"
            )));
        }
        bail!("tcs-loop never left its safe state after the bus came up");
    };
    let rec_ms = ms(rec.stamp_ns as i128 - back_rx as i128);
    let rbound = fig.recover_ms + VM_MARGIN_MS;
    println!(
        "control again {rec_ms:.1} ms after the first WheelSpeeds back (recover_ms {}, bound {rbound} ms)",
        fig.recover_ms
    );
    ensure!(
        rec_ms >= fig.recover_ms - 2.0,
        "tcs-loop left its safe state {rec_ms:.1} ms after the frames came back, before recover_ms {}",
        fig.recover_ms
    );
    if rec_ms > rbound {
        let clean = sensor_gap_ms(&cap, &s.dbc, back_rx, rec.stamp_ns)?;
        if clean >= SENSOR_TIMEOUT_MS {
            return Ok(Attempt::Disturbed(format!(
                "recovery {rec_ms:.1} ms, but the sensor frames paused {clean:.1} ms after the bus came up"
            )));
        }
        bail!("recovery {rec_ms:.1} ms after the frames came back, bound {rbound} ms");
    }
    Ok(Attempt::Done)
}

// --- 2b. bus deleted and re-created -----------------------------------------------------

/// How long `vcan0` stays deleted.
const GONE_MS: u64 = 300;
/// After the interface is back: the services' reopen check (every 100 ms)
/// plus `recover_ms`, with the suite's margins, must fit in well under this.
const BACK_WITHIN_MS: f64 = 1000.0;

/// `vcan0` deleted (`ip link del`, as unplugging a USB-CAN adapter) and
/// re-created under the same name mid-drive: tcs-loop's and plant-sim's
/// sockets, bound to the old interface, are unbound by the kernel; both
/// must reopen theirs on the new one and the loop must control again. The
/// recorder's bus monitor (`recorder.toml` `bus`) must survive it and
/// reopen too.
#[test]
fn bus_deleted_and_recreated_recovers() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("bus-recreated", &asphalt_scenario(5), bus_recreated)
}

fn bus_recreated(s: &Setup) -> anyhow::Result<Attempt> {
    let fig = Figures::of(s)?;
    let mcap = s.out.join("drive.mcap");
    // the capture's socket dies with the interface: a second one records
    // the re-created vcan0
    let ((t_del, t_back, after), _cap_before, drive) = drive_with(
        s,
        &mcap,
        |drive| -> anyhow::Result<(u64, u64, CaptureLog)> {
            wait_scenario_start(s)?;
            std::thread::sleep(Duration::from_millis(1000));
            let t_del = hil::mono_ns();
            hil::delete_vcan(&s.iface)?;
            std::thread::sleep(Duration::from_millis(GONE_MS));
            hil::create_vcan(&s.iface)?;
            let t_back = hil::mono_ns();
            let cap = hil::CanCapture::start(&s.iface)?;
            wait_success(drive, "grip drive", Duration::from_secs(180))?;
            Ok((t_del, t_back, cap.finish()?))
        },
    )?;
    let text = drive.log_text();
    println!("grip drive output:\n{text}");
    hil::require_can_iface(&s.iface)?;
    for l in text.lines().filter(|l| {
        l.contains("stopped")
            || l.contains("reopen")
            || l.contains("vanished")
            || l.contains("INTERFACE GONE")
    }) {
        println!("> {l}");
    }
    let tc_id = s.dbc.by_name("TorqueCommand")?.id;
    let ws_id = s.dbc.by_name("WheelSpeeds")?.id;
    let first = |id: u32| after.with_id(id).map(|f| f.t_ns).min();
    let (tc_back, ws_back) = (first(tc_id), first(ws_id));
    println!(
        "vcan0 deleted for {:.0} ms; on the re-created vcan0: {} TorqueCommands (first {:?} ms after it was back), {} WheelSpeeds (first {:?} ms)",
        ms(t_back as i128 - t_del as i128),
        after.with_id(tc_id).count(),
        tc_back.map(|t| ms(t as i128 - t_back as i128)),
        after.with_id(ws_id).count(),
        ws_back.map(|t| ms(t as i128 - t_back as i128)),
    );
    let l = read_complete_allowing_xruns(&mcap)?;
    // the recorder's read-only bus monitor (its bus log) lost its socket
    // too: it went on recording (the log is complete) and reopened on the
    // new interface
    let bus_meta = |k: &str| -> anyhow::Result<u64> {
        let key = format!("{}.{k}", grip_msgs::topics::BUS);
        l.recorder
            .get(&key)
            .with_context(|| format!("recorder summary lacks {key}"))?
            .parse()
            .with_context(|| key.clone())
    };
    println!(
        "the recorder's bus monitor: {} reopens, {} read errors, {} frames read",
        bus_meta("reopens")?,
        bus_meta("receive_errors")?,
        bus_meta("received")?
    );
    ensure!(
        bus_meta("reopens")? >= 1,
        "the recorder's bus monitor did not reopen on the re-created vcan0"
    );
    let before = cycles_in(&l.cycles, t_del - 30_000_000, t_del);
    if before.is_empty() || before.iter().any(|c| c.safe_state == 1) {
        return Ok(Attempt::Disturbed(format!(
            "tcs-loop was not controlling in the 30 ms before vcan0 was deleted ({} cycles)",
            before.len()
        )));
    }
    let gone = cycles_in(&l.cycles, t_del, t_back);
    let last = l.cycles.last().map_or(0, |c| c.stamp_ns);
    let rec = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns > t_back && c.safe_state == 0);
    println!(
        "cycle records: {} while deleted (safe from {:?} ms after the delete), {} after it was back, the last {:.0} ms after; control again {:?} ms after it was back (recover_ms {})",
        gone.len(),
        gone.iter()
            .find(|c| c.safe_state == 1)
            .map(|c| ms(c.stamp_ns as i128 - t_del as i128)),
        cycles_in(&l.cycles, t_back, u64::MAX).len(),
        ms(last as i128 - t_back as i128),
        rec.map(|c| ms(c.stamp_ns as i128 - t_back as i128)),
        fig.recover_ms
    );
    // fail-safe while gone: safe state, 0 N m
    ensure!(
        gone.iter().any(|c| c.safe_state == 1),
        "tcs-loop never entered its safe state while vcan0 was deleted"
    );
    let tc_back = tc_back.context("no TorqueCommand from tcs-loop on the re-created vcan0")?;
    let ws_back = ws_back.context("no WheelSpeeds from plant-sim on the re-created vcan0")?;
    let rec = rec.context("tcs-loop never left its safe state after vcan0 was re-created")?;
    let (tc_ms, ws_ms) = (
        ms(tc_back as i128 - t_back as i128),
        ms(ws_back as i128 - t_back as i128),
    );
    ensure!(
        tc_ms <= BACK_WITHIN_MS && ws_ms <= BACK_WITHIN_MS,
        "frames back on the re-created vcan0 only {tc_ms:.0} ms (TorqueCommand) / {ws_ms:.0} ms (WheelSpeeds) after it, bound {BACK_WITHIN_MS} ms"
    );
    let rec_ms = ms(rec.stamp_ns as i128 - t_back as i128);
    ensure!(
        rec_ms <= BACK_WITHIN_MS + fig.recover_ms,
        "control again only {rec_ms:.0} ms after vcan0 was back"
    );
    // both services said their bus went and came back, in the same words
    // (their helpers' `grip_io::log_bus_presence!`; forwarded by `grip
    // drive` as `[NAME] ... ERROR/WARN ...`)
    for svc in ["tcs-loop", "plant-sim"] {
        let said = |what: &str| {
            text.lines()
                .any(|l| l.contains(&format!("[{svc}]")) && l.contains(what))
        };
        ensure!(
            said("CAN INTERFACE GONE") && said("CAN interface back: socket reopened"),
            "{svc} did not log its CAN interface gone and back"
        );
    }
    // the frames on the new bus are valid, the commands enabled again
    let c = StreamCheck::run(&s.dbc, &after.frames);
    println!("frames on the re-created bus: {:?}", c.per_message);
    ensure!(c.unknown == 0, "unknown ids on the wire: {}", c.unknown);
    for (m, v) in &c.per_message {
        ensure!(v[1] == 0 && v[2] == 0 && v[3] <= 1, "{m}: {v:?}");
    }
    ensure!(
        !enabled_commands(&after, &s.dbc)?.is_empty(),
        "no enabled TorqueCommand on the re-created vcan0"
    );
    Ok(Attempt::Done)
}

// --- 2c. bus deleted for good -------------------------------------------------------------

/// When `vcan0` is deleted, after the scenario start.
const GONE_AFTER_MS: u64 = 1000;

/// The scenario's length, s: the delete 1 s into it, then twice the
/// time out of control that fails a drive ([`CONTROL_LOST_MIN_S`]), and
/// 1 s for a stall of the emulated machine before the delete.
fn gone_for_good_scenario_s() -> u32 {
    (GONE_AFTER_MS as f64 / 1e3 + 2.0 * CONTROL_LOST_MIN_S).ceil() as u32 + 1
}

/// The summary's statement of a lost control with the safe state to the
/// end (`grip_drive::summary::ControlHealth::line`), up to its figures.
const LOST_IN_SAFE_STATE: &str = "CONTROL LOST AND NOT REGAINED: in the safe state from ";

/// The statements after `control: ` in a summary's text (one per summary).
fn control_lines(text: &str) -> Vec<&str> {
    text.lines()
        .filter_map(|l| l.trim_start().strip_prefix("control: "))
        .collect()
}

/// `vcan0` deleted mid-drive (an adapter unplugged) and not re-created
/// until `grip drive` has ended: tcs-loop sits in its safe state for the
/// rest of the scenario, and plant-sim, whose bus is gone too, runs the
/// scenario to its end on its own clock. The drive ends, every service
/// stops cleanly, and `grip drive` fails it after the summary, because
/// the loop lost control and did not regain it; `grip inspect` of the log
/// prints the same statement and exits 0. `vcan0` is re-created afterwards
/// whatever happens ([`hil::RestoreVcan`]).
#[test]
fn bus_deleted_for_good_fails_the_drive() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in(
        "bus-gone",
        &asphalt_scenario(gone_for_good_scenario_s()),
        bus_gone_for_good,
    )
}

fn bus_gone_for_good(s: &Setup) -> anyhow::Result<Attempt> {
    let mcap = s.out.join("drive.mcap");
    // before the delete: dropped on any return or panic, it re-creates vcan0
    let vcan = hil::RestoreVcan::new(&s.iface);
    let ((t_del, t_gone, status, t_exit), _cap, drive) = drive_with(
        s,
        &mcap,
        |drive| -> anyhow::Result<(u64, u64, ExitStatus, u64)> {
            wait_scenario_start(s)?;
            std::thread::sleep(Duration::from_millis(GONE_AFTER_MS));
            let t_del = hil::mono_ns();
            hil::delete_vcan(&s.iface)?;
            let t_gone = hil::mono_ns();
            // vcan0 stays deleted until grip drive has ended
            let st = wait_exit(drive, "grip drive", Duration::from_secs(180))?;
            Ok((t_del, t_gone, st, hil::mono_ns()))
        },
    )?;
    vcan.restore()?;
    let text = drive.log_text();
    println!("grip drive output:\n{text}");
    for l in text.lines().filter(|l| {
        l.contains("stopped")
            || l.contains("reopen")
            || l.contains("INTERFACE GONE")
            || l.contains("drive failed")
    }) {
        println!("> {l}");
    }
    let l = read_complete_allowing_xruns(&mcap)?;
    // precondition: the loop was controlling just before
    let before = cycles_in(&l.cycles, t_del - 30_000_000, t_del);
    if before.is_empty() || before.iter().any(|c| c.safe_state == 1) {
        return Ok(Attempt::Disturbed(format!(
            "tcs-loop was not controlling in the 30 ms before vcan0 was deleted ({} cycles)",
            before.len()
        )));
    }
    // the statement grip drive and grip inspect print, from the log by
    // their code
    let log = DriveLog::load_with(&mcap, LoadOptions::default())?;
    let (vehicle, from, _) = grip_drive::vehicle_for(&log, &s.config);
    let sum = grip_drive::summarize(&log, &vehicle, &from, None);
    let (ws, we) = sum.window_ns.context("the log has no scenario window")?;
    let health = sum
        .control
        .context("the summary has no control statement")?;
    let rel = |t: u64| ms(t as i128 - ws as i128) / 1e3;
    println!(
        "scenario window {:.3} s; vcan0 deleted at {:.3} s (`ip link del` took {:.1} ms), {:.3} s before the scenario's end; grip drive exited ({status}) {:.3} s after the delete, {:.3} s after the scenario's end",
        rel(we),
        rel(t_del),
        ms(t_gone as i128 - t_del as i128),
        ms(we as i128 - t_gone as i128) / 1e3,
        ms(t_exit as i128 - t_del as i128) / 1e3,
        ms(t_exit as i128 - we as i128) / 1e3,
    );
    // precondition: the delete early enough that the rule applies (a stall
    // before it could leave the loop less than the bound out of control)
    let left_ms = ms(we as i128 - t_gone as i128);
    if left_ms < 1e3 * CONTROL_LOST_MIN_S + SENSOR_TIMEOUT_MS + VM_MARGIN_MS {
        return Ok(Attempt::Disturbed(format!(
            "vcan0 was deleted only {left_ms:.0} ms before the scenario's end"
        )));
    }

    // 1. grip drive fails the drive, for the lost control: its control
    // error comes after a service failure's, so every service ran to the
    // end and stopped cleanly (plant-sim finished the scenario without
    // its bus)
    ensure!(
        !status.success(),
        "grip drive exited 0 although tcs-loop lost control and did not regain it"
    );
    ensure!(
        text.contains(&format!(
            "drive failed: tcs-loop's control during the scenario: {LOST_IN_SAFE_STATE}"
        )),
        "grip drive failed ({status}), but not for the lost control"
    );
    // 2. its summary's control line names the lost control, and why
    let drive_lines = control_lines(&text);
    println!("grip drive's summary: control: {drive_lines:?}");
    ensure!(
        drive_lines == [health.line().as_str()],
        "grip drive's control line(s) {drive_lines:?}, the log's statement {:?}",
        health.line()
    );
    ensure!(
        health.lost() && !health.never_in_control && health.end_records.1,
        "not control lost in the safe state to the end: {health:?}"
    );
    for want in [
        LOST_IN_SAFE_STATE,
        "input timeouts +",
        "tcs-loop received no CAN frame from then to the scenario's end",
    ] {
        ensure!(
            drive_lines[0].contains(want),
            "{want:?} not in grip drive's control line {:?}",
            drive_lines[0]
        );
    }
    // 3. the log: complete (above), the safe state from within the sensor
    // timeout of the delete to the log's end, 0 N m throughout
    let first_safe = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns > t_del && c.safe_state == 1)
        .context("tcs-loop never entered its safe state after vcan0 was deleted")?;
    // after `ip link del` returned the interface was gone for sure
    let safe_ms = ms(first_safe.stamp_ns as i128 - t_gone as i128);
    let bound = SENSOR_TIMEOUT_MS + VM_MARGIN_MS;
    let tail = cycles_in(&l.cycles, first_safe.stamp_ns, u64::MAX);
    let last = tail.last().map_or(0, |c| c.stamp_ns);
    let since = health.end_out.map_or(f64::NAN, |e| e.0);
    println!(
        "safe state at {:.3} s, {:.1} ms after `ip link del` began, {safe_ms:.1} ms after it returned (bound {bound} ms); the statement: from {since:.3} s; {} cycle records from then, the last {:.3} s after the scenario's end, all safe: {}, 0 N m: {}",
        rel(first_safe.stamp_ns),
        ms(first_safe.stamp_ns as i128 - t_del as i128),
        tail.len(),
        ms(last as i128 - we as i128) / 1e3,
        tail.iter().all(|c| c.safe_state == 1),
        tail.iter().all(|c| c.torque_cmd == 0.0),
    );
    ensure!(
        safe_ms <= bound,
        "safe state {safe_ms:.1} ms after the delete, bound {bound} ms"
    );
    ensure!(
        (since - rel(first_safe.stamp_ns)).abs() < 1e-6,
        "the statement's loss of control at {since:.3} s is not the safe state the delete caused ({:.3} s)",
        rel(first_safe.stamp_ns)
    );
    ensure!(
        tail.iter()
            .all(|c| c.safe_state == 1 && c.torque_cmd == 0.0),
        "a cycle left the safe state or commanded torque after vcan0 was deleted"
    );
    ensure!(
        last >= we,
        "tcs-loop's cycle records end {:.3} s before the scenario's end",
        ms(we as i128 - last as i128) / 1e3
    );
    // both services said their bus went, and neither that it came back
    for svc in ["tcs-loop", "plant-sim"] {
        let said = |what: &str| {
            text.lines()
                .any(|l| l.contains(&format!("[{svc}]")) && l.contains(what))
        };
        ensure!(
            said("CAN INTERFACE GONE") && !said("CAN interface back"),
            "{svc} did not log its CAN interface gone (and not back)"
        );
    }
    // 4. grip inspect of the log: the same statement, exit 0
    let o = Command::new(hil::service_bin("grip")?)
        .arg("--config-dir")
        .arg(&s.config)
        .arg("inspect")
        .arg(&mcap)
        .env("NO_COLOR", "1")
        .output()?;
    let out = String::from_utf8_lossy(&o.stdout);
    ensure!(
        o.status.success(),
        "grip inspect exited with {}: {}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    let inspect_lines = control_lines(&out);
    println!("grip inspect ({}): control: {inspect_lines:?}", o.status);
    ensure!(
        inspect_lines == drive_lines,
        "grip inspect's control line(s) {inspect_lines:?}, grip drive's {drive_lines:?}"
    );
    Ok(Attempt::Done)
}

// --- services under the test's own supervisor ----------------------------------------------

/// The five services started as `grip drive` starts them, under
/// grip-drive's supervisor, the scenario started; `recorder_out`: where
/// the recorder writes.
fn start_drive(s: &Setup, tag: &str, recorder_out: &Path) -> anyhow::Result<Supervisor> {
    let inst = instance(tag);
    let specs = hil::drive_specs(&s.config, &s.scenario, recorder_out, &inst, &s.out)?;
    let mut set = hil::start_services(&specs, &inst, Duration::from_secs(60))?;
    set.get("plant-sim")?.signal(libc::SIGUSR1);
    Ok(set)
}

/// Waits for plant-sim's end of the scenario, then stops the others in
/// `grip drive`'s order; returns each one's exit status.
fn finish_drive(set: &mut Supervisor, names: &[&str]) -> anyhow::Result<Statuses> {
    let st = set.get("plant-sim")?.wait_timeout(Duration::from_secs(120));
    ensure!(
        st.is_some_and(|s| s.success()),
        "plant-sim did not finish the scenario ({st:?})"
    );
    let mut out = Vec::new();
    for &name in names {
        let grace = if name.starts_with("recorder") { 60 } else { 10 };
        out.push((name.to_owned(), set.stop(name, Duration::from_secs(grace))?));
    }
    Ok(out)
}

fn log_text(set: &mut Supervisor, name: &str) -> anyhow::Result<String> {
    let p = set.get(name)?;
    Ok(match p.log_path() {
        Some(f) => std::fs::read_to_string(f).unwrap_or_default(),
        None => p.text(),
    })
}

/// tcs-loop's stop line against the wire: every command it says it sent
/// is on the wire (`can_tx`), and it had no bus error.
fn commands_all_on_the_wire(tcs_log: &str, cap: &CaptureLog, s: &Setup) -> anyhow::Result<()> {
    let tx = log_value(tcs_log, "can_tx").context("no can_tx in tcs-loop's stop line")?;
    let errs = log_value(tcs_log, "bus_errors").context("no bus_errors in tcs-loop's stop line")?;
    let misses = log_value(tcs_log, "deadline_misses").unwrap_or(0);
    let wire = cap.with_id(s.dbc.by_name("TorqueCommand")?.id).count() as u64;
    println!(
        "tcs-loop: can_tx {tx}, on the wire {wire}, bus_errors {errs}, deadline_misses {misses}"
    );
    ensure!(
        wire == tx,
        "tcs-loop sent {tx} commands, {wire} on the wire"
    );
    ensure!(errs == 0, "tcs-loop counted {errs} bus errors");
    Ok(())
}

// --- 3. recorder kill -9 ---------------------------------------------------------------------

#[test]
fn killed_recorder_loses_at_most_a_second() -> anyhow::Result<()> {
    let _g = serial();
    // 8 s: the kill at 1.5 s, the new recorder 1 s later, ready up to 3.7 s
    // after the kill under emulation, and it must still see the drive
    with_attempts_in("kill-recorder", &asphalt_scenario(8), kill_recorder)
}

/// How long before `t` the newest of `stamps` is, or "none".
fn last_before(t: u64, stamps: impl Iterator<Item = u64>) -> String {
    stamps.max().map_or("none".to_owned(), |l| {
        format!("{:.0} ms", ms(t as i128 - l as i128))
    })
}

fn kill_recorder(s: &Setup) -> anyhow::Result<Attempt> {
    let fig = Figures::of(s)?;
    let first = s.out.join("first.mcap");
    let second = s.out.join("second.mcap");
    let cap = CanCapture::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let run = || -> anyhow::Result<(u64, u64, u64, String, String, Statuses)> {
        let mut set = start_drive(s, "krec", &first)?;
        wait_scenario_start(s)?;
        std::thread::sleep(Duration::from_millis(1500));
        let t_kill = hil::mono_ns();
        set.get("recorder")?.signal(libc::SIGKILL);
        let st = set
            .get("recorder")?
            .wait_timeout(Duration::from_secs(5))
            .context("the recorder survived SIGKILL")?;
        ensure!(!st.success(), "the killed recorder exited {st}");
        // a new recorder, as a service manager would start it (the unit's
        // RestartSec=1s), on a new file: after the window in which the
        // loop must be unaffected by the kill. A recorder starting makes
        // the loops that publish to it set up their connections to its new
        // subscribers (iceoryx2 does that on their next send, in their
        // cycle): under emulation plant-sim's sensor frames then paused
        // 10-20 ms in two of three drives (2026-12-02), printed below
        std::thread::sleep(
            Duration::from_secs_f64(fig.restart_ms / 1e3)
                .saturating_sub(Duration::from_nanos(hil::mono_ns() - t_kill)),
        );
        let inst = set.instance().to_owned();
        let mut spec = hil::drive_specs(&s.config, &s.scenario, &second, &inst, &s.out)?
            .into_iter()
            .find(|p| p.name == "recorder")
            .context("no recorder in the drive's services")?;
        spec.name = "recorder-2".into();
        spec = spec.output(grip_drive::Output::File(s.out.join("recorder-2.log")));
        let t_start = hil::mono_ns();
        set.start(&spec, Duration::from_secs(60))?;
        let t_new = hil::mono_ns();
        let sts = finish_drive(&mut set, &["tcs-loop", "arte", "audio-acq", "recorder-2"])?;
        let tcs = log_text(&mut set, "tcs-loop")?;
        let rec = log_text(&mut set, "recorder").unwrap_or_default();
        Ok((t_kill, t_start, t_new, tcs, rec, sts))
    };
    let res = run();
    let cap = cap.finish()?;
    player.finish()?;
    let (t_kill, t_start, t_new, tcs_log, rec_log, sts) = res?;
    for (name, st) in &sts {
        ensure!(st.success(), "{name} exited with {st}");
    }
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );

    // the killed recorder's file: readable up to the kill, in order
    let old = DriveLog::load_with(&first, LoadOptions::default())
        .map_err(|e| anyhow::anyhow!("{}", e.full()))?;
    println!("killed recorder's file: {:?}, {:?}", old.report, old.counts);
    ensure!(
        old.report.bad == 0,
        "undecodable messages in the killed recorder's file"
    );
    ensure!(
        !old.cycles.is_empty(),
        "no cycle records in the killed recorder's file"
    );
    if let Some(w) = old.cycles.windows(2).find(|w| w[1].seq != w[0].seq + 1) {
        bail!(
            "killed recorder's file: cycle sequence {} then {}",
            w[0].seq,
            w[1].seq
        );
    }
    let last = old.cycles.iter().map(|c| c.stamp_ns).max().unwrap_or(0);
    let lost = ms(t_kill as i128 - last as i128);
    let bound = LOST_MAX_MS;
    println!(
        "last cycle record in the killed recorder's file {lost:.0} ms before the kill (flush interval {} ms, bound {bound} ms)",
        fig.flush_ms
    );
    // each topic's last record against the kill: one topic behind the
    // others is a receive problem, all of them behind a writer's
    println!(
        "killed recorder's file, last record before the kill: cycle {}, ground truth {}, road {}, CAN {}",
        last_before(t_kill, old.cycles.iter().map(|c| c.stamp_ns)),
        last_before(t_kill, old.truth.iter().map(|m| m.stamp_ns)),
        last_before(t_kill, old.roads.iter().map(|m| m.stamp_ns)),
        last_before(t_kill, old.can.iter().map(|m| m.stamp_ns)),
    );
    if lost > bound {
        // the killed recorder's own log (queue, flushes, stalls), for the cause
        println!("killed recorder's log:\n{rec_log}");
    }
    ensure!(
        lost <= bound,
        "{lost:.0} ms of cycle records lost at the kill, bound {bound} ms"
    );

    // the new recorder's file: complete, starting after the kill
    let peek = DriveLog::load_with(&second, LoadOptions::default())
        .map_err(|e| anyhow::anyhow!("{}", e.full()))?;
    println!(
        "new recorder ready {:.0} ms after the kill; its file: {:?}",
        ms(t_new as i128 - t_kill as i128),
        peek.counts
    );
    let new = read_complete_allowing_xruns(&second)?;
    let first_new = new.cycles[0].stamp_ns;
    println!(
        "new recorder ready {:.0} ms after the kill; its first cycle record {:.0} ms after the kill",
        ms(t_new as i128 - t_kill as i128),
        ms(first_new as i128 - t_kill as i128)
    );
    ensure!(first_new > last, "the new file overlaps the old one");
    // tcs-loop's cycles went on through the gap: its seq continues
    ensure!(
        new.cycles[0].seq > old.cycles[old.cycles.len() - 1].seq,
        "cycle sequence restarted: tcs-loop was disturbed"
    );

    // the loop unaffected: every command on the wire, controlling throughout
    commands_all_on_the_wire(&tcs_log, &cap, s)?;
    let misses_across =
        new.cycles[0].deadline_misses - old.cycles[old.cycles.len() - 1].deadline_misses;
    println!(
        "deadline misses from the old file's last record to the new file's first: {misses_across}"
    );
    // the restart, reported: the inputs on the wire and the commands in the
    // second after the new recorder was started
    let gaps = input_gaps(&cap, &s.dbc, t_start, t_start + 1_000_000_000)?;
    let after: Vec<(u64, bool)> = enabled_commands(&cap, &s.dbc)?
        .into_iter()
        .filter(|&(t, _)| t >= t_start && t <= t_start + 1_000_000_000)
        .collect();
    println!(
        "the second after the new recorder's start: {} commands, {} disabled; longest input gaps on the wire: {gaps}",
        after.len(),
        after.iter().filter(|c| !c.1).count()
    );
    // (the loop's own log is split over two files around the kill: the
    // wire alone judges)
    if let Some(r) = loop_unaffected(
        &cap,
        &s.dbc,
        None,
        t_kill - 500_000_000,
        t_kill + ns(fig.restart_ms),
        "recorder kill",
    )? {
        return Ok(Attempt::Disturbed(r));
    }
    Ok(Attempt::Done)
}

// --- 4. full disk ----------------------------------------------------------------------------

/// Bytes the recorder's disk has free when the scenario starts.
const DISK_HEADROOM: u64 = 1 << 20;

#[test]
fn full_disk_stops_the_recorder_not_the_loop() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("full-disk", &asphalt_scenario(5), full_disk)
}

fn full_disk(s: &Setup) -> anyhow::Result<Attempt> {
    let disk = s.out.join("disk");
    // room for the run metadata and the attachments (the configuration
    // folder, under 1 MB), then filled up to DISK_HEADROOM
    hil::mount_tmpfs(&disk, 8 << 20)?;
    let res = full_disk_on(s, &disk);
    let free = hil::free_bytes(&disk).unwrap_or(u64::MAX);
    // keep what the recorder wrote: copy it off the tmpfs
    let _ = std::fs::copy(disk.join("drive.mcap"), s.out.join("drive.mcap"));
    hil::unmount(&disk)?;
    let a = res?;
    println!("the recorder's disk had {free} bytes free at the end");
    Ok(a)
}

fn full_disk_on(s: &Setup, disk: &Path) -> anyhow::Result<Attempt> {
    let mcap = disk.join("drive.mcap");
    let cap = CanCapture::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let run = || -> anyhow::Result<(u64, u64, String, String, Statuses)> {
        let mut set = start_drive(s, "disk", &mcap)?;
        wait_scenario_start(s)?;
        // fill the disk up to DISK_HEADROOM: the recorder's next ~2 s fit
        let free = hil::free_bytes(disk)?;
        let fill = free.saturating_sub(DISK_HEADROOM);
        let f = std::fs::File::create(disk.join("filler"))?;
        f.set_len(0)?;
        {
            use std::io::Write;
            let mut w = std::io::BufWriter::new(f);
            let block = vec![0xA5u8; 1 << 16];
            let mut left = fill;
            while left > 0 {
                let n = left.min(block.len() as u64) as usize;
                w.write_all(&block[..n])?;
                left -= n as u64;
            }
            w.flush()?;
        }
        let t_fill = hil::mono_ns();
        println!(
            "disk: {free} bytes free at the scenario start, filled to {} bytes free",
            hil::free_bytes(disk)?
        );
        let sts = finish_drive(&mut set, &["tcs-loop", "arte", "audio-acq", "recorder"])?;
        let t_end = hil::mono_ns();
        let tcs = log_text(&mut set, "tcs-loop")?;
        let rec = log_text(&mut set, "recorder")?;
        let _ = t_end;
        Ok((t_fill, t_end, tcs, rec, sts))
    };
    let res = run();
    let cap = cap.finish()?;
    player.finish()?;
    let (t_fill, t_end, tcs_log, rec_log, sts) = res?;
    for (name, st) in &sts {
        if name == "recorder" {
            // a write error stops recording; the recorder exits 1 at the end
            ensure!(
                st.code() == Some(1),
                "the recorder exited with {st} after its disk filled (1 expected):\n{rec_log}"
            );
        } else {
            ensure!(st.success(), "{name} exited with {st}");
        }
    }
    // precondition: the recorder filled the disk (a starved recorder may
    // not have written the headroom before the drive ended)
    let free_end = hil::free_bytes(disk)?;
    if free_end > 64 << 10 && !rec_log.contains("No space left on device") {
        return Ok(Attempt::Disturbed(format!(
            "the recorder did not fill its disk ({free_end} bytes still free at the end)"
        )));
    }
    // the recorder says so in its log
    let says = rec_log
        .lines()
        .find(|l| l.contains("No space left on device"))
        .with_context(|| {
            format!("the recorder's log does not say that its disk is full:\n{rec_log}")
        })?;
    println!("recorder: {says}");

    // the file: readable up to where the disk filled, in order
    let l = DriveLog::load_with(&mcap, LoadOptions::default())
        .map_err(|e| anyhow::anyhow!("{}", e.full()))?;
    println!("the recorder's file on the full disk: {:?}", l.report);
    ensure!(l.report.bad == 0, "undecodable messages in the file");
    ensure!(!l.cycles.is_empty(), "no cycle records in the file");
    if let Some(w) = l.cycles.windows(2).find(|w| w[1].seq != w[0].seq + 1) {
        bail!("cycle sequence {} then {} in the file", w[0].seq, w[1].seq);
    }
    let last = l.cycles[l.cycles.len() - 1].stamp_ns;
    println!(
        "file: {} cycle records, the last {:.0} ms after the disk was filled, {:.0} ms before the drive ended",
        l.cycles.len(),
        ms(last as i128 - t_fill as i128),
        ms(t_end as i128 - last as i128)
    );
    ensure!(
        last > t_fill,
        "nothing recorded after the disk was filled to its headroom"
    );
    ensure!(
        last + 500_000_000 < t_end,
        "the file runs to the drive's end: the disk never filled"
    );

    // the loop unaffected
    commands_all_on_the_wire(&tcs_log, &cap, s)?;
    // (the loop's own log ends where the disk filled: the wire alone judges)
    if let Some(r) = loop_unaffected(
        &cap,
        &s.dbc,
        None,
        t_fill,
        t_end.min(last + 1_500_000_000),
        "full disk",
    )? {
        return Ok(Attempt::Disturbed(r));
    }
    Ok(Attempt::Done)
}

// --- 5. microphone faults ---------------------------------------------------------------------

/// Scenario time of each microphone fault, s: (start, length).
const SILENCE: (f64, f64) = (1.5, 1.0);
const CLIPPING: (f64, f64) = (3.5, 1.0);
const XRUNS: (f64, f64) = (5.5, 1.0);

#[test]
fn microphone_faults_make_the_controller_fall_back() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("mic-faults", &asphalt_scenario(8), mic_faults)
}

/// The share of `used_arte` cycles among the controlling ones in `[t0, t1)`,
/// and how many controlling cycles there were.
fn arte_share(cycles: &[CycleRecord], t0: u64, t1: u64) -> (f64, usize) {
    let c: Vec<&CycleRecord> = cycles_in(cycles, t0, t1)
        .into_iter()
        .filter(|c| c.safe_state == 0)
        .collect();
    let used = c.iter().filter(|c| c.used_arte == 1).count();
    (used as f64 / c.len().max(1) as f64, c.len())
}

fn mic_faults(s: &Setup) -> anyhow::Result<Attempt> {
    let fig = Figures::of(s)?;
    let mcap = s.out.join("drive.mcap");
    let faults = [
        MicFault {
            kind: MicFaultKind::Silence,
            from_s: SILENCE.0,
            len_s: SILENCE.1,
        },
        MicFault {
            kind: MicFaultKind::Clip { gain: 1000.0 },
            from_s: CLIPPING.0,
            len_s: CLIPPING.1,
        },
    ];
    let cap = CanCapture::start(&s.iface)?;
    let player =
        RoadAudioPlayer::start_with_faults(PLAYBACK, &s.iface, &s.config, &s.scenario, &faults)?;
    let mut drive = grip_drive(s, &mcap)?;
    let run = |drive: &mut Proc| -> anyhow::Result<(u64, u64, u64)> {
        let start = wait_scenario_start(s)?.t_ns;
        let at = |sec: f64| start + (sec * 1e9) as u64;
        let sleep_until = |t: u64| {
            let now = hil::mono_ns();
            if t > now {
                std::thread::sleep(Duration::from_nanos(t - now));
            }
        };
        // the xrun storm: audio-acq stopped for longer than its capture
        // buffer, five times, so that the loopback capture overruns
        sleep_until(at(XRUNS.0));
        let acq = hil::child_pid(drive.pid(), "audio-acq").context("audio-acq is not running")?;
        let t_x0 = hil::mono_ns();
        while hil::mono_ns() < at(XRUNS.0 + XRUNS.1) {
            hil::kill_pid(acq, libc::SIGSTOP)?;
            std::thread::sleep(Duration::from_millis(300));
            hil::kill_pid(acq, libc::SIGCONT)?;
            std::thread::sleep(Duration::from_millis(100));
        }
        let t_x1 = hil::mono_ns();
        wait_success(drive, "grip drive", Duration::from_secs(180))?;
        Ok((start, t_x0, t_x1))
    };
    let res = run(&mut drive);
    let cap = cap.finish()?;
    let played = player.finish()?;
    let (start, t_x0, t_x1) = res?;
    println!("grip drive output:\n{}", drive.log_text());
    println!("player: {played:?}");
    ensure!(played.fault_blocks > 0, "the player applied no fault");
    check_frames(&cap, s)?;
    let l = DriveLog::load_with(&mcap, LoadOptions { audio: true })
        .map_err(|e| anyhow::anyhow!("{}", e.full()))?;
    ensure!(
        l.report.truncated.is_none() && l.report.bad == 0,
        "{:?}",
        l.report
    );

    // the faults as the microphone delivered them (captured audio blocks)
    let blocks: Vec<Block> = l
        .audio_blocks
        .iter()
        .map(|a| {
            let n = (a.n_samples as usize).min(a.samples.len());
            let x = &a.samples[..n];
            let end = a.stamp_ns + (n as u64 * 1_000_000_000) / u64::from(a.sample_rate.max(1));
            let silent = x.iter().all(|&v| v == 0);
            let clipped = x
                .iter()
                .filter(|&&v| v == i16::MAX || v == i16::MIN)
                .count()
                * 20
                > n;
            (a.stamp_ns, end, silent, clipped, a.xruns)
        })
        .collect();
    let span = |pred: &dyn Fn(&Block) -> bool, what: &str| -> anyhow::Result<(u64, u64)> {
        let b: Vec<_> = blocks.iter().filter(|b| pred(b)).collect();
        let first = b
            .first()
            .with_context(|| format!("no {what} in the captured audio"))?;
        let last = b[b.len() - 1];
        Ok((first.0, last.1))
    };
    let sil = span(&|b| b.2 && b.0 > start, "silent block after the start")?;
    let clip = span(&|b| b.3, "clipped block")?;
    let xr0 = blocks.iter().rev().find(|b| b.0 < t_x0).map_or(0, |b| b.4);
    let xr1 = blocks.last().map_or(0, |b| b.4);
    println!(
        "captured: silence {:.0}-{:.0} ms, clipping {:.0}-{:.0} ms after the start; xruns {xr0} before the storm, {xr1} at the end",
        ms(sil.0 as i128 - start as i128),
        ms(sil.1 as i128 - start as i128),
        ms(clip.0 as i128 - start as i128),
        ms(clip.1 as i128 - start as i128)
    );
    // the storm on the capture side: overruns reported, or at least the
    // holes in the audio stamps (a stopped audio-acq)
    let holes = blocks
        .windows(2)
        .filter(|w| w[1].0 >= t_x0 && w[1].0 <= t_x1 + 500_000_000 && w[1].0 > w[0].1 + 100_000_000)
        .count();
    println!(
        "xrun storm: {} new overruns reported, {holes} holes over 100 ms in the captured stream",
        xr1 - xr0
    );
    ensure!(
        xr1 > xr0 || holes > 0,
        "the storm left no mark on the captured audio (no overrun, no hole)"
    );
    let xr = (t_x0, t_x1);

    // before the first fault: the controller uses ARTE's knowledge
    let (share0, n0) = arte_share(&l.cycles, sil.0 - 600_000_000, sil.0 - 100_000_000);
    println!(
        "before the faults: ARTE used in {:.0} % of {n0} controlling cycles",
        share0 * 100.0
    );
    if n0 < 100 {
        return Ok(Attempt::Disturbed(format!(
            "only {n0} controlling cycles before the first fault (safe state after stalls)"
        )));
    }
    ensure!(
        share0 >= 0.5,
        "ARTE used in only {:.0} % of the cycles before any fault",
        share0 * 100.0
    );

    for (what, (t0, t1)) in [("silence", sil), ("clipping", clip), ("xrun storm", xr)] {
        // arte's confidence: no confident estimate of audio inside the fault
        let inside: Vec<&grip_msgs::RoadEstimate> = l
            .roads
            .iter()
            .filter(|e| e.frame_t0_ns >= t0 && e.frame_t1_ns <= t1)
            .collect();
        let confident = inside
            .iter()
            .filter(|e| e.class_index != NO_CLASS && e.confidence >= 0.6)
            .count();
        let max_conf = inside
            .iter()
            .filter(|e| e.class_index != NO_CLASS)
            .map(|e| e.confidence)
            .fold(0.0f64, f64::max);
        // the controller: no ARTE from max_age (+ margin) after the last
        // confident estimate of audio heard before the fault (arte publishes
        // a frame's estimate after the frame, later when it runs behind: the
        // loop may use that good knowledge for max_age after it arrived)
        let last_good = l
            .roads
            .iter()
            .filter(|e| {
                // a frame mostly before the fault: audio heard before it
                e.class_index != NO_CLASS
                    && e.confidence >= 0.6
                    && e.frame_t0_ns / 2 + e.frame_t1_ns / 2 < t0
            })
            .max_by_key(|e| e.stamp_ns);
        let heard = last_good.map_or(t0, |e| e.stamp_ns.max(t0));
        let fb0 = heard + ns(fig.max_age_ms + VM_MARGIN_MS);
        let (share, n) = arte_share(&l.cycles, fb0, t1);
        // and back after it
        let (share_after, n_after) = arte_share(&l.cycles, t1, t1 + 1_000_000_000);
        println!(
            "{what}: {} estimates of audio inside it, {confident} confident (highest {max_conf:.2}); the last confident estimate of audio before it published {:.0} ms into it ({:.0} ms after its frame ended); ARTE used in {:.1} % of {n} controlling cycles from {:.0} ms in; in the 1 s after it: {:.0} % of {n_after}",
            inside.len(),
            ms(heard as i128 - t0 as i128),
            last_good.map_or(f64::NAN, |e| ms(e.stamp_ns as i128 - e.frame_t1_ns as i128)),
            share * 100.0,
            ms(fb0 as i128 - t0 as i128),
            share_after * 100.0
        );
        ensure!(
            confident == 0,
            "{what}: arte published {confident} confident estimates of the faulty audio (highest {max_conf:.2})"
        );
        if n == 0 && fb0 >= t1 {
            return Ok(Attempt::Disturbed(format!(
                "{what}: arte's last estimate of the audio before it came {:.0} ms into the {:.0} ms fault: no time left to see the fallback",
                ms(heard as i128 - t0 as i128),
                ms(t1 as i128 - t0 as i128)
            )));
        }
        ensure!(n > 0, "{what}: no controlling cycle during the fault");
        ensure!(
            share == 0.0,
            "{what}: the controller used ARTE in {:.1} % of the cycles during the fault",
            share * 100.0
        );
        ensure!(
            share_after > 0.0,
            "{what}: the controller did not return to ARTE within 1 s after the fault"
        );
    }
    Ok(Attempt::Done)
}

/// Every frame on the wire valid (the faults here are off the bus).
fn check_frames(cap: &CaptureLog, s: &Setup) -> anyhow::Result<()> {
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );
    let c = StreamCheck::run(&s.dbc, &cap.frames);
    ensure!(c.all_valid(), "invalid frames on the bus: {c:#?}");
    Ok(())
}

// --- 6. arte stalled -------------------------------------------------------------------------

/// How long arte is stopped.
const ARTE_STOP_MS: u64 = 2000;

#[test]
fn stalled_arte_ages_out_and_returns() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts_in("stall-arte", &asphalt_scenario(5), stall_arte)
}

fn stall_arte(s: &Setup) -> anyhow::Result<Attempt> {
    let fig = Figures::of(s)?;
    let mcap = s.out.join("drive.mcap");
    let ((t_stop, t_cont), cap, drive) =
        drive_with(s, &mcap, |drive| -> anyhow::Result<(u64, u64)> {
            wait_scenario_start(s)?;
            std::thread::sleep(Duration::from_millis(1000));
            let arte = hil::child_pid(drive.pid(), "arte").context("arte is not running")?;
            hil::kill_pid(arte, libc::SIGSTOP)?;
            let t_stop = hil::mono_ns();
            std::thread::sleep(Duration::from_millis(ARTE_STOP_MS));
            let t_cont = hil::mono_ns();
            hil::kill_pid(arte, libc::SIGCONT)?;
            wait_success(drive, "grip drive", Duration::from_secs(180))?;
            Ok((t_stop, t_cont))
        })?;
    println!("grip drive output:\n{}", drive.log_text());
    check_frames(&cap, s)?;
    let l = read_complete_allowing_audio_gaps(
        &mcap,
        "seen while arte was stopped: a finding, tools/hil/README.md",
    )?;

    let (share0, n0) = arte_share(&l.cycles, t_stop - 500_000_000, t_stop);
    println!(
        "before the stop: ARTE used in {:.0} % of {n0} controlling cycles",
        share0 * 100.0
    );
    if n0 < 100 {
        return Ok(Attempt::Disturbed(format!(
            "only {n0} controlling cycles in the 500 ms before the stop"
        )));
    }
    ensure!(
        share0 >= 0.5,
        "ARTE used in only {:.0} % of the cycles before the stop",
        share0 * 100.0
    );
    let published: Vec<u64> = l
        .roads
        .iter()
        .map(|e| e.stamp_ns)
        .filter(|&t| t > t_stop + 5_000_000 && t < t_cont)
        .collect();
    ensure!(
        published.is_empty(),
        "{} estimates published while arte was stopped",
        published.len()
    );
    // estimates age out: the last one before the stop, then no ARTE
    let last = l
        .roads
        .iter()
        .map(|e| e.stamp_ns)
        .filter(|&t| t <= t_stop + 5_000_000)
        .max()
        .context("no estimate before the stop")?;
    let used_after = l
        .cycles
        .iter()
        .filter(|c| c.stamp_ns > last && c.stamp_ns < t_cont && c.used_arte == 1)
        .map(|c| c.stamp_ns)
        .max();
    let aged_ms = used_after.map_or(0.0, |t| ms(t as i128 - last as i128));
    let bound = fig.max_age_ms + VM_MARGIN_MS;
    println!(
        "ARTE last used {aged_ms:.1} ms after the last estimate (max_age {} ms, bound {bound} ms)",
        fig.max_age_ms
    );
    ensure!(
        aged_ms <= bound,
        "the controller used ARTE {aged_ms:.1} ms after the last estimate, bound {bound} ms"
    );
    let (share_stop, n_stop) = arte_share(&l.cycles, last + ns(bound), t_cont);
    ensure!(
        n_stop > 0 && share_stop == 0.0,
        "ARTE used while stalled: {share_stop} of {n_stop}"
    );
    // back to ARTE after SIGCONT
    let back = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns > t_cont && c.used_arte == 1)
        .context("the controller never returned to ARTE after arte resumed")?;
    println!(
        "ARTE used again {:.0} ms after SIGCONT",
        ms(back.stamp_ns as i128 - t_cont as i128)
    );
    // the 2 s of audio that piled up while arte was stopped are dropped,
    // not classified and published as new (`[input] max_lag_s`): no
    // estimate after SIGCONT is of audio older than max_lag when it went
    // out, with a quarter of the stop as the emulated machine's allowance
    // (classifying the backlog instead gives lags up to the whole stop)
    let max_lag_s = <grip_arte_svc::ArteServiceConfig as grip_io::service::ServiceConfig>::load(
        &s.config.join("arte-svc.toml"),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?
    .input
    .max_lag_s;
    let lag_bound_ms = max_lag_s * 1e3 + ARTE_STOP_MS as f64 / 4.0;
    let after = l.roads.iter().filter(|e| e.stamp_ns > t_cont);
    let worst = after
        .map(|e| ms(e.stamp_ns as i128 - e.frame_t1_ns as i128))
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "estimates after SIGCONT: the oldest audio {worst:.0} ms old when published (max_lag_s {max_lag_s}, bound {lag_bound_ms:.0} ms)"
    );
    ensure!(
        worst <= lag_bound_ms,
        "an estimate after SIGCONT was of audio {worst:.0} ms old (bound {lag_bound_ms:.0} ms): arte classified its backlog"
    );
    Ok(Attempt::Done)
}
