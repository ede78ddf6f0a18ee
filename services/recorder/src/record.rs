//! The recorder: a receive thread drains every deep subscriber into a
//! bounded queue (never blocking: a full queue drops and counts), and the
//! writing thread (the caller of [`run`]) turns the queue into MCAP.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_config::{ConfigDir, ConfigError};
use grip_io::ipc::{IpcError, IpcNode, PeerReport, Subscriber, SubscriberMode};
use grip_io::mcaplog::{McapLogError, McapWriter, RunInfo, sha256_hex};
use grip_io::systemd::{self, Watchdog, WatchdogPoll};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

use crate::config::RecorderConfig;
use crate::stats::{RecvStats, TopicStats};

/// The grip revision this binary was built from (build.rs).
pub const GIT_REV: &str = env!("GRIP_GIT_REV");

/// Command-line choices (see `main.rs`).
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Shared configuration directory (attached and hashed).
    pub config_dir: PathBuf,
    /// The service's own TOML (default `<config_dir>/recorder.toml`).
    pub config: Option<PathBuf>,
    /// Output file (default: `<out_dir>/grip-<unix s>-<pid>.mcap`).
    pub out: Option<PathBuf>,
    /// Extra `grip.run` metadata (scenario, controller, ...).
    pub meta: Vec<(String, String)>,
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
    /// The output directory.
    #[error("{path}: cannot create the log directory: {source}")]
    OutDir {
        /// Directory.
        path: PathBuf,
        /// Error.
        source: std::io::Error,
    },
    /// A thread could not be started.
    #[error("cannot start the receive thread: {0}")]
    Thread(std::io::Error),
}

/// One message on its way to the file.
#[derive(Debug, Clone)]
pub enum Msg {
    /// Audio block (boxed: 8 KiB).
    Audio(Box<AudioBlock>),
    /// Road estimate.
    Road(RoadEstimate),
    /// Cycle record.
    Cycle(CycleRecord),
    /// CAN frame.
    Can(CanFrame),
    /// Ground truth.
    Truth(GroundTruth),
}

impl Msg {
    /// The topic it belongs to.
    pub fn topic(&self) -> &'static str {
        match self {
            Msg::Audio(_) => topics::AUDIO,
            Msg::Road(_) => topics::ROAD,
            Msg::Cycle(_) => topics::CYCLE,
            Msg::Can(_) => topics::CAN_LOG,
            Msg::Truth(_) => topics::TRUTH,
        }
    }

    /// Writes it to `w` on its topic at its own stamp.
    pub fn write_to(&self, w: &mut McapWriter) -> Result<(), McapLogError> {
        match self {
            Msg::Audio(m) => w.write(topics::AUDIO, m.as_ref()),
            Msg::Road(m) => w.write(topics::ROAD, m),
            Msg::Cycle(m) => w.write(topics::CYCLE, m),
            Msg::Can(m) => w.write(topics::CAN_LOG, m),
            Msg::Truth(m) => w.write(topics::TRUTH, m),
        }
    }
}

/// The deep subscribers, one per entry of `topics::ALL`.
#[derive(Debug)]
pub struct Subscribers {
    audio: Subscriber<AudioBlock>,
    road: Subscriber<RoadEstimate>,
    cycle: Subscriber<CycleRecord>,
    can: Subscriber<CanFrame>,
    truth: Subscriber<GroundTruth>,
}

/// The topics [`Subscribers`] covers, in `topics::ALL` order.
pub const RECORDED: [&str; 5] = [
    topics::AUDIO,
    topics::ROAD,
    topics::CYCLE,
    topics::CAN_LOG,
    topics::TRUTH,
];

impl Subscribers {
    /// Opens a deep subscriber on every topic.
    pub fn open(node: &IpcNode) -> Result<Self, IpcError> {
        Ok(Self {
            audio: node.subscriber(topics::AUDIO, SubscriberMode::Deep)?,
            road: node.subscriber(topics::ROAD, SubscriberMode::Deep)?,
            cycle: node.subscriber(topics::CYCLE, SubscriberMode::Deep)?,
            can: node.subscriber(topics::CAN_LOG, SubscriberMode::Deep)?,
            truth: node.subscriber(topics::TRUTH, SubscriberMode::Deep)?,
        })
    }

    /// Peer reports per topic.
    pub fn peers(&self) -> [(&'static str, PeerReport); 5] {
        [
            (topics::AUDIO, self.audio.peers()),
            (topics::ROAD, self.road.peers()),
            (topics::CYCLE, self.cycle.peers()),
            (topics::CAN_LOG, self.can.peers()),
            (topics::TRUTH, self.truth.peers()),
        ]
    }
}

/// The bounded queue's sending side with its counters.
#[derive(Debug)]
pub struct Queue {
    tx: SyncSender<Msg>,
    depth: Arc<AtomicUsize>,
    high_water: Arc<AtomicUsize>,
}

/// Creates the queue (capacity in messages).
pub fn queue(capacity: usize) -> (Queue, Receiver<Msg>, Arc<AtomicUsize>, Arc<AtomicUsize>) {
    let (tx, rx) = sync_channel(capacity);
    let depth = Arc::new(AtomicUsize::new(0));
    let high = Arc::new(AtomicUsize::new(0));
    (
        Queue {
            tx,
            depth: Arc::clone(&depth),
            high_water: Arc::clone(&high),
        },
        rx,
        depth,
        high,
    )
}

impl Queue {
    /// Enqueues without blocking; false if full (or the writer is gone).
    pub fn offer(&self, m: Msg) -> bool {
        // count first: the writer may take the message (and decrement)
        // before try_send returns
        let d = self.depth.fetch_add(1, Ordering::Relaxed).wrapping_add(1);
        match self.tx.try_send(m) {
            Ok(()) => {
                self.high_water.fetch_max(d, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.depth.fetch_sub(1, Ordering::Relaxed);
                false
            }
        }
    }
}

fn account(st: &mut TopicStats, seq: Option<u64>, queued: bool) {
    st.received += 1;
    if let Some(s) = seq {
        st.seq.push(s);
    }
    if !queued {
        st.queue_dropped += 1;
    }
}

/// One pass over every subscriber: moves what is waiting (at most `max`
/// per topic) into the queue, counting gaps and drops. Returns the number
/// of messages taken.
pub fn receive_pass(subs: &Subscribers, q: &Queue, stats: &mut RecvStats, max: usize) -> usize {
    let mut n = 0;
    macro_rules! pass {
        ($sub:expr, $topic:expr, $seq:expr, $wrap:expr) => {{
            for _ in 0..max {
                match $sub.recv() {
                    Ok(Some(m)) => {
                        let seq: Option<u64> = $seq(&m);
                        let queued = q.offer($wrap(m));
                        account(stats.topic($topic), seq, queued);
                        n += 1;
                    }
                    Ok(None) => break,
                    Err(_) => {
                        stats.topic($topic).receive_errors += 1;
                        break;
                    }
                }
            }
        }};
    }
    pass!(
        subs.cycle,
        topics::CYCLE,
        |m: &CycleRecord| Some(m.seq),
        Msg::Cycle
    );
    // CAN: alive counters tracked separately (no sequence number)
    for _ in 0..max {
        match subs.can.recv() {
            Ok(Some(f)) => {
                stats.can.push(&f);
                let queued = q.offer(Msg::Can(f));
                account(stats.topic(topics::CAN_LOG), None, queued);
                n += 1;
            }
            Ok(None) => break,
            Err(_) => {
                stats.topic(topics::CAN_LOG).receive_errors += 1;
                break;
            }
        }
    }
    pass!(
        subs.truth,
        topics::TRUTH,
        |m: &GroundTruth| Some(m.seq),
        Msg::Truth
    );
    pass!(
        subs.road,
        topics::ROAD,
        |m: &RoadEstimate| Some(m.seq),
        Msg::Road
    );
    pass!(
        subs.audio,
        topics::AUDIO,
        |m: &AudioBlock| Some(m.seq),
        |m| Msg::Audio(Box::new(m))
    );
    n
}

/// What a recording did.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// The log file.
    pub path: PathBuf,
    /// Receive-side counters.
    pub recv: RecvStats,
    /// Messages written per topic.
    pub written: BTreeMap<&'static str, u64>,
    /// Largest queue depth seen.
    pub queue_high_water: usize,
    /// Write errors (the first one ends writing).
    pub write_errors: u64,
}

impl Summary {
    /// Metadata map of the `grip.recorder` record.
    pub fn metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        for t in RECORDED {
            let s = self.recv.topics.get(t).copied().unwrap_or_default();
            let w = self.written.get(t).copied().unwrap_or(0);
            m.insert(format!("{t}.received"), s.received.to_string());
            m.insert(format!("{t}.written"), w.to_string());
            m.insert(format!("{t}.queue_dropped"), s.queue_dropped.to_string());
            m.insert(format!("{t}.receive_errors"), s.receive_errors.to_string());
            if t != topics::CAN_LOG {
                m.insert(format!("{t}.seq_gaps"), s.seq.gaps.to_string());
                m.insert(format!("{t}.seq_gap_events"), s.seq.gap_events.to_string());
                m.insert(format!("{t}.seq_resets"), s.seq.resets.to_string());
            }
        }
        m.insert(
            format!("{}.counter_gaps", topics::CAN_LOG),
            self.recv.can.gaps.to_string(),
        );
        m.insert(
            format!("{}.counter_repeats", topics::CAN_LOG),
            self.recv.can.repeats.to_string(),
        );
        m.insert("queue_high_water".into(), self.queue_high_water.to_string());
        m.insert("write_errors".into(), self.write_errors.to_string());
        m
    }
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
/// everything in `models/`. Sorted by name; unreadable directories are
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
    scan("models", None, true);
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// Writes `grip.run` (version, git revision, hashes, extras) and attaches
/// the configuration files.
pub fn write_run_info(
    w: &mut McapWriter,
    config_dir: &Path,
    attach_max: u64,
    meta: &[(String, String)],
) -> Result<(), McapLogError> {
    let mut info = RunInfo {
        version: env!("CARGO_PKG_VERSION").into(),
        git_revision: GIT_REV.into(),
        ..RunInfo::default()
    };
    info.extra
        .insert("config_dir".into(), config_dir.display().to_string());
    for (k, v) in meta {
        info.extra.insert(k.clone(), v.clone());
    }
    let mut attach = Vec::new();
    for f in config_files(config_dir) {
        let data = match std::fs::read(&f.path) {
            Ok(d) => d,
            Err(e) => {
                tracing::warn!(file = %f.path.display(), error = %e, "cannot read config file; not attached");
                continue;
            }
        };
        let h = sha256_hex(&data);
        if f.model {
            info.model_hashes.insert(f.name.clone(), h);
        } else {
            info.config_hashes.insert(f.name.clone(), h);
        }
        if data.len() as u64 <= attach_max {
            attach.push((f, data));
        } else {
            info.extra.insert(
                format!("not_attached.{}", f.name),
                format!("{} bytes > attach_max_bytes", data.len()),
            );
        }
    }
    w.write_run_info(&info)?;
    for (f, data) in attach {
        let media = match f.path.extension().and_then(|e| e.to_str()) {
            Some("toml") => "application/toml",
            Some("json") => "application/json",
            Some("csv") => "text/csv",
            Some("dbc") => "text/plain",
            _ => "application/octet-stream",
        };
        w.attach_bytes(&f.name, media, &data)?;
    }
    Ok(())
}

/// Default log path in `dir`.
pub fn default_out(dir: &Path) -> PathBuf {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    dir.join(format!("grip-{secs}-{}.mcap", std::process::id()))
}

/// Starts the receive thread: it creates the iceoryx2 node and the deep
/// subscribers itself (iceoryx2 ports are not `Send`), reports the outcome
/// through `ready`, then drains into the queue until `stop`, and finally
/// drains once more.
fn spawn_receiver(
    q: Queue,
    stop: Arc<AtomicBool>,
    poll: Duration,
    heartbeat: Arc<AtomicU64>,
    ready: SyncSender<Result<(), IpcError>>,
) -> std::io::Result<JoinHandle<RecvStats>> {
    std::thread::Builder::new()
        .name("recorder-rx".into())
        .spawn(move || {
            let mut stats = RecvStats::default();
            for t in RECORDED {
                stats.topic(t);
            }
            let opened = IpcNode::create(topics::node::RECORDER)
                .and_then(|node| Subscribers::open(&node).map(|s| (node, s)));
            let (_node, subs) = match opened {
                Ok(x) => {
                    let _ = ready.send(Ok(()));
                    x
                }
                Err(e) => {
                    let _ = ready.send(Err(e));
                    return stats;
                }
            };
            let mut last_peers = Instant::now();
            let mut publishers: BTreeMap<&'static str, (usize, usize)> = BTreeMap::new();
            while !stop.load(Ordering::Relaxed) {
                let n = receive_pass(&subs, &q, &mut stats, 4096);
                heartbeat.fetch_add(1, Ordering::Relaxed);
                if n == 0 {
                    std::thread::sleep(poll);
                }
                if last_peers.elapsed() >= Duration::from_secs(1) {
                    last_peers = Instant::now();
                    for (t, p) in subs.peers() {
                        let prev = publishers.insert(t, (p.publishers, p.dead));
                        if prev.is_some_and(|(np, nd)| np != p.publishers || nd != p.dead) {
                            if p.dead > 0 {
                                tracing::warn!(
                                    topic = t,
                                    publishers = p.publishers,
                                    dead_nodes = p.dead,
                                    "a peer of this topic died"
                                );
                            } else {
                                tracing::info!(
                                    topic = t,
                                    publishers = p.publishers,
                                    "publishers changed"
                                );
                            }
                        }
                    }
                }
            }
            // drain what is still waiting in the subscribers
            while receive_pass(&subs, &q, &mut stats, 4096) > 0 {}
            stats
        })
}

/// Runs the recorder until `stop` (SIGTERM/SIGINT): opens the subscribers
/// and the file, writes `grip.run` and the attachments, sends `READY=1`,
/// records; on stop drains what is queued, writes the `grip.recorder`
/// summary metadata and finishes the file.
pub fn run(opts: &Options, stop: &Arc<AtomicBool>) -> Result<Summary, RunError> {
    let dir = ConfigDir::new(&opts.config_dir);
    let own = opts
        .config
        .clone()
        .unwrap_or_else(|| dir.file("recorder.toml"));
    let cfg = RecorderConfig::load(&own)?;
    let path = match &opts.out {
        Some(p) => p.clone(),
        None => {
            std::fs::create_dir_all(&cfg.out_dir).map_err(|source| RunError::OutDir {
                path: cfg.out_dir.clone(),
                source,
            })?;
            default_out(&cfg.out_dir)
        }
    };
    let mut w = McapWriter::create(&path, cfg.writer_options())?;
    for t in grip_msgs::topics::ALL {
        match t.0 {
            x if x == topics::AUDIO => w.add_topic::<AudioBlock>(x)?,
            x if x == topics::ROAD => w.add_topic::<RoadEstimate>(x)?,
            x if x == topics::CYCLE => w.add_topic::<CycleRecord>(x)?,
            x if x == topics::CAN_LOG => w.add_topic::<CanFrame>(x)?,
            x if x == topics::TRUTH => w.add_topic::<GroundTruth>(x)?,
            other => tracing::warn!(topic = other, "topic not known to the recorder"),
        }
    }
    write_run_info(&mut w, &opts.config_dir, cfg.attach_max_bytes, &opts.meta)?;
    w.flush()?;

    let (q, rx, depth, high) = queue(cfg.queue_capacity);
    let rx_stop = Arc::new(AtomicBool::new(false));
    let rx_beat = Arc::new(AtomicU64::new(0));
    let (ready_tx, ready_rx) = sync_channel(1);
    let handle = spawn_receiver(
        q,
        Arc::clone(&rx_stop),
        cfg.poll_interval(),
        Arc::clone(&rx_beat),
        ready_tx,
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

    systemd::notify_ready(&format!("recording to {}", path.display()));
    tracing::info!(file = %path.display(), git = GIT_REV, "recorder ready");

    let mut wd = Watchdog::from_env(rx_beat.load(Ordering::Relaxed));
    // the longest wait for a message: the watchdog is polled at least this
    // often (half its period, at most 50 ms), so a short WatchdogSec works
    let wait = wd.tick();
    let mut summary = Summary {
        path: path.clone(),
        ..Summary::default()
    };
    let mut failed = false;
    let mut stopping = false;
    loop {
        if !stopping && stop.load(Ordering::Relaxed) {
            stopping = true;
            rx_stop.store(true, Ordering::Relaxed);
            systemd::notify_stopping();
        }
        match rx.recv_timeout(wait) {
            Ok(m) => {
                depth.fetch_sub(1, Ordering::Relaxed);
                if !failed {
                    match m.write_to(&mut w) {
                        Ok(()) => *summary.written.entry(m.topic()).or_default() += 1,
                        Err(e) => {
                            summary.write_errors += 1;
                            failed = true;
                            tracing::error!(error = %e, "MCAP write failed: recording stopped (messages are now discarded)");
                        }
                    }
                } else {
                    summary.write_errors += 1;
                }
            }
            Err(RecvTimeoutError::Timeout) => {
                if !failed && let Err(e) = w.maybe_flush() {
                    summary.write_errors += 1;
                    failed = true;
                    tracing::error!(error = %e, "MCAP flush failed: recording stopped");
                }
            }
            Err(RecvTimeoutError::Disconnected) => break,
        }
        // fed only while both the receive thread and this loop advance
        let beat = rx_beat.load(Ordering::Relaxed);
        if wd.poll(beat, Instant::now()) == WatchdogPoll::Stalled {
            tracing::warn!(
                heartbeat = beat,
                "recorder receive thread stalled: watchdog not fed"
            );
        }
    }
    summary.recv = handle.join().unwrap_or_default();
    summary.queue_high_water = high.load(Ordering::Relaxed);
    if !failed {
        w.write_metadata("grip.recorder", &summary.metadata())?;
        w.finish()?;
    }
    let total_rx: u64 = summary.recv.topics.values().map(|s| s.received).sum();
    let total_w: u64 = summary.written.values().sum();
    let gaps: u64 = summary.recv.topics.values().map(|s| s.seq.gaps).sum();
    let dropped: u64 = summary.recv.topics.values().map(|s| s.queue_dropped).sum();
    tracing::info!(
        file = %path.display(),
        received = total_rx,
        written = total_w,
        seq_gaps = gaps,
        can_counter_gaps = summary.recv.can.gaps,
        queue_dropped = dropped,
        queue_high_water = summary.queue_high_water,
        write_errors = summary.write_errors,
        "recorder stopped"
    );
    if failed {
        return Err(RunError::Mcap(McapLogError::Io {
            path,
            source: std::io::Error::other("a write failed during the recording (see above)"),
        }));
    }
    Ok(summary)
}
