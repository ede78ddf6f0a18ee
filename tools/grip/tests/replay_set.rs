//! `grip replay --set` end to end on `tests/data/reference-drive.mcap`,
//! with the log's own configuration (its attachments, which the replay
//! writes to a temporary copy): a value a service refuses is told as the
//! `--set` typed, with the file as the log names it, never the temporary
//! copy; a key outside any table (`FILE:KEY=VALUE`) is set with its TOML
//! type, and tcs-loop.toml's `controller` is the replay's controller.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `grip replay` of the reference drive with `extra`: success, stdout, stderr.
fn replay(extra: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_grip"))
        .arg("replay")
        .arg(root().join("tests/data/reference-drive.mcap"))
        .args(extra)
        .output()
        .expect("running grip replay");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

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
        let tmp = std::env::temp_dir().display().to_string();
        assert!(!line.contains(&tmp) && !line.contains(".tmp"), "{line}");
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
