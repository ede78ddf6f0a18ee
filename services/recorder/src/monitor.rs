//! What the recorder watches and logs outside its per-message work. It
//! has no helper thread of its own: the receive thread follows the
//! publishers of every topic ([`PeerWatch`], once per second), and the
//! writing loop feeds the watchdog (`WATCHDOG=1` through
//! [`grip_io::systemd::Watchdog`]) only while both it and the receive
//! thread advance ([`receive_stalled`] otherwise).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use grip_io::ipc::PeerReport;

/// The receive thread's heartbeat did not move for half a watchdog period.
pub fn receive_stalled(heartbeat: u64) {
    tracing::warn!(
        heartbeat,
        "recorder receive thread stalled: watchdog not fed"
    );
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
