//! The non-real-time helper thread every service runs beside its loop
//! (spawned *before* the caller switches to SCHED_FIFO, so it stays
//! SCHED_OTHER and unpinned).
//!
//! Every tick (50 ms, or half the watchdog period if shorter;
//! [`Watchdog::tick`]) it sends `WATCHDOG=1` at half the watchdog period
//! if the loop's heartbeat advanced (else the service's [`Monitor::stalled`]
//! line), then calls [`Monitor::tick`] (transitions, at tick resolution)
//! and, once per second, [`Monitor::report`] (counters that grew: at most
//! one line per kind per second). Nothing here runs per cycle or per
//! block: the loops only store counters in atomics.
//!
//! The pieces a service's monitor is made of: [`Count`] (a counter that
//! grew → [`warn_if_grew!`](crate::warn_if_grew) logs its total and the new ones), [`Flow`] (a stream
//! that stopped for a while / started / came back) and [`Changed`] (a
//! state that changed).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::systemd::{Watchdog, WatchdogPoll};

#[doc(hidden)]
pub use tracing;

/// What a service's helper thread watches (its loop's shared counters).
pub trait Monitor: Send + 'static {
    /// The loop's heartbeat now (advances while the loop runs).
    fn heartbeat(&self) -> u64;

    /// The watchdog came due and the heartbeat had not moved: log it (the
    /// watchdog is not fed; systemd restarts the service after a period).
    fn stalled(&self, heartbeat: u64);

    /// Every tick, after the watchdog: transitions.
    fn tick(&mut self, _now: Instant) {}

    /// Once per second, after [`Self::tick`]: counters that grew.
    fn report(&mut self, _now: Instant) {}
}

/// How often [`Monitor::report`] runs.
pub const REPORT_INTERVAL: Duration = Duration::from_secs(1);

/// The helper thread could not be started (a start-up error of the
/// service).
#[derive(Debug, thiserror::Error)]
#[error("cannot start the helper thread: {0}")]
pub struct HelperError(#[source] pub std::io::Error);

/// Spawns the helper thread `name` running `monitor` until `done` is set.
pub fn spawn(
    name: &str,
    monitor: impl Monitor,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || run(monitor, &done))
        .map_err(HelperError)
}

fn run(mut m: impl Monitor, done: &AtomicBool) {
    let mut wd = Watchdog::from_env(m.heartbeat());
    let tick = wd.tick();
    let mut last_report = Instant::now();
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let beat = m.heartbeat();
        let now = Instant::now();
        if wd.poll(beat, now) == WatchdogPoll::Stalled {
            m.stalled(beat);
        }
        m.tick(now);
        if last_report.elapsed() >= REPORT_INTERVAL {
            last_report = Instant::now();
            m.report(last_report);
        }
    }
}

/// A counter the helper reports on when it grows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Count {
    last: u64,
}

impl Count {
    /// Last seen at `v`.
    pub fn new(v: u64) -> Self {
        Self { last: v }
    }

    /// The value at the last [`Self::grew`].
    pub fn last(&self) -> u64 {
        self.last
    }

    /// By how much `now` exceeds the last value (`None` if it does not);
    /// `now` becomes the last value either way (a counter of a restarted
    /// peer that went down is followed, not reported).
    pub fn grew(&mut self, now: u64) -> Option<u64> {
        let last = std::mem::replace(&mut self.last, now);
        (now > last).then(|| now - last)
    }
}

/// `warn_if_grew!(count, now, "what")`: [`Count::grew`], and if it did, a
/// `tracing` warning `what` with `total = now` and `new` (since the last
/// line); `warn_if_grew!(count, now, "what", key = value, ...)` adds
/// fields, evaluated only when the line is written. A macro so that the
/// line's target is the calling service's module (log filters such as
/// `RUST_LOG=grip_tcs_loop=warn` keep working).
#[macro_export]
macro_rules! warn_if_grew {
    ($count:expr, $now:expr, $what:literal $(, $key:ident = $value:expr)* $(,)?) => {{
        let now: u64 = $now;
        if let Some(new) = $count.grew(now) {
            $crate::service::monitor::tracing::warn!(total = now, new, $($key = $value,)* $what);
        }
    }};
}

/// A stream followed by its message counter: did it start, stop for
/// `after`, come back?
#[derive(Debug, Clone, Copy)]
pub struct Flow {
    count: Count,
    changed_at: Instant,
    stalled: bool,
    first: bool,
    after: Duration,
}

/// What [`Flow::update`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlowEvent {
    /// The counter moved, and either for the first time or after a
    /// [`FlowEvent::Stopped`] (or both).
    Moving {
        /// The first movement since [`Flow::new`].
        first: bool,
        /// It had been reported stopped.
        after_stall: bool,
    },
    /// The counter has not moved for `after` (reported once per stop).
    Stopped,
}

impl Flow {
    /// A stream whose counter is `count` at `now`; it counts as stopped
    /// after `after` without movement.
    pub fn new(count: u64, now: Instant, after: Duration) -> Self {
        Self {
            count: Count::new(count),
            changed_at: now,
            stalled: false,
            first: true,
            after,
        }
    }

    /// Whether the stream is currently reported stopped.
    pub fn is_stalled(&self) -> bool {
        self.stalled
    }

    /// Takes the counter `count` at `now`.
    pub fn update(&mut self, count: u64, now: Instant) -> Option<FlowEvent> {
        if count != self.count.last() {
            self.count = Count::new(count);
            self.changed_at = now;
            let ev = (self.first || self.stalled).then_some(FlowEvent::Moving {
                first: self.first,
                after_stall: self.stalled,
            });
            self.first = false;
            self.stalled = false;
            ev
        } else if !self.stalled && now.saturating_duration_since(self.changed_at) >= self.after {
            self.stalled = true;
            Some(FlowEvent::Stopped)
        } else {
            None
        }
    }
}

/// A state the helper logs when it changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Changed<T> {
    last: T,
}

impl<T: PartialEq + Copy> Changed<T> {
    /// Currently `v`.
    pub fn new(v: T) -> Self {
        Self { last: v }
    }

    /// `Some(v)` if `v` differs from the last value (which it becomes).
    pub fn update(&mut self, v: T) -> Option<T> {
        (v != self.last).then(|| {
            self.last = v;
            v
        })
    }
}

/// A SocketCAN interface's presence as a service's loop shares it (gone
/// now, sockets reopened so far: [`crate::can::AnyBus::presence`]), followed
/// by its helper thread, which logs each change with
/// [`log_bus_presence!`](crate::log_bus_presence): tcs-loop and plant-sim
/// say it in the same words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusPresence {
    gone: Changed<bool>,
}

/// What [`BusPresence::update`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusEvent {
    /// The interface is gone (deleted or unplugged: its socket unbound).
    Gone,
    /// It is back: the socket was reopened on it.
    Back {
        /// Sockets reopened so far.
        reopens: u64,
    },
}

impl Default for BusPresence {
    fn default() -> Self {
        Self::new()
    }
}

impl BusPresence {
    /// The interface present (as at start-up).
    pub fn new() -> Self {
        Self {
            gone: Changed::new(false),
        }
    }

    /// The loop's `gone` flag and reopen count now: the change, if any.
    pub fn update(&mut self, gone: bool, reopens: u64) -> Option<BusEvent> {
        self.gone.update(gone).map(|g| {
            if g {
                BusEvent::Gone
            } else {
                BusEvent::Back { reopens }
            }
        })
    }
}

/// `log_bus_presence!(presence, gone, reopens)`: [`BusPresence::update`],
/// and a line for a change: an error when the interface is gone, a warning
/// (`reopens = N`) when it is back. A macro so that the line's target is
/// the calling service's module, as [`warn_if_grew!`](crate::warn_if_grew).
#[macro_export]
macro_rules! log_bus_presence {
    ($presence:expr, $gone:expr, $reopens:expr $(,)?) => {{
        match $presence.update($gone, $reopens) {
            Some($crate::service::monitor::BusEvent::Gone) => {
                $crate::service::monitor::tracing::error!(
                    "CAN INTERFACE GONE (deleted or unplugged: ENODEV/ENXIO): no frame in or out; the socket is reopened when an interface of its name is back (checked every 100 ms)"
                )
            }
            Some($crate::service::monitor::BusEvent::Back { reopens }) => {
                $crate::service::monitor::tracing::warn!(
                    reopens,
                    "CAN interface back: socket reopened on it (same name and receive filters)"
                )
            }
            None => {}
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    #[test]
    fn count_reports_growth_only() {
        let mut c = Count::new(3);
        assert_eq!(c.grew(3), None);
        assert_eq!(c.grew(10), Some(7));
        assert_eq!(c.grew(10), None);
        // a restarted peer's counter going down: followed, not reported
        assert_eq!(c.grew(2), None);
        assert_eq!(c.last(), 2);
        assert_eq!(c.grew(5), Some(3));
    }

    #[test]
    fn warn_if_grew_follows_the_counter() {
        let mut c = Count::new(1);
        crate::warn_if_grew!(c, 5, "x grew");
        assert_eq!(c.last(), 5);
        crate::warn_if_grew!(c, 2, "x grew");
        assert_eq!(c.grew(3), Some(1));
    }

    #[test]
    fn flow_first_stop_and_back() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let mut f = Flow::new(0, t0, Duration::from_secs(1));
        assert_eq!(f.update(0, at(500)), None);
        assert_eq!(
            f.update(4, at(600)),
            Some(FlowEvent::Moving {
                first: true,
                after_stall: false
            })
        );
        assert_eq!(f.update(9, at(700)), None);
        assert_eq!(f.update(9, at(1600)), None);
        assert_eq!(f.update(9, at(1700)), Some(FlowEvent::Stopped));
        assert!(f.is_stalled());
        assert_eq!(f.update(9, at(5000)), None, "reported once");
        assert_eq!(
            f.update(10, at(5100)),
            Some(FlowEvent::Moving {
                first: false,
                after_stall: true
            })
        );
        assert!(!f.is_stalled());
    }

    #[test]
    fn flow_stopped_before_it_ever_started() {
        let t0 = Instant::now();
        let mut f = Flow::new(0, t0, Duration::from_secs(1));
        assert_eq!(
            f.update(0, t0 + Duration::from_secs(1)),
            Some(FlowEvent::Stopped)
        );
        assert_eq!(
            f.update(1, t0 + Duration::from_secs(2)),
            Some(FlowEvent::Moving {
                first: true,
                after_stall: true
            })
        );
    }

    #[test]
    fn changed_reports_transitions() {
        let mut c = Changed::new(false);
        assert_eq!(c.update(false), None);
        assert_eq!(c.update(true), Some(true));
        assert_eq!(c.update(true), None);
        assert_eq!(c.update(false), Some(false));
    }

    #[test]
    fn bus_presence_reports_gone_and_back_once_each() {
        let mut p = BusPresence::new();
        assert_eq!(p.update(false, 0), None);
        assert_eq!(p.update(true, 0), Some(BusEvent::Gone));
        assert_eq!(p.update(true, 0), None, "reported once");
        assert_eq!(p.update(false, 1), Some(BusEvent::Back { reopens: 1 }));
        assert_eq!(p.update(false, 1), None);
        // the macro: the same transitions, logged
        let mut q = BusPresence::new();
        crate::log_bus_presence!(q, true, 0);
        assert_eq!(q.update(true, 0), None);
    }

    struct Probe {
        beat: Arc<AtomicU64>,
        ticks: Arc<AtomicU64>,
    }

    impl Monitor for Probe {
        fn heartbeat(&self) -> u64 {
            self.beat.load(Ordering::Relaxed)
        }
        fn stalled(&self, _: u64) {}
        fn tick(&mut self, _: Instant) {
            self.ticks.fetch_add(1, Ordering::Relaxed);
        }
    }

    #[test]
    fn spawned_monitor_ticks_until_done() {
        let ticks = Arc::new(AtomicU64::new(0));
        let done = Arc::new(AtomicBool::new(false));
        let h = spawn(
            "probe",
            Probe {
                beat: Arc::new(AtomicU64::new(0)),
                ticks: Arc::clone(&ticks),
            },
            Arc::clone(&done),
        )
        .unwrap();
        let t0 = Instant::now();
        while ticks.load(Ordering::Relaxed) < 2 {
            assert!(t0.elapsed() < Duration::from_secs(10), "no ticks");
            std::thread::sleep(Duration::from_millis(10));
        }
        done.store(true, Ordering::Relaxed);
        h.join().unwrap();
    }
}
