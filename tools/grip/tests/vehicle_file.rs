//! The vehicle file as a user writes it for their own car: `grip sim`
//! names the `[vehicle]` fields it left to the paper's quarter-car defaults
//! (and the shipped files, which set them all, get no warning), and refuses
//! an implausible value naming the file, field, range and unit.

use std::process::Output;

mod common;
use common::{config_dir, grip};

fn sim(vehicle: &std::path::Path, out: &std::path::Path) -> Output {
    grip()
        .args(["sim", "--seeds", "1", "--variants", "mtte", "--vehicle"])
        .arg(vehicle)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn defaulted_fields_are_named_and_implausible_values_refused() {
    let tmp = tempfile::tempdir().unwrap();
    // a partial file: every field but the drive layout and the limit
    let partial = tmp.path().join("my-car.toml");
    std::fs::write(
        &partial,
        "[vehicle]\nmass = 1400.0\nj_w = 0.6\nr = 0.28\nm_wheel = 10.0\ntau_m = 0.05\nc_rr = 0.015\nrho = 1.2\nc_d_a = 0.7\nv_eps = 0.1\nmic_lead_m = 0.0\n",
    )
    .unwrap();
    let o = sim(&partial, &tmp.path().join("a"));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("my-car.toml: [vehicle] does not set n_driven, torque_max, driven_load_share: they take the paper's quarter-car defaults (n_driven = 4, torque_max = 1000, driven_load_share = 1)"),
        "{err}"
    );
    // the shipped files set every field
    for f in ["vehicle.toml", "vehicles/front-mic.toml"] {
        let o = sim(&config_dir().join(f), &tmp.path().join("b"));
        let err = stderr(&o);
        assert!(o.status.success(), "{f}: {err}");
        assert!(!err.contains("does not set"), "{f}: {err}");
    }
    // millimetres typed as metres
    let mm = tmp.path().join("mm.toml");
    let text = std::fs::read_to_string(config_dir().join("vehicle.toml"))
        .unwrap()
        .replace("r = 0.28 ", "r = 334.0 ");
    std::fs::write(&mm, text).unwrap();
    let o = sim(&mm, &tmp.path().join("c"));
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    for says in [
        "mm.toml",
        "vehicle.r",
        "334 m is outside [0.1, 1] m",
        "334 mm is 0.334 m",
    ] {
        assert!(err.contains(says), "{says}: {err}");
    }
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// MFC's gain is the paper's car's: `grip analyze --vehicle` shows the
/// bounds of the user's own file, and on a light car with small wheels,
/// where K_MFC = 177 lies above the no-overshoot bound (4) on some roads,
/// `grip analyze` and `grip sim` (with an MFC variant) say so, naming the
/// files and roads; the shipped cars get no such warning.
#[test]
fn analyze_takes_the_users_vehicle_and_the_mfc_gain_is_checked_against_it() {
    let tmp = tempfile::tempdir().unwrap();
    let analyze = |vehicle: &std::path::Path| {
        grip()
            .args(["analyze", "--vehicle"])
            .arg(vehicle)
            .output()
            .unwrap()
    };
    let front = config_dir().join("vehicles/front-mic.toml");
    let o = analyze(&front);
    let out = stdout(&o);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.contains("front-mic.toml) =="), "{out}");
    // front-mic's heavier wheel share: asphalt's bound is its own, not vehicle.toml's 582
    let asphalt = out
        .lines()
        .find(|l| l.trim_start().starts_with("asphalt (lambda_opt)"))
        .unwrap();
    assert!(asphalt.contains("1136.9768"), "{asphalt}");
    assert!(!out.contains("warning"), "{out}");

    let light = tmp.path().join("light-car.toml");
    let text = std::fs::read_to_string(config_dir().join("vehicle.toml"))
        .unwrap()
        .replace("mass = 1400.0 ", "mass = 800.0 ")
        .replace("j_w = 0.6 ", "j_w = 0.4 ")
        .replace("r = 0.28 ", "r = 0.25 ");
    assert!(text.contains("mass = 800.0") && text.contains("r = 0.25"));
    std::fs::write(&light, text).unwrap();
    let o = analyze(&light);
    let out = stdout(&o);
    assert!(o.status.success(), "{}", stderr(&o));
    let stone = out
        .lines()
        .find(|l| l.trim_start().starts_with("stone (lambda_opt)"))
        .unwrap();
    assert!(stone.trim_end().ends_with("NO"), "{stone}");
    for says in [
        "warning: ",
        "controllers.toml: [mfc] k_mfc = 177",
        "light-car.toml",
        "stone",
    ] {
        assert!(out.contains(says), "{says}: {out}");
    }

    let sim = |vehicle: &std::path::Path, out: &str| {
        grip()
            .args(["sim", "--seeds", "1", "--variants", "mfc", "--vehicle"])
            .arg(vehicle)
            .arg("--out")
            .arg(tmp.path().join(out))
            .output()
            .unwrap()
    };
    let o = sim(&light, "light");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: ") && err.contains("k_mfc = 177") && err.contains("light-car.toml"),
        "{err}"
    );
    let o = sim(&config_dir().join("vehicle.toml"), "shipped");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("k_mfc"), "{err}");

    // a sweep checks each point's gain: the shipped car at 400 N m s/rad
    // is above the bound on some roads, at 177 it is not
    let o = grip()
        .args([
            "sim",
            "--seeds",
            "1",
            "--variants",
            "mfc,mfc-arte",
            "--sweep",
            "mfc.k_mfc=177,400",
        ])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warned: Vec<&str> = err.lines().filter(|l| l.contains("bound (4)")).collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].starts_with("warning: --sweep mfc.k_mfc = 400: ") && warned[0].contains("stone"),
        "{err}"
    );
}
