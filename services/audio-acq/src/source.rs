//! The [`Source`] trait every audio source implements, and the real-time
//! [`Pacer`] the file and synthetic sources share.

use grip_io::clock::Clock;

/// What one [`Source::read`] produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Read {
    /// `n` samples were written to the front of the buffer; `stamp_ns` is
    /// the CLOCK_MONOTONIC time of the first of them.
    Block {
        /// Valid samples (≤ buffer length; < it only for the last block of a
        /// WAV file played once).
        n: usize,
        /// Time of the first sample, ns.
        stamp_ns: u64,
    },
    /// No complete block within the source's wait limit (ALSA); call again.
    /// The caller checks its stop flag in between.
    Timeout,
    /// The source has ended (WAV file played once).
    End,
}

/// Counters a source keeps; copied out once per block (allocation-free).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SourceStats {
    /// Capture overruns (ALSA xruns; for paced sources: times the pacer fell
    /// more than its slack behind and dropped the backlog).
    pub xruns: u32,
    /// Synth: ground truth is currently lost (older than the timeout, or
    /// never received).
    pub truth_lost: bool,
    /// Synth: ground-truth samples received.
    pub truth_received: u64,
    /// Synth: truth samples naming a road the synthesiser does not know
    /// (generated as vehicle noise only).
    pub unknown_road: u64,
    /// Synth: the last road name of those (NUL-padded, as the truth's).
    pub unknown_name: [u8; grip_msgs::NAME_LEN],
    /// Synth: errors reading the truth topic.
    pub truth_errors: u64,
}

/// An audio source: fills blocks of mono S16 samples.
pub trait Source {
    /// Sample rate of the samples it produces, Hz.
    fn sample_rate(&self) -> u32;
    /// Fills the front of `out` (its length is the block size) with the
    /// next block. Paced sources sleep until the block's last sample is
    /// "due"; ALSA waits for the device at most its configured timeout.
    /// Allocates nothing.
    fn read(&mut self, out: &mut [i16]) -> Result<Read, crate::AcqError>;
    /// Counters.
    fn stats(&self) -> SourceStats;
}

/// f32 (full scale ±1.0) to S16, the rule of the ALSA source's FLOAT_LE
/// ([`crate::format::s16_from_float`]: `round(x · 32768)`, saturated; NaN
/// → 0). A 16-bit WAV's samples, read as s / 32768, come back exactly;
/// with × 32767 (until 2026-12-05) a file's full-scale 32767 arrived as
/// 32766, and arte's clipping rule (|s| ≥ 32767) never saw it.
#[inline]
pub fn f32_to_i16(x: f32) -> i16 {
    crate::format::s16_from_float(x)
}

/// Paces a sample stream in real time: block k (n samples) is released at
/// `t0 + (samples so far + n)/fs` on the clock (exact in integer
/// nanoseconds from the sample count, so no drift), and its first sample is
/// stamped `release − n/fs`, i.e. as if a device had captured it.
///
/// If the caller falls more than `max_lag_ns` behind (a stalled process),
/// the backlog is dropped like a capture device's overrun: the timeline
/// restarts at "now", the stamp jumps forward, and [`Pacer::resyncs`]
/// counts it. Smaller delays are caught up by releasing blocks back to
/// back, as a device buffer would.
#[derive(Debug)]
pub struct Pacer<C: Clock> {
    clock: C,
    fs: u64,
    t0_ns: Option<u64>,
    samples: u64,
    max_lag_ns: u64,
    resyncs: u32,
}

impl<C: Clock> Pacer<C> {
    /// A pacer for `fs` Hz that tolerates `max_lag_ns` of lateness.
    pub fn new(clock: C, fs: u32, max_lag_ns: u64) -> Self {
        Self {
            clock,
            fs: u64::from(fs.max(1)),
            t0_ns: None,
            samples: 0,
            max_lag_ns,
            resyncs: 0,
        }
    }

    fn span_ns(&self, samples: u64) -> u64 {
        (u128::from(samples) * 1_000_000_000 / u128::from(self.fs)) as u64
    }

    /// Sleeps until a block of `n` samples is due; returns the stamp of its
    /// first sample. The first call starts the timeline at "now".
    pub fn wait_block(&mut self, n: usize) -> u64 {
        let n = n as u64;
        let t0 = match self.t0_ns {
            Some(t) => t,
            None => {
                let t = self.clock.now_ns();
                self.t0_ns = Some(t);
                t
            }
        };
        let mut end = t0 + self.span_ns(self.samples + n);
        let now = self.clock.now_ns();
        if now > end.saturating_add(self.max_lag_ns) {
            // Overrun: restart the timeline so this block ends now.
            self.resyncs = self.resyncs.wrapping_add(1);
            let t0 = now.saturating_sub(self.span_ns(self.samples + n));
            self.t0_ns = Some(t0);
            end = now;
        } else if now < end {
            self.clock.sleep_until_ns(end);
        }
        self.samples += n;
        end - self.span_ns(n)
    }

    /// Overruns so far.
    pub fn resyncs(&self) -> u32 {
        self.resyncs
    }

    /// Current time on the pacer's clock.
    pub fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_io::clock::ManualClock;

    #[test]
    fn conversion_rounds_and_saturates() {
        assert_eq!(f32_to_i16(0.0), 0);
        assert_eq!(f32_to_i16(1.0), 32767);
        assert_eq!(f32_to_i16(-1.0), -32768);
        assert_eq!(f32_to_i16(32767.0 / 32768.0), 32767);
        assert_eq!(f32_to_i16(2.0), 32767);
        assert_eq!(f32_to_i16(-2.0), -32768);
        assert_eq!(f32_to_i16(f32::NAN), 0);
        assert_eq!(f32_to_i16(0.5), 16384);
    }

    #[test]
    fn pacer_releases_on_the_sample_clock_without_drift() {
        let c = ManualClock::new(1_000_000_000);
        let mut p = Pacer::new(c.clone(), 44_100, 100_000_000);
        let mut last = 0;
        for k in 0..1000u64 {
            let stamp = p.wait_block(1024);
            let expect = 1_000_000_000 + (u128::from(k * 1024) * 1_000_000_000 / 44_100) as u64;
            assert!(
                stamp.abs_diff(expect) <= 1,
                "block {k}: {stamp} vs {expect}"
            );
            assert!(stamp > last || k == 0);
            last = stamp;
            // released at the block's end
            let end = 1_000_000_000 + (u128::from((k + 1) * 1024) * 1_000_000_000 / 44_100) as u64;
            assert_eq!(c.now_ns(), end);
        }
        assert_eq!(p.resyncs(), 0);
    }

    #[test]
    fn pacer_catches_up_small_delays_and_resyncs_large_ones() {
        let c = ManualClock::new(0);
        let mut p = Pacer::new(c.clone(), 1000, 50_000_000); // 1 kHz, 50 ms slack
        assert_eq!(p.wait_block(10), 0); // ends at 10 ms
        c.advance_ns(30_000_000); // now 40 ms, block 2 was due at 20 ms
        assert_eq!(p.wait_block(10), 10_000_000); // released at once
        assert_eq!(c.now_ns(), 40_000_000);
        assert_eq!(p.resyncs(), 0);
        c.advance_ns(200_000_000); // now 240 ms: 210 ms late
        let s = p.wait_block(10);
        assert_eq!(p.resyncs(), 1);
        assert_eq!(s, 230_000_000); // stamped as ending now
        assert_eq!(p.wait_block(10), 240_000_000);
        assert_eq!(c.now_ns(), 250_000_000);
    }
}
