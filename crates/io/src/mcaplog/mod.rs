//! MCAP logs: [`McapWriter`] for the recorder, [`McapLog`] to read them back
//! (grip inspect, replay, tests).
//!
//! Format: one schema per payload type (JSON Schema, named by the versioned
//! type name, e.g. `grip::CycleRecord::v2`), one channel per topic,
//! `message_encoding = "json"`, log time = the payload's CLOCK_MONOTONIC
//! stamp. Metadata record `grip.clock` relates that clock to wall time.
//! Chunks are compressed with lz4 (default) or single-threaded zstd.
//!
//! Durability: [`McapWriter::flush`] finishes the open chunk (so a reader can
//! read everything before it, without the summary), flushes the buffer and
//! `fdatasync`s the file. `write` calls it by itself once `flush_interval`
//! (default 1 s) has passed since the last flush, and the recorder calls
//! [`McapWriter::maybe_flush`] when idle, so a crash loses at most about one
//! interval. A log cut off that way is read by [`McapLog`] up to the last
//! complete chunk and reported as truncated. A damaged part inside a log (a
//! chunk or attachment whose CRC fails, any record whose fields do not
//! check) is left out and named in the report; the rest is read
//! (`damage.rs`).
//!
//! Never write MCAP from a real-time thread: a write may compress a chunk
//! (~0.25 ms lz4) or fsync.

mod damage;
pub mod json;

pub use damage::{Skipped, SkippedKind, first_damage};

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use grip_msgs::{AudioBlock, BusFrame, CanFrame, CycleRecord, GroundTruth, RoadEstimate};
pub use json::{JsonError, McapRecord};
use mcap::records::{MessageHeader, Record, op};

/// MCAP errors. Each says its reason in its message and returns no
/// [`source`](std::error::Error::source): a service prints the message
/// alone, and a caller that prints the chain (`{:#}` of an `anyhow::Error`)
/// would otherwise say the reason twice.
#[derive(Debug, thiserror::Error)]
pub enum McapLogError {
    /// File system error.
    #[error("{path}: {error}")]
    Io {
        /// File.
        path: PathBuf,
        /// Error.
        error: std::io::Error,
    },
    /// mcap crate error (with its causes: the crate's I/O error names none
    /// in its own message).
    #[error("{path}: MCAP error: {}", error_chain(error))]
    Mcap {
        /// File.
        path: PathBuf,
        /// Error.
        error: mcap::McapError,
    },
    /// The file does not start with the MCAP magic bytes.
    #[error("{path}: not an MCAP file (magic bytes missing)")]
    NotMcap {
        /// File.
        path: PathBuf,
    },
    /// A topic was already registered with another schema.
    #[error("topic {topic:?} already carries {existing}, cannot log {requested} on it")]
    TopicTypeClash {
        /// Topic.
        topic: String,
        /// Registered schema.
        existing: &'static str,
        /// Requested schema.
        requested: &'static str,
    },
}

/// `e` and every error under it (`source()`), joined with ": ", a cause
/// whose message already ends the text left out. The mcap crate's I/O
/// error says only "I/O error from writing, or reading a compression
/// stream"; the cause a reader needs ("No space left on device (os error
/// 28)") is its source. The one home: [`McapLogError::Mcap`]'s message and
/// the recorder's log lines.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        let t = c.to_string();
        if !s.ends_with(&t) {
            s.push_str(": ");
            s.push_str(&t);
        }
        cur = c.source();
    }
    s
}

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// No compression (fastest, largest).
    None,
    /// LZ4 frame (default: 1.8 M msg/s, worst write 0.25 ms here).
    #[default]
    Lz4,
    /// Zstandard, single-threaded (`compression_threads(0)`: the threaded
    /// default stalls writes 5-16 ms on this machine).
    Zstd,
}

/// Writer options.
#[derive(Debug, Clone, PartialEq)]
pub struct McapWriterOptions {
    /// Chunk compression.
    pub compression: Compression,
    /// Target uncompressed chunk size, bytes.
    pub chunk_size: u64,
    /// Longest time between durable flushes.
    pub flush_interval: Duration,
}

impl Default for McapWriterOptions {
    fn default() -> Self {
        Self {
            compression: Compression::Lz4,
            chunk_size: 512 * 1024,
            flush_interval: Duration::from_secs(1),
        }
    }
}

/// Run description written as the `grip.run` metadata record.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RunInfo {
    /// grip version (`CARGO_PKG_VERSION` of the tool).
    pub version: String,
    /// `git rev-parse HEAD` of the build, or "unknown".
    pub git_revision: String,
    /// sha256 of each configuration file, by name.
    pub config_hashes: BTreeMap<String, String>,
    /// sha256 of each model file, by name.
    pub model_hashes: BTreeMap<String, String>,
    /// Anything else (scenario, controller, command line).
    pub extra: BTreeMap<String, String>,
}

/// Hex sha256 of `bytes` (grip-digest's, the one digest of grip; kept here
/// for the writers of [`RunInfo`]).
pub use grip_digest::sha256_hex;

/// The file under the mcap writer: a buffered writer; fsync happens in
/// [`McapWriter::flush`] through a second handle, never behind mcap's back.
struct LogFile(BufWriter<File>);
impl Write for LogFile {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}
impl Seek for LogFile {
    fn seek(&mut self, p: SeekFrom) -> std::io::Result<u64> {
        self.0.seek(p)
    }
}

struct Channel {
    id: u16,
    schema: &'static str,
    seq: u32,
}

/// MCAP writer for the grip payloads (not for real-time threads).
pub struct McapWriter {
    w: Option<mcap::Writer<LogFile>>,
    sync: File,
    path: PathBuf,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, Channel>,
    buf: Vec<u8>,
    opts: McapWriterOptions,
    last_flush: Instant,
    flush_took: Duration,
    messages: u64,
}

impl core::fmt::Debug for McapWriter {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("McapWriter")
            .field("path", &self.path)
            .field("messages", &self.messages)
            .finish()
    }
}

impl McapWriter {
    /// Creates (truncates) `path` and writes the header and the `grip.clock`
    /// metadata record.
    pub fn create(path: impl AsRef<Path>, opts: McapWriterOptions) -> Result<Self, McapLogError> {
        let monotonic_ns = crate::clock::monotonic_now_ns();
        let realtime_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        Self::create_with_clock(path, opts, monotonic_ns, realtime_ns)
    }

    /// [`McapWriter::create`] with the `grip.clock` stamps given rather than
    /// read from the clocks: a log whose bytes do not depend on when, or on
    /// which machine, it was written (its layout shifts with the number of
    /// digits of `monotonic_ns`, i.e. with the machine's uptime).
    pub fn create_with_clock(
        path: impl AsRef<Path>,
        opts: McapWriterOptions,
        monotonic_ns: u64,
        realtime_ns: u128,
    ) -> Result<Self, McapLogError> {
        let path = path.as_ref().to_path_buf();
        let io = |error| McapLogError::Io {
            path: path.clone(),
            error,
        };
        let file = File::create(&path).map_err(io)?;
        let sync = file.try_clone().map_err(io)?;
        let mut wo = mcap::WriteOptions::new()
            .profile("")
            .library(concat!("grip-io ", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(opts.chunk_size));
        wo = match opts.compression {
            Compression::None => wo.compression(None),
            Compression::Lz4 => wo.compression(Some(mcap::Compression::Lz4)),
            Compression::Zstd => wo
                .compression(Some(mcap::Compression::Zstd))
                .compression_threads(0),
        };
        let w = wo
            .create(LogFile(BufWriter::with_capacity(256 * 1024, file)))
            .map_err(|error| McapLogError::Mcap {
                path: path.clone(),
                error,
            })?;
        let mut me = Self {
            w: Some(w),
            sync,
            path,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            buf: Vec::with_capacity(16 * 1024),
            opts,
            last_flush: Instant::now(),
            flush_took: Duration::ZERO,
            messages: 0,
        };
        let mut clock = BTreeMap::new();
        clock.insert("monotonic_ns".into(), monotonic_ns.to_string());
        clock.insert("realtime_ns".into(), realtime_ns.to_string());
        clock.insert(
            "note".into(),
            "log times are CLOCK_MONOTONIC ns; wall = log_time - monotonic_ns + realtime_ns".into(),
        );
        me.write_metadata("grip.clock", &clock)?;
        Ok(me)
    }

    fn mcap_err(&self, error: mcap::McapError) -> McapLogError {
        McapLogError::Mcap {
            path: self.path.clone(),
            error,
        }
    }

    fn writer(&mut self) -> &mut mcap::Writer<LogFile> {
        // `w` is only None after finish(), which consumes self
        self.w.as_mut().expect("writer present until finish")
    }

    /// Registers `topic` for payload `T` (done automatically on first write).
    pub fn add_topic<T: McapRecord>(&mut self, topic: &str) -> Result<(), McapLogError> {
        if let Some(c) = self.channels.get(topic) {
            if c.schema != T::SCHEMA_NAME {
                return Err(McapLogError::TopicTypeClash {
                    topic: topic.into(),
                    existing: c.schema,
                    requested: T::SCHEMA_NAME,
                });
            }
            return Ok(());
        }
        let sid = match self.schemas.get(T::SCHEMA_NAME) {
            Some(&s) => s,
            None => {
                let data = serde_json::to_vec_pretty(&T::json_schema()).unwrap_or_default();
                let s = self
                    .writer()
                    .add_schema(T::SCHEMA_NAME, "jsonschema", &data)
                    .map_err(|e| self.mcap_err(e))?;
                self.schemas.insert(T::SCHEMA_NAME, s);
                s
            }
        };
        let id = self
            .writer()
            .add_channel(sid, topic, "json", &BTreeMap::new())
            .map_err(|e| self.mcap_err(e))?;
        self.channels.insert(
            topic.into(),
            Channel {
                id,
                schema: T::SCHEMA_NAME,
                seq: 0,
            },
        );
        Ok(())
    }

    /// Logs `msg` on `topic` at its own stamp.
    pub fn write<T: McapRecord>(&mut self, topic: &str, msg: &T) -> Result<(), McapLogError> {
        self.write_at(topic, msg.stamp_ns(), msg)
    }

    /// Logs `msg` on `topic` with log time `log_time_ns`.
    pub fn write_at<T: McapRecord>(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        msg: &T,
    ) -> Result<(), McapLogError> {
        if !self.channels.contains_key(topic) {
            self.add_topic::<T>(topic)?;
        }
        let (id, seq) = match self.channels.get_mut(topic) {
            Some(c) if c.schema == T::SCHEMA_NAME => {
                c.seq = c.seq.wrapping_add(1);
                (c.id, c.seq)
            }
            Some(c) => {
                return Err(McapLogError::TopicTypeClash {
                    topic: topic.into(),
                    existing: c.schema,
                    requested: T::SCHEMA_NAME,
                });
            }
            None => unreachable!("channel registered above"),
        };
        let mut buf = core::mem::take(&mut self.buf);
        buf.clear();
        msg.write_json(&mut buf);
        let header = MessageHeader {
            channel_id: id,
            sequence: seq,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        let r = self.writer().write_to_known_channel(&header, &buf);
        self.buf = buf;
        r.map_err(|e| self.mcap_err(e))?;
        self.messages += 1;
        self.maybe_flush()?;
        Ok(())
    }

    /// Writes a metadata record (finishes the current chunk).
    pub fn write_metadata(
        &mut self,
        name: &str,
        map: &BTreeMap<String, String>,
    ) -> Result<(), McapLogError> {
        let m = mcap::records::Metadata {
            name: name.into(),
            metadata: map.clone(),
        };
        self.writer()
            .write_metadata(&m)
            .map_err(|e| self.mcap_err(e))
    }

    /// Writes the `grip.run` metadata record: version, git revision, config
    /// and model hashes (keys `config.<name>`, `model.<name>`), extras.
    pub fn write_run_info(&mut self, info: &RunInfo) -> Result<(), McapLogError> {
        let mut m = BTreeMap::new();
        m.insert("version".into(), info.version.clone());
        m.insert("git_revision".into(), info.git_revision.clone());
        for (k, v) in &info.config_hashes {
            m.insert(format!("config.{k}"), v.clone());
        }
        for (k, v) in &info.model_hashes {
            m.insert(format!("model.{k}"), v.clone());
        }
        for (k, v) in &info.extra {
            m.insert(k.clone(), v.clone());
        }
        self.write_metadata("grip.run", &m)
    }

    /// Attaches bytes (config file, DBC, model).
    pub fn attach_bytes(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
    ) -> Result<(), McapLogError> {
        let t = crate::clock::monotonic_now_ns();
        let a = mcap::Attachment {
            log_time: t,
            create_time: t,
            name: name.into(),
            media_type: media_type.into(),
            data: std::borrow::Cow::Borrowed(data),
        };
        self.writer().attach(&a).map_err(|e| self.mcap_err(e))
    }

    /// Attaches a file under its file name; returns its sha256 (hex).
    pub fn attach_file(&mut self, path: &Path, media_type: &str) -> Result<String, McapLogError> {
        let data = std::fs::read(path).map_err(|error| McapLogError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| path.display().to_string());
        self.attach_bytes(&name, media_type, &data)?;
        Ok(sha256_hex(&data))
    }

    /// Durable flush: finish the chunk, flush buffers, fdatasync.
    pub fn flush(&mut self) -> Result<(), McapLogError> {
        let start = Instant::now();
        self.writer().flush().map_err(|e| self.mcap_err(e))?;
        self.sync.sync_data().map_err(|error| McapLogError::Io {
            path: self.path.clone(),
            error,
        })?;
        self.last_flush = Instant::now();
        self.flush_took = self.last_flush - start;
        Ok(())
    }

    /// How long the last durable flush took (finishing the chunk, writing
    /// it, `fdatasync`); zero before the first.
    pub fn last_flush_took(&self) -> Duration {
        self.flush_took
    }

    /// Flushes if `flush_interval` has passed since the last flush; returns
    /// whether it did.
    pub fn maybe_flush(&mut self) -> Result<bool, McapLogError> {
        if self.last_flush.elapsed() >= self.opts.flush_interval {
            self.flush()?;
            Ok(true)
        } else {
            Ok(false)
        }
    }

    /// Bytes of the file on disk now (`fstat`): what the last flushes
    /// wrote, not the open chunk nor the write buffer (the recorder's
    /// `max_file_mib` is checked against this).
    pub fn file_len(&self) -> Result<u64, McapLogError> {
        self.sync
            .metadata()
            .map(|m| m.len())
            .map_err(|error| McapLogError::Io {
                path: self.path.clone(),
                error,
            })
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Messages written.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes the summary and footer and syncs the file.
    pub fn finish(mut self) -> Result<(), McapLogError> {
        if let Some(mut w) = self.w.take() {
            w.finish().map_err(|e| self.mcap_err(e))?;
            let mut f = w.into_inner();
            f.flush().map_err(|error| McapLogError::Io {
                path: self.path.clone(),
                error,
            })?;
        }
        self.sync.sync_all().map_err(|error| McapLogError::Io {
            path: self.path.clone(),
            error,
        })
    }
}

// ------------------------------------------------------------- reading ----

/// A decoded grip payload.
#[derive(Debug, Clone, PartialEq)]
pub enum LogMessage {
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
    /// A frame of the vehicle bus (channel `grip/can/bus`).
    Bus(BusFrame),
}

/// One message of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct LogEntry {
    /// Topic (channel).
    pub topic: String,
    /// Log time, ns.
    pub log_time_ns: u64,
    /// Channel sequence number.
    pub sequence: u32,
    /// Payload.
    pub msg: LogMessage,
}

/// What a read found besides the messages.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReadReport {
    /// Messages decoded.
    pub messages: u64,
    /// Messages on channels whose schema is not a grip payload (skipped).
    pub foreign: u64,
    /// Messages whose JSON did not decode, with the first error.
    pub bad: u64,
    /// First decode error.
    pub first_error: Option<String>,
    /// The log was not read whole: why, in one line. The damaged parts
    /// skipped, counted by kind, with their byte ranges ([`Self::skipped`]);
    /// messages lost with the channel that defined them
    /// ([`Self::unlinked`]); where reading stopped early ([`Self::stopped`]).
    /// `None`: every part of the file was read.
    pub truncated: Option<String>,
    /// The damaged parts left out, in file order; reading went on after
    /// each (each one is a hole in the log).
    pub skipped: Vec<Skipped>,
    /// Reading stopped before the end of the file (a crash-truncated tail,
    /// a length damaged beyond repair, no footer): where and why.
    pub stopped: Option<String>,
    /// Messages whose channel or schema was defined only in a skipped part
    /// (not read: their topic and type are unknown).
    pub unlinked: u64,
}

impl ReadReport {
    /// Chunks skipped.
    pub fn skipped_chunks(&self) -> usize {
        self.skipped
            .iter()
            .filter(|s| s.kind == SkippedKind::Chunk)
            .count()
    }

    /// Attachments skipped.
    pub fn skipped_attachments(&self) -> usize {
        self.skipped
            .iter()
            .filter(|s| matches!(s.kind, SkippedKind::Attachment { .. }))
            .count()
    }

    /// The one line of [`Self::truncated`].
    fn damage_line(&self) -> Option<String> {
        /// Skipped parts listed one by one; the rest are counted.
        const LISTED: usize = 4;
        let mut parts = Vec::new();
        if !self.skipped.is_empty() {
            let n = self.skipped.len();
            let (chunks, atts) = (self.skipped_chunks(), self.skipped_attachments());
            let mut kinds = Vec::new();
            let plural = |n: usize, one: &str, many: &str| {
                format!("{n} {}", if n == 1 { one } else { many })
            };
            if chunks > 0 {
                kinds.push(plural(chunks, "chunk", "chunks"));
            }
            if atts > 0 {
                kinds.push(plural(atts, "attachment", "attachments"));
            }
            if n > chunks + atts {
                kinds.push(plural(n - chunks - atts, "other record", "other records"));
            }
            let mut list: Vec<String> = self
                .skipped
                .iter()
                .take(LISTED)
                .map(|s| s.to_string())
                .collect();
            if n > LISTED {
                list.push(format!("and {} more", n - LISTED));
            }
            parts.push(format!(
                "{} skipped ({}), the rest read: {}",
                plural(n, "damaged part", "damaged parts"),
                kinds.join(", "),
                list.join("; ")
            ));
        }
        if self.unlinked > 0 {
            parts.push(format!(
                "{} messages not read: their channel was defined in a skipped part",
                self.unlinked
            ));
        }
        if let Some(s) = &self.stopped {
            parts.push(s.clone());
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

/// Key-value map of a metadata record.
pub type MetadataMap = BTreeMap<String, String>;

/// An attachment read back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogAttachment {
    /// Name.
    pub name: String,
    /// Media type.
    pub media_type: String,
    /// Bytes.
    pub data: Vec<u8>,
}

/// A whole MCAP file in memory.
#[derive(Debug)]
pub struct McapLog {
    /// The file's bytes.
    data: Vec<u8>,
    path: PathBuf,
    /// Its records that read and its damaged parts; `None`: not MCAP.
    scan: Option<damage::Scan>,
}

/// Schemas and channels as the messages refer to them: those read so far
/// in the data, then, for what a skipped part defined, those outside chunks
/// (the summary repeats every schema and channel of a finished file).
#[derive(Default)]
struct Links {
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, (String, u16)>,
    spare_schemas: HashMap<u16, String>,
    spare_channels: HashMap<u16, (String, u16)>,
}

impl Links {
    /// Adds a schema or channel record (the first of an id wins).
    fn add(&mut self, rec: &Record<'_>, spare: bool) {
        let (schemas, channels) = if spare {
            (&mut self.spare_schemas, &mut self.spare_channels)
        } else {
            (&mut self.schemas, &mut self.channels)
        };
        match rec {
            Record::Schema { header, .. } => {
                schemas
                    .entry(header.id)
                    .or_insert_with(|| header.name.clone());
            }
            Record::Channel(c) => {
                channels
                    .entry(c.id)
                    .or_insert_with(|| (c.topic.clone(), c.schema_id));
            }
            _ => {}
        }
    }

    /// Topic and schema name of channel `id` (schema "" for none).
    fn resolve(&self, id: u16) -> Option<(&str, &str)> {
        let (topic, sid) = self.channels.get(&id).or(self.spare_channels.get(&id))?;
        let schema = match sid {
            0 => "",
            s => self.schemas.get(s).or(self.spare_schemas.get(s))?,
        };
        Some((topic, schema))
    }
}

fn decode(schema: &str, data: &[u8]) -> Result<Option<LogMessage>, String> {
    let v: serde_json::Value = serde_json::from_slice(data).map_err(|e| e.to_string())?;
    let m = match schema {
        AudioBlock::TYPE_NAME => LogMessage::Audio(Box::new(
            AudioBlock::from_json(&v).map_err(|e| e.to_string())?,
        )),
        RoadEstimate::TYPE_NAME => {
            LogMessage::Road(RoadEstimate::from_json(&v).map_err(|e| e.to_string())?)
        }
        CycleRecord::TYPE_NAME => {
            LogMessage::Cycle(CycleRecord::from_json(&v).map_err(|e| e.to_string())?)
        }
        CanFrame::TYPE_NAME => LogMessage::Can(CanFrame::from_json(&v).map_err(|e| e.to_string())?),
        GroundTruth::TYPE_NAME => {
            LogMessage::Truth(GroundTruth::from_json(&v).map_err(|e| e.to_string())?)
        }
        BusFrame::TYPE_NAME => LogMessage::Bus(BusFrame::from_json(&v).map_err(|e| e.to_string())?),
        _ => return Ok(None),
    };
    Ok(Some(m))
}

impl McapLog {
    /// Reads `path` into memory and finds its damaged parts (`damage.rs`):
    /// a damaged chunk, attachment or other record is left out and the
    /// rest read ([`ReadReport::skipped`]); at a crash-truncated tail, or a
    /// length damaged beyond repair, reading stops
    /// ([`ReadReport::stopped`]). [`ReadReport::truncated`] says both.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, McapLogError> {
        let path = path.as_ref().to_path_buf();
        let data = std::fs::read(&path).map_err(|error| McapLogError::Io {
            path: path.clone(),
            error,
        })?;
        Ok(Self::from_bytes(data, path))
    }

    /// A log from the bytes of a file already in memory, as [`McapLog::open`]
    /// reads it; `path` names the file in errors.
    pub fn from_bytes(data: Vec<u8>, path: impl Into<PathBuf>) -> Self {
        let scan = damage::scan(&data);
        Self {
            data,
            path: path.into(),
            scan,
        }
    }

    /// The damaged parts left out, in file order (also in every
    /// [`ReadReport`]); empty for a file that is not MCAP.
    pub fn skipped(&self) -> &[Skipped] {
        self.scan.as_ref().map_or(&[], |s| &s.skipped)
    }

    fn body(&self, r: &damage::Rec) -> &[u8] {
        &self.data[r.body.0..r.body.1]
    }

    /// Calls `f` for every grip message in file order. Damaged parts are
    /// left out and reading stops quietly at a truncated end (both in
    /// [`ReadReport::truncated`]); a file that is not MCAP at all is an
    /// error.
    pub fn for_each(&self, mut f: impl FnMut(LogEntry)) -> Result<ReadReport, McapLogError> {
        let Some(scan) = &self.scan else {
            return Err(McapLogError::NotMcap {
                path: self.path.clone(),
            });
        };
        let mut rep = ReadReport::default();
        let mut links = Links::default();
        for r in &scan.records {
            if matches!(r.op, op::SCHEMA | op::CHANNEL)
                && let Ok(rec) = mcap::parse_record(r.op, self.body(r))
            {
                links.add(&rec, true);
            }
        }
        let mut handle = |rec: Record<'_>| {
            let Record::Message { header, data } = rec else {
                links.add(&rec, false);
                return;
            };
            let Some((topic, schema)) = links.resolve(header.channel_id) else {
                rep.unlinked += 1;
                return;
            };
            match decode(schema, &data) {
                Ok(Some(msg)) => {
                    rep.messages += 1;
                    f(LogEntry {
                        topic: topic.to_owned(),
                        log_time_ns: header.log_time,
                        sequence: header.sequence,
                        msg,
                    });
                }
                Ok(None) => rep.foreign += 1,
                Err(e) => {
                    rep.bad += 1;
                    if rep.first_error.is_none() {
                        rep.first_error = Some(format!("topic {topic}: {e}"));
                    }
                }
            }
        };
        let mut skipped = scan.skipped.clone();
        for r in &scan.records {
            let body = self.body(r);
            match r.op {
                op::CHUNK => {
                    // checked when opened, so this does not fail
                    let read = damage::for_each_in_chunk(body, |o, b| {
                        handle(mcap::parse_record(o, b).map_err(|e| e.to_string())?);
                        Ok(())
                    });
                    if let Err(reason) = read {
                        skipped.push(Skipped {
                            kind: SkippedKind::Chunk,
                            start: (r.body.0 - damage::HEAD) as u64,
                            end: r.body.1 as u64,
                            log_time_ns: None,
                            reason,
                        });
                    }
                }
                op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                    if let Ok(rec) = mcap::parse_record(r.op, body) {
                        handle(rec);
                    }
                }
                _ => {}
            }
        }
        skipped.sort_by_key(|s| s.start);
        rep.skipped = skipped;
        rep.stopped = match &scan.stop {
            Some((off, why)) => Some(format!("read up to byte {off}: {why}")),
            None if !scan.finished => Some("no footer: the writer did not finish (crash?)".into()),
            None => None,
        };
        rep.truncated = rep.damage_line();
        Ok(rep)
    }

    /// All grip messages, with the report.
    pub fn messages(&self) -> Result<(Vec<LogEntry>, ReadReport), McapLogError> {
        let mut v = Vec::new();
        let rep = self.for_each(|e| v.push(e))?;
        Ok((v, rep))
    }

    /// Calls `f` with every top-level record of type `opcode` that reads.
    fn records(&self, opcode: u8, mut f: impl FnMut(Record<'_>)) -> Result<(), McapLogError> {
        for r in self.scan.iter().flat_map(|s| &s.records) {
            if r.op == opcode
                && let Ok(rec) = mcap::parse_record(r.op, self.body(r))
            {
                f(rec);
            }
        }
        Ok(())
    }

    /// Metadata records (name, map), in file order.
    pub fn metadata(&self) -> Result<Vec<(String, MetadataMap)>, McapLogError> {
        let mut v = Vec::new();
        self.records(op::METADATA, |r| {
            if let Record::Metadata(m) = r {
                v.push((m.name, m.metadata));
            }
        })?;
        Ok(v)
    }

    /// Attachments, in file order (a damaged one is left out and named in
    /// [`McapLog::skipped`]).
    pub fn attachments(&self) -> Result<Vec<LogAttachment>, McapLogError> {
        let mut v = Vec::new();
        self.records(op::ATTACHMENT, |r| {
            if let Record::Attachment { header, data, .. } = r {
                v.push(LogAttachment {
                    name: header.name,
                    media_type: header.media_type,
                    data: data.into_owned(),
                });
            }
        })?;
        Ok(v)
    }
}
