//! The synthetic source: `grip_arte::synth::RoadAudioSynth` driven by the
//! ground truth plant-sim publishes (topic `TRUTH`: true road name and
//! vehicle speed V), paced in real time.
//!
//! Each block: the pacer sleeps until the block is due, the newest truth
//! sample (if any arrived) sets road and speed, and the block is generated
//! for them (so the audio follows the truth with at most one block of lag).
//! Road names map to the synthesiser's roads by exact name, else through
//! `[synth] aliases`; a road neither knows gives vehicle and microphone
//! sound only (counted as `unknown_road`).
//!
//! **When truth stops** (no new sample for `truth_timeout_s`), the source
//! follows `on_truth_lost`: `hold` keeps generating the last known road at
//! the last known speed, `silence` publishes zeros. Before the first truth
//! sample there is no road to hold, so blocks are zeros. Either way the
//! blocks keep coming at the real-time rate (downstream timing does not
//! depend on plant-sim being alive), and `truth_lost` is reported.

use std::collections::BTreeMap;
use std::path::Path;

use grip_arte::synth::{NoiseConfig, ROADS, RoadAudioSynth, SynthConfig};
use grip_io::clock::Clock;
use grip_io::service::ServiceConfig;
use grip_msgs::{GroundTruth, NAME_LEN, name_to_bytes};

use crate::config::{SynthSection, TruthLost};
use crate::source::{Pacer, Read, Source, SourceStats, f32_to_i16};
use crate::{AcqConfig, AcqError};

/// A failed read of the truth topic (counted, not fatal).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TruthReadError;

/// Where the synth source gets ground truth from.
pub trait TruthInput {
    /// The newest truth sample that arrived since the last call, if any.
    /// Allocation-free.
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError>;
}

impl TruthInput for grip_io::ipc::Subscriber<GroundTruth> {
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
        self.latest().map_err(|_| TruthReadError)
    }
}

/// No truth at all (tests; a synth source without plant-sim).
#[derive(Debug, Default, Clone, Copy)]
pub struct NoTruth;

impl TruthInput for NoTruth {
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
        Ok(None)
    }
}

/// Road index meaning "no tyre-road sound" (out of the synthesiser's range).
pub const NO_ROAD: usize = usize::MAX;

/// Synthetic tyre-road audio following ground truth (see the module docs).
pub struct SynthSource<C: Clock, T: TruthInput> {
    synth: RoadAudioSynth,
    truth: T,
    pacer: Pacer<C>,
    buf: Vec<f32>,
    names: Vec<([u8; NAME_LEN], usize)>,
    rate: u32,
    timeout_ns: u64,
    on_lost: TruthLost,
    road: usize,
    speed: f64,
    have_truth: bool,
    last_truth_ns: u64,
    last_name: [u8; NAME_LEN],
    stats: SourceStats,
}

impl<C: Clock, T: TruthInput> std::fmt::Debug for SynthSource<C, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SynthSource")
            .field("rate", &self.rate)
            .field("road", &self.road)
            .field("speed", &self.speed)
            .finish_non_exhaustive()
    }
}

/// The name → synth road table: the synthesiser's own names, then the
/// aliases as resolved by `grip_arte::synth::SynthAliases::resolve`
/// (`sounds`: roads the synthesiser has no sound for → one it has).
fn name_table(sounds: &BTreeMap<String, String>) -> Vec<([u8; NAME_LEN], usize)> {
    let mut t: Vec<([u8; NAME_LEN], usize)> = ROADS
        .iter()
        .enumerate()
        .map(|(i, r)| (name_to_bytes(r), i))
        .collect();
    for (from, to) in sounds {
        if let Some(i) = grip_arte::synth::road_index(to) {
            t.push((name_to_bytes(from), i));
        }
    }
    t
}

impl<C: Clock, T: TruthInput> SynthSource<C, T> {
    /// Builds the synthesiser (all buffers for blocks up to `max_block`).
    /// `cfg.aliases` go through [`SynthSection::resolved_aliases`]; a table
    /// it refuses (which [`crate::AcqConfig`]'s validation refused first)
    /// is [`AcqError::Config`] naming `audio-acq.toml`.
    pub fn new(
        cfg: &SynthSection,
        rate: u32,
        max_block: usize,
        truth: T,
        clock: C,
        max_lag_ns: u64,
    ) -> Result<Self, AcqError> {
        let scfg = SynthConfig {
            sample_rate: rate,
            noise: cfg.noise.as_ref().map(|n| NoiseConfig {
                rain: n.rain,
                car: n.car,
                snr_db: n.snr_db,
            }),
        };
        let synth =
            RoadAudioSynth::new(&scfg, cfg.seed).map_err(|e| AcqError::Synth(e.to_string()))?;
        let sounds = cfg
            .resolved_aliases(Path::new(<AcqConfig as ServiceConfig>::FILE_NAME))?
            .sounds;
        Ok(Self {
            synth,
            truth,
            pacer: Pacer::new(clock, rate, max_lag_ns),
            buf: vec![0.0; max_block],
            names: name_table(&sounds),
            rate,
            timeout_ns: (cfg.truth_timeout_s * 1e9) as u64,
            on_lost: cfg.on_truth_lost,
            road: NO_ROAD,
            speed: 0.0,
            have_truth: false,
            last_truth_ns: 0,
            last_name: [0xff; NAME_LEN],
            stats: SourceStats {
                truth_lost: true,
                ..SourceStats::default()
            },
        })
    }

    /// The road index (into `grip_arte::synth::ROADS`, or [`NO_ROAD`]) and
    /// speed (m/s) the last block was generated for.
    pub fn current(&self) -> (usize, f64) {
        (self.road, self.speed)
    }

    /// The audio is the road at the microphone (`mic_road_name`), which is
    /// `mic_lead_m` ahead of the driven wheel.
    fn take_truth(&mut self, t: &GroundTruth, now: u64) {
        if t.mic_road_name != self.last_name {
            self.last_name = t.mic_road_name;
            self.road = self
                .names
                .iter()
                .find(|(n, _)| *n == t.mic_road_name)
                .map_or(NO_ROAD, |&(_, i)| i);
        }
        if self.road == NO_ROAD {
            self.stats.unknown_road += 1;
            self.stats.unknown_name = t.mic_road_name;
        }
        self.speed = if t.v.is_finite() { t.v.abs() } else { 0.0 };
        self.have_truth = true;
        self.last_truth_ns = now;
        self.stats.truth_received += 1;
    }
}

impl<C: Clock, T: TruthInput> Source for SynthSource<C, T> {
    fn sample_rate(&self) -> u32 {
        self.rate
    }

    fn read(&mut self, out: &mut [i16]) -> Result<Read, AcqError> {
        let n = out.len().min(self.buf.len());
        let stamp_ns = self.pacer.wait_block(n);
        let now = self.pacer.now_ns();
        match self.truth.poll_latest() {
            Ok(Some(t)) => self.take_truth(&t, now),
            Ok(None) => {}
            Err(TruthReadError) => self.stats.truth_errors += 1,
        }
        let lost = !self.have_truth || now.saturating_sub(self.last_truth_ns) > self.timeout_ns;
        self.stats.truth_lost = lost;
        let silent = !self.have_truth || (lost && self.on_lost == TruthLost::Silence);
        if silent {
            out[..n].fill(0);
        } else {
            let buf = &mut self.buf[..n];
            self.synth.fill(self.road, self.speed, buf);
            for (o, &x) in out[..n].iter_mut().zip(buf.iter()) {
                *o = f32_to_i16(x);
            }
        }
        Ok(Read::Block { n, stamp_ns })
    }

    fn stats(&self) -> SourceStats {
        SourceStats {
            xruns: self.pacer.resyncs(),
            ..self.stats
        }
    }
}
