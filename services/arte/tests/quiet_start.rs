//! A start on a machine without an iceoryx2 configuration file (grip ships
//! none: iceoryx2's defaults are grip's) writes no warning about it: arte
//! used to print iceoryx2's two-line "[W] Config::global_config() | No
//! config file was loaded, a config with default values will be used" into
//! the journal at every start of every service (`grip_io::ipc`, the lookup
//! every service's node makes). A configuration file iceoryx2 cannot read
//! (it skips it) is still a warning naming it; one it reads is none, even
//! when its values are the defaults.

use grip_testkit::svc::{Service, copy_config, strip_rt};
use std::path::Path;
use std::process::Command;

/// arte's stderr for a 1 s run with the working directory `cwd` (where
/// iceoryx2 looks first, `config/iceoryx2.toml`).
fn stderr_in(cwd: &Path, tag: &str) -> String {
    let t = copy_config(&["arte-svc.toml", "roads.toml", "roads", "models"]);
    strip_rt(&t.path().join("arte-svc.toml"));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_arte"));
    cmd.current_dir(cwd)
        .arg("--config-dir")
        .arg(t.path())
        .args(["--run-for", "1"])
        .env(
            "GRIP_INSTANCE",
            format!("quiet_start_{tag}_{}", std::process::id()),
        )
        .env_remove("IOX2_LOG_LEVEL")
        .env_remove("INVOCATION_ID")
        .env_remove("NOTIFY_SOCKET");
    let mut svc = Service::spawn(cmd);
    let (exit, stderr) = svc.wait();
    assert!(exit.success(), "{exit:?}: {stderr}");
    assert!(stderr.contains("arte starting"), "{stderr}");
    // iceoryx2's own warnings about its configuration lookup (it prints
    // `N [W] "Config::global_config()"` then the text)
    assert!(
        !stderr.contains("No config file") && !stderr.contains("Config::global_config()"),
        "iceoryx2 warned of its configuration at start-up:\n{stderr}"
    );
    stderr
}

#[test]
fn no_iceoryx2_config_file_is_no_warning() {
    let cwd = tempfile::tempdir().unwrap();
    let err = stderr_in(cwd.path(), "none");
    assert!(!err.contains("iceoryx2 configuration file"), "{err}");
}

#[test]
fn an_unreadable_iceoryx2_config_file_is_named_and_a_readable_one_is_not() {
    let cwd = tempfile::tempdir().unwrap();
    std::fs::create_dir(cwd.path().join("config")).unwrap();
    let f = cwd.path().join("config/iceoryx2.toml");
    std::fs::write(&f, "this is = = not toml\n").unwrap();
    let err = stderr_in(cwd.path(), "bad");
    assert!(
        err.contains("an iceoryx2 configuration file that cannot be read")
            && err.contains("file=config/iceoryx2.toml")
            && err.contains("UnableToDeserializeContents"),
        "{err}"
    );
    // an empty file reads (every value iceoryx2's default): no warning
    std::fs::write(&f, "").unwrap();
    let err = stderr_in(cwd.path(), "empty");
    assert!(!err.contains("iceoryx2 configuration file"), "{err}");
}
