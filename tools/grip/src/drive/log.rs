//! A drive's MCAP log in memory: every payload but audio samples (audio is
//! counted, not kept), the run and recorder metadata, the attachments' names
//! and texts. Shared by `grip drive` (its summary) and `grip inspect`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use grip_io::mcaplog::{LogMessage, McapLog, MetadataMap, ReadReport};
use grip_msgs::{CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

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
    /// `CanFrame`s in log order.
    pub can: Vec<CanFrame>,
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
}

impl DriveLog {
    /// Reads `path`. A file that is not MCAP, or unreadable, is an error; a
    /// truncated one reads up to the damage (see `report.truncated`).
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let log = McapLog::open(path).with_context(|| format!("reading {}", path.display()))?;
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
                    LogMessage::Audio(a) => {
                        me.audio.blocks += 1;
                        me.audio.samples += u64::from(a.n_samples);
                        me.audio.sample_rate = a.sample_rate;
                        me.audio.xruns = a.xruns;
                        me.audio.seqs.push(a.seq);
                    }
                }
            })
            .with_context(|| format!("reading {}", path.display()))?;
        me.report = report;
        for (name, map) in log.metadata().unwrap_or_default() {
            match name.as_str() {
                "grip.run" => me.run = map,
                "grip.recorder" => me.recorder = Some(map),
                _ => {}
            }
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
}
