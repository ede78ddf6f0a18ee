//! The `plant-sim` binary: bad configuration → one `error:` line (file,
//! field, reason), exit 1; `READY=1` on `NOTIFY_SOCKET`; `--exit-at-end`
//! exits 0 at the scenario's end; SIGTERM exits 0.

use std::io::Read;
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_plant-sim");

fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

fn copy_config() -> tempfile::TempDir {
    let t = tempfile::tempdir().unwrap();
    for f in ["vehicle.toml", "can.toml", "roads.toml"] {
        std::fs::copy(config_dir().join(f), t.path().join(f)).unwrap();
    }
    std::fs::create_dir(t.path().join("scenarios")).unwrap();
    std::fs::create_dir(t.path().join("roads")).unwrap();
    std::fs::copy(
        config_dir().join("scenarios/paper.toml"),
        t.path().join("scenarios/paper.toml"),
    )
    .unwrap();
    for e in std::fs::read_dir(config_dir().join("roads")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), t.path().join("roads").join(e.file_name())).unwrap();
    }
    // the shipped file without the real-time set-up
    let text = std::fs::read_to_string(config_dir().join("plant-sim.toml")).unwrap();
    let cut = text.find("[rt]").unwrap();
    std::fs::write(t.path().join("plant-sim.toml"), &text[..cut]).unwrap();
    t
}

fn run(args: &[&str]) -> (i32, String) {
    let out = Command::new(BIN)
        .args(args)
        .env("GRIP_INSTANCE", format!("ps-cli-{}", std::process::id()))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_config_names_file_field_reason() {
    let t = copy_config();
    let dir = t.path().to_str().unwrap();
    let p = t.path().join("plant-sim.toml");
    let text = std::fs::read_to_string(&p).unwrap();
    std::fs::write(
        &p,
        text.replace("cmd_timeout_ms = 20.0", "cmd_timeout_ms = 0.0"),
    )
    .unwrap();
    let (code, err) = run(&["--config-dir", dir]);
    assert_eq!(code, 1, "{err}");
    let line = err.lines().find(|l| l.starts_with("error: ")).expect(&err);
    assert!(
        line.contains("plant-sim.toml: field `cmd_timeout_ms`"),
        "{line}"
    );
    assert!(line.contains("got 0"), "{line}");
    assert!(!err.contains("panicked"), "{err}");
    std::fs::write(&p, &text).unwrap();

    let (code, err) = run(&["--config-dir", dir, "--scenario", "nowhere"]);
    assert_eq!(code, 1);
    assert!(err.contains("scenarios/nowhere.toml: cannot read"), "{err}");

    let sc = t.path().join("scenarios/bad.toml");
    let paper = std::fs::read_to_string(t.path().join("scenarios/paper.toml")).unwrap();
    std::fs::write(&sc, paper.replace("road = \"gravel\"", "road = \"lava\"")).unwrap();
    let (code, err) = run(&["--config-dir", dir, "--scenario", sc.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("bad.toml: field `segment[2].road`"), "{err}");
    assert!(err.contains("unknown road `lava`"), "{err}");

    let (code, _) = run(&["--start-on", "whenever"]);
    assert_eq!(code, 2);
}

fn wait_ready(sock: &UnixDatagram) -> bool {
    let t0 = Instant::now();
    let mut buf = [0u8; 512];
    while t0.elapsed() < Duration::from_secs(20) {
        if let Ok(n) = sock.recv(&mut buf)
            && String::from_utf8_lossy(&buf[..n])
                .lines()
                .any(|l| l == "READY=1")
        {
            return true;
        }
    }
    false
}

/// Kills the child if the test fails before it ends.
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

#[test]
fn ready_then_exit_at_end_and_sigterm() {
    let t = copy_config();
    let dir = t.path().to_str().unwrap();
    let sock_path = t.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();

    // immediate start, exits by itself after 2.4 s + 0.1 s
    let t0 = Instant::now();
    let child = Command::new(BIN)
        .args([
            "--config-dir",
            dir,
            "--start-on",
            "immediate",
            "--exit-at-end",
        ])
        .env("NOTIFY_SOCKET", &sock_path)
        .env("GRIP_INSTANCE", format!("ps-ready-{}", std::process::id()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = KillOnDrop(child);
    assert!(wait_ready(&sock), "no READY=1");
    let status = child.0.wait().unwrap();
    let mut err = String::new();
    child
        .0
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.contains("finished=true"), "{err}");
    assert!(t0.elapsed() >= Duration::from_millis(2500), "real time");

    // signal start: without SIGUSR1 (and commands) it holds; SIGTERM → 0
    let child = Command::new(BIN)
        .args(["--config-dir", dir, "--exit-at-end"])
        .env("NOTIFY_SOCKET", &sock_path)
        .env("GRIP_INSTANCE", format!("ps-ready2-{}", std::process::id()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = KillOnDrop(child);
    assert!(wait_ready(&sock), "no READY=1");
    std::thread::sleep(Duration::from_millis(300));
    // SAFETY: kill(2) on our child.
    unsafe { libc_kill(child.0.id() as i32, 10) }; // SIGUSR1: no commands, so it keeps holding
    std::thread::sleep(Duration::from_millis(300));
    // SAFETY: kill(2) on our child.
    unsafe { libc_kill(child.0.id() as i32, 15) };
    let status = child.0.wait().unwrap();
    let mut err = String::new();
    child
        .0
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.contains("finished=false"), "{err}");
    assert!(err.contains("scenario_time_s=0"), "held: {err}");
}
