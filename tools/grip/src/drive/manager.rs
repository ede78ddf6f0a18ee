//! A small service manager for `grip drive`: starts each service as its own
//! process (own process group, so a terminal Ctrl-C reaches only grip),
//! gives each its own `NOTIFY_SOCKET` datagram socket and waits for
//! `READY=1` like systemd's `Type=notify`, keeps the tail of each stderr,
//! detects early deaths, and stops them with SIGTERM (SIGKILL after a grace
//! period).

use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixDatagram;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};

use super::services::Service;

/// Lines of stderr kept per service.
pub const TAIL_LINES: usize = 40;

/// Removes ANSI escape sequences (coloured tracing output).
pub fn strip_ansi(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut it = s.chars().peekable();
    while let Some(c) = it.next() {
        if c == '\u{1b}' {
            if it.peek() == Some(&'[') {
                it.next();
                for c in it.by_ref() {
                    if ('@'..='~').contains(&c) {
                        break;
                    }
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// How a child ended.
pub fn describe_status(st: &ExitStatus) -> String {
    match (st.code(), st.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!(
            "killed by signal {s}{}",
            if s == 9 { " (SIGKILL)" } else { "" }
        ),
        _ => "ended (unknown status)".to_owned(),
    }
}

/// One running service.
pub struct Proc {
    /// Which.
    pub service: Service,
    /// The command line (for messages).
    pub cmdline: String,
    child: Child,
    notify: UnixDatagram,
    tail: Arc<Mutex<VecDeque<String>>>,
    reader: Option<JoinHandle<()>>,
    /// Exit status once reaped.
    pub status: Option<ExitStatus>,
    /// When it was started.
    pub started: Instant,
    /// Last `STATUS=` it sent.
    pub last_status: Option<String>,
}

impl std::fmt::Debug for Proc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Proc")
            .field("service", &self.service)
            .field("pid", &self.child.id())
            .finish()
    }
}

/// Settings shared by all children of a drive.
#[derive(Debug, Clone)]
pub struct Env {
    /// `GRIP_INSTANCE` of the drive.
    pub instance: String,
    /// Directory for the notify sockets.
    pub sock_dir: PathBuf,
    /// Forward every stderr line (else only warnings and errors).
    pub verbose: bool,
}

impl Proc {
    /// Starts `bin args...` for `service`.
    pub fn spawn(service: Service, bin: &Path, args: &[String], env: &Env) -> anyhow::Result<Self> {
        let sock = env.sock_dir.join(format!("{}.notify", service.name()));
        let _ = std::fs::remove_file(&sock);
        let notify = UnixDatagram::bind(&sock)
            .with_context(|| format!("binding the notify socket {}", sock.display()))?;
        notify.set_read_timeout(Some(Duration::from_millis(50)))?;
        let mut cmd = Command::new(bin);
        cmd.args(args)
            .env(grip_io::ipc::INSTANCE_ENV, &env.instance)
            .env("NOTIFY_SOCKET", &sock)
            .env("NO_COLOR", "1")
            .env_remove("WATCHDOG_USEC")
            .env_remove("WATCHDOG_PID")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .process_group(0);
        let cmdline = std::iter::once(bin.display().to_string())
            .chain(args.iter().cloned())
            .collect::<Vec<_>>()
            .join(" ");
        let mut child = cmd
            .spawn()
            .with_context(|| format!("starting {}: {cmdline}", service.name()))?;
        let tail = Arc::new(Mutex::new(VecDeque::with_capacity(TAIL_LINES)));
        let reader = child.stderr.take().map(|err| {
            let tail = Arc::clone(&tail);
            let name = service.name();
            let verbose = env.verbose;
            std::thread::spawn(move || {
                for line in BufReader::new(err).lines() {
                    let Ok(line) = line else { break };
                    let line = strip_ansi(&line);
                    let loud = line.contains(" WARN ")
                        || line.contains(" ERROR ")
                        || line.starts_with("error");
                    if verbose || loud {
                        eprintln!("  [{name}] {line}");
                    }
                    if let Ok(mut t) = tail.lock() {
                        if t.len() == TAIL_LINES {
                            t.pop_front();
                        }
                        t.push_back(line);
                    }
                }
            })
        });
        Ok(Self {
            service,
            cmdline,
            child,
            notify,
            tail,
            reader,
            status: None,
            started: Instant::now(),
            last_status: None,
        })
    }

    /// Process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The last lines of its stderr.
    pub fn tail(&self, n: usize) -> Vec<String> {
        let t = self.tail.lock().map(|t| t.clone()).unwrap_or_default();
        let skip = t.len().saturating_sub(n);
        t.into_iter().skip(skip).collect()
    }

    /// Its stderr tail, indented, for error messages.
    pub fn tail_text(&self, n: usize) -> String {
        let lines = self.tail(n);
        if lines.is_empty() {
            "    (no output on stderr)".to_owned()
        } else {
            lines
                .iter()
                .map(|l| format!("    {l}"))
                .collect::<Vec<_>>()
                .join("\n")
        }
    }

    /// Reaps it if it ended.
    pub fn poll_exit(&mut self) -> Option<ExitStatus> {
        if self.status.is_none()
            && let Ok(Some(st)) = self.child.try_wait()
        {
            self.status = Some(st);
            self.join_reader();
        }
        self.status
    }

    fn join_reader(&mut self) {
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
    }

    /// Reads pending notify datagrams (waits up to 50 ms); true if one said
    /// `READY=1`.
    pub fn read_notify(&mut self) -> bool {
        let mut buf = [0u8; 4096];
        let mut ready = false;
        while let Ok(n) = self.notify.recv(&mut buf) {
            let text = String::from_utf8_lossy(&buf[..n]);
            for line in text.lines() {
                if line == "READY=1" {
                    ready = true;
                } else if let Some(s) = line.strip_prefix("STATUS=") {
                    self.last_status = Some(s.to_owned());
                }
            }
            let _ = self.notify.set_nonblocking(true);
        }
        let _ = self.notify.set_nonblocking(false);
        ready
    }

    /// Waits for `READY=1` up to `timeout`; error naming the service with
    /// its stderr tail if it died or stayed silent.
    pub fn wait_ready(&mut self, timeout: Duration) -> anyhow::Result<Duration> {
        let t0 = Instant::now();
        loop {
            if self.read_notify() {
                return Ok(t0.elapsed());
            }
            if let Some(st) = self.poll_exit() {
                bail!(
                    "{} exited before it was ready ({}).\n  command: {}\n  last stderr lines:\n{}",
                    self.service.name(),
                    describe_status(&st),
                    self.cmdline,
                    self.tail_text(15)
                );
            }
            if t0.elapsed() > timeout {
                bail!(
                    "{} did not report READY=1 within {:.0} s.\n  command: {}\n  last stderr lines:\n{}",
                    self.service.name(),
                    timeout.as_secs_f64(),
                    self.cmdline,
                    self.tail_text(15)
                );
            }
        }
    }

    /// Sends `sig`.
    pub fn signal(&self, sig: i32) {
        if self.status.is_none() {
            // SAFETY: kill(2) with a pid we spawned and have not reaped
            // (so it cannot have been reused); no memory is involved.
            unsafe {
                libc::kill(self.child.id() as libc::pid_t, sig);
            }
        }
    }

    /// SIGTERM, then SIGKILL after `grace`; returns the exit status and
    /// whether SIGKILL was needed.
    pub fn stop(&mut self, grace: Duration) -> (Option<ExitStatus>, bool) {
        if let Some(st) = self.poll_exit() {
            return (Some(st), false);
        }
        self.signal(libc::SIGTERM);
        let t0 = Instant::now();
        while t0.elapsed() < grace {
            if let Some(st) = self.poll_exit() {
                return (Some(st), false);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.signal(libc::SIGKILL);
        let st = self.child.wait().ok();
        self.status = st;
        self.join_reader();
        (st, true)
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        // never leave a service running behind a failed drive
        if self.poll_exit().is_none() {
            self.signal(libc::SIGKILL);
            let _ = self.child.wait();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ansi_is_stripped() {
        assert_eq!(
            strip_ansi("\u{1b}[2m2026\u{1b}[0m \u{1b}[32m INFO\u{1b}[0m x"),
            "2026  INFO x"
        );
    }
}
