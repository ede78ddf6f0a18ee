//! The recorder under systemd's protocol: `READY=1` once recording, then
//! `WATCHDOG=1` at half the watchdog period even when nothing is published
//! (its writer loop waits for messages at most that long), `STOPPING=1` on
//! SIGTERM and exit 0.

use std::process::Command;
use std::time::Duration;

use grip_testkit::svc::{NotifySocket, Service, shipped_config_dir};

#[test]
fn ready_watchdog_at_half_a_short_period_and_clean_stop() {
    let dir = tempfile::tempdir().unwrap();
    let sock = NotifySocket::bind(dir.path());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_recorder"));
    cmd.arg("--config-dir")
        .arg(shipped_config_dir())
        .arg("--out")
        .arg(dir.path().join("idle.mcap"))
        .env("NOTIFY_SOCKET", sock.path())
        // 60 ms: a ping every 30 ms is due; a writer loop that waited
        // 100 ms for messages could send at most about 20 in 2 s
        .env("WATCHDOG_USEC", "60000")
        .env(
            "GRIP_INSTANCE",
            format!("rec-notify-{}", std::process::id()),
        );
    let mut child = Service::spawn(cmd);
    assert!(
        sock.wait_for("READY=1", Duration::from_secs(20)),
        "no READY=1 within 20 s"
    );
    // about 66 expected; a loaded machine may delay some
    let pings = sock.count("WATCHDOG=1", Duration::from_secs(2));
    assert!(pings >= 25, "{pings} WATCHDOG=1 in 2 s at a 60 ms watchdog");
    child.signal(15);
    assert!(
        sock.wait_for("STOPPING=1", Duration::from_secs(10)),
        "no STOPPING=1 after SIGTERM"
    );
    let (status, err) = child.wait();
    assert_eq!(status.code(), Some(0), "{err}");
}
