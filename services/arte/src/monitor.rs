//! The non-real-time helper thread beside the arte loop (the loop through
//! [`grip_io::service::monitor`]: `WATCHDOG=1` while the loop's heartbeat
//! advances; log lines on transitions, never per block). `READY=1`,
//! `STATUS=` and `STOPPING=1` come from [`grip_io::systemd`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::service::monitor::{self, Count, Flow, FlowEvent, HelperError, Monitor};
use grip_io::warn_if_grew;

use crate::ArteCounters;

/// Spawns the helper thread (before the caller switches to SCHED_FIFO).
/// Every 50 ms (or half the watchdog period if shorter) it sends
/// `WATCHDOG=1` at half the watchdog period if the loop's heartbeat
/// advanced, and logs transitions: audio stopped (no block for 1 s; the
/// audio-acq peer died or stalled) / resumed, lost blocks, estimator
/// restarts, refused sample rates, new xruns upstream, blocks not
/// classified for silence, clipping or overruns, publish and receive
/// errors; at most one line per kind per second. Vehicle speed
/// ([`SpeedLog`]): info once when it first becomes available (or once that
/// none has come after 1 s of audio), info when it goes stale and when it
/// returns, at most one stale line per [`SPEED_STALE_LOG_INTERVAL`].
pub fn spawn_helper(
    stats: Arc<ArteCounters>,
    model_rate: u32,
    speed_normalised: bool,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    let m = ArteMonitor {
        blocks: Flow::new(0, Instant::now(), Duration::from_secs(1)),
        lost: Count::default(),
        stale: Count::default(),
        stale_est: Count::default(),
        resets: Count::default(),
        rate_bad: Count::default(),
        xruns: Count::default(),
        silent: Count::default(),
        clipped: Count::default(),
        xrun_blocks: Count::default(),
        pub_err: Count::default(),
        rx_err: Count::default(),
        cycle_err: Count::default(),
        bad_speeds: Count::default(),
        speed_log: SpeedLog::new(),
        s: stats,
        model_rate,
        speed_normalised,
    };
    monitor::spawn("arte-helper", m, done)
}

/// Shortest time between two "vehicle speed stale" lines.
pub const SPEED_STALE_LOG_INTERVAL: Duration = Duration::from_secs(10);

/// What the helper says about the vehicle speed, from the counters, once
/// per second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SpeedState {
    /// No block has had a speed yet.
    Never,
    /// Blocks get a fresh speed.
    Fresh,
    /// It went stale.
    Stale,
}

/// One line the speed log wants written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpeedEvent {
    /// First block with a speed (m/s).
    Available(f64),
    /// After a logged stale period, speed again (m/s).
    Again(f64),
    /// Blocks go without a speed after having had one; `episodes` stale
    /// periods since the last stale line (suppressed ones included).
    Stale {
        /// Stale periods since the last stale line.
        episodes: u64,
    },
    /// Audio has flowed for a while and no block ever had a speed.
    NeverArrived,
}

/// The helper's vehicle-speed transitions, fed by the block counters once
/// per tick (pure: testable without threads or time).
#[derive(Debug)]
pub struct SpeedLog {
    state: SpeedState,
    with: u64,
    without: u64,
    last_stale_line: Option<Instant>,
    stale_logged: bool,
    episodes: u64,
    never_logged: bool,
    first_block_at: Option<Instant>,
}

impl Default for SpeedLog {
    fn default() -> Self {
        Self::new()
    }
}

impl SpeedLog {
    /// Nothing seen yet.
    pub fn new() -> Self {
        Self {
            state: SpeedState::Never,
            with: 0,
            without: 0,
            last_stale_line: None,
            stale_logged: false,
            episodes: 0,
            never_logged: false,
            first_block_at: None,
        }
    }

    /// Updates from the counters at `now`; `fresh` = the last block had a
    /// speed, `speed` its value. Returns the line to write, if any.
    pub fn update(
        &mut self,
        now: Instant,
        with: u64,
        without: u64,
        fresh: bool,
        speed: f64,
    ) -> Option<SpeedEvent> {
        let new_with = with > self.with;
        let new_without = without > self.without;
        self.with = with;
        self.without = without;
        if (new_with || new_without) && self.first_block_at.is_none() {
            self.first_block_at = Some(now);
        }
        match self.state {
            SpeedState::Never => {
                if new_with {
                    // (stale already: the next update says so)
                    self.state = SpeedState::Fresh;
                    return Some(SpeedEvent::Available(speed));
                }
                if !self.never_logged
                    && self
                        .first_block_at
                        .is_some_and(|t| now.duration_since(t) >= Duration::from_secs(1))
                {
                    self.never_logged = true;
                    return Some(SpeedEvent::NeverArrived);
                }
                None
            }
            SpeedState::Fresh => {
                // a block without speed since the last update (a short
                // stale period counts), or the last block had none
                if new_without || !fresh {
                    self.state = SpeedState::Stale;
                    self.episodes += 1;
                    let due = self
                        .last_stale_line
                        .is_none_or(|t| now.duration_since(t) >= SPEED_STALE_LOG_INTERVAL);
                    self.stale_logged = due;
                    if due {
                        self.last_stale_line = Some(now);
                        let episodes = self.episodes;
                        self.episodes = 0;
                        return Some(SpeedEvent::Stale { episodes });
                    }
                }
                None
            }
            SpeedState::Stale => {
                if new_with && fresh {
                    self.state = SpeedState::Fresh;
                    if self.stale_logged {
                        self.stale_logged = false;
                        return Some(SpeedEvent::Again(speed));
                    }
                }
                None
            }
        }
    }
}

fn log_speed(ev: SpeedEvent, speed_normalised: bool) {
    let effect = if speed_normalised {
        "frames taken as heard at the model's reference speed"
    } else {
        "no effect: the model is not speed-normalised"
    };
    match ev {
        SpeedEvent::Available(v) => tracing::info!(
            v_mps = v,
            speed_normalised,
            "vehicle speed available from grip/tcs/cycle"
        ),
        SpeedEvent::Again(v) => {
            tracing::info!(v_mps = v, "vehicle speed from grip/tcs/cycle again");
        }
        SpeedEvent::Stale { episodes } => tracing::info!(
            episodes,
            "vehicle speed stale or invalid (no record with v_valid = 1 within speed_timeout_s; tcs-loop stopped or lost V): {effect}"
        ),
        SpeedEvent::NeverArrived => tracing::info!(
            "no vehicle speed from grip/tcs/cycle after 1 s of audio (tcs-loop not running or V invalid): {effect}"
        ),
    }
}

struct ArteMonitor {
    s: Arc<ArteCounters>,
    model_rate: u32,
    speed_normalised: bool,
    blocks: Flow,
    lost: Count,
    stale: Count,
    stale_est: Count,
    resets: Count,
    rate_bad: Count,
    xruns: Count,
    silent: Count,
    clipped: Count,
    xrun_blocks: Count,
    pub_err: Count,
    rx_err: Count,
    cycle_err: Count,
    bad_speeds: Count,
    speed_log: SpeedLog,
}

impl Monitor for ArteMonitor {
    fn heartbeat(&self) -> u64 {
        self.s.heartbeat.load(Ordering::Relaxed)
    }

    fn stalled(&self, heartbeat: u64) {
        tracing::warn!(heartbeat, "arte loop heartbeat stalled: watchdog not fed");
    }

    fn tick(&mut self, now: Instant) {
        let b = self.s.blocks.load(Ordering::Relaxed);
        match self.blocks.update(b, now) {
            Some(FlowEvent::Moving { first: true, .. }) => {
                tracing::info!("first audio block received")
            }
            Some(FlowEvent::Moving { .. }) => {
                tracing::info!(blocks = b, "audio blocks arriving again")
            }
            Some(FlowEvent::Stopped) => tracing::warn!(
                blocks = b,
                "no audio block for 1 s (audio-acq dead, stalled or not started): no road estimates"
            ),
            None => {}
        }
    }

    fn report(&mut self, now: Instant) {
        let s = &self.s;
        warn_if_grew!(
            self.lost,
            s.lost_blocks.load(Ordering::Relaxed),
            "audio blocks lost (sequence gaps)"
        );
        warn_if_grew!(
            self.stale,
            s.stale_blocks.load(Ordering::Relaxed),
            "arte is behind the audio: blocks older than input.max_lag_s dropped, not classified (no estimate of old audio; CPU starved or the process was stopped)",
            max_lag_ms = s.max_stale_lag_ns.load(Ordering::Relaxed) as f64 * 1e-6
        );
        warn_if_grew!(
            self.stale_est,
            s.stale_estimates.load(Ordering::Relaxed),
            "estimates not published: their audio was older than input.max_lag_s when they were ready (arte stopped or starved while classifying)"
        );
        warn_if_grew!(
            self.resets,
            s.resets.load(Ordering::Relaxed),
            "audio stream discontinuity: estimator restarted"
        );
        let first_refusal = self.rate_bad.last() == 0;
        if self
            .rate_bad
            .grew(s.rate_mismatch.load(Ordering::Relaxed))
            .is_some()
            && first_refusal
        {
            let model_rate = self.model_rate;
            let audio_rate = s.bad_rate.load(Ordering::Relaxed);
            tracing::error!(
                audio_rate,
                model_rate,
                "audio blocks at {audio_rate} Hz but the model expects {model_rate} Hz: blocks REFUSED, no road estimates (set [audio] sample_rate in audio-acq.toml to {model_rate})",
            );
        }
        warn_if_grew!(
            self.xruns,
            s.xruns.load(Ordering::Relaxed),
            "audio-acq reports capture overruns"
        );
        warn_if_grew!(
            self.silent,
            s.silent_blocks.load(Ordering::Relaxed),
            "microphone silent: blocks not classified (confidence 0, no road)"
        );
        warn_if_grew!(
            self.clipped,
            s.clipped_blocks.load(Ordering::Relaxed),
            "microphone clipping: blocks not classified (confidence 0, no road)"
        );
        warn_if_grew!(
            self.xrun_blocks,
            s.xrun_blocks.load(Ordering::Relaxed),
            "audio after capture overruns: blocks not classified (confidence 0, no road)"
        );
        warn_if_grew!(
            self.pub_err,
            s.publish_errors.load(Ordering::Relaxed),
            "publishing road estimates failed"
        );
        warn_if_grew!(
            self.rx_err,
            s.receive_errors.load(Ordering::Relaxed),
            "receiving audio blocks failed"
        );
        warn_if_grew!(
            self.cycle_err,
            s.cycle_receive_errors.load(Ordering::Relaxed),
            "receiving cycle records (vehicle speed) failed"
        );
        warn_if_grew!(
            self.bad_speeds,
            s.bad_speeds.load(Ordering::Relaxed),
            "cycle records with v_valid = 1 but a non-finite v: ignored"
        );
        if let Some(ev) = self.speed_log.update(
            now,
            s.blocks_with_speed.load(Ordering::Relaxed),
            s.blocks_without_speed.load(Ordering::Relaxed),
            s.speed_fresh.load(Ordering::Relaxed),
            f64::from_bits(s.last_speed_bits.load(Ordering::Relaxed)),
        ) {
            log_speed(ev, self.speed_normalised);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_log_transitions_and_rate_limit() {
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let mut l = SpeedLog::new();
        // nothing yet; audio without speed for < 1 s: silent, then one line
        assert_eq!(l.update(at(0.0), 0, 0, false, 0.0), None);
        assert_eq!(l.update(at(1.0), 0, 40, false, 0.0), None);
        assert_eq!(
            l.update(at(2.0), 0, 80, false, 0.0),
            Some(SpeedEvent::NeverArrived)
        );
        assert_eq!(l.update(at(3.0), 0, 120, false, 0.0), None);
        // speed arrives: once
        assert_eq!(
            l.update(at(4.0), 30, 130, true, 12.5),
            Some(SpeedEvent::Available(12.5))
        );
        assert_eq!(l.update(at(5.0), 70, 130, true, 12.5), None);
        // stale: logged, then back: logged
        assert_eq!(
            l.update(at(6.0), 80, 160, false, 12.5),
            Some(SpeedEvent::Stale { episodes: 1 })
        );
        assert_eq!(l.update(at(7.0), 80, 200, false, 12.5), None);
        assert_eq!(
            l.update(at(8.0), 120, 200, true, 13.0),
            Some(SpeedEvent::Again(13.0))
        );
        // flapping within 10 s of the last stale line: silent, counted
        assert_eq!(l.update(at(9.0), 140, 220, false, 13.0), None);
        assert_eq!(l.update(at(10.0), 180, 220, true, 13.0), None);
        // a short stale period inside one tick (last block fresh) counts
        assert_eq!(l.update(at(11.0), 210, 225, true, 13.0), None);
        assert_eq!(l.update(at(12.0), 250, 225, true, 13.0), None);
        // 10 s after the last stale line: logged with the episodes since
        assert_eq!(
            l.update(at(16.5), 260, 250, false, 13.0),
            Some(SpeedEvent::Stale { episodes: 3 })
        );
        // audio stops while stale: silent
        assert_eq!(l.update(at(17.5), 260, 250, false, 13.0), None);
    }

    #[test]
    fn speed_available_then_stale_in_one_tick_is_reported() {
        let t0 = Instant::now();
        let mut l = SpeedLog::new();
        assert_eq!(
            l.update(t0, 5, 10, false, 9.0),
            Some(SpeedEvent::Available(9.0))
        );
        assert_eq!(
            l.update(t0 + Duration::from_secs(1), 5, 50, false, 9.0),
            Some(SpeedEvent::Stale { episodes: 1 })
        );
    }
}
