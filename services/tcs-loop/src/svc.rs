//! Service plumbing outside the real-time loop: systemd notification and the
//! non-real-time helper thread (watchdog pings while the loop's heartbeat
//! advances; logging of state transitions, never per cycle).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sd_notify::NotifyState;

use crate::cycle::SharedStatus;

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

/// The watchdog period from `WATCHDOG_USEC`, if systemd (or `grip drive`)
/// set one. As `sd_watchdog_enabled(3)`: when `WATCHDOG_PID` is set it must
/// be this process (sd-notify 0.4 also requires it to be set at all; we do
/// not, so a manager that sets only `WATCHDOG_USEC` works too).
pub fn watchdog_period() -> Option<Duration> {
    let usec: u64 = std::env::var("WATCHDOG_USEC").ok()?.trim().parse().ok()?;
    if let Ok(pid) = std::env::var("WATCHDOG_PID")
        && pid.trim().parse::<u32>().ok() != Some(std::process::id())
    {
        return None;
    }
    (usec > 0).then(|| Duration::from_micros(usec))
}

/// Spawns the helper thread (call it *before* the calling thread switches to
/// SCHED_FIFO so the helper stays SCHED_OTHER). It wakes every 50 ms (or at
/// half the watchdog period if shorter), sends `WATCHDOG=1` at half the
/// watchdog period only if the heartbeat advanced since the last ping, and
/// logs transitions: safe state entered/left, ARTE estimates stopped
/// (none for 1 s while ARTE is on) / resumed, new E2E faults, bus errors and
/// deadline misses (at most one line per kind per second). Ends when `done`
/// is set.
pub fn spawn_helper(
    status: Arc<SharedStatus>,
    arte: bool,
    done: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("tcs-helper".into())
        .spawn(move || helper(&status, arte, &done))
}

fn helper(s: &SharedStatus, arte: bool, done: &AtomicBool) {
    let wd = watchdog_period().map(|p| p / 2);
    let tick = wd
        .map_or(Duration::from_millis(50), |h| {
            h.min(Duration::from_millis(50))
        })
        .max(Duration::from_millis(1));
    let mut last_ping = Instant::now();
    let mut beat_at_ping = s.heartbeat.load(Ordering::Relaxed);
    let mut safe = s.safe_state.load(Ordering::Relaxed);
    let mut road_n = 0u64;
    let mut road_changed = Instant::now();
    let mut road_stale = false;
    let mut faults = 0u64;
    let mut bus_err = 0u64;
    let mut misses = 0u64;
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
                last_ping = Instant::now();
            } else {
                tracing::warn!(
                    heartbeat = beat,
                    "control loop heartbeat stalled: watchdog not fed"
                );
                last_ping = Instant::now();
            }
        }
        let now_safe = s.safe_state.load(Ordering::Relaxed);
        if now_safe != safe {
            if now_safe {
                tracing::warn!(
                    entries = s.safe_entries.load(Ordering::Relaxed),
                    "SAFE STATE entered: sensor or driver-demand frames missing; commanding 0 N m, enable cleared"
                );
            } else {
                tracing::info!("safe state left: inputs valid again; controller reset");
            }
            safe = now_safe;
        }
        if arte {
            let n = s.road_estimates.load(Ordering::Relaxed);
            if n != road_n {
                if road_stale {
                    tracing::info!("ARTE road estimates arriving again");
                }
                road_n = n;
                road_changed = Instant::now();
                road_stale = false;
            } else if !road_stale && road_changed.elapsed() >= Duration::from_secs(1) {
                tracing::warn!(
                    "no ARTE road estimate for 1 s (arte dead or not started): controller falls back to its no-ARTE behaviour by age"
                );
                road_stale = true;
            }
        }
        if last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            let f = s.faults_total.load(Ordering::Relaxed);
            if f != faults {
                tracing::warn!(total = f, new = f - faults, "CAN E2E faults");
                faults = f;
            }
            let b = s.bus_errors.load(Ordering::Relaxed);
            if b != bus_err {
                tracing::warn!(total = b, new = b - bus_err, "CAN bus send/receive errors");
                bus_err = b;
            }
            let m = s.deadline_misses.load(Ordering::Relaxed);
            if m != misses {
                tracing::warn!(total = m, new = m - misses, "deadline misses");
                misses = m;
            }
        }
    }
}
