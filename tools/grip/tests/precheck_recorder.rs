//! `grip drive` runs the recorder's start-up checks (`grip_recorder::check`)
//! before any service starts, beside tcs-loop's: a `recorder.toml` the
//! recorder refuses fails the drive and its `--dry-run` there, once, naming
//! the file, the field and the reason. Until then the recorder, started
//! first, refused it, nothing else started, and the drive said only "no
//! readable log".

mod common;
#[path = "common/fake_services.rs"]
mod fake_services;

use std::path::{Path, PathBuf};

use fake_services::Fakes;

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

/// The repository's configuration copied to `dir/cfg`, its `recorder.toml`
/// with `from` replaced by `to`.
fn config_with(dir: &Path, from: &str, to: &str) -> PathBuf {
    let cfg = dir.join("cfg");
    common::copy_dir(&common::config_dir(), &cfg);
    let file = cfg.join("recorder.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains(from), "{from}");
    std::fs::write(&file, text.replacen(from, to, 1)).unwrap();
    cfg
}

/// A negative, an out-of-range and a misspelt key in `recorder.toml`: the
/// drive and its dry run fail before any service starts, with one error
/// line naming the file, the field and the reason, and no "no readable
/// log"; nothing is written at `--out`.
#[test]
fn a_recorder_toml_the_recorder_refuses_fails_before_any_service_starts() {
    for (from, to, field, why) in [
        (
            "flush_interval_ms = 500",
            "flush_interval_ms = -5",
            "flush_interval_ms",
            "invalid value: integer `-5`, expected u64",
        ),
        (
            "flush_interval_ms = 500",
            "flush_interval_ms = 5000",
            "flush_interval_ms",
            "must be in 10 ..= 1000 (got 5000)",
        ),
        (
            "queue_capacity = 65536",
            "queue_capacity = \"many\"",
            "queue_capacity",
            "invalid type: string \"many\"",
        ),
        (
            "flush_interval_ms = 500",
            "flush_interval = 500",
            "flush_interval",
            "unknown field `flush_interval`",
        ),
    ] {
        let d = tempfile::tempdir().unwrap();
        let cfg = config_with(d.path(), from, to);
        let file = cfg.join("recorder.toml");
        let out = d.path().join("drive.mcap");
        for dry in [false, true] {
            let f = Fakes::new();
            let mut args = vec![os("--scenario"), os("e2e"), os("--out"), out.as_os_str()];
            if dry {
                args.push(os("--dry-run"));
            }
            let (ok, so, err) = f.drive(&cfg, &args);
            assert!(!ok, "{to}, dry run {dry}: {so}{err}");
            assert!(
                f.started().is_empty(),
                "{to}, dry run {dry}: {:?}\n{err}",
                f.started()
            );
            assert!(!err.contains("no readable log"), "{to}: {err}");
            let said: Vec<&str> = err
                .lines()
                .filter(|l| l.contains(&format!("field `{field}`")))
                .collect();
            assert_eq!(said.len(), 1, "{to}, dry run {dry}: {err}");
            assert!(
                said[0].starts_with(&format!(
                    "error: the recorder's configuration (checked before any service starts): {}: field `{field}`: ",
                    file.display()
                )) && said[0].contains(why),
                "{to}, dry run {dry}: {err}"
            );
            assert!(
                !out.exists() && !d.path().join("drive.mcap.partial").exists(),
                "{to}"
            );
        }
    }
}

/// The check is the recorder's own start-up: the real recorder refuses
/// the same file with the same words (after the drive's context), and the
/// shipped `recorder.toml` passes the dry run. Needs the workspace's
/// binaries (`cargo build --workspace --bins`).
#[test]
fn the_drive_s_refusal_is_the_recorder_s_own() {
    let d = tempfile::tempdir().unwrap();
    let cfg = config_with(d.path(), "max_file_s = 3600", "max_file_s = 0");
    let f = Fakes::new();
    let (ok, so, err) = f.drive(&cfg, &[os("--dry-run")]);
    assert!(!ok, "{so}{err}");
    let drive_said = err
        .lines()
        .find_map(|l| {
            l.strip_prefix(
                "error: the recorder's configuration (checked before any service starts): ",
            )
        })
        .unwrap_or_else(|| panic!("{err}"));
    let recorder = Path::new(env!("CARGO_BIN_EXE_grip")).with_file_name("recorder");
    assert!(
        recorder.is_file(),
        "{}: build the workspace first",
        recorder.display()
    );
    let o = std::process::Command::new(&recorder)
        .arg("--config-dir")
        .arg(&cfg)
        .arg("--out")
        .arg(d.path().join("r.mcap"))
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    let rec_err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(78), "{rec_err}");
    assert!(
        rec_err
            .lines()
            .any(|l| l.strip_prefix("error: ") == Some(drive_said)),
        "drive: {drive_said}\nrecorder: {rec_err}"
    );
    assert!(drive_said.contains("field `max_file_s`: must be in 1 ..= 86400 (got 0)"));
    // the shipped file passes
    let f = Fakes::new();
    let (ok, so, err) = f.drive(&common::config_dir(), &[os("--dry-run")]);
    assert!(ok, "{so}{err}");
    assert!(so.contains("recorder:"), "{so}");
}
