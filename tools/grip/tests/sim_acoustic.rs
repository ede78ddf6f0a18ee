//! `grip sim --arte acoustic` end to end: the real acoustic chain (synthetic
//! audio of the plant's true road and speed, features, classifier, HMM
//! smoothing) drives the ARTE variants on the reference scenario.
//!
//! The model is `$GRIP_TEST_ARTE_MODEL` when set (`train`: always train),
//! else the shipped `config/models/default.model` when it exists, else one
//! trained here on a small synthetic dataset of the paper's four roads
//! (rain and passing cars at 10 dB, like the shipped models).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod common;
use common::{config_dir, grip, run_ok};

/// Directory kept for the whole test binary (training once).
fn scratch() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("tempdir"))
        .path()
}

fn model() -> &'static Path {
    static MODEL: OnceLock<PathBuf> = OnceLock::new();
    MODEL.get_or_init(|| {
        let forced = std::env::var_os("GRIP_TEST_ARTE_MODEL");
        if let Some(p) = forced.as_ref().filter(|p| *p != "train") {
            let p = PathBuf::from(p);
            eprintln!("model (GRIP_TEST_ARTE_MODEL): {}", p.display());
            return p;
        }
        let shipped = config_dir().join("models/default.model");
        if forced.is_none() && shipped.is_file() {
            eprintln!("model: {}", shipped.display());
            return shipped;
        }
        let data = scratch().join("data");
        run_ok(grip().args(["dataset", "synth", "--out"]).arg(&data).args([
            "--roads",
            "asphalt,gravel,snow,stone",
            "--recordings-per-class",
            "8",
            "--duration",
            "4",
            "--seed",
            "5",
            "--noise",
            "rain,car",
            "--snr-db",
            "10",
        ]));
        let m = scratch().join("test.model");
        run_ok(
            grip()
                .args(["train", "--data"])
                .arg(&data)
                .args([
                    "--features",
                    "rich",
                    "--hidden",
                    "12",
                    "--folds",
                    "0",
                    "--out",
                ])
                .arg(&m),
        );
        eprintln!("model: trained {}", m.display());
        m
    })
}

fn sim(out: &Path, extra: &[&str]) -> String {
    run_ok(
        grip()
            .args([
                "sim",
                "--arte",
                "acoustic",
                "--scenario",
                "paper",
                "--model",
            ])
            .arg(model())
            .arg("--out")
            .arg(out)
            .args(extra),
    )
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// (variant, decisions, correct, single_road, single_road_correct, stable delays)
type InLoopRow = (String, u64, u64, u64, u64, Vec<Option<f64>>);

fn inloop(dir: &Path) -> Vec<InLoopRow> {
    let text = read(&dir.join("arte_inloop.csv"));
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "variant,seed,decisions,correct,single_road,single_road_correct,first_delays_s,stable_delays_s"
        )
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            let n = |i: usize| f[i].parse::<u64>().unwrap();
            let delays = f[7]
                .split(';')
                .map(|d| (d != "missed").then(|| d.parse::<f64>().unwrap()))
                .collect();
            (f[0].to_owned(), n(2), n(3), n(4), n(5), delays)
        })
        .collect()
}

/// The reference scenario with three seeds and the default noise (rain and
/// passing cars at 10 dB SNR): the acoustic chain recognises the road most
/// of the time, detects nearly every change, and every variant's metrics are
/// finite.
///
/// Measured on these seeds (1..=3, all three ARTE variants):
/// - shipped `default.model` of 2026-11-22 (SVM, Rich + fixed bands,
///   speed exponent 0.1, 6 classes), 10 dB, hop 0.025 s: 83.6 % of all
///   in-loop decisions correct, 95.9 % of single-road frames, none of the
///   36 changes missed. Over 20 seeds: 81.0 % / 92.5 % (crates/sim/README.md,
///   which also explains why "all decisions" counts the lag after a change);
/// - the 4-class model trained here (GRIP_TEST_ARTE_MODEL=train; training
///   audio with rain and cars at 10 dB): 88.9 %, 94.3 %, none missed.
///
/// Asserted with margin: at least 65 % overall, at least 70 % on single-road
/// frames, at most 15 % of the changes missed, every detected change within
/// 0.6 s (the next change comes 0.4-0.6 s later).
/// Decisions in the 2.4 s reference scenario at 44.1 kHz: the first when the
/// 0.1 s frame (4410 samples) is full, then one per default hop (0.025 s =
/// 1103 samples).
const DECISIONS: u64 = (105_840 - 4410) / 1103 + 1;

#[test]
fn reference_scenario_in_the_loop() {
    let dir = scratch().join("ref");
    let table = sim(&dir, &["--seeds", "3"]);
    assert!(table.contains("ARTE source: acoustic (model"), "{table}");
    assert!(table.contains("ARTE in the loop (acoustic"), "{table}");
    assert!(table.contains("noise: rain+car at 10 dB SNR"), "{table}");

    let rows = inloop(&dir);
    // Three ARTE variants x three seeds.
    assert_eq!(rows.len(), 9);
    let (mut dec, mut ok, mut single, mut single_ok) = (0, 0, 0, 0);
    let (mut changes, mut missed) = (0, 0);
    for (variant, d, c, s, sc, delays) in &rows {
        assert!(variant.ends_with("-arte"), "{variant}");
        // 2.4 s: first decision at 0.1 s, then every hop.
        assert_eq!(*d, DECISIONS, "{variant}");
        // Changes at 0.4, 1.0, 1.4 and 1.8 s.
        assert_eq!(delays.len(), 4, "{variant}: {delays:?}");
        for x in delays {
            changes += 1;
            match x {
                Some(x) => assert!((0.0..=0.6).contains(x), "{variant}: delay {x} s"),
                None => missed += 1,
            }
        }
        dec += d;
        ok += c;
        single += s;
        single_ok += sc;
    }
    let acc = ok as f64 / dec as f64;
    let single_acc = single_ok as f64 / single as f64;
    eprintln!("in-loop accuracy {acc:.3}, single-road {single_acc:.3}, missed {missed}/{changes}");
    assert!(acc >= 0.65, "in-loop accuracy {acc}");
    assert!(single_acc >= 0.70, "single-road accuracy {single_acc}");
    assert!(
        missed * 100 <= changes * 15,
        "{missed} of {changes} changes never detected"
    );

    // Every run's metrics are finite (SRC-ARTE and MTTE-ARTE included) and
    // the ARTE variants received decisions.
    let summary = read(&dir.join("summary.csv"));
    let mut lines = summary.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (frames, non_finite) = (col("arte_frames"), col("non_finite_cycles"));
    let mut seen = Vec::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        for (i, h) in header.iter().enumerate().skip(2) {
            if *h == "arte_accuracy" && !f[0].ends_with("-arte") {
                continue; // NaN (empty) without ARTE
            }
            let x: f64 = f[i]
                .parse()
                .unwrap_or_else(|_| panic!("{}: `{h}` = `{}` is not a number", f[0], f[i]));
            assert!(x.is_finite(), "{}: {h} = {x}", f[0]);
        }
        if f[0].ends_with("-arte") {
            assert_eq!(f[frames], DECISIONS.to_string(), "{l}");
        }
        assert_eq!(f[non_finite], "0", "{l}");
        seen.push(f[0].to_owned());
    }
    for v in ["src-arte", "mtte-arte", "mfc-arte", "src", "mtte", "mfc"] {
        assert_eq!(seen.iter().filter(|s| *s == v).count(), 3, "{v}: {seen:?}");
    }
}

/// Same seeds give identical results, whatever the thread count; another
/// seed gives another car (another result).
#[test]
fn same_seed_same_summary() {
    let a = scratch().join("det_a");
    let b = scratch().join("det_b");
    let c = scratch().join("det_c");
    let args = [
        "--seeds",
        "2",
        "--seed0",
        "11",
        "--variants",
        "src-arte,mtte-arte",
    ];
    sim(&a, &[&args[..], &["--threads", "1"]].concat());
    sim(&b, &[&args[..], &["--threads", "2"]].concat());
    sim(
        &c,
        &[
            "--seeds",
            "2",
            "--seed0",
            "12",
            "--variants",
            "src-arte,mtte-arte",
        ],
    );
    let (sa, sb, sc) = (
        read(&a.join("summary.csv")),
        read(&b.join("summary.csv")),
        read(&c.join("summary.csv")),
    );
    assert_eq!(sa, sb);
    assert_eq!(
        read(&a.join("arte_inloop.csv")),
        read(&b.join("arte_inloop.csv"))
    );
    // Seeds 12, 13 vs 11, 12: the shared seed 12 rows agree, seed 11 differs from 13.
    let rows = |s: &str, seed: &str| -> Vec<String> {
        s.lines()
            .filter(|l| l.split(',').nth(1) == Some(seed))
            .map(|l| l.split(',').skip(2).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(rows(&sa, "12"), rows(&sc, "12"));
    assert_ne!(rows(&sa, "11"), rows(&sc, "13"));
}

/// Clean audio (`--snr-db off`) runs; bad inputs give errors naming what is wrong.
#[test]
fn noise_and_errors() {
    let dir = scratch().join("noise");
    let table = sim(
        &dir,
        &["--seeds", "1", "--variants", "src-arte", "--snr-db", "off"],
    );
    assert!(table.contains("noise: none"), "{table}");
    assert_eq!(inloop(&dir).len(), 1);

    let missing = scratch().join("no-such.model");
    let out = grip()
        .args(["sim", "--arte", "acoustic", "--seeds", "1", "--model"])
        .arg(&missing)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such.model"), "{err}");

    let bad = scratch().join("bad.model");
    std::fs::write(&bad, b"not a model").unwrap();
    let out = grip()
        .args(["sim", "--arte", "acoustic", "--seeds", "1", "--model"])
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.model"), "{err}");

    let out = grip()
        .args(["sim", "--arte", "acoustic", "--snr-db", "loud"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("loud") && err.contains("--snr-db"), "{err}");

    let out = grip()
        .args([
            "sim",
            "--arte",
            "acoustic",
            "--seeds",
            "1",
            "--sound-as",
            "ice=tarmac",
            "--model",
        ])
        .arg(model())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tarmac"), "{err}");
}
