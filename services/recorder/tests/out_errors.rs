//! Where the log cannot go: an `out_dir` that cannot be created (a path
//! under a regular file) is an error naming the configuration file, the
//! field `out_dir`, the directory and the OS's reason; a `--out` file that
//! cannot be created names the option, the file and the reason. Both exit
//! 1, as before (left to the unit's `Restart=`, e.g. a file system mounted
//! late: not a refused configuration). Until 2026-12-07 the `out_dir`
//! error named the directory only, not `recorder.toml` nor its field.

use std::path::Path;
use std::process::{Command, Output};

use grip_testkit::svc::shipped_config_dir;

/// The recorder binary with `args`, in an isolated iceoryx2 namespace,
/// until it exits (it fails before it opens any port).
fn recorder(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_recorder"))
        .arg("--config-dir")
        .arg(shipped_config_dir())
        .args(args)
        .env(
            grip_io::ipc::INSTANCE_ENV,
            format!("recouterr{}", std::process::id()),
        )
        .env_remove("NOTIFY_SOCKET")
        .env_remove("INVOCATION_ID")
        .output()
        .unwrap()
}

/// The `error` lines of `out`'s standard error.
fn errors(out: &Output) -> Vec<String> {
    String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.starts_with("error"))
        .map(str::to_owned)
        .collect()
}

#[test]
fn an_out_dir_or_out_file_that_cannot_be_created_names_the_field_or_option() {
    let t = tempfile::tempdir().unwrap();
    let file = t.path().join("a-file");
    std::fs::write(&file, b"not a directory").unwrap();
    let logs = file.join("logs");

    // recorder.toml's out_dir under a regular file
    let shipped = std::fs::read_to_string(shipped_config_dir().join("recorder.toml")).unwrap();
    assert!(shipped.contains("\nout_dir = \"/var/log/grip\"\n"));
    let cfg = t.path().join("recorder.toml");
    std::fs::write(
        &cfg,
        shipped.replace(
            "\nout_dir = \"/var/log/grip\"\n",
            &format!("\nout_dir = {:?}\n", logs.display().to_string()),
        ),
    )
    .unwrap();
    let out = recorder(&["--config".as_ref(), cfg.as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let want = format!(
        "error: {}: field `out_dir`: {}: cannot create the log directory or a new log file in it: Not a directory (os error 20)",
        cfg.display(),
        logs.display()
    );
    assert_eq!(errors(&out), [want], "{out:?}");

    // --out under a regular file: the option, not the configuration's field
    let log = file.join("drive.mcap");
    let out = recorder(&["--out".as_ref(), log.as_os_str()]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let want = format!(
        "error: option `--out`: {}: Not a directory (os error 20)",
        log.display()
    );
    assert_eq!(errors(&out), [want], "{out:?}");
    assert!(!Path::new(&log).exists());
}
