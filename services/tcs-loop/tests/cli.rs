//! The `tcs-loop` binary: a bad configuration gives one `error:` line naming
//! file, field and reason and exit code 1; a good one sends `READY=1` to
//! `NOTIFY_SOCKET` and exits 0 on SIGTERM.

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_tcs-loop");

fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// A copy of the shipped config directory's TOML files in a temp dir.
fn copy_config() -> tempfile::TempDir {
    let t = tempfile::tempdir().unwrap();
    for f in [
        "controllers.toml",
        "vehicle.toml",
        "can.toml",
        "tcs-loop.toml",
    ] {
        std::fs::copy(config_dir().join(f), t.path().join(f)).unwrap();
    }
    t
}

fn run(args: &[&str]) -> (i32, String) {
    let out = Command::new(BIN)
        .args(args)
        .env("GRIP_INSTANCE", format!("tcs-cli-{}", std::process::id()))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_own_config_names_file_field_reason() {
    let t = copy_config();
    let p = t.path().join("tcs-loop.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    std::fs::write(
        &p,
        text.replace("controller = \"mtte\"", "controller = \"pid\""),
    )
    .unwrap();
    let (code, err) = run(&["--config-dir", t.path().to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    let line = err.lines().find(|l| l.starts_with("error: ")).expect(&err);
    assert!(line.contains("tcs-loop.toml"), "{line}");
    assert!(line.contains("field `controller`"), "{line}");
    assert!(line.contains("unknown controller `pid`"), "{line}");
    assert!(!err.contains("panicked"), "{err}");

    std::fs::write(&p, text.replace("recover_ms = 50.0", "recover_ms = -5.0")).unwrap();
    let (code, err) = run(&["--config-dir", t.path().to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("field `safety.recover_ms`"), "{err}");

    std::fs::write(&p, text.replace("[safety]", "[safety]\nsensor_timeout = 3")).unwrap();
    let (code, err) = run(&["--config-dir", t.path().to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("unknown field `sensor_timeout`"), "{err}");
    assert!(err.contains("line "), "{err}");
}

#[test]
fn bad_shared_config_names_file_field_reason() {
    let t = copy_config();
    let p = t.path().join("controllers.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, text.replace("tau_hpf = 1.0", "tau_hpf = -1.0")).unwrap();
    let (code, err) = run(&["--config-dir", t.path().to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("controllers.toml: field `mfc.tau_hpf`"),
        "{err}"
    );

    let (code, err) = run(&["--config-dir", "/nonexistent/grip"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("/nonexistent/grip/tcs-loop.toml: cannot read"),
        "{err}"
    );
}

#[test]
fn bad_flag_is_a_usage_error() {
    let (code, err) = run(&["--controller", "pid"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("pid"), "{err}");
    let (code, _) = run(&["--arte", "maybe"]);
    assert_eq!(code, 2);
}

#[test]
fn ready_then_clean_exit_on_sigterm() {
    let t = copy_config();
    // no real-time set-up in tests
    let p = t.path().join("tcs-loop.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    let cut = text.find("[rt]").unwrap();
    std::fs::write(&p, &text[..cut]).unwrap();
    let sock_path = t.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let child = Command::new(BIN)
        .args(["--config-dir", t.path().to_str().unwrap(), "--arte", "off"])
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "200000")
        .env("GRIP_INSTANCE", format!("tcs-ready-{}", std::process::id()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = KillOnDrop(child);
    let t0 = Instant::now();
    let mut ready = false;
    let mut buf = [0u8; 512];
    while t0.elapsed() < Duration::from_secs(20) && !ready {
        if let Ok(n) = sock.recv(&mut buf) {
            ready = String::from_utf8_lossy(&buf[..n])
                .lines()
                .any(|l| l == "READY=1");
        }
    }
    assert!(ready, "no READY=1 within 20 s");
    // the helper feeds the watchdog at half WATCHDOG_USEC while the loop runs
    let t1 = Instant::now();
    let mut pings = 0;
    // 2 s (about 10 pings expected): a loaded machine may delay a few
    while t1.elapsed() < Duration::from_secs(2) {
        if let Ok(n) = sock.recv(&mut buf)
            && String::from_utf8_lossy(&buf[..n])
                .lines()
                .any(|l| l == "WATCHDOG=1")
        {
            pings += 1;
        }
    }
    assert!(pings >= 3, "{pings} WATCHDOG=1 in 2 s at a 0.2 s watchdog");
    // SAFETY: plain kill(2) on our child's pid.
    unsafe { libc_kill(child.0.id() as i32, 15) };
    let status = child.0.wait().unwrap();
    let mut err = String::new();
    use std::io::Read;
    child
        .0
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.contains("tcs-loop stopped"), "{err}");
    // no sensor frames: it stayed in its safe state
    assert!(err.contains("safe_entries=0"), "{err}");
}

/// Kills the child if the test fails before it stops it.
struct KillOnDrop(std::process::Child);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

unsafe extern "C" {
    #[link_name = "kill"]
    fn libc_kill(pid: i32, sig: i32) -> i32;
}
