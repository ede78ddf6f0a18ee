//! Helpers of the end-to-end tests (included with `#[path]`, not a test
//! binary of its own): the service binaries, the configuration directory,
//! and a minimal service manager (own `NOTIFY_SOCKET` per process, stderr
//! capture, SIGTERM/SIGKILL).
//!
//! Binaries: `$GRIP_BIN_DIR` if set; otherwise the test runs
//! `cargo build -p grip -p grip-recorder -p grip-plant-sim -p grip-tcs-loop
//! -p grip-audio-acq -p grip-arte-svc` once per test process, with the
//! profile and target directory the test binary itself was built with, and
//! uses `target/<profile>/` (a no-op when they are up to date).
//! Configuration: the repository's `config/`, or `$GRIP_E2E_CONFIG_DIR`.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixDatagram;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

pub const SERVICES: [&str; 5] = ["recorder", "plant-sim", "audio-acq", "arte", "tcs-loop"];

pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

pub fn config_dir() -> PathBuf {
    std::env::var_os("GRIP_E2E_CONFIG_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("config"))
}

/// The directory with `grip` and the five service binaries (built on first
/// use): grip-io's [`grip_io::binaries::bin_dir`], the rule `grip drive`
/// uses; unless `$GRIP_BIN_DIR` names it, the binaries are built there.
pub fn built_bin_dir() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = grip_io::binaries::bin_dir().expect("locating the binaries");
        if dir.from_env {
            return dir.path;
        }
        // target/<profile>/
        let profile_dir = dir.path;
        let target_dir = profile_dir.parent().unwrap().to_path_buf();
        let profile = profile_dir
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(workspace())
            .arg("build")
            .arg("--target-dir")
            .arg(&target_dir);
        match profile.as_str() {
            "debug" => {}
            "release" => {
                cmd.arg("--release");
            }
            p => {
                cmd.args(["--profile", p]);
            }
        }
        for p in [
            "grip",
            "grip-recorder",
            "grip-plant-sim",
            "grip-tcs-loop",
            "grip-audio-acq",
            "grip-arte-svc",
        ] {
            cmd.args(["-p", p]);
        }
        let out = cmd.output().expect("running cargo build");
        assert!(
            out.status.success(),
            "cargo build of the service binaries failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        profile_dir
    })
    .clone()
}

/// A unique `GRIP_INSTANCE`.
pub fn instance(tag: &str) -> String {
    let n = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    format!("e2e-{tag}-{}-{n:x}", std::process::id())
}

/// Reads `key=value` (a number) from a tracing line.
pub fn field(line: &str, key: &str) -> Option<f64> {
    let pat = format!(" {key}=");
    let i = line.find(&pat)? + pat.len();
    let rest = &line[i..];
    let end = rest.find(' ').unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// One service process.
pub struct Svc {
    pub name: &'static str,
    pub args: Vec<String>,
    child: Child,
    notify: UnixDatagram,
    pub lines: Arc<Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
    pub status: Option<ExitStatus>,
}

impl Svc {
    pub fn spawn(name: &'static str, args: &[String], instance: &str, sock_dir: &Path) -> Svc {
        let sock = sock_dir.join(format!("{name}.sock"));
        let _ = std::fs::remove_file(&sock);
        let notify = UnixDatagram::bind(&sock).unwrap();
        notify
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let mut child = Command::new(built_bin_dir().join(name))
            .args(args)
            .env("GRIP_INSTANCE", instance)
            .env("NOTIFY_SOCKET", &sock)
            .env("NO_COLOR", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let lines = Arc::new(Mutex::new(Vec::new()));
        let err = child.stderr.take().unwrap();
        let l2 = Arc::clone(&lines);
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(err).lines() {
                let Ok(line) = line else { break };
                l2.lock().unwrap().push(line);
            }
        });
        Svc {
            name,
            args: args.to_vec(),
            child,
            notify,
            lines,
            reader: Some(reader),
            status: None,
        }
    }

    pub fn stderr(&self) -> String {
        self.lines.lock().unwrap().join("\n")
    }

    pub fn has_line(&self, needle: &str) -> bool {
        self.lines
            .lock()
            .unwrap()
            .iter()
            .any(|l| l.contains(needle))
    }

    pub fn wait_ready(&mut self, timeout: Duration) {
        let t0 = Instant::now();
        let mut buf = [0u8; 4096];
        loop {
            if let Ok(n) = self.notify.recv(&mut buf)
                && String::from_utf8_lossy(&buf[..n])
                    .lines()
                    .any(|l| l == "READY=1")
            {
                return;
            }
            if let Some(st) = self.poll() {
                panic!(
                    "{} exited before READY=1 ({st}):\n{}",
                    self.name,
                    self.stderr()
                );
            }
            assert!(
                t0.elapsed() < timeout,
                "{} not ready within {timeout:?}:\n{}",
                self.name,
                self.stderr()
            );
        }
    }

    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.status.is_none()
            && let Ok(Some(st)) = self.child.try_wait()
        {
            self.status = Some(st);
            if let Some(h) = self.reader.take() {
                let _ = h.join();
            }
        }
        self.status
    }

    pub fn signal(&self, sig: &str) {
        let ok = Command::new("kill")
            .args([&format!("-{sig}"), &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -{sig} {}", self.name);
    }

    /// SIGTERM and wait (SIGKILL after `grace`, which fails the caller's check).
    pub fn stop(&mut self, grace: Duration) -> ExitStatus {
        if let Some(st) = self.poll() {
            return st;
        }
        self.signal("TERM");
        let t0 = Instant::now();
        while t0.elapsed() < grace {
            if let Some(st) = self.poll() {
                return st;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        self.signal("KILL");
        let st = self.child.wait().unwrap();
        self.status = Some(st);
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
        st
    }

    pub fn describe(st: &ExitStatus) -> String {
        match (st.code(), st.signal()) {
            (Some(c), _) => format!("exit code {c}"),
            (_, Some(s)) => format!("signal {s}"),
            _ => "?".into(),
        }
    }
}

impl Drop for Svc {
    fn drop(&mut self) {
        if self.poll().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
