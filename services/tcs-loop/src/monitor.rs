//! The non-real-time helper thread beside the control loop (the loop
//! through [`grip_io::service::monitor`]: `WATCHDOG=1` while the loop's
//! heartbeat advances; state transitions logged, never per cycle).
//! `READY=1`, `STATUS=` and `STOPPING=1` come from [`grip_io::systemd`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::service::monitor::{
    self, BusPresence, Count, Flow, FlowEvent, HelperError, Monitor, Toggle, ToggleEvent,
};
use grip_io::warn_if_grew;

use crate::cycle::{SafeCause, SharedStatus};

/// Spawns the helper thread (call it *before* the calling thread switches to
/// SCHED_FIFO so the helper stays SCHED_OTHER). It wakes every 50 ms (or at
/// half the watchdog period if shorter), sends `WATCHDOG=1` at half the
/// watchdog period only if the heartbeat advanced since the last ping, and
/// logs transitions: safe state entered/left, traction control inactive
/// (the controller passing the demand through without a vehicle speed) and
/// active again, ARTE estimates stopped
/// (none for 1 s while ARTE is on) / resumed, new E2E faults, bus errors and
/// deadline misses (at most one line per kind per second). Ends when `done`
/// is set.
pub fn spawn_helper(
    status: Arc<SharedStatus>,
    arte: bool,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    let m = TcsMonitor {
        safe: Toggle::new(status.safe_state.load(Ordering::Relaxed)),
        passthrough: Toggle::new(false),
        bus: BusPresence::new(),
        road: arte.then(|| Flow::new(0, Instant::now(), Duration::from_secs(1))),
        faults: Count::default(),
        bus_errors: Count::default(),
        misses: Count::default(),
        s: status,
    };
    monitor::spawn("tcs-helper", m, done)
}

struct TcsMonitor {
    s: Arc<SharedStatus>,
    safe: Toggle,
    /// The controller passing the demand through for want of a speed.
    passthrough: Toggle,
    /// The CAN interface deleted (its socket unbound) and not yet back.
    bus: BusPresence,
    /// ARTE's estimates (only while ARTE is on).
    road: Option<Flow>,
    faults: Count,
    bus_errors: Count,
    misses: Count,
}

impl Monitor for TcsMonitor {
    fn heartbeat(&self) -> u64 {
        self.s.heartbeat.load(Ordering::Relaxed)
    }

    fn stalled(&self, heartbeat: u64) {
        tracing::warn!(
            heartbeat,
            "control loop heartbeat stalled: watchdog not fed"
        );
    }

    fn tick(&mut self, now: Instant) {
        let s = &self.s;
        match self.safe.update(s.safe_state.load(Ordering::Relaxed), now) {
            Some(ToggleEvent::Changed(true)) => tracing::warn!(
                entries = s.safe_entries.load(Ordering::Relaxed),
                "SAFE STATE entered: {}; commanding 0 N m, enable cleared",
                SafeCause::describe(
                    s.safe_cause.load(Ordering::Relaxed),
                    s.inverter_fault_code.load(Ordering::Relaxed)
                )
            ),
            Some(ToggleEvent::Changed(false)) => {
                tracing::info!("safe state left: inputs valid again; controller reset")
            }
            Some(ToggleEvent::Flapping { changes, over, now }) => tracing::warn!(
                changes,
                over_s = over.as_secs_f64(),
                safe = now,
                entries = s.safe_entries.load(Ordering::Relaxed),
                "SAFE STATE FLAPPING: entered and left again and again (inputs come and go); changes summed up here once a minute until steady"
            ),
            Some(ToggleEvent::Steady { changes, now }) => tracing::warn!(
                changes,
                safe = now,
                entries = s.safe_entries.load(Ordering::Relaxed),
                "safe state steady again for 10 s"
            ),
            None => {}
        }
        match self
            .passthrough
            .update(s.passthrough.load(Ordering::Relaxed), now)
        {
            Some(ToggleEvent::Changed(true)) => tracing::warn!(
                "TRACTION CONTROL INACTIVE: no vehicle speed (OmegaRef invalid and no fresh VehicleSpeed frame); the driver's demand is passed through"
            ),
            Some(ToggleEvent::Changed(false)) => {
                tracing::info!("vehicle speed back: traction control active again")
            }
            Some(ToggleEvent::Flapping { changes, over, now }) => tracing::warn!(
                changes,
                over_s = over.as_secs_f64(),
                inactive = now,
                "TRACTION CONTROL FLAPPING: the vehicle speed comes and goes, the demand passed through meanwhile; changes summed up here once a minute until steady"
            ),
            Some(ToggleEvent::Steady { changes, now }) => tracing::warn!(
                changes,
                inactive = now,
                "traction control steady again for 10 s"
            ),
            None => {}
        }
        grip_io::log_bus_presence!(
            self.bus,
            s.bus_gone.load(Ordering::Relaxed),
            s.bus_reopens.load(Ordering::Relaxed)
        );
        if let Some(road) = &mut self.road {
            match road.update(s.road_estimates.load(Ordering::Relaxed), now) {
                Some(FlowEvent::Moving {
                    after_stall: true, ..
                }) => tracing::info!("ARTE road estimates arriving again"),
                Some(FlowEvent::Stopped) => tracing::warn!(
                    "no ARTE road estimate for 1 s (arte dead or not started): controller falls back to its no-ARTE behaviour by age"
                ),
                _ => {}
            }
        }
    }

    fn report(&mut self, _now: Instant) {
        let s = &self.s;
        warn_if_grew!(
            self.faults,
            s.faults_total.load(Ordering::Relaxed),
            "CAN E2E faults"
        );
        warn_if_grew!(
            self.bus_errors,
            s.bus_errors.load(Ordering::Relaxed),
            "CAN bus send/receive errors"
        );
        warn_if_grew!(
            self.misses,
            s.deadline_misses.load(Ordering::Relaxed),
            "deadline misses"
        );
    }
}
