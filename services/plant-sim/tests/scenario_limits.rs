//! The `plant-sim` binary refuses a scenario its vehicle or its loop cannot
//! run, as `grip sim` refuses it (`Scenario::check_for`, through
//! `ConfigDir::scenario_for`): a demand above the vehicle's `torque_max`
//! (it drove the motor at its limit and exited 0), a duration of more than
//! 1e9 loop cycles (it ran for ever with `--exit-at-end`). One `error:`
//! line naming the scenario file, the field and the reason; exit 78 (a
//! refused configuration) before any frame.

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A refused configuration's exit code (`grip_io::service::EXIT_CONFIG`,
/// 78: the units do not restart on it).
use grip_io::service::EXIT_CONFIG;

mod common;
use common::copy_config;

const BIN: &str = env!("CARGO_BIN_EXE_plant-sim");

/// `paper.toml` with `from` replaced by `to`; plant-sim's exit code and stderr.
fn run_paper_with(from: &str, to: &str, extra: &[&str]) -> (i32, String) {
    let t = copy_config();
    let p = t.path().join("scenarios/paper.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains(from), "{from}");
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    let instance = format!("ps-limits-{}", std::process::id());
    let dir = t.path().to_str().unwrap();
    let mut args = vec![
        "--config-dir",
        dir,
        "--start-on",
        "immediate",
        "--exit-at-end",
    ];
    args.extend_from_slice(extra);
    let (code, err) = run_for_at_most(&instance, &args, Duration::from_secs(30));
    // the line names the file in the temporary directory; make it stable
    (code, err.replace(dir, "CONFIG"))
}

/// plant-sim's exit code and stderr; killed (code -1) after `limit` (it ran
/// a 1e300 s scenario for ever before the check).
fn run_for_at_most(instance: &str, args: &[&str], limit: Duration) -> (i32, String) {
    let mut child = Command::new(BIN)
        .args(args)
        .env("GRIP_INSTANCE", instance)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("running plant-sim");
    let mut stderr = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let t0 = Instant::now();
    let code = loop {
        if let Some(st) = child.try_wait().expect("waiting for plant-sim") {
            break st.code().unwrap_or(-1);
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break -1;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (code, reader.join().unwrap_or_default())
}

fn error_line(err: &str) -> &str {
    err.lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line: {err}"))
}

#[test]
fn a_demand_above_the_motor_limit_is_refused() {
    let (code, err) = run_paper_with("torque = 300.0", "torque = 1e300", &[]);
    assert_eq!(code, i32::from(EXIT_CONFIG), "{err}");
    assert_eq!(
        error_line(&err),
        "error: CONFIG/scenarios/paper.toml: field `demand.torque`: 1e300 N m is above the motor limit, the vehicle's torque_max = 1000 N m (the plant would clamp the command there while the controllers and the command's metrics see the demand) (vehicle file CONFIG/vehicle.toml)"
    );
    assert!(!err.contains("plant-sim ready"), "started: {err}");
}

#[test]
fn a_demand_above_a_given_vehicle_s_limit_names_that_vehicle() {
    // the vehicle of --vehicle, not the directory's
    let weak = tempfile::tempdir().unwrap();
    let v = weak.path().join("weak.toml");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/vehicle.toml"),
    )
    .unwrap();
    assert!(text.contains("torque_max = 1000.0"));
    std::fs::write(
        &v,
        text.replacen("torque_max = 1000.0", "torque_max = 250.0", 1),
    )
    .unwrap();
    let (code, err) = run_paper_with(
        "torque = 300.0",
        "torque = 300.0",
        &["--vehicle", v.to_str().unwrap()],
    );
    assert_eq!(code, i32::from(EXIT_CONFIG), "{err}");
    let line = error_line(&err);
    for says in [
        "paper.toml: field `demand.torque`: 300 N m is above the motor limit",
        "torque_max = 250 N m",
        "weak.toml",
    ] {
        assert!(line.contains(says), "{says}: {line}");
    }
}

#[test]
fn a_duration_beyond_the_cycle_bound_is_refused() {
    let (code, err) = run_paper_with("duration = 2.4", "duration = 1e300", &[]);
    assert_eq!(code, i32::from(EXIT_CONFIG), "{err}");
    assert_eq!(
        error_line(&err),
        "error: CONFIG/scenarios/paper.toml: field `duration`: 1e300 s gives 1e303 loop cycles at dt = 0.001 s (need 1 ..= 1e9)"
    );
}
