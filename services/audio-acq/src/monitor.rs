//! The non-real-time helper thread beside the capture loop (the loop
//! through [`grip_io::service::monitor`]: `WATCHDOG=1` while the block
//! counter advances; log lines on transitions, never per block). `READY=1`,
//! `STATUS=` and `STOPPING=1` come from [`grip_io::systemd`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use grip_io::service::monitor::{self, Changed, Count, Flow, FlowEvent, HelperError, Monitor};
use grip_io::warn_if_grew;

use crate::AcqStatus;

/// Spawns the helper thread (before the caller switches to SCHED_FIFO, so
/// the helper stays SCHED_OTHER). Every 50 ms (or half the watchdog period
/// if shorter) it sends `WATCHDOG=1` at half the watchdog period if the
/// block counter advanced, and logs: new xruns, truth lost / back, unknown
/// roads, publish errors, failed truth reads, a stalled source (no block for 1 s); at most one
/// line per kind per second. Ends when `done` is set.
pub fn spawn_helper(
    status: Arc<AcqStatus>,
    synth: bool,
    done: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, HelperError> {
    let m = AcqMonitor {
        blocks: Flow::new(
            status.blocks.load(Ordering::Relaxed),
            Instant::now(),
            Duration::from_secs(1),
        ),
        truth_lost: Changed::new(None),
        xruns: Count::default(),
        pub_err: Count::default(),
        truth_err: Count::default(),
        unknown: Count::default(),
        unknown_said: None,
        s: status,
        synth,
    };
    monitor::spawn("audio-acq-helper", m, done)
}

struct AcqMonitor {
    s: Arc<AcqStatus>,
    synth: bool,
    blocks: Flow,
    truth_lost: Changed<Option<bool>>,
    xruns: Count,
    pub_err: Count,
    truth_err: Count,
    unknown: Count,
    /// The unknown road last said (each new one is said once).
    unknown_said: Option<[u8; grip_msgs::NAME_LEN]>,
}

impl Monitor for AcqMonitor {
    fn heartbeat(&self) -> u64 {
        self.s.blocks.load(Ordering::Relaxed)
    }

    fn stalled(&self, blocks: u64) {
        tracing::warn!(
            blocks,
            "no block since the last watchdog period: watchdog not fed"
        );
    }

    fn tick(&mut self, now: Instant) {
        let s = &self.s;
        let beat = s.blocks.load(Ordering::Relaxed);
        match self.blocks.update(beat, now) {
            Some(FlowEvent::Moving {
                after_stall: true, ..
            }) => tracing::info!(blocks = beat, "audio blocks flowing again"),
            Some(FlowEvent::Stopped) => tracing::warn!(
                blocks = beat,
                timeouts = s.timeouts.load(Ordering::Relaxed),
                "no audio block for 1 s (device delivers no data)"
            ),
            _ => {}
        }
        if self.synth && beat > 0 {
            match self
                .truth_lost
                .update(Some(s.truth_lost.load(Ordering::Relaxed)))
            {
                Some(Some(true)) => tracing::warn!(
                    received = s.truth_received.load(Ordering::Relaxed),
                    "ground truth (topic grip/plant/truth) lost or not yet received: synth follows [synth] on_truth_lost"
                ),
                Some(Some(false)) => {
                    tracing::info!("ground truth arriving: synth follows road and speed")
                }
                _ => {}
            }
        }
    }

    fn report(&mut self, _now: Instant) {
        let s = &self.s;
        warn_if_grew!(
            self.xruns,
            s.xruns.load(Ordering::Relaxed),
            "capture overruns (xruns), recovered"
        );
        warn_if_grew!(
            self.pub_err,
            s.publish_errors.load(Ordering::Relaxed),
            "publishing audio blocks failed"
        );
        warn_if_grew!(
            self.truth_err,
            s.truth_errors.load(Ordering::Relaxed),
            "reading the ground truth failed (the synthesiser keeps its last road until the truth timeout)"
        );
        if self
            .unknown
            .grew(s.unknown_road.load(Ordering::Relaxed))
            .is_some()
        {
            let name = s.unknown_name();
            if self.unknown_said != Some(name) {
                self.unknown_said = Some(name);
                tracing::warn!(
                    "ground truth names road `{}`, which the synthesiser has no sound for: generating vehicle noise only while the microphone is on it (a road without a sound of its own, as ice, is meant to be; for another, add it to [synth] aliases)",
                    grip_msgs::name_from_bytes(&name).unwrap_or("(not UTF-8)")
                );
            }
        }
    }
}
