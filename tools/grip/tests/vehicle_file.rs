//! The vehicle file as a user writes it for their own car: `grip sim`
//! names the `[vehicle]` fields it left to the paper's quarter-car defaults
//! (and the shipped files, which set them all, get no warning), and refuses
//! an implausible value naming the file, field, range and unit.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{config_dir, grip};

fn sim(vehicle: &Path, out: &Path) -> Output {
    sim_of("mtte", vehicle, out)
}

/// `grip sim` of one seed of `variants` with `vehicle`, written to `out`.
fn sim_of(variants: &str, vehicle: &Path, out: &Path) -> Output {
    grip()
        .args(["sim", "--seeds", "1", "--variants", variants, "--vehicle"])
        .arg(vehicle)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// `grip sim --sweep` of one seed of `variants` on the shipped
/// configuration, one `--sweep` per axis.
fn sweep(variants: &str, axes: &[&str]) -> Output {
    let mut c = grip();
    c.args(["sim", "--seeds", "1", "--variants", variants]);
    for axis in axes {
        c.args(["--sweep", axis]);
    }
    c.output().unwrap()
}

/// `config/vehicle.toml` with each `(from, to)` replaced, as `dir/name`
/// (a user's own car); every `from` must be in the file.
fn vehicle_with(dir: &Path, name: &str, changes: &[(&str, &str)]) -> PathBuf {
    file_with("vehicle.toml", dir, name, changes)
}

/// The shipped vehicle file `base` (relative to `config/`) with each
/// `(from, to)` replaced, as `dir/name`; every `from` must be in the file.
fn file_with(base: &str, dir: &Path, name: &str, changes: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(config_dir().join(base)).unwrap();
    for (from, to) in changes {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
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
    let mm = vehicle_with(tmp.path(), "mm.toml", &[("r = 0.28 ", "r = 334.0 ")]);
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
    let analyze = |vehicle: &Path| {
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

    let light = vehicle_with(
        tmp.path(),
        "light-car.toml",
        &[
            ("mass = 1400.0 ", "mass = 800.0 "),
            ("j_w = 0.6 ", "j_w = 0.4 "),
            ("r = 0.28 ", "r = 0.25 "),
        ],
    );
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

    let sim = |vehicle: &Path, out: &str| sim_of("mfc", vehicle, &tmp.path().join(out));
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
    let o = sweep("mfc,mfc-arte", &["mfc.k_mfc=177,400"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warned: Vec<&str> = err.lines().filter(|l| l.contains("bound (4)")).collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].starts_with("warning: --sweep mfc.k_mfc = 400: ") && warned[0].contains("stone"),
        "{err}"
    );
}

/// Lines of `err` that are warnings about SRC's gains.
fn src_gain_warnings(err: &str) -> Vec<&str> {
    err.lines()
        .filter(|l| l.starts_with("warning: ") && l.contains("[src]"))
        .collect()
}

/// SRC's gains are derived from the vehicle (kp = J_w/(2 tau_m), ti =
/// 4 tau_m, kp_recover between J_w/(2 tau_m) and (J_w + (M/n) r^2)/(2
/// tau_m)): `grip sim` with an SRC variant says which do not suit the
/// user's car, in one line naming both files and the values derived for
/// it; the three shipped cars, and a run without SRC, get no such
/// warning; a sweep says it for each point whose answer differs from the
/// configuration's, a swept vehicle key or `[src]` key alike.
#[test]
fn sim_says_when_the_src_gains_do_not_suit_the_vehicle() {
    let tmp = tempfile::tempdir().unwrap();
    // twice the paper's wheel, a motor 2.5 times quicker
    let car = vehicle_with(
        tmp.path(),
        "quick-motor.toml",
        &[
            ("j_w = 0.6 ", "j_w = 1.2 "),
            ("tau_m = 0.05 ", "tau_m = 0.02 "),
        ],
    );
    let o = sim_of("src", &car, &tmp.path().join("a"));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warned = src_gain_warnings(&err);
    assert_eq!(warned.len(), 1, "{err}");
    for says in [
        "controllers.toml: [src] kp = 6 N m s is 0.2x the symmetric optimum J_w/(2 tau_m) = 30 N m s",
        "[src] ti = 0.2 s is 2.5x the symmetric optimum's 4 tau_m = 0.08 s",
        "[src] kp_recover = 20 N m s is below J_w/(2 tau_m) = 30 N m s",
        "quick-motor.toml (J_w = 1.2 kg m^2, tau_m = 0.02 s, M/n = 350 kg, r = 0.28 m)",
        "set kp = 30 N m s, ti = 0.08 s, kp_recover within [30, 716] N m s",
    ] {
        assert!(warned[0].contains(says), "{says}: {err}");
    }
    // `grip analyze` shows the derivation for the car, row by row
    let o = grip()
        .args(["analyze", "--vehicle"])
        .arg(&car)
        .output()
        .unwrap();
    let out = stdout(&o);
    assert!(o.status.success(), "{}", stderr(&o));
    let row = |key: &str| {
        out.lines()
            .find(|l| l.trim_start().starts_with(&format!("{key} ")))
            .unwrap_or_else(|| panic!("{key}: {out}"))
            .to_owned()
    };
    assert!(row("kp").contains("J_w/(2 tau_m) = 30 N m s"), "{out}");
    assert!(row("ti").contains("4 tau_m = 0.08 s"), "{out}");
    assert!(row("kp_recover").contains("= [30, 716] N m s"), "{out}");
    for key in ["kp", "ti", "kp_recover"] {
        assert!(row(key).trim_end().ends_with("NO"), "{out}");
    }
    assert!(
        out.contains("  warning: ") && out.contains("[src] kp = 6 N m s"),
        "{out}"
    );
    // MTTE's gain is computed from the vehicle itself: nothing to say
    let o = sim_of("mtte", &car, &tmp.path().join("b"));
    assert!(src_gain_warnings(&stderr(&o)).is_empty(), "{}", stderr(&o));
    for f in [
        "vehicle.toml",
        "vehicles/front-mic.toml",
        "vehicles/rear-mic.toml",
    ] {
        let o = sim_of("src,src-arte", &config_dir().join(f), &tmp.path().join("c"));
        let err = stderr(&o);
        assert!(o.status.success(), "{f}: {err}");
        assert!(!err.contains("[src]"), "{f}: {err}");
    }
    // a sweep on the shipped car: the points whose gains do not suit
    // their vehicle, each once (tau_m 0.02 s: kp 15 N m s, ti 0.08 s)
    let o = sweep("src,src-arte", &["vehicle.tau_m=0.05,0.02", "src.kp=6,15"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warned = src_gain_warnings(&err);
    assert_eq!(warned.len(), 3, "{err}");
    for (line, starts) in warned.iter().zip([
        "warning: --sweep vehicle.tau_m = 0.05, src.kp = 15: [src] kp = 15 N m s is 2.5x",
        "warning: --sweep vehicle.tau_m = 0.02, src.kp = 6: [src] kp = 6 N m s is 0.4x",
        "warning: --sweep vehicle.tau_m = 0.02, src.kp = 15: [src] ti = 0.2 s is 2.5x",
    ]) {
        assert!(line.starts_with(starts), "{starts}: {err}");
    }
    assert!(
        warned[1].contains("set kp = 15 N m s, ti = 0.08 s for it"),
        "{err}"
    );
}

/// Lines of `err` that are warnings about the sensors' slip noise.
fn sensor_warnings(err: &str) -> Vec<&str> {
    err.lines()
        .filter(|l| l.starts_with("warning: ") && l.contains("[sensors] give a measured slip"))
        .collect()
}

/// Mean `mean_accel` of `variant` in `out/summary.csv`.
fn mean_accel(out: &Path, variant: &str) -> f64 {
    let text = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (v, a) = (col("variant"), col("mean_accel"));
    let xs: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[v] == variant)
        .map(|f| f[a].parse().unwrap())
        .collect();
    assert!(!xs.is_empty(), "{variant}: {text}");
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// The road belief's slip noise is the shipped sensors': a user's car with
/// a coarser wheel speed (the front-mic car with a 4096-count encoder over
/// one 1 ms sample, 4 times the noise) gets one warning from `grip sim` when an ARTE variant
/// runs, naming the vehicle file, the sensor fields and the omega_window
/// that brings the noise within; with that window there is no warning and
/// MTTE-ARTE keeps its baseline's traction (with the coarse encoder the
/// belief settles on ice and it does not: the hazard the warning names).
/// No warning without an ARTE variant, none for the shipped cars.
#[test]
fn sim_says_when_the_sensors_are_noisier_than_the_road_belief_assumes() {
    let tmp = tempfile::tempdir().unwrap();
    let coarse = file_with(
        "vehicles/front-mic.toml",
        tmp.path(),
        "coarse.toml",
        &[("encoder_ppr = 65536", "encoder_ppr = 4096")],
    );
    let o = sim_of("mtte,mtte-arte", &coarse, &tmp.path().join("a"));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let warned = sensor_warnings(&err);
    assert_eq!(warned.len(), 1, "{err}");
    for says in [
        "coarse.toml: [sensors] give a measured slip whose noise at 10 km/h",
        "encoder_ppr 4096 over omega_window 1",
        "controllers.toml's fusion.sigma_lambda",
        "set sensors.omega_window = ",
    ] {
        assert!(warned[0].contains(says), "{says}: {err}");
    }
    let ice =
        mean_accel(&tmp.path().join("a"), "mtte-arte") / mean_accel(&tmp.path().join("a"), "mtte");
    assert!(
        ice < 0.5,
        "the coarse encoder's ice trap: MTTE-ARTE at {ice}x MTTE"
    );
    let w: u32 = warned[0]
        .split("set sensors.omega_window = ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap();
    let fixed = file_with(
        "vehicles/front-mic.toml",
        tmp.path(),
        "fixed.toml",
        &[
            ("encoder_ppr = 65536", "encoder_ppr = 4096"),
            ("omega_window = 1", &format!("omega_window = {w}")),
        ],
    );
    let o = sim_of("mtte,mtte-arte", &fixed, &tmp.path().join("b"));
    assert!(sensor_warnings(&stderr(&o)).is_empty(), "{}", stderr(&o));
    let kept =
        mean_accel(&tmp.path().join("b"), "mtte-arte") / mean_accel(&tmp.path().join("b"), "mtte");
    assert!(kept > 0.98, "omega_window {w}: MTTE-ARTE at {kept}x MTTE");
    // no ARTE variant, no road belief: nothing to say
    let o = sim_of("mtte,src", &coarse, &tmp.path().join("c"));
    assert!(sensor_warnings(&stderr(&o)).is_empty(), "{}", stderr(&o));
    for f in [
        "vehicle.toml",
        "vehicles/front-mic.toml",
        "vehicles/rear-mic.toml",
    ] {
        let o = sim_of("mtte-arte", &config_dir().join(f), &tmp.path().join("d"));
        assert!(
            sensor_warnings(&stderr(&o)).is_empty(),
            "{f}: {}",
            stderr(&o)
        );
    }
}
