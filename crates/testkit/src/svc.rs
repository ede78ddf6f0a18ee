//! Running a service binary from its own tests (`CARGO_BIN_EXE_*`): the
//! shipped configuration copied to a temporary directory, a one-shot run
//! with its exit code and stderr, a `NOTIFY_SOCKET` to read `READY=1` and
//! `WATCHDOG=1` from, and a child that is killed if the test fails first.

use std::io::Read;
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// The repository's `config/` directory.
pub fn shipped_config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// A temporary directory holding copies of `entries` of the shipped
/// configuration (files, or folders copied with their files).
pub fn copy_config(entries: &[&str]) -> tempfile::TempDir {
    let t = tempfile::tempdir().expect("temporary directory");
    let src = shipped_config_dir();
    for e in entries {
        let (from, to) = (src.join(e), t.path().join(e));
        if from.is_dir() {
            std::fs::create_dir_all(&to).expect("creating a config folder");
            for f in std::fs::read_dir(&from).expect("reading a config folder") {
                let f = f.expect("config folder entry");
                std::fs::copy(f.path(), to.join(f.file_name())).expect("copying a config file");
            }
        } else {
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).expect("creating a config folder");
            }
            std::fs::copy(&from, &to).unwrap_or_else(|e| panic!("copying {}: {e}", from.display()));
        }
    }
    t
}

/// Cuts a service's TOML file at its `[rt]` table (tests run without the
/// real-time set-up: no SCHED_FIFO, no mlockall).
pub fn strip_rt(path: &Path) {
    let text = std::fs::read_to_string(path).expect("reading a service config");
    let cut = text.find("[rt]").unwrap_or(text.len());
    std::fs::write(path, &text[..cut]).expect("writing a service config");
}

/// Replaces the `[rt]` of the service configuration `path` (the section
/// [`strip_rt`] cuts, the last of the file) with one that pins to CPU
/// 1000 (the configuration allows CPUs up to 1023; no test machine has
/// 1001): a real-time step that is requested and cannot be applied
/// whoever runs the test (root or not), and nothing else asked.
pub fn unapplicable_rt(path: &Path) {
    strip_rt(path);
    let mut text = std::fs::read_to_string(path).expect("reading a service config");
    text.push_str("[rt]\ncpus = [1000]\n");
    std::fs::write(path, text).expect("writing a service config");
}

/// Runs the service binary `bin` on a copy of the shipped `configs` whose
/// own file `own` asks for a real-time step it cannot apply
/// ([`unapplicable_rt`]), with `args` and `--run-for 1`, reading its
/// `NOTIFY_SOCKET`: the first `STATUS=` line it sent (panicking, with its
/// stderr, if none came), and that it then exited 0. The test of each
/// service's `REAL TIME NOT APPLIED` status note.
pub fn status_with_unapplicable_rt(
    bin: &str,
    configs: &[&str],
    own: &str,
    args: &[&str],
) -> String {
    let t = copy_config(configs);
    unapplicable_rt(&t.path().join(own));
    let notify = NotifySocket::bind(t.path());
    let mut cmd = Command::new(bin);
    cmd.arg("--config-dir")
        .arg(t.path())
        .args(args)
        .args(["--run-for", "1"])
        .env(
            "GRIP_INSTANCE",
            format!("rt_status_{}_{}", own.replace('.', "_"), std::process::id()),
        )
        .env("NOTIFY_SOCKET", notify.path())
        .env_remove("INVOCATION_ID");
    let mut svc = Service::spawn(cmd);
    let status = notify.line_starting("STATUS=", Duration::from_secs(60));
    let (exit, stderr) = svc.wait();
    let status = status.unwrap_or_else(|| panic!("{bin}: no STATUS= line; stderr:\n{stderr}"));
    assert!(exit.success(), "{bin}: {exit:?}: {stderr}");
    status
}

/// Runs `bin` with `args` in the iceoryx2 instance `instance` to its end:
/// (exit code, -1 if killed by a signal; stderr).
pub fn run(bin: &str, instance: &str, args: &[&str]) -> (i32, String) {
    let out = Command::new(bin)
        .args(args)
        .env("GRIP_INSTANCE", instance)
        .output()
        .unwrap_or_else(|e| panic!("running {bin}: {e}"));
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A `NOTIFY_SOCKET` the test reads a service's notifications from.
pub struct NotifySocket {
    sock: UnixDatagram,
    path: PathBuf,
}

impl NotifySocket {
    /// Binds `notify.sock` in `dir`.
    pub fn bind(dir: &Path) -> Self {
        let path = dir.join("notify.sock");
        let sock = UnixDatagram::bind(&path).expect("binding the notify socket");
        sock.set_read_timeout(Some(Duration::from_millis(200)))
            .expect("socket timeout");
        Self { sock, path }
    }

    /// The path to hand over as `NOTIFY_SOCKET`.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Waits up to `timeout` for a datagram with the line `line`.
    pub fn wait_for(&self, line: &str, timeout: Duration) -> bool {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if self.recv_has(line) {
                return true;
            }
        }
        false
    }

    /// Datagrams with the line `line` received during `window`.
    pub fn count(&self, line: &str, window: Duration) -> usize {
        let t0 = Instant::now();
        let mut n = 0;
        while t0.elapsed() < window {
            n += usize::from(self.recv_has(line));
        }
        n
    }

    /// Waits up to `timeout` for a datagram with a line starting with
    /// `prefix` (e.g. `STATUS=`); that line.
    pub fn line_starting(&self, prefix: &str, timeout: Duration) -> Option<String> {
        let t0 = Instant::now();
        let mut buf = [0u8; 512];
        while t0.elapsed() < timeout {
            if let Ok(n) = self.sock.recv(&mut buf)
                && let Some(l) = String::from_utf8_lossy(&buf[..n])
                    .lines()
                    .find(|l| l.starts_with(prefix))
            {
                return Some(l.to_owned());
            }
        }
        None
    }

    fn recv_has(&self, line: &str) -> bool {
        let mut buf = [0u8; 512];
        self.sock.recv(&mut buf).is_ok_and(|n| {
            String::from_utf8_lossy(&buf[..n])
                .lines()
                .any(|l| l == line)
        })
    }
}

/// A spawned service, killed (and reaped) on drop if the test did not
/// stop it: a failing test leaves no process behind.
pub struct Service(pub Child);

impl Service {
    /// Spawns `cmd` with stdout discarded and stderr kept for [`Self::wait`].
    pub fn spawn(mut cmd: Command) -> Self {
        Self(
            cmd.stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .expect("spawning the service"),
        )
    }

    /// Sends signal `sig` (e.g. 15 for SIGTERM, 10 for SIGUSR1).
    pub fn signal(&self, sig: i32) {
        unsafe extern "C" {
            #[link_name = "kill"]
            fn libc_kill(pid: i32, sig: i32) -> i32;
        }
        let pid = i32::try_from(self.0.id()).expect("pid fits i32");
        // SAFETY: plain kill(2) on our own child's pid.
        unsafe { libc_kill(pid, sig) };
    }

    /// Waits for the exit: (status, all of stderr).
    pub fn wait(&mut self) -> (ExitStatus, String) {
        let status = self.0.wait().expect("waiting for the service");
        let mut err = String::new();
        if let Some(mut e) = self.0.stderr.take() {
            let _ = e.read_to_string(&mut err);
        }
        (status, err)
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}
