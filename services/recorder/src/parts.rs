//! The log files of one run: [`Parts`] writes the messages into the
//! current part, starts a new part when rotation says so (without `--out`:
//! `max_file_mib`, `max_file_s`), and after a write error (a full disk)
//! stops writing, counts what it cannot write, and opens a new part again
//! at most every [`RETRY_EVERY`] once the free-space floor is met.
//!
//! Every part stands alone: a complete MCAP file (footer, summary) with the
//! run's `grip.run` metadata and attachments, the part's place in the run
//! (`part`, `part.previous`, `part.run_first`, `part.run_started_ns`) and
//! its own `grip.recorder` counters. The switch happens on the writing
//! thread between two messages: the queue from the receive thread holds
//! what arrives meanwhile, so no message is lost or written twice.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use grip_io::mcaplog::{McapLogError, McapWriter, McapWriterOptions, RunInfo, sha256_hex};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

use crate::cycle::{Msg, RECORDED, Summary, error_chain};
use crate::retention::Retention;
use crate::run::{ConfigFile, GIT_REV, config_files};
use crate::stats::{RecvStats, StatsTap};

/// Least time between two attempts to open a new part after a write
/// error (retention sweeps every 10 s as well).
pub const RETRY_EVERY: Duration = Duration::from_secs(10);
/// How often the size of the part being written is looked at (`fstat`).
pub const SIZE_CHECK_EVERY: Duration = Duration::from_millis(100);
/// Longest wait for the receive thread's counters when a part ends.
pub const TAP_WAIT: Duration = Duration::from_millis(200);
/// Least time between two warnings that recording cannot resume yet.
pub const STILL_FULL_WARN_EVERY: Duration = Duration::from_secs(60);

/// When a new part starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rotation {
    /// Bytes on disk (`None`: no size limit).
    pub max_bytes: Option<u64>,
    /// Recording time of a part.
    pub max_age: Duration,
}

/// What every part of a run carries: the `grip.run` record (hashes taken
/// once, at the run's start) and the files to attach.
#[derive(Debug, Clone)]
pub struct RunHead {
    /// `grip.run` without the part keys.
    pub info: RunInfo,
    /// Files to attach (each checked against its hash of the run's start
    /// when a part is opened).
    pub files: Vec<ConfigFile>,
    /// Whether every part has the bus log's channel (`grip/can/bus`: the
    /// recorder's `bus` is not "off").
    pub bus_log: bool,
}

impl RunHead {
    /// Hashes the configuration directory's files and `extra` (name in the
    /// log, path); files over `attach_max` are hashed only.
    pub fn gather(
        config_dir: &Path,
        attach_max: u64,
        meta: &[(String, String)],
        extra: &[(String, PathBuf)],
    ) -> Self {
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
        let extra = extra.iter().map(|(name, path)| ConfigFile {
            name: name.clone(),
            path: path.clone(),
            model: false,
        });
        let mut files = Vec::new();
        for f in config_files(config_dir).into_iter().chain(extra) {
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
                files.push(f);
            } else {
                info.extra.insert(
                    format!("not_attached.{}", f.name),
                    format!("{} bytes > attach_max_bytes", data.len()),
                );
            }
        }
        Self {
            info,
            files,
            bus_log: false,
        }
    }

    /// Writes `grip.run` (with `part` keys added) and the attachments. A
    /// file whose bytes changed since the run's start is not attached
    /// (`not_attached.<name>` says so): the hashes of `grip.run` stay those
    /// the run started with, in every part.
    pub fn write(
        &self,
        w: &mut McapWriter,
        part: &BTreeMap<String, String>,
    ) -> Result<(), McapLogError> {
        let mut info = self.info.clone();
        let mut attach = Vec::new();
        for f in &self.files {
            let want = if f.model {
                info.model_hashes.get(&f.name)
            } else {
                info.config_hashes.get(&f.name)
            };
            match std::fs::read(&f.path) {
                Ok(d) if want.is_some_and(|h| *h == sha256_hex(&d)) => attach.push((f, d)),
                Ok(_) => {
                    info.extra.insert(
                        format!("not_attached.{}", f.name),
                        "changed on disk since the run's start".into(),
                    );
                }
                Err(e) => {
                    info.extra.insert(
                        format!("not_attached.{}", f.name),
                        format!("unreadable since the run's start: {e}"),
                    );
                }
            }
        }
        for (k, v) in part {
            info.extra.insert(k.clone(), v.clone());
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
}

/// Opens a part: the file, every topic's channel, `grip.run` and the
/// attachments, a durable flush.
fn open_writer(
    path: &Path,
    opts: McapWriterOptions,
    head: &RunHead,
    part: &BTreeMap<String, String>,
) -> Result<McapWriter, McapLogError> {
    let mut w = McapWriter::create(path, opts)?;
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
    if head.bus_log {
        w.add_topic::<grip_msgs::BusFrame>(topics::BUS)?;
    }
    head.write(&mut w, part)?;
    w.flush()?;
    Ok(w)
}

/// The part being written.
#[derive(Debug)]
struct Part {
    w: McapWriter,
    index: u32,
    opened: Instant,
    next_size_check: Instant,
    written: BTreeMap<&'static str, u64>,
    /// Messages not written before this part (while not writing).
    not_written_before: BTreeMap<&'static str, u64>,
}

/// Where a new part's file comes from.
pub type NextPath = Box<dyn FnMut() -> std::io::Result<PathBuf>>;

/// The files of a run (see the module).
pub struct Parts {
    head: RunHead,
    opts: McapWriterOptions,
    rotation: Option<Rotation>,
    next_path: NextPath,
    retry_every: Duration,
    /// Free space to wait for before a new attempt after a write error
    /// (directory, bytes).
    floor: Option<(PathBuf, u64)>,
    cur: Option<Part>,
    parts: u32,
    first_name: String,
    last_name: String,
    run_started_ns: u128,
    /// Set while not writing (after a write error): since when.
    down_since: Option<Instant>,
    last_try: Option<Instant>,
    last_still_warn: Option<Instant>,
    not_written: BTreeMap<&'static str, u64>,
    tap: Option<Arc<StatsTap>>,
    high_water: Option<Arc<AtomicUsize>>,
    recv_before: RecvStats,
    /// Files finished (complete or not), in order.
    pub done: Vec<PathBuf>,
}

impl core::fmt::Debug for Parts {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Parts")
            .field("parts", &self.parts)
            .field(
                "current",
                &self.cur.as_ref().map(|p| p.w.path().to_path_buf()),
            )
            .field("down_since", &self.down_since)
            .finish()
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

impl Parts {
    /// Opens the first part at `first` (an error here fails the start).
    /// `rotation` `None`: one file (`--out`), never rotated nor reopened
    /// after a write error; `next_path` gives the files of the next parts.
    pub fn open(
        first: &Path,
        head: RunHead,
        opts: McapWriterOptions,
        rotation: Option<Rotation>,
        next_path: NextPath,
    ) -> Result<Self, McapLogError> {
        let run_started_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let mut me = Self {
            head,
            opts,
            rotation,
            next_path,
            retry_every: RETRY_EVERY,
            floor: None,
            cur: None,
            parts: 0,
            first_name: file_name(first),
            last_name: String::new(),
            run_started_ns,
            down_since: None,
            last_try: None,
            last_still_warn: None,
            not_written: BTreeMap::new(),
            tap: None,
            high_water: None,
            recv_before: RecvStats::default(),
            done: Vec::new(),
        };
        me.open_part(first, Instant::now())?;
        Ok(me)
    }

    /// After a write error, wait until `min_free` bytes are free in `dir`
    /// before opening a new part (0: try regardless).
    pub fn with_floor(mut self, dir: &Path, min_free: u64) -> Self {
        self.floor = (min_free > 0).then(|| (dir.to_path_buf(), min_free));
        self
    }

    /// Each part's `grip.recorder` gets the receive thread's counters of
    /// its time through `tap`.
    pub fn with_tap(mut self, tap: Arc<StatsTap>) -> Self {
        self.tap = Some(tap);
        self
    }

    /// Each part's `grip.recorder` gets the queue's high-water mark so far.
    pub fn with_high_water(mut self, high: Arc<AtomicUsize>) -> Self {
        self.high_water = Some(high);
        self
    }

    /// The least time between attempts to resume ([`RETRY_EVERY`]; tests
    /// shorten it).
    pub fn with_retry_every(mut self, every: Duration) -> Self {
        self.retry_every = every;
        self
    }

    /// The part's keys of `grip.run` (none for the one file of `--out`).
    fn part_keys(&self, index: u32) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        if self.rotation.is_none() {
            return m;
        }
        m.insert("part".into(), index.to_string());
        if index > 1 {
            m.insert("part.previous".into(), self.last_name.clone());
        }
        m.insert("part.run_first".into(), self.first_name.clone());
        m.insert(
            "part.run_started_ns".into(),
            self.run_started_ns.to_string(),
        );
        if !self.not_written.is_empty() {
            for (t, n) in &self.not_written {
                m.insert(format!("part.not_written_before.{t}"), n.to_string());
            }
        }
        m
    }

    fn open_part(&mut self, path: &Path, now: Instant) -> Result<(), McapLogError> {
        let index = self.parts + 1;
        let keys = self.part_keys(index);
        let w = open_writer(path, self.opts.clone(), &self.head, &keys)?;
        self.parts = index;
        self.last_name = file_name(path);
        self.cur = Some(Part {
            w,
            index,
            opened: now,
            next_size_check: now + SIZE_CHECK_EVERY,
            written: BTreeMap::new(),
            not_written_before: std::mem::take(&mut self.not_written),
        });
        Ok(())
    }

    /// The part being written (`None` while not writing).
    pub fn current(&self) -> Option<&Path> {
        self.cur.as_ref().map(|p| p.w.path())
    }

    /// Parts opened so far.
    pub fn count(&self) -> u32 {
        self.parts
    }

    /// How long the last durable flush took.
    pub fn last_flush_took(&self) -> Duration {
        self.cur
            .as_ref()
            .map(|p| p.w.last_flush_took())
            .unwrap_or_default()
    }

    /// Writes `m` into the current part, or counts it as not written.
    pub fn write(&mut self, m: &Msg, summary: &mut Summary) {
        let Some(p) = self.cur.as_mut() else {
            *self.not_written.entry(m.topic()).or_default() += 1;
            *summary.not_written.entry(m.topic()).or_default() += 1;
            return;
        };
        match m.write_to(&mut p.w) {
            Ok(()) => {
                *p.written.entry(m.topic()).or_default() += 1;
                *summary.written.entry(m.topic()).or_default() += 1;
            }
            Err(e) => {
                // handed to the part's writer like the rest of its last
                // chunk: whether it reached the disk depends on where the
                // write failed (often the flush after it); counted as
                // written, `not_written` counts only what came while no
                // part was open
                *p.written.entry(m.topic()).or_default() += 1;
                *summary.written.entry(m.topic()).or_default() += 1;
                self.fail("MCAP write failed", &e, summary);
            }
        }
    }

    /// No message came for a while: the durable flush if due.
    pub fn idle(&mut self, summary: &mut Summary) {
        if let Some(p) = self.cur.as_mut()
            && let Err(e) = p.w.maybe_flush()
        {
            self.fail("MCAP flush failed", &e, summary);
        }
    }

    /// A write failed: the part is finished as far as it can be, writing
    /// stops until [`Parts::tick`] opens a new part.
    fn fail(&mut self, what: &str, e: &McapLogError, summary: &mut Summary) {
        summary.write_errors += 1;
        let now = Instant::now();
        self.down_since = Some(now);
        self.last_try = Some(now);
        let again = if self.rotation.is_some() {
            "recording stops until a new log file can be written (tried at most every 10 s once min_free_mib is free)"
        } else {
            "recording stopped (--out: one file, not reopened); messages are now discarded and counted"
        };
        tracing::error!(error = %error_chain(e), "{what}: {again}");
        if let Some(p) = self.cur.take() {
            let path = p.w.path().to_path_buf();
            // what can still be finished: its counters, the summary, the
            // footer (the mcap writer refuses every write after a failed
            // one, so this fails in practice: the file then ends where the
            // write failed, as after a crash)
            match self.close(p, summary) {
                Ok(()) => {
                    tracing::info!(file = %path.display(), "the failed log file was finished after all")
                }
                Err(e) => {
                    tracing::warn!(file = %path.display(), error = %error_chain(&e), "the failed log file could not be finished: it ends where the write failed (grip inspect reads it up to there)")
                }
            }
            self.done.push(path);
        }
    }

    fn high_water(&self) -> usize {
        self.high_water
            .as_ref()
            .map(|h| h.load(Ordering::Relaxed))
            .unwrap_or(0)
    }

    /// Writes the part's `grip.recorder` and finishes it.
    fn close(&mut self, p: Part, summary: &Summary) -> Result<(), McapLogError> {
        let recv = self.tap.as_ref().and_then(|t| t.take(TAP_WAIT)).map(|now| {
            let part = now.since(&self.recv_before);
            self.recv_before = now;
            part
        });
        let mut w = p.w;
        let high = self.high_water();
        let mut meta = part_metadata(summary, recv.as_ref(), &p.written, high);
        meta.insert("part".into(), p.index.to_string());
        for (t, n) in &p.not_written_before {
            meta.insert(format!("{t}.not_written_before"), n.to_string());
        }
        w.write_metadata("grip.recorder", &meta)?;
        w.finish()
    }

    /// Between messages: a new part when the current one is full or old
    /// enough; after a write error, an attempt to resume when due.
    /// `retention` learns of every new part (never deleted while written).
    pub fn tick(&mut self, now: Instant, summary: &mut Summary, retention: Option<&mut Retention>) {
        let Some(rot) = self.rotation else {
            return;
        };
        if let Some(p) = self.cur.as_mut() {
            let old = now.duration_since(p.opened) >= rot.max_age;
            let mut full = false;
            if let Some(max) = rot.max_bytes
                && now >= p.next_size_check
            {
                p.next_size_check = now + SIZE_CHECK_EVERY;
                full = p.w.file_len().is_ok_and(|n| n >= max);
            }
            if old || full {
                self.rotate(
                    if full { "max_file_mib" } else { "max_file_s" },
                    summary,
                    retention,
                );
            }
            return;
        }
        // not writing: try again when due and the floor is met
        if self
            .last_try
            .is_some_and(|t| now.duration_since(t) < self.retry_every)
        {
            return;
        }
        self.last_try = Some(now);
        if let Some((dir, min_free)) = &self.floor {
            match crate::retention::free_bytes(dir) {
                Ok(free) if free < *min_free => {
                    self.still_down(
                        now,
                        &format!(
                            "{} MiB free, less than min_free_mib ({} MiB)",
                            free >> 20,
                            min_free >> 20
                        ),
                    );
                    return;
                }
                _ => {}
            }
        }
        let path = match (self.next_path)() {
            Ok(p) => p,
            Err(e) => {
                self.still_down(now, &format!("no new log file: {e}"));
                return;
            }
        };
        match self.open_part(&path, now) {
            Ok(()) => {
                let down = self.down_since.take().map(|t| now.duration_since(t));
                let lost: u64 = self
                    .cur
                    .as_ref()
                    .map(|p| p.not_written_before.values().sum())
                    .unwrap_or(0);
                let per_topic = self
                    .cur
                    .as_ref()
                    .map(|p| {
                        p.not_written_before
                            .iter()
                            .map(|(t, n)| format!("{t}={n}"))
                            .collect::<Vec<_>>()
                            .join(" ")
                    })
                    .unwrap_or_default();
                tracing::info!(
                    file = %path.display(),
                    part = self.parts,
                    not_written = lost,
                    per_topic = %per_topic,
                    down_s = down.unwrap_or_default().as_secs_f64(),
                    "recording resumed in a new log file (the messages not written meanwhile are counted in its grip.run and grip.recorder)"
                );
                if let Some(r) = retention {
                    r.set_current(&path);
                }
                self.last_still_warn = None;
            }
            Err(e) => {
                // an empty or partial file of ours: not left behind
                let _ = std::fs::remove_file(&path);
                self.still_down(now, &error_chain(&e));
            }
        }
    }

    fn still_down(&mut self, now: Instant, why: &str) {
        if self
            .last_still_warn
            .is_some_and(|t| now.duration_since(t) < STILL_FULL_WARN_EVERY)
        {
            return;
        }
        self.last_still_warn = Some(now);
        let lost: u64 = self.not_written.values().sum();
        tracing::warn!(
            reason = why,
            not_written = lost,
            down_s = self
                .down_since
                .map(|t| now.duration_since(t).as_secs_f64())
                .unwrap_or(0.0),
            "not recording yet: a new log file cannot be written (tried every 10 s, said at most once a minute)"
        );
    }

    fn rotate(
        &mut self,
        why: &'static str,
        summary: &mut Summary,
        retention: Option<&mut Retention>,
    ) {
        let Some(p) = self.cur.take() else {
            return;
        };
        let old = p.w.path().to_path_buf();
        let index = p.index;
        let t0 = Instant::now();
        if let Err(e) = self.close(p, summary) {
            // the part stays as far as its last durable flush
            self.done.push(old);
            let now = Instant::now();
            self.down_since = Some(now);
            self.last_try = Some(now);
            summary.write_errors += 1;
            tracing::error!(error = %error_chain(&e), "finishing the log file failed: recording stops until a new log file can be written");
            return;
        }
        self.done.push(old.clone());
        let now = Instant::now();
        let next = (self.next_path)().map_err(|error| McapLogError::Io {
            path: old.clone(),
            error,
        });
        let opened = next.and_then(|path| {
            self.open_part(&path, now)
                .map(|()| path.clone())
                .inspect_err(|_| {
                    // an empty or partial file of ours: not left behind
                    let _ = std::fs::remove_file(&path);
                })
        });
        match opened {
            Ok(path) => {
                tracing::info!(
                    finished = %old.display(),
                    file = %path.display(),
                    part = index + 1,
                    reason = why,
                    took_ms = t0.elapsed().as_secs_f64() * 1e3,
                    "log file rotated: a new part of this run"
                );
                if let Some(r) = retention {
                    r.set_current(&path);
                }
            }
            Err(e) => {
                self.down_since = Some(now);
                self.last_try = Some(now);
                summary.write_errors += 1;
                tracing::error!(finished = %old.display(), error = %error_chain(&e), "cannot open the next log file: recording stops until a new log file can be written (tried at most every 10 s)");
            }
        }
    }

    /// Ends the run: the current part (if any) gets its counters (the
    /// receive thread's final ones, `recv_final`) and is finished.
    pub fn finish(
        mut self,
        recv_final: Option<&RecvStats>,
        summary: &Summary,
    ) -> Result<Vec<PathBuf>, McapLogError> {
        self.tap = None;
        let Some(p) = self.cur.take() else {
            return Ok(self.done);
        };
        let path = p.w.path().to_path_buf();
        let mut w = p.w;
        let part = recv_final.map(|r| r.since(&self.recv_before));
        let high = self.high_water().max(summary.queue_high_water);
        let mut meta = part_metadata(summary, part.as_ref(), &p.written, high);
        if self.rotation.is_some() || p.index > 1 {
            meta.insert("part".into(), p.index.to_string());
        }
        for (t, n) in &p.not_written_before {
            meta.insert(format!("{t}.not_written_before"), n.to_string());
        }
        // without the receive thread's counters the record would claim
        // nothing was received: none is written
        let r = if part.is_some() {
            w.write_metadata("grip.recorder", &meta)
                .and_then(|()| w.finish())
        } else {
            w.finish()
        };
        self.done.push(path);
        r.map(|()| self.done)
    }
}

/// A part's `grip.recorder`: the receive side's counters of its time (none
/// when they could not be had), the messages written into it, the queue's
/// high-water mark and the write errors of the run so far.
fn part_metadata(
    summary: &Summary,
    recv: Option<&RecvStats>,
    written: &BTreeMap<&'static str, u64>,
    queue_high_water: usize,
) -> BTreeMap<String, String> {
    let s = Summary {
        path: PathBuf::new(),
        recv: recv.cloned().unwrap_or_default(),
        written: written.clone(),
        not_written: BTreeMap::new(),
        queue_high_water,
        write_errors: summary.write_errors,
    };
    let mut m = s.metadata();
    if recv.is_none() {
        for t in RECORDED {
            for k in [
                "received",
                "queue_dropped",
                "receive_errors",
                "seq_gaps",
                "seq_gap_events",
                "seq_resets",
            ] {
                m.remove(&format!("{t}.{k}"));
            }
        }
        m.remove(&format!("{}.counter_gaps", topics::CAN_LOG));
        m.remove(&format!("{}.counter_repeats", topics::CAN_LOG));
        m.insert(
            "receive_counters".into(),
            "not available: the receive thread did not answer in time".into(),
        );
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::mcaplog::{LogMessage, McapLog};
    use std::cell::RefCell;
    use std::rc::Rc;

    fn cycle(seq: u64) -> Msg {
        let mut c = CycleRecord::zeroed();
        c.seq = seq;
        c.stamp_ns = 1_000_000 + seq * 1000;
        c.omega = seq as f64 * 0.25;
        Msg::Cycle(c)
    }

    fn head(dir: &Path) -> RunHead {
        std::fs::write(dir.join("a.toml"), "x = 1\n").unwrap();
        RunHead::gather(dir, 1 << 20, &[("scenario".into(), "unit".into())], &[])
    }

    /// The next paths: `dev_full` marks an attempt that cannot be written
    /// (a symbolic link to `/dev/full`: every write fails with ENOSPC).
    fn paths(dir: &Path, plan: Vec<bool>) -> (NextPath, Rc<RefCell<usize>>) {
        let dir = dir.to_path_buf();
        let n = Rc::new(RefCell::new(0usize));
        let calls = Rc::clone(&n);
        let f = move || {
            let mut k = calls.borrow_mut();
            *k += 1;
            let p = dir.join(format!("part-{k}.mcap"));
            if plan.get(*k - 1).copied().unwrap_or(false) {
                std::os::unix::fs::symlink("/dev/full", &p)?;
            }
            Ok(p)
        };
        (Box::new(f), n)
    }

    fn seqs(p: &Path) -> Vec<u64> {
        let (m, rep) = McapLog::open(p).unwrap().messages().unwrap();
        assert!(
            rep.truncated.is_none() && rep.bad == 0,
            "{}: {rep:?}",
            p.display()
        );
        m.iter()
            .filter_map(|e| match &e.msg {
                LogMessage::Cycle(c) => Some(c.seq),
                _ => None,
            })
            .collect()
    }

    fn run_meta(p: &Path, name: &str) -> BTreeMap<String, String> {
        McapLog::open(p)
            .unwrap()
            .metadata()
            .unwrap()
            .into_iter()
            .find(|(n, _)| n == name)
            .map(|(_, m)| m)
            .unwrap_or_else(|| panic!("{}: no {name}", p.display()))
    }

    /// A size limit: parts of about that size, each complete, every
    /// message once across them and in order.
    #[test]
    fn a_full_part_is_followed_by_a_new_one_without_loss() {
        let t = tempfile::tempdir().unwrap();
        let (next, _) = paths(t.path(), vec![]);
        let opts = McapWriterOptions {
            chunk_size: 16 * 1024,
            ..McapWriterOptions::default()
        };
        let rot = Rotation {
            max_bytes: Some(64 * 1024),
            max_age: Duration::from_secs(3600),
        };
        let first = t.path().join("part-0.mcap");
        let mut parts = Parts::open(&first, head(t.path()), opts, Some(rot), next).unwrap();
        let mut s = Summary::default();
        let mut now = Instant::now();
        for k in 0..20_000 {
            parts.write(&cycle(k), &mut s);
            if k % 100 == 0 {
                // the writer's flushes come with time; here every 100 messages
                parts.cur.as_mut().unwrap().w.flush().unwrap();
                now += SIZE_CHECK_EVERY;
                parts.tick(now, &mut s, None);
            }
        }
        let files = parts.finish(None, &s).unwrap();
        assert!(files.len() >= 4, "{files:?}");
        let mut all = Vec::new();
        for (i, f) in files.iter().enumerate() {
            let len = std::fs::metadata(f).unwrap().len();
            assert!(len < 64 * 1024 + 32 * 1024, "{}: {len} bytes", f.display());
            let run = run_meta(f, "grip.run");
            assert_eq!(run["part"], (i + 1).to_string());
            assert_eq!(run["scenario"], "unit");
            assert!(run.contains_key("config.a.toml"));
            all.extend(seqs(f));
        }
        assert_eq!(all, (0..20_000).collect::<Vec<u64>>());
        assert_eq!(s.write_errors, 0);
    }

    /// A part that cannot be written (ENOSPC): writing stops, what comes
    /// meanwhile is counted per topic, attempts follow at most every
    /// `retry_every`, and the first part that can be written again says
    /// what was lost before it.
    #[test]
    fn after_a_write_error_recording_resumes_in_a_new_part_and_counts_the_loss() {
        let t = tempfile::tempdir().unwrap();
        // part 2 and the first retry fail, the second retry works
        let (next, calls) = paths(t.path(), vec![true, true, false]);
        let rot = Rotation {
            max_bytes: None,
            max_age: Duration::from_secs(1),
        };
        let first = t.path().join("part-0.mcap");
        let mut parts = Parts::open(
            &first,
            head(t.path()),
            McapWriterOptions::default(),
            Some(rot),
            next,
        )
        .unwrap()
        .with_retry_every(Duration::from_secs(10));
        let mut s = Summary::default();
        let t0 = Instant::now();
        for k in 0..100 {
            parts.write(&cycle(k), &mut s);
        }
        // one second: a new part, which cannot be written
        parts.tick(t0 + Duration::from_secs(1), &mut s, None);
        assert!(parts.current().is_none(), "not writing");
        assert_eq!(s.write_errors, 1);
        for k in 100..150 {
            parts.write(&cycle(k), &mut s);
        }
        // not before retry_every; then a failed attempt; then a good one
        parts.tick(t0 + Duration::from_secs(5), &mut s, None);
        assert_eq!(*calls.borrow(), 1, "no attempt within 10 s");
        parts.tick(t0 + Duration::from_secs(12), &mut s, None);
        assert_eq!(*calls.borrow(), 2);
        assert!(parts.current().is_none());
        assert!(
            !t.path().join("part-2.mcap").exists(),
            "the failed attempt is not left behind"
        );
        for k in 150..170 {
            parts.write(&cycle(k), &mut s);
        }
        parts.tick(t0 + Duration::from_secs(22), &mut s, None);
        assert_eq!(
            parts.current(),
            Some(t.path().join("part-3.mcap").as_path())
        );
        for k in 170..200 {
            parts.write(&cycle(k), &mut s);
        }
        let files = parts.finish(Some(&RecvStats::default()), &s).unwrap();
        assert_eq!(s.not_written[topics::CYCLE], 70);
        assert_eq!(s.written[topics::CYCLE], 130);
        let first_seqs = seqs(&first);
        assert_eq!(first_seqs, (0..100).collect::<Vec<u64>>());
        let last = files.last().unwrap();
        assert_eq!(seqs(last), (170..200).collect::<Vec<u64>>());
        let run = run_meta(last, "grip.run");
        // parts count the files written: the attempts that failed are not
        // parts (and are gone)
        assert_eq!(run["part"], "2", "{run:?}");
        assert_eq!(
            run[&format!("part.not_written_before.{}", topics::CYCLE)],
            "70"
        );
        assert_eq!(run["part.previous"], "part-0.mcap");
        assert!(!t.path().join("part-1.mcap").exists());
        assert_eq!(files, vec![first.clone(), last.clone()]);
        let rec = run_meta(last, "grip.recorder");
        assert_eq!(rec[&format!("{}.not_written_before", topics::CYCLE)], "70");
        assert_eq!(rec[&format!("{}.written", topics::CYCLE)], "30");
        assert_eq!(rec["write_errors"], "1");
    }

    /// `--out`: one file; a write error is not followed by another file.
    #[test]
    fn one_file_is_never_rotated_nor_reopened() {
        let t = tempfile::tempdir().unwrap();
        let (next, calls) = paths(t.path(), vec![]);
        let first = t.path().join("out.mcap");
        let mut parts = Parts::open(
            &first,
            head(t.path()),
            McapWriterOptions::default(),
            None,
            next,
        )
        .unwrap();
        let mut s = Summary::default();
        let t0 = Instant::now();
        for k in 0..10 {
            parts.write(&cycle(k), &mut s);
            parts.tick(t0 + Duration::from_secs(100_000 * (k + 1)), &mut s, None);
        }
        assert_eq!(*calls.borrow(), 0);
        assert_eq!(parts.finish(None, &s).unwrap(), vec![first.clone()]);
        assert_eq!(seqs(&first), (0..10).collect::<Vec<u64>>());
        assert!(!run_meta(&first, "grip.run").contains_key("part"));
    }
}
