//! A directory of drive logs: `grip inspect DIR --csv FILE` gives one row
//! per drive (50 here: 46 good, a truncated, a cut-to-the-header, a
//! byte-flipped and a not-MCAP one), names every bad one with its reason,
//! and exits non-zero only with `--strict`; `grip replay DIR --jobs 2`
//! replays the good ones identically and names the bad ones without
//! stopping.

mod common;

use std::path::{Path, PathBuf};

fn reference() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap")
}

fn grip(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    common::output(args)
}

/// `good` links to the reference drive plus the four bad logs.
fn dir_with(good: usize) -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(reference()).unwrap();
    for i in 0..good {
        std::os::unix::fs::symlink(reference(), d.path().join(format!("d{i:02}.mcap"))).unwrap();
    }
    std::fs::write(d.path().join("cut.mcap"), &bytes[..bytes.len() / 2]).unwrap();
    std::fs::write(d.path().join("header.mcap"), &bytes[..100]).unwrap();
    let mut flip = bytes.clone();
    let at = bytes.len() / 5;
    flip[at] ^= 0x5A;
    std::fs::write(d.path().join("flip.mcap"), &flip).unwrap();
    std::fs::write(d.path().join("text.mcap"), "not a log").unwrap();
    d
}

#[test]
fn inspect_dir_one_row_per_drive_bad_ones_named() {
    let d = dir_with(46);
    let (ok, out, err, csv) = common::inspect_dir(d.path());
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("50 logs, 4 bad: cut.mcap, flip.mcap, header.mcap, text.mcap"),
        "{out}"
    );
    for bad in ["cut.mcap", "flip.mcap", "header.mcap", "text.mcap"] {
        assert!(
            err.contains(&format!("bad log {bad}: ")),
            "{bad} not named:\n{err}"
        );
    }
    let table = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = table.lines().skip(1).collect();
    assert_eq!(rows.len(), 50);
    assert_eq!(
        rows.iter()
            .filter(|r| r.split(',').nth(1) == Some("ok"))
            .count(),
        46
    );
    assert!(
        rows.iter()
            .any(|r| r.starts_with("text.mcap,unreadable,") && r.contains("not an MCAP file")),
        "{table}"
    );
    assert!(
        rows.iter().any(|r| r.starts_with("cut.mcap,incomplete,")),
        "{table}"
    );
    // a good row carries the metrics
    let good = rows.iter().find(|r| r.starts_with("d00.mcap")).unwrap();
    let slip: f64 = good.split(',').nth(8).unwrap().parse().unwrap();
    assert!(slip > 0.0 && slip < 1.0, "{good}");
    let (ok, _, err) = grip(&[
        "inspect".as_ref(),
        d.path().as_os_str(),
        "--strict".as_ref(),
    ]);
    assert!(
        !ok && err.contains("4 of 50 logs are bad (--strict)"),
        "{err}"
    );
}

#[test]
fn replay_dir_names_bad_logs_and_goes_on() {
    let d = dir_with(2);
    let (ok, out, err) = grip(&[
        "replay".as_ref(),
        d.path().as_os_str(),
        "--jobs".as_ref(),
        "2".as_ref(),
    ]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains("d00.mcap: identical") && out.contains("d01.mcap: identical"),
        "{out}"
    );
    for bad in ["cut.mcap", "flip.mcap", "header.mcap", "text.mcap"] {
        assert!(
            out.contains(&format!("{bad}: not replayed: ")),
            "{bad}:\n{out}"
        );
    }
    assert!(
        out.contains("6 logs, 4 not identical or not replayed"),
        "{out}"
    );
    let (ok, _, err) = grip(&["replay".as_ref(), d.path().as_os_str(), "--check".as_ref()]);
    assert!(
        !ok && err.contains("4 of 6 logs did not replay identically"),
        "{err}"
    );
}
