//! What the recorder watches and logs outside its per-message work: a
//! thread of its own follows the publishers and dead nodes of every topic
//! ([`spawn_peer_watch`], [`PeerWatch`], once per second), and the writing
//! loop feeds the watchdog (`WATCHDOG=1` through
//! [`grip_io::systemd::Watchdog`]) only while both it and the receive
//! thread advance ([`receive_stalled`] otherwise, naming what the receive
//! thread was doing: [`RxProbe`]).
//!
//! The peers are not asked from the receive thread: listing a topic's
//! nodes makes iceoryx2 read and parse every node's details, and under
//! systemd in the HIL VM (emulated CPU, the recorder at `Nice=10` on the
//! CPU of two SCHED_FIFO loops) the receive thread was seen runnable
//! inside that listing for more than half its 10 s watchdog period, so
//! the watchdog went unfed and systemd killed a recorder that was only
//! slow (`tools/hil/README.md`).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU32, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::ipc::{IpcError, IpcNode, PeerReport, TopicWatch};
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};

/// What the receive thread is doing, for the stall warning: it stores its
/// step before each one (a relaxed atomic store: nothing allocates), and
/// its kernel thread id once.
#[derive(Debug, Default)]
pub struct RxProbe {
    step: AtomicU8,
    tid: AtomicU32,
}

/// Steps of the receive thread ([`RxProbe::enter`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum RxStep {
    /// Not started yet.
    Starting = 0,
    /// Taking samples of one topic (index into [`crate::RECORDED`]; its
    /// length: the vehicle bus) + 1.
    Receive = 1,
    /// Sleeping for the poll interval.
    Sleep = 10,
}

impl RxProbe {
    /// Called once by the receive thread: remembers its kernel thread id
    /// (`/proc/thread-self`), 0 where that cannot be read.
    pub fn register_thread(&self) {
        let tid = std::fs::read_link("/proc/thread-self")
            .ok()
            .and_then(|p| p.file_name()?.to_str()?.parse().ok())
            .unwrap_or(0);
        self.tid.store(tid, Ordering::Relaxed);
    }

    /// The thread enters `step`; `topic` is the index of the topic for
    /// [`RxStep::Receive`].
    pub fn enter(&self, step: RxStep, topic: usize) {
        let v = match step {
            RxStep::Receive => RxStep::Receive as u8 + topic.min(8) as u8,
            s => s as u8,
        };
        self.step.store(v, Ordering::Relaxed);
    }

    /// The step as words.
    pub fn step(&self) -> String {
        match self.step.load(Ordering::Relaxed) {
            0 => "starting".into(),
            v @ 1..=9 => {
                let i = usize::from(v - 1);
                // one past the topics: the vehicle bus (crate::bus)
                let t = crate::cycle::RECORDED.get(i).copied().unwrap_or(
                    if i == crate::cycle::RECORDED.len() {
                        grip_msgs::topics::BUS
                    } else {
                        "?"
                    },
                );
                format!("receiving {t}")
            }
            10 => "sleeping for the poll interval".into(),
            v => format!("step {v}"),
        }
    }

    /// The thread's scheduler state, kernel wait channel and system call
    /// as `/proc` shows them (state R: runnable, i.e. waiting for a CPU;
    /// S or D: blocked, in `wchan`).
    pub fn kernel_view(&self) -> String {
        let tid = self.tid.load(Ordering::Relaxed);
        if tid == 0 {
            return "thread id unknown".into();
        }
        let dir = format!("/proc/self/task/{tid}");
        let read = |f: &str| {
            std::fs::read_to_string(format!("{dir}/{f}"))
                .map(|s| s.trim().to_owned())
                .unwrap_or_else(|e| format!("({e})"))
        };
        let stat = read("stat");
        // the state is the field after the parenthesised name
        let state = stat
            .rsplit_once(") ")
            .and_then(|(_, rest)| rest.split_whitespace().next())
            .unwrap_or("?")
            .to_owned();
        let sched = read("schedstat");
        format!(
            "tid {tid} state {state} wchan {} syscall {} schedstat {sched}",
            read("wchan"),
            read("syscall").split_whitespace().next().unwrap_or("?")
        )
    }
}

/// The receive thread's heartbeat did not move for half a watchdog period:
/// says what it was doing ([`RxProbe`]).
pub fn receive_stalled(heartbeat: u64, probe: &RxProbe) {
    tracing::warn!(
        heartbeat,
        step = %probe.step(),
        kernel = %probe.kernel_view(),
        "recorder receive thread stalled: watchdog not fed"
    );
}

/// Every recorded topic's service, held open (no port) by the peer-watch
/// thread.
#[derive(Debug)]
struct Watches {
    audio: TopicWatch<AudioBlock>,
    road: TopicWatch<RoadEstimate>,
    cycle: TopicWatch<CycleRecord>,
    can: TopicWatch<CanFrame>,
    truth: TopicWatch<GroundTruth>,
}

impl Watches {
    fn open(node: &IpcNode) -> Result<Self, IpcError> {
        Ok(Self {
            audio: node.watch(topics::AUDIO)?,
            road: node.watch(topics::ROAD)?,
            cycle: node.watch(topics::CYCLE)?,
            can: node.watch(topics::CAN_LOG)?,
            truth: node.watch(topics::TRUTH)?,
        })
    }

    fn peers(&self) -> [(&'static str, PeerReport); 5] {
        [
            (self.audio.topic(), self.audio.peers()),
            (self.road.topic(), self.road.peers()),
            (self.cycle.topic(), self.cycle.peers()),
            (self.can.topic(), self.can.peers()),
            (self.truth.topic(), self.truth.peers()),
        ]
    }
}

/// Starts the peer-watch thread: its own iceoryx2 node (iceoryx2 ports
/// and services are not `Send`), every recorded topic's service held
/// open, [`PeerWatch::poll`] about once per second, until `stop`. It
/// feeds nothing: how slow it is never reaches the watchdog. If the
/// services cannot be opened it says so once and ends (recording goes on).
pub fn spawn_peer_watch(stop: Arc<AtomicBool>) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("recorder-peers".into())
        .spawn(move || {
            let opened = IpcNode::create(&format!("{}-peers", topics::node::RECORDER))
                .and_then(|node| Watches::open(&node).map(|w| (node, w)));
            let (_node, watches) = match opened {
                Ok(x) => x,
                Err(e) => {
                    tracing::warn!(error = %e, "recorder: cannot watch the topics' peers; recording goes on without");
                    return;
                }
            };
            let mut watch = PeerWatch::new(Instant::now());
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(100));
                watch.poll(Instant::now(), || watches.peers());
            }
        })
}

/// Publishers and dead nodes per topic, checked once per second; a change
/// is logged (a warning if a peer died).
#[derive(Debug)]
pub struct PeerWatch {
    last_check: Instant,
    publishers: BTreeMap<&'static str, (usize, usize)>,
}

impl PeerWatch {
    /// Nothing seen yet; the first check is a second after `now`.
    pub fn new(now: Instant) -> Self {
        Self {
            last_check: now,
            publishers: BTreeMap::new(),
        }
    }

    /// At most once per second: takes `peers()` and logs what changed
    /// since the last check (the first check only records).
    pub fn poll<const N: usize>(
        &mut self,
        now: Instant,
        peers: impl FnOnce() -> [(&'static str, PeerReport); N],
    ) {
        if now.saturating_duration_since(self.last_check) < Duration::from_secs(1) {
            return;
        }
        self.last_check = now;
        for (t, p) in peers() {
            let prev = self.publishers.insert(t, (p.publishers, p.dead));
            if prev.is_some_and(|(np, nd)| np != p.publishers || nd != p.dead) {
                if p.dead > 0 {
                    tracing::warn!(
                        topic = t,
                        publishers = p.publishers,
                        dead_nodes = p.dead,
                        "a peer of this topic died"
                    );
                } else {
                    tracing::info!(topic = t, publishers = p.publishers, "publishers changed");
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_names_the_step_and_shows_a_blocked_thread_as_sleeping() {
        let probe = std::sync::Arc::new(RxProbe::default());
        assert_eq!(probe.step(), "starting");
        assert_eq!(probe.kernel_view(), "thread id unknown");
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let (reg_tx, reg_rx) = std::sync::mpsc::channel::<()>();
        let p = std::sync::Arc::clone(&probe);
        let h = std::thread::spawn(move || {
            p.register_thread();
            p.enter(RxStep::Sleep, 0);
            reg_tx.send(()).unwrap();
            // blocked until the test lets it go
            let _ = rx.recv();
        });
        reg_rx.recv().unwrap();
        assert_eq!(probe.step(), "sleeping for the poll interval");
        // the thread gets to its recv() some time after it said so
        let t0 = Instant::now();
        let view = loop {
            let v = probe.kernel_view();
            if v.contains("state S") || t0.elapsed() > Duration::from_secs(10) {
                break v;
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        assert!(view.starts_with("tid "), "{view}");
        assert!(view.contains("state S"), "{view}");
        tx.send(()).unwrap();
        h.join().unwrap();
        probe.enter(RxStep::Receive, 3);
        assert_eq!(probe.step(), format!("receiving {}", crate::RECORDED[3]));
    }
}
