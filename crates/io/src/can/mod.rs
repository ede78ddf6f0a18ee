//! CAN: the inverter protocol ([`protocol`]) and the transports behind one
//! trait ([`CanBus`]): Linux SocketCAN ([`SocketCanBus`]) and a simulated
//! bus over iceoryx2 ([`SimBus`]) that carries the very same 8-byte frames;
//! [`MemBus`], in-process queues, for single-threaded tests and replay.
//! [`open_bus`] picks one per [`CanBusConfig`]; `auto` takes SocketCAN when
//! the interface exists and the kernel has AF_CAN, else the simulated bus,
//! and logs which and why. Each bus delivers what its [`RxFilter`] lets
//! through: a service's bus only the ids its [`Role`] receives.

pub mod bitrate;
mod dbc;
mod mem;
pub mod protocol;
mod sim;
mod socket;

use core::time::Duration;

pub use bitrate::{
    BitrateChoice, BitrateSource, InterfaceBitrate, choose_bitrate, read_interface_bitrate,
};
pub use dbc::{
    DbcError, DbcSettings, VALID_FLAGS as DBC_VALID_FLAGS, message_names as dbc_message_names,
    name_keys as dbc_name_keys,
};
pub use grip_msgs::CanFrame;
pub use mem::{FrameQueue, MEM_BUS_CAPACITY, MemBus, frame_queue};
pub use sim::SimBus;
pub use socket::{
    CLOCK_PAIR_CHECK_NS, CLOCK_PAIR_MAX_AGE_NS, MONITOR_MAX_EXCLUDED, MONITOR_RCVBUF,
    REOPEN_CHECK_NS, SocketCanBus, StampClock, af_can_available, frame_from_raw, interface_exists,
    physical_interface, physical_interface_in,
};

use crate::ipc::{IpcError, IpcNode};
pub use protocol::Role;

/// Which frames a bus delivers to its owner: given to [`open_bus`] (and
/// [`SocketCanBus::open`], [`SimBus::with_rx_filter`],
/// [`MemBus::with_rx_filter`]). Every transport applies the same rule, so
/// the simulated and in-memory buses deliver what SocketCAN delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RxFilter {
    /// Every data frame on the bus (the behaviour before filters): for a
    /// recorder or bus monitor that must see foreign traffic too.
    #[default]
    All,
    /// Only the protocol messages `role` receives ([`Role::receives`], read
    /// from [`protocol::MESSAGES`]): 11-bit data frames with those ids.
    /// Foreign ids, extended (29-bit) frames and remote frames never reach
    /// the owner; on SocketCAN the kernel drops them (`CAN_RAW_FILTER`), so
    /// a busy shared bus does not wake the receiver either.
    Role(Role),
}

impl RxFilter {
    /// True if the owner receives `frame`. Allocation-free.
    pub fn accepts(&self, frame: &CanFrame) -> bool {
        match self {
            Self::All => true,
            Self::Role(r) => {
                let not_data = grip_msgs::can_flags::EXTENDED
                    | grip_msgs::can_flags::RTR
                    | grip_msgs::can_flags::ERROR;
                frame.flags & not_data == 0 && r.receives_id(frame.id)
            }
        }
    }
}

impl core::fmt::Display for RxFilter {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::All => f.write_str("every frame"),
            Self::Role(r) => {
                write!(f, "{}'s ids", r.node())?;
                for m in r.receives() {
                    write!(f, " 0x{:03X}", m.id)?;
                }
                Ok(())
            }
        }
    }
}

/// Most frames a real-time loop (tcs-loop, plant-sim) drains from its bus
/// in one cycle; the rest waits for the next cycle, so a flood cannot make
/// a cycle unbounded. The bus carries ~3.2 frames per ms and the fault
/// matrix's floods add up to ~4 more; a cycle that comes late after a stall
/// must still reach the valid frames behind a burst of bad ones before the
/// inputs' 10 ms timeout: 256 frames are over 30 ms of a flooded bus (64
/// were 9 ms: a burst of bad-CRC frames at the head of the queue after an
/// 8 ms late wake-up hid every valid WheelSpeeds, and tcs-loop went to its
/// safe state, HIL 2026-12-02). One constant for both loops, so that they
/// cannot drift apart.
pub const MAX_RX_PER_CYCLE: usize = 256;

/// CLOCK_MONOTONIC `timeout` from now, ns, for a bus's
/// [`CanBus::recv_timeout`]: a timeout beyond u64 nanoseconds (centuries)
/// is for ever, not wrapped to a short one.
pub(crate) fn deadline_after(timeout: Duration) -> u64 {
    crate::clock::monotonic_now_ns()
        .saturating_add(u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX))
}

/// What [`drain`] took from a bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Drained {
    /// Frames written to the front of the buffer.
    pub frames: usize,
    /// The drain stopped at a receive error.
    pub error: bool,
}

/// Drops the frames waiting on `bus` (at most `max`), without blocking;
/// how many. A real-time loop calls it once, right before its first cycle:
/// what arrived while the service started (its ports, the real-time
/// set-up: tens to hundreds of ms) is stale, and a backlog of that size
/// overflows a SocketCAN receive queue (about 200-260 frames by default),
/// whose lost frames the first cycles then counted as skipped alive
/// counters (HIL, 2026-12-05). The receivers start from the first fresh
/// frame (a resync, no fault).
pub fn discard_pending<B: CanBus + ?Sized>(bus: &mut B, max: usize) -> usize {
    let mut n = 0;
    while n < max {
        match bus.try_recv() {
            Ok(Some(_)) => n += 1,
            Ok(None) | Err(_) => break,
        }
    }
    n
}

/// Takes the frames waiting on `bus` without blocking into `buf` (at most
/// its length: the real-time loops pass their [`MAX_RX_PER_CYCLE`] array),
/// stopping at the first empty read or error. The loops read their cycle's
/// clock *after* it, so that no frame is stamped earlier than it arrived
/// (a frame reaching the socket while the thread was preempted between a
/// clock read and the drain made an input timeout fire early).
/// Allocation-free.
pub fn drain<B: CanBus + ?Sized>(bus: &mut B, buf: &mut [CanFrame]) -> Drained {
    let mut d = Drained {
        frames: 0,
        error: false,
    };
    while d.frames < buf.len() {
        match bus.try_recv() {
            Ok(Some(f)) => {
                buf[d.frames] = f;
                d.frames += 1;
            }
            Ok(None) => break,
            Err(_) => {
                d.error = true;
                break;
            }
        }
    }
    d
}

/// Errors of CAN transports.
#[derive(Debug, thiserror::Error)]
pub enum CanError {
    /// The kernel has no CAN support.
    #[error(
        "the kernel has no SocketCAN support (socket(AF_CAN) failed: {0}); use transport = \"sim\" or \"auto\", or a kernel with CONFIG_CAN (modprobe can-raw)"
    )]
    NoAfCan(std::io::Error),
    /// The interface does not exist.
    #[error(
        "CAN interface {iface:?} does not exist; create it with `ip link add dev {iface} type vcan && ip link set {iface} up` (virtual) or bring up the real one (`ip link set {iface} up type can bitrate 1000000`), or set transport = \"sim\""
    )]
    NoInterface {
        /// Interface name.
        iface: String,
    },
    /// Other I/O error of the socket.
    #[error("CAN interface {iface:?}: {error}")]
    Io {
        /// Interface name.
        iface: String,
        /// The error (said in the message, not returned as the source:
        /// a chain printed in full would say it twice).
        error: std::io::Error,
    },
    /// Socket send/receive error on the hot path (no allocation).
    #[error("CAN {op} failed: {kind:?}")]
    Transfer {
        /// "send" or "receive".
        op: &'static str,
        /// The OS error kind.
        kind: std::io::ErrorKind,
    },
    /// Frame not sendable (DLC > 8, id out of range).
    #[error("invalid CAN frame id 0x{id:X} dlc {dlc}")]
    InvalidFrame {
        /// Id.
        id: u32,
        /// DLC.
        dlc: u8,
    },
    /// Simulated bus (iceoryx2) error.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// `transport = "auto"` found no usable SocketCAN interface while the
    /// service runs as a systemd unit: on the car the simulated bus would
    /// leave the inverter without commands while the unit looks healthy.
    #[error(
        "can.toml: transport = \"auto\" found no usable SocketCAN interface ({why}), and this service runs as a systemd unit (the car), where the simulated bus instead would carry no frame to or from the inverter: refused. Set transport = \"socketcan\" and interface = your bus (e.g. \"can0\", brought up with `ip link set can0 up type can bitrate 1000000 restart-ms 100`), or transport = \"sim\" for a bench without CAN"
    )]
    AutoUnderSystemd {
        /// Why SocketCAN was not used.
        why: String,
    },
}

/// A CAN transport. Implementations allocate nothing in `send`, `try_recv`
/// and `recv_timeout`. Received frames are stamped with CLOCK_MONOTONIC at
/// arrival (SocketCAN: the kernel's receive time; the simulated bus: the
/// publish time; [`MemBus`]: as fed), not when they are read, and marked
/// `direction = RX`; a participant never receives its own frames.
pub trait CanBus {
    /// Sends one frame (non-blocking where the transport allows).
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError>;
    /// Returns a received frame if one is waiting.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError>;
    /// Waits at most `timeout` for a frame.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError>;
    /// Which transport this is.
    fn kind(&self) -> BusKind;
}

/// Transport kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusKind {
    /// Linux SocketCAN.
    SocketCan,
    /// iceoryx2 simulated bus.
    Sim,
}

/// Which transport to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Transport {
    /// SocketCAN if available, else simulated (logged loudly).
    #[default]
    Auto,
    /// SocketCAN only (error if unavailable).
    Socketcan,
    /// Simulated bus only.
    Sim,
}

/// CAN bus configuration (`config/can.toml`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CanBusConfig {
    /// Transport choice.
    #[serde(default)]
    pub transport: Transport,
    /// SocketCAN interface (`can0` on the car, `vcan0` in tests).
    pub interface: String,
    /// Name of the simulated bus (iceoryx2 service `grip/canbus/<name>`);
    /// defaults to the interface name.
    #[serde(default)]
    pub sim_bus: Option<String>,
    /// Bus number written into logged frames.
    #[serde(default)]
    pub bus_id: u8,
    /// The bus's DBC (a path relative to the configuration directory):
    /// grip's five messages with this bus's ids, layouts, scalings and
    /// timing ([`protocol::Protocol::load_dbc`]). Absent: the built-in
    /// protocol, the one the shipped `config/inverter.dbc` describes.
    #[serde(default)]
    pub dbc: Option<String>,
    /// grip's message and signal names (`TorqueCommand`,
    /// `TorqueCommand.TorqueRequest`) mapped to the DBC's own, where they
    /// differ.
    #[serde(default)]
    pub dbc_names: std::collections::BTreeMap<String, String>,
    /// grip's validity flags (`WheelSpeeds.DrivenValid`,
    /// `WheelSpeeds.RefValid`, `VehicleSpeed.Valid`) mapped to the raw
    /// value that means valid on this bus (0 for a bit that says
    /// *invalid*; one state of a multi-bit status). Wins over the DBC's
    /// `VAL_` table; a flag in neither is valid when non-zero
    /// ([`DbcSettings::valid`]).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub dbc_valid: std::collections::BTreeMap<String, i64>,
}

impl Default for CanBusConfig {
    fn default() -> Self {
        Self {
            transport: Transport::Auto,
            interface: "vcan0".into(),
            sim_bus: None,
            bus_id: 0,
            dbc: None,
            dbc_names: std::collections::BTreeMap::new(),
            dbc_valid: std::collections::BTreeMap::new(),
        }
    }
}

impl CanBusConfig {
    /// Name of the simulated bus.
    pub fn sim_bus_name(&self) -> &str {
        self.sim_bus.as_deref().unwrap_or(&self.interface)
    }
}

/// Either transport, without dynamic dispatch. (The size difference is a
/// one-off at start-up; boxing would add an indirection per frame.)
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum AnyBus {
    /// SocketCAN.
    SocketCan(SocketCanBus),
    /// Simulated.
    Sim(SimBus),
}

impl AnyBus {
    /// Whether a SocketCAN bus's interface is gone now (deleted or
    /// unplugged, its socket unbound) and how often its socket was reopened
    /// on a re-created interface ([`SocketCanBus::gone_since`],
    /// [`SocketCanBus::reopens`]); `(false, 0)` for the simulated bus. What
    /// a loop stores for its helper thread after each cycle
    /// ([`crate::service::monitor::BusPresence`]); allocation-free.
    pub fn presence(&self) -> (bool, u64) {
        match self {
            Self::SocketCan(b) => (b.gone_since().is_some(), b.reopens()),
            Self::Sim(_) => (false, 0),
        }
    }
}

impl CanBus for AnyBus {
    fn send(&mut self, f: &CanFrame) -> Result<(), CanError> {
        match self {
            Self::SocketCan(b) => b.send(f),
            Self::Sim(b) => b.send(f),
        }
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError> {
        match self {
            Self::SocketCan(b) => b.try_recv(),
            Self::Sim(b) => b.try_recv(),
        }
    }
    fn recv_timeout(&mut self, t: Duration) -> Result<Option<CanFrame>, CanError> {
        match self {
            Self::SocketCan(b) => b.recv_timeout(t),
            Self::Sim(b) => b.recv_timeout(t),
        }
    }
    fn kind(&self) -> BusKind {
        match self {
            Self::SocketCan(_) => BusKind::SocketCan,
            Self::Sim(_) => BusKind::Sim,
        }
    }
}

impl AnyBus {
    /// A bus monitor's read ([`open_monitor`]): on SocketCAN
    /// [`SocketCanBus::try_recv_monitor`] (every frame kind, the kernel's
    /// receive time), on the simulated bus [`CanBus::try_recv`] (every
    /// frame another participant sent, stamped when it was published).
    /// Allocation-free.
    pub fn try_recv_monitor(&mut self) -> Result<Option<CanFrame>, CanError> {
        match self {
            Self::SocketCan(b) => b.try_recv_monitor(),
            Self::Sim(b) => b.try_recv(),
        }
    }

    /// Frames the kernel dropped on a full receive queue
    /// ([`SocketCanBus::rx_overflows`]); 0 on the simulated bus, which
    /// cannot tell (a reader that falls 1024 frames behind loses the
    /// oldest unseen).
    pub fn rx_overflows(&self) -> u64 {
        match self {
            Self::SocketCan(b) => b.rx_overflows(),
            Self::Sim(_) => 0,
        }
    }

    /// Sockets reopened on a re-created interface (SocketCAN; 0 simulated).
    pub fn reopens(&self) -> u64 {
        match self {
            Self::SocketCan(b) => b.reopens(),
            Self::Sim(_) => 0,
        }
    }

    /// Frames a monitor read stamped with the kernel's receive time.
    pub fn kernel_stamped(&self) -> u64 {
        match self {
            Self::SocketCan(b) => b.kernel_stamped(),
            Self::Sim(_) => 0,
        }
    }
}

/// Opens the bus `cfg` asks for read-only, as a bus monitor (the
/// recorder's bus log): every frame ([`RxFilter::All`]); on SocketCAN with
/// kernel receive stamps, drop counts and error frames
/// ([`SocketCanBus::open_monitor`], which drops the 11-bit data frames of
/// `exclude` in the kernel). The transport is chosen as
/// [`open_bus_as`] chooses it. Nothing is ever sent on it by its owner
/// (read it with [`AnyBus::try_recv_monitor`]); on the simulated bus it
/// still takes a publisher port (unused), as every participant does.
pub fn open_monitor(
    cfg: &CanBusConfig,
    node: &IpcNode,
    under_systemd: bool,
    exclude: &[u32],
) -> Result<AnyBus, CanError> {
    open_as(cfg, node, under_systemd, RxFilter::All, Some(exclude))
}

/// Opens the bus `cfg` asks for, delivering only what `rx` lets through
/// (a service passes its [`RxFilter::Role`]). `auto`: SocketCAN when AF_CAN works and
/// the interface exists, else the simulated bus, with a loud warning saying
/// which and why; but under systemd (`INVOCATION_ID` set, as systemd sets it
/// for every unit it starts, and `grip drive` does not) that fallback is
/// [`CanError::AutoUnderSystemd`]: a unit on the car must not run on a bus
/// that reaches no inverter (and Restart= retries until the interface is up).
pub fn open_bus(cfg: &CanBusConfig, node: &IpcNode, rx: RxFilter) -> Result<AnyBus, CanError> {
    open_bus_as(cfg, node, std::env::var_os("INVOCATION_ID").is_some(), rx)
}

/// [`open_bus`], saying whether the caller runs as a systemd unit.
pub fn open_bus_as(
    cfg: &CanBusConfig,
    node: &IpcNode,
    under_systemd: bool,
    rx: RxFilter,
) -> Result<AnyBus, CanError> {
    open_as(cfg, node, under_systemd, rx, None)
}

fn open_as(
    cfg: &CanBusConfig,
    node: &IpcNode,
    under_systemd: bool,
    rx: RxFilter,
    monitor: Option<&[u32]>,
) -> Result<AnyBus, CanError> {
    let socket = |iface: &str| match monitor {
        Some(exclude) => SocketCanBus::open_monitor(iface, cfg.bus_id, exclude),
        None => SocketCanBus::open(iface, cfg.bus_id, rx),
    };
    let sim = || -> Result<AnyBus, CanError> {
        Ok(AnyBus::Sim(
            SimBus::open(node, cfg.sim_bus_name(), cfg.bus_id)?.with_rx_filter(rx),
        ))
    };
    match cfg.transport {
        Transport::Socketcan => {
            let b = socket(&cfg.interface)?;
            tracing::info!(iface = %cfg.interface, receives = %rx, "CAN transport: SocketCAN");
            Ok(AnyBus::SocketCan(b))
        }
        Transport::Sim => {
            let b = sim()?;
            tracing::warn!(bus = %cfg.sim_bus_name(), receives = %rx, "CAN transport: SIMULATED bus over iceoryx2 (configured transport = \"sim\")");
            Ok(b)
        }
        Transport::Auto => {
            let why = match af_can_available() {
                Err(e) => format!("kernel has no AF_CAN ({e})"),
                Ok(()) if !interface_exists(&cfg.interface) => {
                    format!("interface {:?} does not exist", cfg.interface)
                }
                Ok(()) => match socket(&cfg.interface) {
                    Ok(b) => {
                        tracing::info!(iface = %cfg.interface, receives = %rx, "CAN transport: SocketCAN (auto)");
                        return Ok(AnyBus::SocketCan(b));
                    }
                    Err(e) => format!("opening {:?} failed: {e}", cfg.interface),
                },
            };
            if under_systemd {
                return Err(CanError::AutoUnderSystemd { why });
            }
            let b = sim()?;
            tracing::warn!(
                bus = %cfg.sim_bus_name(),
                receives = %rx,
                reason = %why,
                "CAN transport: SIMULATED bus over iceoryx2 instead of SocketCAN; frames never reach a real inverter"
            );
            Ok(b)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The start-up backlog is dropped, at most `max`, and counted; the
    /// bus then delivers what comes next.
    #[test]
    fn discard_pending_drops_the_backlog_and_no_more() {
        let mut bus = MemBus::new();
        for k in 0..10u8 {
            bus.inject(CanFrame::new(0x120, &[k; 8]));
        }
        assert_eq!(discard_pending(&mut bus, 4), 4);
        assert_eq!(discard_pending(&mut bus, 100), 6);
        assert_eq!(discard_pending(&mut bus, 100), 0);
        bus.inject(CanFrame::new(0x120, &[42; 8]));
        assert_eq!(bus.try_recv().unwrap().unwrap().data[0], 42);
    }
}
