//! A start on a machine without an iceoryx2 configuration file (grip ships
//! none: iceoryx2's defaults are grip's) writes no warning about it: arte
//! used to print iceoryx2's two-line "[W] Config::global_config() | No
//! config file was loaded, a config with default values will be used" into
//! the journal at every start of every service (`grip_io::ipc`, the lookup
//! every service's node makes).

use grip_testkit::svc::{Service, copy_config, strip_rt};
use std::process::Command;

#[test]
fn no_iceoryx2_config_file_is_no_warning() {
    let t = copy_config(&["arte-svc.toml", "roads.toml", "roads", "models"]);
    strip_rt(&t.path().join("arte-svc.toml"));
    // the working directory holds no config/iceoryx2.toml (iceoryx2's first
    // place to look)
    let cwd = tempfile::tempdir().unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_arte"));
    cmd.current_dir(cwd.path())
        .arg("--config-dir")
        .arg(t.path())
        .args(["--run-for", "1"])
        .env(
            "GRIP_INSTANCE",
            format!("quiet_start_{}", std::process::id()),
        )
        .env_remove("IOX2_LOG_LEVEL")
        .env_remove("INVOCATION_ID")
        .env_remove("NOTIFY_SOCKET");
    let mut svc = Service::spawn(cmd);
    let (exit, stderr) = svc.wait();
    assert!(exit.success(), "{exit:?}: {stderr}");
    assert!(stderr.contains("arte starting"), "{stderr}");
    assert!(
        !stderr.contains("No config file") && !stderr.contains("[W]"),
        "iceoryx2 warned at start-up:\n{stderr}"
    );
}
