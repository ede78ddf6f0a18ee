//! Service plumbing outside the real-time loop: the non-real-time helper
//! thread (`WATCHDOG=1` through [`grip_io::systemd::Watchdog`] while the
//! loop's heartbeat advances; log lines on transitions, never per block).
//! `READY=1`, `STATUS=` and `STOPPING=1` come from [`grip_io::systemd`] too.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::systemd::{Watchdog, WatchdogPoll};

use crate::AcqStatus;

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
    let mut last_beat = s.blocks.load(Ordering::Relaxed);
    let mut wd = Watchdog::from_env(last_beat);
    let tick = wd.tick();
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
        if wd.poll(beat, Instant::now()) == WatchdogPoll::Stalled {
            tracing::warn!(
                blocks = beat,
                "no block since the last watchdog period: watchdog not fed"
            );
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
