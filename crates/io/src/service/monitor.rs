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
/// service). The OS's reason is said in the message, not also returned as
/// the source (a chain printed in full would say it twice).
#[derive(Debug, thiserror::Error)]
#[error("cannot start the helper thread: {0}")]
pub struct HelperError(pub std::io::Error);

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
    /// [`Self::grew_spaced`]: the value at the last call, the reports
    /// waited since the last line, the reports to wait before the next
    /// (0 until the first line: 1), and the reports in a row without
    /// growth.
    seen: u64,
    since: u32,
    wait: u32,
    quiet: u32,
    /// Reports the last line covered.
    over: u32,
}

/// The longest wait between two lines of a counter that keeps growing, in
/// the helper's reports (one per [`REPORT_INTERVAL`], 1 s): 64 s.
pub const MAX_REPORT_SPACING: u32 = 64;

impl Count {
    /// Last seen at `v`.
    pub fn new(v: u64) -> Self {
        Self {
            last: v,
            seen: v,
            ..Self::default()
        }
    }

    /// [`Self::grew`] for a line at most every so many reports, spaced out
    /// while the counter keeps growing: called once per report, it returns
    /// the growth since the last line (`None` if none, or not yet time)
    /// after 1 report, then 2, 4, ... up to [`MAX_REPORT_SPACING`] while
    /// the counter grows in every window, and again after 1 once it has
    /// stood still for a whole window. A persistent fault (a muted
    /// microphone, deadline misses on a loaded ECU) then writes 7 lines in
    /// its first two minutes and one a minute after, not one a second
    /// (86 400 lines a day per counter, under journald's rate limit, so
    /// nothing thinned them); nothing is lost: each line's `new` is all the
    /// growth since the previous line. A counter that goes down (a
    /// restarted peer) is followed, not reported, and starts over.
    pub fn grew_spaced(&mut self, now: u64) -> Option<u64> {
        if now < self.seen {
            *self = Self::new(now);
            return None;
        }
        self.wait = self.wait.max(1);
        self.since = self.since.saturating_add(1);
        self.quiet = if now > self.seen {
            0
        } else {
            self.quiet.saturating_add(1)
        };
        self.seen = now;
        if now > self.last && self.since >= self.wait {
            let new = now - self.last;
            self.last = now;
            self.over = self.since;
            self.since = 0;
            self.wait = (self.wait * 2).min(MAX_REPORT_SPACING);
            return Some(new);
        }
        if now == self.last && self.quiet >= self.wait {
            self.wait = 1;
        }
        None
    }

    /// The reports the last line of [`Self::grew_spaced`] covers (since
    /// the line before it, or since the start): its `over_s` with one
    /// report a second.
    pub fn spacing(&self) -> u32 {
        self.over
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

/// `warn_if_grew!(count, now, "what")`: [`Count::grew_spaced`], and if it
/// is time for a line, a `tracing` warning `what` with `total = now`, `new`
/// (since the last line) and `over_s` (the seconds that line covers: 1,
/// then 2, 4, ... 64 while the counter keeps growing); `warn_if_grew!(count,
/// now, "what", key = value, ...)` adds fields, evaluated only when the
/// line is written. Called once per report ([`REPORT_INTERVAL`]). A macro
/// so that the line's target is the calling service's module (log filters
/// such as `RUST_LOG=grip_tcs_loop=warn` keep working).
#[macro_export]
macro_rules! warn_if_grew {
    ($count:expr, $now:expr, $what:literal $(, $key:ident = $value:expr)* $(,)?) => {{
        let now: u64 = $now;
        if let Some(new) = $count.grew_spaced(now) {
            let over_s = $count.spacing();
            $crate::service::monitor::tracing::warn!(total = now, new, over_s, $($key = $value,)* $what);
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

/// Changes of a [`Toggle`] within [`FLAP_WINDOW`] that make it flapping.
pub const FLAP_CHANGES: usize = 10;
/// The window of [`FLAP_CHANGES`], and the quiet time after which a
/// flapping [`Toggle`] is steady again.
pub const FLAP_WINDOW: Duration = Duration::from_secs(10);
/// The longest time between two lines of a flapping [`Toggle`].
pub const FLAP_SUMMARY: Duration = Duration::from_secs(60);

/// A two-valued state the helper logs at each change (as [`Changed`]),
/// unless it flaps: from the [`FLAP_CHANGES`]th change within
/// [`FLAP_WINDOW`] on, changes are counted and summed up in one line a
/// minute ([`FLAP_SUMMARY`]), until the state has stood still for a whole
/// window. An input that comes and goes (a marginal bus: the loop's safe
/// state entered and left at every helper tick) otherwise writes up to 40
/// lines a second, millions a day, and the journal rotates away what came
/// before it. Allocation-free.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Toggle {
    state: Changed<bool>,
    /// The last changes' times (a ring of [`FLAP_CHANGES`]).
    recent: [Option<Instant>; FLAP_CHANGES],
    next: usize,
    /// Flapping: (since the last line, changes since it, the last change).
    flapping: Option<(Instant, u64, Instant)>,
}

/// What [`Toggle::update`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToggleEvent {
    /// A change, to this value.
    Changed(bool),
    /// Flapping: `changes` changes over the last `over` (the first such
    /// event: the [`FLAP_CHANGES`] within [`FLAP_WINDOW`] that started
    /// it), the state now `now`.
    Flapping {
        /// Changes over `over`.
        changes: u64,
        /// The time they span.
        over: Duration,
        /// The state now.
        now: bool,
    },
    /// Steady again, at `now`, after `changes` changes since the last line.
    Steady {
        /// Changes since the last line.
        changes: u64,
        /// The state now.
        now: bool,
    },
}

impl Toggle {
    /// Currently `v`.
    pub fn new(v: bool) -> Self {
        Self {
            state: Changed::new(v),
            recent: [None; FLAP_CHANGES],
            next: 0,
            flapping: None,
        }
    }

    /// Takes the state `v` at `now`.
    pub fn update(&mut self, v: bool, now: Instant) -> Option<ToggleEvent> {
        let changed = self.state.update(v).is_some();
        if changed {
            self.recent[self.next] = Some(now);
            self.next = (self.next + 1) % FLAP_CHANGES;
        }
        match &mut self.flapping {
            None if changed => {
                // the oldest of the last FLAP_CHANGES changes, within the window
                let oldest = self.recent[self.next];
                match oldest.filter(|t| now.saturating_duration_since(*t) < FLAP_WINDOW) {
                    Some(t0) => {
                        self.flapping = Some((now, 0, now));
                        Some(ToggleEvent::Flapping {
                            changes: FLAP_CHANGES as u64,
                            over: now.saturating_duration_since(t0),
                            now: v,
                        })
                    }
                    None => Some(ToggleEvent::Changed(v)),
                }
            }
            None => None,
            Some((line, changes, last)) => {
                if changed {
                    *changes += 1;
                    *last = now;
                }
                if now.saturating_duration_since(*last) >= FLAP_WINDOW {
                    let changes = *changes;
                    self.flapping = None;
                    self.recent = [None; FLAP_CHANGES];
                    Some(ToggleEvent::Steady { changes, now: v })
                } else if now.saturating_duration_since(*line) >= FLAP_SUMMARY {
                    let ev = ToggleEvent::Flapping {
                        changes: *changes,
                        over: now.saturating_duration_since(*line),
                        now: v,
                    };
                    *line = now;
                    *changes = 0;
                    Some(ev)
                } else {
                    None
                }
            }
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

    /// A counter that grows every second is written at 1, 3, 7, 15, 31,
    /// 63, 127 s, then every 64 s, each line with all the growth since the
    /// last; once it stands still for a whole window, the next growth is
    /// written at once again; a counter that goes down starts over.
    #[test]
    fn a_persistent_growth_is_written_ever_more_seldom_and_nothing_is_lost() {
        let mut c = Count::new(0);
        let mut lines = Vec::new();
        let mut written = 0;
        for t in 1..=86_400u64 {
            if let Some(new) = c.grew_spaced(t * 3) {
                lines.push((t, new, c.spacing()));
                written += new;
            }
        }
        let at: Vec<u64> = lines.iter().take(9).map(|l| l.0).collect();
        assert_eq!(at, [1, 3, 7, 15, 31, 63, 127, 191, 255]);
        assert_eq!(lines[0].1, 3);
        assert_eq!((lines[1].1, lines[1].2), (6, 2));
        assert_eq!((lines[8].1, lines[8].2), (192, 64));
        // a day: 7 lines in the first two minutes, then one each 64 s
        assert_eq!(lines.len(), 7 + (86_400 - 127) / 64);
        assert!(lines.len() < 1400, "{}", lines.len());
        let last = lines.last().unwrap().0;
        assert_eq!(written, last * 3, "every line's new adds up to the total");
        // the counter stands for a whole window (64 reports), then grows
        // once: written at once, as a first growth
        let total = 86_400 * 3;
        let mut pending = None;
        for _ in 0..130 {
            if let Some(new) = c.grew_spaced(total) {
                pending = Some(new);
            }
        }
        assert_eq!(pending, Some(total - last * 3), "the rest, within a window");
        assert_eq!(c.grew_spaced(total + 1), Some(1));
        assert_eq!(c.grew_spaced(total + 2), None, "then 2 reports");
        assert_eq!(c.grew_spaced(total + 3), Some(2));
        // isolated events far apart: each written at once
        let mut d = Count::new(10);
        for k in 0..5u64 {
            assert_eq!(d.grew_spaced(11 + k), Some(1), "event {k}");
            for _ in 0..9 {
                assert_eq!(d.grew_spaced(11 + k), None);
            }
        }
        // a restarted peer's counter goes down: followed, not written
        assert_eq!(d.grew_spaced(2), None);
        assert_eq!(d.grew_spaced(3), Some(1));
    }

    /// Changes far apart: each one; ten within 10 s: one line that says
    /// so, then one a minute with the changes since, and once the state
    /// stands still for 10 s a last line, after which a change is logged
    /// again at once.
    #[test]
    fn a_flapping_state_is_summed_up_not_logged_at_every_change() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let mut s = Toggle::new(false);
        assert_eq!(s.update(false, at(0)), None);
        assert_eq!(s.update(true, at(1000)), Some(ToggleEvent::Changed(true)));
        assert_eq!(s.update(false, at(3000)), Some(ToggleEvent::Changed(false)));
        // every 50 ms tick a change: 7 more are logged, the 10th change
        // within 10 s (the first at 1 s) starts the summary
        let mut v = false;
        let mut lines = Vec::new();
        let mut ms = 3000;
        for _ in 0..4000 {
            ms += 50;
            v = !v;
            if let Some(e) = s.update(v, at(ms)) {
                lines.push((ms, e));
            }
        }
        assert_eq!(lines.len(), 7 + 1 + 3, "{lines:?}");
        assert!(matches!(lines[6].1, ToggleEvent::Changed(_)));
        assert_eq!(
            lines[7],
            (
                3400,
                ToggleEvent::Flapping {
                    changes: 10,
                    over: Duration::from_millis(2400),
                    now: false
                }
            )
        );
        // then a line a minute, each with the 1200 changes of that minute
        for (k, (t, e)) in lines[8..].iter().enumerate() {
            assert_eq!(*t, 3400 + 60_000 * (k as u64 + 1));
            assert!(
                matches!(e, ToggleEvent::Flapping { changes: 1200, .. }),
                "{e:?}"
            );
        }
        // it stops: 10 s later, steady, with the changes since the last line
        let end = ms;
        let mut steady = None;
        for k in 1..=250 {
            if let Some(e) = s.update(v, at(end + 50 * k)) {
                steady = Some((50 * k, e));
            }
        }
        let (after, e) = steady.expect("steady again");
        assert_eq!(after, 10_000);
        let since_last = (end - lines.last().unwrap().0) / 50;
        assert_eq!(
            e,
            ToggleEvent::Steady {
                changes: since_last,
                now: v
            }
        );
        assert_eq!(
            s.update(!v, at(end + 20_000)),
            Some(ToggleEvent::Changed(!v))
        );
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
