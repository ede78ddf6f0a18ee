//! `grip inspect DIR` names each drive's run: the reference drive (MTTE,
//! ARTE on, seed 1, its attached vehicle.toml) and its open-loop replay
//! with SRC and ARTE off (`grip replay --out`), whose figures are the
//! same, are told apart by the printed table's `ctrl` and `arte` columns
//! and by the CSV's `controller` and `arte`, not only by their file names;
//! the CSV's run and vehicle columns hold what `grip inspect --json` gives.

mod common;

use std::path::{Path, PathBuf};

use serde_json::Value;

fn reference() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/reference-drive.mcap")
}

fn json_of(path: &Path) -> Value {
    let (ok, out, err) = common::output(&["inspect".as_ref(), "--json".as_ref(), path.as_os_str()]);
    assert!(ok, "{out}{err}");
    serde_json::from_str(out.lines().next().unwrap()).unwrap()
}

#[test]
fn inspect_dir_tells_the_runs_apart() {
    let d = tempfile::tempdir().unwrap();
    let on = d.path().join("on.mcap");
    std::os::unix::fs::symlink(reference(), &on).unwrap();
    let off = d.path().join("off.mcap");
    let r = reference();
    let (ok, out, err) = common::output(&[
        "replay".as_ref(),
        r.as_os_str(),
        "--controller".as_ref(),
        "src".as_ref(),
        "--arte".as_ref(),
        "off".as_ref(),
        "--out".as_ref(),
        off.as_os_str(),
    ]);
    assert!(ok, "{out}{err}");
    let (ok, out, err, csv) = common::inspect_dir(d.path());
    assert!(ok, "{out}{err}");

    // the printed table: the run beside the file
    let words = |l: &str| -> Vec<String> { l.split_whitespace().map(str::to_owned).collect() };
    let head = words(out.lines().next().unwrap());
    let row = |file: &str| {
        words(
            out.lines()
                .find(|l| l.starts_with(file))
                .unwrap_or_else(|| panic!("{file} not in\n{out}")),
        )
    };
    assert_eq!(
        head[..6],
        ["file", "status", "ctrl", "arte", "vehicle", "seed"],
        "{out}"
    );
    assert_eq!(
        row("on.mcap")[..6],
        ["on.mcap", "ok", "mtte", "on", "vehicle.toml", "1"],
        "{out}"
    );
    assert_eq!(
        row("off.mcap")[..6],
        ["off.mcap", "ok", "src", "off", "vehicle.toml", "1"],
        "{out}"
    );
    assert!(
        out.contains("ctrl, arte, seed: the controller, ARTE switch and seed the drive ran with"),
        "{out}"
    );

    // the CSV: as --json gives them
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = rd.headers().unwrap().iter().map(str::to_owned).collect();
    let rows: Vec<Vec<String>> = rd
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect();
    for (file, path) in [("on.mcap", &on), ("off.mcap", &off)] {
        let j = json_of(path);
        let r = rows.iter().find(|r| r[0] == file).unwrap();
        let col = |c: &str| r[header.iter().position(|h| h == c).unwrap()].as_str();
        for c in ["controller", "arte", "seed", "vehicle", "vehicle_sha256"] {
            assert_eq!(col(c), j[c].as_str().unwrap(), "{file} {c}");
        }
        assert_eq!(col("mic_lead_m"), "0", "{file}: config/vehicle.toml's");
        assert_eq!(col("vehicle"), "vehicle.toml (attached to the log)");
    }
    let col = |file: &str, c: &str| {
        let r = rows.iter().find(|r| r[0] == file).unwrap();
        r[header.iter().position(|h| h == c).unwrap()].clone()
    };
    assert_eq!(
        (col("on.mcap", "arte"), col("off.mcap", "arte")),
        ("on".to_owned(), "off".to_owned())
    );
    // an open-loop replay: the same plant, so the same metrics (only the
    // run tells them apart)
    assert_eq!(
        col("on.mcap", "slip_deviation"),
        col("off.mcap", "slip_deviation")
    );
}
