//! `grip replay` says, as tcs-loop says at its start in a drive and `grip
//! sim` for the controllers it runs, when the gains of the controller the
//! replay's loop runs do not suit the vehicle it runs
//! (`grip_tcs::analysis::vehicle_tf::gain_warning`: SRC's kp, ti and
//! kp_recover against their derivation from J_w and tau_m, MFC's k_mfc
//! against bound (4); nothing for MTTE), once, in open and closed loop,
//! naming the files as the log's configuration names them (never the
//! replay's temporary copy) and the `--set`s on them. Until then a replay
//! whose what-if made such a loop said nothing.

mod common;

use common::replay_reference as replay;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

/// Lines of `err` that are warnings about the gains of `section` (`[src]`,
/// `[mfc]`).
fn gain_warnings<'a>(err: &'a str, section: &str) -> Vec<&'a str> {
    err.lines()
        .filter(|l| l.starts_with("warning: ") && l.contains(section))
        .collect()
}

/// No line of `err` names the replay's temporary copy of the configuration.
fn no_temporary_copy(err: &str) {
    assert!(!common::names_a_temporary_copy(err), "{err}");
}

/// twice the paper's wheel, a motor 2.5 times quicker (as
/// `vehicle_file.rs`'s `sim_says_when_the_src_gains_do_not_suit_the_vehicle`)
const QUICK_MOTOR: [&str; 4] = ["--set", "vehicle.j_w=1.2", "--set", "vehicle.tau_m=0.02"];

#[test]
fn replay_says_when_the_src_gains_do_not_suit_the_vehicle() {
    for closed in [false, true] {
        let mut args: Vec<&std::ffi::OsStr> = vec![os("--controller"), os("src")];
        args.extend(QUICK_MOTOR.map(os));
        if closed {
            args.push(os("--closed-loop"));
        }
        let (ok, out, err) = replay(&args);
        assert!(ok, "closed {closed}: {out}{err}");
        let warned = gain_warnings(&err, "[src]");
        assert_eq!(warned.len(), 1, "closed {closed}: {err}");
        for says in [
            "warning: controllers.toml: [src] kp = 6 N m s is 0.2x the symmetric optimum J_w/(2 tau_m) = 30 N m s",
            "[src] ti = 0.2 s is 2.5x the symmetric optimum's 4 tau_m = 0.08 s",
            "[src] kp_recover = 20 N m s is below J_w/(2 tau_m) = 30 N m s",
            "for the vehicle of vehicle.toml (J_w = 1.2 kg m^2, tau_m = 0.02 s, M/n = 350 kg, r = 0.28 m)",
            "set kp = 30 N m s, ti = 0.08 s, kp_recover within [30, 716] N m s",
            "(the replay's, with --set vehicle.j_w=1.2, --set vehicle.tau_m=0.02)",
        ] {
            assert!(warned[0].contains(says), "{says}: {err}");
        }
        no_temporary_copy(&err);
    }
    // a vehicle file given with --vehicle is named as given
    let tmp = tempfile::tempdir().unwrap();
    let car = tmp.path().join("quick-motor.toml");
    let text = std::fs::read_to_string(root().join("config/vehicle.toml")).unwrap();
    let quick =
        text.replacen("j_w = 0.6 ", "j_w = 1.2 ", 1)
            .replacen("tau_m = 0.05 ", "tau_m = 0.02 ", 1);
    assert_ne!(quick, text);
    std::fs::write(&car, quick).unwrap();
    let (ok, out, err) = replay(&[
        os("--controller"),
        os("src"),
        os("--vehicle"),
        car.as_os_str(),
    ]);
    assert!(ok, "{out}{err}");
    let warned = gain_warnings(&err, "[src]");
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].contains(&format!(
            "for the vehicle of {} (J_w = 1.2 kg m^2",
            car.display()
        )),
        "{err}"
    );
    // the drive's own SRC on its own car, and MTTE on the quick car: the
    // gains suit, or MTTE's gain is computed from the vehicle itself
    let (ok, out, err) = replay(&[os("--controller"), os("src")]);
    assert!(ok, "{out}{err}");
    assert!(gain_warnings(&err, "[src]").is_empty(), "{err}");
    let mut args: Vec<&std::ffi::OsStr> = vec![os("--controller"), os("mtte")];
    args.extend(QUICK_MOTOR.map(os));
    let (ok, out, err) = replay(&args);
    assert!(ok, "{out}{err}");
    assert!(!err.contains("warning: controllers.toml"), "{err}");
}

/// MFC's gain above bound (4), as tcs-loop warns at its start.
#[test]
fn replay_says_when_the_mfc_gain_is_above_bound_4() {
    let (ok, out, err) = replay(&[
        os("--controller"),
        os("mfc"),
        os("--set"),
        os("mfc.k_mfc=400"),
    ]);
    assert!(ok, "{out}{err}");
    let warned = gain_warnings(&err, "[mfc]");
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].starts_with("warning: controllers.toml: [mfc] k_mfc = 400 N m s/rad is above the MFC's no-overshoot bound (4) for the vehicle of vehicle.toml")
            && warned[0].ends_with("(the replay's, with --set mfc.k_mfc=400)"),
        "{err}"
    );
    no_temporary_copy(&err);
}

/// The road belief's slip noise, as tcs-loop warns at its start for the
/// ARTE variants: a coarser encoder (4096 counts over one 1 ms sample, a
/// closed-loop what-if: open loop replays the logged readings) is said
/// once, naming the vehicle file, the fields and the --set; nothing with
/// ARTE off (no belief).
#[test]
fn replay_says_when_the_sensors_are_noisier_than_the_road_belief_assumes() {
    let coarse = ["--closed-loop", "--set", "sensors.encoder_ppr=4096"];
    let (ok, out, err) = replay(&coarse);
    assert!(ok, "{out}{err}");
    let warned: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("warning: ") && l.contains("[sensors] give a measured slip"))
        .collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].starts_with("warning: vehicle.toml: [sensors] give a measured slip")
            && warned[0].contains("encoder_ppr 4096 over omega_window 1")
            && warned[0].ends_with("(the replay's, with --set sensors.encoder_ppr=4096)"),
        "{err}"
    );
    no_temporary_copy(&err);
    let (ok, out, err) = replay(&[&coarse[..], &["--arte", "off"]].concat());
    assert!(ok, "{out}{err}");
    assert!(!err.contains("[sensors] give a measured slip"), "{err}");
}

/// The `--set`s named after a warning are those on the files its checks
/// read: roads.toml for MFC's bound (per road), not for SRC's gains.
#[test]
fn the_sets_named_are_those_the_check_reads() {
    let snow = ["--set", "roads.toml:road[snow].c1=0.2"];
    let (ok, out, err) = replay(&[&["--controller", "src"][..], &QUICK_MOTOR, &snow].concat());
    assert!(ok, "{out}{err}");
    let warned = gain_warnings(&err, "[src]");
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].ends_with("(the replay's, with --set vehicle.j_w=1.2, --set vehicle.tau_m=0.02)"),
        "{err}"
    );
    let (ok, out, err) = replay(
        &[
            &["--controller", "mfc", "--set", "mfc.k_mfc=400"][..],
            &snow,
        ]
        .concat(),
    );
    assert!(ok, "{out}{err}");
    let warned = gain_warnings(&err, "[mfc]");
    assert_eq!(warned.len(), 1, "{err}");
    assert!(
        warned[0].ends_with(
            "(the replay's, with --set mfc.k_mfc=400, --set roads.toml:road[snow].c1=0.2)"
        ),
        "{err}"
    );
}
