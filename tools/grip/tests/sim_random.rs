//! `grip sim --scenario random` end to end: each seed's roads in the report
//! and in scenarios.csv, the same output for the same seeds, and the
//! `--entry-plot` zoom with `--compare-vehicle`.

use std::path::Path;

mod common;
use common::{config_dir, grip, run_ok};

fn random(out: &Path) -> String {
    run_ok(
        grip()
            .args([
                "sim",
                "--scenario",
                "random",
                "--seed0",
                "1000",
                "--seeds",
                "2",
                "--threads",
                "2",
                "--out",
            ])
            .arg(out),
    )
}

#[test]
fn random_scenarios_are_listed_and_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let text = random(&a);
    random(&b);
    assert!(text.contains("seed 1000: "), "{text}");
    assert!(text.contains("seed 1001: "), "{text}");
    let csv = std::fs::read_to_string(a.join("scenarios.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("seed,segment,road,length_m,start_m"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().any(|r| r[0] == "1000") && rows.iter().any(|r| r[0] == "1001"));
    for r in &rows {
        assert!(grip_arte::synth::road_index(r[2]).is_some(), "{r:?}");
        let len: f64 = r[3].parse().unwrap();
        assert!((1.0..=4.0).contains(&len), "{r:?}");
    }
    let seq = |s: &str| -> Vec<&str> { rows.iter().filter(|r| r[0] == s).map(|r| r[2]).collect() };
    assert_ne!(seq("1000"), seq("1001"));
    for f in ["summary.csv", "scenarios.csv"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f} differs between two runs of the same seeds"
        );
    }
}

#[test]
fn entry_plot_draws_both_vehicles() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config_dir();
    run_ok(
        grip()
            .args([
                "sim",
                "--scenario",
                "paper",
                "--seeds",
                "1",
                "--variants",
                "mtte,mtte-arte",
            ])
            .arg("--vehicle")
            .arg(cfg.join("vehicles/front-mic.toml"))
            .arg("--compare-vehicle")
            .arg(cfg.join("vehicle.toml"))
            .args(["--entry-plot", "snow", "--out"])
            .arg(dir.path()),
    );
    let png = std::fs::read(dir.path().join("entry_snow.png")).unwrap();
    assert!(png.len() > 10_000 && png.starts_with(b"\x89PNG"));
    let out = grip()
        .args(["sim", "--seeds", "1", "--entry-plot", "nosuchroad", "--out"])
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("nosuchroad") && err.contains("not a catalogue road"),
        "{err}"
    );
}
