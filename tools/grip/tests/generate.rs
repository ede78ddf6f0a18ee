//! `grip generate`: the logs it writes read with grip-drive's reader like a
//! drive's (every topic, `grip.run` marked `source = generated`, the
//! configuration attached, the recorder's counters), `grip inspect --json`
//! gives sane figures whose counts add up, `grip replay --json` of a
//! generated log is identical (0 differing messages), the per-log draws
//! (start speed, demand, noise) land in the log, and the same seed gives
//! the same log.

mod common;

use std::path::Path;

use grip_drive::{DriveLog, LoadOptions};
use serde_json::Value;

fn grip(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    common::output(args)
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

fn generate(out: &Path, extra: &[&str]) {
    let mut args = vec![os("generate"), os("--out"), out.as_os_str()];
    args.extend(extra.iter().map(|s| os(s)));
    let (ok, stdout, stderr) = grip(&args);
    assert!(ok, "grip generate failed:\n{stdout}{stderr}");
    assert!(stdout.contains("generated"), "{stdout}");
}

/// `grip generate --out OUT EXTRA...`, which must fail; its stderr.
fn refused(out: &Path, extra: &[&str]) -> String {
    let mut args = vec![os("generate"), os("--out"), out.as_os_str()];
    args.extend(extra.iter().map(|s| os(s)));
    let (ok, _, err) = grip(&args);
    assert!(!ok, "grip generate {extra:?} was not refused");
    err
}

fn json_of(args: &[&std::ffi::OsStr]) -> Value {
    let (_, stdout, stderr) = grip(args);
    let line = stdout
        .lines()
        .find(|l| l.starts_with('{'))
        .unwrap_or_else(|| panic!("no JSON object:\n{stdout}{stderr}"));
    serde_json::from_str(line).unwrap()
}

#[test]
fn generated_logs_read_inspect_and_replay_like_drives() {
    let d = tempfile::tempdir().unwrap();
    generate(
        d.path(),
        &[
            "--count",
            "2",
            "--seed0",
            "7",
            "--controllers",
            "mfc,src",
            "--snr-db",
            "5:15",
            "--jobs",
            "2",
        ],
    );
    let mut files: Vec<_> = std::fs::read_dir(d.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert_eq!(files.len(), 2, "{files:?}");
    for (i, f) in files.iter().enumerate() {
        let seed = 7 + i as u64;
        let log = DriveLog::load_with(f, LoadOptions { audio: true }).unwrap();
        assert!(log.report.truncated.is_none(), "{:?}", log.report.truncated);
        assert_eq!(log.report.bad, 0);
        assert_eq!(log.run.get("source").map(String::as_str), Some("generated"));
        assert_eq!(log.run.get("clock").map(String::as_str), Some("scripted"));
        assert_eq!(log.run.get("seed"), Some(&seed.to_string()));
        let want = if i == 0 { "mfc" } else { "src" };
        assert_eq!(log.run.get("controller").map(String::as_str), Some(want));
        let scenario = format!("random-s{seed}");
        assert_eq!(log.run.get("scenario"), Some(&scenario));
        assert!(
            log.attachments
                .contains_key(&format!("scenarios/{scenario}.toml")),
            "{:?}",
            log.attachments.keys().collect::<Vec<_>>()
        );
        let acq = log.attachment_text("audio-acq.toml").unwrap();
        assert!(acq.contains(&format!("seed = {seed}")), "{acq}");
        assert!(acq.contains("snr_db"), "{acq}");
        assert!(log.recorder.is_some(), "no grip.recorder record");
        // 0.5 s hold + 2.4 s scenario at 1 kHz; audio at 44.1 kHz in 1024-sample blocks
        assert!(log.cycles.len() > 2800, "{}", log.cycles.len());
        assert!(log.truth.len() > 2800, "{}", log.truth.len());
        assert!(log.audio_blocks.len() > 120, "{}", log.audio_blocks.len());
        assert!(log.roads.len() > 100, "{}", log.roads.len());
        assert!(log.can.len() > 3 * log.cycles.len());

        let j = json_of(&[os("inspect"), os("--json"), f.as_os_str()]);
        assert_eq!(j["status"], "ok", "{j}");
        assert_eq!(j["simulated"], true);
        let acc = j["arte_accuracy"].as_f64().unwrap();
        assert!((0.5..=1.0).contains(&acc), "ARTE accuracy {acc}");
        let dist = j["metrics"]["distance_m"].as_f64().unwrap();
        assert!(dist > 5.0 && dist < 40.0, "distance {dist} m");
        assert_eq!(j["deadline_misses"], 0);
        let judged = j["arte_judged"].as_u64().unwrap();
        let sum = |k: &str, f: &str| -> u64 {
            j[k].as_array()
                .unwrap()
                .iter()
                .map(|x| x[f].as_u64().unwrap())
                .sum()
        };
        assert_eq!(sum("confusion", "count"), judged);
        assert_eq!(sum("speed_bands", "judged"), judged);
        assert_eq!(
            sum("speed_bands", "correct"),
            j["arte_correct"].as_u64().unwrap()
        );

        let r = json_of(&[os("replay"), os("--json"), f.as_os_str()]);
        assert_eq!(r["status"], "replayed", "{r}");
        assert_eq!(r["identical"], true, "{r}");
        assert_eq!(r["differing_messages"], 0);
        assert_eq!(r["first_divergence"], Value::Null);
    }
    // another controller diverges, and says where
    let r = json_of(&[
        os("replay"),
        os("--json"),
        os("--controller"),
        os("mtte"),
        files[0].as_os_str(),
    ]);
    assert_eq!(r["identical"], false, "{r}");
    assert!(r["first_divergence"].as_str().is_some());
}

/// The number in `text` between the first `before` and the `after` that
/// follows it.
fn number_between(text: &str, before: &str, after: &str) -> f64 {
    text.split(before)
        .nth(1)
        .and_then(|x| x.split(after).next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no number between {before:?} and {after:?}:\n{text}"))
}

/// `grip replay --closed-loop` of a generated drive, nothing changed,
/// gives every logged cycle, frame and ground-truth figure again: from rest
/// (`stop-and-go`: nothing moves until the demand has reached the motor,
/// so the plant's start is found by trying candidates; before 2026-12-06
/// it was started at the first sample that moved, 11 ms late, slip
/// deviation +18.8 %), and moving (`e2e`: before 2026-12-06 the replay
/// ran two loop cycles past the generated ones), and from rest with a
/// driver who waits 0.3 s before the demand ramps up (the start lies that
/// much before the loop's first demand; on a hill the car rolls back as the
/// plant starts, which is then the start). `grip generate` asks the plant
/// to start after its 0.5 s hold, at cycle 500.
#[test]
fn generated_drives_replay_identically_in_closed_loop_from_rest_and_moving() {
    // a driver who waits 0.3 s from rest, on the flat and on a 10 % hill
    // (where the car rolls back as the plant starts)
    let late = tempfile::tempdir().unwrap();
    let waiting = |name: &str, road: &str| {
        let p = late.path().join(format!("{name}.toml"));
        std::fs::write(
            &p,
            format!(
                "name = \"{name}\"\ndescription = \"from rest, 0.3 s wait, 0 to 300 N m over 0.2 s\"\n\
                 v0_kmh = 0.0\nsegments_by = \"distance\"\nduration = 1.5\n\
                 [demand]\nkind = \"ramp\"\nfrom = 0.0\nto = 300.0\nstart = 0.3\nduration = 0.2\n\
                 {road}"
            ),
        )
        .unwrap();
        p.to_str().unwrap().to_owned()
    };
    let late_ramp = waiting(
        "late-ramp",
        "[[segment]]\nroad = \"asphalt\"\nlength = 1.0\n[[segment]]\nroad = \"snow\"\nlength = 20.0\n",
    );
    let hill = waiting(
        "hill-wait",
        "[[segment]]\nroad = \"asphalt\"\nlength = 30.0\ngrade_pct = 10.0\n",
    );
    for (scenario, how) in [
        ("stop-and-go", "a drive from rest"),
        ("e2e", "the first ground-truth sample that moved"),
        (late_ramp.as_str(), "a drive from rest"),
        (hill.as_str(), "the first ground-truth sample that moved"),
    ] {
        let d = tempfile::tempdir().unwrap();
        generate(d.path(), &["--count", "1", "--scenario", scenario]);
        let f = d.path().join("gen-00000-s1.mcap");
        // on the log's own configuration (no --config-dir: the waiting
        // driver's scenario is in the log only)
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_grip"))
            .args([
                os("replay"),
                os("--json"),
                os("--closed-loop"),
                f.as_os_str(),
            ])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        let r: Value = stdout
            .lines()
            .find(|l| l.starts_with('{'))
            .and_then(|l| serde_json::from_str(l).ok())
            .unwrap_or_else(|| panic!("{scenario}: no JSON object:\n{stdout}"));
        assert_eq!(r["status"], "replayed", "{scenario}: {r}");
        assert_eq!(r["identical"], true, "{scenario}: {r}");
        assert_eq!(r["differing_messages"], 0, "{scenario}: {r}");
        assert_eq!(r["plant_start"]["seq"], 500, "{scenario}: {r}");
        let line = r["plant_start"]["how"].as_str().unwrap();
        assert!(line.contains(how), "{scenario}: {line}");
        if scenario == late_ramp {
            // started 0.3 s and more before the wheel moved
            let ms = number_between(line, "cycle 500, ", " ms before");
            assert!(ms >= 300.0, "{line}");
            // and the summary's scenario window starts within a
            // DriverDemand period of where the plant did (0.5 s), not at
            // the first movement 0.3 s later
            let (ok, text, err) = grip(&[os("inspect"), f.as_os_str()]);
            assert!(ok, "{text}{err}");
            let from = number_between(&text, "scenario window ", "-");
            assert!(
                (0.5..=0.512).contains(&from),
                "window from {from} s:\n{text}"
            );
        }
        for m in ["slip_deviation", "distance_m", "energy_j"] {
            let old = &r["old"]["metrics"][m];
            assert!(old.as_f64().is_some(), "{scenario}: {m}: {r}");
            assert_eq!(old, &r["new"]["metrics"][m], "{scenario}: {m}: {r}");
        }
    }
}

#[test]
fn start_speed_and_demand_are_drawn_per_log_and_a_seed_repeats() {
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let args = [
        "--count",
        "1",
        "--seed0",
        "3",
        "--scenario",
        "paper",
        "--v0-kmh",
        "20",
        "--torque",
        "150:250",
        "--hold-s",
        "0.2",
    ];
    generate(a.path(), &args);
    generate(b.path(), &args);
    let f = a.path().join("gen-00000-s3.mcap");
    let la = DriveLog::load(&f).unwrap();
    let lb = DriveLog::load(&b.path().join("gen-00000-s3.mcap")).unwrap();
    assert_eq!(la.run.get("scenario").map(String::as_str), Some("paper-s3"));
    let torque: f64 = la.run["torque_nm"].parse().unwrap();
    assert!((150.0..=250.0).contains(&torque), "{torque}");
    let sc = la.attachment_text("scenarios/paper-s3.toml").unwrap();
    assert!(sc.contains("v0_kmh = 20"), "{sc}");
    let j = json_of(&[os("inspect"), os("--json"), f.as_os_str()]);
    let v0 = j["speed_kmh_start"].as_f64().unwrap();
    assert!((v0 - 20.0).abs() < 1.0, "start speed {v0} km/h");
    let max_t = j["metrics"]["max_torque_nm"].as_f64().unwrap();
    assert!(
        max_t <= torque + 0.5,
        "max torque {max_t} > demand {torque}"
    );
    // the same seed and options: the same drive, message for message
    // (compared as text: NaN fields, e.g. an estimate without speed, are equal there)
    let text = |l: &DriveLog| format!("{:?}{:?}{:?}{:?}", l.cycles, l.roads, l.truth, l.can);
    assert!(!la.cycles.is_empty());
    assert!(text(&la) == text(&lb), "the same seed gave different logs");
    // again into the same --out: refused before any log, naming it,
    // unless --force (it replaced the log silently)
    let before = std::fs::metadata(&f).unwrap().modified().unwrap();
    let err = refused(a.path(), &args);
    assert!(
        err.contains(
            "1 of the 1 logs it would write exists (gen-00000-s3.mcap); --force replaces them"
        ),
        "{err}"
    );
    assert_eq!(std::fs::metadata(&f).unwrap().modified().unwrap(), before);
    let mut forced = args.to_vec();
    forced.push("--force");
    generate(a.path(), &forced);
    let again = DriveLog::load(&f).unwrap();
    assert!(text(&again) == text(&la), "--force wrote another drive");
}

#[test]
fn bad_options_are_refused_with_the_reason() {
    let d = tempfile::tempdir().unwrap();
    let err = refused(d.path(), &["--v0-kmh", "30:10"]);
    assert!(err.contains("LO must not exceed HI"), "{err}");
    // in the flag's unit, at once (1e9 km/h drew road sequences for ever
    // before the scenario's check in m/s refused it)
    let err = refused(d.path(), &["--v0-kmh", "1e9"]);
    assert!(
        err.contains("--v0-kmh 1000000000: a start speed must lie within 0..=360 km/h"),
        "{err}"
    );
    let err = refused(d.path(), &["--torque=-5"]);
    assert!(
        err.contains("--torque -5: a driver demand must be >= 0 N m"),
        "{err}"
    );
    let err = refused(
        d.path(),
        &["--count", "1", "--scenario", "no-such-scenario"],
    );
    assert!(err.contains("no-such-scenario"), "{err}");
}

/// Log i has seed --seed0 + i: past u64 it is refused with the reason (was
/// an overflow: a panic in a debug build), before anything is written.
#[test]
fn a_seed_range_past_u64_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("logs");
    let err = refused(&out, &["--seed0", "18446744073709551615", "--count", "2"]);
    assert!(
        err.contains("--seed0 18446744073709551615 with --count 2")
            && err.contains("overflows u64")
            && err.contains("the largest --seed0 for 2 logs is 18446744073709551614"),
        "{err}"
    );
    assert!(!out.exists(), "the output directory was created");
}

#[test]
fn the_random_recipe_is_taken_as_grip_sim_takes_it() {
    // `--random` changes the road sequence's recipe: segments of 3-5 m at
    // 150 N m, as `grip sim --scenario random --random ...` would draw them.
    let d = tempfile::tempdir().unwrap();
    generate(
        d.path(),
        &[
            "--count",
            "1",
            "--seed0",
            "4",
            "--random",
            "min_len_m=3,max_len_m=5,torque=150",
            "--hold-s",
            "0.2",
        ],
    );
    let log = DriveLog::load(&d.path().join("gen-00000-s4.mcap")).unwrap();
    let sc: toml::Table = log
        .attachment_text("scenarios/random-s4.toml")
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(sc["demand"]["torque"].as_float(), Some(150.0), "{sc}");
    let segs = sc["segment"].as_array().unwrap();
    assert!(segs.len() >= 2, "{sc}");
    // every segment but the last (which runs to the end of the cover)
    for g in &segs[..segs.len() - 1] {
        let len = g["length"].as_float().unwrap();
        assert!((3.0..=5.0).contains(&len), "segment of {len} m: {sc}");
    }
    // refused: a bad key (named), and --random with another scenario
    let err = refused(d.path(), &["--random", "min_len=3"]);
    assert!(
        err.contains("random.min_len") && err.contains("unknown key"),
        "{err}"
    );
    let err = refused(
        d.path(),
        &["--scenario", "paper", "--random", "min_len_m=3"],
    );
    assert!(err.contains("--random changes the recipe"), "{err}");
}

/// A generated drive is a drive: with `[stream]` settings the model's
/// confidence calibration was not fitted for, arte's start-up refuses it as
/// the service does, naming the field.
#[test]
fn a_calibration_fitted_for_other_stream_settings_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("config");
    common::copy_dir(&common::config_dir(), &cfg);
    let f = cfg.join("arte-svc.toml");
    let text = std::fs::read_to_string(&f).unwrap();
    assert!(text.contains("hop_s = 0.025"), "the shipped hop changed");
    std::fs::write(&f, text.replace("hop_s = 0.025", "hop_s = 0.05")).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("--config-dir")
        .arg(&cfg)
        .args(["generate", "--count", "1", "--out"])
        .arg(d.path().join("logs"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "not refused: {err}");
    assert!(
        err.contains("arte's start-up") && err.contains("stream.hop_s"),
        "{err}"
    );
}

/// A configuration directory whose `can.toml` names `tests/data/own-bus.dbc`
/// (other ids, names, byte order, units: a car's own bus), or, with
/// `edit`, that DBC changed by it.
fn own_bus_config(root: &Path, edit: impl Fn(String) -> String) -> std::path::PathBuf {
    let cfg = root.join("config");
    common::copy_dir(&common::config_dir(), &cfg);
    let dbc =
        std::fs::read_to_string(common::config_dir().join("../tests/data/own-bus.dbc")).unwrap();
    std::fs::write(cfg.join("own-bus.dbc"), edit(dbc)).unwrap();
    let can = std::fs::read_to_string(cfg.join("can.toml")).unwrap();
    assert!(can.contains("dbc = \"inverter.dbc\""), "{can}");
    let can = can.replace("dbc = \"inverter.dbc\"", "dbc = \"own-bus.dbc\"")
        + "[dbc_names]\nTorqueCommand = \"MCU_TrqCmd\"\n\"TorqueCommand.TorqueRequest\" = \"TrqReq\"\n\
           DriverDemand = \"VCU_Demand\"\n\"DriverDemand.TorqueDemand\" = \"TrqDmd\"\n";
    std::fs::write(cfg.join("can.toml"), can).unwrap();
    cfg
}

/// A drive on a bus whose DBC is not grip's: the services (here in
/// `grip generate`, which runs their start-up and cycles) speak it, the log
/// carries it, `grip inspect` names its frames and `grip replay` runs the
/// drive again identically; a DBC lacking a message is refused naming it.
#[test]
fn a_drive_on_a_foreign_bus_speaks_its_dbc() {
    use grip_io::can::protocol::{InverterMsg, MsgKind};
    let d = tempfile::tempdir().unwrap();
    let cfg = own_bus_config(d.path(), |t| t);
    let out = d.path().join("logs");
    let (ok, so, se) = common::output_in(
        &cfg,
        &[
            os("generate"),
            os("--count"),
            os("1"),
            os("--seed0"),
            os("3"),
            os("--scenario"),
            os("paper"),
            os("--out"),
            out.as_os_str(),
        ],
    );
    assert!(ok, "{so}{se}");
    let f = out.join("gen-00000-s3.mcap");
    let log = DriveLog::load(&f).unwrap();
    assert!(log.attachments.contains_key("own-bus.dbc"));
    let p = log.protocol().unwrap();
    assert_eq!(p.spec(MsgKind::TorqueCommand).id, 0x191);
    assert!(log.can.len() > 3 * log.cycles.len());
    let (mut torque_max, mut omega_max) = (0.0f64, 0.0f64);
    for c in &log.can {
        assert!((0x191..=0x195).contains(&c.id), "frame 0x{:X}", c.id);
        match InverterMsg::decode_in(&p, c).unwrap() {
            InverterMsg::TorqueCommand(t) => torque_max = torque_max.max(t.torque_request),
            InverterMsg::WheelSpeeds(w) => omega_max = omega_max.max(w.omega_driven),
            _ => {}
        }
    }
    // what the loop computed with is what the frames carried, in grip's units
    let loop_omega = log.cycles.iter().map(|c| c.omega).fold(0.0f64, f64::max);
    assert!(
        (omega_max - loop_omega).abs() < 0.02,
        "{omega_max} vs {loop_omega}"
    );
    assert!(torque_max > 100.0, "{torque_max}");
    let j = json_of(&[os("inspect"), os("--json"), f.as_os_str()]);
    assert_eq!(j["status"], "ok", "{j}");
    assert_eq!(j["e2e_rejected_frames"], 0, "{j}");
    let (_, text, _) = grip(&[os("inspect"), f.as_os_str()]);
    // named by the log's DBC, with the bus's id beside the name
    assert!(
        text.contains("bus: own-bus.dbc, attached")
            && text.contains("TorqueCommand  0x191 tx")
            && text.contains("WheelSpeeds    0x193 rx"),
        "{text}"
    );
    let r = json_of(&[os("replay"), os("--json"), f.as_os_str()]);
    assert_eq!(r["identical"], true, "{r}");

    let e = tempfile::tempdir().unwrap();
    let cfg = own_bus_config(e.path(), |t| {
        t.replace("BO_ 403 WheelSpeeds", "BO_ 403 WheelSpeed")
    });
    let (ok, _, err) = common::output_in(
        &cfg,
        &[
            os("generate"),
            os("--count"),
            os("1"),
            os("--out"),
            out.as_os_str(),
        ],
    );
    assert!(!ok, "not refused");
    assert!(
        err.contains("own-bus.dbc")
            && err.contains("message WheelSpeeds")
            && err.contains("not in the DBC"),
        "{err}"
    );
    // grip drive refuses it before starting any service (it started the
    // recorder, left an empty log and reported an empty drive)
    let log = e.path().join("drive.mcap");
    let (ok, so, err) = common::output_in(&cfg, &[os("drive"), os("--out"), log.as_os_str()]);
    assert!(!ok, "not refused: {so}");
    assert!(
        err.contains("the CAN bus (can.toml's dbc)") && err.contains("message WheelSpeeds"),
        "{err}"
    );
    assert!(!log.exists() && !err.contains("recorder"), "{err}");
}
