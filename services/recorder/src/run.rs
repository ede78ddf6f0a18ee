//! [`run`]: opens the log file and writes the run's metadata, starts the
//! receive thread, sends `READY=1`, runs the writing loop
//! ([`crate::cycle`]) until stopped, then writes the summary and finishes
//! the file.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::sync_channel;

use grip_config::ConfigError;
use grip_io::ipc::IpcError;
use grip_io::mcaplog::{McapLogError, McapWriter};
use grip_io::service::{ConfigArgs, ServiceConfig};
use grip_io::systemd;
#[cfg(test)]
use grip_msgs::topics;

use crate::bus::BusSetup;
use crate::config::{BusRecord, RecorderConfig};
use crate::cycle::{Summary, queue, spawn_receiver, write_loop};
use crate::monitor::RxProbe;
use crate::parts::{NextPath, Parts, Rotation, RunHead};
use crate::retention::Retention;
use crate::stats::{RecvStats, StatsTap};

/// The grip revision this binary was built from (build.rs).
pub const GIT_REV: &str = env!("GRIP_GIT_REV");

/// Command-line choices (see `main.rs`).
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config-dir` and `--config`.
    pub config: ConfigArgs,
    /// Output file (default: a new `<out_dir>/grip-<unix s>-<boot id>-<pid>.mcap`,
    /// never an existing one: [`default_out`]).
    pub out: Option<PathBuf>,
    /// Extra `grip.run` metadata (scenario, controller, ...).
    pub meta: Vec<(String, String)>,
    /// Extra files to hash and attach: (name in the log, path); `grip
    /// drive` attaches its `--vehicle` file as `drive/vehicle.toml`.
    pub attach: Vec<(String, PathBuf)>,
}

/// Fatal errors.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Bad configuration.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// iceoryx2.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The MCAP file.
    #[error(transparent)]
    Mcap(#[from] McapLogError),
    /// The output directory (`out_dir` of the configuration file): the
    /// message names the file and field, then the directory.
    #[error(
        "{}: field `out_dir`: {}: cannot create the log directory or a new log file in it: {error}",
        config_file.display(),
        path.display()
    )]
    OutDir {
        /// The configuration file that named it (`recorder.toml`).
        config_file: PathBuf,
        /// Directory.
        path: PathBuf,
        /// The error (said in the message, not returned as the source:
        /// a chain printed in full would say it twice).
        error: std::io::Error,
    },
    /// The file `--out` names cannot be created or its head written (its
    /// directory missing, no permission): the message names the option,
    /// then the file and the reason.
    #[error("option `--out`: {0}")]
    Out(McapLogError),
    /// An `--attach` file that cannot be read: refused at start, before
    /// any file is created or recorded (the log would lack what its caller
    /// asked it to carry).
    #[error("--attach {name}={}: cannot read: {error}; nothing recorded", path.display())]
    Attach {
        /// The attachment's name in the log.
        name: String,
        /// The file.
        path: PathBuf,
        /// Why (the service prints this error's Display alone, so it is
        /// said here and not also returned as its source).
        error: std::io::Error,
    },
    /// A thread could not be started.
    #[error("cannot start the receive thread: {0}")]
    Thread(std::io::Error),
    /// The receive thread panicked: recording ended there, its counters are lost.
    #[error(
        "the receive thread panicked ({0}): recording stopped there; its counters are lost (no grip.recorder summary); the log holds what was written"
    )]
    ReceiveThread(String),
}

impl grip_io::service::ServiceError for RunError {
    /// Only a configuration file: an output directory not there yet (a
    /// file system mounted late) or an unreadable `--attach` file are left
    /// to the unit's `Restart=` and to `grip drive`.
    fn is_config(&self) -> bool {
        matches!(self, Self::Config(_))
    }
}

/// The receive thread's counters; its panic is an error, never counters of
/// zero.
fn join_receiver(h: std::thread::JoinHandle<RecvStats>) -> Result<RecvStats, RunError> {
    h.join().map_err(|p| {
        let why = p
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".to_owned());
        RunError::ReceiveThread(why)
    })
}

/// Every `--attach` file (name in the log, path) can be opened and read:
/// the first that cannot is [`RunError::Attach`] (a missing file, a
/// directory, no permission), naming it, its path and the OS's reason.
fn check_attachments(attach: &[(String, PathBuf)]) -> Result<(), RunError> {
    use std::io::Read;
    for (name, path) in attach {
        std::fs::File::open(path)
            // a directory opens, and its first read fails
            .and_then(|mut f| f.read(&mut [0u8; 1]))
            .map_err(|error| RunError::Attach {
                name: name.clone(),
                path: path.clone(),
                error,
            })?;
    }
    Ok(())
}

/// A file to attach: its name in the log, path, and whether it is a model.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigFile {
    /// Name in the log (relative to the config directory).
    pub name: String,
    /// Path on disk.
    pub path: PathBuf,
    /// Under `models/`.
    pub model: bool,
}

/// The files of a configuration directory that describe a run: `*.toml`,
/// `*.dbc`, `*.csv` at the top and in `roads/`, `scenarios/*.toml`,
/// `vehicles/*.toml` (the profiles `--vehicle` picks), everything in `models/`. Sorted by name; unreadable directories are
/// skipped.
pub fn config_files(dir: &Path) -> Vec<ConfigFile> {
    let mut out = Vec::new();
    let mut scan = |sub: &str, exts: Option<&[&str]>, model: bool| {
        let d = if sub.is_empty() {
            dir.to_path_buf()
        } else {
            dir.join(sub)
        };
        let Ok(rd) = std::fs::read_dir(&d) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            if !p.is_file() {
                continue;
            }
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
            if exts.is_some_and(|xs| !xs.contains(&ext)) {
                continue;
            }
            let file = e.file_name().to_string_lossy().into_owned();
            let name = if sub.is_empty() {
                file
            } else {
                format!("{sub}/{file}")
            };
            out.push(ConfigFile {
                name,
                path: p,
                model,
            });
        }
    };
    scan("", Some(&["toml", "dbc", "csv"]), false);
    scan("roads", Some(&["toml", "csv"]), false);
    scan("scenarios", Some(&["toml"]), false);
    scan("vehicles", Some(&["toml"]), false);
    scan("models", None, true);
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// Writes `grip.run` (version, git revision, hashes, extras) and attaches
/// the configuration files and the `extra` files (name in the log, path):
/// the head of a run's first part ([`RunHead`]).
pub fn write_run_info(
    w: &mut McapWriter,
    config_dir: &Path,
    attach_max: u64,
    meta: &[(String, String)],
    extra: &[(String, PathBuf)],
) -> Result<(), McapLogError> {
    RunHead::gather(config_dir, attach_max, meta, extra).write(w, &Default::default())
}

/// A new log file in `dir`, created empty (so that no other recorder can
/// take the name) and never one that exists: `grip-<unix s>-<boot>-<pid>.mcap`,
/// `<boot>` the first 8 characters of this boot's id
/// (`/proc/sys/kernel/random/boot_id`), and `-1`, `-2`, ... appended while
/// a name is taken. An ECU without a real-time clock starts every boot at
/// the same wall time, and its recorder often gets the same PID: the name
/// alone repeats, and the boot id and `create_new` keep an earlier drive's
/// log from being overwritten. Retention ([`crate::retention`]) deletes
/// only files named this way.
pub fn default_out(dir: &Path) -> std::io::Result<PathBuf> {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let boot = crate::retention::boot_token();
    let stem = format!("grip-{secs}-{boot}-{}", std::process::id());
    new_file(dir, &stem)
}

/// Creates `dir/<stem>.mcap`, or `dir/<stem>-N.mcap` with the smallest N
/// not taken, with `create_new` (never truncating a file that exists).
pub fn new_file(dir: &Path, stem: &str) -> std::io::Result<PathBuf> {
    for n in 0u32.. {
        let name = if n == 0 {
            format!("{stem}.mcap")
        } else {
            format!("{stem}-{n}.mcap")
        };
        let path = dir.join(name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(_) => return Ok(path),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free log file name"))
}

/// The start-up's refusals, in its order: the `--attach` files (the
/// files the caller asked the log to carry, before anything is created,
/// deleted by retention or recorded), then `recorder.toml` (`--config`, else
/// in `--config-dir`) read, parsed and range-checked. Returns its path and
/// the configuration.
fn load(opts: &Options) -> Result<(PathBuf, RecorderConfig), RunError> {
    check_attachments(&opts.attach)?;
    let own = opts.config.own_file::<RecorderConfig>();
    let cfg = RecorderConfig::load(&own)?;
    Ok((own, cfg))
}

/// Every check of the service's start-up that can refuse it, short of
/// creating its log and opening iceoryx2: the `--attach` files readable
/// and `recorder.toml` as [`run`] loads it (unknown keys, types, ranges;
/// the error names the file, the field and the reason). Nothing is
/// created, written or said; `out_dir` is not made (without `--out` the
/// run creates it, and a directory not there yet is left to the unit's
/// `Restart=`), and the bus configuration, which the recorder only warns
/// about, is not read. `grip drive` runs it before starting any service,
/// beside `grip_tcs_loop::check`, so that a `recorder.toml` the recorder
/// refuses fails there, once, and not as a drive with no readable log.
pub fn check(opts: &Options) -> Result<(), RunError> {
    load(opts).map(drop)
}

/// Runs the recorder until `stop` (SIGTERM/SIGINT): opens the subscribers
/// and the file, writes `grip.run` and the attachments, sends `READY=1`,
/// records; on stop drains what is queued, writes the `grip.recorder`
/// summary metadata and finishes the file.
pub fn run(opts: &Options, stop: &Arc<AtomicBool>) -> Result<Summary, RunError> {
    let (own, cfg) = load(opts)?;
    // the bus's protocol, so that the CAN log's alive counters are read
    // where its DBC puts them; a configuration that gives none leaves the
    // built-in one (the services themselves refuse it, naming why)
    let dir = grip_config::ConfigDir::new(&opts.config.config_dir);
    let can = grip_io::service::load_can(&dir);
    if let Err(e) = can.as_ref().map_err(Clone::clone).and_then(|can| {
        // the recorder reads ids and alive counters only, which no
        // wheel radius moves; the configuration's vehicle gives the radii
        // its protocol line names (none readable: 1 m, never used for a
        // speed here)
        let radii = dir.vehicle().map_or(
            grip_io::can::protocol::WheelRadii {
                driven_m: 1.0,
                reference_m: 1.0,
            },
            |(v, _)| grip_io::can::protocol::WheelRadii::of(&v),
        );
        grip_io::service::install_protocol_with(&dir, can, Some(radii)).map(|_| ())
    }) {
        tracing::warn!(error = %e, "CAN alive counters read as the built-in protocol places them (and, with bus = \"foreign\", grip's ids on the bus are the built-in ones)");
    }
    // the vehicle bus, read-only (crate::bus): a bus that cannot be
    // configured is a warning, the rest is recorded
    let bus = match (cfg.bus, can) {
        (BusRecord::Off, _) => {
            tracing::info!("bus log off (recorder.toml: bus = \"off\")");
            None
        }
        (mode, Ok(can)) => Some(BusSetup {
            can,
            mode,
            under_systemd: std::env::var_os("INVOCATION_ID").is_some(),
        }),
        (mode, Err(e)) => {
            tracing::warn!(error = %e, record = mode.as_str(), "bus log: no bus configuration; the vehicle bus is not recorded");
            None
        }
    };
    let bus_mode = cfg.bus;
    let path = match &opts.out {
        Some(p) => p.clone(),
        None => std::fs::create_dir_all(&cfg.out_dir)
            .and_then(|()| default_out(&cfg.out_dir))
            .map_err(|error| RunError::OutDir {
                config_file: own.clone(),
                path: cfg.out_dir.clone(),
                error,
            })?,
    };
    // retention of out_dir, when the recorder named its file there itself
    // (the systemd unit); with --out (grip drive, tests) nothing is deleted
    let mut retention = match (&opts.out, cfg.retention_limits()) {
        (None, Some(limits)) => {
            tracing::info!(
                dir = %cfg.out_dir.display(),
                max_total_mib = cfg.max_total_mib,
                min_free_mib = cfg.min_free_mib,
                every_s = crate::retention::SWEEP_PERIOD.as_secs(),
                "retention: the oldest finished logs are deleted while grip's logs take more than max_total_mib or less than min_free_mib is free (0: that limit off)"
            );
            let mut r = Retention::new(&cfg.out_dir, &path, limits);
            // the floor before the first byte; the rest once recording
            r.sweep_start();
            Some(r)
        }
        (None, None) => {
            tracing::info!(dir = %cfg.out_dir.display(), "retention off (max_total_mib = 0 and min_free_mib = 0): no log is ever deleted");
            None
        }
        (Some(_), _) => {
            tracing::debug!("retention: not applied to a log named by --out");
            None
        }
    };
    let mut head = RunHead::gather(
        &opts.config.config_dir,
        cfg.attach_max_bytes,
        &opts.meta,
        &opts.attach,
    );
    head.bus_log = bus_mode != BusRecord::Off;
    // rotation and resuming after a write error only where the recorder
    // names its files itself (out_dir); --out is one file
    let (rotation, next_path): (Option<Rotation>, NextPath) = match &opts.out {
        Some(_) => (
            None,
            Box::new(|| Err(std::io::Error::other("--out: one file"))),
        ),
        None => {
            let dir = cfg.out_dir.clone();
            (
                Some(cfg.rotation()),
                Box::new(move || std::fs::create_dir_all(&dir).and_then(|()| default_out(&dir))),
            )
        }
    };
    if let Some(r) = rotation {
        tracing::info!(
            max_file_mib = cfg.max_file_mib(),
            max_file_s = r.max_age.as_secs(),
            "rotation: a new log file once the one being written holds max_file_mib (0: no size limit) or has recorded max_file_s"
        );
    }
    let (q, rx, depth, high) = queue(cfg.queue_capacity);
    let tap = Arc::new(StatsTap::default());
    let mut parts = Parts::open(&path, head, cfg.writer_options(), rotation, next_path)
        .map_err(|e| match opts.out {
            // the file the option named
            Some(_) => RunError::Out(e),
            None => {
                // an empty file of ours, not a log
                let _ = std::fs::remove_file(&path);
                RunError::Mcap(e)
            }
        })?
        .with_floor(&cfg.out_dir, cfg.min_free_mib << 20)
        .with_tap(Arc::clone(&tap))
        .with_high_water(Arc::clone(&high));

    let rx_stop = Arc::new(AtomicBool::new(false));
    let rx_beat = Arc::new(AtomicU64::new(0));
    let probe = Arc::new(RxProbe::default());
    let (ready_tx, ready_rx) = sync_channel(1);
    let handle = spawn_receiver(
        q,
        Arc::clone(&rx_stop),
        cfg.poll_interval(),
        Arc::clone(&rx_beat),
        Arc::clone(&probe),
        tap,
        ready_tx,
        bus,
    )
    .map_err(RunError::Thread)?;
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            let _ = handle.join();
            return Err(RunError::Ipc(e));
        }
        Err(_) => {
            let _ = handle.join();
            return Err(RunError::Thread(std::io::Error::other(
                "the receive thread ended before opening its subscribers",
            )));
        }
    }

    // the topics' peers, watched beside the receive thread (never on it)
    let peers = crate::monitor::spawn_peer_watch(Arc::clone(&rx_stop))
        .inspect_err(|e| tracing::warn!(error = %e, "cannot start the peer-watch thread; recording goes on without"))
        .ok();
    systemd::notify_ready(&format!("recording to {}", path.display()));
    tracing::info!(file = %path.display(), git = GIT_REV, "recorder ready");

    let mut summary = Summary {
        path: path.clone(),
        ..Summary::default()
    };
    let failed = write_loop(
        &rx,
        &mut parts,
        &depth,
        stop,
        &rx_stop,
        &rx_beat,
        &probe,
        &mut summary,
        retention.as_mut(),
    );
    let rx_failed = match join_receiver(handle) {
        Ok(recv) => {
            summary.recv = recv;
            None
        }
        Err(e) => {
            tracing::error!(error = %e, "receive thread failed");
            Some(e)
        }
    };
    if let Some(p) = peers {
        let _ = p.join();
    }
    summary.queue_high_water = high.load(Ordering::Relaxed);
    // the file's end: a failure here (a disk that filled up at the stop)
    // is returned after the stop line, so the counters are still logged
    // (without the receive thread's counters the record would claim
    // nothing was received: none is written)
    let n_parts = parts.count();
    let last_file = parts.current().map(Path::to_path_buf);
    let end = parts.finish(rx_failed.is_none().then_some(&summary.recv), &summary);
    let not_written: u64 = summary.not_written.values().sum();
    let total_rx: u64 = summary.recv.topics.values().map(|s| s.received).sum();
    let total_w: u64 = summary.written.values().sum();
    let gaps: u64 = summary.recv.topics.values().map(|s| s.seq.gaps).sum();
    let dropped: u64 = summary.recv.topics.values().map(|s| s.queue_dropped).sum();
    let receive_errors: u64 = summary.recv.topics.values().map(|s| s.receive_errors).sum();
    let ret = retention.as_ref().map(Retention::stats).unwrap_or_default();
    let bus = summary.recv.bus.map(|b| b.stats).unwrap_or_default();
    let bus_written = summary
        .written
        .get(grip_msgs::topics::BUS)
        .copied()
        .unwrap_or(0);
    tracing::info!(
        file = %path.display(),
        received = total_rx,
        written = total_w,
        seq_gaps = gaps,
        can_counter_gaps = summary.recv.can.gaps,
        queue_dropped = dropped,
        receive_errors,
        queue_high_water = summary.queue_high_water,
        write_errors = summary.write_errors,
        not_written,
        parts = n_parts,
        last_file = %last_file.as_deref().unwrap_or(Path::new("-")).display(),
        retention_deleted = ret.deleted,
        retention_deleted_mib = ret.deleted_bytes >> 20,
        retention_failed = ret.failed,
        retention_longest_sweep_ms = ret.longest.as_secs_f64() * 1e3,
        bus_log = bus_mode.as_str(),
        bus_received = bus.received,
        bus_written,
        bus_kernel_dropped = bus.kernel_dropped,
        bus_queue_dropped = bus.queue_dropped,
        bus_receive_errors = bus.receive_errors,
        bus_reopens = bus.reopens,
        "recorder stopped"
    );
    end?;
    if failed {
        return Err(RunError::Mcap(McapLogError::Io {
            path,
            error: std::io::Error::other("a write failed during the recording (see above)"),
        }));
    }
    if let Some(e) = rx_failed {
        return Err(e);
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log name that is taken (an earlier boot at the same wall time and
    /// PID) gets `-1`, `-2`: the earlier log keeps its bytes.
    #[test]
    fn a_new_log_never_overwrites_an_existing_one() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("grip-5-ab-7.mcap"), b"earlier drive").unwrap();
        let p1 = new_file(dir.path(), "grip-5-ab-7").unwrap();
        assert_eq!(p1, dir.path().join("grip-5-ab-7-1.mcap"));
        let p2 = new_file(dir.path(), "grip-5-ab-7").unwrap();
        assert_eq!(p2, dir.path().join("grip-5-ab-7-2.mcap"));
        assert_eq!(
            std::fs::read(dir.path().join("grip-5-ab-7.mcap")).unwrap(),
            b"earlier drive"
        );
        let d = default_out(dir.path()).unwrap();
        let name = d.file_name().unwrap().to_str().unwrap().to_owned();
        assert!(
            d.exists() && name.starts_with("grip-") && name.ends_with(".mcap"),
            "{name}"
        );
        assert_eq!(name.split('-').count(), 4, "grip-<s>-<boot>-<pid>: {name}");
    }

    /// [`check`] refuses what [`run`] refuses at its start (a bad
    /// `recorder.toml`, an unreadable `--attach` file), naming the file and
    /// field, creates nothing, and passes the shipped configuration.
    #[test]
    fn check_refuses_what_the_start_refuses_and_creates_nothing() {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("never.mcap");
        let opts = |config_dir: &Path, attach: Vec<(String, PathBuf)>| Options {
            config: ConfigArgs::in_dir(config_dir),
            out: Some(out.clone()),
            meta: Vec::new(),
            attach,
        };
        check(&opts(&shipped, Vec::new())).unwrap();
        let text = std::fs::read_to_string(shipped.join("recorder.toml")).unwrap();
        let bad = text.replacen("poll_interval_ms = 2", "poll_interval_ms = -2", 1);
        assert_ne!(bad, text);
        std::fs::write(dir.path().join("recorder.toml"), bad).unwrap();
        let e = check(&opts(dir.path(), Vec::new())).unwrap_err();
        assert!(matches!(e, RunError::Config(_)), "{e:?}");
        let s = e.to_string();
        assert!(
            s.contains("recorder.toml: field `poll_interval_ms`") && s.contains("-2"),
            "{s}"
        );
        let e = check(&opts(
            &shipped,
            vec![("drive/vehicle.toml".into(), dir.path().join("gone.toml"))],
        ))
        .unwrap_err();
        assert!(
            e.to_string().starts_with("--attach drive/vehicle.toml="),
            "{e}"
        );
        assert!(!out.exists());
    }

    /// A panicked receive thread is an error naming the panic, not "0
    /// received, 0 dropped" and exit 0.
    #[test]
    fn a_panicked_receive_thread_is_an_error() {
        let h = std::thread::spawn(|| -> RecvStats { panic!("subscriber on fire") });
        let e = join_receiver(h).unwrap_err();
        assert!(matches!(e, RunError::ReceiveThread(_)), "{e:?}");
        let text = e.to_string();
        assert!(
            text.contains("receive thread panicked (subscriber on fire)"),
            "{text}"
        );
        let h = std::thread::spawn(|| -> RecvStats { panic!("{} errors", 3) });
        assert!(
            join_receiver(h)
                .unwrap_err()
                .to_string()
                .contains("(3 errors)")
        );
        let h = std::thread::spawn(|| {
            let mut s = RecvStats::default();
            s.topic(topics::CYCLE).received = 7;
            s
        });
        let s = join_receiver(h).unwrap();
        assert_eq!(s.topics[topics::CYCLE].received, 7);
    }
}
