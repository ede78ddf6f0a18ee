//! The non-real-time helper thread beside the plant loop (the loop through
//! [`grip_io::service::monitor`]: `WATCHDOG=1` while the heartbeat
//! advances; transitions logged, never per cycle). `READY=1`, `STATUS=`
//! and `STOPPING=1` come from [`grip_io::systemd`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Instant;

use grip_io::service::monitor::{self, Changed, Count, HelperError, Monitor};
use grip_io::systemd::notify_status;
use grip_io::warn_if_grew;

use crate::cycle::PlantStatus;

/// Spawns the helper thread (before the caller goes SCHED_FIFO). Every
/// 50 ms (or half the watchdog period if shorter) it pings the watchdog if
/// the heartbeat advanced and logs transitions: scenario started/ended,
/// command timeout entered (with the episode count)/left, new E2E faults,
/// CAN errors and failed ground-truth publishes (at most once per second).
pub fn spawn_helper(
    status: Arc<PlantStatus>,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    let m = PlantMonitor {
        phase: Changed::new(status.phase.load(Ordering::Relaxed)),
        timed_out: Changed::new(status.cmd_timed_out.load(Ordering::Relaxed)),
        faults: Count::default(),
        io_errors: Count::default(),
        truth_errors: Count::default(),
        s: status,
    };
    monitor::spawn("plant-helper", m, done)
}

struct PlantMonitor {
    s: Arc<PlantStatus>,
    phase: Changed<u8>,
    timed_out: Changed<bool>,
    faults: Count,
    io_errors: Count,
    truth_errors: Count,
}

impl Monitor for PlantMonitor {
    fn heartbeat(&self) -> u64 {
        self.s.heartbeat.load(Ordering::Relaxed)
    }

    fn stalled(&self, heartbeat: u64) {
        tracing::warn!(heartbeat, "plant loop heartbeat stalled: watchdog not fed");
    }

    fn tick(&mut self, _now: Instant) {
        let s = &self.s;
        match self.phase.update(s.phase.load(Ordering::Relaxed)) {
            Some(1) => {
                tracing::info!("scenario started");
                notify_status("scenario running");
            }
            Some(3) => {
                tracing::info!(
                    "pre-roll: rolling at v0 over the microphone's lead to x = 0 before the scenario clock starts"
                );
                notify_status("pre-roll");
            }
            Some(2) => {
                tracing::info!("scenario ended: zero torque, zero demand");
                notify_status("scenario ended");
            }
            _ => {}
        }
        match self
            .timed_out
            .update(s.cmd_timed_out.load(Ordering::Relaxed))
        {
            // The inverter starts timed out (no command yet, not counted as
            // an episode): that is the start, not a fault.
            Some(true) => match s.cmd_timeouts.load(Ordering::Relaxed) {
                0 => tracing::info!(
                    "inverter: no TorqueCommand yet: torque zero until the first valid one (CmdTimeout=1)"
                ),
                episodes => tracing::warn!(
                    episodes,
                    "inverter: no valid TorqueCommand within the timeout: torque zeroed (CmdTimeout=1)"
                ),
            },
            Some(false) => {
                tracing::info!("inverter: valid TorqueCommand frames again: torque resumed")
            }
            None => {}
        }
    }

    fn report(&mut self, _now: Instant) {
        let s = &self.s;
        warn_if_grew!(
            self.faults,
            s.faults_total.load(Ordering::Relaxed),
            "inverter: CAN E2E faults on TorqueCommand"
        );
        warn_if_grew!(
            self.io_errors,
            s.io_errors.load(Ordering::Relaxed),
            "CAN errors"
        );
        warn_if_grew!(
            self.truth_errors,
            s.truth_errors.load(Ordering::Relaxed),
            "publishing the ground truth failed (audio-acq's synthesiser and the recorder miss those samples)"
        );
    }
}
