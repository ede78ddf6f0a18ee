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
//! complete chunk and reported as truncated.
//!
//! Never write MCAP from a real-time thread: a write may compress a chunk
//! (~0.25 ms lz4) or fsync.

mod damage;
pub mod json;

pub use damage::first_damage;

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate};
pub use json::{JsonError, McapRecord};
use mcap::records::MessageHeader;

/// MCAP errors.
#[derive(Debug, thiserror::Error)]
pub enum McapLogError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Error.
        source: std::io::Error,
    },
    /// mcap crate error.
    #[error("{path}: MCAP error: {source}")]
    Mcap {
        /// File.
        path: PathBuf,
        /// Error.
        source: mcap::McapError,
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
        let path = path.as_ref().to_path_buf();
        let io = |source| McapLogError::Io {
            path: path.clone(),
            source,
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
            .map_err(|source| McapLogError::Mcap {
                path: path.clone(),
                source,
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
        clock.insert(
            "monotonic_ns".into(),
            crate::clock::monotonic_now_ns().to_string(),
        );
        let wall = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        clock.insert("realtime_ns".into(), wall.to_string());
        clock.insert(
            "note".into(),
            "log times are CLOCK_MONOTONIC ns; wall = log_time - monotonic_ns + realtime_ns".into(),
        );
        me.write_metadata("grip.clock", &clock)?;
        Ok(me)
    }

    fn mcap_err(&self, source: mcap::McapError) -> McapLogError {
        McapLogError::Mcap {
            path: self.path.clone(),
            source,
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
        let data = std::fs::read(path).map_err(|source| McapLogError::Io {
            path: path.to_path_buf(),
            source,
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
        self.sync.sync_data().map_err(|source| McapLogError::Io {
            path: self.path.clone(),
            source,
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

    /// Messages written.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes the summary and footer and syncs the file.
    pub fn finish(mut self) -> Result<(), McapLogError> {
        if let Some(mut w) = self.w.take() {
            w.finish().map_err(|e| self.mcap_err(e))?;
            let mut f = w.into_inner();
            f.flush().map_err(|source| McapLogError::Io {
                path: self.path.clone(),
                source,
            })?;
        }
        self.sync.sync_all().map_err(|source| McapLogError::Io {
            path: self.path.clone(),
            source,
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
    /// Reading stopped early (truncated file, e.g. after a crash): why.
    pub truncated: Option<String>,
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
    /// The file's bytes up to the first damage ([`first_damage`]).
    data: Vec<u8>,
    path: PathBuf,
    /// Where and why the file was cut short on opening.
    damage: Option<String>,
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
        _ => return Ok(None),
    };
    Ok(Some(m))
}

impl McapLog {
    /// Reads `path` into memory, up to its first damaged record or chunk
    /// (a crash-truncated tail, an implausible chunk header, a chunk whose
    /// CRC fails): what follows is not read, and [`ReadReport::truncated`]
    /// says where and why.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, McapLogError> {
        let path = path.as_ref().to_path_buf();
        let data = std::fs::read(&path).map_err(|source| McapLogError::Io {
            path: path.clone(),
            source,
        })?;
        Ok(Self::from_bytes(data, path))
    }

    /// A log from the bytes of a file already in memory, as [`McapLog::open`]
    /// reads it; `path` names the file in errors.
    pub fn from_bytes(mut data: Vec<u8>, path: impl Into<PathBuf>) -> Self {
        let path = path.into();
        let damage = if data.starts_with(mcap::MAGIC) {
            first_damage(&data).map(|(off, why)| {
                data.truncate(off);
                format!("read up to byte {off}: {why}")
            })
        } else {
            None
        };
        Self { data, path, damage }
    }

    /// Calls `f` for every grip message in file order. Stops quietly at a
    /// truncated end (reported in [`ReadReport::truncated`]); a file that is
    /// not MCAP at all is an error.
    pub fn for_each(&self, mut f: impl FnMut(LogEntry)) -> Result<ReadReport, McapLogError> {
        let mut rep = ReadReport::default();
        if !self.data.starts_with(mcap::MAGIC) {
            return Err(McapLogError::NotMcap {
                path: self.path.clone(),
            });
        }
        let opts = mcap::read::Options::IgnoreEndMagic.into();
        let stream = mcap::MessageStream::new_with_options(&self.data, opts).map_err(|source| {
            McapLogError::Mcap {
                path: self.path.clone(),
                source,
            }
        })?;
        for m in stream {
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    rep.truncated = Some(e.to_string());
                    break;
                }
            };
            let schema = m
                .channel
                .schema
                .as_ref()
                .map(|s| s.name.as_str())
                .unwrap_or("");
            match decode(schema, &m.data) {
                Ok(Some(msg)) => {
                    rep.messages += 1;
                    f(LogEntry {
                        topic: m.channel.topic.clone(),
                        log_time_ns: m.log_time,
                        sequence: m.sequence,
                        msg,
                    });
                }
                Ok(None) => rep.foreign += 1,
                Err(e) => {
                    rep.bad += 1;
                    if rep.first_error.is_none() {
                        rep.first_error = Some(format!("topic {}: {e}", m.channel.topic));
                    }
                }
            }
        }
        if let Some(d) = &self.damage {
            rep.truncated = Some(d.clone());
        } else if rep.truncated.is_none() && mcap::read::footer(&self.data).is_err() {
            rep.truncated = Some("no footer: the writer did not finish (crash?)".into());
        }
        Ok(rep)
    }

    /// All grip messages, with the report.
    pub fn messages(&self) -> Result<(Vec<LogEntry>, ReadReport), McapLogError> {
        let mut v = Vec::new();
        let rep = self.for_each(|e| v.push(e))?;
        Ok((v, rep))
    }

    fn records(&self, mut f: impl FnMut(mcap::records::Record<'_>)) -> Result<(), McapLogError> {
        let opts = mcap::read::Options::IgnoreEndMagic.into();
        let r = mcap::read::LinearReader::new_with_options(&self.data, opts).map_err(|source| {
            McapLogError::Mcap {
                path: self.path.clone(),
                source,
            }
        })?;
        for rec in r {
            match rec {
                Ok(rec) => f(rec),
                Err(_) => break, // truncated tail
            }
        }
        Ok(())
    }

    /// Metadata records (name, map), in file order.
    pub fn metadata(&self) -> Result<Vec<(String, MetadataMap)>, McapLogError> {
        let mut v = Vec::new();
        self.records(|r| {
            if let mcap::records::Record::Metadata(m) = r {
                v.push((m.name, m.metadata));
            }
        })?;
        Ok(v)
    }

    /// Attachments, in file order.
    pub fn attachments(&self) -> Result<Vec<LogAttachment>, McapLogError> {
        let mut v = Vec::new();
        self.records(|r| {
            if let mcap::records::Record::Attachment { header, data, .. } = r {
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
