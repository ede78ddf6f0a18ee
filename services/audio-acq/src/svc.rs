//! Service plumbing outside the real-time loop: systemd notification and the
//! non-real-time helper thread (watchdog pings while the loop's heartbeat
//! advances; log lines on transitions, never per block).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sd_notify::NotifyState;

use crate::AcqStatus;

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

/// Spawns the helper thread (before the caller switches to SCHED_FIFO, so
/// the helper stays SCHED_OTHER). Every 50 ms (or half the watchdog period
/// if shorter) it sends `WATCHDOG=1` at half the watchdog period if the
/// block counter advanced, and logs: new xruns, truth lost / back, unknown
/// roads, publish errors, a stalled source (no block for 1 s); at most one
/// line per kind per second. Ends when `done` is set.
pub fn spawn_helper(
    status: Arc<AcqStatus>,
    synth: bool,
    done: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("audio-acq-helper".into())
        .spawn(move || helper(&status, synth, &done))
}

fn helper(s: &AcqStatus, synth: bool, done: &AtomicBool) {
    let wd = watchdog_period().map(|p| p / 2);
    let tick = wd
        .map_or(Duration::from_millis(50), |h| {
            h.min(Duration::from_millis(50))
        })
        .max(Duration::from_millis(1));
    let mut last_ping = Instant::now();
    let mut beat_at_ping = s.blocks.load(Ordering::Relaxed);
    let mut last_beat = beat_at_ping;
    let mut beat_changed = Instant::now();
    let mut stalled = false;
    let mut xruns = 0u64;
    let mut pub_err = 0u64;
    let mut unknown = 0u64;
    let mut truth_lost: Option<bool> = None;
    let mut last_report = Instant::now();
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let beat = s.blocks.load(Ordering::Relaxed);
        if let Some(half) = wd
            && last_ping.elapsed() >= half
        {
            if beat != beat_at_ping {
                let _ = sd_notify::notify(false, &[NotifyState::Watchdog]);
                beat_at_ping = beat;
            } else {
                tracing::warn!(
                    blocks = beat,
                    "no block since the last watchdog period: watchdog not fed"
                );
            }
            last_ping = Instant::now();
        }
        if beat != last_beat {
            if stalled {
                tracing::info!(blocks = beat, "audio blocks flowing again");
                stalled = false;
            }
            last_beat = beat;
            beat_changed = Instant::now();
        } else if !stalled && beat_changed.elapsed() >= Duration::from_secs(1) {
            tracing::warn!(
                blocks = beat,
                timeouts = s.timeouts.load(Ordering::Relaxed),
                "no audio block for 1 s (device delivers no data)"
            );
            stalled = true;
        }
        if synth && beat > 0 {
            let lost = s.truth_lost.load(Ordering::Relaxed);
            if truth_lost != Some(lost) {
                match (truth_lost, lost) {
                    (_, true) => tracing::warn!(
                        received = s.truth_received.load(Ordering::Relaxed),
                        "ground truth (topic grip/plant/truth) lost or not yet received: synth follows [synth] on_truth_lost"
                    ),
                    (Some(true), false) | (None, false) => {
                        tracing::info!("ground truth arriving: synth follows road and speed")
                    }
                    _ => {}
                }
                truth_lost = Some(lost);
            }
        }
        if last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            let x = s.xruns.load(Ordering::Relaxed);
            if x != xruns {
                tracing::warn!(
                    total = x,
                    new = x.wrapping_sub(xruns),
                    "capture overruns (xruns), recovered"
                );
                xruns = x;
            }
            let p = s.publish_errors.load(Ordering::Relaxed);
            if p != pub_err {
                tracing::warn!(
                    total = p,
                    new = p - pub_err,
                    "publishing audio blocks failed"
                );
                pub_err = p;
            }
            let u = s.unknown_road.load(Ordering::Relaxed);
            if u != unknown {
                if unknown == 0 {
                    tracing::warn!(
                        "ground truth names a road the synthesiser does not know (add it to [synth] aliases): generating vehicle noise only"
                    );
                }
                unknown = u;
            }
        }
    }
}
