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
        out.contains("asphalt -> snow at 0.500 s (x 1.66 m), limit 182.7 N m"),
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

/// `--json` carries what the text's preview and release lines say (a
/// trial found the preview in the text only), the largest slip with its
/// time, how often road knowledge's cap bound the command beside how often
/// the estimate passed the loop's gate, and the number of driven wheels
/// the torques are per. Figures of the stored reference drive (e2e: the
/// wheel meets snow unpreviewed at 0.5 s, leaves it for gravel at 1.0 s).
#[test]
fn inspect_json_has_the_preview_the_releases_and_the_largest_slip() {
    let j = json_of(&reference());
    let p = j["preview"].as_array().unwrap();
    assert_eq!(p.len(), 1, "{j}");
    assert_eq!(
        (p[0]["from"].as_str(), p[0]["to"].as_str()),
        (Some("asphalt"), Some("snow"))
    );
    assert!(p[0]["ahead_s"].is_null(), "no preview at lead 0: {}", p[0]);
    let r = j["releases"].as_array().unwrap();
    assert_eq!(r.len(), 1, "{j}");
    assert_eq!(
        (r[0]["from"].as_str(), r[0]["to"].as_str()),
        (Some("snow"), Some("gravel"))
    );
    assert_eq!(r[0]["release"], "after");
    let after = r[0]["release_s"].as_f64().unwrap();
    assert!((0.0..0.2).contains(&after), "{}", r[0]);
    // the text says the same to its three decimals
    let (ok, out, err) = common::output(&["inspect".as_ref(), reference().as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains(&format!("command rose above it {after:.3} s")),
        "{out}"
    );
    let (slip, at) = (
        j["max_slip"].as_f64().unwrap(),
        j["max_slip_s"].as_f64().unwrap(),
    );
    assert!(
        out.contains(&format!(
            "max slip |λ|                    {slip:.4} at {at:.3} s"
        )),
        "{out}"
    );
    assert!((0.5..0.7).contains(&at), "the snow entry: {at}");
    assert!(p[0]["max_slip_after"].as_f64().unwrap() <= slip);
    let (capped, used, active) = (
        j["arte_capped_cycles"].as_u64().unwrap(),
        j["arte_used_cycles"].as_u64().unwrap(),
        j["arte_active_cycles"].as_u64().unwrap(),
    );
    assert!(
        capped > 0 && capped < active && used <= active,
        "{capped} {used} {active}"
    );
    assert_eq!(j["n_driven"], 4.0, "the paper's quarter car");
    // each road change's first estimate and its first past the loop's gate
    assert_eq!(j["arte_min_confidence"], 0.6);
    assert_eq!(j["arte_min_confidence_from_log"], true);
    for c in j["road_changes"].as_array().unwrap() {
        let (d, g) = (
            c["delay_s"].as_f64().unwrap(),
            c["gated_delay_s"].as_f64().unwrap(),
        );
        assert!(g >= d, "{c}");
    }
    let m = j["measured"]["max_abs_slip_s"].as_f64().unwrap();
    assert!((0.5..0.7).contains(&m), "{m}");
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
    // the reference drive of 2026-12-05 (regenerated for the loop's
    // roads_taken): no deadline missed during its scenario (an earlier
    // one had 12, all from its host's scheduling)
    assert_eq!(j["deadline_misses_in_scenario"], 0);
    assert_eq!(
        (j["arte_judged"].as_u64(), j["arte_correct"].as_u64()),
        (Some(60), Some(60))
    );
    assert_eq!(
        j["arte_judged_whole_log"], 71,
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
    std::os::unix::fs::symlink(reference(), d.path().join("ref.mcap")).unwrap();
    let (ok, out, err, csv) = common::inspect_dir(d.path());
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

/// `grip replay REFERENCE --out DIR/NAME [ARGS]`: the written log and the
/// report.
fn replayed(dir: &Path, name: &str, extra: &[&std::ffi::OsStr]) -> (PathBuf, String) {
    let p = dir.join(name);
    let r = reference();
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "replay".as_ref(),
        r.as_os_str(),
        "--out".as_ref(),
        p.as_os_str(),
    ];
    args.extend_from_slice(extra);
    let (ok, out, err) = common::output(&args);
    assert!(ok, "{out}{err}");
    (p, out)
}

/// A log of `grip replay --out` has no `grip.recorder` record (there is no
/// recorder): `grip inspect` recognises its `grip.replay` record and says
/// whose replay it is instead of a crash warning, `grip inspect A B`
/// compares it with its drive (saying what an open-loop replay's plant
/// metrics are) instead of calling it incomplete, and the directory table
/// and `--json` agree.
#[test]
fn a_replay_log_is_recognised_and_compares_with_its_drive() {
    let d = tempfile::tempdir().unwrap();
    let (rep, _) = replayed(d.path(), "replay.mcap", &[]);
    let (ok, out, err) = common::output(&["inspect".as_ref(), rep.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains(&format!("replay of {} (open loop)", reference().display())),
        "{out}"
    );
    assert!(!out.contains("the recorder did not finish"), "{out}");
    assert!(!out.contains("WARNING"), "{out}");
    // replayed again it would run the source drive's configuration, not
    // the what-if it ran: refused, naming the source (it reported a
    // divergence)
    let (ok, out, err) = common::output(&["replay".as_ref(), rep.as_os_str()]);
    assert!(!ok, "{out}{err}");
    assert!(
        err.contains("the output of `grip replay`")
            && err.contains(&format!(
                "replay the source drive {}",
                reference().display()
            )),
        "{err}"
    );

    let (ok, out, err) =
        common::output(&["inspect".as_ref(), reference().as_os_str(), rep.as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(!out.contains("not a complete drive"), "{out}");
    assert!(!out.contains("not comparable"), "{out}");
    assert!(
        out.contains("NOTE: B is a replay of") && out.contains("its plant metrics"),
        "{out}"
    );

    let j = json_of(&rep);
    assert_eq!(j["status"], "ok", "{j}");
    assert_eq!(j["replay"]["mode"], "open loop", "{j}");
    assert_eq!(
        j["replay"]["source"].as_str(),
        Some(reference().display().to_string().as_str())
    );
    assert!(
        !j["warnings"].to_string().contains("grip.recorder"),
        "{}",
        j["warnings"]
    );
    assert!(json_of(&reference())["replay"].is_null());

    // a what-if replay: its own controller, not the source's grip.run
    let (src, _) = replayed(
        d.path(),
        "src.mcap",
        &["--controller".as_ref(), "src".as_ref()],
    );
    assert_eq!(json_of(&src)["controller"], "src");
    let (ok, out, err) =
        common::output(&["inspect".as_ref(), reference().as_os_str(), src.as_os_str()]);
    assert!(ok, "{out}{err}");
    let row: Vec<&str> = out
        .lines()
        .find(|l| l.starts_with("controller "))
        .unwrap()
        .split_whitespace()
        .collect();
    assert_eq!(row, ["controller", "mtte", "src"], "{out}");
}

/// The model arte ran is named (arte-svc.toml's `model`, attached to the
/// log, with its SHA-256), in the summary, `--json` and `grip inspect A B`,
/// which flags two logs that ran different models (here a replay with
/// `--model`, whose `grip.replay` record names the model it ran).
#[test]
fn the_model_arte_ran_is_named() {
    let (ok, out, err) = common::output(&["inspect".as_ref(), reference().as_os_str()]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains(
            "\n  model: models/default.model (sha256 4a6ce5407aaf, arte-svc.toml's model, attached to the log)\n"
        ),
        "{out}"
    );
    let j = json_of(&reference());
    assert_eq!(j["model"], "models/default.model", "{j}");
    assert_eq!(j["model_sha256"], j["run"]["model.models/default.model"]);

    let d = tempfile::tempdir().unwrap();
    let paper = common::config_dir().join("models/paper.model");
    let (rep, _) = replayed(
        d.path(),
        "paper.mcap",
        &["--model".as_ref(), paper.as_os_str()],
    );
    let sha = j["run"]["model.models/paper.model"].as_str().unwrap();
    let r = json_of(&rep);
    assert_eq!(r["model_sha256"].as_str(), Some(sha), "{r}");
    let (ok, out, err) =
        common::output(&["inspect".as_ref(), reference().as_os_str(), rep.as_os_str()]);
    assert!(ok, "{out}{err}");
    let row = out
        .lines()
        .find(|l| l.starts_with("model (sha256)"))
        .unwrap_or_else(|| panic!("no model row in\n{out}"));
    assert!(
        row.contains("4a6ce5407aaf") && row.contains(&sha[..12]) && row.ends_with("DIFFER"),
        "{row}"
    );
    assert!(out.contains("NOTE: A and B ran different models"), "{out}");
    // the same model on both sides is not flagged
    let (_, out, _) = common::output(&[
        "inspect".as_ref(),
        reference().as_os_str(),
        reference().as_os_str(),
    ]);
    assert!(
        !out.contains("DIFFER") && !out.contains("different models"),
        "{out}"
    );
}

/// `grip inspect DIR`'s printed table: numbers rounded, ARTE accuracy in
/// %, the road changes missed beside the delay, and the deadline misses
/// named so (no bare `misses` column to read as missed changes).
#[test]
fn the_directory_table_is_rounded_and_unambiguous() {
    let d = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(reference(), d.path().join("ref.mcap")).unwrap();
    let (ok, out, err) = common::output(&["inspect".as_ref(), d.path().as_os_str()]);
    assert!(ok, "{out}{err}");
    let mut lines = out.lines();
    let head: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    assert!(!head.contains(&"misses"), "{head:?}");
    let row: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    let col = |name: &str| {
        let i = head
            .iter()
            .position(|c| *c == name)
            .unwrap_or_else(|| panic!("no column {name} in {head:?}"));
        row[i]
    };
    assert_eq!(col("slip_dev"), "0.0381", "{out}");
    assert_eq!(col("effort"), "240.3", "{out}");
    assert_eq!(col("dist_m"), "6.60", "{out}");
    assert_eq!(col("arte_acc_%"), "100.0", "{out}");
    assert_eq!(col("delay_s"), "0.083", "{out}");
    assert_eq!(col("missed"), "0/2", "{out}");
    assert_eq!(col("deadline_misses"), "0", "{out}");
    // the delay column is followed by the missed changes
    let delay = head.iter().position(|c| *c == "delay_s").unwrap();
    assert_eq!(head[delay + 1], "missed", "{head:?}");
}

/// `grip replay`'s table: every row labelled with its window (the
/// scenario's, as `grip inspect` gives it, or the whole log), and the
/// blocks through arte counted as the blocks the "not classified" line
/// counts.
#[test]
fn the_replay_table_says_each_rows_window() {
    let (ok, out, err) = common::output(&["replay".as_ref(), reference().as_os_str()]);
    assert!(ok, "{out}{err}");
    let through: usize = out
        .split(" audio blocks through ArteLoop::on_block")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    assert!(
        out.contains(&format!("arte's blocks not classified, of {through}: none")),
        "{out}"
    );
    assert!(out.contains("(of the log's 85: "), "{out}");
    let row = |name: &str| -> Vec<String> {
        let l = out
            .lines()
            .find(|l| l.trim_start().starts_with(name))
            .unwrap_or_else(|| panic!("no row {name:?} in\n{out}"));
        l[l.find(name).unwrap() + name.len()..]
            .split_whitespace()
            .map(str::to_owned)
            .collect()
    };
    // inspect: no cycle of the scenario in the safe state, 107 in the log
    assert_eq!(
        row("cycles in the safe state (scenario)"),
        ["0.000", "0.000"]
    );
    assert_eq!(
        row("cycles in the safe state (whole log)"),
        ["107.000", "107.000"]
    );
    for r in [
        "mean torque command, N m (time-weighted, scenario)",
        "max torque command, N m (active cycles, scenario)",
        "mean torque taken off the demand, N m (time-weighted, scenario)",
        "cycles using ARTE, % (active cycles, scenario)",
        "ARTE accuracy vs ground truth, % (scenario)",
        "ARTE accuracy vs ground truth, % (whole log)",
    ] {
        assert_eq!(row(r).len(), 2, "{r}: {out}");
    }
    let (ok, out, err) = common::output(&[
        "replay".as_ref(),
        "--json".as_ref(),
        reference().as_os_str(),
    ]);
    assert!(ok, "{out}{err}");
    let j: Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
    assert_eq!(j["old"]["safe_cycles"], 107.0, "{j}");
    assert_eq!(j["old"]["safe_cycles_in_scenario"], 0.0, "{j}");
    assert_eq!(j["old"]["arte_accuracy_whole_log"], 1.0, "{j}");
    // one computation: replay's mean torque command and the torque taken
    // off the demand in the scenario are inspect's measured figures (until
    // 2026-12-05 replay's unweighted mean over the active cycles differed)
    let m = &json_of(&reference())["measured"];
    let (cmd, withheld, time) = (
        m["mean_cmd_nm"].as_f64().unwrap(),
        m["withheld_nms"].as_f64().unwrap(),
        m["time_s"].as_f64().unwrap(),
    );
    let got = j["old"]["mean_torque_cmd_nm_in_scenario"].as_f64().unwrap();
    assert!((got - cmd).abs() < 1e-9, "replay {got}, inspect {cmd}");
    let cut = j["old"]["mean_torque_cut_nm_in_scenario"].as_f64().unwrap();
    assert!(
        (cut - withheld / time).abs() < 1e-9,
        "replay {cut}, inspect {}",
        withheld / time
    );
}

/// The inverter section of the reference drive as it is: plant-sim, the
/// inverter, comes up reporting Fault and CmdTimeout with FaultCode 0x01
/// (no command has reached it yet) in its first frame, 0.073 s before the
/// scenario start, and reports ready with no flag in every frame after it,
/// the scenario's 1499 and the stop's (it ends before tcs-loop stops
/// sending, so the log has no timeout after the drive). The start-up
/// episode is listed before the scenario, from the inverter's first frame,
/// with the loop already in its safe state (start-up); `--json` gives the
/// same, and `command_timeouts` (clear → set) stays 0.
#[test]
fn inspect_shows_the_inverter_as_its_motor_status_frames_report_it() {
    let (ok, out, err) = common::output(&["inspect".as_ref(), reference().as_os_str()]);
    assert!(ok, "{out}{err}");
    let want = "
inverter (its MotorStatus frames tcs-loop received and the E2E check accepted: 1675, -0.073 to 1.602 s; t from the scenario start)
  during the scenario (0.000-1.500 s, 1499 frames): ready throughout, no fault, derating or command timeout
  whole log: fault 1 (0.001 s), derating 0, command timeout 1 (0.001 s), not ready 0
  fault: 1 episode (1 before the scenario)
    -0.073 to -0.072 s (0.001 s, 1 frame), before the scenario, from the inverter's first frame, FaultCode 0x01: the loop in its safe state throughout (1 cycle)
  command timeout: 1 episode (1 before the scenario)
    -0.073 to -0.072 s (0.001 s, 1 frame), before the scenario, from the inverter's first frame
  fault codes: 0x01 first at -0.073 s (1 frame)
";
    assert!(out.contains(want), "{want} not in\n{out}");
    // after the CAN section, before ARTE's
    let at = |s: &str| out.find(s).unwrap_or_else(|| panic!("{s:?} not in\n{out}"));
    assert!(at("\nCAN frames") < at("\ninverter (") && at("\ninverter (") < at("\nARTE ("));

    let j = json_of(&reference());
    let inv = &j["inverter"];
    assert_eq!(inv["motor_status_frames"], 1675, "{inv}");
    assert_eq!(inv["rejected_frames"], 0);
    assert_eq!(inv["frames_in_scenario"], 1499);
    assert_eq!(inv["origin"], "scenario_start");
    assert_eq!(inv["clean"], false);
    for flag in ["fault", "cmd_timeout"] {
        let f = &inv[flag];
        assert_eq!(
            (
                f["episodes"].as_u64(),
                f["entered"].as_u64(),
                f["episodes_in_scenario"].as_u64(),
                f["before_scenario"].as_u64()
            ),
            (Some(1), Some(0), Some(0), Some(1)),
            "{flag}: {f}"
        );
        let e = &f["listed"][0];
        assert_eq!(e["place"], "before", "{e}");
        assert_eq!(e["at_first_frame"], true, "{e}");
        assert!(
            (e["start_s"].as_f64().unwrap() + 0.0732).abs() < 1e-3,
            "{e}"
        );
    }
    assert_eq!(
        inv["fault"]["listed"][0]["fault_codes"],
        serde_json::json!([1])
    );
    // the loop's first cycle read it: safe from the start, nothing before
    assert_eq!(inv["fault"]["listed"][0]["safe_before"], false);
    assert_eq!(inv["fault"]["safe_throughout"], 1);
    // the totals over every fault episode: here the one listed, before
    // the scenario (none of its cycles in it)
    let f = &inv["fault"];
    assert!(f["listed"][0]["cycles"].as_u64() > Some(0), "{f}");
    assert_eq!(f["loop_cycles"], f["listed"][0]["cycles"], "{f}");
    assert_eq!(f["loop_cycles_safe"], f["listed"][0]["safe_cycles"], "{f}");
    assert_eq!(f["loop_cycles_in_scenario"], 0, "{f}");
    assert_eq!(f["loop_cycles_safe_in_scenario"], 0, "{f}");
    assert_eq!(inv["derating"]["loop_cycles"], serde_json::Value::Null);
    for flag in ["derating", "not_ready"] {
        assert_eq!(inv[flag]["episodes"], 0, "{flag}: {inv}");
    }
    assert_eq!(inv["fault_codes"][0]["code"], 1, "{inv}");
    assert_eq!(inv["fault_codes"][0]["frames"], 1, "{inv}");
    assert_eq!(inv["fault_codes"].as_array().map(Vec::len), Some(1));
    assert_eq!(j["command_timeouts"], 0, "no clear -> set in the drive");
}
