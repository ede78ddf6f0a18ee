//! `grip inspect` on the reference drive and on a copy cut short: the
//! preview report uses the log's own road catalogue (also with a
//! configuration directory that has none), `--json` and the directory
//! table separate the scenario from the whole log and say how much of the
//! scenario a cut log covers, and `grip inspect A B` warns when the two are
//! not comparable.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn reference() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap")
}

/// `grip --config-dir DIR ARGS`: success, stdout, stderr.
fn grip_in(config_dir: &Path, args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("--config-dir")
        .arg(config_dir)
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn json_of(path: &Path) -> Value {
    let (ok, out, err) = common::output(&["inspect".as_ref(), "--json".as_ref(), path.as_os_str()]);
    assert!(ok, "{out}{err}");
    serde_json::from_str(out.lines().next().unwrap()).unwrap()
}

/// The reference drive's first 70 % (its ground truth ends 0.237 s into
/// the 1.5 s scenario; the first 30 % of the file is the attachments).
fn cut_copy(dir: &Path) -> PathBuf {
    let bytes = std::fs::read(reference()).unwrap();
    let p = dir.join("cut.mcap");
    std::fs::write(&p, &bytes[..bytes.len() * 7 / 10]).unwrap();
    p
}

/// With a configuration directory without `roads.toml` (as outside the
/// repository), the preview report is still there: from the log's own
/// catalogue, and it says so.
#[test]
fn inspect_uses_the_logs_own_road_catalogue() {
    let empty = tempfile::tempdir().unwrap();
    let (ok, out, err) = grip_in(empty.path(), &["inspect".as_ref(), reference().as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("road catalogue: roads.toml attached to the log"),
        "{out}{err}"
    );
    assert!(
        out.contains("asphalt -> snow at 0.500 s (x 1.67 m), limit 182.7 N m"),
        "{out}"
    );
    assert!(!err.contains("no preview report"), "{err}");
    let (ok, out, err) = grip_in(
        empty.path(),
        &[
            "inspect".as_ref(),
            "--json".as_ref(),
            reference().as_os_str(),
        ],
    );
    assert!(ok, "{out}{err}");
    let j: Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
    assert_eq!(j["roads_from"], "roads.toml attached to the log", "{j}");
}

/// `--json`: the scenario window and how much of it the log covers; the
/// loop's figures during the scenario beside the whole log's; ARTE judged
/// in the scenario (the headline) and over the whole log while there is
/// ground truth. A cut copy is `partial`, says what its metrics cover, and
/// `grip inspect A B` warns before comparing it.
#[test]
fn inspect_json_separates_the_scenario_from_the_whole_log() {
    let j = json_of(&reference());
    assert_eq!(j["status"], "ok");
    assert_eq!(j["scenario_window"], "complete", "{j}");
    assert_eq!(j["scenario_duration_s"], 1.5);
    assert_eq!(j["safe_state_entries"], 1, "the stop's");
    assert_eq!(j["safe_state_entries_in_scenario"], 0);
    // the reference drive of 2026-12-05 (regenerated for the spin cut's
    // landing): no deadline missed during its scenario (the one before
    // had 12, all from its host's scheduling)
    assert_eq!(j["deadline_misses_in_scenario"], 0);
    assert_eq!(
        (j["arte_judged"].as_u64(), j["arte_correct"].as_u64()),
        (Some(60), Some(60))
    );
    assert_eq!(
        j["arte_judged_whole_log"], 69,
        "none after the ground truth ends"
    );
    let sha = j["scenario_sha256"].as_str().unwrap();
    assert_eq!(sha, j["run"]["config.scenarios/e2e.toml"].as_str().unwrap());

    let d = tempfile::tempdir().unwrap();
    let cut = cut_copy(d.path());
    let c = json_of(&cut);
    assert_eq!(c["status"], "incomplete");
    assert_eq!(c["scenario_window"], "partial", "{c}");
    let covered = c["scenario_s"].as_f64().unwrap();
    assert!(covered > 0.1 && covered < 1.0, "{covered}");
    let w = c["warnings"].to_string();
    assert!(
        w.contains(&format!(
            "metrics cover {covered:.3} of 1.500 s of the scenario"
        )),
        "{w}"
    );

    // the directory table carries the window's status
    let csv = d.path().join("table.csv");
    std::os::unix::fs::symlink(reference(), d.path().join("ref.mcap")).unwrap();
    let (ok, out, err) = common::output(&[
        "inspect".as_ref(),
        d.path().as_os_str(),
        "--csv".as_ref(),
        csv.as_os_str(),
    ]);
    assert!(ok, "{out}{err}");
    let table = std::fs::read_to_string(&csv).unwrap();
    let head: Vec<&str> = table.lines().next().unwrap().split(',').collect();
    let col = head.iter().position(|c| *c == "scenario_window").unwrap();
    let misses = head
        .iter()
        .position(|c| *c == "deadline_misses_in_scenario")
        .unwrap();
    // a field of a row, counted from the end (the reason, third, may hold
    // quoted commas; none of the later fields does)
    let field = |f: &str, c: usize| -> String {
        let r: Vec<&str> = table
            .lines()
            .find(|l| l.starts_with(f))
            .unwrap()
            .split(',')
            .collect();
        r[r.len() - (head.len() - c)].to_owned()
    };
    assert_eq!(field("cut.mcap", col), "partial", "{table}");
    assert_eq!(field("ref.mcap", col), "complete", "{table}");
    assert_eq!(field("ref.mcap", misses), "0", "{table}");

    let (ok, out, err) =
        common::output(&["inspect".as_ref(), reference().as_os_str(), cut.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(out.contains("WARNING: A and B are not comparable"), "{out}");
    assert!(out.contains("B is not a complete drive"), "{out}");
    assert!(
        out.contains(&format!(
            "the metrics cover 1.500 s in A and {covered:.3} s in B"
        )),
        "{out}"
    );
}
