//! A drive's MCAP log in memory, typed: every payload (audio samples only
//! when asked, [`DriveLog::load_with`]; else audio is counted), the run and
//! recorder metadata, every metadata record, the attachments. A damaged
//! file reads all it can (a damaged chunk or attachment skipped, the rest
//! read; a cut-off tail up to the cut: [`McapLog::open`]'s tolerance) and
//! says what was left out in [`DriveLog::report`]. Shared by `grip drive` (its summary),
//! `grip inspect`, `grip replay` and the tests.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use grip_io::mcaplog::{LogMessage, McapLog, McapLogError, MetadataMap, ReadReport};
use grip_msgs::{AudioBlock, BusFrame, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

/// A log that cannot be read at all (missing, unreadable, not MCAP):
/// "reading PATH: reason", the path and the reason said once. The reason
/// is in the message and not returned as the
/// [`source`](std::error::Error::source) (`{:#}` of an `anyhow::Error`
/// would print it twice).
#[derive(Debug)]
pub struct LogError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub error: McapLogError,
}

impl std::fmt::Display for LogError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let path = self.path.display().to_string();
        let why = self.error.to_string();
        // the reader's errors name their file first: once is enough
        let why = why
            .strip_prefix(path.as_str())
            .and_then(|w| w.strip_prefix(": "))
            .unwrap_or(&why);
        write!(f, "reading {path}: {why}")
    }
}

impl std::error::Error for LogError {}

impl LogError {
    /// "reading PATH: reason" (its message).
    pub fn full(&self) -> String {
        self.to_string()
    }
}

/// What to keep beyond the default.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Keep every audio block ([`DriveLog::audio_blocks`]; 8 KiB each).
    pub audio: bool,
}

/// What the audio topic carried (samples are not kept).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AudioInfo {
    /// Blocks.
    pub blocks: u64,
    /// Samples in all blocks.
    pub samples: u64,
    /// Sample rate of the last block, Hz.
    pub sample_rate: u32,
    /// Capture overruns reported by the last block.
    pub xruns: u32,
    /// Sequence numbers of the blocks, in log order.
    pub seqs: Vec<u64>,
}

/// A log read back.
#[derive(Debug, Clone, Default)]
pub struct DriveLog {
    /// The file.
    pub path: PathBuf,
    /// `CycleRecord`s in log order.
    pub cycles: Vec<CycleRecord>,
    /// `GroundTruth` in log order.
    pub truth: Vec<GroundTruth>,
    /// `RoadEstimate`s in log order.
    pub roads: Vec<RoadEstimate>,
    /// `CanFrame`s in log order (tcs-loop's CAN log, `grip/can/log`).
    pub can: Vec<CanFrame>,
    /// The vehicle bus as the recorder read it (`grip/can/bus`, absent
    /// before the recorder logged it or with `bus = "off"`), in log order.
    /// Nothing of a drive's summary or replay reads it (`grip inspect`'s
    /// bus section and `--candump` do).
    pub bus: Vec<BusFrame>,
    /// Audio blocks.
    pub audio: AudioInfo,
    /// Messages per topic (every topic, also unknown ones).
    pub counts: BTreeMap<String, u64>,
    /// What the reader found (truncation, foreign or bad messages).
    pub report: ReadReport,
    /// `grip.run` metadata (empty if absent).
    pub run: MetadataMap,
    /// `grip.recorder` metadata (absent when the recorder did not finish).
    pub recorder: Option<MetadataMap>,
    /// Attachments: name → bytes.
    pub attachments: BTreeMap<String, Vec<u8>>,
    /// Every metadata record by name (the last of a name wins).
    pub metadata: BTreeMap<String, MetadataMap>,
    /// The audio blocks in log order, when [`LoadOptions::audio`] asked.
    pub audio_blocks: Vec<AudioBlock>,
}

impl DriveLog {
    /// The first stamp of the log's cycle records, ground truth, estimates
    /// and CAN frames, ns (0 for none): the time origin of `grip inspect`'s
    /// CSVs and of the measured section's demand window.
    pub fn first_stamp_ns(&self) -> u64 {
        [
            self.cycles.first().map(|c| c.stamp_ns),
            self.truth.first().map(|c| c.stamp_ns),
            self.roads.first().map(|c| c.stamp_ns),
            self.can.first().map(|c| c.stamp_ns),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(0)
    }

    /// Reads `path`. A file that is not MCAP, or unreadable, is an error; a
    /// damaged one reads all it can (see `report.truncated`).
    pub fn load(path: &Path) -> Result<Self, LogError> {
        Self::load_with(path, LoadOptions::default())
    }

    /// [`DriveLog::load`], keeping what `opts` asks for.
    pub fn load_with(path: &Path, opts: LoadOptions) -> Result<Self, LogError> {
        let err = |error| LogError {
            path: path.to_path_buf(),
            error,
        };
        let log = McapLog::open(path).map_err(err)?;
        Self::from_mcap(&log, path, opts)
    }

    /// The drive log of an opened `log` (named `path` in errors), keeping
    /// what `opts` asks for (the fuzz target reads logs from memory).
    pub fn from_mcap(log: &McapLog, path: &Path, opts: LoadOptions) -> Result<Self, LogError> {
        let err = |error| LogError {
            path: path.to_path_buf(),
            error,
        };
        let mut me = DriveLog {
            path: path.to_path_buf(),
            ..Self::default()
        };
        let report = log
            .for_each(|e| {
                *me.counts.entry(e.topic.clone()).or_default() += 1;
                match e.msg {
                    LogMessage::Cycle(c) => me.cycles.push(c),
                    LogMessage::Truth(t) => me.truth.push(t),
                    LogMessage::Road(r) => me.roads.push(r),
                    LogMessage::Can(f) => me.can.push(f),
                    LogMessage::Bus(f) => me.bus.push(f),
                    LogMessage::Audio(a) => {
                        me.audio.blocks += 1;
                        me.audio.samples += u64::from(a.n_samples);
                        me.audio.sample_rate = a.sample_rate;
                        me.audio.xruns = a.xruns;
                        me.audio.seqs.push(a.seq);
                        if opts.audio {
                            me.audio_blocks.push(*a);
                        }
                    }
                }
            })
            .map_err(err)?;
        me.report = report;
        for (name, map) in log.metadata().unwrap_or_default() {
            match name.as_str() {
                "grip.run" => me.run = map.clone(),
                "grip.recorder" => me.recorder = Some(map.clone()),
                _ => {}
            }
            me.metadata.insert(name, map);
        }
        for a in log.attachments().unwrap_or_default() {
            me.attachments.insert(a.name, a.data);
        }
        for (t, _) in topics::ALL {
            me.counts.entry(t.to_owned()).or_default();
        }
        Ok(me)
    }

    /// An attachment as text.
    pub fn attachment_text(&self, name: &str) -> Option<&str> {
        self.attachments
            .get(name)
            .and_then(|d| std::str::from_utf8(d).ok())
    }

    /// The CAN protocol the drive's services spoke: the DBC its attached
    /// `can.toml` names (`dbc`, attached beside it), read as they read it;
    /// the built-in protocol when the log carries no `can.toml` or it names
    /// no DBC (logs from before the services read the DBC). An attached
    /// configuration that does not give a protocol is an error naming it.
    pub fn protocol(&self) -> Result<grip_io::can::protocol::Protocol, String> {
        use grip_io::can::protocol::Protocol;
        let Some(text) = self.attachment_text("can.toml") else {
            return Ok(Protocol::builtin().clone());
        };
        let can = grip_io::service::parse_can(Path::new("can.toml (attached)"), text)
            .map_err(|e| e.to_string())?;
        let Some(dbc) = &can.dbc else {
            return Ok(Protocol::builtin().clone());
        };
        let bytes = self.attachments.get(dbc).ok_or_else(|| {
            format!("can.toml (attached) names dbc = {dbc:?}, which the log does not carry")
        })?;
        // the wheels' radii of the drive's vehicle (attached), for a bus
        // whose wheel speeds are in km/h or m/s, as tcs-loop read it
        // (the vehicle the summary uses, as far as the log tells it)
        let radii = crate::plan::vehicle_of_log(self, &mut Vec::new())
            .map(|(v, _)| grip_io::can::protocol::WheelRadii::of(&v));
        let mut settings = grip_io::can::DbcSettings::from_can(&can, radii);
        // the bus load was judged when the drive started, at the rate its
        // interface ran at (which the log does not keep): not again here
        settings.skip_bus_load = true;
        // decoded as the services decode the file (UTF-8, else Latin-1)
        Protocol::from_dbc_bytes_with(bytes, &format!("{dbc} (attached)"), &settings)
            .map_err(|e| e.to_string())
    }
}

/// For each frame of tcs-loop's CAN log `can`, in order, the number of
/// commands (direction TX) logged before it: tcs-loop logs each cycle's
/// received frames and then its command, so a received frame with `k`
/// commands before it was drained by the loop's `k`-th cycle (counting
/// from the log's first). The one statement of that rule, for the inverter
/// summary and the HIL checks; whether a log can be trusted to follow it
/// (no lost message) is the caller's to judge.
pub fn commands_before(can: &[CanFrame]) -> impl Iterator<Item = usize> + '_ {
    can.iter().scan(0usize, |k, f| {
        let this = *k;
        *k += usize::from(f.direction == grip_msgs::can_dir::TX);
        Some(this)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::mcaplog::{McapWriter, McapWriterOptions};
    use grip_msgs::{CanFrame, CycleRecord, GroundTruth, RoadEstimate};

    fn sample_log(path: &Path) {
        let mut w = McapWriter::create(
            path,
            McapWriterOptions {
                chunk_size: 4096,
                ..McapWriterOptions::default()
            },
        )
        .unwrap();
        for k in 0..600u64 {
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            c.stamp_ns = 1_000_000_000 + k * 1_000_000;
            w.write(topics::CYCLE, &c).unwrap();
            let mut g = GroundTruth::zeroed();
            g.seq = k;
            g.stamp_ns = c.stamp_ns;
            g.x = if k < 100 { 0.0 } else { k as f64 * 0.01 };
            g.road_index = u32::from(k >= 300);
            g.road_name = grip_msgs::name_to_bytes(if k >= 300 { "snow" } else { "asphalt" });
            // microphone at the wheel (lead 0)
            g.mic_road_index = g.road_index;
            g.mic_road_name = g.road_name;
            w.write(topics::TRUTH, &g).unwrap();
            let mut f = CanFrame::new(0x100, &[1, (k & 15) as u8, 0, 0, 0, 0, 0, 0]);
            f.stamp_ns = c.stamp_ns;
            w.write(topics::CAN_LOG, &f).unwrap();
            if k % 100 == 50 {
                let mut e = RoadEstimate::zeroed();
                e.seq = k / 100;
                e.stamp_ns = c.stamp_ns;
                e.frame_t0_ns = c.stamp_ns - 100_000_000;
                e.frame_t1_ns = c.stamp_ns;
                e.class_index = 0;
                e.class_name = grip_msgs::name_to_bytes("asphalt");
                w.write(topics::ROAD, &e).unwrap();
            }
        }
        w.finish().unwrap();
    }

    #[test]
    fn complete_log_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.mcap");
        sample_log(&p);
        let log = DriveLog::load(&p).unwrap();
        assert!(log.report.truncated.is_none());
        assert_eq!(
            (
                log.cycles.len(),
                log.truth.len(),
                log.can.len(),
                log.roads.len()
            ),
            (600, 600, 600, 6)
        );
        let s = crate::summary::summarize(
            &log,
            &grip_physics::VehicleParams::default(),
            "defaults",
            None,
        );
        assert!(
            s.warnings.iter().any(|w| w.contains("grip.recorder")),
            "{:?}",
            s.warnings
        );
        assert_eq!(s.arte.changes.len(), 1);
    }

    /// Every truncation and many single-byte corruptions give an error or a
    /// partial log that says it is incomplete; never a panic.
    #[test]
    fn truncated_or_corrupt_logs_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.mcap");
        sample_log(&p);
        let bytes = std::fs::read(&p).unwrap();
        let q = dir.path().join("b.mcap");
        let v = grip_physics::VehicleParams::default();
        let step = (bytes.len() / 120).max(1);
        for cut in (0..bytes.len()).step_by(step) {
            std::fs::write(&q, &bytes[..cut]).unwrap();
            match DriveLog::load(&q) {
                Ok(log) => {
                    assert!(log.report.truncated.is_some(), "cut at {cut} not reported");
                    let s = crate::summary::summarize(&log, &v, "defaults", None);
                    let text = s.render();
                    assert!(text.contains("incomplete"), "cut at {cut}: {text}");
                }
                Err(e) => assert!(!e.to_string().is_empty()),
            }
        }
        for pos in (0..bytes.len()).step_by(step) {
            let mut b = bytes.clone();
            b[pos] ^= 0x5A;
            std::fs::write(&q, &b).unwrap();
            if let Ok(log) = DriveLog::load(&q) {
                let _ = crate::summary::summarize(&log, &v, "defaults", None).render();
            }
        }
    }

    #[test]
    fn not_mcap_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.mcap");
        std::fs::write(&p, "hello, not a log").unwrap();
        let e = DriveLog::load(&p).unwrap_err().full();
        assert_eq!(
            e,
            format!(
                "reading {}: not an MCAP file (magic bytes missing)",
                p.display()
            )
        );
        // the path and the reason once, and no source to say them again
        let missing = dir.path().join("missing.mcap");
        let e = DriveLog::load(&missing).unwrap_err();
        assert!(std::error::Error::source(&e).is_none());
        assert_eq!(
            e.full(),
            format!(
                "reading {}: No such file or directory (os error 2)",
                missing.display()
            )
        );
    }
}
