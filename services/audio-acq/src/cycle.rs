//! [`AcqLoop`]: the per-block loop body of audio-acq (source → block →
//! sink), and the counters it shares with the helper thread
//! ([`AcqStatus`]).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use grip_msgs::AudioBlock;

use crate::{AcqError, Read, Source};

/// Counters shared between the loop and the non-real-time helper thread.
#[derive(Debug, Default)]
pub struct AcqStatus {
    /// Blocks published (the loop's heartbeat).
    pub blocks: AtomicU64,
    /// Source overruns so far.
    pub xruns: AtomicU64,
    /// Publish failures.
    pub publish_errors: AtomicU64,
    /// Synth: truth currently lost.
    pub truth_lost: AtomicBool,
    /// Synth: truth samples received.
    pub truth_received: AtomicU64,
    /// Synth: truth samples naming an unknown road.
    pub unknown_road: AtomicU64,
    /// Synth: the last of those roads' name, its 16 bytes as two words
    /// (written only with the count; the monitor reads it after the count
    /// grew).
    pub unknown_name: [AtomicU64; 2],
    /// Synth: failed reads of the ground truth.
    pub truth_errors: AtomicU64,
    /// Source waits that timed out (ALSA).
    pub timeouts: AtomicU64,
}

impl AcqStatus {
    /// Stores the last unknown road's name (relaxed, allocation-free).
    pub fn set_unknown_name(&self, name: &[u8; grip_msgs::NAME_LEN]) {
        for (word, bytes) in self.unknown_name.iter().zip(name.chunks_exact(8)) {
            let mut b = [0u8; 8];
            b.copy_from_slice(bytes);
            word.store(u64::from_le_bytes(b), Ordering::Relaxed);
        }
    }

    /// The last unknown road's name as stored.
    pub fn unknown_name(&self) -> [u8; grip_msgs::NAME_LEN] {
        let mut name = [0u8; grip_msgs::NAME_LEN];
        for (bytes, word) in name.chunks_exact_mut(8).zip(&self.unknown_name) {
            bytes.copy_from_slice(&word.load(Ordering::Relaxed).to_le_bytes());
        }
        name
    }
}

/// Where blocks go: the iceoryx2 publisher, or a test sink.
pub trait BlockSink {
    /// Sends one block. Allocation-free.
    fn send(&mut self, block: &AudioBlock) -> Result<(), grip_io::ipc::IpcError>;
}

impl BlockSink for grip_io::ipc::Publisher<AudioBlock> {
    fn send(&mut self, block: &AudioBlock) -> Result<(), grip_io::ipc::IpcError> {
        self.publish(block).map(|_| ())
    }
}

/// What one [`AcqLoop::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// A block was published (or its publish failed and was counted).
    Published,
    /// The source timed out waiting; nothing published.
    Timeout,
    /// The source ended.
    End,
}

/// The per-block loop body: source → [`AudioBlock`] → sink.
#[derive(Debug)]
pub struct AcqLoop<S: Source> {
    source: S,
    block: Box<AudioBlock>,
    block_samples: usize,
    seq: u64,
    status: Arc<AcqStatus>,
}

impl<S: Source> AcqLoop<S> {
    /// A loop publishing blocks of `block_samples` (clamped to
    /// 1..=`AUDIO_MAX_SAMPLES`) from `source`, reporting on `channel`.
    pub fn new(source: S, block_samples: usize, channel: u16, status: Arc<AcqStatus>) -> Self {
        let mut block = Box::new(AudioBlock::zeroed());
        block.sample_rate = source.sample_rate();
        block.channel = channel;
        Self {
            source,
            block,
            block_samples: block_samples.clamp(1, grip_msgs::AUDIO_MAX_SAMPLES),
            seq: 0,
            status,
        }
    }

    /// Reads one block from the source and sends it. Allocation-free. A
    /// failed publish is counted in [`AcqStatus::publish_errors`], not
    /// returned; source errors (unrecoverable ALSA failures) are.
    pub fn step(&mut self, sink: &mut impl BlockSink) -> Result<Step, AcqError> {
        let r = self
            .source
            .read(&mut self.block.samples[..self.block_samples])?;
        let st = self.source.stats();
        self.status
            .xruns
            .store(u64::from(st.xruns), Ordering::Relaxed);
        self.status
            .truth_lost
            .store(st.truth_lost, Ordering::Relaxed);
        self.status
            .truth_received
            .store(st.truth_received, Ordering::Relaxed);
        self.status
            .unknown_road
            .store(st.unknown_road, Ordering::Relaxed);
        self.status.set_unknown_name(&st.unknown_name);
        self.status
            .truth_errors
            .store(st.truth_errors, Ordering::Relaxed);
        match r {
            Read::Block { n, stamp_ns } => {
                let n = n.min(self.block_samples);
                if n < self.block_samples {
                    self.block.samples[n..self.block_samples].fill(0);
                }
                self.block.seq = self.seq;
                self.block.stamp_ns = stamp_ns;
                self.block.n_samples = n as u32;
                self.block.xruns = st.xruns;
                if sink.send(&self.block).is_err() {
                    self.status.publish_errors.fetch_add(1, Ordering::Relaxed);
                }
                self.seq += 1;
                self.status.blocks.store(self.seq, Ordering::Relaxed);
                Ok(Step::Published)
            }
            Read::Timeout => {
                self.status.timeouts.fetch_add(1, Ordering::Relaxed);
                Ok(Step::Timeout)
            }
            Read::End => Ok(Step::End),
        }
    }

    /// The source.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// Blocks published so far (= the next block's sequence number).
    pub fn blocks(&self) -> u64 {
        self.seq
    }

    /// The last block built.
    pub fn last_block(&self) -> &AudioBlock {
        &self.block
    }
}
