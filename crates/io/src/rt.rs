//! Real-time set-up and periodic timing.
//!
//! Each set-up step returns an [`RtStatus`]; a step that is not permitted
//! (no root / no `CAP_SYS_NICE`, `RLIMIT_MEMLOCK`, no
//! `/dev/cpu_dma_latency`) is *never* fatal: the caller logs it with
//! [`RtReport::log`] as a clear warning and runs on, slower.
//!
//! [`PeriodicTimer`] sleeps to absolute deadlines
//! (`clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)` through [`Clock`]),
//! so lateness never accumulates; it measures each wake-up's latency and
//! counts deadline misses. Never busy-poll at FIFO priority (RT throttling
//! stalls such a thread ~50 ms per second, see the machine notes).

use std::fs::File;

use crate::clock::Clock;

/// Outcome of one set-up step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RtStatus {
    /// Done.
    Applied,
    /// Not permitted here; runs without it.
    NotPermitted(String),
    /// Not requested by the configuration.
    Skipped,
    /// Failed for another reason (bad priority, bad CPU).
    Failed(String),
}

impl RtStatus {
    /// True if applied.
    pub fn is_applied(&self) -> bool {
        matches!(self, RtStatus::Applied)
    }
    fn from_errno(what: &str, e: std::io::Error) -> Self {
        match e.raw_os_error() {
            Some(libc::EPERM) | Some(libc::EACCES) | Some(libc::ENOMEM) => {
                RtStatus::NotPermitted(format!("{what}: {e}"))
            }
            _ => RtStatus::Failed(format!("{what}: {e}")),
        }
    }
}

/// Puts the calling thread under SCHED_FIFO at `priority` (1..=99).
pub fn set_fifo_priority(priority: u8) -> RtStatus {
    use thread_priority::{
        RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
        set_thread_priority_and_policy, thread_native_id,
    };
    if !(1..=99).contains(&priority) {
        return RtStatus::Failed(format!("SCHED_FIFO priority {priority} not in 1..=99"));
    }
    let Ok(v) = ThreadPriorityValue::try_from(priority) else {
        return RtStatus::Failed(format!("priority {priority} rejected by thread-priority"));
    };
    match set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(v),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    ) {
        Ok(()) => RtStatus::Applied,
        Err(thread_priority::Error::OS(code)) if code == libc::EPERM => RtStatus::NotPermitted(
            "SCHED_FIFO: operation not permitted (run as root, grant CAP_SYS_NICE, or set LimitRTPRIO in the systemd unit)".into(),
        ),
        Err(e) => RtStatus::Failed(format!("SCHED_FIFO: {e:?}")),
    }
}

/// `mlockall(MCL_CURRENT | MCL_FUTURE)`: no page faults on the hot path.
pub fn lock_memory() -> RtStatus {
    // SAFETY: plain syscall wrapper.
    let r = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if r == 0 {
        RtStatus::Applied
    } else {
        RtStatus::from_errno(
            "mlockall (raise RLIMIT_MEMLOCK / LimitMEMLOCK=infinity)",
            std::io::Error::last_os_error(),
        )
    }
}

/// Pins the calling thread to `cpus`.
pub fn pin_to_cpus(cpus: &[usize]) -> RtStatus {
    if cpus.is_empty() {
        return RtStatus::Skipped;
    }
    // SAFETY: cpu_set_t is plain data; CPU_ZERO/CPU_SET only touch it.
    let mut set: libc::cpu_set_t = unsafe { core::mem::zeroed() };
    for &c in cpus {
        if c >= libc::CPU_SETSIZE as usize {
            return RtStatus::Failed(format!("CPU {c} out of range"));
        }
        // SAFETY: c < CPU_SETSIZE checked above.
        unsafe { libc::CPU_SET(c, &mut set) };
    }
    // SAFETY: pid 0 = calling thread; set is initialised.
    let r = unsafe { libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) };
    if r == 0 {
        RtStatus::Applied
    } else {
        RtStatus::from_errno(
            &format!("sched_setaffinity({cpus:?})"),
            std::io::Error::last_os_error(),
        )
    }
}

/// Holds `/dev/cpu_dma_latency` at 0 µs while alive (keeps the CPU out of
/// deep idle states; halves wake-up latency on the development VM).
#[derive(Debug)]
pub struct DmaLatencyGuard {
    _file: File,
}

impl DmaLatencyGuard {
    /// Opens `/dev/cpu_dma_latency` and writes a 32-bit 0.
    pub fn hold() -> (Option<Self>, RtStatus) {
        use std::io::Write;
        let path = "/dev/cpu_dma_latency";
        match std::fs::OpenOptions::new().write(true).open(path) {
            Ok(mut f) => match f.write_all(&0i32.to_ne_bytes()) {
                Ok(()) => (Some(Self { _file: f }), RtStatus::Applied),
                Err(e) => (None, RtStatus::from_errno(path, e)),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (
                None,
                RtStatus::NotPermitted(format!("{path} does not exist")),
            ),
            Err(e) => (None, RtStatus::from_errno(path, e)),
        }
    }
}

/// What to apply.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct RtConfig {
    /// SCHED_FIFO priority for the calling thread (None: stay SCHED_OTHER).
    #[serde(default)]
    pub fifo_priority: Option<u8>,
    /// mlockall.
    #[serde(default)]
    pub lock_memory: bool,
    /// CPUs to pin the calling thread to (empty: no pinning).
    #[serde(default)]
    pub cpus: Vec<usize>,
    /// Hold /dev/cpu_dma_latency at 0.
    #[serde(default)]
    pub cpu_dma_latency_zero: bool,
}

/// Statuses of all steps, plus the latency guard to keep alive.
#[derive(Debug)]
pub struct RtReport {
    /// SCHED_FIFO.
    pub fifo: RtStatus,
    /// mlockall.
    pub mlock: RtStatus,
    /// Affinity.
    pub affinity: RtStatus,
    /// /dev/cpu_dma_latency.
    pub dma_latency: RtStatus,
    /// Keep this alive as long as low latency is wanted.
    pub dma_guard: Option<DmaLatencyGuard>,
}

impl RtReport {
    /// Logs each step: info when applied, a clear warning when not.
    pub fn log(&self) {
        for (what, s) in [
            ("SCHED_FIFO", &self.fifo),
            ("mlockall", &self.mlock),
            ("CPU affinity", &self.affinity),
            ("cpu_dma_latency=0", &self.dma_latency),
        ] {
            match s {
                RtStatus::Applied => tracing::info!("real-time set-up: {what} applied"),
                RtStatus::Skipped => tracing::debug!("real-time set-up: {what} not requested"),
                RtStatus::NotPermitted(m) => tracing::warn!(
                    "real-time set-up: {what} NOT applied ({m}); running with worse latency"
                ),
                RtStatus::Failed(m) => {
                    tracing::warn!("real-time set-up: {what} FAILED ({m}); running without it")
                }
            }
        }
    }
    /// True if every requested step was applied.
    pub fn all_applied(&self) -> bool {
        self.not_applied().is_empty()
    }

    /// The requested steps that were not applied (not permitted or
    /// failed), in [`RtReport::log`]'s order.
    pub fn not_applied(&self) -> Vec<&'static str> {
        [
            ("SCHED_FIFO", &self.fifo),
            ("mlockall", &self.mlock),
            ("CPU affinity", &self.affinity),
            ("cpu_dma_latency=0", &self.dma_latency),
        ]
        .into_iter()
        .filter(|(_, s)| !matches!(s, RtStatus::Applied | RtStatus::Skipped))
        .map(|(w, _)| w)
        .collect()
    }

    /// What a service's systemd `STATUS=` line adds when a requested step
    /// was not applied (`systemctl status` then shows it, not only the
    /// journal's warning): `, REAL TIME NOT APPLIED: SCHED_FIFO, mlockall
    /// (see the journal)`; empty when all were.
    pub fn status_note(&self) -> String {
        let missing = self.not_applied();
        if missing.is_empty() {
            String::new()
        } else {
            format!(
                ", REAL TIME NOT APPLIED: {} (see the journal)",
                missing.join(", ")
            )
        }
    }
}

/// Applies `cfg` to the calling thread (and process, for mlockall). Order:
/// lock memory, pin, latency guard, then priority.
pub fn apply(cfg: &RtConfig) -> RtReport {
    let mlock = if cfg.lock_memory {
        lock_memory()
    } else {
        RtStatus::Skipped
    };
    let affinity = pin_to_cpus(&cfg.cpus);
    let (dma_guard, dma_latency) = if cfg.cpu_dma_latency_zero {
        DmaLatencyGuard::hold()
    } else {
        (None, RtStatus::Skipped)
    };
    let fifo = match cfg.fifo_priority {
        Some(p) => set_fifo_priority(p),
        None => RtStatus::Skipped,
    };
    RtReport {
        fifo,
        mlock,
        affinity,
        dma_latency,
        dma_guard,
    }
}

// ------------------------------------------------------------ histogram ----

/// Fixed-bucket latency histogram: 1 µs buckets from 0 to `max_us`, one
/// overflow bucket, exact min/max/count/sum. Buckets are allocated at
/// construction; [`record`](Self::record) allocates nothing.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    buckets: Box<[u64]>,
    overflow: u64,
    count: u64,
    sum_ns: u128,
    min_ns: u64,
    max_ns: u64,
}

impl LatencyHistogram {
    /// Buckets of 1 µs up to `max_us` (values above land in the overflow
    /// bucket; percentiles falling there report the exact maximum).
    pub fn new(max_us: usize) -> Self {
        Self {
            buckets: vec![0; max_us.max(1)].into_boxed_slice(),
            overflow: 0,
            count: 0,
            sum_ns: 0,
            min_ns: u64::MAX,
            max_ns: 0,
        }
    }
    /// Records one latency (negative values count as 0).
    pub fn record(&mut self, latency_ns: i64) {
        let v = latency_ns.max(0) as u64;
        let b = (v / 1000) as usize;
        match self.buckets.get_mut(b) {
            Some(c) => *c += 1,
            None => self.overflow += 1,
        }
        self.count += 1;
        self.sum_ns += u128::from(v);
        self.min_ns = self.min_ns.min(v);
        self.max_ns = self.max_ns.max(v);
    }
    /// Samples recorded.
    pub fn count(&self) -> u64 {
        self.count
    }
    /// Largest value, ns (0 if empty).
    pub fn max_ns(&self) -> u64 {
        self.max_ns
    }
    /// Smallest value, ns (0 if empty).
    pub fn min_ns(&self) -> u64 {
        if self.count == 0 { 0 } else { self.min_ns }
    }
    /// Mean, ns.
    pub fn mean_ns(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.sum_ns as f64 / self.count as f64
        }
    }
    /// Values above the bucket range.
    pub fn overflow(&self) -> u64 {
        self.overflow
    }
    /// The `q`-quantile (0..=1) as the upper edge of its 1 µs bucket, ns,
    /// capped at the exact maximum. 0 if empty.
    pub fn quantile_ns(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let q = if q.is_nan() { 1.0 } else { q.clamp(0.0, 1.0) };
        let rank = ((q * self.count as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, &c) in self.buckets.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return ((i as u64 + 1) * 1000).min(self.max_ns);
            }
        }
        self.max_ns
    }
    /// Median, ns.
    pub fn p50_ns(&self) -> u64 {
        self.quantile_ns(0.5)
    }
    /// 99th percentile, ns.
    pub fn p99_ns(&self) -> u64 {
        self.quantile_ns(0.99)
    }
    /// Clears all counts.
    pub fn reset(&mut self) {
        self.buckets.iter_mut().for_each(|c| *c = 0);
        self.overflow = 0;
        self.count = 0;
        self.sum_ns = 0;
        self.min_ns = u64::MAX;
        self.max_ns = 0;
    }
}

// -------------------------------------------------------- periodic timer ----

/// Timing of one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleTiming {
    /// Cycle number (0-based, counts skipped periods too).
    pub cycle: u64,
    /// The deadline this wake-up was for, ns.
    pub deadline_ns: u64,
    /// Actual wake-up time, ns.
    pub woke_ns: u64,
    /// woke − deadline, ns.
    pub latency_ns: i64,
    /// Deadlines that passed while the previous cycle overran (0 normally);
    /// each is a deadline miss and its cycle is skipped.
    pub skipped: u64,
}

/// Absolute-deadline periodic timer. A cycle that is still running when its
/// successor's deadline passes is a *deadline miss*; the timer then skips
/// the periods that are already over (counting them) so it never bursts to
/// catch up.
#[derive(Debug)]
pub struct PeriodicTimer<C: Clock> {
    clock: C,
    period_ns: u64,
    next_ns: u64,
    cycle: u64,
    misses: u64,
    hist: LatencyHistogram,
}

impl<C: Clock> PeriodicTimer<C> {
    /// First deadline one period from now. Histogram range 10 ms.
    pub fn new(clock: C, period_ns: u64) -> Self {
        let period_ns = period_ns.max(1);
        let next_ns = clock.now_ns() + period_ns;
        Self {
            clock,
            period_ns,
            next_ns,
            cycle: 0,
            misses: 0,
            hist: LatencyHistogram::new(10_000),
        }
    }
    /// Sleeps to the next deadline and reports the wake-up.
    pub fn wait_next(&mut self) -> CycleTiming {
        let now = self.clock.now_ns();
        let mut skipped = 0;
        if now > self.next_ns {
            // overran: this deadline (and maybe more) already passed; skip
            // to the first deadline in the future, counting each passed one
            let behind = (now - self.next_ns) / self.period_ns + 1;
            skipped = behind;
            self.misses += behind;
            self.next_ns += behind * self.period_ns;
            self.cycle += behind;
        }
        let deadline = self.next_ns;
        let woke = self.clock.sleep_until_ns(deadline);
        let latency = woke as i64 - deadline as i64;
        self.hist.record(latency);
        let t = CycleTiming {
            cycle: self.cycle,
            deadline_ns: deadline,
            woke_ns: woke,
            latency_ns: latency,
            skipped,
        };
        self.cycle += 1;
        self.next_ns += self.period_ns;
        t
    }
    /// Deadline misses so far.
    pub fn deadline_misses(&self) -> u64 {
        self.misses
    }
    /// Wake-up latency histogram.
    pub fn histogram(&self) -> &LatencyHistogram {
        &self.hist
    }
    /// The clock.
    pub fn clock(&self) -> &C {
        &self.clock
    }
    /// Period, ns.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The STATUS= note names the requested steps not applied, nothing
    /// when each was applied or not requested.
    #[test]
    fn the_status_note_names_what_was_not_applied() {
        let mut r = RtReport {
            fifo: RtStatus::Applied,
            mlock: RtStatus::Applied,
            affinity: RtStatus::Skipped,
            dma_latency: RtStatus::Applied,
            dma_guard: None,
        };
        assert!(r.all_applied());
        assert_eq!(r.status_note(), "");
        r.fifo = RtStatus::NotPermitted("EPERM".into());
        r.affinity = RtStatus::Failed("CPU 7".into());
        assert!(!r.all_applied());
        assert_eq!(
            r.status_note(),
            ", REAL TIME NOT APPLIED: SCHED_FIFO, CPU affinity (see the journal)"
        );
    }
    use crate::clock::{ManualClock, MonotonicClock};

    #[test]
    fn histogram_percentiles() {
        let mut h = LatencyHistogram::new(1000);
        for us in 1..=100 {
            h.record(us * 1000 - 500); // 0.5, 1.5, ... 99.5 µs
        }
        assert_eq!(h.count(), 100);
        assert_eq!(h.p50_ns(), 50_000);
        assert_eq!(h.p99_ns(), 99_000);
        assert_eq!(h.max_ns(), 99_500);
        assert_eq!(h.quantile_ns(1.0), 99_500);
        h.record(5_000_000); // overflow
        assert_eq!(h.overflow(), 1);
        assert_eq!(h.quantile_ns(1.0), 5_000_000);
        assert_eq!(h.min_ns(), 500);
        h.record(-10);
        assert_eq!(h.min_ns(), 0);
    }

    #[test]
    fn manual_timer_is_deterministic_and_counts_overruns() {
        let clock = ManualClock::new(0);
        let mut t = PeriodicTimer::new(clock.clone(), 1_000_000);
        clock.set_wakeup_latency_ns(20_000);
        let a = t.wait_next();
        assert_eq!(
            (a.cycle, a.deadline_ns, a.latency_ns, a.skipped),
            (0, 1_000_000, 20_000, 0)
        );
        // compute takes 0.5 ms: fine
        clock.advance_ns(500_000);
        let b = t.wait_next();
        assert_eq!((b.cycle, b.deadline_ns), (1, 2_000_000));
        assert_eq!(t.deadline_misses(), 0);
        // compute takes 2.5 ms: deadline 3 ms and 4 ms are gone
        clock.advance_ns(2_500_000);
        let c = t.wait_next();
        assert_eq!(c.deadline_ns, 5_000_000);
        assert_eq!(c.skipped, 2);
        assert_eq!(c.cycle, 4);
        assert_eq!(c.latency_ns, 20_000);
        assert_eq!(t.deadline_misses(), 2);
        assert_eq!(t.histogram().count(), 3);
        assert_eq!(t.histogram().max_ns(), 20_000);
    }

    #[test]
    fn real_timer_wakes_after_each_deadline() {
        let mut t = PeriodicTimer::new(MonotonicClock, 1_000_000);
        let mut last = 0;
        for _ in 0..20 {
            let c = t.wait_next();
            assert!(c.woke_ns >= c.deadline_ns);
            assert!(c.deadline_ns > last);
            last = c.deadline_ns;
        }
        assert_eq!(t.histogram().count(), 20);
    }

    #[test]
    fn fifo_status_matches_the_kernel_policy() {
        // in a fresh thread so the test runner's threads keep SCHED_OTHER
        std::thread::spawn(|| {
            let s = set_fifo_priority(10);
            // SAFETY: querying the calling thread's policy.
            let policy = unsafe { libc::sched_getscheduler(0) };
            match s {
                RtStatus::Applied => assert_eq!(policy, libc::SCHED_FIFO),
                RtStatus::NotPermitted(_) => assert_ne!(policy, libc::SCHED_FIFO),
                RtStatus::Failed(m) => panic!("unexpected failure: {m}"),
                RtStatus::Skipped => unreachable!(),
            }
            assert!(matches!(set_fifo_priority(0), RtStatus::Failed(_)));
        })
        .join()
        .unwrap();
    }

    #[test]
    fn affinity_status_matches_the_kernel_mask() {
        std::thread::spawn(|| {
            let s = pin_to_cpus(&[0]);
            // SAFETY: reading the calling thread's mask into a zeroed set.
            let mut set: libc::cpu_set_t = unsafe { core::mem::zeroed() };
            // SAFETY: `set` is a valid, writable cpu_set_t of the size passed.
            let r = unsafe {
                libc::sched_getaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &mut set)
            };
            assert_eq!(r, 0);
            if s.is_applied() {
                // SAFETY: index in range.
                assert!(unsafe { libc::CPU_ISSET(0, &set) });
                // SAFETY: `set` was filled by sched_getaffinity above.
                assert_eq!(unsafe { libc::CPU_COUNT(&set) }, 1);
            }
            assert!(matches!(pin_to_cpus(&[100_000]), RtStatus::Failed(_)));
            assert_eq!(pin_to_cpus(&[]), RtStatus::Skipped);
        })
        .join()
        .unwrap();
    }
}
