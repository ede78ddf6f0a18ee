//! SocketCAN transport (the `socketcan` crate).

use core::time::Duration;
use std::io::ErrorKind;

use socketcan::{CanDataFrame, CanFilter, CanSocket, Socket, SocketOptions};
use socketcan::{EmbeddedFrame as _, ExtendedId, Id, StandardId};

use super::{BusKind, CanBus, CanError, CanFrame, RxFilter};
use crate::clock::monotonic_now_ns;
use grip_msgs::{can_dir, can_flags};

/// Checks that the kernel supports AF_CAN raw sockets.
pub fn af_can_available() -> Result<(), std::io::Error> {
    // SAFETY: plain socket(2) call; the descriptor is closed right away.
    let fd = unsafe { libc::socket(libc::AF_CAN, libc::SOCK_RAW, libc::CAN_RAW) };
    if fd < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: fd is a descriptor we own.
    unsafe { libc::close(fd) };
    Ok(())
}

/// True if a network interface of this name exists.
pub fn interface_exists(iface: &str) -> bool {
    let Ok(c) = std::ffi::CString::new(iface) else {
        return false;
    };
    // SAFETY: valid NUL-terminated string.
    unsafe { libc::if_nametoindex(c.as_ptr()) != 0 }
}

/// The sysfs path that shows network interface `iface` is backed by a
/// device (a CAN controller on a bus: PCI, USB, SPI, a SoC's own), if it
/// is: virtual interfaces (`vcan`, `vxcan`) have no `device` link in
/// `/sys/class/net/<iface>/`.
pub fn physical_interface(iface: &str) -> Option<std::path::PathBuf> {
    physical_interface_in(std::path::Path::new("/sys/class/net"), iface)
}

/// [`physical_interface`] under another sysfs root (tests).
pub fn physical_interface_in(
    sys_class_net: &std::path::Path,
    iface: &str,
) -> Option<std::path::PathBuf> {
    if iface.is_empty() || iface.contains('/') || iface == "." || iface == ".." {
        return None;
    }
    let dev = sys_class_net.join(iface).join("device");
    dev.exists().then_some(dev)
}

/// A raw CAN socket on one interface, non-blocking; receive waits use ppoll(2).
///
/// Every frame it reads is stamped with the kernel's receive time
/// (`SO_TIMESTAMPNS`, moved onto CLOCK_MONOTONIC): when the frame arrived,
/// not when its reader got to it, so that a CAN log written by a loop that
/// was stalled shows the frames spread over the stall as they came (until
/// 2026-12-07 only a monitor's were; the others carried the read time).
///
/// When the interface is deleted (a USB-CAN adapter unplugged, `ip link
/// del`), the kernel unbinds the socket for good: one receive reports
/// `ENODEV`, every send `ENXIO`, and nothing arrives again, even once an
/// interface of that name is back (a new one, with a new index). The bus
/// notes either error, then, at most every [`REOPEN_CHECK_NS`], on a send
/// or receive, looks the name up and, when it exists again, opens a new
/// socket on it with the same receive filters ([`Self::reopens`] counts
/// it). Until then sends and receives fail as before (the owner's input
/// timeouts put it in its safe state). The check and the reopen are a
/// few bounded, non-blocking system calls, without allocation.
#[derive(Debug)]
pub struct SocketCanBus {
    sock: CanSocket,
    iface: String,
    /// `iface` for if_nametoindex(3) (made once, at open).
    iface_c: std::ffi::CString,
    bus_id: u8,
    rx: RxFilter,
    /// The kernel filters of `rx` (made once, at open; reused to reopen).
    filters: Option<Vec<CanFilter>>,
    /// CLOCK_MONOTONIC when the interface was found gone, while it is.
    gone_since: Option<u64>,
    /// Next time (ns) to look whether it is back.
    next_check_ns: u64,
    /// Sockets reopened on a re-created interface.
    reopens: u64,
    /// Opened as a bus monitor ([`Self::open_monitor`]): receive-queue
    /// overflow counts, error frames (re-applied on a reopen; every socket
    /// has kernel receive stamps).
    monitor: bool,
    /// Frames the kernel dropped on earlier sockets (before a reopen).
    dropped_before: u64,
    /// The current socket's drop counter (`SO_RXQ_OVFL`), as last seen.
    dropped_now: u32,
    /// Frames read stamped with the kernel's receive time.
    kernel_stamped: u64,
    /// 11-bit ids a monitor's kernel filter drops ([`Self::open_monitor`]).
    exclude: heapless::Vec<u32, MONITOR_MAX_EXCLUDED>,
    /// Moves the kernel's stamps onto CLOCK_MONOTONIC.
    stamps: StampClock,
}

/// How long a reading of the two clocks serves to move kernel stamps from
/// CLOCK_REALTIME onto CLOCK_MONOTONIC: reading both for every frame would
/// triple the clock reads of each read, which the real-time loops do up to
/// [`super::MAX_RX_PER_CYCLE`] times a cycle (a clock read is slow under
/// emulation, where the HIL suite floods the bus). An NTP slew (at most
/// 500 ppm) moves a stamp by at most 50 µs over it. A wall-clock step
/// makes a stamp fall after its read, before the stamp handed out before
/// it, or more than
/// [`CLOCK_PAIR_CHECK_NS`] before its read: then the pair is read again at
/// once (and the stamp kept within the last one and its read).
pub const CLOCK_PAIR_MAX_AGE_NS: u64 = 100_000_000;

/// A kernel stamp this long before its read has the clock pair read again
/// before it is believed (a wall-clock step back; or a frame that really
/// waited this long, which the new pair then confirms).
pub const CLOCK_PAIR_CHECK_NS: u64 = 1_000_000_000;

/// How often a bus whose interface vanished looks whether it is back.
pub const REOPEN_CHECK_NS: u64 = 100_000_000;

/// True for the errors of a socket whose interface was deleted: `ENODEV`
/// (receive, once) and `ENXIO` (send: the socket is no longer bound).
fn interface_gone(e: &std::io::Error) -> bool {
    matches!(e.raw_os_error(), Some(libc::ENODEV | libc::ENXIO))
}

/// The kernel receive filters (`CAN_RAW_FILTER`) of `rx`, `None` for
/// [`RxFilter::All`] (the kernel's default: one filter that passes every
/// frame). One filter per id the role receives; its mask covers the 11 id
/// bits and the EFF and RTR flags, so an extended frame or a remote frame
/// with the same number does not pass. Error frames are governed by
/// `CAN_RAW_ERR_FILTER`, which grip leaves at the kernel's default (none
/// subscribed) for every filter.
fn kernel_filters(rx: RxFilter) -> Option<Vec<CanFilter>> {
    match rx {
        RxFilter::All => None,
        RxFilter::Role(role) => Some(
            role.receives()
                .map(|m| {
                    CanFilter::new(
                        m.id,
                        libc::CAN_SFF_MASK | libc::CAN_EFF_FLAG | libc::CAN_RTR_FLAG,
                    )
                })
                .collect(),
        ),
    }
}

/// Most frames read and dropped right after the filters are set (those
/// queued between bind(2) and setsockopt(2), which the filters do not reach).
const FLUSH_MAX: usize = 4096;

impl SocketCanBus {
    /// Opens `iface`, receiving what `rx` lets through (kernel filters, set
    /// before the socket is handed out; frames queued in the instant between
    /// binding and setting them are dropped). Errors name the interface and
    /// say how to create it.
    pub fn open(iface: &str, bus_id: u8, rx: RxFilter) -> Result<Self, CanError> {
        af_can_available().map_err(CanError::NoAfCan)?;
        if !interface_exists(iface) {
            return Err(CanError::NoInterface {
                iface: iface.into(),
            });
        }
        let io = |e| CanError::Io {
            iface: iface.into(),
            error: e,
        };
        let iface_c = std::ffi::CString::new(iface).map_err(|_| CanError::NoInterface {
            iface: iface.into(),
        })?;
        let filters = kernel_filters(rx);
        let sock = CanSocket::open(iface).map_err(io)?;
        configure(&sock, filters.as_deref()).map_err(io)?;
        Ok(Self {
            sock,
            iface: iface.into(),
            iface_c,
            bus_id,
            rx,
            filters,
            gone_since: None,
            next_check_ns: 0,
            reopens: 0,
            monitor: false,
            dropped_before: 0,
            dropped_now: 0,
            kernel_stamped: 0,
            exclude: heapless::Vec::new(),
            stamps: StampClock::default(),
        })
    }

    /// Opens `iface` read-only as a bus monitor (a CAN logger): every
    /// frame, data, remote and error frames alike ([`RxFilter::All`] and
    /// `CAN_RAW_ERR_FILTER` = every error class), each stamped with the
    /// kernel's receive time (`SO_TIMESTAMPNS`) and the frames the kernel
    /// dropped on a full receive queue counted (`SO_RXQ_OVFL`). Read it
    /// with [`Self::try_recv_monitor`]; the receive buffer is asked for
    /// [`MONITOR_RCVBUF`] bytes (the kernel caps it at `net.core.rmem_max`).
    ///
    /// `exclude`: 11-bit data-frame ids the kernel drops before the
    /// monitor sees them (inverted `CAN_RAW_FILTER`s joined with
    /// `CAN_RAW_JOIN_FILTERS`: a frame passes only if it is none of them;
    /// an extended or remote frame with the same number passes), so that
    /// traffic the owner does not log costs it nothing, not even a read
    /// (the recorder's `bus = "foreign"`: grip's own ids). At most
    /// [`MONITOR_MAX_EXCLUDED`].
    pub fn open_monitor(iface: &str, bus_id: u8, exclude: &[u32]) -> Result<Self, CanError> {
        let io = |e| CanError::Io {
            iface: iface.into(),
            error: e,
        };
        let mut b = Self::open(iface, bus_id, RxFilter::All)?;
        b.exclude = heapless::Vec::from_slice(exclude).map_err(|_| {
            io(std::io::Error::other(format!(
                "{} ids to exclude, at most {MONITOR_MAX_EXCLUDED}",
                exclude.len()
            )))
        })?;
        monitor_options(&b.sock, &b.exclude).map_err(io)?;
        b.monitor = true;
        Ok(b)
    }

    /// Frames the kernel dropped because this socket's receive queue was
    /// full, summed over every socket it reopened: the socket's drop
    /// counter (`SO_MEMINFO`, one `getsockopt(2)`; also what the
    /// `SO_RXQ_OVFL` control messages of a monitor's reads said, which
    /// come only with a frame queued after a drop, so that drops at the
    /// end of a burst would go unseen by them alone).
    pub fn rx_overflows(&self) -> u64 {
        let now = socket_drops(&self.sock).unwrap_or(0).max(self.dropped_now);
        self.dropped_before + u64::from(now)
    }

    /// Frames read stamped with the kernel's receive time (the others,
    /// none on a kernel that stamps, with CLOCK_MONOTONIC at read).
    pub fn kernel_stamped(&self) -> u64 {
        self.kernel_stamped
    }

    /// A monitor's read: the next frame waiting, any kind (data, remote:
    /// `can_flags::RTR`, error: `can_flags::ERROR` with the error class
    /// bits as its id), without blocking, stamped with the kernel's receive
    /// time as every read of this bus is ([`SocketCanBus`]). The
    /// interface's loss and return are handled as in [`CanBus::try_recv`].
    pub fn try_recv_monitor(&mut self) -> Result<Option<CanFrame>, CanError> {
        self.reopen_if_back();
        self.recv_stamped()
    }

    /// The next frame waiting on the socket, any kind, without blocking,
    /// stamped with the kernel's receive time (every socket asks for it,
    /// `SO_TIMESTAMPNS`, which is CLOCK_REALTIME) moved onto
    /// CLOCK_MONOTONIC by [`StampClock`]; where the kernel gave no stamp,
    /// CLOCK_MONOTONIC at read. So a frame that waited in the socket while
    /// its reader was stalled carries the time it arrived, not the time it
    /// was read. `recvmsg(2)` into buffers on
    /// the stack: allocation-free.
    fn recv_stamped(&mut self) -> Result<Option<CanFrame>, CanError> {
        use std::os::fd::AsRawFd as _;
        // SAFETY: can_frame is plain data; all-zero is a valid frame.
        let mut raw: libc::can_frame = unsafe { core::mem::zeroed() };
        // 8-byte aligned room for a timespec and a u32 control message
        let mut control = [0u64; 16];
        let mut iov = libc::iovec {
            iov_base: (&raw mut raw).cast(),
            iov_len: core::mem::size_of::<libc::can_frame>(),
        };
        // SAFETY: msghdr is plain data; all-zero is a valid empty header.
        let mut msg: libc::msghdr = unsafe { core::mem::zeroed() };
        msg.msg_iov = &raw mut iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control.as_mut_ptr().cast();
        msg.msg_controllen = core::mem::size_of_val(&control) as _;
        // SAFETY: the header points at live buffers of the sizes given.
        let n = unsafe { libc::recvmsg(self.sock.as_raw_fd(), &mut msg, libc::MSG_DONTWAIT) };
        if n < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == ErrorKind::WouldBlock {
                return Ok(None);
            }
            self.note(&e);
            return Err(CanError::Transfer {
                op: "receive",
                kind: e.kind(),
            });
        }
        let read_mono = monotonic_now_ns();
        let mut kernel_real: Option<u64> = None;
        // SAFETY: msg was filled by recvmsg; the CMSG_* walk stays within
        // msg_controllen, and the data are read unaligned.
        unsafe {
            let mut c = libc::CMSG_FIRSTHDR(&msg);
            while !c.is_null() {
                let h = &*c;
                if h.cmsg_level == libc::SOL_SOCKET {
                    if h.cmsg_type == libc::SCM_TIMESTAMPNS {
                        let ts: libc::timespec =
                            core::ptr::read_unaligned(libc::CMSG_DATA(c).cast());
                        kernel_real = u64::try_from(ts.tv_sec)
                            .ok()
                            .zip(u64::try_from(ts.tv_nsec).ok())
                            .map(|(s, ns)| s.saturating_mul(1_000_000_000).saturating_add(ns));
                    } else if h.cmsg_type == libc::SO_RXQ_OVFL {
                        let d: u32 = core::ptr::read_unaligned(libc::CMSG_DATA(c).cast());
                        self.dropped_now = self.dropped_now.max(d);
                    }
                }
                c = libc::CMSG_NXTHDR(&msg, c);
            }
        }
        if (n as usize) < core::mem::size_of::<libc::can_frame>() {
            // not a classic frame (never, without CAN_RAW_FD_FRAMES)
            return Ok(None);
        }
        let stamp = match kernel_real {
            Some(k) => {
                self.kernel_stamped += 1;
                self.stamps
                    .to_monotonic(k, read_mono, || (realtime_now_ns(), monotonic_now_ns()))
            }
            None => read_mono,
        };
        Ok(Some(frame_from_raw(&raw, stamp, self.bus_id)))
    }

    /// Waits at most `timeout_ns` for the socket to have something to
    /// read (`ppoll(2)`): true when it has (or has an error to report),
    /// false on the timeout or a signal. Allocation-free.
    fn wait_readable(&self, timeout_ns: u64) -> Result<bool, CanError> {
        use std::os::fd::AsRawFd as _;
        let mut pfd = libc::pollfd {
            fd: self.sock.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ts = libc::timespec {
            tv_sec: (timeout_ns / 1_000_000_000) as libc::time_t,
            tv_nsec: (timeout_ns % 1_000_000_000) as libc::c_long,
        };
        // SAFETY: one live pollfd, a valid timespec, no signal mask.
        let r = unsafe { libc::ppoll(&raw mut pfd, 1, &raw const ts, core::ptr::null()) };
        if r < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == ErrorKind::Interrupted {
                return Ok(false);
            }
            return Err(CanError::Transfer {
                op: "receive",
                kind: e.kind(),
            });
        }
        Ok(r > 0)
    }

    /// Times the socket was reopened on a re-created interface.
    pub fn reopens(&self) -> u64 {
        self.reopens
    }

    /// Since when (CLOCK_MONOTONIC, ns) the interface has been gone (its
    /// socket unbound by the kernel), if it is now.
    pub fn gone_since(&self) -> Option<u64> {
        self.gone_since
    }

    /// Notes an error of the socket: one of an unbound socket marks the
    /// interface gone.
    fn note(&mut self, e: &std::io::Error) {
        if self.gone_since.is_none() && interface_gone(e) {
            let now = monotonic_now_ns();
            self.gone_since = Some(now);
            self.next_check_ns = now;
        }
    }

    /// While the interface is gone, at most every [`REOPEN_CHECK_NS`]:
    /// if an interface of its name exists, a new socket on it replaces
    /// the dead one. Bounded and non-blocking; allocation-free.
    fn reopen_if_back(&mut self) {
        if self.gone_since.is_none() {
            return;
        }
        let now = monotonic_now_ns();
        if now < self.next_check_ns {
            return;
        }
        self.next_check_ns = now.saturating_add(REOPEN_CHECK_NS);
        // SAFETY: valid NUL-terminated string.
        let index = unsafe { libc::if_nametoindex(self.iface_c.as_ptr()) };
        if index == 0 {
            return;
        }
        let Ok(sock) = CanSocket::open_iface(index) else {
            return;
        };
        if configure(&sock, self.filters.as_deref()).is_ok()
            && (!self.monitor || monitor_options(&sock, &self.exclude).is_ok())
        {
            self.sock = sock;
            self.gone_since = None;
            self.reopens += 1;
            let old = socket_drops(&self.sock).unwrap_or(0).max(self.dropped_now);
            self.dropped_before += u64::from(old);
            self.dropped_now = 0;
        }
    }

    /// What this socket receives.
    pub fn rx_filter(&self) -> RxFilter {
        self.rx
    }

    /// Interface name.
    pub fn iface(&self) -> &str {
        &self.iface
    }
}

/// Receive buffer a monitor asks for (`SO_RCVBUF`), bytes: the kernel
/// caps it at `net.core.rmem_max` (and doubles it for its bookkeeping):
/// on a default kernel (rmem_max 212992) that doubles the queue a bus
/// monitor has, to 555 classic frames (HIL VM, 2026-12-05), 0.28 s of a
/// busy bus at 2000 frames/s.
pub const MONITOR_RCVBUF: libc::c_int = 4 << 20;

fn setsockopt_int(
    sock: &CanSocket,
    level: libc::c_int,
    name: libc::c_int,
    v: libc::c_int,
) -> std::io::Result<()> {
    use std::os::fd::AsRawFd as _;
    // SAFETY: a c_int option value of its size.
    let r = unsafe {
        libc::setsockopt(
            sock.as_raw_fd(),
            level,
            name,
            (&raw const v).cast(),
            core::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if r < 0 {
        Err(std::io::Error::last_os_error())
    } else {
        Ok(())
    }
}

/// A monitor socket's options (beyond the kernel receive stamps every
/// socket has): drop counts, every error class, a larger receive buffer
/// (best effort).
fn monitor_options(sock: &CanSocket, exclude: &[u32]) -> std::io::Result<()> {
    use std::os::fd::AsRawFd as _;
    if !exclude.is_empty() {
        let mut filters = [libc::can_filter {
            can_id: 0,
            can_mask: 0,
        }; MONITOR_MAX_EXCLUDED];
        for (f, &id) in filters.iter_mut().zip(exclude) {
            f.can_id = (id & libc::CAN_SFF_MASK) | libc::CAN_INV_FILTER;
            f.can_mask = libc::CAN_SFF_MASK | libc::CAN_EFF_FLAG | libc::CAN_RTR_FLAG;
        }
        let n = exclude.len().min(MONITOR_MAX_EXCLUDED);
        // SAFETY: an array of n can_filter and its byte length.
        let r = unsafe {
            libc::setsockopt(
                sock.as_raw_fd(),
                libc::SOL_CAN_RAW,
                libc::CAN_RAW_FILTER,
                filters.as_ptr().cast(),
                (n * core::mem::size_of::<libc::can_filter>()) as libc::socklen_t,
            )
        };
        if r < 0 {
            return Err(std::io::Error::last_os_error());
        }
        setsockopt_int(sock, libc::SOL_CAN_RAW, libc::CAN_RAW_JOIN_FILTERS, 1)?;
    }
    setsockopt_int(sock, libc::SOL_SOCKET, libc::SO_RXQ_OVFL, 1)?;
    setsockopt_int(
        sock,
        libc::SOL_CAN_RAW,
        libc::CAN_RAW_ERR_FILTER,
        libc::CAN_ERR_MASK as libc::c_int,
    )?;
    // capped by rmem_max; a smaller buffer still works
    let _ = setsockopt_int(sock, libc::SOL_SOCKET, libc::SO_RCVBUF, MONITOR_RCVBUF);
    Ok(())
}

/// Most ids a monitor's kernel filter excludes ([`SocketCanBus::open_monitor`]).
pub const MONITOR_MAX_EXCLUDED: usize = 16;

/// `SO_MEMINFO` (asm-generic's value: x86-64, AArch64, ARM, RISC-V).
const SO_MEMINFO: libc::c_int = 55;

/// The socket's count of frames dropped on a full receive queue
/// (`sk_drops`, by `SO_MEMINFO`); `None` if the kernel does not say.
fn socket_drops(sock: &CanSocket) -> Option<u32> {
    use std::os::fd::AsRawFd as _;
    let mut mem = [0u32; 9];
    let mut len = core::mem::size_of_val(&mem) as libc::socklen_t;
    // SAFETY: a buffer of `len` bytes and its length.
    let r = unsafe {
        libc::getsockopt(
            sock.as_raw_fd(),
            libc::SOL_SOCKET,
            SO_MEMINFO,
            mem.as_mut_ptr().cast(),
            &mut len,
        )
    };
    let drops = libc::SK_MEMINFO_DROPS as usize;
    (r == 0 && len as usize >= (drops + 1) * 4).then_some(mem[drops])
}

/// CLOCK_REALTIME now, ns.
fn realtime_now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid out-pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_REALTIME, &mut ts) };
    (ts.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(ts.tv_nsec as u64)
}

/// Moves a socket's kernel receive stamps (CLOCK_REALTIME) onto
/// CLOCK_MONOTONIC: `mono_at + (real - real_at)` with a pair of the two
/// clocks read together at most [`CLOCK_PAIR_MAX_AGE_NS`] before. The pair
/// is read again at once when a stamp comes out odd: after its read, before
/// the stamp handed out before it (a socket's queue is in arrival order),
/// or more than [`CLOCK_PAIR_CHECK_NS`] before its read (each a sign of a
/// wall-clock step since the pair was read); and a stamp is always kept
/// within the one before it and its read. Allocation-free.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StampClock {
    /// (CLOCK_REALTIME, CLOCK_MONOTONIC) read together; (0, 0): not yet.
    pair: (u64, u64),
    /// The last stamp handed out.
    last: u64,
}

impl StampClock {
    /// The kernel stamp `real` of a frame read at `read_mono`, on
    /// CLOCK_MONOTONIC; `read_pair` reads the two clocks together when the
    /// pair is due or the stamp odd.
    pub fn to_monotonic(
        &mut self,
        real: u64,
        read_mono: u64,
        read_pair: impl FnOnce() -> (u64, u64),
    ) -> u64 {
        let convert = |(real_at, mono_at): (u64, u64)| {
            i128::from(mono_at) + i128::from(real) - i128::from(real_at)
        };
        let read = i128::from(read_mono);
        let mut m = convert(self.pair);
        let odd =
            m > read || m < i128::from(self.last) || m < read - i128::from(CLOCK_PAIR_CHECK_NS);
        if self.pair.1 == 0 || read_mono.saturating_sub(self.pair.1) > CLOCK_PAIR_MAX_AGE_NS || odd
        {
            self.pair = read_pair();
            m = convert(self.pair);
        }
        let s = m.max(i128::from(self.last)).min(read).max(0) as u64;
        self.last = s;
        s
    }
}

/// A grip frame of a raw SocketCAN frame: 11- or 29-bit id and the
/// extended, remote and error flags; payload bytes beyond the DLC zeroed.
pub fn frame_from_raw(raw: &libc::can_frame, stamp_ns: u64, bus_id: u8) -> CanFrame {
    let id = raw.can_id;
    let mut flags = 0;
    let ident = if id & libc::CAN_ERR_FLAG != 0 {
        flags |= can_flags::ERROR;
        id & libc::CAN_ERR_MASK
    } else if id & libc::CAN_EFF_FLAG != 0 {
        flags |= can_flags::EXTENDED;
        id & libc::CAN_EFF_MASK
    } else {
        id & libc::CAN_SFF_MASK
    };
    if id & libc::CAN_RTR_FLAG != 0 {
        flags |= can_flags::RTR;
    }
    let dlc = raw.can_dlc.min(8);
    let mut out = CanFrame::new(ident, &[]);
    out.dlc = dlc;
    if flags & can_flags::RTR == 0 {
        let n = usize::from(dlc);
        out.data[..n].copy_from_slice(&raw.data[..n]);
    }
    out.flags = flags;
    out.stamp_ns = stamp_ns;
    out.direction = can_dir::RX;
    out.bus = bus_id;
    out
}

/// Makes a new socket non-blocking and sets its kernel filters, dropping
/// what arrived before they were set.
fn configure(sock: &CanSocket, filters: Option<&[CanFilter]>) -> std::io::Result<()> {
    sock.set_nonblocking(true)?;
    // every read carries the kernel's receive time ([`SocketCanBus`]'s
    // `recv_stamped`)
    setsockopt_int(sock, libc::SOL_SOCKET, libc::SO_TIMESTAMPNS, 1)?;
    if let Some(filters) = filters {
        sock.set_filters(filters)?;
        for _ in 0..FLUSH_MAX {
            if sock.read_frame().is_err() {
                break;
            }
        }
    }
    Ok(())
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        self.reopen_if_back();
        let bad = CanError::InvalidFrame {
            id: frame.id,
            dlc: frame.dlc,
        };
        if frame.dlc > 8 {
            return Err(bad);
        }
        let id: Id = if frame.flags & can_flags::EXTENDED != 0 {
            match ExtendedId::new(frame.id) {
                Some(e) => e.into(),
                None => return Err(bad),
            }
        } else {
            match u16::try_from(frame.id).ok().and_then(StandardId::new) {
                Some(s) => s.into(),
                None => return Err(bad),
            }
        };
        let Some(f) = CanDataFrame::new(id, frame.payload()) else {
            return Err(bad);
        };
        self.sock.write_frame(&f).map_err(|e| {
            self.note(&e);
            CanError::Transfer {
                op: "send",
                kind: e.kind(),
            }
        })
    }

    /// The next data frame waiting (remote and error frames are not part
    /// of the protocol and are skipped), stamped with the kernel's receive
    /// time ([`SocketCanBus`]'s `recv_stamped`): the time it arrived, not
    /// the time it was read.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError> {
        self.reopen_if_back();
        loop {
            match self.recv_stamped()? {
                Some(f) if f.flags & (can_flags::RTR | can_flags::ERROR) != 0 => {}
                other => return Ok(other),
            }
        }
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError> {
        let deadline = super::deadline_after(timeout);
        loop {
            if let Some(f) = self.try_recv()? {
                return Ok(Some(f));
            }
            let now = monotonic_now_ns();
            if now >= deadline {
                return Ok(None);
            }
            self.wait_readable(deadline - now)?;
        }
    }

    fn kind(&self) -> BusKind {
        BusKind::SocketCan
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::protocol::{MESSAGES, Role};

    /// The kernel filters of a role: one per id it receives, each matching
    /// only that 11-bit data frame (the EFF and RTR flags in the mask, not
    /// in the id); none for `All`. How the kernel matches
    /// (`received & mask == id & mask`), written out here.
    #[test]
    fn kernel_filters_pass_exactly_the_roles_standard_data_frames() {
        assert!(kernel_filters(RxFilter::All).is_none());
        let passes = |fs: &[CanFilter], can_id: u32| {
            fs.iter().any(|f| {
                let f: &libc::can_filter = f.as_ref();
                can_id & f.can_mask == f.can_id & f.can_mask
            })
        };
        for role in [Role::Tcs, Role::Inverter] {
            let fs = kernel_filters(RxFilter::Role(role)).unwrap();
            assert_eq!(fs.len(), role.receives().count());
            for m in MESSAGES {
                let mine = m.receiver == role;
                assert_eq!(passes(&fs, m.id), mine, "{role:?} {}", m.name);
                assert!(
                    !passes(&fs, m.id | libc::CAN_EFF_FLAG),
                    "extended {}",
                    m.name
                );
                assert!(!passes(&fs, m.id | libc::CAN_RTR_FLAG), "remote {}", m.name);
            }
            for foreign in [0x000, 0x7FF, 0x5A5, 0x1ABC_DEF0 | libc::CAN_EFF_FLAG] {
                assert!(!passes(&fs, foreign), "{role:?} {foreign:#x}");
            }
        }
    }

    /// A raw kernel frame as the monitor hands it out: 11- and 29-bit ids,
    /// remote frames without payload, error frames with their class as the
    /// id, a corrupt DLC clamped, bytes beyond the DLC zeroed.
    #[test]
    fn raw_frames_become_grip_frames_with_their_kind() {
        // SAFETY: can_frame is plain data; all-zero is a valid frame.
        let mut raw: libc::can_frame = unsafe { core::mem::zeroed() };
        raw.data = [1, 2, 3, 4, 5, 6, 7, 8];
        let conv = |raw: &libc::can_frame| frame_from_raw(raw, 42, 7);
        raw.can_id = 0x3E9;
        raw.can_dlc = 3;
        let f = conv(&raw);
        assert_eq!(
            (f.id, f.flags, f.dlc, f.stamp_ns, f.bus),
            (0x3E9, 0, 3, 42, 7)
        );
        assert_eq!(f.data, [1, 2, 3, 0, 0, 0, 0, 0]);
        raw.can_id = 0x18DA_F110 | libc::CAN_EFF_FLAG;
        raw.can_dlc = 12;
        let f = conv(&raw);
        assert_eq!(
            (f.id, f.flags, f.dlc),
            (0x18DA_F110, can_flags::EXTENDED, 8)
        );
        raw.can_id = 0x7AB | libc::CAN_RTR_FLAG;
        raw.can_dlc = 4;
        let f = conv(&raw);
        assert_eq!(
            (f.id, f.flags, f.dlc, f.data),
            (0x7AB, can_flags::RTR, 4, [0; 8])
        );
        raw.can_id = libc::CAN_ERR_FLAG | 0x04;
        raw.can_dlc = 8;
        let f = conv(&raw);
        assert_eq!((f.id, f.flags), (0x04, can_flags::ERROR));
    }

    /// The kernel's CLOCK_REALTIME stamps onto CLOCK_MONOTONIC: shifted by
    /// the clocks' difference, the pair read once per
    /// [`CLOCK_PAIR_MAX_AGE_NS`]; a wall-clock step either way since the
    /// pair was read has it read again at once, and no stamp is later than
    /// its read or earlier than the one before it.
    #[test]
    fn realtime_stamps_move_onto_the_monotonic_clock() {
        const S: u64 = 1_000_000_000;
        const MS: u64 = 1_000_000;
        let mut c = StampClock::default();
        let reads = std::cell::Cell::new(0);
        // the wall clock 1000 s ahead of the monotonic one
        let pair = |real: u64, mono: u64| {
            let r = &reads;
            move || {
                r.set(r.get() + 1);
                (real, mono)
            }
        };
        // received 1.5 ms before the read (the first read reads the pair)
        assert_eq!(
            c.to_monotonic(1000 * S + 5 * S - 1_500_000, 5 * S, pair(1005 * S, 5 * S)),
            5 * S - 1_500_000
        );
        assert_eq!(reads.get(), 1);
        // 50 ms later: the same pair serves, a frame received after it
        assert_eq!(
            c.to_monotonic(1005 * S + 40 * MS, 5 * S + 50 * MS, pair(0, 0)),
            5 * S + 40 * MS
        );
        assert_eq!(reads.get(), 1);
        // 150 ms after the pair: read again
        assert_eq!(
            c.to_monotonic(
                1005 * S + 140 * MS,
                5 * S + 150 * MS,
                pair(1005 * S + 150 * MS, 5 * S + 150 * MS)
            ),
            5 * S + 140 * MS
        );
        assert_eq!(reads.get(), 2);
        // the wall clock stepped back 10 s: with the old pair the stamp
        // would be 10 s before its read; the pair is read again
        let t = 5 * S + 160 * MS;
        assert_eq!(
            c.to_monotonic(995 * S + 158 * MS, t, pair(995 * S + 160 * MS, t)),
            t - 2 * MS
        );
        assert_eq!(reads.get(), 3);
        // stepped forward 10 s: a stamp after its read; read again
        let t = 5 * S + 170 * MS;
        assert_eq!(
            c.to_monotonic(1005 * S + 169 * MS, t, pair(1005 * S + 170 * MS, t)),
            t - MS
        );
        assert_eq!(reads.get(), 4);
        // a stamp before the last one even with a fresh pair (a step
        // within the frame's wait): kept at the last one
        assert_eq!(
            c.to_monotonic(
                1005 * S + 150 * MS,
                t + MS,
                pair(1005 * S + 171 * MS, t + MS)
            ),
            t - MS
        );
        assert_eq!(reads.get(), 5);
        // a pair that cannot explain it (earlier than boot): never below 0
        let mut c = StampClock::default();
        assert_eq!(c.to_monotonic(0, 5, pair(1000 * S, 5)), 0);
    }

    /// A fake `/sys/class/net`: `can0` with a `device` link (a controller on
    /// a bus), `vcan0` without (virtual).
    #[test]
    fn physical_interfaces_are_those_with_a_device() {
        let sys = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(sys.path().join("can0/device")).unwrap();
        std::fs::create_dir_all(sys.path().join("vcan0")).unwrap();
        assert_eq!(
            physical_interface_in(sys.path(), "can0"),
            Some(sys.path().join("can0/device"))
        );
        assert_eq!(physical_interface_in(sys.path(), "vcan0"), None);
        assert_eq!(physical_interface_in(sys.path(), "absent0"), None);
        // a name cannot climb out of the directory
        std::fs::create_dir_all(sys.path().join("device")).unwrap();
        assert_eq!(physical_interface_in(sys.path(), ".."), None);
        assert_eq!(physical_interface_in(sys.path(), "."), None);
        assert_eq!(physical_interface_in(sys.path(), ""), None);
    }
}
