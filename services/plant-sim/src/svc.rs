//! Service plumbing outside the real-time loop: the non-real-time helper
//! thread (`WATCHDOG=1` through [`grip_io::systemd::Watchdog`] while the
//! heartbeat advances; transition logging, never per cycle). `READY=1`,
//! `STATUS=` and `STOPPING=1` come from [`grip_io::systemd`] too.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::systemd::{Watchdog, WatchdogPoll, notify_status};

use crate::sim::PlantStatus;

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

fn helper(s: &PlantStatus, done: &AtomicBool) {
    let mut wd = Watchdog::from_env(s.heartbeat.load(Ordering::Relaxed));
    let tick = wd.tick();
    let mut phase = s.phase.load(Ordering::Relaxed);
    let mut timed_out = s.cmd_timed_out.load(Ordering::Relaxed);
    let mut faults = 0u64;
    let mut io = 0u64;
    let mut last_report = Instant::now();
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let beat = s.heartbeat.load(Ordering::Relaxed);
        if wd.poll(beat, Instant::now()) == WatchdogPoll::Stalled {
            tracing::warn!(
                heartbeat = beat,
                "plant loop heartbeat stalled: watchdog not fed"
            );
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
