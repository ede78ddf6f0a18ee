//! HIL drives: all five services on a real kernel's `vcan0`, with audio-acq
//! capturing the ALSA loopback while the scenario's synthetic road sound
//! plays into it. Run by `tools/hil/run` (natively or in its VM).
//!
//! Every drive uses the shipped configuration with two files changed
//! ([`hil::hil_config_dir`]): `can.toml` forces SocketCAN on `vcan0` (no
//! silent fallback to the simulated bus) and `audio-acq.toml` selects the
//! ALSA source on `hw:Loopback,1,0`. A [`hil::RoadAudioPlayer`] plays the
//! scenario's road sound into `hw:Loopback,0,0`, following the drive off
//! the bus. A [`hil::CanCapture`] records every frame on `vcan0` through its
//! own raw socket with kernel time stamps, and the frames are decoded with
//! a decoder built from `config/inverter.dbc` alone ([`hil::Dbc`], CRC and
//! counter written from the DBC's text, not grip-io's code).
//!
//! 1. `full_drive_through_road_changes`: `grip drive --scenario e2e`
//!    (asphalt, snow, gravel; 0.5 s each): every frame decodes per the DBC
//!    with valid CRC and counters; the torque command reacts to the
//!    asphalt→snow change within [`REACTION_BOUND_MS`]; audio came through
//!    the loopback; `grip inspect` reads the log.
//! 2. `killed_tcs_loop_makes_the_inverter_zero_torque`: services started
//!    with `grip drive`'s command lines, `kill -9` of tcs-loop mid-drive:
//!    MotorStatus reports `CmdTimeout` within the inverter's 20 ms timeout
//!    plus [`VM_MARGIN_MS`], and the torque decays to zero.
//! 3. `stopped_sensor_frames_put_tcs_loop_in_its_safe_state`: `SIGSTOP` of
//!    plant-sim mid-drive: tcs-loop's cycle records show `safe_state` and
//!    its commands on `vcan0` are 0 N m / disabled within its 10 ms sensor
//!    timeout plus the margin; after `SIGCONT` it recovers and the drive ends.
//! 4. `corrupted_frames_are_rejected_and_counted`: frames injected with
//!    `cansend` (bad CRC, wrong length) and a replayed frame (repeated
//!    counter) are counted exactly in tcs-loop's fault counters; frames of
//!    an unknown id are on the wire but never reach tcs-loop (its bus's
//!    kernel receive filter): no `unknown_id` fault; none changes anything
//!    in the control (an 8 s drive on asphalt, so the
//!    injection fits in it on a slow host).
//!
//! Every drive's MCAP is read back: not truncated, no bad message,
//! contiguous cycle and ground-truth sequence numbers, the recorder's
//! summary present with nothing dropped.
//!
//! **Time bounds.** The VM is for functional checks, not deadlines: under
//! TCG it runs about 2x slower and a 1 kHz loop wakes about 100 µs late
//! (max 1-4 ms), with seven processes on two emulated CPUs. Every bound
//! below is the protocol's figure plus [`VM_MARGIN_MS`]; the measured
//! figures are printed (`--nocapture`) and the README lists them.
//!
//! The drives share `vcan0` and the loopback, so the tests take a lock and
//! run one at a time.

use std::process::Command;
use std::time::Duration;

use anyhow::{Context, ensure};
use grip_msgs::CycleRecord;
use grip_tests::hil::{self, CanCapture, Captured, RawFrame, RoadAudioPlayer, StreamCheck};
use grip_tests::hil_drives::{
    Attempt, INVERTER_TIMEOUT_MS, PLAYBACK, SENSOR_TIMEOUT_MS, Setup, VM_MARGIN_MS,
    asphalt_scenario, cansend, check_all_frames_valid, drive_with, grip_drive, instance, ms, ns,
    raw_socket, read_complete, serial, sig, wait_scenario_start, wait_success, with_attempts,
    with_attempts_in,
};

/// Torque-command reaction to asphalt → snow: about 20-25 ms in the offline
/// closed loop (`grip sim --scenario e2e`, MTTE with ARTE: the command is
/// below 90 % of the asphalt level 25 ms after the change), driven by the
/// wheel's slip; bound here: 150 ms for the live services on a real bus
/// (ARTE's estimate, a 1 ms loop, frame delays) plus [`VM_MARGIN_MS`].
const REACTION_BOUND_MS: f64 = 150.0 + VM_MARGIN_MS;

// --- 1. a full drive ----------------------------------------------------------------

#[test]
fn full_drive_through_road_changes() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts("drive", full_drive)
}

fn full_drive(s: &Setup) -> anyhow::Result<Attempt> {
    let mcap = s.out.join("drive.mcap");
    let cap = CanCapture::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let mut drive = grip_drive(s, &mcap)?;
    let res = wait_success(&mut drive, "grip drive", Duration::from_secs(180));
    let cap = cap.finish()?;
    let played = player.finish()?;
    res?;
    println!("grip drive output:\n{}", drive.log_text());
    println!("player: {played:?}");

    // the bus: every frame decodes per the DBC, counters and CRCs valid
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

    // the road change in the ground truth
    let first = l.truth[0].road_name().unwrap_or_default().to_owned();
    let change = l
        .truth
        .iter()
        .find(|t| t.road_name().unwrap_or_default() != first)
        .context("no road change in the ground truth")?;
    let t_rc = change.stamp_ns;
    println!(
        "road change {first} -> {} at {t_rc} ns",
        change.road_name().unwrap_or_default()
    );
    // the torque command on the wire around it: enabled commands are the
    // controller's; disabled zeros are the safe state (a sensor timeout,
    // which a stall of the emulated machine causes)
    let tc_id = s.dbc.by_name("TorqueCommand")?.id;
    let cmds: Vec<(u64, f64, bool)> = cap
        .with_id(tc_id)
        .map(|f| {
            (
                f.t_ns,
                sig(&s.dbc, "TorqueCommand", "TorqueRequest", f),
                sig(&s.dbc, "TorqueCommand", "Enable", f) == 1.0,
            )
        })
        .collect();
    let mut before: Vec<f64> = cmds
        .iter()
        .filter(|(t, _, en)| *en && *t < t_rc && *t + 200_000_000 >= t_rc)
        .map(|&(_, v, _)| v)
        .collect();
    if before.len() < 20 {
        return Ok(Attempt::Disturbed(format!(
            "only {} enabled commands in the 200 ms before the road change (safe state after stalls)",
            before.len()
        )));
    }
    before.sort_by(f64::total_cmp);
    let level = before[before.len() / 2];
    ensure!(
        level > 250.0,
        "the command on asphalt was {level} N m, expected near the 300 N m demand"
    );
    let thr = 0.9 * level;
    let react = cmds
        .iter()
        .find(|(t, v, en)| *t >= t_rc && *en && *v < thr)
        .context("the enabled torque command never fell below 90 % of its asphalt level after the change")?;
    let reaction_ms = ms(react.0 as i128 - t_rc as i128);
    let safe_between = l
        .cycles
        .iter()
        .filter(|c| c.stamp_ns + 200_000_000 >= t_rc && c.stamp_ns <= react.0)
        .filter(|c| c.safe_state == 1)
        .count();
    let cyc = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns >= t_rc && c.safe_state == 0 && c.torque_cmd < thr)
        .map(|c| ms(c.stamp_ns as i128 - t_rc as i128));
    println!(
        "torque reaction to {first} -> snow: command {level:.1} N m -> {:.1} N m (< {thr:.1}) after {reaction_ms:.1} ms on the wire ({cyc:?} ms in the cycle records); bound {REACTION_BOUND_MS} ms; safe-state cycles from 200 ms before the change to the reaction: {safe_between}",
        react.1
    );
    if reaction_ms > REACTION_BOUND_MS && safe_between > 0 {
        return Ok(Attempt::Disturbed(format!(
            "reaction {reaction_ms:.1} ms, but the loop spent {safe_between} cycles in its safe state around the change"
        )));
    }
    ensure!(
        reaction_ms <= REACTION_BOUND_MS,
        "torque command reacted {reaction_ms:.1} ms after the road change, bound {REACTION_BOUND_MS} ms"
    );

    // the audio went through the loopback into audio-acq and arte
    ensure!(
        played.started_ns.is_some(),
        "the player never saw the scenario start"
    );
    let names: Vec<&str> = played.roads.iter().map(|(_, n)| n.as_str()).collect();
    ensure!(
        names == ["asphalt", "snow", "gravel"],
        "the player played {names:?}"
    );
    let t0 = played.started_ns.unwrap_or(0);
    let loud: Vec<f64> = l
        .audio
        .iter()
        .filter(|(t, _)| *t > t0 + 200_000_000)
        .map(|&(_, r)| r)
        .collect();
    ensure!(
        loud.len() > 20,
        "only {} audio blocks recorded during the drive",
        loud.len()
    );
    let quiet = loud.iter().filter(|&&r| r < 1e-3).count();
    println!(
        "captured audio: {} blocks during the drive, {quiet} silent (player underruns: {})",
        loud.len(),
        played.xruns
    );
    ensure!(
        quiet * 2 < loud.len(),
        "{quiet} of {} captured blocks are silent: no road sound through the loopback",
        loud.len()
    );
    ensure!(
        !l.roads.is_empty(),
        "arte published no road estimate from the captured audio"
    );
    let (mut judged, mut right) = (0, 0);
    for e in l
        .roads
        .iter()
        .filter(|e| e.class_index != grip_msgs::NO_CLASS)
    {
        let mid = e.frame_t0_ns / 2 + e.frame_t1_ns / 2;
        let i = l.truth.partition_point(|g| g.stamp_ns <= mid);
        if i > 0 {
            judged += 1;
            right += usize::from(e.class_name() == l.truth[i - 1].road_name());
        }
    }
    println!("arte on the loopback audio: {right}/{judged} estimates match the true road");

    // grip inspect reads the log
    let o = Command::new(hil::service_bin("grip")?)
        .arg("inspect")
        .arg(&mcap)
        .output()?;
    ensure!(
        o.status.success(),
        "grip inspect failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    Ok(Attempt::Done)
}

// --- 2. kill -9 tcs-loop -------------------------------------------------------------

#[test]
fn killed_tcs_loop_makes_the_inverter_zero_torque() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts("kill-tcs-loop", kill_tcs_loop)
}

fn kill_tcs_loop(s: &Setup) -> anyhow::Result<Attempt> {
    let mcap = s.out.join("drive.mcap");
    let inst = instance("kill");
    let specs = hil::drive_specs(&s.config, &s.scenario, &mcap, &inst, &s.out)?;
    let cap = CanCapture::start(&s.iface)?;
    let player = RoadAudioPlayer::start(PLAYBACK, &s.iface, &s.config, &s.scenario)?;
    let run = || -> anyhow::Result<u64> {
        let mut set = hil::start_services(&specs, &inst, Duration::from_secs(60))?;
        set.get("plant-sim")?.signal(libc::SIGUSR1);
        wait_scenario_start(s)?;
        std::thread::sleep(Duration::from_millis(500));
        let t_kill = hil::mono_ns();
        set.get("tcs-loop")?.signal(libc::SIGKILL);
        let st = set.get("plant-sim")?.wait_timeout(Duration::from_secs(60));
        ensure!(
            st.is_some_and(|s| s.success()),
            "plant-sim did not finish the scenario after tcs-loop died ({st:?})"
        );
        for (name, grace) in [("arte", 10), ("audio-acq", 10), ("recorder", 60)] {
            let st = set.stop(name, Duration::from_secs(grace))?;
            ensure!(st.success(), "{name} exited with {st}");
        }
        Ok(t_kill)
    };
    let res = run();
    let cap = cap.finish()?;
    player.finish()?;
    let t_kill = res?;

    check_all_frames_valid(&cap, &s.dbc)?;
    let tc = s.dbc.by_name("TorqueCommand")?;
    let ms_id = s.dbc.by_name("MotorStatus")?.id;
    let last_cmd = cap
        .with_id(tc.id)
        .last()
        .context("no TorqueCommand on the bus")?;
    let last_torque = sig(&s.dbc, "TorqueCommand", "TorqueRequest", last_cmd);
    if last_torque < 50.0 {
        return Ok(Attempt::Disturbed(format!(
            "tcs-loop commanded {last_torque} N m when it was killed (safe state after a stall), not a drive torque"
        )));
    }
    ensure!(
        last_cmd.t_ns <= t_kill + 50_000_000,
        "TorqueCommand frames after the kill"
    );
    let status: Vec<&Captured> = cap
        .with_id(ms_id)
        .filter(|f| f.t_ns > last_cmd.t_ns)
        .collect();
    let first_to = status
        .iter()
        .find(|f| sig(&s.dbc, "MotorStatus", "CmdTimeout", f) == 1.0)
        .context("the inverter never reported CmdTimeout after tcs-loop died")?;
    let to_ms = ms(first_to.t_ns as i128 - last_cmd.t_ns as i128);
    let bound = INVERTER_TIMEOUT_MS + VM_MARGIN_MS;
    println!(
        "inverter command timeout {to_ms:.1} ms after the last TorqueCommand (timeout {INVERTER_TIMEOUT_MS} ms, bound {bound} ms)"
    );
    ensure!(
        to_ms <= bound,
        "CmdTimeout {to_ms:.1} ms after the last command, bound {bound} ms"
    );
    ensure!(
        to_ms >= INVERTER_TIMEOUT_MS - 5.0,
        "the inverter zeroed torque {to_ms:.1} ms after the last command, before its {INVERTER_TIMEOUT_MS} ms timeout"
    );
    // from then on: timed out, the torque decays to zero (motor lag 50 ms)
    let after: Vec<&&Captured> = status.iter().filter(|f| f.t_ns >= first_to.t_ns).collect();
    ensure!(
        after
            .iter()
            .all(|f| sig(&s.dbc, "MotorStatus", "CmdTimeout", f) == 1.0),
        "CmdTimeout cleared again without a command"
    );
    let late: Vec<f64> = after
        .iter()
        .filter(|f| f.t_ns > first_to.t_ns + 300_000_000)
        .map(|f| sig(&s.dbc, "MotorStatus", "TorqueActual", f))
        .collect();
    ensure!(!late.is_empty(), "no MotorStatus 300 ms after the timeout");
    let worst = late.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    println!("TorqueActual from 300 ms after the timeout: at most {worst:.1} N m");
    ensure!(
        worst < 10.0,
        "TorqueActual still {worst:.1} N m 300 ms after the timeout"
    );

    let l = read_complete(&mcap)?;
    let applied = l
        .truth
        .iter()
        .filter(|t| t.stamp_ns > first_to.t_ns + 300_000_000)
        .fold(0.0f64, |a, t| a.max(t.torque.abs()));
    ensure!(
        applied < 5.0,
        "the plant's true torque is still {applied:.1} N m 300 ms after the timeout"
    );
    ensure!(
        l.cycles
            .last()
            .is_some_and(|c| c.stamp_ns <= t_kill + 50_000_000),
        "cycle records after tcs-loop was killed"
    );
    Ok(Attempt::Done)
}

// --- 3. sensor frames stop -------------------------------------------------------------

#[test]
fn stopped_sensor_frames_put_tcs_loop_in_its_safe_state() -> anyhow::Result<()> {
    let _g = serial();
    with_attempts("stop-plant-sim", stop_plant_sim)
}

fn stop_plant_sim(s: &Setup) -> anyhow::Result<Attempt> {
    let mcap = s.out.join("drive.mcap");
    let ((t_stop, t_cont), cap, drive) =
        drive_with(s, &mcap, |drive| -> anyhow::Result<(u64, u64)> {
            wait_scenario_start(s)?;
            std::thread::sleep(Duration::from_millis(500));
            let plant =
                hil::child_pid(drive.pid(), "plant-sim").context("plant-sim is not running")?;
            hil::kill_pid(plant, libc::SIGSTOP)?;
            let t_stop = hil::mono_ns();
            std::thread::sleep(Duration::from_millis(300));
            let t_cont = hil::mono_ns();
            hil::kill_pid(plant, libc::SIGCONT)?;
            wait_success(drive, "grip drive", Duration::from_secs(180))?;
            Ok((t_stop, t_cont))
        })?;
    println!("grip drive output:\n{}", drive.log_text());

    check_all_frames_valid(&cap, &s.dbc)?;
    let l = read_complete(&mcap)?;
    let ws_id = s.dbc.by_name("WheelSpeeds")?.id;
    let tc_id = s.dbc.by_name("TorqueCommand")?.id;
    let t_last = cap
        .with_id(ws_id)
        .filter(|f| f.t_ns <= t_stop + 5_000_000)
        .last()
        .context("no WheelSpeeds before the stop")?
        .t_ns;
    let t_back = cap
        .with_id(ws_id)
        .find(|f| f.t_ns > t_last)
        .context("WheelSpeeds never came back after SIGCONT")?
        .t_ns;
    ensure!(
        t_back >= t_cont,
        "WheelSpeeds frames while plant-sim was stopped"
    );
    // precondition: the loop was controlling just before the stop
    let before: Vec<&CycleRecord> = l
        .cycles
        .iter()
        .filter(|c| c.stamp_ns <= t_last && c.stamp_ns + 30_000_000 > t_last)
        .collect();
    if before.is_empty() || before.iter().any(|c| c.safe_state == 1) {
        return Ok(Attempt::Disturbed(format!(
            "tcs-loop was not controlling in the 30 ms before the stop ({} cycles, some in the safe state)",
            before.len()
        )));
    }
    let during: Vec<&Captured> = cap
        .with_id(tc_id)
        .filter(|f| f.t_ns > t_last && f.t_ns < t_back)
        .collect();
    let is_zero = |f: &Captured| {
        sig(&s.dbc, "TorqueCommand", "TorqueRequest", f) == 0.0
            && sig(&s.dbc, "TorqueCommand", "Enable", f) == 0.0
    };
    let first_zero = during
        .iter()
        .find(|f| is_zero(f))
        .context("tcs-loop never sent a zero, disabled command while the sensors were silent")?;
    let z_ms = ms(first_zero.t_ns as i128 - t_last as i128);
    let bound = SENSOR_TIMEOUT_MS + VM_MARGIN_MS;
    ensure!(
        during
            .iter()
            .filter(|f| f.t_ns >= first_zero.t_ns)
            .all(|f| is_zero(f)),
        "a non-zero command after the safe state was entered, before the sensors came back"
    );
    let gap_ms = ms(t_back as i128 - t_last as i128);
    println!(
        "sensors silent {gap_ms:.0} ms; zero-torque commands on vcan0 from {z_ms:.1} ms after the last WheelSpeeds (timeout {SENSOR_TIMEOUT_MS} ms, bound {bound} ms); {} commands while silent",
        during.len()
    );
    ensure!(
        z_ms <= bound,
        "zero torque {z_ms:.1} ms after the sensors stopped, bound {bound} ms"
    );
    ensure!(
        z_ms >= SENSOR_TIMEOUT_MS - 2.0,
        "zero torque {z_ms:.1} ms after the sensors stopped: before the {SENSOR_TIMEOUT_MS} ms timeout"
    );
    ensure!(
        during.len() * 10 > gap_ms as usize,
        "tcs-loop sent only {} commands in {gap_ms:.0} ms of silence (1 kHz expected)",
        during.len()
    );

    let safe = l
        .cycles
        .iter()
        .find(|c| c.stamp_ns > t_last && c.safe_state == 1)
        .context("no cycle record in the safe state after the sensors stopped")?;
    let s_ms = ms(safe.stamp_ns as i128 - t_last as i128);
    println!("cycle records: safe_state from {s_ms:.1} ms after the last WheelSpeeds");
    ensure!(
        s_ms <= bound,
        "safe state {s_ms:.1} ms after the sensors stopped, bound {bound} ms"
    );
    ensure!(
        l.cycles
            .iter()
            .filter(|c| c.stamp_ns >= safe.stamp_ns && c.stamp_ns < t_back)
            .all(|c| c.safe_state == 1 && c.torque_cmd == 0.0),
        "a cycle left the safe state or commanded torque while the sensors were silent"
    );
    ensure!(
        safe.faults.timeout >= 1,
        "the sensor timeout was not counted"
    );
    // recovery: back to control after the sensors returned (it needs 50 ms
    // of valid inputs without a gap, which stalls of the machine can deny)
    if !l
        .cycles
        .iter()
        .any(|c| c.stamp_ns > t_back && c.safe_state == 0 && c.torque_cmd > 0.0)
    {
        let ws: Vec<u64> = cap
            .with_id(ws_id)
            .filter(|f| f.t_ns >= t_back)
            .map(|f| f.t_ns)
            .collect();
        let mut clean = 0u64;
        let mut run = 0u64;
        for w in ws.windows(2) {
            run = if w[1] - w[0] < 8_000_000 {
                run + (w[1] - w[0])
            } else {
                0
            };
            clean = clean.max(run);
        }
        ensure!(
            clean < 100_000_000,
            "tcs-loop never left its safe state after the sensors came back, though they flowed {:.0} ms without a gap",
            ms(i128::from(clean))
        );
        return Ok(Attempt::Disturbed(format!(
            "after SIGCONT the sensor frames never flowed 100 ms without an 8 ms gap (longest {:.0} ms)",
            ms(i128::from(clean))
        )));
    }
    Ok(Attempt::Done)
}

// --- 4. corrupted frames ---------------------------------------------------------------

#[test]
fn corrupted_frames_are_rejected_and_counted() -> anyhow::Result<()> {
    let _g = serial();
    // 8 s on one road: the injection spawns can-utils' cansend four times,
    // which under emulation on a slow host took 3.5-3.9 s, longer than the
    // 3 s drive of the other tests (2026-12-03)
    with_attempts_in("corrupt-frames", &asphalt_scenario(8), corrupt_frames)
}

fn corrupt_frames(s: &Setup) -> anyhow::Result<Attempt> {
    let mcap = s.out.join("drive.mcap");
    let ws = s.dbc.by_name("WheelSpeeds")?.clone();
    let tc = s.dbc.by_name("TorqueCommand")?.clone();
    let dd = s.dbc.by_name("DriverDemand")?.clone();
    const N_CRC: u32 = 5;
    const N_LEN: u32 = 3;
    const N_UNKNOWN: u32 = 3;
    const N_TC_CRC: u32 = 3;
    const N_REPLAY: u32 = 3;
    let unknown_id = 0x7FF;
    ensure!(s.dbc.by_id(unknown_id).is_none(), "0x7FF is in the DBC");

    let ((t0, t1), cap, drive) = drive_with(s, &mcap, |drive| -> anyhow::Result<(u64, u64)> {
        wait_scenario_start(s)?;
        std::thread::sleep(Duration::from_millis(150));
        // each kind once through can-utils' cansend, the repetitions
        // through a plain raw socket (spawning processes is slow under TCG)
        let tx = raw_socket(&s.iface, &[dd.id])?;
        let inject = |k: u32, id: u32, d: &[u8]| -> anyhow::Result<()> {
            if k == 0 {
                cansend(&s.iface, id, d)
            } else {
                tx.send(&RawFrame::new(id, d)?)
            }
        };
        let t0 = hil::mono_ns();
        // replays: a genuine DriverDemand sent again at once (repeated counter)
        for _ in 0..N_REPLAY {
            let f = hil::wait_for_frame(&tx, dd.id, Duration::from_secs(5), |_| true)?;
            tx.send(&RawFrame::new(dd.id, f.frame.payload())?)?;
            std::thread::sleep(Duration::from_millis(12));
        }
        for k in 0..N_CRC {
            // a wheel spinning at 300 rad/s, if anyone believed it
            let mut d = ws.encode(
                &[
                    ("DrivenValid", 1.0),
                    ("RefValid", 1.0),
                    ("OmegaDriven", 300.0),
                    ("OmegaRef", 300.0),
                ],
                k as u8,
            )?;
            d[0] ^= 0x5A;
            inject(k, ws.id, &d)?;
        }
        for k in 0..N_LEN {
            inject(k, ws.id, &[0x01, 0x02])?;
        }
        for k in 0..N_UNKNOWN {
            inject(k, unknown_id, &[0xDE, 0xAD, 0xBE, 0xEF])?;
        }
        for k in 0..N_TC_CRC {
            // 3000 N m to the inverter, with a broken CRC
            let mut d = tc.encode(&[("Enable", 1.0), ("TorqueRequest", 3000.0)], k as u8)?;
            d[0] ^= 0xA5;
            inject(k, tc.id, &d)?;
        }
        let t1 = hil::mono_ns();
        wait_success(drive, "grip drive", Duration::from_secs(180))?;
        Ok((t0, t1))
    })?;
    println!(
        "injected over {:.0} ms; grip drive output:\n{}",
        ms(t1 as i128 - t0 as i128),
        drive.log_text()
    );
    ensure!(
        cap.dropped == 0,
        "the capture socket dropped {} frames",
        cap.dropped
    );

    // on the wire: exactly the injected faults, nothing else wrong
    let c = StreamCheck::run(&s.dbc, &cap.frames);
    println!(
        "frames on the bus: {:?}, unknown {}",
        c.per_message, c.unknown
    );
    let get = |m: &str| c.per_message.get(m).copied().unwrap_or_default();
    ensure!(
        c.unknown == u64::from(N_UNKNOWN),
        "unknown ids on the wire: {}",
        c.unknown
    );
    ensure!(
        get("WheelSpeeds")[1] == u64::from(N_LEN),
        "{:?}",
        get("WheelSpeeds")
    );
    ensure!(
        get("WheelSpeeds")[2] == u64::from(N_CRC),
        "{:?}",
        get("WheelSpeeds")
    );
    ensure!(get("WheelSpeeds")[3] == 0, "{:?}", get("WheelSpeeds"));
    ensure!(
        get("TorqueCommand")[2] == u64::from(N_TC_CRC),
        "{:?}",
        get("TorqueCommand")
    );
    ensure!(
        get("TorqueCommand")[1] + get("TorqueCommand")[3] == 0,
        "{:?}",
        get("TorqueCommand")
    );
    for m in ["MotorStatus", "VehicleSpeed"] {
        ensure!(get(m)[1..].iter().all(|&x| x == 0), "{m}: {:?}", get(m));
    }
    // a replay right behind its original is a repeated counter; one that
    // lost the race to the next genuine frame is an old (skipped) counter
    let dds: Vec<&Captured> = cap.with_id(dd.id).collect();
    let repeated_in_order = dds
        .windows(2)
        .filter(|w| w[0].frame.data == w[1].frame.data)
        .count() as u32;
    if repeated_in_order == 0 {
        return Ok(Attempt::Disturbed(
            "no replay landed right behind its original (the test was too slow to replay within 10 ms)".into(),
        ));
    }
    println!("replays right behind their original: {repeated_in_order} of {N_REPLAY}");

    let l = read_complete(&mcap)?;
    let before = l
        .cycles
        .iter()
        .rev()
        .find(|c| c.stamp_ns < t0)
        .context("no cycle before the injection")?;
    let after = l.cycles.last().context("no cycle records")?;
    if after.stamp_ns < t1 + ns(VM_MARGIN_MS) {
        return Ok(Attempt::Disturbed(format!(
            "the injection outlasted the logged drive: its last cycle record came {:.0} ms after the last frame was injected (at least {VM_MARGIN_MS} ms needed for it to be read)",
            ms(after.stamp_ns as i128 - t1 as i128)
        )));
    }
    let (b, a) = (before.faults, after.faults);
    println!("tcs-loop faults before the injection {b:?}, at the end {a:?}");
    ensure!(
        a.crc - b.crc == N_CRC,
        "crc faults {} -> {}, injected {N_CRC}",
        b.crc,
        a.crc
    );
    ensure!(
        a.length - b.length == N_LEN,
        "length faults {} -> {}, injected {N_LEN}",
        b.length,
        a.length
    );
    // the unknown id is on the wire (checked above) but tcs-loop's bus
    // receives only the ids it consumes (CAN_RAW_FILTER): not one counted
    ensure!(
        a.unknown_id == b.unknown_id,
        "unknown-id faults {} -> {}: {N_UNKNOWN} frames of 0x7FF reached tcs-loop through its receive filter",
        b.unknown_id,
        a.unknown_id
    );
    ensure!(
        a.counter_repeated - b.counter_repeated == repeated_in_order,
        "repeated-counter faults {} -> {}, replays right behind their original {repeated_in_order}",
        b.counter_repeated,
        a.counter_repeated
    );

    // control unaffected: no safe state but from sensor timeouts (stalls of
    // the machine), no 300 rad/s wheel, no 3000 N m
    let window =
        |c: &&CycleRecord| c.stamp_ns + 100_000_000 >= t0 && c.stamp_ns <= t1 + 100_000_000;
    let win: Vec<&CycleRecord> = l.cycles.iter().filter(window).collect();
    ensure!(
        win.len() > 50,
        "only {} cycles around the injection",
        win.len()
    );
    let entries = win
        .windows(2)
        .filter(|w| w[0].safe_state == 0 && w[1].safe_state == 1)
        .count();
    let timeouts = win[win.len() - 1].faults.timeout - win[0].faults.timeout;
    // a stall of tcs-loop longer than the inverter's command timeout makes
    // the inverter (plant-sim) report Fault, which is a safe state too
    // (since 2026-12-05): the MotorStatus frames the loop accepted in the
    // window, each rise of their Fault flag
    let (w0, w1) = (win[0].stamp_ns, win[win.len() - 1].stamp_ns);
    let inverter_faults = {
        use grip_io::can::protocol::{MotorStatus, MsgKind, ProtocolMessage, active};
        let id = active().spec(MsgKind::MotorStatus).id;
        let faults: Vec<bool> = l
            .can
            .iter()
            .filter(|f| {
                f.id == id
                    && f.direction == grip_msgs::can_dir::RX
                    && f.flags & grip_msgs::can_flags::E2E_REJECTED == 0
                    && (w0..=w1).contains(&f.stamp_ns)
            })
            .map(|f| MotorStatus::read_signals(&f.data).fault)
            .collect();
        faults.windows(2).filter(|w| !w[0] && w[1]).count() as u32
    };
    println!(
        "around the injection: {} cycles, {entries} safe-state entries, {timeouts} sensor timeouts, {inverter_faults} inverter faults",
        win.len()
    );
    ensure!(
        entries as u32 <= timeouts + inverter_faults,
        "tcs-loop entered its safe state {entries} times around the injection, with only {timeouts} timeouts and {inverter_faults} inverter faults to explain it"
    );
    let max_omega = win.iter().fold(0.0f64, |m, c| m.max(c.omega));
    ensure!(
        max_omega < 100.0,
        "tcs-loop saw omega {max_omega} rad/s: a corrupt frame got through"
    );
    let max_cmd = l.cycles.iter().fold(0.0f64, |m, c| m.max(c.torque_cmd));
    ensure!(
        max_cmd <= 300.0 + 1e-6,
        "torque command {max_cmd} N m above the demand"
    );
    let max_torque = l.truth.iter().fold(0.0f64, |m, t| m.max(t.torque));
    ensure!(
        max_torque <= 301.0,
        "the plant applied {max_torque} N m: the corrupt 3000 N m command got through"
    );
    Ok(Attempt::Done)
}
