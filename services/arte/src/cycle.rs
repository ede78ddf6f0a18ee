//! [`ArteLoop`]: the per-block work of the arte service (see the crate
//! docs), and the counters it shares with the helper thread
//! ([`ArteCounters`]).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use grip_arte::model::Model;
use grip_arte::stream::{Classify, StreamConfig, StreamEstimator};
use grip_io::clock::Clock;
use grip_msgs::{AUDIO_MAX_SAMPLES, AudioBlock, CycleRecord, MAX_ROAD_CLASSES, RoadEstimate};

use crate::{ArteError, ClassKnowledge};

/// Counters shared with the helper thread (and read by tests).
#[derive(Debug, Default)]
pub struct ArteCounters {
    /// Loop iterations and blocks taken (the heartbeat the watchdog follows:
    /// it moves while the loop drains a backlog, too).
    pub heartbeat: AtomicU64,
    /// Audio blocks received.
    pub blocks: AtomicU64,
    /// Blocks that never reached the loop: sequence numbers skipped between
    /// two blocks it took (lost in transport, or overwritten in the
    /// subscriber's queue while the loop was stopped or starved). Counted on
    /// every path a block takes ([`ArteLoop::on_block`], a block refused for
    /// its rate, one dropped as stale by [`ArteLoop::on_live_block`]).
    pub lost_blocks: AtomicU64,
    /// Estimator restarts (time discontinuity or publisher restart).
    pub resets: AtomicU64,
    /// Blocks refused for a sample rate other than the model's.
    pub rate_mismatch: AtomicU64,
    /// The last refused rate, Hz.
    pub bad_rate: AtomicU64,
    /// Road estimates published.
    pub estimates: AtomicU64,
    /// Publish failures.
    pub publish_errors: AtomicU64,
    /// Receive failures.
    pub receive_errors: AtomicU64,
    /// Latest xrun count reported by audio-acq.
    pub xruns: AtomicU64,
    /// Blocks not classified because their audio had ended more than
    /// `input.max_lag_s` before the loop took them ([`ArteLoop::on_live_block`]).
    pub stale_blocks: AtomicU64,
    /// Estimates not published by the live loop because their audio had
    /// ended more than `input.max_lag_s` before the moment of publication
    /// (the process was stopped or starved between taking a block and
    /// classifying it).
    pub stale_estimates: AtomicU64,
    /// The largest lag of a dropped block so far (its audio's end to the
    /// moment the loop took it), ns.
    pub max_stale_lag_ns: AtomicU64,
    /// Blocks not classified because the microphone's signal was unusable
    /// (see [`AudioQuality`]): digital silence or near it.
    pub silent_blocks: AtomicU64,
    /// ... clipped.
    pub clipped_blocks: AtomicU64,
    /// ... reporting a new capture overrun, or within
    /// [`AudioQuality::xrun_hold_ns`] after one.
    pub xrun_blocks: AtomicU64,
    /// Published estimates per winning class index.
    pub per_class: [AtomicU64; MAX_ROAD_CLASSES],
    /// Cycle records received from tcs-loop (`grip/tcs/cycle`), valid or not.
    pub cycle_records: AtomicU64,
    /// Cycle records with `v_valid = 1` but a non-finite `v` (ignored).
    pub bad_speeds: AtomicU64,
    /// Receive failures on `grip/tcs/cycle`.
    pub cycle_receive_errors: AtomicU64,
    /// Blocks given to the estimator with a fresh vehicle speed.
    pub blocks_with_speed: AtomicU64,
    /// Blocks given to the estimator without one (none yet, or stale).
    pub blocks_without_speed: AtomicU64,
    /// Whether the last block given to the estimator had a fresh speed.
    pub speed_fresh: AtomicBool,
    /// The speed (m/s, `f64::to_bits`) of the last block that had one.
    pub last_speed_bits: AtomicU64,
}

impl ArteCounters {
    /// The speed the estimator got with the last block: `Some(m/s)` if
    /// that block had a fresh speed, `None` if it had none (or no block
    /// yet).
    pub fn speed_in_use(&self) -> Option<f64> {
        self.speed_fresh
            .load(Ordering::Relaxed)
            .then(|| f64::from_bits(self.last_speed_bits.load(Ordering::Relaxed)))
    }
}

/// Where estimates go: the iceoryx2 publisher, or a test sink.
pub trait EstimateSink {
    /// Sends one estimate. Allocation-free.
    fn send(&mut self, e: &RoadEstimate) -> Result<(), grip_io::ipc::IpcError>;
}

/// Sends `e` and counts it (`estimates`, or `publish_errors`); whether it
/// went out. Allocation-free.
fn publish(sink: &mut impl EstimateSink, e: &RoadEstimate, stats: &ArteCounters) -> bool {
    let ok = sink.send(e).is_ok();
    let c = if ok {
        &stats.estimates
    } else {
        &stats.publish_errors
    };
    c.fetch_add(1, Ordering::Relaxed);
    ok
}

impl EstimateSink for grip_io::ipc::Publisher<RoadEstimate> {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), grip_io::ipc::IpcError> {
        self.publish(e).map(|_| ())
    }
}

pub use grip_arte::quality::{AudioQuality, BadAudio};

/// The per-block work of the arte service (see the crate docs).
///
/// Frame spans: the estimator counts samples since its last restart; a
/// decision at sample count `t_end` that falls inside a block starting at
/// count `S0` with stamp `B` gets `frame_t1 = B + (t_end − S0)/fs` and
/// `frame_t0 = frame_t1 − frame_len/fs`. Each block re-anchors time, so
/// lost blocks and overruns shift no later estimate's span (within a frame
/// that straddles a small gap, `frame_t0` is off by the gap).
pub struct ArteLoop<C: Classify, K: Clock> {
    est: StreamEstimator<C>,
    roads: Vec<ClassKnowledge>,
    fs: u32,
    frame_ns: u64,
    scratch: Vec<f32>,
    expected_seq: Option<u64>,
    next_stamp: Option<u64>,
    pushed: u64,
    out_seq: u64,
    resync_ns: u64,
    clock: K,
    est_buf: RoadEstimate,
    /// Newest valid vehicle speed: (|v| m/s, its record's stamp ns).
    speed: Option<(f64, u64)>,
    /// tcs-loop's odometer in the record `speed` came from, m.
    odometer: f64,
    speed_timeout_ns: u64,
    quality: AudioQuality,
    /// The xrun count of the previous block.
    last_xruns: Option<u32>,
    /// Blocks stamped before this follow an overrun too closely, ns.
    xrun_hold_until: u64,
    /// [`Self::on_live_block`] drops a block whose audio ended longer ago, ns.
    max_lag_ns: u64,
}

/// Default of `input.speed_timeout_s`, s.
pub const DEFAULT_SPEED_TIMEOUT_S: f64 = 0.2;

/// Default of `input.max_lag_s`, s: an estimate of audio older than this
/// is no longer knowledge of the road ahead of (or under) the wheel. At
/// 36 km/h the front microphone's 2.77 m of preview last 0.28 s, and
/// tcs-loop takes the stream for dead `[arte] max_age_s` (0.3 s) after its
/// last estimate.
pub const DEFAULT_MAX_LAG_S: f64 = 0.5;

impl<C: Classify, K: Clock> std::fmt::Debug for ArteLoop<C, K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArteLoop")
            .field("fs", &self.fs)
            .field("out_seq", &self.out_seq)
            .finish_non_exhaustive()
    }
}

/// The odometer at `t_ns` from `x` m at `t_rec_ns` and speed `v` m/s (the
/// extrapolation behind every estimate's `x_from`/`x_to`).
pub fn odometer_at(x: f64, v: f64, t_rec_ns: u64, t_ns: u64) -> f64 {
    x + v * (t_ns as i128 - t_rec_ns as i128) as f64 * 1e-9
}

fn samples_ns(n: u64, fs: u32) -> u64 {
    (u128::from(n) * 1_000_000_000 / u128::from(fs.max(1))) as u64
}

impl<K: Clock> ArteLoop<grip_arte::model::Predictor, K> {
    /// From a model: its predictor, feature config and class table.
    pub fn from_model(
        model: &Model,
        stream: &StreamConfig,
        roads: Vec<ClassKnowledge>,
        resync_gap_s: f64,
        clock: K,
    ) -> Result<Self, ArteError> {
        Self::new(
            model.predictor(),
            model.feature_config(),
            stream,
            roads,
            resync_gap_s,
            clock,
        )
    }
}

impl<C: Classify, K: Clock> ArteLoop<C, K> {
    /// Builds the estimator for `classifier` on `model`'s features at
    /// `sample_rate`; `roads[i]` describes class i.
    pub fn new(
        classifier: C,
        features: &grip_arte::features::FeatureConfig,
        stream: &StreamConfig,
        roads: Vec<ClassKnowledge>,
        resync_gap_s: f64,
        clock: K,
    ) -> Result<Self, ArteError> {
        if roads.len() != classifier.n_classes() || roads.len() > MAX_ROAD_CLASSES {
            return Err(ArteError::Other(format!(
                "{} road entries for {} classes (max {MAX_ROAD_CLASSES})",
                roads.len(),
                classifier.n_classes()
            )));
        }
        let est = StreamEstimator::new(classifier, features, stream)?;
        let fs = features.sample_rate;
        Ok(Self {
            frame_ns: samples_ns(est.frame_len() as u64, fs),
            est,
            roads,
            fs,
            scratch: vec![0.0; AUDIO_MAX_SAMPLES],
            expected_seq: None,
            next_stamp: None,
            pushed: 0,
            out_seq: 0,
            resync_ns: (resync_gap_s.max(0.0) * 1e9) as u64,
            clock,
            est_buf: RoadEstimate::zeroed(),
            speed: None,
            odometer: f64::NAN,
            speed_timeout_ns: (DEFAULT_SPEED_TIMEOUT_S * 1e9) as u64,
            quality: AudioQuality::default(),
            last_xruns: None,
            xrun_hold_until: 0,
            max_lag_ns: (DEFAULT_MAX_LAG_S * 1e9) as u64,
        })
    }

    /// Sets how old (s) a vehicle speed may be and still be used (default
    /// [`DEFAULT_SPEED_TIMEOUT_S`]; `input.speed_timeout_s`). Negative or
    /// NaN: 0.
    pub fn with_speed_timeout(mut self, timeout_s: f64) -> Self {
        self.speed_timeout_ns = (timeout_s.max(0.0) * 1e9) as u64;
        self
    }

    /// Sets how late (s) a block may be taken and still be classified by
    /// [`Self::on_live_block`] (default [`DEFAULT_MAX_LAG_S`];
    /// `input.max_lag_s`). Negative or NaN: 0.
    pub fn with_max_lag(mut self, max_lag_s: f64) -> Self {
        self.max_lag_ns = (max_lag_s.max(0.0) * 1e9) as u64;
        self
    }

    /// Sets what counts as unusable audio (default [`AudioQuality::default`]).
    pub fn with_quality(mut self, quality: AudioQuality) -> Self {
        self.quality = quality;
        self
    }

    /// Whether the model's features depend on the vehicle speed (if not,
    /// the speed is still tracked and counted but changes nothing).
    pub fn speed_normalised(&self) -> bool {
        self.est.speed_normalised()
    }

    /// Takes one tcs-loop cycle record: if `v_valid = 1` and `v` is finite,
    /// its |v| becomes the vehicle speed unless a record with a later stamp
    /// was taken before and is still fresh ([`Self::current_speed`]; a kept
    /// record stamped far in the future is not, so it cannot lock out every
    /// later one). Other records change nothing (the kept speed ages out).
    /// Allocation-free.
    pub fn on_cycle(&mut self, r: &CycleRecord, stats: &ArteCounters) {
        stats.cycle_records.fetch_add(1, Ordering::Relaxed);
        if r.v_valid != 1 {
            return;
        }
        if !r.v.is_finite() {
            stats.bad_speeds.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.speed.is_none_or(|(_, t)| r.stamp_ns >= t) || self.current_speed().is_none() {
            // reversing: the tyre noise depends on the speed's magnitude
            self.speed = Some((r.v.abs(), r.stamp_ns));
            self.odometer = if r.odometer.is_finite() {
                r.odometer
            } else {
                f64::NAN
            };
        }
    }

    /// Drains `sub` (non-blocking) into [`Self::on_cycle`]. Receive errors
    /// are counted in `cycle_receive_errors`. Allocation-free once the
    /// subscriber is connected to its publisher.
    pub fn poll_cycles(
        &mut self,
        sub: &grip_io::ipc::Subscriber<CycleRecord>,
        stats: &ArteCounters,
    ) {
        if sub.drain(|r| self.on_cycle(r, stats)).is_err() {
            stats.cycle_receive_errors.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The vehicle speed a block processed now would get: the kept speed
    /// if its record's stamp is within `speed_timeout` of the clock's now
    /// (either side: a stamp far in the future is not trusted either).
    pub fn current_speed(&self) -> Option<f64> {
        let now = self.clock.now_ns();
        self.speed
            .filter(|&(_, t)| now.abs_diff(t) <= self.speed_timeout_ns)
            .map(|(v, _)| v)
    }

    /// The model's sample rate, Hz.
    pub fn sample_rate(&self) -> u32 {
        self.fs
    }

    /// Estimates published so far.
    pub fn estimates(&self) -> u64 {
        self.out_seq
    }

    fn restart(&mut self, stats: &ArteCounters) {
        self.est.reset();
        self.pushed = 0;
        stats.resets.fetch_add(1, Ordering::Relaxed);
    }

    /// The live service's entry: block `b` taken from the topic at `now_ns`
    /// (the clock its stamps come from). Audio that ended more than
    /// `max_lag` ago is dropped and counted (`stale_blocks`,
    /// `max_stale_lag_ns`; the blocks skipped before it, as on every path,
    /// in `lost_blocks`): it is not classified, no estimate is made of it,
    /// and the estimator starts a fresh frame at the next block in time, so
    /// a backlog (a starved CPU, a stopped and resumed process) never turns
    /// into estimates of old audio published as new. Otherwise
    /// [`Self::on_block`], except that an estimate whose audio is older
    /// than `max_lag` by the time it would go out (the process stopped
    /// between taking the block and publishing) is not published either
    /// (`stale_estimates`). Replays and generated drives call `on_block`
    /// directly: they classify every block. Returns the estimates sent.
    /// Allocation-free.
    pub fn on_live_block(
        &mut self,
        b: &AudioBlock,
        now_ns: u64,
        sink: &mut impl EstimateSink,
        stats: &ArteCounters,
    ) -> usize {
        let end = b
            .stamp_ns
            .saturating_add(samples_ns(b.samples().len() as u64, self.fs));
        let lag = now_ns.saturating_sub(end);
        if lag <= self.max_lag_ns || b.sample_rate != self.fs {
            return self.process(b, sink, stats, self.max_lag_ns);
        }
        stats.blocks.fetch_add(1, Ordering::Relaxed);
        stats.xruns.store(u64::from(b.xruns), Ordering::Relaxed);
        stats.stale_blocks.fetch_add(1, Ordering::Relaxed);
        stats.max_stale_lag_ns.fetch_max(lag, Ordering::Relaxed);
        // taken, not lost: the sequence, the time line and the overrun count
        // go on from it (the next block starts a fresh frame anyway). The
        // blocks skipped before it were lost (a queue that overflowed while
        // the process was stopped): counted, as on every path.
        self.follow_seq(b.seq, stats);
        self.next_stamp = Some(end);
        self.last_xruns = Some(b.xruns);
        self.fresh_frame();
        0
    }

    /// Takes sequence number `seq`: the numbers skipped since the block
    /// expected are counted as lost (`lost_blocks`), and the next one is
    /// expected after it. Whether `seq` went backwards (the publisher
    /// restarted). Every block taken goes through here, whatever becomes of
    /// it (classified, refused for its rate, dropped as stale), so that a
    /// gap is counted whichever kind of block comes after it.
    fn follow_seq(&mut self, seq: u64, stats: &ArteCounters) -> bool {
        let mut backwards = false;
        if let Some(exp) = self.expected_seq {
            if seq > exp {
                stats.lost_blocks.fetch_add(seq - exp, Ordering::Relaxed);
            } else if seq < exp {
                backwards = true;
            }
        }
        self.expected_seq = Some(seq.wrapping_add(1));
        backwards
    }

    /// The next block classified starts a fresh frame: nothing of the
    /// audio before it (unusable, or dropped as too old) carries over.
    fn fresh_frame(&mut self) {
        if self.pushed > 0 {
            self.est.reset();
            self.pushed = 0;
        }
    }

    /// Processes one block; sends every estimate that falls due in it.
    /// Returns how many. Allocation-free.
    pub fn on_block(
        &mut self,
        b: &AudioBlock,
        sink: &mut impl EstimateSink,
        stats: &ArteCounters,
    ) -> usize {
        self.process(b, sink, stats, u64::MAX)
    }

    /// [`Self::on_block`], publishing no estimate whose audio ended more
    /// than `max_lag_ns` before the clock's reading at its publication
    /// (counted in `stale_estimates`).
    fn process(
        &mut self,
        b: &AudioBlock,
        sink: &mut impl EstimateSink,
        stats: &ArteCounters,
        max_lag_ns: u64,
    ) -> usize {
        stats.blocks.fetch_add(1, Ordering::Relaxed);
        stats.xruns.store(u64::from(b.xruns), Ordering::Relaxed);
        if b.sample_rate != self.fs {
            stats.rate_mismatch.fetch_add(1, Ordering::Relaxed);
            stats
                .bad_rate
                .store(u64::from(b.sample_rate), Ordering::Relaxed);
            // received, not lost: later blocks are not counted as gaps (a
            // long run of refused blocks restarts the estimator by time);
            // the blocks skipped before it are
            self.follow_seq(b.seq, stats);
            return 0;
        }
        let x = b.samples();
        let n = x.len();
        // Sequence: gaps are counted; a sequence going backwards means the
        // publisher restarted.
        let mut discontinuity = self.follow_seq(b.seq, stats);
        if let Some(ns) = self.next_stamp
            && b.stamp_ns.abs_diff(ns) > self.resync_ns
        {
            discontinuity = true;
        }
        if discontinuity && self.pushed > 0 {
            self.restart(stats);
        }
        self.next_stamp = Some(b.stamp_ns.saturating_add(samples_ns(n as u64, self.fs)));
        // after a restart, which may reset the estimator's speed
        let speed = self.current_speed();
        self.est.set_speed(speed);
        // tcs-loop's odometer at time t (ns), extrapolated from the newest
        // fresh cycle record at its speed; NaN without one
        let odo = match (speed, self.speed) {
            (Some(v), Some((_, t_rec))) => Some((self.odometer, v, t_rec)),
            _ => None,
        };
        match speed {
            Some(v) => {
                stats.blocks_with_speed.fetch_add(1, Ordering::Relaxed);
                stats.last_speed_bits.store(v.to_bits(), Ordering::Relaxed);
                stats.speed_fresh.store(true, Ordering::Relaxed);
            }
            None => {
                stats.blocks_without_speed.fetch_add(1, Ordering::Relaxed);
                stats.speed_fresh.store(false, Ordering::Relaxed);
            }
        }
        // the microphone's faults: no classification of unusable audio
        let new_xrun = self.last_xruns.is_some_and(|last| last != b.xruns);
        self.last_xruns = Some(b.xruns);
        // never more than the hold past this block: a block stamped far in
        // the future must not hold every later one back for good
        let hold_end = b.stamp_ns.saturating_add(self.quality.xrun_hold_ns);
        self.xrun_hold_until = if new_xrun {
            hold_end
        } else {
            self.xrun_hold_until.min(hold_end)
        };
        let held = b.stamp_ns < self.xrun_hold_until;
        if let Some(why) = self.quality.judge(x, new_xrun || held) {
            let c = match why {
                BadAudio::Silence => &stats.silent_blocks,
                BadAudio::Clipping => &stats.clipped_blocks,
                BadAudio::Xrun => &stats.xrun_blocks,
            };
            c.fetch_add(1, Ordering::Relaxed);
            self.fresh_frame();
            let e = &mut self.est_buf;
            *e = RoadEstimate::zeroed();
            e.seq = self.out_seq;
            e.frame_t1_ns = b.stamp_ns.saturating_add(samples_ns(n as u64, self.fs));
            e.frame_t0_ns = e.frame_t1_ns.saturating_sub(self.frame_ns);
            e.n_classes = self.roads.len().min(MAX_ROAD_CLASSES) as u32;
            e.confidence = 0.0;
            e.lambda_opt = f64::NAN;
            e.mu_peak = f64::NAN;
            e.alpha = f64::NAN;
            e.x_from = f64::NAN;
            e.x_to = f64::NAN;
            e.stamp_ns = self.clock.now_ns();
            if e.stamp_ns.saturating_sub(e.frame_t1_ns) > max_lag_ns {
                stats.stale_estimates.fetch_add(1, Ordering::Relaxed);
                return 0;
            }
            publish(sink, e, stats);
            self.out_seq += 1;
            return 1;
        }
        for (d, &s) in self.scratch.iter_mut().zip(x) {
            *d = f32::from(s) / 32768.0;
        }
        let start = self.pushed;
        let stamp = b.stamp_ns;
        let fs = self.fs;
        let frame_ns = self.frame_ns;
        let roads = &self.roads;
        let clock = &self.clock;
        let e = &mut self.est_buf;
        let out_seq = &mut self.out_seq;
        let mut sent = 0;
        self.est.push(&self.scratch[..n], |d| {
            let end = (d.t_end * f64::from(fs)).round().max(0.0) as u64;
            let t1 = stamp.saturating_add(samples_ns(end.saturating_sub(start), fs));
            let k = d.probs.len().min(MAX_ROAD_CLASSES);
            let class = d.class.min(k.saturating_sub(1));
            e.seq = *out_seq;
            e.frame_t1_ns = t1;
            e.frame_t0_ns = t1.saturating_sub(frame_ns);
            (e.x_from, e.x_to) = match odo {
                Some((x, v, t_rec)) => (
                    odometer_at(x, v, t_rec, e.frame_t0_ns),
                    odometer_at(x, v, t_rec, t1),
                ),
                None => (f64::NAN, f64::NAN),
            };
            e.class_index = class as u32;
            e.n_classes = k as u32;
            e.probabilities = [0.0; MAX_ROAD_CLASSES];
            for (p, &q) in e.probabilities.iter_mut().zip(d.probs) {
                *p = q as f32;
            }
            let c = d.probs.get(class).copied().unwrap_or(0.0);
            // clamp keeps a NaN; the estimator gives none, but a NaN must
            // never reach tcs-loop as a confidence
            e.confidence = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
            let r = &roads[class];
            e.class_name = r.name;
            e.lambda_opt = r.lambda_opt;
            e.mu_peak = r.mu_peak;
            e.alpha = r.alpha;
            e.stamp_ns = clock.now_ns();
            // the live loop was stopped or starved between taking the
            // block and getting here: this is old audio, not news
            if e.stamp_ns.saturating_sub(t1) > max_lag_ns {
                stats.stale_estimates.fetch_add(1, Ordering::Relaxed);
                return;
            }
            if publish(sink, e, stats) {
                stats.per_class[class].fetch_add(1, Ordering::Relaxed);
            }
            *out_seq += 1;
            sent += 1;
        });
        self.pushed += n as u64;
        sent
    }
}
