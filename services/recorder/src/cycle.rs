//! The recorder's loop: a receive thread drains every deep subscriber into
//! a bounded queue (never blocking: a full queue drops and counts), and
//! the writing thread ([`write_loop`], the caller of [`crate::run()`]) turns
//! the queue into MCAP.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::ipc::{IpcError, IpcNode, Subscriber, SubscriberMode};
use grip_io::mcaplog::{McapLogError, McapWriter};
use grip_io::systemd::{Watchdog, WatchdogPoll};
use grip_msgs::{AudioBlock, BusFrame, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

use crate::bus::{BusSetup, BusTap};
use crate::monitor::{self, RxProbe, RxStep};
use crate::parts::Parts;
use crate::retention::Retention;
use crate::stats::{RecvStats, StatsTap, TopicStats};

/// The error and its causes in one line (the one home is grip-io's).
pub use grip_io::mcaplog::error_chain;

/// One message on its way to the file.
#[derive(Debug, Clone)]
pub enum Msg {
    /// Audio block (boxed: 8 KiB).
    Audio(Box<AudioBlock>),
    /// Road estimate.
    Road(RoadEstimate),
    /// Cycle record.
    Cycle(CycleRecord),
    /// CAN frame.
    Can(CanFrame),
    /// Ground truth.
    Truth(GroundTruth),
    /// A frame read off the vehicle bus ([`crate::bus`]).
    Bus(BusFrame),
}

impl Msg {
    /// The topic it belongs to.
    pub fn topic(&self) -> &'static str {
        match self {
            Msg::Audio(_) => topics::AUDIO,
            Msg::Road(_) => topics::ROAD,
            Msg::Cycle(_) => topics::CYCLE,
            Msg::Can(_) => topics::CAN_LOG,
            Msg::Truth(_) => topics::TRUTH,
            Msg::Bus(_) => topics::BUS,
        }
    }

    /// Writes it to `w` on its topic at its own stamp.
    pub fn write_to(&self, w: &mut McapWriter) -> Result<(), McapLogError> {
        match self {
            Msg::Audio(m) => w.write(topics::AUDIO, m.as_ref()),
            Msg::Road(m) => w.write(topics::ROAD, m),
            Msg::Cycle(m) => w.write(topics::CYCLE, m),
            Msg::Can(m) => w.write(topics::CAN_LOG, m),
            Msg::Truth(m) => w.write(topics::TRUTH, m),
            Msg::Bus(m) => w.write(topics::BUS, m),
        }
    }
}

/// The deep subscribers, one per entry of `topics::ALL`.
#[derive(Debug)]
pub struct Subscribers {
    audio: Subscriber<AudioBlock>,
    road: Subscriber<RoadEstimate>,
    cycle: Subscriber<CycleRecord>,
    can: Subscriber<CanFrame>,
    truth: Subscriber<GroundTruth>,
}

/// The topics [`Subscribers`] covers, in `topics::ALL` order.
pub const RECORDED: [&str; 5] = [
    topics::AUDIO,
    topics::ROAD,
    topics::CYCLE,
    topics::CAN_LOG,
    topics::TRUTH,
];

impl Subscribers {
    /// Opens a deep subscriber on every topic.
    pub fn open(node: &IpcNode) -> Result<Self, IpcError> {
        Ok(Self {
            audio: node.subscriber(topics::AUDIO, SubscriberMode::Deep)?,
            road: node.subscriber(topics::ROAD, SubscriberMode::Deep)?,
            cycle: node.subscriber(topics::CYCLE, SubscriberMode::Deep)?,
            can: node.subscriber(topics::CAN_LOG, SubscriberMode::Deep)?,
            truth: node.subscriber(topics::TRUTH, SubscriberMode::Deep)?,
        })
    }
}

/// The bounded queue's sending side with its counters.
#[derive(Debug)]
pub struct Queue {
    tx: SyncSender<Msg>,
    depth: Arc<AtomicUsize>,
    high_water: Arc<AtomicUsize>,
    capacity: usize,
}

/// Creates the queue (capacity in messages).
pub fn queue(capacity: usize) -> (Queue, Receiver<Msg>, Arc<AtomicUsize>, Arc<AtomicUsize>) {
    let (tx, rx) = sync_channel(capacity);
    let depth = Arc::new(AtomicUsize::new(0));
    let high = Arc::new(AtomicUsize::new(0));
    (
        Queue {
            tx,
            depth: Arc::clone(&depth),
            high_water: Arc::clone(&high),
            capacity,
        },
        rx,
        depth,
        high,
    )
}

impl Queue {
    /// True while the queue is at least half full: the vehicle bus's frames
    /// are then dropped (and counted) rather than queued, so that a bus
    /// flood can never fill the queue the loops' topics need
    /// ([`crate::bus`]).
    pub fn half_full(&self) -> bool {
        self.depth.load(Ordering::Relaxed) >= self.capacity / 2
    }

    /// Enqueues without blocking; false if full (or the writer is gone).
    pub fn offer(&self, m: Msg) -> bool {
        // count first: the writer may take the message (and decrement)
        // before try_send returns
        let d = self.depth.fetch_add(1, Ordering::Relaxed).wrapping_add(1);
        match self.tx.try_send(m) {
            Ok(()) => {
                self.high_water.fetch_max(d, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.depth.fetch_sub(1, Ordering::Relaxed);
                false
            }
        }
    }
}

fn account(st: &mut TopicStats, seq: Option<u64>, queued: bool) {
    st.received += 1;
    if let Some(s) = seq {
        st.seq.push(s);
    }
    if !queued {
        st.queue_dropped += 1;
    }
}

/// One pass over every subscriber: moves what is waiting (at most `max`
/// per topic) into the queue, counting gaps and drops. `beat` moves with
/// every message taken (the watchdog's sign that the receive path
/// advances: a pass over a full backlog can take seconds on a starved
/// CPU). Returns the number of messages taken.
pub fn receive_pass(
    subs: &Subscribers,
    q: &Queue,
    stats: &mut RecvStats,
    errors: &mut ErrorReport,
    max: usize,
    probe: &RxProbe,
    beat: &AtomicU64,
) -> usize {
    let mut n = 0;
    let at = |t: &str| RECORDED.iter().position(|r| *r == t).unwrap_or(0);
    macro_rules! pass {
        ($sub:expr, $topic:expr, $seq:expr, $wrap:expr) => {{
            probe.enter(RxStep::Receive, at($topic));
            for _ in 0..max {
                match $sub.recv() {
                    Ok(Some(m)) => {
                        let seq: Option<u64> = $seq(&m);
                        let queued = q.offer($wrap(m));
                        account(stats.topic($topic), seq, queued);
                        n += 1;
                        beat.fetch_add(1, Ordering::Relaxed);
                    }
                    Ok(None) => break,
                    Err(e) => {
                        stats.topic($topic).receive_errors += 1;
                        errors.warn($topic, &e, Instant::now());
                        break;
                    }
                }
            }
        }};
    }
    pass!(
        subs.cycle,
        topics::CYCLE,
        |m: &CycleRecord| Some(m.seq),
        Msg::Cycle
    );
    // CAN: alive counters tracked separately (no sequence number)
    probe.enter(RxStep::Receive, at(topics::CAN_LOG));
    for _ in 0..max {
        match subs.can.recv() {
            Ok(Some(f)) => {
                stats.can.push(&f);
                let queued = q.offer(Msg::Can(f));
                account(stats.topic(topics::CAN_LOG), None, queued);
                n += 1;
                beat.fetch_add(1, Ordering::Relaxed);
            }
            Ok(None) => break,
            Err(e) => {
                stats.topic(topics::CAN_LOG).receive_errors += 1;
                errors.warn(topics::CAN_LOG, &e, Instant::now());
                break;
            }
        }
    }
    pass!(
        subs.truth,
        topics::TRUTH,
        |m: &GroundTruth| Some(m.seq),
        Msg::Truth
    );
    pass!(
        subs.road,
        topics::ROAD,
        |m: &RoadEstimate| Some(m.seq),
        Msg::Road
    );
    pass!(
        subs.audio,
        topics::AUDIO,
        |m: &AudioBlock| Some(m.seq),
        |m| Msg::Audio(Box::new(m))
    );
    n
}

/// What a recording did.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// The log file.
    pub path: PathBuf,
    /// Receive-side counters.
    pub recv: RecvStats,
    /// Messages written per topic.
    pub written: BTreeMap<&'static str, u64>,
    /// Largest queue depth seen.
    pub queue_high_water: usize,
    /// Messages taken from the queue but not written (after a write error,
    /// until a new part opens), per topic.
    pub not_written: BTreeMap<&'static str, u64>,
    /// Write errors: each stops writing (until a new part opens, without
    /// `--out`).
    pub write_errors: u64,
}

impl Summary {
    /// Metadata map of the `grip.recorder` record.
    pub fn metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        for t in RECORDED {
            let s = self.recv.topics.get(t).copied().unwrap_or_default();
            let w = self.written.get(t).copied().unwrap_or(0);
            m.insert(format!("{t}.received"), s.received.to_string());
            m.insert(format!("{t}.written"), w.to_string());
            if let Some(n) = self.not_written.get(t) {
                m.insert(format!("{t}.not_written"), n.to_string());
            }
            m.insert(format!("{t}.queue_dropped"), s.queue_dropped.to_string());
            m.insert(format!("{t}.receive_errors"), s.receive_errors.to_string());
            if t != topics::CAN_LOG {
                m.insert(format!("{t}.seq_gaps"), s.seq.gaps.to_string());
                m.insert(format!("{t}.seq_gap_events"), s.seq.gap_events.to_string());
                m.insert(format!("{t}.seq_resets"), s.seq.resets.to_string());
            }
        }
        m.insert(
            format!("{}.counter_gaps", topics::CAN_LOG),
            self.recv.can.gaps.to_string(),
        );
        m.insert(
            format!("{}.counter_repeats", topics::CAN_LOG),
            self.recv.can.repeats.to_string(),
        );
        if let Some(b) = &self.recv.bus {
            let t = topics::BUS;
            let w = self.written.get(t).copied().unwrap_or(0);
            let transport = match b.stats.transport {
                Some(grip_io::can::BusKind::SocketCan) => "socketcan",
                Some(grip_io::can::BusKind::Sim) => "sim",
                None => "none (never opened)",
            };
            let stamps = match b.stats.transport {
                Some(grip_io::can::BusKind::SocketCan) => {
                    "kernel receive time (SO_TIMESTAMPNS) on CLOCK_MONOTONIC".to_owned()
                }
                _ => "sender's CLOCK_MONOTONIC at publish (the simulated bus has no delay)"
                    .to_owned(),
            };
            for (k, v) in [
                ("mode", b.mode.to_owned()),
                ("transport", transport.to_owned()),
                ("stamps", stamps),
                ("received", b.stats.received.to_string()),
                ("skipped_own", b.stats.skipped_own.to_string()),
                ("written", w.to_string()),
                ("queue_dropped", b.stats.queue_dropped.to_string()),
                ("receive_errors", b.stats.receive_errors.to_string()),
                ("kernel_dropped", b.stats.kernel_dropped.to_string()),
                ("kernel_stamped", b.stats.kernel_stamped.to_string()),
                ("reopens", b.stats.reopens.to_string()),
                ("open_failures", b.stats.open_failures.to_string()),
            ] {
                m.insert(format!("{t}.{k}"), v);
            }
        }
        m.insert("queue_high_water".into(), self.queue_high_water.to_string());
        m.insert("write_errors".into(), self.write_errors.to_string());
        m
    }
}

/// Starts the receive thread: it creates the iceoryx2 node and the deep
/// subscribers itself (iceoryx2 ports are not `Send`), reports the outcome
/// through `ready`, then drains into the queue until `stop`, and finally
/// drains once more.
pub fn spawn_receiver(
    q: Queue,
    stop: Arc<AtomicBool>,
    poll: Duration,
    heartbeat: Arc<AtomicU64>,
    probe: Arc<RxProbe>,
    tap: Arc<StatsTap>,
    ready: SyncSender<Result<(), IpcError>>,
    bus: Option<BusSetup>,
) -> std::io::Result<JoinHandle<RecvStats>> {
    std::thread::Builder::new()
        .name("recorder-rx".into())
        .spawn(move || {
            probe.register_thread();
            let mut stats = RecvStats::default();
            for t in RECORDED {
                stats.topic(t);
            }
            let opened = IpcNode::create(topics::node::RECORDER)
                .and_then(|node| Subscribers::open(&node).map(|s| (node, s)));
            let poll_ms = poll.as_millis() as u64;
            let mut bus = bus.map(BusTap::new);
            let (node, subs) = match opened {
                Ok(x) => {
                    // the bus before READY=1 (a failure is a warning,
                    // retried: crate::bus)
                    if let Some(b) = bus.as_mut() {
                        b.poll_open(&x.0, Instant::now());
                    }
                    let _ = ready.send(Ok(()));
                    x
                }
                Err(e) => {
                    let _ = ready.send(Err(e));
                    return stats;
                }
            };
            let mut errors = ErrorReport::default();
            // only receiving and sleeping here: the topics' peers are
            // watched by a thread of their own (monitor::spawn_peer_watch)
            while !stop.load(Ordering::Relaxed) {
                let n = receive_pass(&subs, &q, &mut stats, &mut errors, 4096, &probe, &heartbeat);
                let mut n_bus = 0;
                if let Some(b) = bus.as_mut() {
                    probe.enter(RxStep::Receive, RECORDED.len());
                    if b.is_open() {
                        n_bus = b.pass(&q, crate::bus::MAX_PER_PASS, &heartbeat);
                    } else {
                        // a bus not opened yet: tried again once a second
                        b.poll_open(&node, Instant::now());
                    }
                }
                heartbeat.fetch_add(1, Ordering::Relaxed);
                // a part ends: the writer asks for the counters so far
                if tap.wanted() {
                    stats.bus = bus.as_ref().map(|b| crate::stats::BusSummary {
                        mode: b.mode().as_str(),
                        poll_ms,
                        stats: b.stats(),
                    });
                    tap.give(&stats);
                }
                // the loops' topics first: a pass that read the bus is
                // followed by the sleep, so that a flooded bus (at most
                // MAX_PER_PASS a pass) cannot keep this thread from its
                // subscribers or from yielding the CPU; what the bus sends
                // beyond that overflows the socket (counted)
                if n == 0 || n_bus > 0 {
                    probe.enter(RxStep::Sleep, 0);
                    std::thread::sleep(poll);
                }
            }
            // drain what is still waiting in the subscribers; the bus once
            // (a car's other ECUs never stop sending: draining it until
            // empty could last for ever)
            while receive_pass(&subs, &q, &mut stats, &mut errors, 4096, &probe, &heartbeat) > 0 {}
            if let Some(b) = bus.as_mut() {
                b.pass(&q, 4096, &heartbeat);
            }
            stats.bus = bus.map(|b| crate::stats::BusSummary {
                mode: b.mode().as_str(),
                poll_ms,
                stats: b.stats(),
            });
            stats
        })
}

/// A warning's gate: open the first time, then at most once a second.
#[derive(Debug, Default)]
struct OncePerSecond {
    last: Option<Instant>,
}

impl OncePerSecond {
    /// Whether a warning may go out at `now` (it then counts as sent).
    fn due(&mut self, now: Instant) -> bool {
        if self
            .last
            .is_some_and(|t| now.duration_since(t) < Duration::from_secs(1))
        {
            return false;
        }
        self.last = Some(now);
        true
    }
}

/// Rate-limits the receive thread's warning about receive errors (every
/// one is counted in `receive_errors`): the first at once, then at most
/// one a second, each with the errors since the last warning.
#[derive(Debug, Default)]
pub struct ErrorReport {
    gate: OncePerSecond,
    since: u64,
}

impl ErrorReport {
    /// One receive error at `now`: the errors to report (this one and those
    /// held back since the last report), when a report is due.
    pub fn observe(&mut self, now: Instant) -> Option<u64> {
        self.since += 1;
        self.gate.due(now).then(|| std::mem::take(&mut self.since))
    }

    /// [`ErrorReport::observe`], logging the warning when due.
    fn warn(&mut self, topic: &str, e: &IpcError, now: Instant) {
        if let Some(n) = self.observe(now) {
            tracing::warn!(
                topic,
                error = %e,
                errors = n,
                "receive error (counted in grip.recorder's receive_errors; at most one warning a second, `errors` counts those since the last)"
            );
        }
    }
}

/// Messages waiting in the queue from which the writer counts as behind:
/// about half a second of a drive's traffic (1 kHz cycle records and ground
/// truth, the CAN copies at about 3 kHz).
pub const BACKLOG_WARN: usize = 2500;

/// Rate-limits the writer's backlog warning: at most one a second, each
/// naming the deepest queue since the last.
#[derive(Debug, Default)]
pub struct Backlog {
    gate: OncePerSecond,
    peak: usize,
}

impl Backlog {
    /// One message taken with `waiting` still queued at `now`: the peak to
    /// report, when one is due.
    pub fn observe(&mut self, waiting: usize, now: Instant) -> Option<usize> {
        if waiting < BACKLOG_WARN {
            return None;
        }
        self.peak = self.peak.max(waiting);
        self.gate.due(now).then(|| std::mem::take(&mut self.peak))
    }
}

/// The writing thread's loop: takes the queue into `parts` until the
/// receive thread is gone (after `stop`: it is told to stop, `STOPPING=1`
/// is sent, what is queued is written). Polls the watchdog at least every
/// 50 ms (half its period if shorter), fed only while both the receive
/// thread (`rx_beat`) and this loop advance (also while not writing after
/// a write error: the loop still drains the queue and tries to resume).
/// Counts into `summary`; returns whether a write failed. Between
/// messages, `parts` starts a new part when rotation says so, or after a
/// write error tries to resume ([`Parts::tick`]), and with `retention` the
/// log directory is swept when its period has passed (here, never on the
/// receive thread: a sweep or a switch delays only the writer, the queue
/// takes up the messages meanwhile).
pub fn write_loop(
    rx: &Receiver<Msg>,
    parts: &mut Parts,
    depth: &AtomicUsize,
    stop: &AtomicBool,
    rx_stop: &AtomicBool,
    rx_beat: &AtomicU64,
    probe: &RxProbe,
    summary: &mut Summary,
    mut retention: Option<&mut Retention>,
) -> bool {
    let mut wd = Watchdog::from_env(rx_beat.load(Ordering::Relaxed));
    // the longest wait for a message: the watchdog is polled at least this
    // often (half its period, at most 50 ms), so a short WatchdogSec works
    let wait = wd.tick();
    let mut stopping = false;
    let mut backlog = Backlog::default();
    loop {
        if !stopping && stop.load(Ordering::Relaxed) {
            stopping = true;
            rx_stop.store(true, Ordering::Relaxed);
            grip_io::systemd::notify_stopping();
        }
        match rx.recv_timeout(wait) {
            Ok(m) => {
                let waiting = depth.fetch_sub(1, Ordering::Relaxed).saturating_sub(1);
                // (the clock is read only when the queue is deep)
                if waiting >= BACKLOG_WARN
                    && let Some(peak) = backlog.observe(waiting, Instant::now())
                {
                    tracing::warn!(
                        waiting = peak,
                        topic = m.topic(),
                        last_flush_ms = parts.last_flush_took().as_secs_f64() * 1e3,
                        "the writer is behind: messages wait in the queue (a crash now loses them too)"
                    );
                }
                parts.write(&m, summary);
            }
            Err(RecvTimeoutError::Timeout) => parts.idle(summary),
            Err(RecvTimeoutError::Disconnected) => break,
        }
        // fed only while both the receive thread and this loop advance
        let beat = rx_beat.load(Ordering::Relaxed);
        let now = Instant::now();
        if wd.poll(beat, now) == WatchdogPoll::Stalled {
            monitor::receive_stalled(beat, probe);
        }
        if !stopping {
            parts.tick(now, summary, retention.as_deref_mut());
            if let Some(r) = retention.as_deref_mut() {
                r.maybe_sweep(now);
            }
        }
    }
    summary.write_errors > 0
}

#[cfg(test)]
mod error_tests {
    use super::*;

    #[test]
    fn receive_errors_are_reported_at_once_then_at_most_once_a_second() {
        let mut r = ErrorReport::default();
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert_eq!(r.observe(at(0)), Some(1), "the first at once");
        assert_eq!(r.observe(at(10)), None, "within the second");
        assert_eq!(r.observe(at(900)), None);
        assert_eq!(r.observe(at(1000)), Some(3), "the errors since the last");
        assert_eq!(r.observe(at(5000)), Some(1));
    }

    #[test]
    fn a_backlog_is_reported_at_most_once_a_second_with_its_peak() {
        let mut b = Backlog::default();
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert_eq!(b.observe(BACKLOG_WARN - 1, at(0)), None, "not behind");
        assert_eq!(b.observe(BACKLOG_WARN, at(1)), Some(BACKLOG_WARN));
        assert_eq!(b.observe(9000, at(200)), None, "within the second");
        assert_eq!(b.observe(BACKLOG_WARN + 1, at(900)), None);
        assert_eq!(b.observe(10, at(1100)), None, "caught up");
        assert_eq!(b.observe(3000, at(1200)), Some(9000), "the deepest since");
        assert_eq!(b.observe(3000, at(1300)), None);
    }

    /// Shaped like the mcap crate's `McapError::Io`: a message that hides
    /// its I/O cause, the cause as its source.
    #[derive(Debug)]
    struct Opaque(std::io::Error);

    impl std::fmt::Display for Opaque {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("I/O error from writing, or reading a compression stream")
        }
    }

    impl std::error::Error for Opaque {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    /// A full disk under such an error: the recorder's log line names it.
    #[test]
    fn write_errors_name_their_cause() {
        // 28 = ENOSPC on Linux
        let e = Opaque(std::io::Error::from_raw_os_error(28));
        assert!(!e.to_string().contains("No space"));
        let s = error_chain(&e);
        assert!(
            s.starts_with("I/O error from writing") && s.contains("No space left on device"),
            "{s}"
        );
        // a message that already ends with its source's is not repeated
        let io = std::io::Error::other("disk on fire");
        assert_eq!(error_chain(&io), "disk on fire");
    }
}
