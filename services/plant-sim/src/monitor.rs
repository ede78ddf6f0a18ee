//! The non-real-time helper thread beside the plant loop (the loop through
//! [`grip_io::service::monitor`]: `WATCHDOG=1` while the heartbeat
//! advances; transitions logged, never per cycle). `READY=1`, `STATUS=`
//! and `STOPPING=1` come from [`grip_io::systemd`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Instant;

use grip_io::service::monitor::{self, BusPresence, Changed, Count, HelperError, Monitor};
use grip_io::systemd::notify_status;
use grip_io::warn_if_grew;

use crate::cycle::PlantStatus;

/// Spawns the helper thread (before the caller goes SCHED_FIFO). Every
/// 50 ms (or half the watchdog period if shorter) it pings the watchdog if
/// the heartbeat advanced and logs transitions: scenario started/ended,
/// command timeout entered (with the episode count)/left, the CAN
/// interface gone/back (deleted and re-created: the same lines as
/// tcs-loop's), new E2E faults, CAN errors and failed ground-truth publishes (at most once per second).
pub fn spawn_helper(
    status: Arc<PlantStatus>,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    monitor::spawn("plant-helper", PlantMonitor::new(status), done)
}

struct PlantMonitor {
    s: Arc<PlantStatus>,
    phase: Changed<u8>,
    timed_out: Changed<bool>,
    /// The CAN interface deleted (its socket unbound) and not yet back.
    bus: BusPresence,
    faults: Count,
    io_errors: Count,
    truth_errors: Count,
}

impl PlantMonitor {
    fn new(status: Arc<PlantStatus>) -> Self {
        Self {
            phase: Changed::new(status.phase.load(Ordering::Relaxed)),
            timed_out: Changed::new(status.cmd_timed_out.load(Ordering::Relaxed)),
            bus: BusPresence::new(),
            faults: Count::default(),
            io_errors: Count::default(),
            truth_errors: Count::default(),
            s: status,
        }
    }
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
        grip_io::log_bus_presence!(
            self.bus,
            s.bus_gone.load(Ordering::Relaxed),
            s.bus_reopens.load(Ordering::Relaxed)
        );
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

#[cfg(test)]
mod tests {
    use std::io::Write;
    use std::sync::Mutex;

    use grip_io::service::monitor::Monitor as _;

    use super::*;

    /// The lines a subscriber writes, kept for the test.
    #[derive(Clone, Default)]
    struct Lines(Arc<Mutex<Vec<u8>>>);

    impl Write for Lines {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Lines {
        fn take(&self) -> String {
            String::from_utf8(std::mem::take(&mut *self.0.lock().unwrap())).unwrap()
        }
    }

    /// The CAN interface deleted and re-created (what `run` stores from
    /// `AnyBus::presence` after each cycle): the helper says it is gone,
    /// once, and back with the reopen count, in tcs-loop's words
    /// (`grip_io::log_bus_presence!`); nothing while nothing changes.
    #[test]
    fn the_bus_going_and_coming_back_is_logged_as_tcs_loop_logs_it() {
        let lines = Lines::default();
        let w = lines.clone();
        let sub = tracing_subscriber::fmt()
            .with_writer(move || w.clone())
            .with_ansi(false)
            .finish();
        tracing::subscriber::with_default(sub, || {
            let status = Arc::new(PlantStatus::default());
            let mut m = PlantMonitor::new(Arc::clone(&status));
            let now = Instant::now();
            m.tick(now);
            let quiet = lines.take();
            assert!(!quiet.contains("CAN"), "{quiet}");
            status.bus_gone.store(true, Ordering::Relaxed);
            m.tick(now);
            let gone = lines.take();
            assert!(
                gone.contains("ERROR")
                    && gone.contains("CAN INTERFACE GONE (deleted or unplugged: ENODEV/ENXIO)"),
                "{gone}"
            );
            m.tick(now);
            assert_eq!(lines.take(), "", "said once");
            status.bus_reopens.store(1, Ordering::Relaxed);
            status.bus_gone.store(false, Ordering::Relaxed);
            m.tick(now);
            let back = lines.take();
            assert!(
                back.contains("WARN")
                    && back.contains("CAN interface back: socket reopened on it")
                    && back.contains("reopens=1"),
                "{back}"
            );
        });
    }
}
