//! Every reader of a scenario refuses what `grip sim` refuses, with one
//! message (the scenario file, the field, the reason): `grip generate`
//! (before any log; it drove the motor at its limit, and a `duration =
//! 1e300` never ended) as plant-sim's start-up does
//! (`services/plant-sim/tests/scenario_limits.rs`). `grip generate`'s
//! errors name the caller's files, not a log's temporary copy, and print
//! no "generated 0 logs" line. A run whose plant state goes non-finite
//! fails `grip sim` and `grip generate` (exit 1), naming the runs.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::config_dir;

/// A copy of the repository's `config/` in a temporary directory.
fn config_copy() -> (tempfile::TempDir, PathBuf) {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let p = e.unwrap().path();
            let q = to.join(p.file_name().unwrap());
            if p.is_dir() {
                copy(&p, &q);
            } else {
                std::fs::copy(&p, &q).unwrap();
            }
        }
    }
    // not named like grip generate's own copies (`.tmpXXXX`)
    let t = tempfile::Builder::new()
        .prefix("grip-limits")
        .tempdir()
        .unwrap();
    let c = t.path().join("cfg");
    copy(&config_dir(), &c);
    (t, c)
}

/// `file` with its first `from` replaced by `to`.
fn edit(file: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(file).unwrap();
    assert!(text.contains(from), "{} has no {from}", file.display());
    std::fs::write(file, text.replacen(from, to, 1)).unwrap();
}

struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

/// `grip --config-dir CONFIG ARGS`, killed after 120 s (code None).
fn grip(config: &Path, args: &[&str]) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("--config-dir")
        .arg(config)
        .args(args)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let o = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let e = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let t0 = Instant::now();
    let code = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st.code();
        }
        if t0.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Run {
        code,
        stdout: o.join().unwrap(),
        stderr: e.join().unwrap(),
    }
}

/// A refusal: exit 1, no "generated" line, nothing of the temporary copy.
fn refused(r: &Run) -> &str {
    assert_eq!(r.code, Some(1), "{}{}", r.stdout, r.stderr);
    assert!(!r.stdout.contains("generated"), "{}", r.stdout);
    assert!(!r.stderr.contains("/.tmp"), "names the copy: {}", r.stderr);
    &r.stderr
}

/// The text after the field of `line`'s `error: FILE: field `F`: ` prefix.
fn reason(line: &str) -> &str {
    let at = line.find("`: ").unwrap_or_else(|| panic!("{line}"));
    &line[at + 3..]
}

#[test]
fn generate_refuses_a_demand_above_the_motor_limit_as_sim_does() {
    let (t, c) = config_copy();
    let paper = c.join("scenarios/paper.toml");
    edit(&paper, "torque = 300.0", "torque = 1e300");
    let out = t.path().join("gen");
    let o = out.to_str().unwrap();
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            o,
            "--count",
            "1",
            "--scenario",
            "paper",
        ],
    );
    let err = refused(&g);
    let line = err.lines().find(|l| l.starts_with("error: ")).unwrap();
    assert_eq!(
        line,
        format!(
            "error: {}: field `demand.torque`: 1e300 N m is above the motor limit, the vehicle's torque_max = 1000 N m (the plant would clamp the command there while the controllers and the command's metrics see the demand) (vehicle file {})",
            paper.display(),
            c.join("vehicle.toml").display()
        )
    );
    assert!(!out.exists(), "refused after creating --out");
    // grip sim: the same file, field and reason, and the vehicle file (it
    // named the field `scenario.demand.torque`, not as the file has it)
    let s = grip(&c, &["sim", "--seeds", "1"]);
    assert_eq!(s.code, Some(1), "{}", s.stderr);
    let sline = s.stderr.lines().find(|l| l.starts_with("error: ")).unwrap();
    assert_eq!(sline, line);
    assert_eq!(reason(sline), reason(line));
}

#[test]
fn generate_names_the_flag_that_raised_the_demand() {
    let (t, c) = config_copy();
    let out = t.path().join("gen");
    let o = out.to_str().unwrap();
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            o,
            "--count",
            "1",
            "--scenario",
            "paper",
            "--torque",
            "5000",
        ],
    );
    let err = refused(&g);
    assert!(
        err.contains(&format!(
            "error: {} with --torque 5000: field `demand.torque`: 5000 N m is above the motor limit",
            c.join("scenarios/paper.toml").display()
        )),
        "{err}"
    );
    let g = grip(
        &c,
        &["generate", "--out", o, "--count", "1", "--torque", "5000"],
    );
    let err = refused(&g);
    assert!(
        err.contains("error: --scenario random (seed 1): field `demand.torque`: 5000 N m is above the motor limit"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn generate_refuses_a_scenario_longer_than_the_cycle_bound() {
    let (t, c) = config_copy();
    edit(
        &c.join("scenarios/paper.toml"),
        "duration = 2.4",
        "duration = 1e300",
    );
    let out = t.path().join("gen");
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            out.to_str().unwrap(),
            "--count",
            "1",
            "--scenario",
            "paper",
        ],
    );
    let err = refused(&g);
    assert!(
        err.contains(&format!(
            "error: {}: field `duration`: 1e300 s gives 1e303 loop cycles at dt = 0.001 s (need 1 ..= 1e9)",
            c.join("scenarios/paper.toml").display()
        )),
        "{err}"
    );
}

#[test]
fn generate_errors_name_the_caller_s_files() {
    // roads.toml a directory: the user's path and the true reason (it said
    // "/tmp/.tmpXXXX/roads.toml: cannot read: No such file or directory")
    let (t, c) = config_copy();
    let roads = c.join("roads.toml");
    std::fs::remove_file(&roads).unwrap();
    std::fs::create_dir(&roads).unwrap();
    let out = t.path().join("gen");
    let o = out.to_str().unwrap();
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            o,
            "--count",
            "1",
            "--scenario",
            "paper",
        ],
    );
    let err = refused(&g);
    assert!(
        err.contains(&format!(
            "error: {}: cannot read: Is a directory",
            roads.display()
        )),
        "{err}"
    );
    // a missing scenario: its path (it said "reading paper: No such file")
    let (t, c) = config_copy();
    let paper = c.join("scenarios/paper.toml");
    std::fs::remove_file(&paper).unwrap();
    let out = t.path().join("gen");
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            out.to_str().unwrap(),
            "--count",
            "1",
            "--scenario",
            "paper",
        ],
    );
    let err = refused(&g);
    assert!(
        err.contains(&format!(
            "error: {}: cannot read: No such file or directory",
            paper.display()
        )),
        "{err}"
    );
}

/// The first Burckhardt road's c1 at 1e300: the plant state goes
/// non-finite at once.
fn non_finite_config() -> (tempfile::TempDir, PathBuf) {
    let (t, c) = config_copy();
    edit(&c.join("roads.toml"), "c1 = 1.2801", "c1 = 1e300");
    (t, c)
}

#[test]
fn a_non_finite_plant_state_fails_sim_naming_the_runs() {
    let (t, c) = non_finite_config();
    let out = t.path().join("sim");
    let s = grip(
        &c,
        &[
            "sim",
            "--seeds",
            "1",
            "--variants",
            "mfc,src",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(s.code, Some(1), "{}{}", s.stdout, s.stderr);
    assert!(
        s.stderr
            .contains("error: 2 of 2 runs had a non-finite plant state")
            && s.stderr.contains("mfc seed 1 (")
            && s.stderr.contains("src seed 1 ("),
        "{}",
        s.stderr
    );
    // the report and files are there to look at
    assert!(
        s.stdout
            .contains("WARNING: 2 runs had a non-finite plant state"),
        "{}",
        s.stdout
    );
    assert!(out.join("summary.csv").is_file());
}

/// The sweep fails the same way (it exited 0 with a table of NaN), naming
/// each point and its runs, after writing its report and files. No
/// `--sweep` value alone gets a run there (the vehicle's and the
/// controllers' validation and the controllers' guards keep every run
/// finite), so the configuration's road does it, at every point.
#[test]
fn a_non_finite_plant_state_fails_the_sweep_naming_the_points() {
    let (t, c) = non_finite_config();
    let out = t.path().join("sweep");
    let s = grip(
        &c,
        &[
            "sim",
            "--seeds",
            "1",
            "--variants",
            "mfc,mfc-arte",
            "--sweep",
            "preview.cap_share=0.9",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(s.code, Some(1), "{}{}", s.stdout, s.stderr);
    assert!(
        s.stderr
            .contains("error: --sweep: runs at 2 of 2 points had a non-finite plant state")
            && s.stderr
                .contains("#0 `as configured`: 2 of 2 runs: mfc seed 1 (")
            && s.stderr
                .contains("; #1 `preview.cap_share = 0.9`: 2 of 2 runs: mfc seed 1 (")
            && s.stderr.contains("mfc-arte seed 1 ("),
        "{}",
        s.stderr
    );
    // the report and files are there to look at
    assert!(s.stdout.contains("(2 unhealthy runs)"), "{}", s.stdout);
    for f in ["sweep.csv", "sweep.txt", "sweep.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
}

#[test]
fn a_non_finite_plant_state_fails_generate_naming_the_log() {
    let (t, c) = non_finite_config();
    let out = t.path().join("gen");
    let g = grip(
        &c,
        &[
            "generate",
            "--out",
            out.to_str().unwrap(),
            "--count",
            "1",
            "--scenario",
            "paper",
        ],
    );
    let err = refused(&g);
    let log = out.join("gen-00000-s1.mcap");
    assert!(
        err.contains(&format!(
            "{}: the plant state went non-finite",
            log.display()
        )) && err.contains("no log written"),
        "{err}"
    );
    assert!(err.contains("1 of 1 logs failed"), "{err}");
    assert!(
        !log.exists(),
        "a log of no numbers left for a fleet to read"
    );
}
