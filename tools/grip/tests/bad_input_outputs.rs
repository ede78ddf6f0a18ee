//! Bad input gets a clear error naming the file, field and reason, and
//! loses nothing (a bad-input trial of 2026-12-06):
//!
//! - an output that exists is refused unless `--force`, naming it, before
//!   any work: `grip replay --out` (a file, and the files of a directory of
//!   logs), `grip inspect --candump`, `--csv DIR` and `--plot DIR` (the
//!   files in them), `grip features --out`, `grip roads --plot`, `grip
//!   dataset synth --out`, `grip calibrate --out` (the input model too);
//! - `grip train --out` in a folder that does not exist is refused (it
//!   used to create every missing folder, at the root too); a directory as
//!   `--out` or `--report` is said to be one, before the training;
//! - wording: `--set KEY=1e999` is out of f64's range (not "a bare word"),
//!   a model's reason is said once, a missing log's once, `grip analyze
//!   --src-nominal-road lava` prints nothing before its error, a cycle
//!   `seq` of u64::MAX is no gap of 1.8e19 messages and a ground-truth
//!   speed of -1e308 m/s is said to be damage.

mod common;

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use grip_io::mcaplog::{McapWriter, McapWriterOptions, RunInfo};
use grip_msgs::{CycleRecord, topics};

fn os(s: &str) -> &OsStr {
    s.as_ref()
}

/// The shipped reference drive (read only).
fn reference() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap")
}

/// `grip ARGS` on the repository's configuration: (success, stdout, stderr).
fn grip(args: &[&OsStr]) -> (bool, String, String) {
    common::output(args)
}

/// A file holding `mine`, which nothing may replace.
fn mine(path: &Path) -> PathBuf {
    std::fs::write(path, b"mine").unwrap();
    path.to_path_buf()
}

fn kept(path: &Path) {
    assert_eq!(
        std::fs::read(path).unwrap(),
        b"mine",
        "{} was replaced",
        path.display()
    );
}

/// The refusal of an existing `flag FILE`.
fn refused(ok: bool, err: &str, flag: &str, file: &Path) {
    assert!(!ok, "{flag} {} was not refused", file.display());
    assert!(
        err.contains(&format!("{flag} {}", file.display()))
            && err.contains("already exists")
            && err.contains("--force"),
        "{err}"
    );
}

#[test]
fn replay_and_inspect_refuse_an_existing_output_unless_forced() {
    let d = tempfile::tempdir().unwrap();
    let log = reference();

    // grip replay LOG --out FILE
    let out = mine(&d.path().join("old.mcap"));
    let (ok, so, err) = grip(&[os("replay"), log.as_os_str(), os("--out"), out.as_os_str()]);
    refused(ok, &err, "--out", &out);
    assert!(so.is_empty(), "replayed before refusing:\n{so}");
    kept(&out);
    let (ok, so, err) = grip(&[
        os("replay"),
        log.as_os_str(),
        os("--out"),
        out.as_os_str(),
        os("--force"),
    ]);
    assert!(ok, "{so}{err}");
    assert!(std::fs::read(&out).unwrap().starts_with(b"\x89MCAP"));

    // grip replay DIR --out DIR: a log of that name already there
    let logs = d.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    std::fs::copy(&log, logs.join("a.mcap")).unwrap();
    let outdir = d.path().join("replayed");
    std::fs::create_dir(&outdir).unwrap();
    let there = mine(&outdir.join("a.mcap"));
    let (ok, _, err) = grip(&[
        os("replay"),
        logs.as_os_str(),
        os("--out"),
        outdir.as_os_str(),
    ]);
    assert!(!ok, "--out DIR with a.mcap in it was not refused");
    assert!(
        err.contains(&there.display().to_string()) && err.contains("--force"),
        "{err}"
    );
    kept(&there);

    // grip inspect LOG --candump FILE (the reference drive's bus log has no
    // frame: the file was replaced by an empty dump)
    let dump = mine(&d.path().join("bus.log"));
    let (ok, so, err) = grip(&[
        os("inspect"),
        log.as_os_str(),
        os("--candump"),
        dump.as_os_str(),
    ]);
    refused(ok, &err, "--candump", &dump);
    assert!(so.is_empty(), "summarised before refusing:\n{so}");
    kept(&dump);
    let (ok, so, err) = grip(&[
        os("inspect"),
        log.as_os_str(),
        os("--candump"),
        dump.as_os_str(),
        os("--force"),
    ]);
    assert!(ok && so.contains("wrote"), "{so}{err}");

    // --csv DIR and --plot DIR: the files they would replace
    let csv = d.path().join("csv");
    std::fs::create_dir(&csv).unwrap();
    let cycles = mine(&csv.join("cycles.csv"));
    let (ok, so, err) = grip(&[os("inspect"), log.as_os_str(), os("--csv"), csv.as_os_str()]);
    assert!(!ok && so.is_empty(), "{so}{err}");
    assert!(
        err.contains(&format!("--csv {}", csv.display()))
            && err.contains("cycles.csv")
            && err.contains("--force"),
        "{err}"
    );
    kept(&cycles);
    let plots = d.path().join("plots");
    std::fs::create_dir(&plots).unwrap();
    let png = mine(&plots.join("timing.png"));
    let (ok, _, err) = grip(&[
        os("inspect"),
        log.as_os_str(),
        os("--plot"),
        plots.as_os_str(),
    ]);
    assert!(
        !ok && err.contains("timing.png") && err.contains("--force"),
        "{err}"
    );
    kept(&png);
    // a file given as --csv DIR is said to be one
    let (ok, _, err) = grip(&[
        os("inspect"),
        log.as_os_str(),
        os("--csv"),
        dump.as_os_str(),
    ]);
    assert!(!ok && err.contains("is a file, not a directory"), "{err}");
}

#[test]
fn train_checks_its_output_paths_before_any_work() {
    let d = tempfile::tempdir().unwrap();
    // no such data: every error below comes before the data is read
    let data = d.path().join("no-data");
    let train = |extra: &[&OsStr]| {
        let mut a = vec![os("train"), os("--data"), data.as_os_str()];
        a.extend_from_slice(extra);
        grip(&a)
    };
    // a missing folder is not created (it was, even at the root)
    let missing = d.path().join("not-there/deeper");
    let out = missing.join("x.model");
    let (ok, _, err) = train(&[os("--out"), out.as_os_str()]);
    assert!(!ok);
    assert!(
        err.contains(&format!("--out {}", out.display()))
            && err.contains(&format!("the folder {} does not exist", missing.display())),
        "{err}"
    );
    assert!(!d.path().join("not-there").exists(), "a folder was created");
    // a directory is said to be one (not "the file already exists")
    let (ok, _, err) = train(&[os("--out"), d.path().as_os_str()]);
    assert!(!ok && err.contains("is a directory, not a file"), "{err}");
    let (ok, _, err) = train(&[os("--out"), d.path().as_os_str(), os("--force")]);
    assert!(!ok && err.contains("is a directory, not a file"), "{err}");
    // --report: checked before the training (it failed after the model
    // was written)
    let model = d.path().join("m.model");
    let (ok, _, err) = train(&[
        os("--out"),
        model.as_os_str(),
        os("--report"),
        d.path().as_os_str(),
    ]);
    assert!(!ok, "--report DIR was not refused");
    assert!(
        err.contains(&format!("--report {}", d.path().display()))
            && err.contains("is a directory")
            && !err.contains("no-data"),
        "{err}"
    );
    let report = mine(&d.path().join("my-report.txt"));
    let (ok, _, err) = train(&[
        os("--out"),
        model.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    refused(ok, &err, "--report", &report);
    kept(&report);
    assert!(!model.exists());
}

#[test]
fn other_outputs_refuse_existing_files() {
    let d = tempfile::tempdir().unwrap();
    // grip features FILE --out CSV
    let wav = d.path().join("a.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for i in 0..44_100 {
        w.write_sample(((i * 37) % 2000 - 1000) as i16).unwrap();
    }
    w.finalize().unwrap();
    let csv = mine(&d.path().join("f.csv"));
    let (ok, _, err) = grip(&[
        os("features"),
        wav.as_os_str(),
        os("--out"),
        csv.as_os_str(),
    ]);
    refused(ok, &err, "--out", &csv);
    kept(&csv);
    let (ok, so, err) = grip(&[
        os("features"),
        wav.as_os_str(),
        os("--out"),
        csv.as_os_str(),
        os("--force"),
    ]);
    assert!(ok, "{so}{err}");
    assert!(
        std::fs::read_to_string(&csv)
            .unwrap()
            .starts_with("t_start")
    );

    // grip roads --plot FILE
    let png = mine(&d.path().join("roads.png"));
    let (ok, so, err) = grip(&[os("roads"), os("--plot"), png.as_os_str()]);
    refused(ok, &err, "--plot", &png);
    assert!(so.is_empty(), "{so}");
    kept(&png);

    // grip dataset synth --out DIR holding an earlier dataset's manifest
    let ds = d.path().join("ds");
    std::fs::create_dir(&ds).unwrap();
    let manifest = mine(&ds.join("manifest.csv"));
    let (ok, _, err) = grip(&[
        os("dataset"),
        os("synth"),
        os("--out"),
        ds.as_os_str(),
        os("--recordings-per-class"),
        os("1"),
        os("--duration"),
        os("0.2"),
    ]);
    assert!(!ok, "an earlier dataset's manifest was not kept");
    assert!(
        err.contains(&manifest.display().to_string()) && err.contains("--force"),
        "{err}"
    );
    kept(&manifest);
    assert_eq!(std::fs::read_dir(&ds).unwrap().count(), 1, "files written");

    // grip calibrate --out: an existing file, and the input model itself
    let model = d.path().join("m.model");
    std::fs::copy(common::config_dir().join("models/paper.model"), &model).unwrap();
    let before = std::fs::read(&model).unwrap();
    let nowhere = d.path().join("no-changes");
    let (ok, _, err) = grip(&[
        os("calibrate"),
        os("--model"),
        model.as_os_str(),
        os("--data"),
        nowhere.as_os_str(),
        os("--out"),
        model.as_os_str(),
    ]);
    assert!(!ok);
    assert!(
        err.contains(&format!("--out {}", model.display()))
            && err.contains("the input model")
            && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read(&model).unwrap(), before);
    let other = mine(&d.path().join("other.model"));
    let (ok, _, err) = grip(&[
        os("calibrate"),
        os("--model"),
        model.as_os_str(),
        os("--data"),
        nowhere.as_os_str(),
        os("--out"),
        other.as_os_str(),
    ]);
    refused(ok, &err, "--out", &other);
    kept(&other);
}

/// `paper.model` with its MLP cut to 5 weights (checksum right).
fn model_with_5_weights(path: &Path) {
    let bytes = std::fs::read(common::config_dir().join("models/paper.model")).unwrap();
    let nl = bytes.iter().position(|&b| b == b'\n').unwrap();
    let header = std::str::from_utf8(&bytes[..nl]).unwrap();
    let mut v: serde_json::Value = serde_json::from_slice(&bytes[nl + 1..]).unwrap();
    let w = v["classifier"]["mlp"]["weights"].as_array_mut().unwrap();
    w.truncate(5);
    let payload = serde_json::to_vec(&v).unwrap();
    let magic = header.split(" sha256=").next().unwrap();
    let mut out = format!("{magic} sha256={}\n", grip_digest::sha256_hex(&payload)).into_bytes();
    out.extend_from_slice(&payload);
    std::fs::write(path, out).unwrap();
}

#[test]
fn errors_say_their_reason_once_and_before_any_output() {
    let d = tempfile::tempdir().unwrap();
    // --set with a number out of f64's range
    let (ok, _, err) = grip(&[
        os("replay"),
        reference().as_os_str(),
        os("--set"),
        os("mfc.k_mfc=1e999"),
    ]);
    assert!(!ok);
    assert!(
        err.contains("1e999 is out of f64's range") && !err.contains("bare word"),
        "{err}"
    );
    let (ok, _, err) = grip(&[
        os("replay"),
        reference().as_os_str(),
        os("--set"),
        os("mfc.k_mfc=nan"),
    ]);
    assert!(!ok && err.contains("nan is not a finite number"), "{err}");

    // a model's reason once
    let bad = d.path().join("bad.model");
    model_with_5_weights(&bad);
    let wav = d.path().join("a.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for i in 0..44_100 {
        w.write_sample(((i * 37) % 2000 - 1000) as i16).unwrap();
    }
    w.finalize().unwrap();
    let (ok, _, err) = grip(&[
        os("classify"),
        wav.as_os_str(),
        os("--model"),
        bad.as_os_str(),
    ]);
    assert!(!ok);
    assert_eq!(err.matches("5 weights given").count(), 1, "{err}");
    assert!(err.contains(&bad.display().to_string()), "{err}");

    // a missing log's reason once
    let missing = d.path().join("missing.mcap");
    let (ok, so, err) = grip(&[os("inspect"), missing.as_os_str()]);
    assert!(!ok && so.is_empty());
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
    assert!(err.contains(&missing.display().to_string()), "{err}");

    // options that do nothing where they are given are refused (they were
    // ignored, exit 0)
    for (args, want) in [
        (
            vec![reference().into_os_string(), "--strict".into()],
            "--strict takes a directory of logs",
        ),
        (
            vec![
                d.path().as_os_str().to_owned(),
                "--plot".into(),
                d.path().join("p").into_os_string(),
            ],
            "--plot and --candump take one log",
        ),
    ] {
        let mut a: Vec<&OsStr> = vec![os("inspect")];
        a.extend(args.iter().map(|x| x.as_os_str()));
        let (ok, _, err) = grip(&a);
        assert!(!ok && err.contains(want), "{args:?}: {err}");
    }

    // two paths, one a directory: named, with what A B takes (it said
    // "reading DIR: Is a directory (os error 21)")
    let (ok, so, err) = grip(&[os("inspect"), reference().as_os_str(), d.path().as_os_str()]);
    assert!(!ok && so.is_empty());
    assert!(
        err.contains(&format!(
            "{} is a directory: `grip inspect A B` compares two logs",
            d.path().display()
        )),
        "{err}"
    );

    // grip analyze: the road checked before the analysis is printed
    let (ok, so, err) = grip(&[os("analyze"), os("--src-nominal-road"), os("lava")]);
    assert!(!ok && err.contains("--src-nominal-road `lava`"), "{err}");
    assert!(so.is_empty(), "printed before the error:\n{so}");
}

/// `grip replay` says a bad `--model`'s reason once (arte's start-up error
/// said it, and returned it as its source, which `{:#}` printed again) and
/// a missing or foreign log's reason and path once (the reader's I/O error
/// said the OS's reason and returned it as its source; "reading PATH: PATH:
/// No such file or directory (os error 2): No such file or directory (os
/// error 2)").
#[test]
fn replay_says_a_model_s_and_a_log_s_reason_once() {
    let d = tempfile::tempdir().unwrap();
    let garbage = d.path().join("garbage.model");
    std::fs::write(&garbage, "garbage\n").unwrap();
    let bad = d.path().join("bad.model");
    model_with_5_weights(&bad);
    for (model, reason) in [
        (&garbage, "not a grip ARTE model: header must start with"),
        (&bad, "5 weights given"),
    ] {
        let (ok, _, err) = grip(&[
            os("replay"),
            reference().as_os_str(),
            os("--model"),
            model.as_os_str(),
        ]);
        assert!(!ok);
        assert_eq!(err.matches(reason).count(), 1, "{err}");
        assert_eq!(
            err.matches(&*model.display().to_string()).count(),
            1,
            "{err}"
        );
    }
    let missing = d.path().join("missing.mcap");
    let foreign = d.path().join("foreign.mcap");
    std::fs::write(&foreign, "not a log").unwrap();
    for (log, reason) in [
        (&missing, "No such file or directory (os error 2)"),
        (&foreign, "not an MCAP file"),
    ] {
        for cmd in ["replay", "inspect"] {
            let (ok, so, err) = grip(&[os(cmd), log.as_os_str()]);
            assert!(!ok && so.is_empty(), "{cmd}: {so}");
            assert_eq!(
                err.trim_end(),
                format!("error: reading {}: {reason}", log.display())
                    + if log == &foreign {
                        " (magic bytes missing)"
                    } else {
                        ""
                    },
                "{cmd}"
            );
        }
    }
}

/// A vehicle whose microphone leads the wheel with a scenario in time
/// segments: `grip generate` refuses it naming the files, field and reason
/// once (plant-sim's start-up error said its model's error in its message
/// and returned it as its source too, so the printed chain said it twice).
/// Since 2026-12-07 the rule is `Scenario::check_mic_lead`'s, checked with
/// the scenario: the scenario file's `segments_by`, with the vehicle file
/// named; `grip sim` gives the same error.
#[test]
fn generate_says_plant_sim_s_reason_once() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("cfg");
    common::copy_dir(&common::config_dir(), &cfg);
    let vehicle = cfg.join("vehicles/front-mic.toml");
    let out = d.path().join("out");
    let scenario = cfg.join("scenarios/e2e.toml");
    let reason = "scenario `e2e` is in time segments";
    // the command's stderr: refused, the reason and both files named once
    let refused = |args: &[&OsStr]| {
        let mut a = args.to_vec();
        a.extend([
            os("--scenario"),
            os("e2e"),
            os("--vehicle"),
            vehicle.as_os_str(),
        ]);
        let (ok, _, err) = common::output_in(&cfg, &a);
        assert!(!ok, "{err}");
        assert_eq!(err.matches(reason).count(), 1, "{err}");
        assert_eq!(err.matches("field `segments_by`").count(), 1, "{err}");
        for file in [&vehicle, &scenario] {
            let n = err.matches(&*file.display().to_string()).count();
            assert_eq!(n, 1, "{err}");
        }
        err
    };
    let generate = refused(&[
        os("generate"),
        os("--out"),
        out.as_os_str(),
        os("--count"),
        os("1"),
    ]);
    // grip sim: the same error line
    let sim = refused(&[os("sim"), os("--seeds"), os("1")]);
    let line = |e: &str| e.lines().find(|l| l.contains(reason)).unwrap().to_owned();
    assert_eq!(line(&sim), line(&generate));
}

/// A 3 s drive whose cycle 1500 carries seq u64::MAX and whose ground
/// truth at 2 s says V = -1e308 m/s (damaged numbers).
fn write_damaged(path: &Path) {
    let mut w = McapWriter::create(path, McapWriterOptions::default()).unwrap();
    let mut extra = BTreeMap::new();
    extra.insert("scenario".to_owned(), "test".to_owned());
    extra.insert("scenario_duration_s".to_owned(), "3".to_owned());
    w.write_run_info(&RunInfo {
        version: "test".into(),
        git_revision: "unknown".into(),
        extra,
        ..RunInfo::default()
    })
    .unwrap();
    for k in 0..3100u64 {
        let mut g = grip_testkit::drives::asphalt_truth(k);
        if k == 2000 {
            g.v = -1e308;
        }
        w.write(topics::TRUTH, &g).unwrap();
        let mut c = CycleRecord::zeroed();
        c.seq = if k == 1500 { u64::MAX } else { k };
        c.stamp_ns = k * 1_000_000;
        c.torque_cmd = 100.0;
        w.write(topics::CYCLE, &c).unwrap();
    }
    w.write_metadata("grip.recorder", &BTreeMap::new()).unwrap();
    w.finish().unwrap();
}

#[test]
fn damaged_numbers_in_a_log_are_said_to_be_damage() {
    let d = tempfile::tempdir().unwrap();
    let log = d.path().join("damaged.mcap");
    write_damaged(&log);
    let (ok, so, err) = grip(&[os("inspect"), log.as_os_str()]);
    assert!(ok, "{so}{err}");
    let line = so
        .lines()
        .find(|l| l.trim_start().starts_with(topics::CYCLE))
        .unwrap_or_else(|| panic!("no {} line in\n{so}", topics::CYCLE));
    assert!(
        line.contains("seq gaps 0 ") && line.contains("restarts 2"),
        "a seq of u64::MAX is no gap of 1.8e19 messages: {line}"
    );
    assert!(
        so.contains("1 ground-truth sample(s) hold values no plant makes")
            && so.contains("seq 2000")
            && so.contains("v = -1e308 m/s"),
        "{so}"
    );
}
