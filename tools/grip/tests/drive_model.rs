//! `grip drive --model FILE`: arte runs FILE, given to it the way its
//! configuration gives a model (arte-svc.toml's `model`, in a view of the
//! configuration directory the services get as `--config-dir`, so the log
//! carries the model); a missing or unreadable FILE is refused naming it
//! before any service starts. The services are stand-ins
//! (`common/fake_services.rs`) that record what they were given. The
//! refusal of a model at another rate than the audio: `rate_mismatch.rs`.

mod common;
#[path = "common/fake_services.rs"]
mod fake_services;

use fake_services::Fakes;

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

#[test]
fn drive_model_reaches_arte_through_its_configuration() {
    let d = tempfile::tempdir().unwrap();
    let mine = d.path().join("mine.model");
    let bytes = std::fs::read(common::config_dir().join("models/paper.model")).unwrap();
    std::fs::write(&mine, &bytes).unwrap();
    let out = d.path().join("drive.mcap");
    let f = Fakes::new();
    let (ok, so, err) = f.drive(
        &common::config_dir(),
        &[
            os("--model"),
            mine.as_os_str(),
            os("--out"),
            out.as_os_str(),
        ],
    );
    // the stand-in recorder exits 3: the drive fails at it
    assert!(!ok, "{so}{err}");
    let started = f.started();
    assert_eq!(started.len(), 1, "{started:?}\n{err}");
    assert!(
        started[0].starts_with("recorder --config-dir "),
        "{started:?}"
    );
    assert!(
        err.contains(&format!(
            "drive: arte's model {} (44100 Hz)",
            mine.display()
        )),
        "{err}"
    );
    // every service gets the view as its configuration directory
    let view = f.config_dir("recorder");
    assert_ne!(view, common::config_dir());
    let cfg: toml::Table = String::from_utf8(f.seen("recorder", "arte-svc.toml").unwrap())
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(cfg["model"].as_str(), Some("models/mine.model"), "{cfg:?}");
    let own: toml::Table = std::fs::read_to_string(common::config_dir().join("arte-svc.toml"))
        .unwrap()
        .parse()
        .unwrap();
    // the rest of arte-svc.toml as it was
    for (k, v) in &own {
        if k != "model" {
            assert_eq!(cfg.get(k), Some(v), "{k}");
        }
    }
    assert_eq!(f.seen("recorder", "models/mine.model"), Some(bytes));
    assert!(f.seen("recorder", "models/default.model").is_some());
    // removed after the drive; the repository's configuration untouched
    assert!(!view.exists(), "{}", view.display());
    assert_eq!(own["model"].as_str(), Some("models/default.model"));
}

#[test]
fn drive_without_model_starts_on_the_configuration_directory() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("drive.mcap");
    let f = Fakes::new();
    let (ok, so, err) = f.drive(&common::config_dir(), &[os("--out"), out.as_os_str()]);
    assert!(!ok, "{so}{err}");
    assert_eq!(f.started().len(), 1, "{err}");
    assert_eq!(f.config_dir("recorder"), common::config_dir());
    assert!(!err.contains("arte's model"), "{err}");
}

#[test]
fn drive_refuses_a_missing_or_unreadable_model_before_any_service() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("drive.mcap");
    let garbage = d.path().join("garbage.model");
    std::fs::write(&garbage, "not a model\n").unwrap();
    let missing = d.path().join("missing.model");
    for (model, why) in [
        (&missing, "cannot read"),
        (&garbage, "not a grip ARTE model"),
    ] {
        let f = Fakes::new();
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
            err.contains(&format!("--model {}", model.display())) && err.contains(why),
            "{err}"
        );
        assert_eq!(err.matches(why).count(), 1, "said once: {err}");
        assert!(f.started().is_empty(), "{:?}", f.started());
        assert!(!out.exists());
    }
}

/// A vehicle file that leaves out a field is refused once, before any
/// service starts, naming the user's file and the field, also with
/// `--model` (the services then read the configuration through a temporary
/// view, whose copy a service's message would name). Until 2026-12-07 the
/// drive warned and ran on the paper's quarter-car default (a fail-safe
/// trial drove an empty vehicle file); the warning, said once with the
/// user's path, was this test's subject.
#[test]
fn a_vehicle_file_without_a_field_is_refused_once_naming_the_user_s_file_with_model() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("cfg");
    common::copy_dir(&common::config_dir(), &cfg);
    let vehicle = cfg.join("vehicle.toml");
    let text = std::fs::read_to_string(&vehicle).unwrap();
    let without: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with("mic_lead_m"))
        .collect();
    assert!(without.len() < text.lines().count());
    std::fs::write(&vehicle, without.join("\n")).unwrap();
    let out = d.path().join("drive.mcap");
    let f = Fakes::new();
    f.real("recorder");
    let (ok, so, err) = f.drive(
        &cfg,
        &[
            os("--model"),
            cfg.join("models/default.model").as_os_str(),
            os("--out"),
            out.as_os_str(),
        ],
    );
    assert!(!ok, "{so}{err}");
    assert!(f.started().is_empty(), "{:?}\n{err}", f.started());
    let said: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("field `vehicle.mic_lead_m`: not set"))
        .collect();
    assert_eq!(said.len(), 1, "{err}");
    assert!(
        said[0].starts_with(&format!("error: {}: ", vehicle.display())),
        "{err}"
    );
    assert!(!out.exists());
}

/// A DBC whose `TorqueRequest` cannot carry the vehicle's `torque_max`
/// (found in a newcomer's trial: `[-250|250]` against 1400 N m passed
/// `--dry-run`, started four services, failed at tcs-loop with its error
/// said twice, and left an empty log): tcs-loop's start-up checks run in
/// `grip` first, so the drive and its dry run fail before any service
/// starts, naming the vehicle file and the field once.
#[test]
fn a_dbc_tcs_loop_refuses_fails_before_any_service_starts() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("cfg");
    common::copy_dir(&common::config_dir(), &cfg);
    let dbc = cfg.join("inverter.dbc");
    let text = std::fs::read_to_string(&dbc).unwrap();
    let narrow = text.replacen(
        "TorqueRequest : 16|16@1- (0.1,0) [-3276.8|3276.7]",
        "TorqueRequest : 16|16@1- (0.1,0) [-250|250]",
        1,
    );
    assert_ne!(narrow, text);
    std::fs::write(&dbc, narrow).unwrap();
    let out = d.path().join("drive.mcap");
    for dry in [false, true] {
        let f = Fakes::new();
        let mut args = vec![os("--out"), out.as_os_str()];
        if dry {
            args.push(os("--dry-run"));
        }
        let (ok, so, err) = f.drive(&cfg, &args);
        assert!(!ok, "dry run {dry}: {so}{err}");
        assert!(f.started().is_empty(), "{:?}\n{err}", f.started());
        let said: Vec<&str> = err
            .lines()
            .filter(|l| l.contains("field `vehicle.torque_max`: 1000 N m is beyond what TorqueCommand's TorqueRequest carries in inverter.dbc (-250 to 250 N m)"))
            .collect();
        assert_eq!(said.len(), 1, "dry run {dry}: {err}");
        assert!(
            said[0].starts_with(
                "error: tcs-loop's configuration (checked before any service starts): "
            ),
            "{err}"
        );
        assert!(!out.exists() && !d.path().join("drive.mcap.partial").exists());
    }
}

#[test]
fn drive_help_gives_model() {
    let (ok, so, err) = common::output(&[os("drive"), os("--help")]);
    assert!(ok, "{err}");
    let line = so
        .lines()
        .find(|l| l.trim_start().starts_with("--model"))
        .unwrap_or_else(|| panic!("no --model in:\n{so}"));
    assert!(line.contains("arte-svc.toml"), "{line}");
}

/// A drive whose services fail leaves the log that was at `--out` as it
/// was (found in a trial: a bad controllers.toml replaced a 2.9 MB log
/// with a 0.2 s one): the recorder writes to `--out` + `.partial`, which
/// takes `--out`'s name only when the drive ran or nothing was there; a
/// `.partial` an earlier failure left is removed before the recorder
/// starts (never taken for this drive's log); `--out` naming a directory
/// is refused before any service starts. The stand-in recorder writes a
/// copy of the reference drive to its `--out` and fails.
#[test]
fn a_failed_drive_leaves_the_log_that_was_at_out() {
    let reference = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/reference-drive.mcap");
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("drive.mcap");
    let partial = d.path().join("drive.mcap.partial");
    std::fs::write(&out, b"the log of yesterday's drive").unwrap();
    std::fs::write(&partial, b"a log an earlier failure left").unwrap();
    let f = Fakes::new();
    let (ok, so, err) = f.drive_recording(
        &common::config_dir(),
        &reference,
        &[os("--out"), out.as_os_str()],
    );
    assert!(!ok, "{so}{err}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        b"the log of yesterday's drive",
        "{err}"
    );
    // this attempt's log beside it, the earlier .partial gone, both said
    assert_eq!(
        std::fs::read(&partial).unwrap(),
        std::fs::read(&reference).unwrap()
    );
    for says in [
        format!(
            "drive: removed {}, the log of an earlier drive that failed",
            partial.display()
        ),
        format!(
            "so {} (there before it) is left as it was; this attempt's log is {}",
            out.display(),
            partial.display()
        ),
    ] {
        assert!(err.contains(&says), "{says:?} not in\n{err}");
    }
    // nothing at --out before: the log takes its name, even after a failure
    std::fs::remove_file(&out).unwrap();
    let (ok, so, err) = f.drive_recording(
        &common::config_dir(),
        &reference,
        &[os("--out"), out.as_os_str()],
    );
    assert!(!ok, "{so}{err}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&reference).unwrap()
    );
    assert!(!partial.exists());
    // a directory as --out: refused before anything starts
    let (ok, _, err) = f.drive(&common::config_dir(), &[os("--out"), d.path().as_os_str()]);
    assert!(!ok);
    assert!(
        err.contains("is a directory; give the log's file name"),
        "{err}"
    );
}

/// A scenario plant-sim would refuse (a demand above the vehicle's
/// torque_max) is refused by `grip drive` before any service starts, with
/// plant-sim's message (the check's one home: `grip_config::check_scenario`).
#[test]
fn a_scenario_beyond_the_vehicle_is_refused_before_any_service() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("config");
    let status = std::process::Command::new("cp")
        .args(["-r"])
        .arg(common::config_dir())
        .arg(&cfg)
        .status()
        .unwrap();
    assert!(status.success());
    let paper = cfg.join("scenarios/paper.toml");
    let text = std::fs::read_to_string(&paper).unwrap();
    assert!(text.contains("torque = 300.0"));
    std::fs::write(&paper, text.replace("torque = 300.0", "torque = 1e300")).unwrap();
    let f = Fakes::new();
    let out = d.path().join("drive.mcap");
    let (ok, _, err) = f.drive(&cfg, &[os("--out"), out.as_os_str()]);
    assert!(!ok);
    assert!(
        err.contains(
            "scenarios/paper.toml: field `demand.torque`: 1e300 N m is above the motor limit"
        ),
        "{err}"
    );
    assert!(f.started().is_empty(), "{:?}", f.started());
}
