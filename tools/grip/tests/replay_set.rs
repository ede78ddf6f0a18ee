//! `grip replay --set` end to end on `tests/data/reference-drive.mcap`,
//! with the log's own configuration (its attachments, which the replay
//! writes to a temporary copy): a value a service refuses is told as the
//! `--set` typed, with the file as the log names it, never the temporary
//! copy; a key outside any table (`FILE:KEY=VALUE`) is set with its TOML
//! type, and tcs-loop.toml's `controller` is the replay's controller.
//! `grip inspect` of a `--out` log whose `--set` changed the gate and the
//! vehicle reports the gate and the vehicle the replay ran.

mod common;

use common::replay_reference as replay;
use std::path::Path;
use std::process::Command;

#[test]
fn a_refused_set_is_named_as_typed_with_the_logs_file() {
    for (spec, field) in [
        ("mfc.k_mfc=-5", "mfc.k_mfc"),
        ("preview.cap_share=7", "preview.cap_share"),
    ] {
        let (ok, _, err) = replay(&["--set", spec]);
        assert!(!ok, "{err}");
        let line = err
            .lines()
            .find(|l| l.starts_with("error: "))
            .unwrap_or_else(|| panic!("no error line:\n{err}"));
        assert!(
            line.starts_with(&format!(
                "error: --set {spec}: controllers.toml: field `{field}`: "
            )),
            "{line}"
        );
        // the replay's temporary copy of the configuration is not named
        assert!(!common::names_a_temporary_copy(line), "{line}");
    }
}

#[test]
fn a_top_level_key_sets_the_controller_and_keeps_its_type() {
    let (ok, out, err) = replay(&["--set", "tcs-loop.toml:controller=src"]);
    assert!(ok, "{out}{err}");
    assert!(
        out.contains(
            "\n  change: tcs-loop.toml: controller mtte -> src (the replay's controller, as --controller src)\n"
        ),
        "{out}"
    );
    assert!(
        out.contains("cycles through TcsLoop::cycle, controller src,"),
        "{out}"
    );
    // the same replay as --controller src: every per-topic line alike
    let (ok, same, err) = replay(&["--controller", "src"]);
    assert!(ok, "{same}{err}");
    let topics = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| l.trim_start().starts_with("grip/"))
            .map(str::to_owned)
            .collect()
    };
    assert!(!topics(&out).is_empty(), "{out}");
    assert_eq!(topics(&out), topics(&same));
    assert!(
        topics(&out)
            .iter()
            .any(|l| l.contains("grip/tcs/cycle") && !l.ends_with("identical")),
        "{out}"
    );

    // a value of another type than the key's is refused, naming both
    let (ok, _, err) = replay(&["--set", "tcs-loop.toml:arte=on"]);
    assert!(!ok);
    assert!(
        err.contains(
            "error: --set tcs-loop.toml:arte=on: tcs-loop.toml's arte: on is a string (a bare word), but the key is a boolean"
        ),
        "{err}"
    );
}

/// A file the replay does not read is refused, saying why (here:
/// audio-acq, whose audio the log holds).
#[test]
fn a_set_the_replay_does_not_read_is_refused() {
    let (ok, out, err) = replay(&["--set", "audio-acq.toml:audio.sample_rate=16000"]);
    assert!(!ok, "{out}");
    assert!(
        err.contains("error: --set audio-acq.toml:audio.sample_rate=16000: the replay does not read [audio] sample_rate of audio-acq.toml")
            && err.contains("audio-acq is not re-run"),
        "{err}"
    );
}

/// `grip inspect` (text and `--json`) of `path`.
fn inspect(path: &Path) -> (String, serde_json::Value) {
    let run = |json: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_grip"));
        c.arg("inspect");
        if json {
            c.arg("--json");
        }
        let out = c.arg(path).output().expect("running grip inspect");
        assert!(out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let j = serde_json::from_str(run(true).lines().next().unwrap()).unwrap();
    (run(false), j)
}

/// A replay's log whose `--set`s changed `[arte] min_confidence` and the
/// vehicle: `grip inspect` reports the gate the replay's tcs-loop ran, not
/// the source's `controllers.toml` copied into the log ("from the log's
/// controllers.toml", 0.6); in open loop the source's vehicle (its ground
/// truth is the source car's) and the one the replay's loop ran beside
/// it; in closed loop the replay's vehicle (plant and loop both ran it).
#[test]
fn inspect_of_a_replay_reports_the_gate_and_vehicle_it_ran() {
    let d = tempfile::tempdir().unwrap();
    let open = d.path().join("open.mcap");
    let (ok, out, err) = replay(&[
        "--set",
        "controllers.toml:arte.min_confidence=0.5",
        "--set",
        "vehicle.toml:vehicle.mass=1800",
        "--out",
        open.to_str().unwrap(),
    ]);
    assert!(ok, "{out}{err}");
    let (text, j) = inspect(&open);
    assert_eq!(j["arte_min_confidence"], 0.5, "{text}");
    assert_eq!(j["arte_min_confidence_from"], "replay");
    assert_eq!(j["replay"]["min_confidence"], 0.5);
    assert!(
        text.contains("(then the first at confidence >= 0.5, the loop's gate, the one the replay's tcs-loop ran (its grip.replay record; the log's controllers.toml is the source drive's)):"),
        "{text}"
    );
    assert!(!text.contains("from the log's controllers.toml"), "{text}");
    assert_eq!(j["vehicle"], "vehicle.toml (attached to the log)");
    assert_eq!(j["replay"]["vehicle"], "vehicle.toml");
    assert_eq!(
        j["replay"]["vehicle_set"],
        "--set vehicle.toml:vehicle.mass=1800"
    );
    let heavy = j["replay"]["vehicle_sha256"].as_str().unwrap().to_owned();
    assert_ne!(j["vehicle_sha256"].as_str(), Some(heavy.as_str()));
    assert!(
        text.contains(&format!(
            "\n  the replay's tcs-loop ran vehicle vehicle.toml with --set vehicle.toml:vehicle.mass=1800 (sha256 {}, attached to the log as replay/vehicle.toml), not vehicle.toml (attached to the log): in open loop",
            &heavy[..12]
        )),
        "{text}"
    );

    // closed loop: the replay's vehicle is the summary's
    let closed = d.path().join("closed.mcap");
    let (ok, out, err) = replay(&[
        "--closed-loop",
        "--set",
        "vehicle.toml:vehicle.mass=1800",
        "--out",
        closed.to_str().unwrap(),
    ]);
    assert!(ok, "{out}{err}");
    let (text, j) = inspect(&closed);
    assert_eq!(
        j["vehicle"],
        "vehicle.toml (the vehicle the replay ran with --set vehicle.toml:vehicle.mass=1800, not its source drive's; attached to the log as replay/vehicle.toml)",
        "{text}"
    );
    assert_eq!(j["vehicle_sha256"], heavy.as_str());
    assert_eq!(
        j["arte_min_confidence_from"], "log",
        "the source's gate, unchanged"
    );
    assert!(
        text.contains("the loop's gate, from the log's controllers.toml"),
        "{text}"
    );
}
