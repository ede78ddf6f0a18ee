//! Service plumbing outside the real-time loop: systemd notification and the
//! non-real-time helper thread (watchdog pings while the heartbeat advances;
//! transition logging, never per cycle).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sd_notify::NotifyState;

use crate::sim::PlantStatus;

/// `READY=1` plus a `STATUS=` line (no-op without `NOTIFY_SOCKET`).
pub fn notify_ready(status: &str) {
    if let Err(e) = sd_notify::notify(false, &[NotifyState::Ready, NotifyState::Status(status)]) {
        tracing::warn!("sd_notify READY failed: {e}");
    }
}

/// A `STATUS=` line.
pub fn notify_status(status: &str) {
    let _ = sd_notify::notify(false, &[NotifyState::Status(status)]);
}

/// `STOPPING=1`.
pub fn notify_stopping() {
    let _ = sd_notify::notify(false, &[NotifyState::Stopping]);
}

/// Spawns the helper thread (before the caller goes SCHED_FIFO). Every
/// 50 ms (or half the watchdog period if shorter) it pings the watchdog if
/// the heartbeat advanced and logs transitions: scenario started/ended,
/// command timeout entered (with the episode count)/left, new E2E faults and
/// I/O errors (at most once per second).
pub fn spawn_helper(
    status: Arc<PlantStatus>,
    done: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("plant-helper".into())
        .spawn(move || helper(&status, &done))
}

/// The watchdog period from `WATCHDOG_USEC`, if set. As
/// `sd_watchdog_enabled(3)`: when `WATCHDOG_PID` is set it must be this
/// process; unlike sd-notify 0.4 it need not be set.
pub fn watchdog_period() -> Option<Duration> {
    let usec: u64 = std::env::var("WATCHDOG_USEC").ok()?.trim().parse().ok()?;
    if let Ok(pid) = std::env::var("WATCHDOG_PID")
        && pid.trim().parse::<u32>().ok() != Some(std::process::id())
    {
        return None;
    }
    (usec > 0).then(|| Duration::from_micros(usec))
}

fn helper(s: &PlantStatus, done: &AtomicBool) {
    let wd = watchdog_period().map(|p| p / 2);
    let tick = wd
        .map_or(Duration::from_millis(50), |h| {
            h.min(Duration::from_millis(50))
        })
        .max(Duration::from_millis(1));
    let mut last_ping = Instant::now();
    let mut beat_at_ping = s.heartbeat.load(Ordering::Relaxed);
    let mut phase = s.phase.load(Ordering::Relaxed);
    let mut timed_out = s.cmd_timed_out.load(Ordering::Relaxed);
    let mut faults = 0u64;
    let mut io = 0u64;
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
                    "plant loop heartbeat stalled: watchdog not fed"
                );
            }
            last_ping = Instant::now();
        }
        let p = s.phase.load(Ordering::Relaxed);
        if p != phase {
            match p {
                1 => {
                    tracing::info!("scenario started");
                    notify_status("scenario running");
                }
                2 => {
                    tracing::info!("scenario ended: zero torque, zero demand");
                    notify_status("scenario ended");
                }
                _ => {}
            }
            phase = p;
        }
        let t = s.cmd_timed_out.load(Ordering::Relaxed);
        if t != timed_out {
            if t {
                tracing::warn!(
                    episodes = s.cmd_timeouts.load(Ordering::Relaxed),
                    "inverter: no valid TorqueCommand within the timeout: torque zeroed (CmdTimeout=1)"
                );
            } else {
                tracing::info!("inverter: valid TorqueCommand frames again: torque resumed");
            }
            timed_out = t;
        }
        if last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            let f = s.faults_total.load(Ordering::Relaxed);
            if f != faults {
                tracing::warn!(
                    total = f,
                    new = f - faults,
                    "inverter: CAN E2E faults on TorqueCommand"
                );
                faults = f;
            }
            let e = s.io_errors.load(Ordering::Relaxed);
            if e != io {
                tracing::warn!(total = e, new = e - io, "CAN / publish errors");
                io = e;
            }
        }
    }
}
