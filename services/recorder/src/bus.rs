//! The vehicle bus as a CAN logger records it: `recorder.toml`'s `bus`.
//!
//! The recorder opens the bus of `can.toml` read-only ([`open_monitor`]:
//! every frame, nothing ever sent), on the receive thread beside the
//! subscribers, and logs what it reads on the MCAP channel
//! [`topics::BUS`] as [`BusFrame`]s: with `bus = "foreign"` (the default)
//! only the frames that are not grip's protocol messages (those are in
//! tcs-loop's CAN log, `grip/can/log`, with the loop's own stamps), with
//! `"all"` every frame, with `"off"` nothing (the bus is not opened). On
//! SocketCAN the kernel drops grip's frames before the recorder reads them
//! (`"foreign"`: inverted, joined `CAN_RAW_FILTER`s), so they cost it
//! nothing; on the simulated bus they are read and skipped (`skipped_own`).
//!
//! - **Stamps**: on SocketCAN the kernel's receive time (`SO_TIMESTAMPNS`,
//!   moved onto CLOCK_MONOTONIC, the log's time base); on the simulated
//!   bus the recorder's CLOCK_MONOTONIC when it reads the frame, up to one
//!   `poll_interval_ms` (2 ms) after its arrival (plus the pass over the
//!   other topics).
//! - **Losses**: frames the kernel dropped on the monitor's full receive
//!   queue (`SO_RXQ_OVFL`: `kernel_dropped`), frames the recorder's queue
//!   had no room for (`queue_dropped`), as for every topic.
//! - **A bus that cannot be opened** is a warning, never the recorder's
//!   end: the loops' topics are recorded regardless, and the bus is tried
//!   again every [`RETRY`] (on the car the recorder may start before the
//!   CAN interface is up; `transport = "auto"` under systemd refuses the
//!   simulated fallback, as the loops do, and waits for the interface).
//!   An interface deleted and re-created while recording is reopened by
//!   the transport ([`grip_io::can::SocketCanBus`]); read errors are
//!   counted (`receive_errors`) and warned about at most once a second.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use grip_io::can::{AnyBus, BusKind, CanBusConfig, CanError, open_monitor, protocol};
use grip_io::ipc::IpcNode;
use grip_msgs::{BusFrame, CanFrame, can_flags, topics};

use crate::config::BusRecord;
use crate::cycle::{ErrorReport, Msg, Queue};

/// How often a bus that could not be opened is tried again.
pub const RETRY: Duration = Duration::from_secs(1);

/// Most frames the receive thread reads off the bus in one pass; a pass
/// that read any is followed by its `poll_interval_ms` sleep. A real bus
/// carries at most about 21 000 frames a second (1 Mbit/s, empty frames),
/// 42 per 2 ms: 256 a pass keep up with it six times over, and a flood
/// beyond (a babbling node on vcan, the HIL fault matrix's 39 000
/// frames/s) is lost in the socket, counted, instead of starving the
/// loops' topics of the thread (on the HIL VM's one emulated CPU the flood
/// read 4096 a pass cost 43 cycle records and 171 ground-truth samples).
pub const MAX_PER_PASS: usize = 256;

/// True for one of grip's protocol messages on the bus: an 11-bit data
/// frame whose id the active protocol (`can.toml`'s DBC) gives to one of
/// its five messages. Allocation-free.
pub fn is_grips(f: &CanFrame) -> bool {
    let not_data = can_flags::EXTENDED | can_flags::RTR | can_flags::ERROR;
    f.flags & not_data == 0 && protocol::spec_for_id(f.id).is_some()
}

/// Whether `mode` logs `f`.
pub fn keeps(mode: BusRecord, f: &CanFrame) -> bool {
    match mode {
        BusRecord::All => true,
        BusRecord::Foreign => !is_grips(f),
        BusRecord::Off => false,
    }
}

/// What the bus log counted (the `grip/can/bus.*` keys of `grip.recorder`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Frames read off the bus.
    pub received: u64,
    /// Frames of grip's protocol not logged (`bus = "foreign"`).
    pub skipped_own: u64,
    /// Frames the recorder's queue had no room for.
    pub queue_dropped: u64,
    /// Read errors.
    pub receive_errors: u64,
    /// Frames the kernel dropped on the full receive queue (SocketCAN).
    pub kernel_dropped: u64,
    /// Frames stamped with the kernel's receive time.
    pub kernel_stamped: u64,
    /// Sockets reopened on a re-created interface.
    pub reopens: u64,
    /// Failed attempts to open the bus.
    pub open_failures: u64,
    /// The transport, once open.
    pub transport: Option<BusKind>,
}

/// What the receive thread needs to open the bus (it opens it itself:
/// iceoryx2 ports, the simulated bus's, are not `Send`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusSetup {
    /// `can.toml`.
    pub can: CanBusConfig,
    /// `recorder.toml`'s `bus` (not [`BusRecord::Off`]: then no setup).
    pub mode: BusRecord,
    /// Running as a systemd unit (`transport = "auto"` then refuses the
    /// simulated fallback, as [`open_monitor`] documents).
    pub under_systemd: bool,
}

/// The bus on the receive thread: opened (and retried), drained into the
/// queue.
pub struct BusTap {
    cfg: CanBusConfig,
    mode: BusRecord,
    under_systemd: bool,
    bus: Option<AnyBus>,
    next_try: Option<Instant>,
    warned: bool,
    errors: ErrorReport,
    stats: BusStats,
}

impl core::fmt::Debug for BusTap {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("BusTap")
            .field("mode", &self.mode)
            .field("open", &self.bus.is_some())
            .field("stats", &self.stats)
            .finish()
    }
}

impl BusTap {
    /// A tap on the bus of `setup` (not opened yet: [`Self::poll_open`]).
    pub fn new(setup: BusSetup) -> Self {
        Self {
            cfg: setup.can,
            mode: setup.mode,
            under_systemd: setup.under_systemd,
            bus: None,
            next_try: None,
            warned: false,
            errors: ErrorReport::default(),
            stats: BusStats::default(),
        }
    }

    /// Opens the bus if it is not open and a try is due (at once, then
    /// every [`RETRY`]). A failure is a warning (once; the success after
    /// it an info line), never an error.
    pub fn poll_open(&mut self, node: &IpcNode, now: Instant) {
        if self.bus.is_some() || self.mode == BusRecord::Off {
            return;
        }
        if self.next_try.is_some_and(|t| now < t) {
            return;
        }
        self.next_try = Some(now + RETRY);
        // "foreign": grip's ids dropped in the kernel already (SocketCAN;
        // the simulated bus delivers them and `keeps` skips them)
        let mut exclude = [0u32; 5];
        let exclude: &[u32] = match self.mode {
            BusRecord::Foreign => {
                for (e, m) in exclude.iter_mut().zip(protocol::active().messages()) {
                    *e = m.id;
                }
                &exclude
            }
            BusRecord::All | BusRecord::Off => &[],
        };
        match open_monitor(&self.cfg, node, self.under_systemd, exclude) {
            Ok(b) => {
                self.stats.transport = Some(grip_io::can::CanBus::kind(&b));
                tracing::info!(
                    bus = %self.cfg.interface,
                    record = self.mode.as_str(),
                    channel = topics::BUS,
                    after_failures = self.stats.open_failures,
                    "bus log: recording the vehicle bus (read-only)"
                );
                self.bus = Some(b);
            }
            Err(e) => {
                self.stats.open_failures += 1;
                if !self.warned {
                    self.warned = true;
                    tracing::warn!(
                        interface = %self.cfg.interface,
                        transport = ?self.cfg.transport,
                        error = %e,
                        retry_s = RETRY.as_secs(),
                        "bus log: cannot open the vehicle bus (can.toml); recording everything else, and trying again every second"
                    );
                }
            }
        }
    }

    /// Moves at most `max` frames waiting on the bus into `q` (those
    /// `mode` keeps); `beat` moves with each. Returns the frames read.
    /// Allocation-free.
    pub fn pass(&mut self, q: &Queue, max: usize, beat: &AtomicU64) -> usize {
        let Some(bus) = self.bus.as_mut() else {
            return 0;
        };
        let mut n = 0;
        while n < max {
            match bus.try_recv_monitor() {
                Ok(Some(f)) => {
                    n += 1;
                    self.stats.received += 1;
                    beat.fetch_add(1, Ordering::Relaxed);
                    if !keeps(self.mode, &f) {
                        self.stats.skipped_own += 1;
                    } else if q.half_full() || !q.offer(Msg::Bus(BusFrame::from_can(&f))) {
                        // the other half of the queue is the loops'
                        self.stats.queue_dropped += 1;
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    self.stats.receive_errors += 1;
                    warn(&mut self.errors, &e);
                    break;
                }
            }
        }
        self.stats.kernel_dropped = bus.rx_overflows();
        self.stats.reopens = bus.reopens();
        self.stats.kernel_stamped = bus.kernel_stamped();
        n
    }

    /// Whether the bus is open.
    pub fn is_open(&self) -> bool {
        self.bus.is_some()
    }

    /// The mode it records in.
    pub fn mode(&self) -> BusRecord {
        self.mode
    }

    /// Its counters.
    pub fn stats(&self) -> BusStats {
        self.stats
    }
}

/// A read error, warned about at most once a second ([`ErrorReport`]).
fn warn(errors: &mut ErrorReport, e: &CanError) {
    if let Some(n) = errors.observe(Instant::now()) {
        tracing::warn!(
            topic = topics::BUS,
            error = %e,
            errors = n,
            "bus log: read error (counted in grip.recorder's grip/can/bus.receive_errors; at most one warning a second)"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// "foreign" keeps every frame but grip's 11-bit data frames of the
    /// active (here built-in) protocol: an extended or remote frame with
    /// the same number is foreign; "all" keeps everything.
    #[test]
    fn foreign_is_everything_but_grips_standard_data_frames() {
        for m in protocol::MESSAGES {
            let f = CanFrame::new(m.id, &[1; 8]);
            assert!(is_grips(&f), "{}", m.name);
            assert!(!keeps(BusRecord::Foreign, &f));
            assert!(keeps(BusRecord::All, &f));
            assert!(!keeps(BusRecord::Off, &f));
            let mut ext = f;
            ext.flags = can_flags::EXTENDED;
            assert!(keeps(BusRecord::Foreign, &ext), "extended {}", m.name);
            let mut rtr = f;
            rtr.flags = can_flags::RTR;
            assert!(keeps(BusRecord::Foreign, &rtr), "remote {}", m.name);
        }
        for id in [0x000, 0x7FF, 0x3E9, 0x18F] {
            let f = CanFrame::new(id, &[2; 4]);
            assert!(keeps(BusRecord::Foreign, &f), "{id:#x}");
        }
    }
}
