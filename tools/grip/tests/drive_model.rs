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

/// A drive whose services fail to start leaves the log that was at `--out`
/// as it was (found in a trial: a bad controllers.toml replaced a 2.9 MB
/// log with a 0.2 s one): the recorder writes to `--out` + `.partial`,
/// which takes `--out`'s name only when the drive ran or nothing was there.
#[test]
fn a_failed_drive_leaves_the_log_that_was_at_out() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("drive.mcap");
    std::fs::write(&out, b"the log of yesterday's drive").unwrap();
    let f = Fakes::new();
    let (ok, so, err) = f.drive(&common::config_dir(), &[os("--out"), out.as_os_str()]);
    // the stand-in recorder exits 3: the drive fails at it
    assert!(!ok, "{so}{err}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        b"the log of yesterday's drive",
        "{err}"
    );
    let recorder = f
        .started()
        .into_iter()
        .find(|s| s.starts_with("recorder "))
        .unwrap();
    assert!(
        recorder.contains(&format!("--out {}.partial", out.display())),
        "{recorder}"
    );
}
