//! Service plumbing outside the real-time loop: the non-real-time helper
//! thread (`WATCHDOG=1` through [`grip_io::systemd::Watchdog`] while the
//! loop's heartbeat advances; logging of state transitions, never per
//! cycle). `READY=1`, `STATUS=` and `STOPPING=1` come from
//! [`grip_io::systemd`] too.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::systemd::{Watchdog, WatchdogPoll};

use crate::cycle::SharedStatus;

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
    let mut wd = Watchdog::from_env(s.heartbeat.load(Ordering::Relaxed));
    let tick = wd.tick();
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
        if wd.poll(beat, Instant::now()) == WatchdogPoll::Stalled {
            tracing::warn!(
                heartbeat = beat,
                "control loop heartbeat stalled: watchdog not fed"
            );
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
