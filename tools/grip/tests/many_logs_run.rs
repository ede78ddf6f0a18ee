//! `grip inspect DIR` names each drive's run: the reference drive (MTTE,
//! ARTE on, seed 1, its attached vehicle.toml) and its open-loop replay
//! with SRC and ARTE off (`grip replay --out`), whose figures are the
//! same, are told apart by the printed table's `ctrl` and `arte` columns
//! and by the CSV's `controller` and `arte`, not only by their file names;
//! the CSV's run and vehicle columns hold what `grip inspect --json` gives.
//! A log copied to a name with a space is one quoted cell of the printed
//! table, whose other columns keep their places.

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
        // --json gives the microphone's lead too (it had none)
        assert_eq!(
            col("mic_lead_m").parse::<f64>().ok(),
            j["mic_lead_m"].as_f64(),
            "{file}: mic_lead_m"
        );
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

/// A file name with a space is one cell of the printed table, quoted (it
/// was printed as it is, so a reader splitting the row at white space
/// read the name as two cells and every column after it shifted by one),
/// and the CSV keeps the name.
#[test]
fn inspect_dir_quotes_a_file_name_with_a_space() {
    let d = tempfile::tempdir().unwrap();
    std::fs::copy(reference(), d.path().join("my drive.mcap")).unwrap();
    std::os::unix::fs::symlink(reference(), d.path().join("on.mcap")).unwrap();
    let (ok, out, err, csv) = common::inspect_dir(d.path());
    assert!(ok, "{out}{err}");
    let lines: Vec<&str> = out.lines().collect();
    let head = lines[0];
    let row = |file: &str| {
        *lines
            .iter()
            .find(|l| l.starts_with(file))
            .unwrap_or_else(|| panic!("{file} not in\n{out}"))
    };
    let spaced = row("\"my drive.mcap\" ");
    let plain = row("on.mcap ");
    // the columns after the file's keep their places: the same cells as
    // the same drive under a plain name, from the header's `status` on
    let status = head.find("status").unwrap();
    assert_eq!(spaced[status..], plain[status..], "{out}");
    assert!(spaced[status..].starts_with("ok "), "{out}");
    // a reader splitting at white space finds the header's columns after
    // the file
    let words = |l: &str| l[status..].split_whitespace().count();
    assert_eq!(words(spaced), words(head), "{out}");
    assert!(out.contains("2 logs, 0 bad"), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let files: Vec<String> = rd.records().map(|r| r.unwrap()[0].to_owned()).collect();
    assert_eq!(files, ["my drive.mcap", "on.mcap"]);
}
