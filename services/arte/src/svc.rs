//! Service plumbing outside the real-time loop: systemd notification and the
//! non-real-time helper thread (watchdog pings while the loop's heartbeat
//! advances; log lines on transitions, never per block).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sd_notify::NotifyState;

use crate::ArteStats;

/// `READY=1` plus a `STATUS=` line (no-op without `NOTIFY_SOCKET`).
pub fn notify_ready(status: &str) {
    if let Err(e) = sd_notify::notify(false, &[NotifyState::Ready, NotifyState::Status(status)]) {
        tracing::warn!("sd_notify READY failed: {e}");
    }
}

/// `STOPPING=1` (no-op without `NOTIFY_SOCKET`).
pub fn notify_stopping() {
    let _ = sd_notify::notify(false, &[NotifyState::Stopping]);
}

/// The watchdog period from `WATCHDOG_USEC`, if set.
pub fn watchdog_period() -> Option<Duration> {
    let mut usec = 0u64;
    sd_notify::watchdog_enabled(false, &mut usec).then(|| Duration::from_micros(usec))
}

/// Spawns the helper thread (before the caller switches to SCHED_FIFO).
/// Every 50 ms (or half the watchdog period if shorter) it sends
/// `WATCHDOG=1` at half the watchdog period if the loop's heartbeat
/// advanced, and logs transitions: audio stopped (no block for 1 s; the
/// audio-acq peer died or stalled) / resumed, lost blocks, estimator
/// restarts, refused sample rates, new xruns upstream, publish and receive
/// errors; at most one line per kind per second.
pub fn spawn_helper(
    stats: Arc<ArteStats>,
    model_rate: u32,
    done: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("arte-helper".into())
        .spawn(move || helper(&stats, model_rate, &done))
}

fn helper(s: &ArteStats, model_rate: u32, done: &AtomicBool) {
    let wd = watchdog_period().map(|p| p / 2);
    let tick = wd
        .map_or(Duration::from_millis(50), |h| {
            h.min(Duration::from_millis(50))
        })
        .max(Duration::from_millis(1));
    let mut last_ping = Instant::now();
    let mut beat_at_ping = s.heartbeat.load(Ordering::Relaxed);
    let mut blocks = 0u64;
    let mut blocks_changed = Instant::now();
    let mut audio_stale = false;
    let mut first_block = true;
    let mut lost = 0u64;
    let mut resets = 0u64;
    let mut rate_bad = 0u64;
    let mut xruns = 0u64;
    let mut pub_err = 0u64;
    let mut rx_err = 0u64;
    let mut last_report = Instant::now();
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let beat = s.heartbeat.load(Ordering::Relaxed);
        if let Some(half) = wd
            && last_ping.elapsed() >= half
        {
            if beat != beat_at_ping {
                let _ = sd_notify::notify(false, &[NotifyState::Watchdog]);
                beat_at_ping = beat;
            } else {
                tracing::warn!(
                    heartbeat = beat,
                    "arte loop heartbeat stalled: watchdog not fed"
                );
            }
            last_ping = Instant::now();
        }
        let b = s.blocks.load(Ordering::Relaxed);
        if b != blocks {
            if first_block {
                tracing::info!("first audio block received");
                first_block = false;
            } else if audio_stale {
                tracing::info!(blocks = b, "audio blocks arriving again");
            }
            audio_stale = false;
            blocks = b;
            blocks_changed = Instant::now();
        } else if !audio_stale && blocks_changed.elapsed() >= Duration::from_secs(1) {
            tracing::warn!(
                blocks = b,
                "no audio block for 1 s (audio-acq dead, stalled or not started): no road estimates"
            );
            audio_stale = true;
        }
        if last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            let v = s.lost_blocks.load(Ordering::Relaxed);
            if v != lost {
                tracing::warn!(
                    total = v,
                    new = v - lost,
                    "audio blocks lost (sequence gaps)"
                );
                lost = v;
            }
            let v = s.resets.load(Ordering::Relaxed);
            if v != resets {
                tracing::warn!(total = v, "audio stream discontinuity: estimator restarted");
                resets = v;
            }
            let v = s.rate_mismatch.load(Ordering::Relaxed);
            if v != rate_bad {
                if rate_bad == 0 {
                    tracing::error!(
                        audio_rate = s.bad_rate.load(Ordering::Relaxed),
                        model_rate,
                        "audio blocks at {} Hz but the model expects {model_rate} Hz: blocks REFUSED, no road estimates (set [audio] sample_rate in audio-acq.toml to {model_rate})",
                        s.bad_rate.load(Ordering::Relaxed)
                    );
                }
                rate_bad = v;
            }
            let v = s.xruns.load(Ordering::Relaxed);
            if v != xruns {
                if v > xruns {
                    tracing::warn!(total = v, "audio-acq reports capture overruns");
                }
                xruns = v;
            }
            let v = s.publish_errors.load(Ordering::Relaxed);
            if v != pub_err {
                tracing::warn!(total = v, "publishing road estimates failed");
                pub_err = v;
            }
            let v = s.receive_errors.load(Ordering::Relaxed);
            if v != rx_err {
                tracing::warn!(total = v, "receiving audio blocks failed");
                rx_err = v;
            }
        }
    }
}
