//! grip as it runs on an ECU: the Debian package installed with `dpkg -i`
//! on a Debian root file system whose PID 1 is systemd, the units started
//! with `systemctl`, plant-sim on `vcan0` and audio-acq on the ALSA
//! loopback. Run by `tools/hil/run --systemd` (in its VM; the binary fails
//! anywhere PID 1 is not systemd or `GRIP_HIL_DEB` names no package).
//!
//! One test, in steps, each asserting its outcome (they share one install
//! and one bus, so they cannot run in parallel):
//!
//! 1. `dpkg -i` exits 0; binaries, units, conffiles, user and runtime
//!    directories are where the units expect them; nothing is enabled or
//!    started by the install.
//! 2. `systemctl start grip-rig.target` exits 0 and every service reaches
//!    READY (`Type=notify`: active only after `READY=1`) in the units'
//!    order: recorder before plant-sim before audio-acq before arte,
//!    and recorder and plant-sim before tcs-loop.
//! 3. The drive starts (`systemctl kill -s SIGUSR1 grip-plant-sim`).
//! 4. Each service in turn is `SIGSTOP`ped: systemd's watchdog kills it
//!    ("Watchdog timeout" in its journal, `NRestarts` + 1) and restarts it;
//!    while plant-sim is stopped tcs-loop holds its safe state (disabled
//!    0 N m commands on the wire), while tcs-loop is stopped the inverter
//!    reports `CmdTimeout`; after each, tcs-loop's enabled commands come
//!    back without anyone touching anything.
//! 5. The same with `kill -9` of each service in turn.
//! 6. `systemctl stop grip-rig.target grip.target` exits 0; the last
//!    `TorqueCommand` on the wire is 0 N m, disabled; the recorder's last
//!    log is complete (not truncated, its summary written) and `grip
//!    inspect` reads it; its bus log holds the frames another ECU put on
//!    the bus before the stop (the recorder's CAN socket under its unit's
//!    sandbox).
//!
//!    6b. With arte's start hung (a drop-in `ExecStartPre=/bin/sleep`),
//!    tcs-loop's commands are enabled while arte is still activating.
//!
//!    6c. arte started on a configuration file it refuses (a drop-in's
//!    `ExecStart=`) exits 78 and its unit stays failed, not restarted
//!    (`RestartPreventExitStatus=78`), the refused field in its journal.
//!
//! 7. `dpkg -r grip` exits 0 and takes the binaries and units away.
//!
//! Time bounds are function bounds (emulated machine): a watchdog kill and
//! restart must happen within the unit's `WatchdogSec` + 20 s.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context, bail, ensure};
use grip_tests::hil::{self, CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_SFF_MASK, CanCapture, Dbc};

/// The services in an order their units allow (After=/Before=).
const ORDER: [&str; 5] = ["recorder", "plant-sim", "audio-acq", "arte", "tcs-loop"];
/// The units' `After=` pairs (first ready before second): tcs-loop waits for
/// the recorder and the plant, not for the road estimate's chain
/// (audio-acq, arte), which starts in parallel.
const AFTER: [(&str, &str); 5] = [
    ("recorder", "plant-sim"),
    ("plant-sim", "audio-acq"),
    ("audio-acq", "arte"),
    ("recorder", "tcs-loop"),
    ("plant-sim", "tcs-loop"),
];
/// Another ECU's frames put on the bus in step 5's end: an id the
/// built-in protocol does not have.
const FOREIGN_ID: u32 = 0x3E9;
const FOREIGN_FRAMES: u8 = 20;
const PLAYBACK: &str = "hw:Loopback,0,0";
const CAPTURE: &str = "hw:Loopback,1,0";
const ETC: &str = "/etc/grip";
/// In the VM a unit's `WatchdogSec=` is raised to at least this (a drop-in
/// written after the install): under emulation on a loaded host the guest
/// stalls for more than a second at times, and the shipped 1 s watchdog then
/// killed a healthy plant-sim (seen at load average 18-20); at 4 s a
/// healthy arte was killed during the start (its SCHED_FIFO 50 loop shares
/// the first vCPU with plant-sim's SCHED_FIFO 70 one, which under emulation
/// on a loaded host can keep that vCPU busy for seconds; load average
/// 13-16). A unit without `WatchdogSec=` gets no drop-in, so it has no
/// watchdog and the SIGSTOP step fails for it.
const VM_WATCHDOG_FLOOR_US: u64 = 8_000_000;
/// The same floor where the guest's clocks count its instructions
/// (`GRIP_HIL_CLOCK=virtual`, tools/hil/run's default under TCG): a host
/// stall does not exist for the guest there, but its one CPU at 1 GIPS is
/// shared by the five services, systemd and this test's `systemctl`
/// calls, so the two 1 s watchdogs (plant-sim, tcs-loop) get 2 s; the
/// others run as shipped.
const VIRTUAL_CLOCK_WATCHDOG_FLOOR_US: u64 = 2_000_000;
/// In the VM a unit's `TimeoutStartSec=` is raised to at least this (the
/// same drop-in). A restart during the drive starts the new process beside
/// the running real-time services: under emulation their SCHED_FIFO loops
/// keep the first vCPU nearly busy (arte about half of it, plant-sim a third
/// in one run), and the recorder (`Nice=10`, pinned there) got so little of
/// what was left that its start took 9.4 and 15.4 s on the development
/// machine and 22 s on CI's (2026-12-02; 0.6 s at the first start, before
/// the drive; 20 ms of CPU on the host), against its shipped 30 s.
const VM_START_TIMEOUT_FLOOR_US: u64 = 90_000_000;
/// For systemd's kill of the stopped process and the test's polling, on
/// top of the unit's own `WatchdogSec=`, `RestartSec=` and
/// `TimeoutStartSec=` (a start that takes longer fails the unit).
const RESTART_SLACK: Duration = Duration::from_secs(5);

fn unit(s: &str) -> String {
    format!("grip-{s}.service")
}

/// Runs a command; its stdout, or an error with its whole output.
fn run(cmd: &str, args: &[&str]) -> anyhow::Result<String> {
    let out = Command::new(cmd)
        .args(args)
        .output()
        .with_context(|| format!("running {cmd}"))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    ensure!(
        out.status.success(),
        "`{cmd} {}` failed ({}):\n{text}",
        args.join(" "),
        out.status
    );
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Properties `names` of `unit`, in that order, from one `systemctl show`
/// (each call is a process start, which the waits below pay every poll
/// under emulation).
fn props<const N: usize>(unit: &str, names: [&str; N]) -> anyhow::Result<[String; N]> {
    let mut args = vec!["show"];
    for n in &names {
        args.extend(["-p", n]);
    }
    args.push(unit);
    pick(unit, &run("systemctl", &args)?, names)
}

/// `names`' values in `systemctl show` output (`Name=value` lines).
fn pick<const N: usize>(unit: &str, out: &str, names: [&str; N]) -> anyhow::Result<[String; N]> {
    let mut found: [Option<String>; N] = std::array::from_fn(|_| None);
    for l in out.lines() {
        if let Some((k, v)) = l.split_once('=')
            && let Some(i) = names.iter().position(|n| *n == k)
        {
            found[i] = Some(v.trim().to_owned());
        }
    }
    let mut values: [String; N] = std::array::from_fn(|_| String::new());
    for (i, f) in found.into_iter().enumerate() {
        values[i] = f.with_context(|| format!("{unit}: no {} in {out:?}", names[i]))?;
    }
    Ok(values)
}

fn prop(unit: &str, name: &str) -> anyhow::Result<String> {
    let [v] = props(unit, [name])?;
    Ok(v)
}

fn to_u64(unit: &str, name: &str, v: &str) -> anyhow::Result<u64> {
    v.parse()
        .with_context(|| format!("{unit}: {name}={v:?} is not a number"))
}

/// NRestarts and whether the unit is active, in one `systemctl` call.
fn restarts_and_active(unit: &str) -> anyhow::Result<(u64, bool)> {
    let [n, state] = props(unit, ["NRestarts", "ActiveState"])?;
    Ok((to_u64(unit, "NRestarts", &n)?, state == "active"))
}

fn prop_u64(unit: &str, name: &str) -> anyhow::Result<u64> {
    to_u64(unit, name, &prop(unit, name)?)
}

/// A systemd time span as `systemctl show` prints it ("2s", "500ms",
/// "1min 30s", "infinity" is an error), in µs.
fn parse_span_us(v: &str) -> anyhow::Result<u64> {
    let mut total = 0.0;
    for part in v.split_whitespace() {
        let i = part
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(part.len());
        let (num, unit) = part.split_at(i);
        let n: f64 = num.parse().with_context(|| format!("{part:?}"))?;
        total += n * match unit {
            "us" | "\u{b5}s" => 1.0,
            "ms" => 1e3,
            "s" | "" => 1e6,
            "min" => 60e6,
            "h" => 3600e6,
            _ => bail!("unknown unit in {part:?}"),
        };
    }
    Ok(total as u64)
}

/// The highest CPU a systemd CPU list names ("1", "0-3", "0,2 5").
fn max_cpu(v: &str) -> anyhow::Result<usize> {
    let mut max = None;
    for part in v
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|p| !p.is_empty())
    {
        let hi = part.rsplit('-').next().unwrap_or(part);
        let n: usize = hi
            .parse()
            .with_context(|| format!("{part:?} is not a CPU or range"))?;
        max = max.max(Some(n));
    }
    max.context("no CPU named")
}

/// How often the waits ask systemd (each ask starts `systemctl`).
const POLL: Duration = Duration::from_millis(250);

fn wait_until(
    what: &str,
    limit: Duration,
    mut ok: impl FnMut() -> anyhow::Result<bool>,
) -> anyhow::Result<Duration> {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if ok()? {
            return Ok(t0.elapsed());
        }
        std::thread::sleep(POLL);
    }
    bail!("{what}: not within {limit:?}")
}

/// `systemctl status` and the journal of `unit`, for a failure message.
fn report(unit: &str) -> String {
    let _ = run("journalctl", &["--sync"]);
    let out = Command::new("systemctl")
        .args(["status", "--no-pager", "-l", "-n", "40", unit])
        .output();
    out.map_or_else(
        |e| format!("(systemctl status {unit}: {e})"),
        |o| String::from_utf8_lossy(&o.stdout).into_owned(),
    )
}

/// The journal of `unit` since `since_us` (CLOCK_REALTIME µs).
fn journal(unit: &str, since_us: u64) -> anyhow::Result<String> {
    let since = format!("@{}.{:06}", since_us / 1_000_000, since_us % 1_000_000);
    // journald may hold the last lines for a moment
    let _ = run("journalctl", &["--sync"]);
    run(
        "journalctl",
        &[
            "-u",
            unit,
            "--since",
            &since,
            "--no-pager",
            "-o",
            "short-monotonic",
        ],
    )
}

fn realtime_us() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// The rig's configuration in /etc/grip (the package's conffiles, edited as
/// an operator would): SocketCAN on vcan0, the microphone on the loopback.
fn configure_rig(iface: &str) -> anyhow::Result<()> {
    for (file, edits) in [
        (
            "can.toml",
            vec![
                ("", "transport", "\"socketcan\"".to_owned()),
                ("", "interface", format!("{iface:?}")),
            ],
        ),
        (
            "audio-acq.toml",
            vec![
                ("audio", "source", "\"alsa\"".to_owned()),
                ("alsa", "device", format!("{CAPTURE:?}")),
            ],
        ),
    ] {
        let path = Path::new(ETC).join(file);
        let mut text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        for (section, key, value) in edits {
            text = hil::set_toml_line(&text, &path.display().to_string(), section, key, &value)?;
        }
        std::fs::write(&path, text)?;
    }
    Ok(())
}

/// A raw socket that sees only `ids`.
fn raw_socket(iface: &str, ids: &[u32]) -> anyhow::Result<hil::RawCanSocket> {
    let s = hil::RawCanSocket::open(iface)?;
    let m = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
    s.set_filters(&ids.iter().map(|&i| (i, m)).collect::<Vec<_>>())?;
    Ok(s)
}

/// Writes the whole journal of this boot into the test's output folder
/// when dropped (the test passed or failed): it comes back to the host.
struct JournalOnDrop(PathBuf);

impl Drop for JournalOnDrop {
    fn drop(&mut self) {
        let _ = Command::new("journalctl").arg("--sync").status();
        if let Ok(o) = Command::new("journalctl")
            .args(["-b", "--no-pager", "-o", "short-monotonic"])
            .output()
        {
            let _ = std::fs::write(&self.0, o.stdout);
        }
    }
}

struct Rig {
    iface: String,
    dbc: Dbc,
    out: PathBuf,
}

impl Rig {
    /// Waits for a valid TorqueCommand satisfying `pred` (fresh socket: only
    /// frames from now on).
    fn wait_command(
        &self,
        what: &str,
        limit: Duration,
        pred: impl Fn(f64, f64) -> bool,
    ) -> anyhow::Result<()> {
        let tc = self.dbc.by_name("TorqueCommand")?.clone();
        let sock = raw_socket(&self.iface, &[tc.id])?;
        hil::wait_for_frame(&sock, tc.id, limit, |d| {
            d[0] == tc.expected_crc(d) && pred(tc.value("Enable", d), tc.value("TorqueRequest", d))
        })
        .with_context(|| format!("waiting for {what}"))?;
        Ok(())
    }

    /// tcs-loop controls again: an enabled TorqueCommand on the wire.
    fn wait_control(&self, after: &str) -> anyhow::Result<()> {
        self.wait_command(
            &format!("tcs-loop's enabled commands after {after}"),
            Duration::from_secs(30),
            |en, _| en > 0.5,
        )
        .with_context(|| report("grip-tcs-loop.service"))
    }

    /// Waits for a MotorStatus with CmdTimeout = 1 (the inverter's own zero-torque reaction).
    fn wait_inverter_timeout(&self, limit: Duration) -> anyhow::Result<()> {
        let ms = self.dbc.by_name("MotorStatus")?.clone();
        let sock = raw_socket(&self.iface, &[ms.id])?;
        hil::wait_for_frame(&sock, ms.id, limit, |d| {
            d[0] == ms.expected_crc(d) && ms.value("CmdTimeout", d) > 0.5
        })
        .context("waiting for the inverter's CmdTimeout")?;
        Ok(())
    }

    /// Sends `signal` to the service's main process, waits for systemd to
    /// restart it (NRestarts + 1, active again) and returns the journal of
    /// the unit over that time.
    fn fault_and_restart(
        &self,
        s: &str,
        signal: &str,
        during: impl Fn() -> anyhow::Result<()>,
    ) -> anyhow::Result<String> {
        let u = unit(s);
        let others0 = ORDER
            .iter()
            .filter(|o| **o != s)
            .map(|o| Ok((unit(o), prop_u64(&unit(o), "NRestarts")?)))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let n0 = prop_u64(&u, "NRestarts")?;
        let pid0 = prop(&u, "MainPID")?;
        let wd = prop(&u, "WatchdogUSec")?;
        let wd_us = parse_span_us(&wd).with_context(|| format!("{u}: WatchdogUSec={wd:?}"))?;
        ensure!(wd_us > 0, "{u} has no watchdog (WatchdogUSec={wd:?})");
        let t0 = realtime_us();
        run("systemctl", &["kill", "--kill-whom=main", "-s", signal, &u])?;
        during()?;
        // systemd's own bound: the watchdog, the pause before the restart,
        // the start's timeout (a slower start fails the unit, which the
        // NRestarts check below would see)
        let span = |name: &str| -> anyhow::Result<u64> {
            let v = prop(&u, name)?;
            parse_span_us(&v).with_context(|| format!("{u}: {name}={v:?}"))
        };
        let limit = Duration::from_micros(wd_us + span("RestartUSec")? + span("TimeoutStartUSec")?)
            + RESTART_SLACK;
        let took = wait_until(&format!("{u} restarted after {signal}"), limit, || {
            let (n, active) = restarts_and_active(&u)?;
            Ok(n > n0 && active)
        })
        .with_context(|| report(&u))?;
        let pid1 = prop(&u, "MainPID")?;
        ensure!(pid1 != pid0, "{u}: same main PID {pid0} after the restart");
        ensure!(
            prop_u64(&u, "NRestarts")? == n0 + 1,
            "{u}: restarted more than once"
        );
        // a fault of one service takes no other down
        for (o, n) in &others0 {
            let now = prop_u64(o, "NRestarts")?;
            ensure!(
                now == *n,
                "{o} was restarted {} time(s) while {u} had {signal}:\n{}",
                now - n,
                journal(o, t0)?
            );
        }
        let j = journal(&u, t0)?;
        std::fs::write(self.out.join(format!("{s}-{signal}.journal")), &j)?;
        println!(
            "{u}: {signal}: restarted and active again after {took:.1?} (pid {pid0} -> {pid1})"
        );
        Ok(j)
    }
}

#[test]
fn grip_package_under_systemd() -> anyhow::Result<()> {
    let comm = std::fs::read_to_string("/proc/1/comm").unwrap_or_default();
    ensure!(
        comm.trim() == "systemd",
        "PID 1 is {:?}, not systemd: run this through tools/hil/run --systemd",
        comm.trim()
    );
    let deb = std::env::var("GRIP_HIL_DEB").context(
        "GRIP_HIL_DEB (the .deb to install) is not set: tools/hil/run --systemd sets it",
    )?;
    let iface = hil::vcan_iface();
    hil::require_can_iface(&iface)?;
    hil::require_alsa_loopback()?;
    let rig = Rig {
        iface: iface.clone(),
        dbc: Dbc::inverter()?,
        out: hil::out_dir("systemd")?,
    };

    let _journal = JournalOnDrop(rig.out.join("journal.txt"));

    // --- 1. install ------------------------------------------------------------
    let t = Instant::now();
    let out = run("dpkg", &["-i", &deb])?;
    println!("dpkg -i {deb}: exit 0 in {:.1?}", t.elapsed());
    std::fs::write(rig.out.join("dpkg-i.log"), out)?;
    for s in ORDER {
        let b = Path::new("/usr/lib/grip/bin").join(s);
        ensure!(b.is_file(), "{} not installed", b.display());
        ensure!(
            Path::new("/lib/systemd/system").join(unit(s)).is_file(),
            "{} not installed",
            unit(s)
        );
    }
    ensure!(
        Path::new("/usr/bin/grip").is_file(),
        "/usr/bin/grip not installed"
    );
    ensure!(
        Path::new("/usr/lib/udev/rules.d/60-grip.rules").is_file(),
        "the udev rule for /dev/cpu_dma_latency (60-grip.rules) not installed"
    );
    let conffiles = run("dpkg-query", &["-W", "-f", "${Conffiles}", "grip"])?;
    for f in [
        "can.toml",
        "audio-acq.toml",
        "tcs-loop.toml",
        "models/default.model",
    ] {
        let p = format!("{ETC}/{f}");
        ensure!(
            conffiles.contains(&format!("{p} ")),
            "{p} is not a conffile:\n{conffiles}"
        );
    }
    run("getent", &["passwd", "grip"]).context("the user grip")?;
    ensure!(
        run("id", &["-nG", "grip"])?
            .split_whitespace()
            .any(|g| g == "audio"),
        "grip is not in the audio group"
    );
    ensure!(
        Path::new("/tmp/iceoryx2").is_dir(),
        "/tmp/iceoryx2 not created"
    );
    for u in ["grip.target", "grip-rig.target"]
        .into_iter()
        .map(String::from)
        .chain(ORDER.iter().map(|s| unit(s)))
    {
        let en = Command::new("systemctl")
            .args(["is-enabled", &u])
            .output()?;
        let en = String::from_utf8_lossy(&en.stdout).trim().to_owned();
        // "static": no [Install] section (grip-rig.target), cannot be enabled
        ensure!(
            en == "disabled" || en == "static",
            "{u} is {en:?} after the install: the package must enable nothing"
        );
        ensure!(
            prop(&u, "ActiveState")? == "inactive",
            "{u} was started by the install"
        );
    }
    println!(
        "installed: binaries, units, conffiles, user grip (audio), /tmp/iceoryx2; nothing enabled or started"
    );

    // the VM's allowance on the watchdogs the package ships
    let virtual_clock = std::env::var("GRIP_HIL_CLOCK").is_ok_and(|c| c == "virtual");
    let wd_floor_us = if virtual_clock {
        VIRTUAL_CLOCK_WATCHDOG_FLOOR_US
    } else {
        VM_WATCHDOG_FLOOR_US
    };
    println!(
        "guest clock: {}; watchdogs at least {} s",
        if virtual_clock {
            "virtual (counts instructions)"
        } else {
            "the host's"
        },
        wd_floor_us / 1_000_000
    );
    // a unit pinned to a CPU this guest lacks (tools/hil/run's deterministic
    // emulation has one CPU; no unit ships such a pin today) would fail its
    // start (systemd's exec step CPUAFFINITY): the pin is reset, and said
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    for s in ORDER {
        let path = Path::new("/lib/systemd/system").join(unit(s));
        let text = std::fs::read_to_string(&path)?;
        let shipped = |key: &str| {
            text.lines()
                .find_map(|l| l.trim().strip_prefix(key).map(str::to_owned))
        };
        let mut dropin = String::new();
        if let Some(v) = shipped("WatchdogSec=") {
            let us = parse_span_us(&v)
                .with_context(|| format!("{}: WatchdogSec={v}", path.display()))?;
            let start_us = parse_span_us(&prop(&unit(s), "TimeoutStartUSec")?)
                .with_context(|| format!("{}: TimeoutStartUSec", unit(s)))?;
            dropin += &format!(
                "# the shipped WatchdogSec={v} and TimeoutStartSec, at least {} s and {} s on the emulated machine\nWatchdogSec={}us\nTimeoutStartSec={}us\n",
                wd_floor_us / 1_000_000,
                VM_START_TIMEOUT_FLOOR_US / 1_000_000,
                us.max(wd_floor_us),
                start_us.max(VM_START_TIMEOUT_FLOOR_US)
            );
        }
        if let Some(v) = shipped("CPUAffinity=") {
            let max =
                max_cpu(&v).with_context(|| format!("{}: CPUAffinity={v}", path.display()))?;
            if max >= cpus {
                dropin += &format!(
                    "# the shipped CPUAffinity={v} names CPU {max}; this guest has {cpus}\nCPUAffinity=\n"
                );
                println!(
                    "{}: CPUAffinity={v} names CPU {max} but this guest has {cpus} CPU(s): pin reset by a drop-in (not exercised here)",
                    unit(s)
                );
            }
        }
        if !dropin.is_empty() {
            let dir = PathBuf::from(format!("/etc/systemd/system/{}.d", unit(s)));
            std::fs::create_dir_all(&dir)?;
            std::fs::write(
                dir.join("hil-vm.conf"),
                format!("# written by tests/pid1_systemd.rs\n[Service]\n{dropin}"),
            )?;
        }
    }
    run("systemctl", &["daemon-reload"])?;

    // --- 2. start: READY in the units' order ------------------------------------
    configure_rig(&iface)?;
    let capture = CanCapture::start(&iface)?;
    let player = hil::RoadAudioPlayer::start(PLAYBACK, &iface, Path::new(ETC), "paper")?;
    let t = Instant::now();
    run("systemctl", &["start", "grip-rig.target"])?;
    println!(
        "systemctl start grip-rig.target: exit 0 in {:.1?}",
        t.elapsed()
    );
    let mut ready = Vec::new();
    for s in ORDER {
        let u = unit(s);
        ensure!(
            prop(&u, "ActiveState")? == "active",
            "{u} is not active:\n{}",
            report(&u)
        );
        ready.push((s, prop_u64(&u, "ActiveEnterTimestampMonotonic")?));
    }
    let t_first = ready[0].1;
    let at = |s: &str| ready.iter().find(|r| r.0 == s).map(|r| r.1).unwrap_or(0);
    for (a, b) in AFTER {
        ensure!(
            at(a) < at(b),
            "{a} was ready at {} µs, not before {b} at {} µs",
            at(a),
            at(b)
        );
    }
    println!(
        "READY in order: {}",
        ready
            .iter()
            .map(|(s, t)| format!("{s} +{:.2} s", (t - t_first) as f64 / 1e6))
            .collect::<Vec<_>>()
            .join(", ")
    );

    // --- 3. the drive ------------------------------------------------------------
    run("systemctl", &["kill", "-s", "SIGUSR1", &unit("plant-sim")])?;
    let dd = rig.dbc.by_name("DriverDemand")?.clone();
    let sock = raw_socket(&iface, &[dd.id])?;
    hil::wait_for_frame(&sock, dd.id, Duration::from_secs(30), |d| {
        d[0] == dd.expected_crc(d) && dd.value("TorqueDemand", d) > 0.05
    })
    .context("the scenario did not start after SIGUSR1")?;
    rig.wait_control("the scenario start")?;
    println!("the drive runs: DriverDemand with a demand, tcs-loop's commands enabled");
    std::thread::sleep(Duration::from_secs(2));

    // --- 4. SIGSTOP: the watchdog kills, systemd restarts ------------------------
    for s in ["arte", "audio-acq", "recorder", "plant-sim", "tcs-loop"] {
        let j = rig.fault_and_restart(s, "SIGSTOP", || match s {
            // sensors silent: tcs-loop goes to its safe state (disabled, 0 N m)
            "plant-sim" => rig.wait_command(
                "tcs-loop's safe state (disabled 0 N m) while plant-sim is stopped",
                Duration::from_secs(5),
                |en, tq| en < 0.5 && tq.abs() < 0.05,
            ),
            // no commands: the inverter zeroes the torque
            "tcs-loop" => rig.wait_inverter_timeout(Duration::from_secs(5)),
            _ => Ok(()),
        })?;
        ensure!(
            j.contains("Watchdog timeout"),
            "{}: no watchdog timeout in the journal:\n{j}",
            unit(s)
        );
        rig.wait_control(&format!("{s}'s watchdog restart"))?;
    }
    println!("SIGSTOP of each service: killed by its watchdog, restarted, control back");

    // --- 5. kill -9 ---------------------------------------------------------------
    for s in ["arte", "audio-acq", "recorder", "plant-sim", "tcs-loop"] {
        rig.fault_and_restart(s, "SIGKILL", || match s {
            "tcs-loop" => rig.wait_inverter_timeout(Duration::from_secs(5)),
            _ => Ok(()),
        })?;
        rig.wait_control(&format!("{s}'s restart after kill -9"))?;
    }
    println!("kill -9 of each service: restarted, control back");
    // another ECU's frames on the bus: the recorder, under its unit's
    // sandbox, reads the vehicle bus (recorder.toml `bus = "foreign"`) and
    // logs them (until 2026-12-05 the unit's PrivateNetwork= and
    // RestrictAddressFamilies=AF_UNIX refused its CAN socket: no bus log)
    for i in 0..FOREIGN_FRAMES {
        grip_tests::hil_drives::cansend(&iface, FOREIGN_ID, &[i, 0xB5, 0, 0, 0, 0, 0, 0])?;
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_secs(2));

    // --- 6. stop ---------------------------------------------------------------------
    let t = Instant::now();
    run("systemctl", &["stop", "grip-rig.target", "grip.target"])?;
    println!(
        "systemctl stop grip-rig.target grip.target: exit 0 in {:.1?}",
        t.elapsed()
    );
    // the targets' stop jobs end before the services' (PartOf= queues
    // those): every service must be inactive within its TimeoutStopSec
    for s in ORDER {
        let u = unit(s);
        wait_until(&format!("{u} stopped"), Duration::from_secs(60), || {
            Ok(prop(&u, "ActiveState")? == "inactive")
        })
        .with_context(|| report(&u))?;
        let r = prop(&u, "Result")?;
        ensure!(
            r == "success",
            "{u} stopped with result {r:?}:\n{}",
            report(&u)
        );
    }
    println!(
        "every service inactive, result success, {:.1?} after the stop command",
        t.elapsed()
    );
    std::thread::sleep(Duration::from_millis(200));
    let cap = capture.finish()?;
    let rep = player.finish()?;
    println!("road-audio player: {rep:?}");
    let tc = rig.dbc.by_name("TorqueCommand")?;
    let last = cap
        .with_id(tc.id)
        .last()
        .context("no TorqueCommand captured")?;
    let d = last.data8();
    ensure!(
        d[0] == tc.expected_crc(&d),
        "the last TorqueCommand has a bad CRC"
    );
    let (en, tq) = (tc.value("Enable", &d), tc.value("TorqueRequest", &d));
    ensure!(
        en < 0.5 && tq == 0.0,
        "the last TorqueCommand is Enable={en}, {tq} N m, not 0 N m disabled"
    );
    println!(
        "last TorqueCommand: Enable=0, 0 N m ({} commands captured)",
        cap.with_id(tc.id).count()
    );
    let mut logs: Vec<PathBuf> = std::fs::read_dir("/var/log/grip")?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    logs.sort_by_key(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
    let log = logs.last().context("no MCAP in /var/log/grip")?;
    let kept = rig.out.join("last.mcap");
    std::fs::copy(log, &kept)?;
    let inspect = run("grip", &["inspect", &log.display().to_string()])?;
    std::fs::write(rig.out.join("inspect.txt"), &inspect)?;
    // complete: read to its end (no damage, every message decoded) and the
    // recorder's summary written, which it does only when it finishes the
    // file (a killed recorder leaves a file without it); grip inspect (the
    // packaged release build, fast in the VM) reads the whole log and says
    // so otherwise
    for bad in [
        "log is incomplete",
        "did not decode",
        "no grip.recorder summary",
    ] {
        ensure!(
            !inspect.contains(bad),
            "{}: grip inspect says {bad:?}:\n{inspect}",
            log.display()
        );
    }
    println!(
        "grip inspect: exit 0\n{}",
        inspect.lines().take(25).collect::<Vec<_>>().join("\n")
    );
    // the bus log: the foreign frames, by their id
    let bus = inspect
        .split("bus (the vehicle bus")
        .nth(1)
        .with_context(|| format!("no bus section in grip inspect:\n{inspect}"))?;
    let frames: u64 = bus
        .lines()
        .nth(1)
        .and_then(|l| l.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .with_context(|| format!("no frame count in the bus section:\n{bus}"))?;
    ensure!(
        frames >= u64::from(FOREIGN_FRAMES) && bus.contains(&format!("0x{FOREIGN_ID:03X}")),
        "the recorder's bus log lacks the {FOREIGN_FRAMES} foreign frames (id 0x{FOREIGN_ID:03X}):\nbus{bus}\n{}",
        report(&unit("recorder"))
    );
    println!(
        "the recorder's bus log under its unit: {frames} frames, 0x{FOREIGN_ID:03X} among them"
    );

    // --- 6b. a start of arte that hangs does not hold traction control ------------
    // (a microphone whose open blocks, a model on a stalled file system):
    // tcs-loop is not ordered after arte, so it controls while arte's start
    // job still runs. Before 2026-12-05 it was, and waited for arte's
    // TimeoutStartSec (90 s here, 30 s as shipped) with the inverter at 0 N m.
    let hang_dir = PathBuf::from(format!("/etc/systemd/system/{}.d", unit("arte")));
    std::fs::create_dir_all(&hang_dir)?;
    let hang = hang_dir.join("hil-hang.conf");
    std::fs::write(
        &hang,
        "# written by tests/pid1_systemd.rs: a start that hangs\n[Service]\nExecStartPre=/bin/sleep 3600\n",
    )?;
    run("systemctl", &["daemon-reload"])?;
    let t = Instant::now();
    run("systemctl", &["start", "--no-block", "grip-rig.target"])?;
    let pu = unit("plant-sim");
    wait_until(&format!("{pu} active"), Duration::from_secs(120), || {
        Ok(prop(&pu, "ActiveState")? == "active")
    })
    .with_context(|| report(&pu))?;
    run("systemctl", &["kill", "-s", "SIGUSR1", &pu])?;
    rig.wait_control("a start in which arte's start hangs")?;
    let arte = prop(&unit("arte"), "ActiveState")?;
    ensure!(
        arte == "activating",
        "arte is {arte:?} once tcs-loop controls, not still activating: the hang did not hold"
    );
    println!(
        "arte's start hung (ExecStartPre sleeps): tcs-loop controls {:.1?} after the start, arte still {arte}",
        t.elapsed()
    );
    run("systemctl", &["stop", "grip-rig.target", "grip.target"])?;
    for s in ORDER {
        let u = unit(s);
        wait_until(&format!("{u} stopped"), Duration::from_secs(120), || {
            let a = prop(&u, "ActiveState")?;
            Ok(a == "inactive" || a == "failed")
        })
        .with_context(|| report(&u))?;
    }
    std::fs::remove_file(&hang)?;
    run("systemctl", &["daemon-reload"])?;

    // --- 6c. a configuration the service refuses: the unit fails, no restart ----
    // The service exits 78 (EX_CONFIG) on a file, field or value it
    // refuses, and the units' RestartPreventExitStatus=78 leaves the unit
    // failed with the error in its status, instead of a restart every
    // second for ever (before 2026-12-07: exit 1, restarted without end,
    // StartLimitIntervalSec=0). Other failures (exit 1) are still
    // restarted: steps 4 and 5.
    let au = unit("arte");
    let bad_cfg = Path::new("/tmp/hil-bad-arte-svc.toml");
    std::fs::write(
        bad_cfg,
        "# written by tests/pid1_systemd.rs: a field arte does not know\nbogus_key = 1\n",
    )?;
    std::fs::set_permissions(bad_cfg, std::os::unix::fs::PermissionsExt::from_mode(0o644))?;
    let bad = hang_dir.join("hil-bad-config.conf");
    std::fs::write(
        &bad,
        format!(
            "# written by tests/pid1_systemd.rs: arte started on a file it refuses\n[Service]\nExecStart=\nExecStart=/usr/lib/grip/bin/arte --config-dir /etc/grip --config {}\n",
            bad_cfg.display()
        ),
    )?;
    run("systemctl", &["daemon-reload"])?;
    let since = realtime_us();
    // the start job fails (Type=notify: no READY=1): not an error here
    let _ = Command::new("systemctl").args(["start", &au]).output();
    wait_until(&format!("{au} failed"), Duration::from_secs(120), || {
        Ok(prop(&au, "ActiveState")? == "failed")
    })
    .with_context(|| report(&au))?;
    let [n0] = props(&au, ["NRestarts"])?;
    // well past RestartSec=1s: a restart would have come by now
    std::thread::sleep(Duration::from_secs(5));
    let [state, status, n1] = props(&au, ["ActiveState", "ExecMainStatus", "NRestarts"])?;
    ensure!(
        state == "failed" && status == "78" && n0 == n1,
        "{au} on a configuration it refuses: ActiveState {state}, ExecMainStatus {status}, NRestarts {n0} -> {n1} (want failed, 78, unchanged)\n{}",
        report(&au)
    );
    let j = journal(&au, since)?;
    ensure!(
        j.contains("bogus_key"),
        "{au}'s journal does not name the refused field:\n{j}"
    );
    println!(
        "a configuration arte refuses: unit failed, exit status 78, no restart in 5 s (NRestarts {n1})"
    );
    std::fs::remove_file(&bad)?;
    std::fs::remove_file(bad_cfg)?;
    run("systemctl", &["daemon-reload"])?;
    run("systemctl", &["reset-failed", &au])?;

    // --- 7. remove -------------------------------------------------------------------
    let t = Instant::now();
    let out = run("dpkg", &["-r", "grip"])?;
    std::fs::write(rig.out.join("dpkg-r.log"), out)?;
    println!("dpkg -r grip: exit 0 in {:.1?}", t.elapsed());
    ensure!(
        !Path::new("/usr/lib/grip/bin/tcs-loop").exists(),
        "binaries left after dpkg -r"
    );
    ensure!(
        !Path::new("/lib/systemd/system/grip.target").exists(),
        "units left after dpkg -r"
    );
    ensure!(
        Path::new("/etc/grip/can.toml").exists(),
        "dpkg -r (not purge) must keep the conffiles"
    );
    Ok(())
}

#[test]
fn systemctl_show_lines_are_picked_by_name() {
    let out = "ActiveState=active\nNRestarts=3\nExecStart={ path=/x ; argv[]=/x a=b }\n";
    let [n, a] = pick("u", out, ["NRestarts", "ActiveState"]).unwrap();
    assert_eq!((n.as_str(), a.as_str()), ("3", "active"));
    let [e] = pick("u", out, ["ExecStart"]).unwrap();
    assert_eq!(e, "{ path=/x ; argv[]=/x a=b }");
    let err = pick("u", out, ["NRestarts", "MainPID"])
        .unwrap_err()
        .to_string();
    assert!(err.contains("u: no MainPID"), "{err}");
}

#[test]
fn cpu_lists_read_as_systemd_writes_them() {
    assert_eq!(max_cpu("1").unwrap(), 1);
    assert_eq!(max_cpu("0-3").unwrap(), 3);
    assert_eq!(max_cpu("0,2 5").unwrap(), 5);
    assert!(max_cpu("").is_err());
    assert!(max_cpu("one").is_err());
}
