//! HIL on real CAN controllers: two SJA1000s (QEMU's `kvaser_pci`, driven
//! by Linux's `kvaser_pci`/`sja1000` drivers) on one emulated CAN bus in
//! the VM, `GRIP_HIL_CAN_PAIR` (the VM's `can0 can1`; see
//! `tools/hil/README.md`, "Real CAN controllers"). Unlike `vcan0` they
//! have a driver, a bit rate set through netlink, error states and error
//! counters, and a frame reaches the other side only through the
//! controllers and the bus.
//!
//! 1. `closed_loop_across_two_controllers_at_1_mbit`: both controllers at
//!    1 Mbit/s; tcs-loop on the first, plant-sim (the inverter and the
//!    vehicle) on the second, each with its own configuration folder; the
//!    paper scenario driven closed-loop. Asserts: tcs-loop's start-up line
//!    gives the bit rate read from its interface (1000000 bit/s); every
//!    sensor frame captured on tcs-loop's controller and every
//!    TorqueCommand captured on plant-sim's crossed the bus (nobody on
//!    that side sends them), valid (DLC, CRC, counter); the loop enabled
//!    throughout the scenario with a real torque and at its end; tcs-loop's
//!    E2E faults and bus errors 0; plant-sim received the commands (no
//!    E2E fault, no command timeout, no send error); both controllers
//!    still error-active with their error counters at 0.
//! 2. `tcs_loop_refuses_a_500_kbit_interface`: tcs-loop's controller at
//!    500 kbit/s: tcs-loop exits 78 (a refused configuration) at start, naming the interface, 500000
//!    bit/s and the load, 86.4 %.
//!
//! The two share the controllers, so they take a lock and run one at a
//! time; each sets the bit rates it needs.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, bail, ensure};
use grip_tests::hil::{self, CanCapture, CaptureLog, Dbc, HilConfig};
use grip_tests::hil_drives::{check_all_frames_valid, instance, serial, sig};
use socketcan::CanInterface;
use socketcan::nl::CanState;

/// The scenario driven: the paper's (2.4 s, five roads).
const SCENARIO: &str = "paper";

/// The two controllers: `$GRIP_HIL_CAN_PAIR` ("can0 can1" in the VM).
fn pair() -> anyhow::Result<(String, String)> {
    let v = std::env::var("GRIP_HIL_CAN_PAIR").unwrap_or_default();
    let mut it = v.split_whitespace();
    match (it.next(), it.next(), it.next()) {
        (Some(a), Some(b), None) => Ok((a.to_owned(), b.to_owned())),
        _ => bail!(
            "GRIP_HIL_CAN_PAIR={v:?}: this test needs two CAN controllers on one bus, \
             named there (tools/hil/run's VM gives its emulated SJA1000s, \"can0 can1\")"
        ),
    }
}

/// Sets `iface`'s bit rate through netlink (down, bit rate, up, as `ip
/// link set IFACE type can bitrate N` does; busybox's `ip` cannot) and
/// checks what the kernel then reports.
fn set_bitrate(iface: &str, bitrate: u32) -> anyhow::Result<()> {
    let i = CanInterface::open(iface).with_context(|| format!("netlink: {iface}"))?;
    hil::set_link_up(iface, false)?;
    i.set_bitrate(bitrate, None)
        .with_context(|| format!("setting {iface}'s bit rate to {bitrate}"))?;
    hil::set_link_up(iface, true)?;
    let got = i.bit_rate()?;
    ensure!(
        got == Some(bitrate),
        "{iface}: bit rate {got:?} after setting {bitrate}"
    );
    let state = i.state()?;
    ensure!(
        state == Some(CanState::ErrorActive),
        "{iface}: state {state:?} once up (expected error-active)"
    );
    Ok(())
}

/// The controller's state, error counters and the interface's error
/// statistics, for the report; an error when it is not error-active or
/// counted an error.
fn check_controller(iface: &str) -> anyhow::Result<()> {
    let i = CanInterface::open(iface)?;
    let state = i.state()?;
    let berr = i.berr_counter()?;
    let stat = |name: &str| -> u64 {
        std::fs::read_to_string(format!("/sys/class/net/{iface}/statistics/{name}"))
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(u64::MAX)
    };
    let stats: Vec<(&str, u64)> = [
        "rx_packets",
        "tx_packets",
        "rx_errors",
        "tx_errors",
        "rx_over_errors",
        "rx_dropped",
        "tx_dropped",
    ]
    .into_iter()
    .map(|n| (n, stat(n)))
    .collect();
    println!("{iface}: state {state:?}, error counters {berr:?}, {stats:?}");
    ensure!(
        state == Some(CanState::ErrorActive),
        "{iface}: state {state:?} after the drive (expected error-active)"
    );
    ensure!(
        berr.is_some_and(|b| b.txerr == 0 && b.rxerr == 0),
        "{iface}: error counters {berr:?} after the drive"
    );
    for (n, v) in stats.iter().skip(2) {
        ensure!(*v == 0, "{iface}: {n} = {v} after the drive");
    }
    Ok(())
}

/// A configuration folder for one service on `iface` (SocketCAN only);
/// for plant-sim with `allow_physical_bus = true` (it refuses a device's
/// interface otherwise: this is a bench bus with nothing else on it).
fn config_for(dir: &Path, iface: &str, plant: bool) -> anyhow::Result<PathBuf> {
    let cfg = hil::hil_config_dir(
        dir,
        &HilConfig {
            iface: iface.to_owned(),
            capture_device: grip_tests::hil_drives::CAPTURE.to_owned(),
        },
    )?;
    if plant {
        let src = hil::config_dir().join("plant-sim.toml");
        let text = std::fs::read_to_string(&src)?;
        let text = hil::set_toml_line(
            &text,
            &src.display().to_string(),
            "",
            "allow_physical_bus",
            "true",
        )?;
        let dst = cfg.join("plant-sim.toml");
        std::fs::remove_file(&dst)?;
        std::fs::write(&dst, text)?;
    }
    Ok(cfg)
}

/// The value of `key=` in the last line of `log` that contains `marker`
/// (a service's tracing line).
fn field(log: &str, marker: &str, key: &str) -> anyhow::Result<f64> {
    let line = log
        .lines()
        .rfind(|l| l.contains(marker))
        .with_context(|| format!("no line {marker:?} in the log"))?;
    let pat = format!(" {key}=");
    let at = line
        .find(&pat)
        .with_context(|| format!("no {key}= in {line:?}"))?;
    let v: String = line[at + pat.len()..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    v.parse()
        .with_context(|| format!("{key}={v:?} in {line:?} is not a number"))
}

/// Frames with message `msg`'s id.
fn count(cap: &CaptureLog, dbc: &Dbc, msg: &str) -> anyhow::Result<usize> {
    Ok(cap.with_id(dbc.by_name(msg)?.id).count())
}

#[test]
fn closed_loop_across_two_controllers_at_1_mbit() -> anyhow::Result<()> {
    let _g = serial();
    let (tcs_if, plant_if) = pair()?;
    set_bitrate(&tcs_if, 1_000_000)?;
    set_bitrate(&plant_if, 1_000_000)?;
    let out = hil::out_dir("sja1000-drive")?;
    let tcs_cfg = config_for(&out.join("config-tcs"), &tcs_if, false)?;
    let plant_cfg = config_for(&out.join("config-plant"), &plant_if, true)?;
    let dbc = Dbc::inverter()?;
    let id = |m: &str| dbc.by_name(m).map(|m| m.id);
    let sensors = [
        id("MotorStatus")?,
        id("WheelSpeeds")?,
        id("VehicleSpeed")?,
        id("DriverDemand")?,
    ];
    let mask = hil::CAN_SFF_MASK | hil::CAN_EFF_FLAG | hil::CAN_RTR_FLAG;
    let sensor_filters: Vec<(u32, u32)> = sensors.iter().map(|&i| (i, mask)).collect();
    // what reaches each side only over the bus: the sensors on tcs-loop's
    // controller, the commands on plant-sim's
    let cap_tcs = CanCapture::start_filtered(&tcs_if, &sensor_filters)?;
    let cap_plant = CanCapture::start_filtered(&plant_if, &[(id("TorqueCommand")?, mask)])?;

    let inst = instance("sja1000");
    let bin = grip_io::binaries::bin_dir()?.path;
    let scn = grip_config::ConfigDir::new(&tcs_cfg)
        .scenario_with(SCENARIO, &grip_config::ConfigDir::new(&tcs_cfg).roads()?)?;
    let plan = |cfg: &Path| {
        let mut p = grip_drive::DrivePlan::new(
            cfg,
            SCENARIO,
            scn.duration,
            &out.join("unused.mcap"),
            &inst,
        );
        p.arte = false;
        p
    };
    let spec = |svc: grip_drive::Service, cfg: &Path| {
        svc.spec(&bin, &plan(cfg).args(svc))
            .output(grip_drive::Output::File(
                out.join(format!("{}.log", svc.name())),
            ))
    };
    let tcs_spec = spec(grip_drive::Service::TcsLoop, &tcs_cfg);
    let plant_spec = spec(grip_drive::Service::PlantSim, &plant_cfg);
    let run = || -> anyhow::Result<(String, String)> {
        let mut sup = grip_drive::Supervisor::new(&inst)?;
        sup.start(&tcs_spec, Duration::from_secs(60))?;
        sup.start(&plant_spec, Duration::from_secs(60))?;
        sup.get("plant-sim")?.signal(libc::SIGUSR1);
        let st = sup.get("plant-sim")?.wait_timeout(Duration::from_secs(120));
        ensure!(
            st.is_some_and(|s| s.success()),
            "plant-sim did not finish the scenario ({st:?}):\n{}",
            sup.get("plant-sim")?.tail_text(20)
        );
        let st = sup.stop("tcs-loop", Duration::from_secs(20))?;
        ensure!(st.success(), "tcs-loop exited with {st}");
        Ok((sup.get("tcs-loop")?.text(), sup.get("plant-sim")?.text()))
    };
    let res = run();
    let cap_tcs = cap_tcs.finish()?;
    let cap_plant = cap_plant.finish()?;
    let (tcs_log, plant_log) = res?;

    // tcs-loop read the bit rate from its interface and judged the load there
    let starting = tcs_log
        .lines()
        .find(|l| l.contains("tcs-loop starting"))
        .context("no `tcs-loop starting` line")?;
    let protocol = tcs_log
        .lines()
        .find(|l| l.contains("CAN protocol"))
        .context("no `CAN protocol` line")?;
    println!("tcs-loop: {starting}\ntcs-loop: {protocol}");
    let read = format!("1000000 bit/s read from {tcs_if}");
    ensure!(
        starting.contains(&read) && starting.contains("43.2 %"),
        "tcs-loop's start-up line does not give the bit rate read from {tcs_if} ({read}, 43.2 %): {starting}"
    );
    ensure!(
        protocol.contains(&read),
        "tcs-loop's CAN protocol line does not say {read}: {protocol}"
    );

    // the frames crossed the bus between the two controllers, all valid
    let on_tcs = check_all_frames_valid(&cap_tcs, &dbc)?;
    let on_plant = check_all_frames_valid(&cap_plant, &dbc)?;
    println!("at {tcs_if}: {:?}", on_tcs.per_message);
    println!("at {plant_if}: {:?}", on_plant.per_message);
    for (m, min) in [
        ("MotorStatus", 2000),
        ("WheelSpeeds", 2000),
        ("VehicleSpeed", 200),
        ("DriverDemand", 200),
    ] {
        let n = count(&cap_tcs, &dbc, m)?;
        ensure!(
            n >= min,
            "{n} {m} frames reached {tcs_if} from {plant_if} (at least {min})"
        );
    }
    let commands = count(&cap_plant, &dbc, "TorqueCommand")?;
    ensure!(
        commands >= 2000,
        "{commands} TorqueCommands reached {plant_if} from {tcs_if} (at least 2000)"
    );

    // the loop in control through the scenario and at its end
    let dd = dbc.by_name("DriverDemand")?;
    let start = cap_tcs
        .with_id(dd.id)
        .find(|f| sig(&dbc, "DriverDemand", "TorqueDemand", f) > 0.05)
        .context("no DriverDemand with a demand: the scenario never started")?
        .t_ns;
    let last_ws = cap_tcs
        .with_id(id("WheelSpeeds")?)
        .last()
        .context("no WheelSpeeds")?
        .t_ns;
    let during: Vec<_> = cap_plant
        .with_id(id("TorqueCommand")?)
        .filter(|f| f.t_ns >= start && f.t_ns <= last_ws)
        .collect();
    let disabled = during
        .iter()
        .filter(|f| sig(&dbc, "TorqueCommand", "Enable", f) != 1.0)
        .count();
    let max_torque = during
        .iter()
        .map(|f| sig(&dbc, "TorqueCommand", "TorqueRequest", f))
        .fold(f64::NEG_INFINITY, f64::max);
    let last = during
        .last()
        .context("no TorqueCommand during the scenario")?;
    println!(
        "scenario {:.3} s on the wire: {} TorqueCommands at {plant_if}, {disabled} disabled, largest {max_torque:.1} N m, the last {:.1} N m enabled = {}",
        (last_ws - start) as f64 / 1e9,
        during.len(),
        sig(&dbc, "TorqueCommand", "TorqueRequest", last),
        sig(&dbc, "TorqueCommand", "Enable", last)
    );
    ensure!(
        (last_ws - start) as f64 / 1e9 >= scn.duration - 0.1,
        "the scenario on the wire lasted {:.3} s of {} s",
        (last_ws - start) as f64 / 1e9,
        scn.duration
    );
    ensure!(
        disabled == 0,
        "{disabled} of {} TorqueCommands during the scenario were disabled (safe state)",
        during.len()
    );
    ensure!(
        max_torque >= 100.0,
        "the largest command during the scenario was {max_torque:.1} N m (the demand is 300)"
    );
    ensure!(
        sig(&dbc, "TorqueCommand", "Enable", last) == 1.0,
        "the loop was not in control at the scenario's end"
    );

    // tcs-loop's and plant-sim's own counts
    let stop = "tcs-loop stopped";
    for key in ["bus_errors", "bus_reopens"] {
        let v = field(&tcs_log, stop, key)?;
        ensure!(v == 0.0, "tcs-loop: {key}={v}");
    }
    // plant-sim ends before tcs-loop is stopped: its inputs time out then
    // (WheelSpeeds and MotorStatus after 10 ms, the others after 50 ms),
    // once each, and the loop enters its safe state once, after the
    // scenario (no disabled command during it, above); every other E2E
    // fault (a frame rejected: CRC, length, alive counter, unknown id) is
    // a failure
    let faults = field(&tcs_log, stop, "e2e_faults")?;
    let timeouts = field(&tcs_log, stop, "e2e_timeouts")?;
    ensure!(
        faults == timeouts,
        "tcs-loop rejected {} frames (e2e_faults={faults}, of them timeouts {timeouts})",
        faults - timeouts
    );
    ensure!(timeouts <= 4.0, "tcs-loop: e2e_timeouts={timeouts}");
    let safe = field(&tcs_log, stop, "safe_entries")?;
    ensure!(safe <= 1.0, "tcs-loop: safe_entries={safe}");
    let pstop = "plant-sim";
    let plant_stop = plant_log
        .lines()
        .rfind(|l| l.contains(" can_rx="))
        .context("no plant-sim stop line")?;
    println!("plant-sim: {plant_stop}");
    for key in ["e2e_faults", "cmd_timeouts", "can_errors", "bus_reopens"] {
        let v = field(plant_stop, " can_rx=", key)?;
        ensure!(v == 0.0, "{pstop}: {key}={v}");
    }
    // every frame one side sent reached the other (tcs-loop runs on after
    // plant-sim ends, so plant-sim misses the last commands)
    let (rx, ptx) = (
        field(&tcs_log, stop, "can_rx")?,
        field(plant_stop, " can_rx=", "can_tx")?,
    );
    ensure!(
        rx == ptx,
        "tcs-loop received {rx} frames, plant-sim sent {ptx}"
    );
    let (prx, tx) = (
        field(plant_stop, " can_rx=", "can_rx")?,
        field(&tcs_log, stop, "can_tx")?,
    );
    ensure!(
        prx >= 2000.0 && prx <= tx,
        "plant-sim received {prx} commands, tcs-loop sent {tx} (at least 2000 during the drive)"
    );
    println!(
        "tcs-loop received {rx} of plant-sim's {ptx} frames; plant-sim {prx} of tcs-loop's {tx} commands; tcs-loop e2e_faults={faults} (timeouts {timeouts}), safe_entries={safe}"
    );

    check_controller(&tcs_if)?;
    check_controller(&plant_if)?;
    Ok(())
}

#[test]
fn tcs_loop_refuses_a_500_kbit_interface() -> anyhow::Result<()> {
    let _g = serial();
    let (tcs_if, _) = pair()?;
    set_bitrate(&tcs_if, 500_000)?;
    let res = (|| -> anyhow::Result<()> {
        let out = hil::out_dir("sja1000-500k")?;
        let cfg = config_for(&out.join("config-tcs"), &tcs_if, false)?;
        let cfg_s = cfg.display().to_string();
        let mut p =
            hil::Proc::service("tcs-loop", &["--config-dir", &cfg_s, "--arte", "off"], &out)?;
        let st = p
            .wait_timeout(Duration::from_secs(60))?
            .context("tcs-loop still runs after 60 s on a 500 kbit/s interface")?;
        let log = p.log_text();
        println!("tcs-loop on {tcs_if} at 500 kbit/s: {st}\n{log}");
        // a refused configuration: exit 78 (EX_CONFIG; the units do not
        // restart on it), not 1
        ensure!(st.code() == Some(78), "tcs-loop exited with {st}, not 78");
        let err = log
            .lines()
            .find(|l| l.starts_with("error:"))
            .context("no `error:` line")?;
        for want in [
            "field `interface`".to_owned(),
            format!("{tcs_if}'s 500000 bit/s"),
            "86.4 %".to_owned(),
        ] {
            ensure!(
                err.contains(&want),
                "the refusal does not name {want}: {err}"
            );
        }
        ensure!(
            !log.contains("tcs-loop ready"),
            "tcs-loop got ready on a 500 kbit/s bus"
        );
        Ok(())
    })();
    // the next test (or run) finds the controller as the harness left it
    set_bitrate(&tcs_if, 1_000_000)?;
    res
}
