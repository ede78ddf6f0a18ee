//! systemd service notification (`sd_notify(3)`) and the heartbeat-gated
//! watchdog shared by every grip service.
//!
//! Every service runs as `Type=notify` with `WatchdogSec=` (see
//! `config/systemd/`). It says `READY=1` once set up ([`notify_ready`]),
//! `STOPPING=1` on SIGTERM ([`notify_stopping`]), and a non-real-time helper
//! pings `WATCHDOG=1` through a [`Watchdog`].
//!
//! **Ping only if the real-time loop's heartbeat advanced.** The helper
//! thread that sends the pings is not the thread doing the work: pinging
//! on a timer alone would keep a service alive whose loop is stuck
//! (deadlocked, spinning in a bad branch, starved). So each service's loop
//! increments a counter (its heartbeat) and [`Watchdog::poll`] sends
//! `WATCHDOG=1` at half the watchdog period only if that counter moved
//! since the previous ping; otherwise it reports [`WatchdogPoll::Stalled`]
//! (the caller logs its own line) and systemd kills and restarts the
//! service once a whole period passes without a ping.
//!
//! **The period follows `sd_watchdog_enabled(3)`**: `WATCHDOG_USEC` is the
//! period in µs (absent, unparsable or 0 → no watchdog); `WATCHDOG_PID`, if
//! set, must be this process's pid (it was meant for a parent, not for us),
//! and if unset `WATCHDOG_USEC` alone counts. sd-notify 0.4's
//! `watchdog_enabled` requires `WATCHDOG_PID` to be set, so a manager that
//! sets only `WATCHDOG_USEC` (as the tests do) would get no watchdog;
//! hence [`watchdog_period_from`] parses the variables itself.
//!
//! Without `NOTIFY_SOCKET` (a service started by hand or by a test) every
//! notification here is a no-op.

use std::time::{Duration, Instant};

use sd_notify::NotifyState;

/// Longest sleep between two helper-thread ticks (also the tick without a
/// watchdog): the helpers' transition logging wants about this resolution.
const MAX_TICK: Duration = Duration::from_millis(50);

/// Shortest helper tick, for very short (test) watchdog periods.
const MIN_TICK: Duration = Duration::from_millis(1);

/// Sends `states` to `$NOTIFY_SOCKET` (no-op, `Ok`, when it is unset).
fn send(states: &[NotifyState<'_>]) -> std::io::Result<()> {
    sd_notify::notify(false, states)
}

/// `READY=1` plus a `STATUS=` line; a failed send is logged as a warning
/// (no-op without `NOTIFY_SOCKET`).
pub fn notify_ready(status: &str) {
    if let Err(e) = send(&[NotifyState::Ready, NotifyState::Status(status)]) {
        tracing::warn!("sd_notify READY failed: {e}");
    }
}

/// A `STATUS=` line (no-op without `NOTIFY_SOCKET`; errors ignored).
pub fn notify_status(status: &str) {
    let _ = send(&[NotifyState::Status(status)]);
}

/// `STOPPING=1` (no-op without `NOTIFY_SOCKET`; errors ignored).
pub fn notify_stopping() {
    let _ = send(&[NotifyState::Stopping]);
}

/// The watchdog period this process was given, from `WATCHDOG_USEC` and
/// `WATCHDOG_PID` as in `sd_watchdog_enabled(3)` (see
/// [`watchdog_period_from`]). `None`: no watchdog.
pub fn watchdog_period() -> Option<Duration> {
    let usec = std::env::var("WATCHDOG_USEC").ok();
    let pid = std::env::var("WATCHDOG_PID").ok();
    watchdog_period_from(usec.as_deref(), pid.as_deref(), std::process::id())
}

/// The watchdog period from the values of `WATCHDOG_USEC` (`usec`) and
/// `WATCHDOG_PID` (`pid`) for the process `my_pid`: `None` if `usec` is
/// unset, not a whole number of µs, or 0, or if `pid` is set and is not
/// `my_pid` (an unparsable `pid` matches no process). Surrounding
/// whitespace is ignored in both.
pub fn watchdog_period_from(
    usec: Option<&str>,
    pid: Option<&str>,
    my_pid: u32,
) -> Option<Duration> {
    let usec: u64 = usec?.trim().parse().ok()?;
    if let Some(pid) = pid
        && pid.trim().parse::<u32>().ok() != Some(my_pid)
    {
        return None;
    }
    (usec > 0).then(|| Duration::from_micros(usec))
}

/// What one [`Watchdog::poll`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchdogPoll {
    /// No watchdog configured: nothing to do, ever.
    Off,
    /// Less than half the period since the last ping (or stall report).
    NotDue,
    /// Due, and the heartbeat advanced: `WATCHDOG=1` was sent.
    Fed,
    /// Due, but the heartbeat did not advance since the last ping: nothing
    /// sent. The caller logs its warning; the next report comes half a
    /// period later.
    Stalled,
}

/// The heartbeat-gated watchdog pinger of one service (see the module
/// docs). Owned by the helper thread; pure apart from the `WATCHDOG=1`
/// datagram, with time passed in, so its state machine is testable with
/// explicit [`Instant`]s.
#[derive(Debug, Clone)]
pub struct Watchdog {
    /// Half the watchdog period: the ping interval. `None`: off.
    half: Option<Duration>,
    /// Time of the last ping or stall report.
    last: Instant,
    /// Heartbeat value at the last ping (or at construction).
    beat_at_ping: u64,
}

impl Watchdog {
    /// From the environment ([`watchdog_period`]), starting now with the
    /// loop's current heartbeat `beat` (the first ping needs the heartbeat
    /// to move past it).
    pub fn from_env(beat: u64) -> Self {
        Self::new(watchdog_period(), beat, Instant::now())
    }

    /// With an explicit `period` (`None`: off), heartbeat `beat` and start
    /// time `now`.
    pub fn new(period: Option<Duration>, beat: u64, now: Instant) -> Self {
        Self {
            half: period.map(|p| p / 2),
            last: now,
            beat_at_ping: beat,
        }
    }

    /// The full watchdog period, if one is configured.
    pub fn period(&self) -> Option<Duration> {
        self.half.map(|h| h * 2)
    }

    /// How long the helper thread should sleep between polls: half the
    /// period, at most 50 ms (50 ms without a watchdog), at least 1 ms.
    pub fn tick(&self) -> Duration {
        self.half
            .map_or(MAX_TICK, |h| h.min(MAX_TICK))
            .max(MIN_TICK)
    }

    /// Called every tick with the loop's heartbeat `beat` at `now`: once
    /// half the period has passed since the last ping (or stall report),
    /// sends `WATCHDOG=1` if `beat` differs from the value at the last
    /// ping ([`WatchdogPoll::Fed`]), else reports
    /// [`WatchdogPoll::Stalled`]; either way the next one is due half a
    /// period after `now`. A failed send is ignored: systemd acts on the
    /// missing ping, and the next one is half a period later.
    pub fn poll(&mut self, beat: u64, now: Instant) -> WatchdogPoll {
        let Some(half) = self.half else {
            return WatchdogPoll::Off;
        };
        if now.saturating_duration_since(self.last) < half {
            return WatchdogPoll::NotDue;
        }
        self.last = now;
        if beat == self.beat_at_ping {
            return WatchdogPoll::Stalled;
        }
        self.beat_at_ping = beat;
        let _ = send(&[NotifyState::Watchdog]);
        WatchdogPoll::Fed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ME: u32 = 4242;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    #[test]
    fn period_unset_garbage_or_zero_is_none() {
        assert_eq!(watchdog_period_from(None, None, ME), None);
        assert_eq!(watchdog_period_from(None, Some("4242"), ME), None);
        assert_eq!(watchdog_period_from(Some(""), None, ME), None);
        assert_eq!(watchdog_period_from(Some("1s"), None, ME), None);
        assert_eq!(watchdog_period_from(Some("-5"), None, ME), None);
        assert_eq!(watchdog_period_from(Some("1.5"), None, ME), None);
        assert_eq!(watchdog_period_from(Some("0"), None, ME), None);
        assert_eq!(watchdog_period_from(Some("0"), Some("4242"), ME), None);
    }

    #[test]
    fn period_without_pid_counts() {
        assert_eq!(
            watchdog_period_from(Some("200000"), None, ME),
            Some(ms(200))
        );
        assert_eq!(
            watchdog_period_from(Some("1"), None, ME),
            Some(Duration::from_micros(1))
        );
    }

    #[test]
    fn period_pid_must_match_when_set() {
        assert_eq!(
            watchdog_period_from(Some("2000000"), Some("4242"), ME),
            Some(ms(2000))
        );
        assert_eq!(
            watchdog_period_from(Some("2000000"), Some("4243"), ME),
            None
        );
        assert_eq!(watchdog_period_from(Some("2000000"), Some(""), ME), None);
        assert_eq!(watchdog_period_from(Some("2000000"), Some("abc"), ME), None);
    }

    #[test]
    fn period_whitespace_is_ignored() {
        assert_eq!(
            watchdog_period_from(Some(" 1000000\n"), Some("\t4242 "), ME),
            Some(ms(1000))
        );
        assert_eq!(watchdog_period_from(Some("  "), None, ME), None);
    }

    #[test]
    fn tick_is_half_period_clamped() {
        let t0 = Instant::now();
        assert_eq!(Watchdog::new(None, 0, t0).tick(), ms(50));
        assert_eq!(Watchdog::new(Some(ms(2000)), 0, t0).tick(), ms(50));
        assert_eq!(Watchdog::new(Some(ms(100)), 0, t0).tick(), ms(50));
        assert_eq!(Watchdog::new(Some(ms(60)), 0, t0).tick(), ms(30));
        assert_eq!(
            Watchdog::new(Some(Duration::from_micros(10)), 0, t0).tick(),
            ms(1)
        );
        assert_eq!(Watchdog::new(Some(ms(60)), 0, t0).period(), Some(ms(60)));
        assert_eq!(Watchdog::new(None, 0, t0).period(), None);
    }

    #[test]
    fn off_without_a_period() {
        let t0 = Instant::now();
        let mut w = Watchdog::new(None, 0, t0);
        assert_eq!(w.poll(0, t0), WatchdogPoll::Off);
        assert_eq!(w.poll(1, t0 + Duration::from_secs(100)), WatchdogPoll::Off);
    }

    #[test]
    fn fed_at_half_period_only_when_the_beat_advanced() {
        use WatchdogPoll::{Fed, NotDue, Stalled};
        let t0 = Instant::now();
        let mut w = Watchdog::new(Some(ms(200)), 7, t0);
        // (heartbeat, time in ms, expected), in order
        let steps = [
            // not due before half the period, however the beat moves
            (8, 0, NotDue),
            (9, 99, NotDue),
            // due at 100 ms, beat 7 → 10: fed
            (10, 100, Fed),
            // next due 100 ms after that ping, not after the previous due time
            (11, 150, NotDue),
            (11, 199, NotDue),
            (11, 230, Fed),
            // the beat stops at 11: stalled at the next due time, nothing sent
            (11, 300, NotDue),
            (11, 330, Stalled),
            // a stall report also restarts the half period
            (11, 400, NotDue),
            (11, 430, Stalled),
            // the beat moves again: fed at the next due time
            (12, 500, NotDue),
            (12, 530, Fed),
        ];
        for (beat, t, want) in steps {
            assert_eq!(w.poll(beat, t0 + ms(t)), want, "beat {beat} at {t} ms");
        }
    }

    #[test]
    fn first_ping_needs_the_beat_to_leave_its_start_value_any_way() {
        let t0 = Instant::now();
        let mut w = Watchdog::new(Some(ms(100)), u64::MAX - 1, t0);
        assert_eq!(w.poll(u64::MAX - 1, t0 + ms(50)), WatchdogPoll::Stalled);
        assert_eq!(w.poll(u64::MAX, t0 + ms(100)), WatchdogPoll::Fed);
        // a wrapped counter has still moved
        assert_eq!(w.poll(0, t0 + ms(150)), WatchdogPoll::Fed);
    }

    #[test]
    fn a_clock_before_the_last_ping_is_not_due() {
        let t0 = Instant::now() + Duration::from_secs(1);
        let mut w = Watchdog::new(Some(ms(100)), 0, t0);
        assert_eq!(w.poll(1, t0 - ms(500)), WatchdogPoll::NotDue);
        assert_eq!(w.poll(1, t0 + ms(50)), WatchdogPoll::Fed);
    }
}
