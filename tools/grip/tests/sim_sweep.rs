//! `grip sim --sweep` end to end: one row per point and controller in
//! sweep.csv, the configuration as loaded reproduced by the grid point that
//! repeats it, baselines untouched by a `[preview]` value, the figure
//! written; bad axes refused with the key and the reason.

use std::ffi::OsStr;

mod common;
use common::{grip, output, run_ok};

/// `grip sim --seeds 2 --threads 2 --variants VARIANTS`.
fn sim(variants: &str) -> std::process::Command {
    let mut c = grip();
    c.args([
        "sim",
        "--seeds",
        "2",
        "--threads",
        "2",
        "--variants",
        variants,
    ]);
    c
}

#[test]
fn a_preview_sweep_reports_each_point_against_the_same_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let text = run_ok(
        sim("src,src-arte,mtte,mtte-arte")
            .args([
                "--sweep",
                "preview.cap_share=0.8,1.0",
                "--sweep-target",
                "0.4,0.98",
                "--out",
            ])
            .arg(&out),
    );
    assert!(text.contains("preview.cap_share = 0.8"), "{text}");
    assert!(text.contains("Target (--sweep-target)"), "{text}");
    assert!(
        text.contains(
            "Note: --sweep preview.cap_share does not reach SRC-ARTE: its own [preview.src] cap_share = 0.9 wins"
        ),
        "{text}"
    );
    assert!(!text.contains("reach MTTE-ARTE"), "{text}");
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        &header[..4],
        ["point", "label", "preview.cap_share", "controller"]
    );
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // 3 points (as configured, 0.8, 1.0) x 2 controllers.
    assert_eq!(rows.len(), 6, "{csv}");
    let get = |point: &str, ctl: &str, c: &str| -> f64 {
        let r = rows
            .iter()
            .find(|r| r[0] == point && r[3] == ctl)
            .unwrap_or_else(|| panic!("no row {point} {ctl} in {csv}"));
        r[col(c)].parse().unwrap()
    };
    // SRC-ARTE has its own cap ([preview.src] cap_share = 0.9 as shipped):
    // the shared value does not move it, its baseline neither.
    for p in ["1", "2"] {
        for c in ["slip_arte", "accel_arte", "slip_base"] {
            assert_eq!(get("0", "src", c), get(p, "src", c), "src {c} {p}");
        }
    }
    {
        let ctl = "mtte";
        // controllers.toml ships cap_share = 1.0: point 2 is point 0 again.
        for c in ["slip_arte", "accel_arte", "cmd_tv_arte"] {
            assert_eq!(get("0", ctl, c), get("2", ctl, c), "{ctl} {c}");
        }
        // [preview] is for the ARTE variants only: the baseline is the same
        // at every point, and the lower cap changes the ARTE variant.
        for p in ["1", "2"] {
            assert_eq!(get("0", ctl, "slip_base"), get(p, ctl, "slip_base"));
            assert_eq!(get("0", ctl, "accel_base"), get(p, ctl, "accel_base"));
        }
        assert_ne!(
            get("0", ctl, "slip_arte"),
            get("1", ctl, "slip_arte"),
            "{ctl}"
        );
        let ratio = get("1", ctl, "slip_ratio");
        let expect = get("1", ctl, "slip_arte") / get("1", ctl, "slip_base");
        assert!((ratio - expect).abs() < 1e-12, "{ratio} {expect}");
    }
    let png = std::fs::read(out.join("sweep.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(
        std::fs::read_to_string(out.join("sweep.txt"))
            .unwrap()
            .contains("as configured")
    );
}

#[test]
fn a_controllers_own_trade_is_swept_as_section_table_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("own");
    let text = run_ok(
        sim("src,src-arte,mtte,mtte-arte")
            .args(["--sweep", "preview.src.cap_share=0.8,0.9", "--out"])
            .arg(&out),
    );
    assert!(text.contains("preview.src.cap_share = 0.8"), "{text}");
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header[2], "preview.src.cap_share", "{csv}");
    let slip_arte = header.iter().position(|h| *h == "slip_arte").unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 6, "{csv}");
    let get = |point: &str, ctl: &str| -> &str {
        rows.iter()
            .find(|r| r[0] == point && r[3] == ctl)
            .unwrap_or_else(|| panic!("no row {point} {ctl} in {csv}"))[slip_arte]
    };
    // Shipped 0.9: point 2 is point 0 again; 0.8 moves SRC-ARTE alone.
    assert_eq!(get("0", "src"), get("2", "src"), "{csv}");
    assert_ne!(get("0", "src"), get("1", "src"), "{csv}");
    for p in ["1", "2"] {
        assert_eq!(get("0", "mtte"), get(p, "mtte"), "{csv}");
    }
}

#[test]
fn a_vehicle_axis_moves_the_microphone() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lead");
    let vehicle = common::config_dir().join("vehicles/front-mic.toml");
    run_ok(
        sim("src,src-arte")
            .arg("--vehicle")
            .arg(&vehicle)
            .args(["--sweep", "vehicle.mic_lead_m=0,2.77", "--out"])
            .arg(&out),
    );
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 3, "{csv}");
    // columns: point,label,vehicle.mic_lead_m,controller,slip_base,slip_arte,...
    let slip_arte = |p: &str| rows.iter().find(|r| r[0] == p).unwrap()[5];
    // front-mic.toml ships 2.77 m: point 2 is point 0 again; without the
    // lead the preview is gone and SRC-ARTE slips more.
    assert_eq!(slip_arte("0"), slip_arte("2"), "{csv}");
    let (lead0, lead277): (f64, f64) = (
        slip_arte("1").parse().unwrap(),
        slip_arte("2").parse().unwrap(),
    );
    assert!(lead0 > lead277, "{csv}");
}

#[test]
fn bad_sweeps_name_the_key_and_the_reason() {
    for (args, says) in [
        (
            vec!["--sweep", "previw.cap_share=0.8"],
            "controllers.toml has no [previw]",
        ),
        (vec!["--sweep", "preview.cap_share=2"], "cap_share"),
        (vec!["--sweep", "preview.cap_shar=0.8"], "cap_shar"),
        (
            vec!["--sweep", "preview.cap_share=0.8,x"],
            "`x` is not a TOML value",
        ),
        (vec!["--sweep", "cap_share=0.8"], "not a SECTION.KEY"),
        (
            vec!["--sweep", "preview.src.cap_share=2"],
            "preview.src.cap_share",
        ),
        (
            vec!["--sweep", "preview.src.cap=0.8"],
            "unknown field `cap`",
        ),
        (
            vec![
                "--variants",
                "src,mtte-arte",
                "--sweep",
                "preview.cap_share=0.8",
            ],
            "at least one controller with and without ARTE",
        ),
        (
            vec!["--sweep", "preview.cap_share=0.8", "--sweep-target", "0.4"],
            "expected SLIP,ACCEL",
        ),
        (vec!["--sweep", "vehicle.mic_leadd=1"], "mic_leadd"),
        (
            vec!["--scenario", "e2e", "--sweep", "vehicle.mic_lead_m=1"],
            "time segments",
        ),
    ] {
        let mut a: Vec<&OsStr> = vec![OsStr::new("sim"), OsStr::new("--seeds"), OsStr::new("1")];
        a.extend(args.iter().map(OsStr::new));
        let (ok, _, err) = output(&a);
        assert!(!ok, "{args:?} succeeded");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
