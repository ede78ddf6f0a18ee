//! Injected time: a [`Clock`] gives CLOCK_MONOTONIC nanoseconds and sleeps to
//! an absolute deadline. [`MonotonicClock`] is the real one, [`ManualClock`]
//! a deterministic one for tests and replay (sleeping just advances it).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Monotonic time source.
pub trait Clock {
    /// Now, ns on CLOCK_MONOTONIC (or the manual timeline).
    fn now_ns(&self) -> u64;
    /// Sleeps until `deadline_ns` (absolute); returns the time of waking.
    fn sleep_until_ns(&self, deadline_ns: u64) -> u64;
}

/// CLOCK_MONOTONIC now, ns.
pub fn monotonic_now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid pointer to a timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    (ts.tv_sec as u64) * 1_000_000_000 + ts.tv_nsec as u64
}

/// The real clock: `clock_gettime` and `clock_nanosleep(TIMER_ABSTIME)` on
/// CLOCK_MONOTONIC.
#[derive(Debug, Clone, Copy, Default)]
pub struct MonotonicClock;

impl Clock for MonotonicClock {
    fn now_ns(&self) -> u64 {
        monotonic_now_ns()
    }
    fn sleep_until_ns(&self, deadline_ns: u64) -> u64 {
        let ts = libc::timespec {
            tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
        };
        loop {
            // SAFETY: valid timespec; remaining-time pointer unused with TIMER_ABSTIME.
            let r = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    core::ptr::null_mut(),
                )
            };
            if r != libc::EINTR {
                break;
            }
        }
        monotonic_now_ns()
    }
}

/// A clock that only moves when told to. Clones share the same time.
/// `sleep_until_ns` jumps to the deadline plus the configured wake-up
/// latency (default 0), so a periodic loop runs deterministically.
#[derive(Debug, Clone, Default)]
pub struct ManualClock {
    now: Arc<AtomicU64>,
    latency: Arc<AtomicU64>,
}

impl ManualClock {
    /// Starts at `t0_ns`.
    pub fn new(t0_ns: u64) -> Self {
        Self {
            now: Arc::new(AtomicU64::new(t0_ns)),
            latency: Arc::new(AtomicU64::new(0)),
        }
    }
    /// Sets the time (never moves backwards: earlier values are ignored).
    pub fn set_ns(&self, t: u64) {
        self.now.fetch_max(t, Ordering::SeqCst);
    }
    /// Advances by `dt_ns`.
    pub fn advance_ns(&self, dt_ns: u64) {
        self.now.fetch_add(dt_ns, Ordering::SeqCst);
    }
    /// Wake-up latency added to every following `sleep_until_ns`.
    pub fn set_wakeup_latency_ns(&self, l: u64) {
        self.latency.store(l, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now_ns(&self) -> u64 {
        self.now.load(Ordering::SeqCst)
    }
    fn sleep_until_ns(&self, deadline_ns: u64) -> u64 {
        let wake = deadline_ns + self.latency.load(Ordering::SeqCst);
        self.set_ns(wake);
        self.now_ns()
    }
}

impl<C: Clock + ?Sized> Clock for &C {
    fn now_ns(&self) -> u64 {
        (**self).now_ns()
    }
    fn sleep_until_ns(&self, d: u64) -> u64 {
        (**self).sleep_until_ns(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_is_monotonic_and_sleeps_to_deadline() {
        let c = MonotonicClock;
        let t0 = c.now_ns();
        let woke = c.sleep_until_ns(t0 + 2_000_000);
        assert!(woke >= t0 + 2_000_000);
        assert!(c.now_ns() >= woke);
    }

    #[test]
    fn manual_clock_is_shared_and_never_goes_back() {
        let c = ManualClock::new(100);
        let c2 = c.clone();
        c.advance_ns(50);
        assert_eq!(c2.now_ns(), 150);
        c.set_ns(10);
        assert_eq!(c.now_ns(), 150);
        c.set_wakeup_latency_ns(7);
        assert_eq!(c.sleep_until_ns(1000), 1007);
        // a deadline in the past does not move time backwards
        assert_eq!(c.sleep_until_ns(500), 1007);
    }
}
