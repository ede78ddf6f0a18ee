//! A model and audio at different sample rates are refused up front, naming
//! both rates: `grip replay --model` of another rate than the log's audio
//! blocks (arte refused every block and the replay silently published no
//! road estimate), `grip generate` with `[audio] sample_rate` other than the
//! model's, `grip drive` with `[audio] sample_rate` other than its model's
//! (arte-svc.toml's or `--model`'s; refused before any service starts: the
//! drive ran, exited 0 and recorded no estimate), and `grip train --test`
//! with a held-out folder at another rate than the training set (refused
//! before any training, no model written); and a model class that is no
//! road of the catalogue (arte's other start-up refusal), by `grip train`
//! and `grip drive --model`.

mod common;
#[path = "common/fake_services.rs"]
mod fake_services;

use std::path::Path;

use grip_arte::synth::{ROADS, Segment, SynthConfig, render};

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

/// `grip ARGS` on `config` (the repository's when `None`): success, stdout,
/// stderr.
fn grip_in(config: Option<&Path>, args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    match config {
        None => common::output(args),
        Some(dir) => common::output_in(dir, args),
    }
}

/// `grip train` of an RBF SVM on the Rich features of `data` into `model`,
/// with `extra` arguments.
fn train_svm(data: &Path, model: &Path, extra: &[&std::ffi::OsStr]) -> (bool, String, String) {
    train_svm_in(None, data, model, extra)
}

/// [`train_svm`] on `config` (the repository's when `None`).
fn train_svm_in(
    config: Option<&Path>,
    data: &Path,
    model: &Path,
    extra: &[&std::ffi::OsStr],
) -> (bool, String, String) {
    let mut args = vec![
        os("train"),
        os("--data"),
        data.as_os_str(),
        os("--classifier"),
        os("svm"),
        os("--features"),
        os("rich"),
        os("--out"),
        model.as_os_str(),
    ];
    args.extend_from_slice(extra);
    grip_in(config, &args)
}

/// A dataset of `classes` × 2 recordings × 0.5 s at `rate` Hz.
fn dataset(dir: &Path, rate: u32, classes: &[&str]) {
    let cfg = SynthConfig {
        sample_rate: rate,
        noise: None,
    };
    for road in classes {
        let r = ROADS.iter().position(|n| n == road).unwrap();
        std::fs::create_dir_all(dir.join(road)).unwrap();
        for k in 0..2u64 {
            let x = render(
                &cfg,
                100 * r as u64 + k,
                &[Segment {
                    road: r,
                    speed_mps: (10.0 + 4.0 * k as f64) / 3.6,
                    duration_s: 0.5,
                }],
            )
            .unwrap();
            grip_io::wav::write_mono_i16(&dir.join(road).join(format!("r{k}.wav")), rate, &x)
                .unwrap();
        }
    }
}

#[test]
fn replay_with_a_model_at_another_rate_is_refused_naming_both_rates() {
    let d = tempfile::tempdir().unwrap();
    // a log at the repository's rate (44100 Hz)
    let logs = d.path().join("logs");
    let (ok, out, err) = grip_in(
        None,
        &[
            os("generate"),
            os("--out"),
            logs.as_os_str(),
            os("--count"),
            os("1"),
            os("--seed0"),
            os("3"),
        ],
    );
    assert!(ok, "generate: {out}{err}");
    let log = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .unwrap();
    // a model at 16000 Hz
    let data = d.path().join("data16");
    dataset(&data, 16_000, &["asphalt", "gravel", "snow"]);
    let model = d.path().join("m16.model");
    let (ok, out, err) = train_svm(
        &data,
        &model,
        &[
            os("--folds"),
            os("0"),
            os("--svm-c"),
            os("1"),
            os("--svm-gamma"),
            os("1"),
        ],
    );
    assert!(ok, "train: {out}{err}");
    let (ok, out, err) = grip_in(
        None,
        &[
            os("replay"),
            log.as_os_str(),
            os("--model"),
            model.as_os_str(),
        ],
    );
    assert!(
        !ok,
        "replay with a 16 kHz model on 44.1 kHz audio ran:\n{out}"
    );
    assert!(
        err.contains("expects 16000 Hz audio") && err.contains("at 44100 Hz"),
        "{err}"
    );
    assert!(err.contains("--model"), "{err}");
    assert!(!out.contains("replayed"), "{out}");
}

#[test]
fn generate_with_audio_at_another_rate_than_the_model_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("config");
    common::copy_dir(&common::config_dir(), &cfg);
    let acq = cfg.join("audio-acq.toml");
    let text = std::fs::read_to_string(&acq).unwrap();
    assert!(text.contains("sample_rate = 44100"), "{text}");
    std::fs::write(
        &acq,
        text.replace("sample_rate = 44100", "sample_rate = 48000"),
    )
    .unwrap();
    let out_dir = d.path().join("logs");
    let (ok, out, err) = grip_in(
        Some(&cfg),
        &[
            os("generate"),
            os("--out"),
            out_dir.as_os_str(),
            os("--count"),
            os("2"),
        ],
    );
    assert!(!ok, "generate at 48 kHz with a 44.1 kHz model ran:\n{out}");
    // the rule of `grip drive` (tools/grip/src/drive/rates.rs): the user's
    // files (not a per-log copy), both rates and what to change
    let acq = std::path::absolute(&acq).unwrap();
    let cfg = std::path::absolute(&cfg).unwrap();
    for want in [
        format!("{}: field audio.sample_rate is 48000 Hz", acq.display()),
        format!(
            "arte's model {} (the `model` of {}) expects 44100 Hz",
            cfg.join("models/default.model").display(),
            cfg.join("arte-svc.toml").display()
        ),
        "the logs would carry no road estimate".to_owned(),
        format!("Set [audio] sample_rate = 44100 in {}", acq.display()),
        format!(
            "set `model` in {} to a model trained at 48000 Hz",
            cfg.join("arte-svc.toml").display()
        ),
    ] {
        assert!(err.contains(&want), "{want}:\n{err}");
    }
    assert!(!err.contains("arte.toml"), "{err}");
    // once, before any log: no log file, no output folder
    assert_eq!(err.matches("expects 44100 Hz").count(), 1, "{err}");
    assert!(!out_dir.exists(), "{}", out_dir.display());
}

#[test]
fn train_refuses_a_held_out_folder_at_another_rate_before_training() {
    let d = tempfile::tempdir().unwrap();
    let data = d.path().join("data16");
    dataset(&data, 16_000, &["asphalt", "gravel", "snow"]);
    let test = d.path().join("test22");
    dataset(&test, 22_050, &["asphalt", "gravel", "snow"]);
    let model = d.path().join("x.model");
    let train = |test: &Path, extra: &[&str]| {
        let mut args = vec![os("--folds"), os("2"), os("--test"), test.as_os_str()];
        args.extend(extra.iter().map(|s| os(s)));
        train_svm(&data, &model, &args)
    };
    let (ok, out, err) = train(&test, &[]);
    assert!(!ok, "trained with a 22050 Hz --test:\n{out}");
    assert!(
        err.contains("held-out set at 22050 Hz, training set")
            && err.contains("at 16000 Hz")
            && err.contains(&format!("--test {}", test.display())),
        "{err}"
    );
    // before any feature, cross-validation or fit
    assert!(
        !out.contains("cross-validation") && !out.contains("frames of"),
        "{out}"
    );
    assert!(!model.exists());

    // a held-out class the training set lacks: refused up front too
    let odd = d.path().join("odd16");
    dataset(&odd, 16_000, &["asphalt", "stone"]);
    let (ok, out, err) = train(&odd, &[]);
    assert!(!ok, "{out}");
    assert!(
        err.contains("class folder `stone`") && !out.contains("frames of"),
        "{err}"
    );
    assert!(!model.exists());
}

/// `config/models/paper.model` as if trained at `rate` Hz (its feature
/// configuration's rate changed, the checksum redone), written to `path`.
fn paper_model_at(path: &Path, rate: u32) {
    let bytes = std::fs::read(common::config_dir().join("models/paper.model")).unwrap();
    let nl = bytes.iter().position(|&b| b == b'\n').unwrap();
    let payload = String::from_utf8(bytes[nl + 1..].to_vec()).unwrap();
    assert_eq!(payload.matches("\"sample_rate\":44100").count(), 1);
    let payload = payload.replace("\"sample_rate\":44100", &format!("\"sample_rate\":{rate}"));
    let header = String::from_utf8(bytes[..nl].to_vec()).unwrap();
    let version = header.split_whitespace().nth(1).unwrap();
    let text = format!(
        "GRIP-ARTE-MODEL {version} sha256={}\n{payload}",
        grip_digest::sha256_hex(payload.as_bytes())
    );
    std::fs::write(path, text).unwrap();
}

#[test]
fn drive_with_audio_at_another_rate_than_the_model_is_refused_before_any_service() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("config");
    common::copy_dir(&common::config_dir(), &cfg);
    let acq = cfg.join("audio-acq.toml");
    let text = std::fs::read_to_string(&acq).unwrap();
    std::fs::write(
        &acq,
        text.replace("sample_rate = 44100", "sample_rate = 48000"),
    )
    .unwrap();
    let out = d.path().join("drive.mcap");
    let f = fake_services::Fakes::new();
    let (ok, so, err) = f.drive(&cfg, &[os("--out"), out.as_os_str()]);
    assert!(
        !ok,
        "a drive at 48 kHz with a 44.1 kHz model started:\n{so}{err}"
    );
    for want in [
        format!("{}: field audio.sample_rate is 48000 Hz", acq.display()),
        format!(
            "arte's model {} (the `model` of {}) expects 44100 Hz",
            cfg.join("models/default.model").display(),
            cfg.join("arte-svc.toml").display()
        ),
        format!("Set [audio] sample_rate = 44100 in {}", acq.display()),
        "grip drive --model FILE".to_owned(),
    ] {
        assert!(err.contains(&want), "{want}:\n{err}");
    }
    assert!(
        f.started().is_empty(),
        "services started: {:?}",
        f.started()
    );
    assert!(!out.exists());

    // --model at another rate than the repository's audio
    let m16 = d.path().join("m16.model");
    paper_model_at(&m16, 16_000);
    let f = fake_services::Fakes::new();
    let (ok, so, err) = f.drive(
        &common::config_dir(),
        &[os("--model"), m16.as_os_str(), os("--out"), out.as_os_str()],
    );
    assert!(!ok, "{so}{err}");
    assert!(
        err.contains("field audio.sample_rate is 44100 Hz")
            && err.contains(&format!("--model {} expects 16000 Hz", m16.display()))
            && err.contains("a model trained at 44100 Hz"),
        "{err}"
    );
    assert!(
        f.started().is_empty(),
        "services started: {:?}",
        f.started()
    );

    // the same model with the audio at its rate: the check passes, the
    // services start (the stand-in recorder then fails the drive)
    let text = std::fs::read_to_string(&acq).unwrap();
    std::fs::write(
        &acq,
        text.replace("sample_rate = 48000", "sample_rate = 16000"),
    )
    .unwrap();
    let f = fake_services::Fakes::new();
    let (_, so, err) = f.drive(
        &cfg,
        &[os("--model"), m16.as_os_str(), os("--out"), out.as_os_str()],
    );
    assert_eq!(f.started().len(), 1, "{so}{err}");
}

/// A class arte would refuse is refused up front too (found in review:
/// `grip train` wrote such models, and `grip drive --model` found out only
/// after starting the services, naming their temporary copy): `grip train`
/// with a class folder that is not a road of the catalogue refuses before
/// any feature is extracted, naming the folder, the catalogue and the way
/// out; `grip drive --model` of a model with such a class (trained on a
/// configuration whose catalogue has that road) refuses before any service
/// starts, naming the user's file and the class.
#[test]
fn a_class_that_is_no_road_of_the_catalogue_is_refused_up_front() {
    let d = tempfile::tempdir().unwrap();
    let data = d.path().join("data");
    dataset(&data, 44_100, &["asphalt", "snow"]);
    // "cobble": recordings of stone in a folder of that name
    std::fs::rename(data.join("snow"), data.join("cobble")).unwrap();
    let model = d.path().join("cobble.model");
    let (ok, so, err) = train_svm(&data, &model, &[]);
    assert!(!ok, "{so}{err}");
    for want in [
        "class `cobble` is not a road in the catalogue",
        "roads.toml",
        "arte would refuse a model of these classes",
        "--classes",
        &format!("--data {}: class `cobble`", data.display()),
    ] {
        assert!(err.contains(want), "{want}:\n{err}");
    }
    // the folder is at fault, not the model file (which is not written)
    assert!(!err.contains("model file"), "{err}");
    assert!(
        !so.contains("cross-validation"),
        "features were extracted:\n{so}"
    );
    assert!(!model.exists());

    // a configuration whose catalogue has a road `cobble`: the model trains
    let cfg = d.path().join("config");
    common::copy_dir(&common::config_dir(), &cfg);
    let roads = cfg.join("roads.toml");
    let mut text = std::fs::read_to_string(&roads).unwrap();
    text.push_str(
        "\n[[road]]\nname = \"cobble\"\nmodel = \"burckhardt\"\nc1 = 1.37\nc2 = 6.46\nc3 = 0.67\n",
    );
    std::fs::write(&roads, text).unwrap();
    let (ok, so, err) = train_svm_in(Some(&cfg), &data, &model, &[os("--folds"), os("2")]);
    assert!(ok, "{so}{err}");
    assert!(model.exists());
    // ... and a drive on the repository's configuration refuses it
    let out = d.path().join("drive.mcap");
    let f = fake_services::Fakes::new();
    let (ok, so, err) = f.drive(
        &common::config_dir(),
        &[
            os("--model"),
            model.as_os_str(),
            os("--out"),
            out.as_os_str(),
        ],
    );
    assert!(!ok, "{so}{err}");
    assert!(
        err.contains(&format!("--model {}", model.display()))
            && err.contains("class `cobble` is not a road in the catalogue")
            && err.contains("arte would refuse it at start-up"),
        "{err}"
    );
    assert!(
        f.started().is_empty(),
        "services started: {:?}",
        f.started()
    );
    assert!(!out.exists());
}
