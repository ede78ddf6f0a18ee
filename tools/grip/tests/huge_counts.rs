//! Counts and lengths a machine cannot hold are refused by name before
//! any work (found by an audit of the command line, 2026-12-07: each of
//! these aborted, panicked or ran out of memory): a sweep's grid counted
//! before it is built, `grip dataset synth`'s counts and shortest segment,
//! `grip generate --count`, `grip drive --ready-timeout`; and a scenario
//! name that points to a file where grip runs.

mod common;

use std::ffi::OsStr;

fn refused(args: &[&str], said: &str) {
    let a: Vec<&OsStr> = args.iter().map(OsStr::new).collect();
    let (ok, out, err) = common::output(&a);
    assert!(!ok, "{args:?} ran: {out}");
    assert!(err.contains(said), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_sweep_too_large_is_refused_before_its_grid_is_built() {
    let v: Vec<String> = (1..=30).map(|i| i.to_string()).collect();
    let v = v.join(",");
    let sweeps: Vec<String> = (1..=6).map(|k| format!("mtte.k{k}={v}")).collect();
    let mut args = vec!["sim", "--seeds", "1"];
    for s in &sweeps {
        args.push("--sweep");
        args.push(s);
    }
    refused(
        &args,
        "--sweep: 30 x 30 x 30 x 30 x 30 x 30 grid points (the product of the axes' value counts) are more than 200",
    );
}

#[test]
fn dataset_synth_counts_and_segments_have_bounds() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("ds");
    let out = out.to_str().unwrap();
    refused(
        &[
            "dataset",
            "synth",
            "--out",
            out,
            "--recordings-per-class",
            "100000000000",
        ],
        "--recordings-per-class 100000000000: at most 1000000",
    );
    refused(
        &[
            "dataset",
            "synth",
            "--out",
            out,
            "--recordings-per-class",
            "1",
            "--changes",
            "18446744073709551615",
        ],
        "--changes 18446744073709551615: at most 1000000",
    );
    refused(
        &[
            "dataset",
            "synth",
            "--out",
            out,
            "--changes",
            "1",
            "--segment",
            "0.000000001",
        ],
        "--segment: segments must be at least 0.01 s long",
    );
    assert!(!d.path().join("ds").exists());
}

#[test]
fn generate_count_and_drive_ready_timeout_have_bounds() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("logs");
    refused(
        &[
            "generate",
            "--count",
            "100000000000",
            "--out",
            out.to_str().unwrap(),
        ],
        "--count 100000000000: must be 1 to 1000000",
    );
    refused(
        &["drive", "--dry-run", "--ready-timeout", "1e300"],
        "--ready-timeout 1e300: must be a positive number of seconds, at most 3600",
    );
}

/// `--scenario NAME` reads `<config-dir>/scenarios/NAME.toml`; when that
/// does not exist but `./NAME.toml` does, the error says how to give it
/// (a newcomer's `--scenario myscen` said only "cannot read").
#[test]
fn a_scenario_name_points_to_the_file_here() {
    let d = tempfile::tempdir().unwrap();
    std::fs::copy(
        common::config_dir().join("scenarios/e2e.toml"),
        d.path().join("myscen.toml"),
    )
    .unwrap();
    let o = common::grip()
        .current_dir(d.path())
        .args(["sim", "--scenario", "myscen", "--seeds", "1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("scenarios/myscen.toml")
            && err.contains(
                "the file myscen.toml where grip runs is given as a path: --scenario myscen.toml"
            ),
        "{err}"
    );
    // given so, it runs
    let o = common::grip()
        .current_dir(d.path())
        .args(["sim", "--scenario", "myscen.toml", "--seeds", "1"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
