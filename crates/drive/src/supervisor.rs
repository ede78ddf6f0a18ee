//! The one service supervisor of grip: `grip drive`, the end-to-end tests
//! and the HIL tests start services with it.
//!
//! Each service runs as its own process (own process group, so a terminal
//! Ctrl-C reaches only the caller) with its own `NOTIFY_SOCKET` datagram
//! socket; [`Proc::wait_ready`] waits for `READY=1` like systemd's
//! `Type=notify`. Its output either goes through a pipe whose last lines
//! are kept (and echoed: warnings and errors, or everything) or into a
//! file (the HIL tests keep every service's log). A [`Supervisor`] starts
//! services in order, watches for early deaths, stops them with SIGTERM
//! (SIGKILL after a grace period) and kills whatever still runs when it
//! is dropped.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::os::unix::net::UnixDatagram;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::services::Placement;

/// Lines of output kept per service by default.
pub const TAIL_LINES: usize = 40;

/// Errors of the supervisor; each names the service, its command line and
/// the last lines it wrote.
#[derive(Debug, thiserror::Error)]
pub enum SuperviseError {
    /// A file-system or socket operation failed.
    #[error("{what}: {error}")]
    Io {
        /// What was being done (names the path or service).
        what: String,
        /// The error (said in the message, not returned as the source: a
        /// chain printed in full, as grip prints it, would say it twice).
        error: std::io::Error,
    },
    /// The service ended before it reported `READY=1`.
    #[error(
        "{service} exited before it was ready ({status}).\n  command: {cmdline}\n  last stderr lines:\n{tail}"
    )]
    ExitedBeforeReady {
        /// Service.
        service: String,
        /// How it ended ([`describe_status`]).
        status: String,
        /// Its command line.
        cmdline: String,
        /// Its last output lines, indented.
        tail: String,
    },
    /// The service stayed silent.
    #[error(
        "{service} did not report READY=1 within {secs:.0} s.\n  command: {cmdline}\n  last stderr lines:\n{tail}"
    )]
    NotReady {
        /// Service.
        service: String,
        /// The timeout, s.
        secs: f64,
        /// Its command line.
        cmdline: String,
        /// Its last output lines, indented.
        tail: String,
    },
    /// The service did not stop within its grace period and was killed.
    #[error(
        "{service} did not stop within {secs:.0} s of SIGTERM and was killed.\n  last stderr lines:\n{tail}"
    )]
    Killed {
        /// Service.
        service: String,
        /// The grace period, s.
        secs: f64,
        /// Its last output lines, indented.
        tail: String,
    },
    /// No service of that name was started.
    #[error("no service {0} in this supervisor")]
    Unknown(String),
}

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

/// The file in a view of a configuration directory (`grip drive --model`'s,
/// whose entries are links to the user's directory and a copy of the
/// user's model) that says which of the user's files the view's paths
/// stand for; see [`ViewPaths`].
pub const VIEW_PATHS_FILE: &str = ".grip-view-paths";

/// What the paths of a view of a configuration directory stand for: a
/// service started with `--config-dir VIEW` names the view's files in its
/// lines (`warning: VIEW/vehicle.toml: ...`), which the supervisor says in
/// the user's paths (`warning: CONFIG/vehicle.toml: ...`): the line the
/// user's own file gives, and which `grip drive` itself, having read the
/// file, may have said already (then it is said once). Empty (nothing
/// mapped) for a directory that is no view.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ViewPaths {
    /// (the view's path, the user's), the longest view path first.
    pairs: Vec<(String, String)>,
}

impl ViewPaths {
    /// The view's paths `pairs` (a path in the view, the user's file or
    /// directory it stands for; a directory stands for what is in it).
    pub fn new(pairs: &[(PathBuf, PathBuf)]) -> Self {
        let mut pairs: Vec<(String, String)> = pairs
            .iter()
            .map(|(v, u)| (v.display().to_string(), u.display().to_string()))
            .filter(|(v, _)| !v.is_empty())
            .collect();
        pairs.sort_by_key(|(v, _)| std::cmp::Reverse(v.len()));
        Self { pairs }
    }

    /// Writes `dir`'s [`VIEW_PATHS_FILE`] (`dir` being a view): a new
    /// file, any entry of that name removed first, so that the write never
    /// follows a link (to a user's file of that name, say).
    pub fn write(&self, dir: &Path) -> std::io::Result<()> {
        let mut t = toml::Table::new();
        t.insert(
            "path".into(),
            toml::Value::Array(
                self.pairs
                    .iter()
                    .map(|(v, u)| {
                        let mut e = toml::Table::new();
                        e.insert("view".into(), toml::Value::String(v.clone()));
                        e.insert("user".into(), toml::Value::String(u.clone()));
                        toml::Value::Table(e)
                    })
                    .collect(),
            ),
        );
        let text = format!(
            "# grip drive: a temporary view of a configuration directory; the user's files its paths stand for\n{}",
            toml::to_string(&t).map_err(std::io::Error::other)?
        );
        let path = dir.join(VIEW_PATHS_FILE);
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        // create_new fails on any entry there, a dangling link included
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)?;
        std::io::Write::write_all(&mut f, text.as_bytes())
    }

    /// `dir`'s [`VIEW_PATHS_FILE`]; empty when it has none (no view) or
    /// it cannot be read (the lines then keep the view's paths).
    pub fn read(dir: &Path) -> Self {
        let Ok(text) = std::fs::read_to_string(dir.join(VIEW_PATHS_FILE)) else {
            return Self::default();
        };
        let Ok(t) = text.parse::<toml::Table>() else {
            return Self::default();
        };
        let pairs: Vec<(PathBuf, PathBuf)> = t
            .get("path")
            .and_then(toml::Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(|e| {
                        let (v, u) = (e.get("view")?.as_str()?, e.get("user")?.as_str()?);
                        Some((PathBuf::from(v), PathBuf::from(u)))
                    })
                    .collect()
            })
            .unwrap_or_default();
        Self::new(&pairs)
    }

    /// Those of the `--config-dir DIR` in `args` (a service's arguments).
    pub fn of_args(args: &[String]) -> Self {
        args.iter()
            .position(|a| a == "--config-dir")
            .and_then(|i| args.get(i + 1))
            .map_or_else(Self::default, |d| Self::read(Path::new(d)))
    }

    /// `line` with every view path in it replaced by the user's (a view
    /// path counts where the name it ends in ends: `VIEW/roads` is not
    /// the start of `VIEW/roads.toml`'s name, nor of `VIEW/roads2`).
    pub fn map(&self, line: &str) -> String {
        if self.pairs.is_empty() {
            return line.to_owned();
        }
        let name_goes_on = |rest: &str| {
            rest.chars()
                .next()
                .is_some_and(|c| c.is_alphanumeric() || matches!(c, '.' | '_' | '-'))
        };
        let mut out = String::with_capacity(line.len());
        let mut rest = line;
        'scan: while let Some(c) = rest.chars().next() {
            for (v, u) in &self.pairs {
                if let Some(after) = rest.strip_prefix(v.as_str())
                    && !name_goes_on(after)
                {
                    out.push_str(u);
                    rest = after;
                    continue 'scan;
                }
            }
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
        out
    }
}

/// How a child ended: `exit code N` (78, [`grip_io::service::EXIT_CONFIG`],
/// named as a refused configuration) or `killed by signal N`.
pub fn describe_status(st: &ExitStatus) -> String {
    match (st.code(), st.signal()) {
        (Some(c), _) if c == i32::from(grip_io::service::EXIT_CONFIG) => {
            format!("exit code {c}: it refused its configuration")
        }
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!(
            "killed by signal {s}{}",
            if s == 9 { " (SIGKILL)" } else { "" }
        ),
        _ => "ended (unknown status)".to_owned(),
    }
}

/// Where a service's stdout and stderr go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Output {
    /// stderr through a pipe (stdout discarded): the last `keep` lines are
    /// kept; lines are echoed to the caller's stderr as `  [name] line`
    /// (all of them with `echo_all`, else only warnings and errors).
    Pipe {
        /// Lines kept.
        keep: usize,
        /// Echo every line (else only `WARN`/`ERROR`/`error` lines, and a
        /// `warning:` line of a configuration file once per process).
        echo_all: bool,
    },
    /// stderr kept in memory in full, nothing echoed (tests that look for
    /// a line).
    Capture,
    /// stdout and stderr both appended to this file.
    File(PathBuf),
}

/// What to start: a name (the service and its notify socket), the binary
/// and its arguments, extra environment variables, and the output.
#[derive(Debug, Clone)]
pub struct ProcSpec {
    /// Service name (messages, socket file, [`Supervisor::get`]).
    pub name: String,
    /// Executable.
    pub bin: PathBuf,
    /// Arguments.
    pub args: Vec<String>,
    /// Extra environment.
    pub env: Vec<(String, String)>,
    /// Output handling.
    pub output: Output,
    /// CPUs, nice and I/O priority of the process (its unit's).
    pub placement: Placement,
}

impl ProcSpec {
    /// `bin args...` named `name`, output piped with the default tail.
    pub fn new(name: &str, bin: &Path, args: &[String]) -> Self {
        Self {
            name: name.to_owned(),
            bin: bin.to_path_buf(),
            args: args.to_vec(),
            env: Vec::new(),
            output: Output::Pipe {
                keep: TAIL_LINES,
                echo_all: false,
            },
            placement: Placement::default(),
        }
    }

    /// Placed by `placement` (applied between fork and exec, as systemd
    /// applies a unit's `CPUAffinity=`, `Nice=` and I/O priority).
    pub fn placement(mut self, placement: Placement) -> Self {
        self.placement = placement;
        self
    }

    /// With `output`.
    pub fn output(mut self, output: Output) -> Self {
        self.output = output;
        self
    }

    /// The command line, for messages.
    pub fn cmdline(&self) -> String {
        std::iter::once(self.bin.display().to_string())
            .chain(self.args.iter().cloned())
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// Applies `p` in the child between fork and exec: affinity to the CPUs
/// of `p.cpus` that this process may use (none usable: left as it is; the
/// caller reports it, see [`Placement::usable_cpus`]), then the nice
/// value, then the I/O priority. A refused call fails the start with the
/// kernel's error, as a unit whose placement fails does not start.
fn place(cmd: &mut Command, p: &Placement) {
    if p.is_default() {
        return;
    }
    let cpus = p.usable_cpus();
    // SAFETY: an all-zero cpu_set_t is a valid empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &c in &cpus {
        // SAFETY: usable_cpus keeps only CPUs inside the set's size.
        unsafe { libc::CPU_SET(c, &mut set) };
    }
    let pin = !cpus.is_empty();
    let nice = p.nice;
    let io = p.io_best_effort;
    // SAFETY: the closure makes only async-signal-safe system calls
    // (sched_setaffinity, setpriority, ioprio_set) on data copied in
    // before the fork, and allocates nothing.
    unsafe {
        cmd.pre_exec(move || {
            if pin && libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            if nice != 0 && libc::setpriority(libc::PRIO_PROCESS, 0, nice) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if let Some(level) = io {
                // ioprio_set(IOPRIO_WHO_PROCESS, self, class best-effort << 13 | level)
                const IOPRIO_WHO_PROCESS: libc::c_long = 1;
                const IOPRIO_CLASS_BE: libc::c_long = 2;
                let prio = (IOPRIO_CLASS_BE << 13) | libc::c_long::from(level);
                if libc::syscall(libc::SYS_ioprio_set, IOPRIO_WHO_PROCESS, 0, prio) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
            }
            Ok(())
        });
    }
}

/// One running service.
pub struct Proc {
    name: String,
    /// The command line (for messages).
    pub cmdline: String,
    child: Child,
    notify: UnixDatagram,
    sock: PathBuf,
    lines: Arc<Mutex<VecDeque<String>>>,
    file: Option<PathBuf>,
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
            .field("name", &self.name)
            .field("pid", &self.child.id())
            .finish()
    }
}

impl Proc {
    /// Starts `spec` in iceoryx2 instance `instance` (`GRIP_INSTANCE`),
    /// with its notify socket `<sock_dir>/<name>.notify`.
    pub fn spawn(spec: &ProcSpec, instance: &str, sock_dir: &Path) -> Result<Self, SuperviseError> {
        let io = |what: String| move |error| SuperviseError::Io { what, error };
        let sock = sock_dir.join(format!("{}.notify", spec.name));
        let _ = std::fs::remove_file(&sock);
        let notify = UnixDatagram::bind(&sock)
            .map_err(io(format!("binding the notify socket {}", sock.display())))?;
        notify
            .set_read_timeout(Some(Duration::from_millis(50)))
            .map_err(io(format!("notify socket {}", sock.display())))?;
        let mut cmd = Command::new(&spec.bin);
        cmd.args(&spec.args)
            .env(grip_io::ipc::INSTANCE_ENV, instance)
            .env("NOTIFY_SOCKET", &sock)
            .env("NO_COLOR", "1")
            .env_remove("WATCHDOG_USEC")
            .env_remove("WATCHDOG_PID")
            // not a systemd unit, even when grip drive runs inside one (a
            // CI runner's service, systemd-run): the services' unit-only
            // rules (can.toml's auto transport, audio-acq's microphone)
            // read this
            .env_remove("INVOCATION_ID")
            .envs(spec.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::null())
            .process_group(0);
        place(&mut cmd, &spec.placement);
        let mut file = None;
        let (keep, echo) = match &spec.output {
            Output::Pipe { keep, echo_all } => {
                cmd.stdout(Stdio::null()).stderr(Stdio::piped());
                (*keep, Some(*echo_all))
            }
            Output::Capture => {
                cmd.stdout(Stdio::null()).stderr(Stdio::piped());
                (usize::MAX, None)
            }
            Output::File(p) => {
                let f = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)
                    .map_err(io(format!("creating {}", p.display())))?;
                let f2 = f
                    .try_clone()
                    .map_err(io(format!("opening {}", p.display())))?;
                cmd.stdout(f).stderr(f2);
                file = Some(p.clone());
                (0, None)
            }
        };
        let cmdline = spec.cmdline();
        let placed = if spec.placement.is_default() {
            String::new()
        } else {
            format!(" (placed: {})", spec.placement)
        };
        let mut child = cmd
            .spawn()
            .map_err(io(format!("starting {}: {cmdline}{placed}", spec.name)))?;
        let lines = Arc::new(Mutex::new(VecDeque::new()));
        // a view's paths (`grip drive --model`) said as the user's files
        let paths = ViewPaths::of_args(&spec.args);
        let reader = child.stderr.take().map(|err| {
            let lines = Arc::clone(&lines);
            let name = spec.name.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(err).lines() {
                    let Ok(line) = line else { break };
                    let line = paths.map(&strip_ansi(&line));
                    if let Some(all) = echo {
                        // a configuration file's `warning: FILE: ...` (the
                        // loaders print it raw) is said once: the same file
                        // read by grip itself or by another service already
                        // said it (with `echo_all`, every line as it comes)
                        let warning = line.starts_with("warning:");
                        let loud = line.contains(" WARN ")
                            || line.contains(" ERROR ")
                            || line.starts_with("error");
                        if warning && !all {
                            if grip_config::first_time(&line) {
                                eprintln!("  [{name}] {line}");
                            }
                        } else if all || loud {
                            eprintln!("  [{name}] {line}");
                        }
                    }
                    if let Ok(mut t) = lines.lock() {
                        if t.len() == keep {
                            t.pop_front();
                        }
                        t.push_back(line);
                    }
                }
            })
        });
        Ok(Self {
            name: spec.name.clone(),
            cmdline,
            child,
            notify,
            sock,
            lines,
            file,
            reader,
            status: None,
            started: Instant::now(),
            last_status: None,
        })
    }

    /// Service name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Its output so far, as lines: the kept pipe lines, or the log file's.
    pub fn lines(&self) -> Vec<String> {
        match &self.file {
            Some(p) => std::fs::read(p)
                .map(|b| {
                    String::from_utf8_lossy(&b)
                        .lines()
                        .map(strip_ansi)
                        .collect()
                })
                .unwrap_or_default(),
            None => self
                .lines
                .lock()
                .map(|t| t.iter().cloned().collect())
                .unwrap_or_default(),
        }
    }

    /// Its output so far as one text.
    pub fn text(&self) -> String {
        self.lines().join("\n")
    }

    /// Whether a line of its output contains `needle`.
    pub fn has_line(&self, needle: &str) -> bool {
        self.lines().iter().any(|l| l.contains(needle))
    }

    /// The log file ([`Output::File`]).
    pub fn log_path(&self) -> Option<&Path> {
        self.file.as_deref()
    }

    /// The last `n` lines of its output.
    pub fn tail(&self, n: usize) -> Vec<String> {
        let t = self.lines();
        let skip = t.len().saturating_sub(n);
        t.into_iter().skip(skip).collect()
    }

    /// Its output tail, indented, for error messages.
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

    /// Whether it is stopped (`T` in `/proc/<pid>/stat`: `SIGSTOP`, a
    /// terminal's `SIGTSTP` or a debugger's stop, `t`): alive, but none of
    /// its threads runs, so it neither exits nor makes progress. False once
    /// reaped or when `/proc` cannot be read.
    pub fn is_stopped(&self) -> bool {
        self.status.is_none()
            && std::fs::read_to_string(format!("/proc/{}/stat", self.pid()))
                .ok()
                .and_then(|s| proc_state(&s))
                .is_some_and(|c| c == 'T' || c == 't')
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

    /// Waits up to `timeout` for it to end.
    pub fn wait_timeout(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.poll_exit() {
                return Some(st);
            }
            if t0.elapsed() >= timeout {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
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

    /// Waits for `READY=1` up to `timeout`; an error naming the service
    /// with its output tail if it died or stayed silent.
    pub fn wait_ready(&mut self, timeout: Duration) -> Result<Duration, SuperviseError> {
        let t0 = Instant::now();
        loop {
            if self.read_notify() {
                return Ok(t0.elapsed());
            }
            if let Some(st) = self.poll_exit() {
                return Err(SuperviseError::ExitedBeforeReady {
                    service: self.name.clone(),
                    status: describe_status(&st),
                    cmdline: self.cmdline.clone(),
                    tail: self.tail_text(15),
                });
            }
            if t0.elapsed() > timeout {
                return Err(SuperviseError::NotReady {
                    service: self.name.clone(),
                    secs: timeout.as_secs_f64(),
                    cmdline: self.cmdline.clone(),
                    tail: self.tail_text(15),
                });
            }
        }
    }

    /// Sends `sig` (e.g. `libc::SIGUSR1`) unless it has been reaped.
    pub fn signal(&self, sig: i32) {
        if self.status.is_none() {
            // SAFETY: kill(2) with a pid we spawned and have not reaped
            // (so it cannot have been reused); no memory is involved.
            unsafe {
                libc::kill(self.child.id() as libc::pid_t, sig);
            }
        }
    }

    /// SIGTERM (and SIGCONT, so that a stopped process handles it), then
    /// SIGKILL after `grace`; returns the exit status and whether SIGKILL
    /// was needed.
    pub fn stop(&mut self, grace: Duration) -> (Option<ExitStatus>, bool) {
        if let Some(st) = self.poll_exit() {
            return (Some(st), false);
        }
        self.signal(libc::SIGTERM);
        // as systemd does: a stopped process (SIGSTOP, a debugger) handles
        // the SIGTERM only once continued
        self.signal(libc::SIGCONT);
        if let Some(st) = self.wait_timeout(grace) {
            return (Some(st), false);
        }
        self.signal(libc::SIGKILL);
        let st = self.child.wait().ok();
        self.status = st;
        self.join_reader();
        (st, true)
    }
}

/// The state letter of a `/proc/<pid>/stat` line (the field after the
/// command name, which is in parentheses and may itself hold spaces and
/// parentheses: the last `)` ends it).
fn proc_state(stat: &str) -> Option<char> {
    stat.rsplit_once(')')?.1.trim_start().chars().next()
}

impl Drop for Proc {
    fn drop(&mut self) {
        // never leave a service running behind a failed drive or test
        if self.poll_exit().is_none() {
            self.signal(libc::SIGKILL);
            let _ = self.child.wait();
        }
        let _ = std::fs::remove_file(&self.sock);
    }
}

/// Services of one drive (one `GRIP_INSTANCE`), started in order, each
/// awaited for `READY=1`; dropping it kills what still runs and removes
/// the notify sockets.
#[derive(Debug)]
pub struct Supervisor {
    instance: String,
    sock_dir: PathBuf,
    procs: Vec<Proc>,
}

impl Supervisor {
    /// A supervisor for instance `instance`; its notify sockets go to a
    /// fresh folder `<tmp>/grip-<instance>`.
    pub fn new(instance: &str) -> Result<Self, SuperviseError> {
        let sock_dir = std::env::temp_dir().join(format!("grip-{instance}"));
        std::fs::create_dir_all(&sock_dir).map_err(|error| SuperviseError::Io {
            what: format!("creating {}", sock_dir.display()),
            error,
        })?;
        Ok(Self {
            instance: instance.to_owned(),
            sock_dir,
            procs: Vec::new(),
        })
    }

    /// The `GRIP_INSTANCE`.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// Spawns `spec` without waiting for readiness (replacing a reaped or
    /// still running service of the same name, which is killed).
    pub fn spawn(&mut self, spec: &ProcSpec) -> Result<&mut Proc, SuperviseError> {
        self.procs.retain(|p| p.name != spec.name);
        let p = Proc::spawn(spec, &self.instance, &self.sock_dir)?;
        self.procs.push(p);
        let last = self.procs.len() - 1;
        Ok(&mut self.procs[last])
    }

    /// Spawns `spec` and waits up to `ready` for its `READY=1`; returns how
    /// long that took. On an error the process stays in the supervisor (its
    /// output can still be read; it is killed on drop).
    pub fn start(&mut self, spec: &ProcSpec, ready: Duration) -> Result<Duration, SuperviseError> {
        self.spawn(spec)?.wait_ready(ready)
    }

    /// The service `name`.
    pub fn get(&mut self, name: &str) -> Result<&mut Proc, SuperviseError> {
        self.procs
            .iter_mut()
            .find(|p| p.name == name)
            .ok_or_else(|| SuperviseError::Unknown(name.to_owned()))
    }

    /// Every service, in start order.
    pub fn procs(&self) -> &[Proc] {
        &self.procs
    }

    /// Every service, in start order, mutable.
    pub fn procs_mut(&mut self) -> &mut [Proc] {
        &mut self.procs
    }

    /// The services that ended since the last call (name and status),
    /// reaped: the watchdog of a running drive.
    pub fn ended(&mut self) -> Vec<(String, ExitStatus)> {
        let mut v = Vec::new();
        for p in &mut self.procs {
            let was = p.status.is_some();
            if let Some(st) = p.poll_exit()
                && !was
            {
                v.push((p.name.clone(), st));
            }
        }
        v
    }

    /// The names of the services that are stopped now
    /// ([`Proc::is_stopped`]), in start order.
    pub fn stopped(&self) -> Vec<String> {
        self.procs
            .iter()
            .filter(|p| p.is_stopped())
            .map(|p| p.name.clone())
            .collect()
    }

    /// SIGTERM to `name`, waiting up to `grace`; killed after it is an
    /// error. Returns its exit status.
    pub fn stop(&mut self, name: &str, grace: Duration) -> Result<ExitStatus, SuperviseError> {
        let p = self.get(name)?;
        match p.stop(grace) {
            (Some(st), false) => Ok(st),
            (_, _) => Err(SuperviseError::Killed {
                service: name.to_owned(),
                secs: grace.as_secs_f64(),
                tail: p.tail_text(10),
            }),
        }
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        self.procs.clear();
        let _ = std::fs::remove_dir_all(&self.sock_dir);
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

    fn sh(name: &str, script: &str) -> ProcSpec {
        ProcSpec::new(
            name,
            Path::new("/bin/sh"),
            &["-c".to_owned(), script.to_owned()],
        )
    }

    /// READY=1 over the notify socket, stderr kept, SIGTERM stops it; a
    /// process that exits early is named with its exit code and output.
    #[test]
    fn ready_stop_and_early_exit() {
        let mut s = Supervisor::new(&format!("test-sup-{}", std::process::id())).unwrap();
        let ready = "import os, socket; s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM); \
                     s.sendto(b'STATUS=up\\nREADY=1', os.environ['NOTIFY_SOCKET']); import time; time.sleep(30)";
        let spec = ProcSpec::new(
            "notifier",
            Path::new("/usr/bin/env"),
            &["python3".to_owned(), "-c".to_owned(), ready.to_owned()],
        );
        s.start(&spec, Duration::from_secs(20)).unwrap();
        assert_eq!(
            s.get("notifier").unwrap().last_status.as_deref(),
            Some("up")
        );
        let st = s.stop("notifier", Duration::from_secs(5)).unwrap();
        assert_eq!(st.signal(), Some(libc::SIGTERM));
        let e = s
            .start(
                &sh("quitter", "echo bad field >&2; exit 3").output(Output::Capture),
                Duration::from_secs(10),
            )
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("quitter exited before it was ready (exit code 3)")
                && e.contains("bad field"),
            "{e}"
        );
        let e = s
            .start(&sh("silent", "exec sleep 30"), Duration::from_millis(200))
            .unwrap_err()
            .to_string();
        assert!(e.contains("silent did not report READY=1"), "{e}");
        let st = s.stop("silent", Duration::from_secs(5)).unwrap();
        assert_eq!(st.signal(), Some(libc::SIGTERM));
        assert!(s.get("nobody").is_err());
    }

    /// A stopped process is told from a running and an ended one, and
    /// the state is read past a command name holding `)` and spaces.
    #[test]
    fn a_stopped_process_is_seen_as_stopped() {
        assert_eq!(proc_state("42 (a) b (c)) T 1 42"), Some('T'));
        assert_eq!(proc_state("42 (sleep) S 1 42"), Some('S'));
        assert_eq!(proc_state("garbage"), None);
        let mut s = Supervisor::new(&format!("test-sup5-{}", std::process::id())).unwrap();
        s.spawn(&sh("sleeper", "exec sleep 30")).unwrap();
        assert!(s.stopped().is_empty(), "{:?}", s.stopped());
        s.get("sleeper").unwrap().signal(libc::SIGSTOP);
        let t0 = Instant::now();
        while s.stopped().is_empty() && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(s.stopped(), vec!["sleeper".to_owned()]);
        s.get("sleeper").unwrap().signal(libc::SIGCONT);
        let t0 = Instant::now();
        while !s.stopped().is_empty() && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(s.stopped().is_empty());
        // stopped again, it still ends on the SIGTERM (continued), not killed
        s.get("sleeper").unwrap().signal(libc::SIGSTOP);
        let t0 = Instant::now();
        while s.stopped().is_empty() && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(s.stopped(), vec!["sleeper".to_owned()]);
        let st = s.stop("sleeper", Duration::from_secs(5)).unwrap();
        assert_eq!(st.signal(), Some(libc::SIGTERM));
        assert!(
            !s.get("sleeper").unwrap().is_stopped(),
            "reaped: not stopped"
        );
    }

    /// A placed process runs on its CPU, at its nice value and I/O
    /// priority from its first instruction (read back from /proc and
    /// ioprio_get(2)); an unplaced one keeps the caller's.
    #[test]
    fn placement_is_applied_before_exec() {
        let mut s = Supervisor::new(&format!("test-sup3-{}", std::process::id())).unwrap();
        let placed = Placement {
            cpus: &[0],
            nice: 10,
            io_best_effort: Some(7),
        };
        let pid = s
            .spawn(&sh("placed", "exec sleep 30").placement(placed))
            .unwrap()
            .pid();
        let plain = s.spawn(&sh("plain", "exec sleep 30")).unwrap().pid();
        let status = |pid: u32, key: &str| -> String {
            let text = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
            text.lines()
                .find_map(|l| l.strip_prefix(key))
                .unwrap()
                .trim()
                .to_owned()
        };
        // Field 19 of /proc/PID/stat (after the parenthesised name) is nice.
        let nice = |pid: u32| -> i64 {
            let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
            let after = &text[text.rfind(')').unwrap() + 2..];
            after.split(' ').nth(16).unwrap().parse().unwrap()
        };
        // SAFETY: ioprio_get(IOPRIO_WHO_PROCESS, pid) reads a number.
        let ioprio = |pid: u32| unsafe { libc::syscall(libc::SYS_ioprio_get, 1, pid as i64) };
        assert_eq!(status(pid, "Cpus_allowed_list:"), "0");
        assert_eq!(nice(pid), 10);
        assert_eq!(ioprio(pid), (2 << 13) | 7, "best-effort, level 7");
        assert_eq!(
            status(plain, "Cpus_allowed_list:"),
            status(std::process::id(), "Cpus_allowed_list:")
        );
        assert_eq!(nice(plain), nice(std::process::id()));
    }

    /// A view's paths are the user's: each view path where its name ends
    /// (the longest first), nothing else; a directory that is no view
    /// maps nothing.
    #[test]
    fn a_view_s_paths_map_to_the_user_s() {
        let v = ViewPaths::new(&[
            ("/tmp/v".into(), "/srv/u/cfg".into()),
            ("/tmp/v/models/m.model".into(), "/srv/u/m.model".into()),
        ]);
        for (line, want) in [
            (
                "warning: /tmp/v/vehicle.toml: [vehicle] does not set r_ref",
                "warning: /srv/u/cfg/vehicle.toml: [vehicle] does not set r_ref",
            ),
            (
                "model /tmp/v/models/m.model, roads /tmp/v/roads.toml; /tmp/v",
                "model /srv/u/m.model, roads /srv/u/cfg/roads.toml; /srv/u/cfg",
            ),
            // another directory whose name starts like the view's
            (
                "/tmp/v2/vehicle.toml /tmp/v.old",
                "/tmp/v2/vehicle.toml /tmp/v.old",
            ),
            // a model whose name starts like the copied one's
            ("/tmp/v/models/m.model2 é", "/srv/u/cfg/models/m.model2 é"),
        ] {
            assert_eq!(v.map(line), want);
        }
        let d = tempfile::tempdir().unwrap();
        assert_eq!(ViewPaths::read(d.path()), ViewPaths::default());
        assert_eq!(ViewPaths::default().map("/tmp/v/x"), "/tmp/v/x");
        v.write(d.path()).unwrap();
        assert_eq!(ViewPaths::read(d.path()), v);
        let args = ["--config-dir".to_owned(), d.path().display().to_string()];
        assert_eq!(ViewPaths::of_args(&args), v);
        assert_eq!(ViewPaths::of_args(&args[..1]), ViewPaths::default());
    }

    /// A service started on a view (`--config-dir VIEW`) has its lines
    /// kept and echoed in the user's paths: its configuration warning is
    /// the one `grip drive` says of the user's file (and then not echoed
    /// again). It was echoed naming the view's temporary copy: the user saw
    /// the same warning twice, with two paths.
    #[test]
    fn a_service_on_a_view_is_heard_in_the_user_s_paths() {
        let view = tempfile::tempdir().unwrap();
        let user = Path::new("/srv/u/cfg");
        ViewPaths::new(&[(view.path().to_path_buf(), user.to_path_buf())])
            .write(view.path())
            .unwrap();
        let warning = |dir: &Path| {
            format!(
                "warning: {}: [vehicle] does not set mic_lead_m (a line no other test says)",
                dir.join("vehicle.toml").display()
            )
        };
        // said by grip itself first, of the user's file
        assert!(grip_config::first_time(&warning(user)));
        let mut s = Supervisor::new(&format!("test-sup4-{}", std::process::id())).unwrap();
        let spec = ProcSpec::new(
            "viewer",
            Path::new("/bin/sh"),
            &[
                "-c".to_owned(),
                r#"echo "warning: $1/vehicle.toml: [vehicle] does not set mic_lead_m (a line no other test says)" >&2; exit 3"#.to_owned(),
                "--config-dir".to_owned(),
                view.path().display().to_string(),
            ],
        );
        let e = s
            .start(&spec, Duration::from_secs(10))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&warning(user)), "{e}");
        assert!(
            !e.lines()
                .any(|l| !l.contains("command:") && l.contains(&view.path().display().to_string())),
            "{e}"
        );
        // the echo compared the user's line: already said, not said again
        assert!(!grip_config::first_time(&warning(user)));
        assert!(grip_config::first_time(&warning(view.path())));
    }

    /// A process that ignores SIGTERM is killed and reported; dropping the
    /// supervisor kills what still runs.
    #[test]
    fn kill_after_grace_and_on_drop() {
        let mut s = Supervisor::new(&format!("test-sup2-{}", std::process::id())).unwrap();
        s.spawn(&sh("stubborn", "trap '' TERM; sleep 2 & wait"))
            .unwrap();
        std::thread::sleep(Duration::from_millis(100));
        let e = s.stop("stubborn", Duration::from_millis(200)).unwrap_err();
        assert!(e.to_string().contains("stubborn did not stop"), "{e}");
        let dir = std::env::temp_dir();
        let f = dir.join(format!("grip-sup-{}.log", std::process::id()));
        let pid = s
            .spawn(&sh("sleeper", "echo started; exec sleep 30").output(Output::File(f.clone())))
            .unwrap()
            .pid();
        std::thread::sleep(Duration::from_millis(200));
        assert!(s.get("sleeper").unwrap().has_line("started"));
        drop(s);
        assert!(
            !Path::new(&format!("/proc/{pid}")).exists()
                || std::fs::read_to_string(format!("/proc/{pid}/stat"))
                    .is_ok_and(|t| t.contains(") Z")),
            "sleeper survived the drop"
        );
        let _ = std::fs::remove_file(f);
    }
}
