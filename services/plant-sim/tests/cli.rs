//! The `plant-sim` binary: bad configuration → one `error:` line (file,
//! field, reason), exit 78; `READY=1` on `NOTIFY_SOCKET`; `--exit-at-end`
//! exits 0 at the scenario's end; SIGTERM exits 0.

use std::process::Command;
use std::time::{Duration, Instant};

use grip_testkit::svc::{NotifySocket, Service};

/// A refused configuration's exit code (`grip_io::service::EXIT_CONFIG`,
/// 78: the units do not restart on it).
use grip_io::service::EXIT_CONFIG;

mod common;
use common::copy_config;

const BIN: &str = env!("CARGO_BIN_EXE_plant-sim");

fn run(args: &[&str]) -> (i32, String) {
    let instance = format!("ps-cli-{}", std::process::id());
    grip_testkit::svc::run(BIN, &instance, args)
}

#[test]
fn bad_config_names_file_field_reason() {
    let t = copy_config();
    let dir = t.path().to_str().unwrap();
    let p = t.path().join("plant-sim.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    // plant-sim on its configuration with `cmd_timeout_ms = ms`: the exit
    // code must be EX_CONFIG; the error output
    let refused = |ms: &str| -> String {
        let timeout = format!("cmd_timeout_ms = {ms}");
        std::fs::write(&p, text.replace("cmd_timeout_ms = 20.0", &timeout)).unwrap();
        let (code, err) = run(&["--config-dir", dir]);
        assert_eq!(code, i32::from(EXIT_CONFIG), "{err}");
        err
    };
    let err = refused("0.0");
    let line = err.lines().find(|l| l.starts_with("error: ")).expect(&err);
    assert!(
        line.contains("plant-sim.toml: field `cmd_timeout_ms`"),
        "{line}"
    );
    assert!(line.contains("got 0"), "{line}");
    assert!(!err.contains("panicked"), "{err}");
    // longer than the bus's GripTimeoutMs for TorqueCommand (20 ms in the
    // shipped DBC): the simulated inverter would apply a timed-out command
    let err = refused("21.0");
    assert!(
        err.contains("plant-sim.toml: field `cmd_timeout_ms`: 21 ms is longer than TorqueCommand's timeout on the bus (GripTimeoutMs 20 ms in inverter.dbc)"),
        "{err}"
    );
    std::fs::write(&p, &text).unwrap();

    let (code, err) = run(&["--config-dir", dir, "--scenario", "nowhere"]);
    assert_eq!(code, i32::from(EXIT_CONFIG));
    assert!(err.contains("scenarios/nowhere.toml: cannot read"), "{err}");

    let sc = t.path().join("scenarios/bad.toml");
    let paper = std::fs::read_to_string(t.path().join("scenarios/paper.toml")).unwrap();
    std::fs::write(&sc, paper.replace("road = \"gravel\"", "road = \"lava\"")).unwrap();
    let (code, err) = run(&["--config-dir", dir, "--scenario", sc.to_str().unwrap()]);
    assert_eq!(code, i32::from(EXIT_CONFIG));
    assert!(err.contains("bad.toml: field `segment[2].road`"), "{err}");
    assert!(err.contains("unknown road `lava`"), "{err}");

    let (code, _) = run(&["--start-on", "whenever"]);
    assert_eq!(code, 2);
}

#[test]
fn ready_then_exit_at_end_and_sigterm() {
    let t = copy_config();
    let dir = t.path().to_str().unwrap();
    let sock = NotifySocket::bind(t.path());
    let ready = || sock.wait_for("READY=1", Duration::from_secs(20));

    // immediate start, exits by itself after 2.4 s + 0.1 s
    let t0 = Instant::now();
    let mut cmd = Command::new(BIN);
    cmd.args([
        "--config-dir",
        dir,
        "--start-on",
        "immediate",
        "--exit-at-end",
    ])
    .env("NOTIFY_SOCKET", sock.path())
    .env("GRIP_INSTANCE", format!("ps-ready-{}", std::process::id()));
    let mut child = Service::spawn(cmd);
    assert!(ready(), "no READY=1");
    let (status, err) = child.wait();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.contains("finished=true"), "{err}");
    assert!(t0.elapsed() >= Duration::from_millis(2500), "real time");

    // signal start: without SIGUSR1 (and commands) it holds; SIGTERM → 0
    let mut cmd = Command::new(BIN);
    cmd.args(["--config-dir", dir, "--exit-at-end"])
        .env("NOTIFY_SOCKET", sock.path())
        .env("GRIP_INSTANCE", format!("ps-ready2-{}", std::process::id()));
    let mut child = Service::spawn(cmd);
    assert!(ready(), "no READY=1");
    std::thread::sleep(Duration::from_millis(300));
    child.signal(10); // SIGUSR1: no commands, so it keeps holding
    std::thread::sleep(Duration::from_millis(300));
    child.signal(15);
    let (status, err) = child.wait();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.contains("finished=false"), "{err}");
    assert!(err.contains("scenario_time_s=0"), "held: {err}");
}
