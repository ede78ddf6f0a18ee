//! An engineer's own recordings through `grip dataset synth`, `grip train`
//! and `grip calibrate`, as the built binary runs them:
//!
//! - `grip train` needs `--out` (it wrote `<config-dir>/models/trained.model`
//!   in silence, into the repository's config when run from its root),
//!   refuses an existing `--out` unless `--force` (it overwrote it without a
//!   word, after the whole training) and says where it wrote the model;
//! - `grip dataset synth --recordings-per-class 0 --changes N` names the
//!   folder it wrote the change recordings to (`OUT-changes`; it said
//!   `OUT`), leaves no empty class folders and no empty manifest, and
//!   `--calib-data OUT` points at `OUT-changes`;
//! - `grip calibrate --model ../m.model --data ../train` from another
//!   folder than the training's is refused as the model's own training data
//!   (the path stored in the model is relative to where it was trained: only
//!   the check by content finds it).

mod common;

use std::path::Path;
use std::process::Command;

/// `grip --config-dir <repo>/config ARGS` in `cwd`: success, stdout, stderr.
fn grip_at(cwd: &Path, args: &[&str]) -> (bool, String, String) {
    let o = common::grip().current_dir(cwd).args(args).output().unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A small class dataset `data` (2 roads × 3 recordings × 0.4 s at 16 kHz).
fn synth_data(cwd: &Path, data: &str) {
    let (ok, out, err) = grip_at(
        cwd,
        &[
            "dataset",
            "synth",
            "--out",
            data,
            "--roads",
            "asphalt,gravel",
            "--recordings-per-class",
            "3",
            "--duration",
            "0.4",
            "--sample-rate",
            "16000",
            "--seed",
            "4",
        ],
    );
    assert!(ok, "synth: {out}{err}");
}

/// `grip train --data DATA --out OUT` (a quick SVM, no cross-validation)
/// plus `extra`.
fn train(cwd: &Path, data: &str, out: &str, extra: &[&str]) -> (bool, String, String) {
    let mut args = vec![
        "train",
        "--data",
        data,
        "--classifier",
        "svm",
        "--features",
        "rich",
        "--folds",
        "0",
        "--svm-c",
        "1",
        "--svm-gamma",
        "1",
        "--date",
        "2026-01-01",
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    grip_at(cwd, &args)
}

#[test]
fn train_needs_out_and_keeps_an_existing_model_without_force() {
    let d = tempfile::tempdir().unwrap();
    synth_data(d.path(), "data");
    // no --out: refused by name, nothing written into the config folder
    let cfg = d.path().join("config");
    std::fs::create_dir_all(&cfg).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_grip"))
        .current_dir(d.path())
        .args(["--config-dir", "config", "train", "--data", "data"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--out"), "{err}");
    assert!(!cfg.join("models").exists());
    // a new file: written, and said where
    let (ok, out, err) = train(d.path(), "data", "m.model", &[]);
    assert!(ok, "train: {out}{err}");
    assert!(out.contains("wrote model m.model"), "{out}");
    // the written model's own figures, apart from the cross-validation
    assert!(
        out.contains("the written model on the final fit's own frames")
            && out.contains("training frames (6 recordings): n = ")
            && out.contains("validation frames: none (the SVM fit holds no recordings out)"),
        "{out}"
    );
    let first = std::fs::read(d.path().join("m.model")).unwrap();
    // an existing one: refused before the training, naming file and option
    std::fs::write(d.path().join("m.model"), b"mine").unwrap();
    let (ok, out, err) = train(d.path(), "data", "m.model", &[]);
    assert!(!ok, "{out}");
    assert!(
        err.contains("m.model") && err.contains("already exists") && err.contains("--force"),
        "{err}"
    );
    assert!(!out.contains("frames of"), "trained before refusing: {out}");
    assert_eq!(std::fs::read(d.path().join("m.model")).unwrap(), b"mine");
    // --force replaces it, and says so
    let (ok, out, err) = train(d.path(), "data", "m.model", &["--force"]);
    assert!(ok, "train --force: {out}{err}");
    assert!(
        out.contains("wrote model m.model") && out.contains("replacing"),
        "{out}"
    );
    assert_eq!(std::fs::read(d.path().join("m.model")).unwrap(), first);
}

#[test]
fn change_recordings_alone_go_to_the_folder_the_message_names() {
    let d = tempfile::tempdir().unwrap();
    let (ok, out, err) = grip_at(
        d.path(),
        &[
            "dataset",
            "synth",
            "--out",
            "chcal",
            "--recordings-per-class",
            "0",
            "--changes",
            "2",
            "--roads",
            "asphalt,gravel",
            "--duration",
            "1",
            "--segment",
            "0.4-0.6",
            "--sample-rate",
            "16000",
            "--seed",
            "9",
        ],
    );
    assert!(ok, "synth: {out}{err}");
    assert!(
        err.contains("2 change recordings to chcal-changes"),
        "{err}"
    );
    assert!(d.path().join("chcal-changes/segments.csv").is_file());
    // no empty class folders, no empty manifest
    assert!(!d.path().join("chcal").exists());
    // --calib-data chcal: the error points at chcal-changes
    synth_data(d.path(), "data");
    let (ok, out, err) = train(d.path(), "data", "m.model", &["--calib-data", "chcal"]);
    assert!(!ok, "{out}");
    assert!(err.contains("chcal-changes"), "{err}");
    // an old run's leftovers (empty class folder, 0-byte manifest): the same hint
    std::fs::create_dir_all(d.path().join("chcal/asphalt")).unwrap();
    std::fs::write(d.path().join("chcal/manifest.csv"), b"").unwrap();
    let (ok, out, err) = train(d.path(), "data", "m.model", &["--calib-data", "chcal"]);
    assert!(!ok, "{out}");
    assert!(
        err.contains("lists no recordings") && err.contains("chcal-changes"),
        "{err}"
    );
}

#[test]
fn calibrating_on_the_training_data_from_another_folder_is_refused() {
    let d = tempfile::tempdir().unwrap();
    synth_data(d.path(), "train");
    let (ok, out, err) = train(d.path(), "train", "my.model", &[]);
    assert!(ok, "train: {out}{err}");
    let sub = d.path().join("elsewhere");
    std::fs::create_dir_all(&sub).unwrap();
    // from the training folder's parent (as before) and from another
    // folder, and a copy of one class folder
    let copy = d.path().join("copy/gravel");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::copy(
        d.path().join("train/gravel/gravel_0001.wav"),
        copy.join("g.wav"),
    )
    .unwrap();
    for (cwd, model, data) in [
        (d.path(), "my.model", "train"),
        (sub.as_path(), "../my.model", "../train"),
        (sub.as_path(), "../my.model", "../train/asphalt"),
        (sub.as_path(), "../my.model", "../copy"),
    ] {
        let (ok, out, err) = grip_at(
            cwd,
            &[
                "calibrate",
                "--model",
                model,
                "--data",
                data,
                "--out",
                "c.model",
            ],
        );
        assert!(!ok, "{data}: {out}");
        assert!(
            err.contains("held-out") && err.contains("training"),
            "{data}: {err}"
        );
        assert!(!cwd.join("c.model").exists());
    }
}

/// `grip dataset delay` on the recordings the model's calibration was
/// fitted on says its figures are in-sample there (a newcomer read the
/// calibration set's ECE as held out); on other change recordings it
/// says nothing of the kind. The calibration stores its recordings by
/// content (`files`), as the model its training files.
#[test]
fn delay_on_the_calibration_recordings_is_said_to_be_in_sample() {
    let d = tempfile::tempdir().unwrap();
    synth_data(d.path(), "data");
    let changes = |out: &str, seed: &str| {
        let (ok, o, e) = grip_at(
            d.path(),
            &[
                "dataset",
                "synth",
                "--out",
                out,
                "--recordings-per-class",
                "0",
                "--changes",
                "2",
                "--roads",
                "asphalt,gravel",
                "--duration",
                "1",
                "--segment",
                "0.4-0.6",
                "--sample-rate",
                "16000",
                "--seed",
                seed,
            ],
        );
        assert!(ok, "synth: {o}{e}");
    };
    changes("cal", "11");
    changes("other", "12");
    let (ok, out, err) = train(
        d.path(),
        "data",
        "m.model",
        &["--calib-data", "cal-changes"],
    );
    assert!(ok, "train: {out}{err}");
    let delay = |dir: &str| {
        let (ok, out, err) = grip_at(d.path(), &["dataset", "delay", "--model", "m.model", dir]);
        assert!(ok, "delay {dir}: {out}{err}");
        out
    };
    let on_cal = delay("cal-changes");
    assert!(
        on_cal.contains("warning: cal-changes holds ")
            && on_cal.contains("one of the recordings its confidence calibration was fitted on")
            && on_cal.contains("in-sample"),
        "{on_cal}"
    );
    let on_other = delay("other-changes");
    assert!(!on_other.contains("in-sample"), "{on_other}");
}
