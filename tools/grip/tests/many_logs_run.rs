//! `grip inspect DIR` names each drive's run: the reference drive (MTTE,
//! ARTE on, seed 1, its attached vehicle.toml) and its open-loop replay
//! with SRC and ARTE off (`grip replay --out`), whose figures are the
//! same, are told apart by the printed table's `ctrl` and `arte` columns
//! and by the CSV's `controller` and `arte`, not only by their file names;
//! the CSV's run and vehicle columns hold what `grip inspect --json` gives.
//! A log copied to a name with a space is one quoted cell of the printed
//! table, whose other columns keep their places. Drives of one scenario,
//! controller, vehicle and seed with ARTE on and off are paired, their
//! ratios those of the CSV's figures.

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

/// `grip inspect DIR --csv`'s header and rows.
fn csv_table(csv: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = rd.headers().unwrap().iter().map(str::to_owned).collect();
    let rows: Vec<Vec<String>> = rd
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect();
    (header, rows)
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
    // a replay with ARTE off alone: the drive's scenario, controller,
    // vehicle and seed, which would pair with it were it a drive
    let mtte_off = d.path().join("replay-off.mcap");
    let (ok, out, err) = common::output(&[
        "replay".as_ref(),
        r.as_os_str(),
        "--arte".as_ref(),
        "off".as_ref(),
        "--out".as_ref(),
        mtte_off.as_os_str(),
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
    let (header, rows) = csv_table(&csv);
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
        // the ground truth's figures, as --json's metrics, to the last bit
        for c in [
            "slip_deviation",
            "mean_accel_ms2",
            "kinetic_energy_gain_j",
            "cmd_tv_per_s",
        ] {
            assert_eq!(
                col(c).parse::<f64>().ok(),
                j["metrics"][c].as_f64(),
                "{file} {c}"
            );
        }
    }
    let col = |file: &str, c: &str| {
        let r = rows.iter().find(|r| r[0] == file).unwrap();
        r[header.iter().position(|h| h == c).unwrap()].clone()
    };
    // a replay does not pair with the drive it replays
    assert_eq!(
        (
            col("replay-off.mcap", "controller"),
            col("replay-off.mcap", "arte")
        ),
        ("mtte".to_owned(), "off".to_owned())
    );
    assert!(!out.contains("ARTE on against off"), "{out}");
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

/// Two seeds of `grip generate`, each with ARTE on and off, in one
/// directory: the "ARTE on against off" block pairs them by seed and gives
/// the mean, least and greatest of the ratios the CSV's figures make.
#[test]
fn inspect_dir_pairs_arte_on_with_off() {
    let d = tempfile::tempdir().unwrap();
    let all = d.path().join("all");
    std::fs::create_dir(&all).unwrap();
    for arte in ["on", "off"] {
        let gen_dir = d.path().join(arte);
        let (ok, out, err) = common::output(&[
            "generate".as_ref(),
            "--out".as_ref(),
            gen_dir.as_os_str(),
            "--count".as_ref(),
            "2".as_ref(),
            "--scenario".as_ref(),
            "paper".as_ref(),
            "--arte".as_ref(),
            arte.as_ref(),
        ]);
        assert!(ok, "{out}{err}");
        for seed in [1, 2] {
            let from = gen_dir.join(format!("gen-0000{}-s{seed}.mcap", seed - 1));
            std::fs::rename(from, all.join(format!("{arte}-{seed}.mcap"))).unwrap();
        }
    }
    let (ok, out, err, csv) = common::inspect_dir(&all);
    assert!(ok, "{out}{err}");
    let (header, rows) = csv_table(&csv);
    let value = |file: &str, c: &str| -> f64 {
        let r = rows.iter().find(|r| r[0] == file).unwrap();
        r[header.iter().position(|h| h == c).unwrap()]
            .parse()
            .unwrap()
    };
    // the ratios on/off of seeds 1 and 2: mean [least, greatest]
    let cell = |c: &str, decimals: usize| -> Vec<String> {
        let q: Vec<f64> = [1, 2]
            .iter()
            .map(|s| value(&format!("on-{s}.mcap"), c) / value(&format!("off-{s}.mcap"), c))
            .collect();
        let (lo, hi) = (q[0].min(q[1]), q[0].max(q[1]));
        vec![
            format!("{:.decimals$}x", (q[0] + q[1]) / 2.0),
            format!("[{lo:.decimals$},"),
            format!("{hi:.decimals$}]"),
        ]
    };
    let at_least = [1, 2]
        .iter()
        .filter(|s| {
            value(&format!("on-{s}.mcap"), "mean_accel_ms2")
                >= value(&format!("off-{s}.mcap"), "mean_accel_ms2")
        })
        .count();
    let mut want: Vec<String> = ["paper", "mtte", "vehicle.toml", "2"]
        .iter()
        .map(|s| (*s).to_owned())
        .collect();
    want.extend(cell("slip_deviation", 3));
    want.extend(cell("mean_accel_ms2", 4));
    want.push(format!("{at_least}/2"));
    want.extend(cell("cmd_tv_per_s", 2));
    let block = &out[out
        .find("ARTE on against off")
        .unwrap_or_else(|| panic!("no pairs in\n{out}"))..];
    let line = block
        .lines()
        .find(|l| l.starts_with("paper "))
        .unwrap_or_else(|| panic!("{block}"));
    assert_eq!(line.split_whitespace().collect::<Vec<_>>(), want, "{block}");
    // the road estimate cuts the generated drives' slip
    assert!(value("on-1.mcap", "slip_deviation") < value("off-1.mcap", "slip_deviation"));
    let words = block.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        words.contains("4 of 4 complete drives (not replays) paired"),
        "{block}"
    );
}
