//! Crafted inputs of an audit of the command line (2026-12-07) whose
//! errors named no flag or file, or whose wording contradicted what the
//! command accepts: each is now refused naming the flag (as typed) or the
//! files, with the reason, before any work, and never with a panic.

mod common;

use std::ffi::OsStr;
use std::path::Path;

/// `grip ARGS` on the repository's configuration: refused, saying `said`,
/// with no panic; its stdout and stderr.
fn refused(args: &[&OsStr], said: &str) -> (String, String) {
    let (ok, out, err) = common::output(args);
    assert!(!ok, "{args:?} ran: {out}");
    assert!(err.contains(said), "{args:?}: wanted {said:?} in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    (out, err)
}

fn os<'a>(args: &[&'a str]) -> Vec<&'a OsStr> {
    args.iter().map(|s| OsStr::new(*s)).collect()
}

/// `n` samples of a 16-bit mono WAV at 16 kHz: a 500 Hz tone with a
/// little noise, per `seed`.
fn write_wav(path: &Path, n: usize, seed: u64) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 16_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    let mut s = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
    for i in 0..n {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let noise = ((s >> 33) as f64 / f64::from(1u32 << 31)) - 0.5;
        let x =
            0.3 * (2.0 * std::f64::consts::PI * 500.0 * i as f64 / 16_000.0).sin() + 0.1 * noise;
        w.write_sample((x * 32767.0) as i16).unwrap();
    }
    w.finalize().unwrap();
}

/// `grip analyze --k-motor 1e308` said "coefficient 0 is inf, not a finite
/// number" after half the report, naming no flag.
#[test]
fn analyze_names_the_flag_of_an_overflowing_operating_point() {
    for (args, said) in [
        (
            ["analyze", "--k-motor", "1e308"],
            "--k-motor 1e308: must be a finite number from 1e-6 to 1e6 N m/A",
        ),
        (
            ["analyze", "--k-motor", "5e-324"],
            "--k-motor 5e-324: must be a finite number from 1e-6 to 1e6 N m/A",
        ),
        (
            ["analyze", "--speed-kmh", "1e308"],
            "--speed-kmh 1e308: must be a finite number from 0.001 to 1000 km/h",
        ),
        (
            ["analyze", "--speed-kmh", "1e-200"],
            "--speed-kmh 1e-200: must be a finite number from 0.001 to 1000 km/h",
        ),
    ] {
        let (out, err) = refused(&os(&args), said);
        assert!(!err.contains("inf, not a finite"), "{err}");
        assert!(!err.contains("identically zero"), "{err}");
        // refused before the report begins
        assert!(out.is_empty(), "{args:?} printed: {out}");
    }
    // the ends of the ranges run
    for args in [
        ["analyze", "--k-motor", "1e6"],
        ["analyze", "--speed-kmh", "0.001"],
    ] {
        let (ok, _, err) = common::output(&os(&args));
        assert!(ok, "{args:?}: {err}");
    }
}

/// `grip generate --torque 0:1.79e308` drew an infinite demand and said
/// "field `random.demand.torque`: must be >= 0 (got inf)".
#[test]
fn generate_names_a_torque_out_of_range_as_typed() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("logs");
    let o = out.to_str().unwrap();
    for torque in ["0:1.79e308", "1e308", "10000.5"] {
        let (_, err) = refused(
            &os(&["generate", "--out", o, "--count", "1", "--torque", torque]),
            &format!("--torque {torque}: a driver demand must lie within 0..=10000 N m"),
        );
        assert!(!err.contains("inf"), "{err}");
    }
    assert!(!out.exists(), "--out created before the refusal");
}

/// `grip dataset delay --stay 0` runs (no smoothing) while `--stay 1` said
/// "field `smoothing.stay`: 1 is not in (0, 1)": the error now names the
/// flag and says that 0 is taken too.
#[test]
fn dataset_delay_stay_error_says_what_it_takes() {
    let d = tempfile::tempdir().unwrap();
    let ds = d.path().join("ds");
    let changes = d.path().join("changes");
    let (ok, _, err) = common::output(&[
        "dataset".as_ref(),
        "synth".as_ref(),
        "--out".as_ref(),
        ds.as_os_str(),
        "--recordings-per-class".as_ref(),
        "1".as_ref(),
        "--duration".as_ref(),
        "0.2".as_ref(),
        "--changes".as_ref(),
        "1".as_ref(),
        "--changes-out".as_ref(),
        changes.as_os_str(),
        "--segment".as_ref(),
        "0.5-0.8".as_ref(),
    ]);
    assert!(ok, "{err}");
    let model = common::config_dir().join("models/default.model");
    let delay = |stay: &str| {
        common::output(&[
            "dataset".as_ref(),
            "delay".as_ref(),
            "--model".as_ref(),
            model.as_os_str(),
            changes.as_os_str(),
            format!("--stay={stay}").as_ref(),
        ])
    };
    let (ok, _, err) = delay("0");
    assert!(ok, "--stay 0 (no smoothing): {err}");
    for stay in ["1", "1.5", "-0.1"] {
        let (ok, out, err) = delay(stay);
        assert!(!ok, "--stay {stay} ran: {out}");
        assert!(
            err.contains(&format!(
                "--stay {stay}: must be 0 (no smoothing) or within (0, 1)"
            )),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `grip features --dataset DIR` of recordings all shorter than one frame
/// said "feature matrix: 0 values for 0 rows of 20 columns", naming no
/// file.
#[test]
fn features_dataset_names_the_recordings_shorter_than_a_frame() {
    let d = tempfile::tempdir().unwrap();
    // 3 classes x 2 recordings of 0.05 s at 16 kHz; a frame is 0.1 s
    for (i, road) in ["asphalt", "gravel", "snow"].iter().enumerate() {
        for k in 0..2 {
            write_wav(
                &d.path().join(road).join(format!("r{k}.wav")),
                800,
                (10 * i + k) as u64,
            );
        }
    }
    let first = d.path().join("asphalt/r0.wav");
    let (_, err) = refused(
        &[
            "features".as_ref(),
            "--dataset".as_ref(),
            d.path().as_os_str(),
        ],
        "all 6 recordings are shorter than one 0.1 s frame (1600 samples at 16000 Hz): ",
    );
    assert!(
        err.contains(&format!("{} (0.050 s, 800 samples)", first.display())),
        "{err}"
    );
    assert!(err.contains(", and 1 more;"), "{err}");
    assert!(err.contains("the dataset has no frame to analyse"), "{err}");
    assert!(!err.contains("0 values for 0 rows"), "{err}");

    // one class long enough: the class folders left without a frame named
    for k in 0..2 {
        write_wav(
            &d.path().join("snow").join(format!("r{k}.wav")),
            16_000,
            20 + k,
        );
    }
    let (_, err) = refused(
        &[
            "features".as_ref(),
            "--dataset".as_ref(),
            d.path().as_os_str(),
        ],
        "4 of the 6 recordings are shorter than one 0.1 s frame",
    );
    assert!(
        err.contains("class folders asphalt, gravel have no frame to analyse"),
        "{err}"
    );
}

/// `grip train --hidden 256,256` was refused by the Levenberg-Marquardt fit
/// only after every feature had been extracted; now before, with the fit's
/// own wording.
#[test]
fn train_refuses_too_many_weights_before_extracting_features() {
    let d = tempfile::tempdir().unwrap();
    let data = d.path().join("data");
    for (i, road) in ["asphalt", "snow"].iter().enumerate() {
        for k in 0..3 {
            write_wav(
                &data.join(road).join(format!("r{k}.wav")),
                16_000,
                (10 * i + k) as u64,
            );
        }
    }
    let model = d.path().join("m.model");
    // paper7 (7 features) -> 256 -> 256 -> 2 classes
    let fit_says = grip_arte::mlp::MlpError::TooManyForLm {
        sizes: vec![7, 256, 256, 2],
        weights: 8 * 256 + 257 * 256 + 257 * 2,
    }
    .to_string();
    let (out, _) = refused(
        &[
            "train".as_ref(),
            "--data".as_ref(),
            data.as_os_str(),
            "--folds".as_ref(),
            "0".as_ref(),
            "--hidden".as_ref(),
            "256,256".as_ref(),
            "--out".as_ref(),
            model.as_os_str(),
        ],
        &format!("--hidden 256,256: {fit_says}"),
    );
    assert!(!out.contains("frames of"), "features were extracted: {out}");
    assert!(!model.exists());
    // the feature count is the model's: paper20's 20
    let (_, err) = refused(
        &[
            "train".as_ref(),
            "--data".as_ref(),
            data.as_os_str(),
            "--folds".as_ref(),
            "0".as_ref(),
            "--features".as_ref(),
            "paper20".as_ref(),
            "--hidden".as_ref(),
            "250".as_ref(),
            "--out".as_ref(),
            model.as_os_str(),
        ],
        "--hidden 250: the network [20, 250, 2] (input, hidden layers, output) has 5752 weights",
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// `--calib-stay`, `--calib-hop` and `--calib-floor` of `grip calibrate`
/// and `grip train` are refused naming the flag before anything is read
/// or trained (`grip train` fits its calibration after the model: a
/// `--calib-stay 1` was refused only then, as `smoothing.stay: 1 is not
/// in (0, 1)`, while 0 is "no smoothing").
#[test]
fn calibration_stream_flags_are_refused_before_any_work() {
    let d = tempfile::tempdir().unwrap();
    let gone = d.path().join("no-such-folder");
    let model = common::config_dir().join("models/default.model");
    let out = d.path().join("m.model");
    for (flag, value, said) in [
        (
            "--calib-stay",
            "1",
            "--calib-stay 1: must be 0 (no smoothing) or within (0, 1)",
        ),
        (
            "--calib-stay",
            "-0.5",
            "--calib-stay -0.5: must be 0 (no smoothing) or within (0, 1)",
        ),
        (
            "--calib-hop",
            "0",
            "--calib-hop 0: must be within (0, 10] s",
        ),
        (
            "--calib-floor",
            "2",
            "--calib-floor 2: must be within (0, 1]",
        ),
    ] {
        let set = format!("{flag}={value}");
        let (model, gone, out) = (
            model.to_str().unwrap(),
            gone.to_str().unwrap(),
            out.to_str().unwrap(),
        );
        // calibrate and train: their data folder does not exist, the flag
        // is said first (nothing is read)
        for args in [
            vec![
                "calibrate",
                "--model",
                model,
                "--data",
                gone,
                "--out",
                out,
                &set,
            ],
            vec!["train", "--data", gone, "--out", out, &set],
        ] {
            let (_, err) = refused(&os(&args), said);
            assert!(!err.contains("no-such-folder"), "{err}");
        }
        assert!(!Path::new(out).exists());
    }
}
