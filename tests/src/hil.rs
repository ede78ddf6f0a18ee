//! Helpers for the hardware-in-the-loop tests (`tests/hil_*.rs`).
//!
//! The HIL tests talk to real kernel interfaces: SocketCAN on `vcan0` and the
//! ALSA loopback card (`snd-aloop`). `tools/hil/run` runs them either natively
//! (where the kernel has both) or inside a throw-away VM with a Debian kernel,
//! and sets these environment variables in both cases:
//!
//! | variable | meaning |
//! |---|---|
//! | `GRIP_HIL=1` | the harness started this run |
//! | `GRIP_BIN_DIR` | the workspace's built service binaries (`target/<profile>`) |
//! | `GRIP_CONFIG_DIR` | the workspace's `config/` |
//! | `GRIP_HIL_OUT` | a folder for files to keep (logs, MCAP); copied back to the host |
//! | `GRIP_HIL_VCAN` | the CAN interface the tests use (default `vcan0`) |
//!
//! Every helper falls back to a sensible value when a variable is unset, so a
//! test binary can also be run by hand (`target/debug/deps/hil_smoke-*`).
//! None of them skips anything: a missing interface is an error that fails the
//! test, because the harness is what guarantees the interfaces exist.

use std::ffi::CString;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};
use std::{env, fs, io, mem, thread};

use anyhow::{Context, bail};

/// The service binaries `tools/hil/run` copies into the VM when they exist.
pub const SERVICE_BINARIES: [&str; 6] = [
    "audio-acq",
    "arte",
    "tcs-loop",
    "recorder",
    "plant-sim",
    "grip",
];

/// The workspace root (the parent of this package's directory).
pub fn workspace_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")))
}

/// True when `tools/hil/run` started this process (`GRIP_HIL=1`).
pub fn under_harness() -> bool {
    env::var("GRIP_HIL").is_ok_and(|v| v == "1")
}

/// The CAN interface the HIL tests use: `$GRIP_HIL_VCAN`, else `vcan0`.
pub fn vcan_iface() -> String {
    env::var("GRIP_HIL_VCAN")
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "vcan0".to_owned())
}

/// The workspace's configuration folder: `$GRIP_CONFIG_DIR`, else `<workspace>/config`.
pub fn config_dir() -> PathBuf {
    env::var_os("GRIP_CONFIG_DIR")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join("config"))
}

/// A folder for files a failing run should leave behind (service logs, MCAP
/// files): `$GRIP_HIL_OUT/<sub>`, else `target/hil/manual/<sub>`. Created if
/// missing. In the VM, everything under `$GRIP_HIL_OUT` is copied back to the
/// host (see `tools/hil/README.md`).
pub fn out_dir(sub: &str) -> anyhow::Result<PathBuf> {
    let base = env::var_os("GRIP_HIL_OUT")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join("target/hil/manual"));
    let dir = base.join(sub);
    fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

/// The path of a built service binary, or an error saying how to build it.
/// The folder is grip-io's [`grip_io::binaries::bin_dir`] (the one `grip
/// drive` uses): `$GRIP_BIN_DIR`, else `target/<profile>/`, the parent of
/// this test binary's `deps/`.
pub fn service_bin(name: &str) -> anyhow::Result<PathBuf> {
    let dir = grip_io::binaries::bin_dir()?.path;
    let p = dir.join(name);
    if p.is_file() {
        Ok(p)
    } else {
        bail!(
            "service binary {} not found (GRIP_BIN_DIR={}); tools/hil/run builds \
             the workspace's service binaries, or run `cargo build --bin {name}`",
            p.display(),
            dir.display()
        )
    }
}

/// The path of an external tool (e.g. `candump`) on `PATH`, or an error.
pub fn tool(name: &str) -> anyhow::Result<PathBuf> {
    let path = env::var_os("PATH").unwrap_or_default();
    env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
        .with_context(|| {
            format!(
                "`{name}` not found on PATH; it comes with Debian's can-utils \
                 (tools/hil/run puts it into the VM; natively: apt-get install can-utils)"
            )
        })
}

/// Fails with a clear message unless CAN interface `iface` exists and is up.
pub fn require_can_iface(iface: &str) -> anyhow::Result<()> {
    let flags = fs::read_to_string(format!("/sys/class/net/{iface}/flags")).with_context(|| {
        format!(
            "CAN interface {iface} does not exist on this kernel; the HIL tests need \
             vcan (run them with tools/hil/run, which boots a VM where it is missing)"
        )
    })?;
    let flags = u32::from_str_radix(flags.trim().trim_start_matches("0x"), 16)
        .with_context(|| format!("/sys/class/net/{iface}/flags: not a hex number: {flags:?}"))?;
    if flags & 1 == 0 {
        bail!("CAN interface {iface} is down (ip link set {iface} up)");
    }
    Ok(())
}

/// Fails with a clear message unless an ALSA card with id `Loopback` exists.
pub fn require_alsa_loopback() -> anyhow::Result<()> {
    let cards = fs::read_to_string("/proc/asound/cards").context(
        "no ALSA on this kernel (/proc/asound/cards missing); the HIL tests need \
         snd-aloop (run them with tools/hil/run, which boots a VM where it is missing)",
    )?;
    if !cards.contains("[Loopback") {
        bail!("no ALSA Loopback card (modprobe snd-aloop); /proc/asound/cards:\n{cards}");
    }
    Ok(())
}

// --- an independent raw CAN socket ------------------------------------------

/// `struct can_frame` as the kernel defines it (16 bytes), declared here so the
/// HIL tests check `socketcan` against plain syscalls, not against itself.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RawFrame {
    /// Identifier word: 11 or 29 bit id plus `CAN_EFF_FLAG`/`CAN_RTR_FLAG`/`CAN_ERR_FLAG`.
    pub can_id: u32,
    /// Payload length, 0..=8.
    pub len: u8,
    pad: u8,
    res0: u8,
    len8_dlc: u8,
    /// Payload; bytes past `len` are zero.
    pub data: [u8; 8],
}

/// Extended (29-bit) frame flag in [`RawFrame::can_id`].
pub const CAN_EFF_FLAG: u32 = 0x8000_0000;
/// Remote transmission request flag.
pub const CAN_RTR_FLAG: u32 = 0x4000_0000;
/// Standard frame id mask.
pub const CAN_SFF_MASK: u32 = 0x7FF;
/// Extended frame id mask.
pub const CAN_EFF_MASK: u32 = 0x1FFF_FFFF;

impl RawFrame {
    /// A data frame; `id_word` carries the flags (e.g. `0x123`, `CAN_EFF_FLAG | 0x1234567`).
    pub fn new(id_word: u32, payload: &[u8]) -> anyhow::Result<Self> {
        if payload.len() > 8 {
            bail!(
                "a classic CAN frame carries at most 8 bytes, not {}",
                payload.len()
            );
        }
        let mut f = RawFrame {
            can_id: id_word,
            len: payload.len() as u8,
            ..RawFrame::default()
        };
        f.data[..payload.len()].copy_from_slice(payload);
        Ok(f)
    }

    /// The payload bytes.
    pub fn payload(&self) -> &[u8] {
        &self.data[..usize::from(self.len.min(8))]
    }
}

/// A `PF_CAN/SOCK_RAW/CAN_RAW` socket bound to one interface, through libc only.
#[derive(Debug)]
pub struct RawCanSocket {
    fd: OwnedFd,
}

fn cvt(r: libc::c_int) -> io::Result<libc::c_int> {
    if r < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(r)
    }
}

impl RawCanSocket {
    /// Opens a raw CAN socket bound to `iface`.
    pub fn open(iface: &str) -> anyhow::Result<Self> {
        let name = CString::new(iface).context("interface name contains NUL")?;
        // SAFETY: plain syscalls on values we own; the fd is wrapped at once.
        let fd = cvt(unsafe {
            libc::socket(
                libc::PF_CAN,
                libc::SOCK_RAW | libc::SOCK_CLOEXEC,
                libc::CAN_RAW,
            )
        })
        .context("socket(PF_CAN, SOCK_RAW, CAN_RAW): is CAN in this kernel?")?;
        // SAFETY: fd was just returned by socket() and is owned by nobody else.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: name is a valid NUL-terminated string.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if ifindex == 0 {
            return Err(io::Error::last_os_error())
                .with_context(|| format!("if_nametoindex({iface})"));
        }
        // SAFETY: sockaddr_can is plain old data; all-zero is a valid value.
        let mut addr: libc::sockaddr_can = unsafe { mem::zeroed() };
        addr.can_family = libc::AF_CAN as libc::sa_family_t;
        addr.can_ifindex = ifindex as libc::c_int;
        // SAFETY: addr is a valid sockaddr_can of the given size.
        cvt(unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&raw const addr).cast::<libc::sockaddr>(),
                mem::size_of::<libc::sockaddr_can>() as libc::socklen_t,
            )
        })
        .with_context(|| format!("bind raw CAN socket to {iface}"))?;
        Ok(Self { fd })
    }

    /// Replaces the receive filters (`CAN_RAW_FILTER`): a frame is received
    /// when `received_id & mask == id & mask` for any `(id, mask)`. An empty
    /// slice receives nothing.
    pub fn set_filters(&self, filters: &[(u32, u32)]) -> anyhow::Result<()> {
        let raw: Vec<libc::can_filter> = filters
            .iter()
            .map(|&(can_id, can_mask)| libc::can_filter { can_id, can_mask })
            .collect();
        // SAFETY: raw is a valid array of can_filter of the given byte length.
        cvt(unsafe {
            libc::setsockopt(
                self.fd.as_raw_fd(),
                libc::SOL_CAN_RAW,
                libc::CAN_RAW_FILTER,
                raw.as_ptr().cast(),
                mem::size_of_val(raw.as_slice()) as libc::socklen_t,
            )
        })
        .context("setsockopt(CAN_RAW_FILTER)")?;
        Ok(())
    }

    /// Sends one frame.
    pub fn send(&self, frame: &RawFrame) -> anyhow::Result<()> {
        // SAFETY: frame is a valid 16-byte can_frame.
        let n = unsafe {
            libc::write(
                self.fd.as_raw_fd(),
                (frame as *const RawFrame).cast(),
                mem::size_of::<RawFrame>(),
            )
        };
        if n != mem::size_of::<RawFrame>() as isize {
            return Err(io::Error::last_os_error()).context("write(can_frame)");
        }
        Ok(())
    }

    /// Receives one frame, or `None` when nothing arrives within `timeout`.
    pub fn recv_timeout(&self, timeout: Duration) -> anyhow::Result<Option<RawFrame>> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = libc::c_int::try_from(timeout.as_millis()).unwrap_or(libc::c_int::MAX);
        // SAFETY: pfd is one valid pollfd.
        let ready = cvt(unsafe { libc::poll(&raw mut pfd, 1, ms) }).context("poll")?;
        if ready == 0 {
            return Ok(None);
        }
        let mut frame = RawFrame::default();
        // SAFETY: frame is a writable 16-byte buffer.
        let n = unsafe {
            libc::read(
                self.fd.as_raw_fd(),
                (&raw mut frame).cast(),
                mem::size_of::<RawFrame>(),
            )
        };
        if n != mem::size_of::<RawFrame>() as isize {
            let e = io::Error::last_os_error();
            if matches!(e.raw_os_error(), Some(libc::ENETDOWN | libc::ENODEV)) {
                // the interface went down (ENETDOWN) or was deleted (ENODEV:
                // the socket is unbound from then on): the kernel reports
                // it once (a test may do either on purpose); no frame
                return Ok(None);
            }
            return Err(e).with_context(|| format!("read(can_frame) returned {n}"));
        }
        Ok(Some(frame))
    }
}

// --- child processes ---------------------------------------------------------

/// A child process (a service binary or a tool) that is killed when dropped,
/// with its stdout and stderr written to `<out_dir>/<label>.log`.
#[derive(Debug)]
pub struct Proc {
    child: Child,
    label: String,
    log: PathBuf,
}

impl Proc {
    /// Spawns `program args...` with output to `<log_dir>/<label>.log`.
    pub fn spawn(
        program: &Path,
        args: &[&str],
        label: &str,
        log_dir: &Path,
    ) -> anyhow::Result<Self> {
        Self::spawn_env(program, args, &[], label, log_dir)
    }

    /// Like [`Proc::spawn`], with extra environment variables.
    pub fn spawn_env(
        program: &Path,
        args: &[&str],
        envs: &[(&str, &str)],
        label: &str,
        log_dir: &Path,
    ) -> anyhow::Result<Self> {
        let log = log_dir.join(format!("{label}.log"));
        let out = fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        let err = out.try_clone()?;
        let child = Command::new(program)
            .args(args)
            .envs(envs.iter().copied())
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .with_context(|| format!("spawning {}", program.display()))?;
        Ok(Self {
            child,
            label: label.to_owned(),
            log,
        })
    }

    /// Spawns the workspace's service binary `name` (see [`service_bin`]).
    pub fn service(name: &str, args: &[&str], log_dir: &Path) -> anyhow::Result<Self> {
        Self::spawn(&service_bin(name)?, args, name, log_dir)
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The log file.
    pub fn log_path(&self) -> &Path {
        &self.log
    }

    /// The log so far (lossy UTF-8), for assertion messages.
    pub fn log_text(&self) -> String {
        fs::read(&self.log)
            .map(|b| String::from_utf8_lossy(&b).into_owned())
            .unwrap_or_default()
    }

    /// Sends `signal` (e.g. `libc::SIGKILL`, `libc::SIGTERM`).
    pub fn signal(&self, signal: libc::c_int) -> anyhow::Result<()> {
        let pid = libc::pid_t::try_from(self.child.id()).context("pid out of range")?;
        // SAFETY: kill(2) with a pid we spawned.
        cvt(unsafe { libc::kill(pid, signal) })
            .with_context(|| format!("kill({}, {signal})", self.label))?;
        Ok(())
    }

    /// Waits up to `timeout` for the process to exit.
    pub fn wait_timeout(&mut self, timeout: Duration) -> anyhow::Result<Option<ExitStatus>> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(st) = self.child.try_wait()? {
                return Ok(Some(st));
            }
            if Instant::now() >= end {
                return Ok(None);
            }
            thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

// --- signal analysis for the audio checks -----------------------------------

/// `n` samples of a sine of `freq` Hz at `rate` Hz, peak `amplitude` (full scale 1.0).
pub fn sine_i16(freq: f64, rate: u32, amplitude: f64, n: usize) -> Vec<i16> {
    let w = 2.0 * std::f64::consts::PI * freq / f64::from(rate);
    (0..n)
        .map(|i| {
            let x = amplitude * (w * i as f64).sin() * f64::from(i16::MAX);
            x.round().clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
        })
        .collect()
}

/// Root mean square relative to full scale (1.0 = a full-scale square wave).
pub fn rms(x: &[i16]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let s: f64 = x
        .iter()
        .map(|&v| (f64::from(v) / f64::from(i16::MAX)).powi(2))
        .sum();
    (s / x.len() as f64).sqrt()
}

/// Frequency of a tone from its rising zero crossings, interpolated linearly
/// between samples: (crossings − 1) periods between the first and the last.
/// `None` with fewer than two crossings.
pub fn zero_crossing_frequency(x: &[i16], rate: u32) -> Option<f64> {
    let mut first = None;
    let mut last = 0.0;
    let mut count = 0usize;
    for i in 1..x.len() {
        let (a, b) = (f64::from(x[i - 1]), f64::from(x[i]));
        if a < 0.0 && b >= 0.0 {
            let t = (i - 1) as f64 + (-a) / (b - a);
            first.get_or_insert(t);
            last = t;
            count += 1;
        }
    }
    let first = first?;
    if count < 2 || last <= first {
        return None;
    }
    Some((count - 1) as f64 * f64::from(rate) / (last - first))
}

// --- monotonic time ------------------------------------------------------------

/// CLOCK_MONOTONIC now, ns: the clock the services stamp their records with.
pub fn mono_ns() -> u64 {
    // SAFETY: all-zero is a valid timespec; clock_gettime only writes it.
    let mut ts: libc::timespec = unsafe { mem::zeroed() };
    // SAFETY: ts is a valid timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &raw mut ts) };
    (ts.tv_sec as u64) * 1_000_000_000 + ts.tv_nsec as u64
}

// --- the inverter DBC, decoded independently of grip-io --------------------------

/// CRC-8 SAE J1850 (poly 0x1D, init 0xFF, final XOR 0xFF, not reflected) over
/// the 16-bit E2E data id (low byte, high byte) followed by `bytes`: the E2E
/// CRC the DBC's comment specifies, written here from that text (not taken
/// from grip-io) so the HIL checks are independent of the code under test.
pub fn e2e_crc8(data_id: u16, bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for b in data_id.to_le_bytes().iter().chain(bytes) {
        crc ^= *b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x1D
            } else {
                crc << 1
            };
        }
    }
    crc ^ 0xFF
}

/// The factor from a DBC signal's physical unit to SI (rpm to rad/s, km/h
/// to m/s, g to m/s²); 1 for a unit that is SI already or unknown here.
pub fn si_factor(unit: &str) -> f64 {
    match unit.trim().to_ascii_lowercase().as_str() {
        "rpm" | "1/min" => std::f64::consts::PI / 30.0,
        "km/h" | "kph" => 1.0 / 3.6,
        "g" => 9.806_65,
        _ => 1.0,
    }
}

/// One signal of a DBC message, Intel (little-endian) or Motorola
/// (big-endian) byte order.
#[derive(Debug, Clone)]
pub struct DbcSignal {
    /// Signal name (grip's, where [`Dbc::with_names`] mapped it).
    pub name: String,
    /// The signal's name in the DBC file.
    pub dbc_name: String,
    /// The DBC's physical unit.
    pub unit: String,
    len: u32,
    signed: bool,
    factor: f64,
    offset: f64,
    /// The field's bit positions (bit `i` of byte `b` is `8 * b + i`), most
    /// significant first.
    bits: Vec<u32>,
}

/// The bit positions of a field of `len` bits at DBC start bit `start`,
/// most significant first (bit `i` of byte `b` is `8 * b + i`), or `None`
/// when it runs past byte 7. Intel: `start` is the least significant bit
/// and the field counts upwards. Motorola: `start` is the most significant
/// bit; the field runs down a byte to its bit 0 and goes on at bit 7 of the
/// next byte (the DBC's "sawtooth" numbering), walked bit by bit.
fn field_bits(start: u32, len: u32, motorola: bool) -> Option<Vec<u32>> {
    if len == 0 || len > 64 || start > 63 {
        return None;
    }
    let mut v = Vec::with_capacity(len as usize);
    if motorola {
        let mut p = start;
        for k in 0..len {
            if p > 63 {
                return None;
            }
            v.push(p);
            if k + 1 < len {
                p = if p.is_multiple_of(8) { p + 15 } else { p - 1 };
            }
        }
    } else {
        if start + len > 64 {
            return None;
        }
        v.extend((start..start + len).rev());
    }
    Some(v)
}

impl DbcSignal {
    /// Raw value in an 8-byte payload.
    pub fn raw(&self, data: &[u8; 8]) -> i64 {
        let v = self.bits.iter().fold(0u64, |v, &p| {
            (v << 1) | u64::from((data[(p / 8) as usize] >> (p % 8)) & 1)
        });
        if self.signed && self.len < 64 && (v >> (self.len - 1)) & 1 == 1 {
            (v | !((1u64 << self.len) - 1)) as i64
        } else {
            v as i64
        }
    }

    /// Physical value in an 8-byte payload, in the DBC's unit.
    pub fn phys(&self, data: &[u8; 8]) -> f64 {
        self.raw(data) as f64 * self.factor + self.offset
    }

    /// Physical value in an 8-byte payload in SI units ([`si_factor`]).
    pub fn si(&self, data: &[u8; 8]) -> f64 {
        self.phys(data) * si_factor(&self.unit)
    }

    /// Writes the raw value of `phys` (in the DBC's unit; rounded,
    /// saturated to the field) into `data`.
    pub fn put(&self, data: &mut [u8; 8], phys: f64) {
        let (lo, hi) = if self.signed {
            (-(1i64 << (self.len - 1)), (1i64 << (self.len - 1)) - 1)
        } else {
            (0, (1i64 << self.len) - 1)
        };
        let raw = (((phys - self.offset) / self.factor).round() as i64).clamp(lo, hi) as u64;
        for (k, &p) in self.bits.iter().enumerate() {
            let bit = (raw >> (self.len as usize - 1 - k)) & 1;
            let (b, m) = ((p / 8) as usize, 1u8 << (p % 8));
            if bit == 1 {
                data[b] |= m;
            } else {
                data[b] &= !m;
            }
        }
    }
}

/// One message of the DBC with grip's attributes.
#[derive(Debug, Clone)]
pub struct DbcMessage {
    /// 11-bit identifier.
    pub id: u32,
    /// Message name (grip's, where [`Dbc::with_names`] mapped it).
    pub name: String,
    /// The message's name in the DBC file.
    pub dbc_name: String,
    /// The byte the signal `CRC` fills.
    pub crc_byte: usize,
    /// Data length code.
    pub dlc: u8,
    /// `GripE2eDataId`.
    pub data_id: u16,
    /// `GenMsgCycleTime`, ms.
    pub cycle_ms: u32,
    /// `GripTimeoutMs`, ms.
    pub timeout_ms: u32,
    /// Signals.
    pub signals: Vec<DbcSignal>,
}

impl DbcMessage {
    /// The signal called `name`.
    pub fn sig(&self, name: &str) -> anyhow::Result<&DbcSignal> {
        self.signals
            .iter()
            .find(|s| s.name == name)
            .with_context(|| format!("{} has no signal {name} in the DBC", self.name))
    }

    /// Physical value of signal `name` in `data` (NaN when the DBC lacks it).
    pub fn value(&self, name: &str, data: &[u8; 8]) -> f64 {
        self.sig(name).map_or(f64::NAN, |s| s.phys(data))
    }

    /// The E2E CRC `data` should carry in its CRC byte: over the data id
    /// and the other seven bytes, in order.
    pub fn expected_crc(&self, data: &[u8; 8]) -> u8 {
        let rest: Vec<u8> = data
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != self.crc_byte)
            .map(|(_, &b)| b)
            .collect();
        e2e_crc8(self.data_id, &rest)
    }

    /// The CRC `data` carries (its CRC byte).
    pub fn crc(&self, data: &[u8; 8]) -> u8 {
        data[self.crc_byte]
    }

    /// True when `data` carries the E2E CRC it should.
    pub fn crc_ok(&self, data: &[u8; 8]) -> bool {
        self.crc(data) == self.expected_crc(data)
    }

    /// Physical value of signal `name` in `data` in SI units (NaN when the
    /// DBC lacks it).
    pub fn si(&self, name: &str, data: &[u8; 8]) -> f64 {
        self.sig(name).map_or(f64::NAN, |s| s.si(data))
    }

    /// The alive counter (signal `Counter`).
    pub fn counter(&self, data: &[u8; 8]) -> u8 {
        self.sig("Counter").map_or(0, |s| s.raw(data) as u8)
    }

    /// A payload with the given signal values, `counter` and a correct CRC.
    pub fn encode(&self, values: &[(&str, f64)], counter: u8) -> anyhow::Result<[u8; 8]> {
        let mut d = [0u8; 8];
        for (n, v) in values {
            self.sig(n)?.put(&mut d, *v);
        }
        self.sig("Counter")?.put(&mut d, f64::from(counter & 0x0F));
        d[self.crc_byte] = self.expected_crc(&d);
        Ok(d)
    }
}

/// A DBC (`config/inverter.dbc`, or a car's own bus) parsed with `can-dbc`.
#[derive(Debug, Clone)]
pub struct Dbc {
    /// The messages.
    pub messages: Vec<DbcMessage>,
}

impl Dbc {
    /// Parses the DBC at `path`.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        use can_dbc::{AttributeValue, ByteOrder, MessageId, ValueType};
        let text =
            fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let dbc = can_dbc::Dbc::try_from(text.as_str())
            .map_err(|e| anyhow::anyhow!("{}: DBC parse error: {e:?}", path.display()))?;
        let attr = |name: &str, id: u32| -> anyhow::Result<i64> {
            let a = dbc
                .attribute_values_message
                .iter()
                .find(|a| a.name == name && a.message_id.raw() == id)
                .with_context(|| format!("{}: message {id:#x} lacks {name}", path.display()))?;
            Ok(match &a.value {
                AttributeValue::Uint(u) => *u as i64,
                AttributeValue::Int(i) => *i,
                AttributeValue::Double(d) => *d as i64,
                AttributeValue::String(s) => bail!("{}: {name} is a string {s:?}", path.display()),
            })
        };
        let mut messages = Vec::new();
        for m in &dbc.messages {
            let MessageId::Standard(id) = m.id else {
                bail!("{}: {} is not an 11-bit id", path.display(), m.name);
            };
            let id = u32::from(id);
            let mut signals = Vec::new();
            for s in &m.signals {
                let motorola = s.byte_order == ByteOrder::BigEndian;
                let (start, len) = (u32::try_from(s.start_bit)?, u32::try_from(s.size)?);
                let bits = field_bits(start, len, motorola).with_context(|| {
                    format!(
                        "{}: {}.{}: start bit {start}, {len} bits runs past the 8th byte",
                        path.display(),
                        m.name,
                        s.name
                    )
                })?;
                signals.push(DbcSignal {
                    name: s.name.clone(),
                    dbc_name: s.name.clone(),
                    unit: s.unit.clone(),
                    len,
                    signed: s.value_type == ValueType::Signed,
                    factor: s.factor,
                    offset: s.offset,
                    bits,
                });
            }
            // the CRC: one whole byte, wherever the DBC puts it
            let crc = signals
                .iter()
                .find(|s| s.name == "CRC")
                .with_context(|| format!("{}: {} has no CRC signal", path.display(), m.name))?;
            let crc_byte = (crc.bits[0] / 8) as usize;
            let mut crc_bits = crc.bits.clone();
            crc_bits.sort_unstable();
            let whole: Vec<u32> = (0..8).map(|i| crc_byte as u32 * 8 + i).collect();
            if crc_bits != whole {
                bail!(
                    "{}: {}.CRC does not fill one whole byte",
                    path.display(),
                    m.name
                );
            }
            messages.push(DbcMessage {
                id,
                name: m.name.clone(),
                dbc_name: m.name.clone(),
                crc_byte,
                dlc: u8::try_from(m.size)?,
                data_id: u16::try_from(attr("GripE2eDataId", id)?)?,
                cycle_ms: u32::try_from(attr("GenMsgCycleTime", id)?)?,
                timeout_ms: u32::try_from(attr("GripTimeoutMs", id)?)?,
                signals,
            });
        }
        Ok(Self { messages })
    }

    /// The workspace's `inverter.dbc` (from [`config_dir`]).
    pub fn inverter() -> anyhow::Result<Self> {
        Self::load(&config_dir().join("inverter.dbc"))
    }

    /// The DBC a configuration directory's `can.toml` names (`dbc`;
    /// without it `inverter.dbc`, the built-in protocol's), with its
    /// `[dbc_names]` applied ([`Self::with_names`]): the bus the services
    /// started with `config` speak, read from the files' text.
    pub fn for_config(config: &Path) -> anyhow::Result<Self> {
        let path = config.join("can.toml");
        let text =
            fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        let can: toml::Table = text
            .parse()
            .with_context(|| format!("parsing {}", path.display()))?;
        let file = match can.get("dbc") {
            None => "inverter.dbc",
            Some(v) => v
                .as_str()
                .with_context(|| format!("{}: dbc is not a string", path.display()))?,
        };
        let mut names = std::collections::BTreeMap::new();
        if let Some(t) = can.get("dbc_names") {
            let t = t
                .as_table()
                .with_context(|| format!("{}: dbc_names is not a table", path.display()))?;
            for (k, v) in t {
                let v = v.as_str().with_context(|| {
                    format!("{}: dbc_names.{k} is not a string", path.display())
                })?;
                names.insert(k.clone(), v.to_owned());
            }
        }
        Self::load(&config.join(file))?.with_names(&names)
    }

    /// The DBC with grip's names for the DBC's own: `names` maps grip's
    /// message names (`"TorqueCommand"`) and `"Message.Signal"` keys
    /// (`"TorqueCommand.TorqueRequest"`) to the DBC's names, as `can.toml`'s
    /// `[dbc_names]` does. The DBC's names stay in `dbc_name`.
    pub fn with_names(
        mut self,
        names: &std::collections::BTreeMap<String, String>,
    ) -> anyhow::Result<Self> {
        for (grip, theirs) in names.iter().filter(|(k, _)| !k.contains('.')) {
            let m = self
                .messages
                .iter_mut()
                .find(|m| &m.dbc_name == theirs)
                .with_context(|| format!("name map {grip} = {theirs:?}: no message {theirs}"))?;
            m.name = grip.clone();
        }
        for (key, theirs) in names {
            let Some((msg, sig)) = key.split_once('.') else {
                continue;
            };
            let m = self
                .messages
                .iter_mut()
                .find(|m| m.name == msg)
                .with_context(|| format!("name map {key:?}: no message {msg}"))?;
            let s = m
                .signals
                .iter_mut()
                .find(|s| &s.dbc_name == theirs)
                .with_context(|| {
                    format!("name map {key:?} = {theirs:?}: {msg} has no signal {theirs}")
                })?;
            s.name = sig.to_owned();
        }
        Ok(self)
    }

    /// The message with identifier `id`.
    pub fn by_id(&self, id: u32) -> Option<&DbcMessage> {
        self.messages.iter().find(|m| m.id == id)
    }

    /// The message called `name`.
    pub fn by_name(&self, name: &str) -> anyhow::Result<&DbcMessage> {
        self.messages
            .iter()
            .find(|m| m.name == name)
            .with_context(|| format!("no message {name} in the DBC"))
    }
}

/// A frame seen on the bus by a [`CanCapture`], with its time of arrival
/// (the kernel's stamp mapped onto CLOCK_MONOTONIC, else the reading
/// thread's CLOCK_MONOTONIC).
#[derive(Debug, Clone, Copy)]
pub struct Captured {
    /// Arrival time, ns (CLOCK_MONOTONIC, as the services' stamps).
    pub t_ns: u64,
    /// The frame.
    pub frame: RawFrame,
}

impl Captured {
    /// Standard id (flags removed).
    pub fn id(&self) -> u32 {
        self.frame.can_id & CAN_SFF_MASK
    }

    /// The payload padded to 8 bytes.
    pub fn data8(&self) -> [u8; 8] {
        self.frame.data
    }
}

/// Result of checking a captured stream against the DBC, per message.
#[derive(Debug, Default, Clone)]
pub struct StreamCheck {
    /// Per message name: frames, bad DLC, bad CRC, counter breaks (not +1 mod 16).
    pub per_message: std::collections::BTreeMap<String, [u64; 4]>,
    /// Frames whose id the DBC does not have.
    pub unknown: u64,
    /// First few problems, for messages.
    pub problems: Vec<String>,
}

impl StreamCheck {
    /// Checks every frame of `frames` (in bus order): known id, the DBC's
    /// DLC, a valid E2E CRC, and an alive counter that is the previous
    /// frame's of the same id + 1 mod 16.
    pub fn run(dbc: &Dbc, frames: &[Captured]) -> Self {
        let mut c = StreamCheck::default();
        let mut last: std::collections::BTreeMap<u32, u8> = Default::default();
        for f in frames {
            let Some(m) = dbc.by_id(f.id()) else {
                c.unknown += 1;
                c.note(format!("unknown id {:#x}", f.id()));
                continue;
            };
            let e = c.per_message.entry(m.name.clone()).or_default();
            e[0] += 1;
            let d = f.data8();
            if f.frame.len != m.dlc {
                e[1] += 1;
                c.note(format!("{} with DLC {}", m.name, f.frame.len));
                continue;
            }
            if !m.crc_ok(&d) {
                e[2] += 1;
                c.note(format!(
                    "{} at {} ns: CRC {:#04x} (byte {}), expected {:#04x}",
                    m.name,
                    f.t_ns,
                    m.crc(&d),
                    m.crc_byte,
                    m.expected_crc(&d)
                ));
                continue;
            }
            let ctr = m.counter(&d);
            if let Some(p) = last.insert(m.id, ctr)
                && ctr != (p + 1) & 0x0F
            {
                let e = c.per_message.entry(m.name.clone()).or_default();
                e[3] += 1;
                c.note(format!(
                    "{} at {} ns: counter {ctr} after {p}",
                    m.name, f.t_ns
                ));
            }
        }
        c
    }

    fn note(&mut self, s: String) {
        if self.problems.len() < 20 {
            self.problems.push(s);
        }
    }

    /// True when every frame was known, of the right length, with a valid
    /// CRC and counter.
    pub fn all_valid(&self) -> bool {
        self.unknown == 0
            && self
                .per_message
                .values()
                .all(|v| v[1..].iter().all(|&x| x == 0))
    }
}

impl RawCanSocket {
    /// Raises the receive buffer to `bytes` (`SO_RCVBUFFORCE` as root, else
    /// `SO_RCVBUF` up to `rmem_max`), so a briefly descheduled reader loses nothing.
    pub fn set_rcvbuf(&self, bytes: i32) -> anyhow::Result<()> {
        let set = |opt| {
            // SAFETY: a valid int option value of the given size.
            cvt(unsafe {
                libc::setsockopt(
                    self.fd.as_raw_fd(),
                    libc::SOL_SOCKET,
                    opt,
                    (&raw const bytes).cast(),
                    mem::size_of::<i32>() as libc::socklen_t,
                )
            })
        };
        if set(libc::SO_RCVBUFFORCE).is_err() {
            set(libc::SO_RCVBUF).context("setsockopt(SO_RCVBUF)")?;
        }
        Ok(())
    }

    /// Asks the kernel to report frames dropped for this socket
    /// (`SO_RXQ_OVFL`), read by [`RawCanSocket::recv_counting_drops`].
    pub fn enable_drop_count(&self) -> anyhow::Result<()> {
        let one: i32 = 1;
        // SAFETY: a valid int option value of the given size.
        cvt(unsafe {
            libc::setsockopt(
                self.fd.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_RXQ_OVFL,
                (&raw const one).cast(),
                mem::size_of::<i32>() as libc::socklen_t,
            )
        })
        .context("setsockopt(SO_RXQ_OVFL)")?;
        Ok(())
    }

    /// Asks the kernel to stamp each received frame (`SO_TIMESTAMPNS`,
    /// CLOCK_REALTIME at the frame's arrival on the interface), read by
    /// [`RawCanSocket::recv_counting_drops`].
    pub fn enable_timestamps(&self) -> anyhow::Result<()> {
        let one: i32 = 1;
        // SAFETY: a valid int option value of the given size.
        cvt(unsafe {
            libc::setsockopt(
                self.fd.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_TIMESTAMPNS,
                (&raw const one).cast(),
                mem::size_of::<i32>() as libc::socklen_t,
            )
        })
        .context("setsockopt(SO_TIMESTAMPNS)")?;
        Ok(())
    }

    /// Like [`RawCanSocket::recv_timeout`], also returning the socket's
    /// cumulative drop count (`SO_RXQ_OVFL`) and the kernel's CLOCK_REALTIME
    /// stamp in ns (`SO_TIMESTAMPNS`) when enabled.
    pub fn recv_counting_drops(&self, timeout: Duration) -> anyhow::Result<Option<RecvMeta>> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = libc::c_int::try_from(timeout.as_millis()).unwrap_or(libc::c_int::MAX);
        // SAFETY: pfd is one valid pollfd.
        if cvt(unsafe { libc::poll(&raw mut pfd, 1, ms) }).context("poll")? == 0 {
            return Ok(None);
        }
        let mut frame = RawFrame::default();
        let mut iov = libc::iovec {
            iov_base: (&raw mut frame).cast(),
            iov_len: mem::size_of::<RawFrame>(),
        };
        let mut cbuf = [0u64; 8];
        // SAFETY: all-zero is a valid msghdr; the pointers set below are valid.
        let mut msg: libc::msghdr = unsafe { mem::zeroed() };
        msg.msg_iov = &raw mut iov;
        msg.msg_iovlen = 1;
        msg.msg_control = cbuf.as_mut_ptr().cast();
        msg.msg_controllen = mem::size_of_val(&cbuf);
        // SAFETY: msg describes valid buffers we own.
        let n = unsafe { libc::recvmsg(self.fd.as_raw_fd(), &raw mut msg, 0) };
        if n != mem::size_of::<RawFrame>() as isize {
            let e = io::Error::last_os_error();
            if matches!(e.raw_os_error(), Some(libc::ENETDOWN | libc::ENODEV)) {
                // the interface went down or was deleted (reported once):
                // no frame
                return Ok(None);
            }
            return Err(e).with_context(|| format!("recvmsg(can_frame) returned {n}"));
        }
        let (mut drops, mut stamp) = (None, None);
        // SAFETY: walking the control messages the kernel wrote into cbuf.
        unsafe {
            let mut c = libc::CMSG_FIRSTHDR(&raw const msg);
            while !c.is_null() {
                if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == libc::SO_RXQ_OVFL {
                    drops = Some(std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<u32>()));
                }
                if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == libc::SCM_TIMESTAMPNS {
                    let ts = std::ptr::read_unaligned(libc::CMSG_DATA(c).cast::<libc::timespec>());
                    stamp = Some(ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64);
                }
                c = libc::CMSG_NXTHDR(&raw const msg, c);
            }
        }
        Ok(Some(RecvMeta {
            frame,
            drops,
            stamp,
        }))
    }
}

/// A frame with what the kernel said about it.
#[derive(Debug, Clone, Copy)]
pub struct RecvMeta {
    /// The frame.
    pub frame: RawFrame,
    /// The socket's cumulative drop count (`SO_RXQ_OVFL`), when enabled.
    pub drops: Option<u32>,
    /// Kernel receive time, CLOCK_REALTIME ns (`SO_TIMESTAMPNS`), when enabled.
    pub stamp: Option<u64>,
}

/// Everything a [`CanCapture`] saw.
#[derive(Debug, Default, Clone)]
pub struct CaptureLog {
    /// Frames in bus order.
    pub frames: Vec<Captured>,
    /// Frames the kernel dropped for the capturing socket (`SO_RXQ_OVFL`).
    pub dropped: u32,
}

impl CaptureLog {
    /// Frames with standard id `id`.
    pub fn with_id(&self, id: u32) -> impl Iterator<Item = &Captured> {
        self.frames.iter().filter(move |f| f.id() == id)
    }
}

/// CLOCK_REALTIME now, ns.
fn realtime_ns() -> u64 {
    // SAFETY: as in mono_ns.
    let mut ts: libc::timespec = unsafe { mem::zeroed() };
    // SAFETY: ts is a valid timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_REALTIME, &raw mut ts) };
    (ts.tv_sec as u64) * 1_000_000_000 + ts.tv_nsec as u64
}

/// A thread that records every frame on a CAN interface through its own raw
/// socket (independent of the services and of grip-io), like `candump`, with
/// the kernel's receive time stamp of each frame (mapped to CLOCK_MONOTONIC)
/// and the kernel's count of frames dropped for the socket.
#[derive(Debug)]
pub struct CanCapture {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    handle: thread::JoinHandle<anyhow::Result<CaptureLog>>,
}

impl CanCapture {
    /// Opens the socket (4 MiB receive buffer, drop counting) and starts recording.
    pub fn start(iface: &str) -> anyhow::Result<Self> {
        Self::start_filtered(iface, &[])
    }

    /// [`Self::start`] recording only the frames that pass `filters`
    /// ((id, mask) pairs as [`RawCanSocket::set_filters`]; empty: all), e.g.
    /// all but a flood's id (`CAN_INV_FILTER`).
    pub fn start_filtered(iface: &str, filters: &[(u32, u32)]) -> anyhow::Result<Self> {
        require_can_iface(iface)?;
        let sock = RawCanSocket::open(iface)?;
        if !filters.is_empty() {
            sock.set_filters(filters)?;
        }
        sock.set_rcvbuf(4 << 20)?;
        sock.enable_drop_count()?;
        sock.enable_timestamps()?;
        // kernel stamps are CLOCK_REALTIME: map them onto CLOCK_MONOTONIC
        // with the offset now (nothing steps the clock during a test)
        let offset = realtime_ns().wrapping_sub(mono_ns());
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stop2 = std::sync::Arc::clone(&stop);
        let handle = thread::Builder::new()
            .name("can-capture".into())
            .spawn(move || {
                let mut log = CaptureLog::default();
                while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
                    while let Some(RecvMeta {
                        frame,
                        drops,
                        stamp,
                    }) = sock.recv_counting_drops(Duration::from_millis(20))?
                    {
                        let t_ns = stamp.map_or_else(mono_ns, |s| s.wrapping_sub(offset));
                        log.frames.push(Captured { t_ns, frame });
                        if let Some(d) = drops {
                            log.dropped = d;
                        }
                    }
                }
                Ok(log)
            })?;
        Ok(Self { stop, handle })
    }

    /// Stops recording and returns what was seen.
    pub fn finish(self) -> anyhow::Result<CaptureLog> {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("the CAN capture thread panicked"))?
    }
}

/// A thread that counts the frames matching a set of receive filters
/// through its own raw socket, with the kernel's count of frames it dropped
/// for that socket (`SO_RXQ_OVFL`): `received + dropped` is every matching
/// frame on the bus, however fast they came.
#[derive(Debug)]
pub struct FrameCounter {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    handle: thread::JoinHandle<anyhow::Result<FrameCount>>,
}

/// What a [`FrameCounter`] counted.
#[derive(Debug, Default, Clone, Copy)]
pub struct FrameCount {
    /// Frames read.
    pub received: u64,
    /// Frames the kernel dropped for the counting socket.
    pub dropped: u64,
    /// CLOCK_MONOTONIC time of the first and the last frame read, ns.
    pub first_ns: Option<u64>,
    /// See `first_ns`.
    pub last_ns: Option<u64>,
}

impl FrameCount {
    /// Every matching frame on the bus: read + dropped.
    pub fn total(&self) -> u64 {
        self.received + self.dropped
    }
}

impl FrameCounter {
    /// Starts counting the frames that pass `filters` ((id, mask) pairs, as
    /// [`RawCanSocket::set_filters`]).
    pub fn start(iface: &str, filters: &[(u32, u32)]) -> anyhow::Result<Self> {
        let sock = RawCanSocket::open(iface)?;
        sock.set_filters(filters)?;
        sock.set_rcvbuf(4 << 20)?;
        sock.enable_drop_count()?;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stop2 = std::sync::Arc::clone(&stop);
        let handle = thread::Builder::new()
            .name("can-count".into())
            .spawn(move || {
                let mut c = FrameCount::default();
                while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
                    while let Some(m) = sock.recv_counting_drops(Duration::from_millis(20))? {
                        let now = mono_ns();
                        c.received += 1;
                        c.first_ns.get_or_insert(now);
                        c.last_ns = Some(now);
                        if let Some(d) = m.drops {
                            c.dropped = u64::from(d);
                        }
                    }
                }
                Ok(c)
            })?;
        Ok(Self { stop, handle })
    }

    /// Stops counting and returns the count.
    pub fn finish(self) -> anyhow::Result<FrameCount> {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("the CAN frame counter thread panicked"))?
    }
}

/// Waits for a frame with id `id` whose payload satisfies `pred` on `sock`;
/// returns it with its receive time, or an error after `timeout`.
pub fn wait_for_frame(
    sock: &RawCanSocket,
    id: u32,
    timeout: Duration,
    mut pred: impl FnMut(&[u8; 8]) -> bool,
) -> anyhow::Result<Captured> {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if let Some(frame) = sock.recv_timeout(Duration::from_millis(50))?
            && frame.can_id & CAN_SFF_MASK == id
            && pred(&frame.data)
        {
            return Ok(Captured {
                t_ns: mono_ns(),
                frame,
            });
        }
    }
    bail!("no matching frame {id:#x} within {timeout:?}")
}

// --- configuration for HIL drives ----------------------------------------------

/// What a HIL drive changes in the shipped configuration.
#[derive(Debug, Clone)]
pub struct HilConfig {
    /// CAN interface (`can.toml` `interface`), with `transport = "socketcan"`
    /// (no silent fallback to the simulated bus).
    pub iface: String,
    /// ALSA capture PCM of audio-acq (`audio-acq.toml`, `source = "alsa"`).
    pub capture_device: String,
}

/// Replaces the line of `file` that starts with `key =` inside `[section]`
/// (`""` = top level) by `key = value`; an error when there is none.
pub fn set_toml_line(
    text: &str,
    file: &str,
    section: &str,
    key: &str,
    value: &str,
) -> anyhow::Result<String> {
    let mut cur = String::new();
    let mut done = false;
    let mut out = String::new();
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            cur = t.trim_matches(|c| c == '[' || c == ']').to_owned();
        }
        let is_key = t
            .split_once('=')
            .is_some_and(|(k, _)| k.trim() == key && !t.starts_with('#'));
        if !done && cur == section && is_key {
            out.push_str(&format!(
                "{key} = {value}  # set by grip_tests::hil (HIL drive)\n"
            ));
            done = true;
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    if !done {
        bail!("{file}: no `{key} =` in [{section}] to set for the HIL drive");
    }
    Ok(out)
}

/// A configuration folder for a HIL drive in `dir`: every entry of the
/// shipped [`config_dir`] symlinked, except `can.toml` (SocketCAN only, on
/// `cfg.iface`) and `audio-acq.toml` (the ALSA source on
/// `cfg.capture_device`), which are written modified. That is how a car is
/// configured too (its `/etc/grip`), and the recorder attaches both files
/// to the MCAP.
pub fn hil_config_dir(dir: &Path, cfg: &HilConfig) -> anyhow::Result<PathBuf> {
    let src = config_dir();
    let _ = fs::remove_dir_all(dir);
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for e in fs::read_dir(&src).with_context(|| format!("reading {}", src.display()))? {
        let e = e?;
        let name = e.file_name();
        if name == "can.toml" || name == "audio-acq.toml" {
            continue;
        }
        std::os::unix::fs::symlink(e.path(), dir.join(&name))
            .with_context(|| format!("symlinking {}", e.path().display()))?;
    }
    let can_path = src.join("can.toml");
    let can =
        fs::read_to_string(&can_path).with_context(|| format!("reading {}", can_path.display()))?;
    let f = can_path.display().to_string();
    let can = set_toml_line(&can, &f, "", "transport", "\"socketcan\"")?;
    let can = set_toml_line(&can, &f, "", "interface", &format!("{:?}", cfg.iface))?;
    fs::write(dir.join("can.toml"), can)?;
    let acq_path = src.join("audio-acq.toml");
    let acq =
        fs::read_to_string(&acq_path).with_context(|| format!("reading {}", acq_path.display()))?;
    let f = acq_path.display().to_string();
    let acq = set_toml_line(&acq, &f, "audio", "source", "\"alsa\"")?;
    let acq = set_toml_line(
        &acq,
        &f,
        "alsa",
        "device",
        &format!("{:?}", cfg.capture_device),
    )?;
    fs::write(dir.join("audio-acq.toml"), acq)?;
    Ok(dir.to_path_buf())
}

/// Makes the configuration folder `dir` (from [`hil_config_dir`]) speak a
/// car's own bus: the DBC at `dbc` copied in (a file, not a link, so the
/// recorder attaches it), `can.toml` set to `dbc = "<its file name>"` and
/// `names_toml` (a `[dbc_names]` table, or `""`) appended. Returns the
/// DBC's file name.
pub fn set_bus_dbc(dir: &Path, dbc: &Path, names_toml: &str) -> anyhow::Result<String> {
    let name = dbc
        .file_name()
        .and_then(|n| n.to_str())
        .with_context(|| format!("{}: no file name", dbc.display()))?
        .to_owned();
    let target = dir.join(&name);
    let _ = fs::remove_file(&target);
    fs::copy(dbc, &target)
        .with_context(|| format!("copying {} to {}", dbc.display(), target.display()))?;
    let can_path = dir.join("can.toml");
    let can =
        fs::read_to_string(&can_path).with_context(|| format!("reading {}", can_path.display()))?;
    // `dbc` first (the top level, before any table), the map last
    let mut out = format!("dbc = {name:?}  # set by grip_tests::hil (own bus)\n");
    let mut section = String::new();
    for line in can.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            section = t.to_owned();
        }
        let is_dbc = t.split_once('=').is_some_and(|(k, _)| k.trim() == "dbc");
        if section.is_empty() && is_dbc {
            continue;
        }
        anyhow::ensure!(
            names_toml.is_empty() || !t.starts_with("[dbc_names]"),
            "{}: has a [dbc_names] table already",
            can_path.display()
        );
        out.push_str(line);
        out.push('\n');
    }
    out.push('\n');
    out.push_str(names_toml);
    let parsed: toml::Table = out
        .parse()
        .with_context(|| format!("the modified can.toml does not parse:\n{out}"))?;
    anyhow::ensure!(
        parsed.get("dbc").and_then(toml::Value::as_str) == Some(name.as_str()),
        "the modified can.toml does not name {name}:\n{out}"
    );
    fs::write(&can_path, out)?;
    Ok(name)
}

// --- the road-audio player --------------------------------------------------------

/// What the [`RoadAudioPlayer`] did.
#[derive(Debug, Default, Clone)]
pub struct PlayerReport {
    /// Blocks written to the playback PCM.
    pub blocks: u64,
    /// Playback underruns (recovered).
    pub xruns: u64,
    /// When the scenario started (first DriverDemand with demand > 0), ns.
    pub started_ns: Option<u64>,
    /// (time ns, synthesiser road name) at every change of the played road.
    pub roads: Vec<(u64, String)>,
    /// Highest vehicle speed the player followed, m/s.
    pub max_speed: f64,
    /// Blocks played with a [`MicFault`] applied.
    pub fault_blocks: u64,
}

/// What a faulty microphone does to the road sound, for a while
/// ([`RoadAudioPlayer::start_with_faults`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MicFaultKind {
    /// Digital silence (a cut cable, a muted preamplifier).
    Silence,
    /// The sound amplified by `gain` and clipped at full scale (an
    /// overdriven input).
    Clip {
        /// Amplification before the clipping.
        gain: f64,
    },
}

/// A [`MicFaultKind`] from `from_s` for `len_s` seconds of scenario time
/// (the clock that starts with the first `DriverDemand` carrying a demand).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MicFault {
    /// What happens.
    pub kind: MicFaultKind,
    /// Start, s after the scenario start.
    pub from_s: f64,
    /// Duration, s.
    pub len_s: f64,
}

/// Plays the scenario's synthetic tyre-road sound into an ALSA playback PCM
/// (the loopback's `hw:Loopback,0,0`) in real time, following the drive
/// from outside, off the bus (the frames decoded per the DBC `config`'s
/// `can.toml` names, [`Dbc::for_config`]): the road comes from the scenario's road
/// timeline, whose clock starts with the first `DriverDemand` carrying a
/// demand (plant-sim sends 0 until its scenario runs); `VehicleSpeed`
/// frames give the distance for distance-based timelines. Before the start
/// it plays the first road, as the plant holds the car rolling there.
///
/// The sound of each segment's road is pre-rendered with
/// `grip_arte::synth::RoadAudioSynth` (seed 1, clean) at [`PLAYER_SPEED`]
/// as a 2 s loop: under emulation a live synthesiser beside five services
/// could not keep up with 44.1 kHz (it underran in half its blocks). Mono
/// S16 at 44.1 kHz, written in 1024-frame blocks into an 8192-frame buffer
/// by a SCHED_FIFO (55) thread where permitted; the playback blocks pace
/// it, so the sound lags the plant by at most about 186 ms.
#[derive(Debug)]
pub struct RoadAudioPlayer {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    handle: thread::JoinHandle<anyhow::Result<PlayerReport>>,
}

/// Sample rate of the player (= audio-acq's and the ARTE model's).
pub const PLAYER_RATE: u32 = 44_100;
/// Length of the pre-rendered loop per road, s.
const PLAYER_LOOP_S: usize = 2;
/// The speed the road sound is rendered at, m/s: about the middle of a HIL
/// drive (10 km/h rising to 20-30 km/h).
pub const PLAYER_SPEED: f64 = 5.0;
const PLAYER_BLOCK: usize = 1024;

impl RoadAudioPlayer {
    /// Opens `device` for playback and starts the player thread for
    /// `scenario` (a name under `config` or a path); `iface` is the bus.
    pub fn start(device: &str, iface: &str, config: &Path, scenario: &str) -> anyhow::Result<Self> {
        Self::start_with_faults(device, iface, config, scenario, &[])
    }

    /// [`Self::start`], with `faults` applied to the blocks written while
    /// the scenario clock is in their windows (the sound reaches the
    /// capture up to a buffer, about 186 ms, later).
    pub fn start_with_faults(
        device: &str,
        iface: &str,
        config: &Path,
        scenario: &str,
        faults: &[MicFault],
    ) -> anyhow::Result<Self> {
        use alsa::pcm::{Access, Format, HwParams, PCM};
        let faults = faults.to_vec();
        use alsa::{Direction, ValueOr};
        let cdir = grip_config::ConfigDir::new(config);
        let roads = cdir.roads()?;
        let scn = cdir.scenario_with(scenario, &roads)?;
        // the same road-name aliases audio-acq's synth source uses (its
        // rule: grip_arte::synth::SynthAliases::resolve)
        let acq_file = config.join("audio-acq.toml");
        let acq_text = fs::read_to_string(&acq_file)?;
        let aliases = toml::from_str::<grip_arte::synth::AudioAcqAliases>(&acq_text)
            .context("audio-acq.toml")?
            .aliases()
            .resolve(&acq_file)?
            .sounds;
        let alias = |name: &str| -> usize {
            grip_arte::synth::road_index(name)
                .or_else(|| grip_arte::synth::road_index(aliases.get(name)?))
                .unwrap_or(usize::MAX)
        };
        let seg_roads: Vec<(usize, String)> = scn
            .segments
            .iter()
            .map(|s| (alias(&s.road_name), s.road_name.clone()))
            .collect();
        let dbc = Dbc::for_config(config)?;
        let vs = dbc.by_name("VehicleSpeed")?.clone();
        let dd = dbc.by_name("DriverDemand")?.clone();
        let sock = RawCanSocket::open(iface)?;
        let std_mask = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
        sock.set_filters(&[(vs.id, std_mask), (dd.id, std_mask)])?;
        sock.set_rcvbuf(1 << 20)?;
        let mut synth = grip_arte::synth::RoadAudioSynth::new(
            &grip_arte::synth::SynthConfig {
                sample_rate: PLAYER_RATE,
                noise: None,
            },
            1,
        )
        .map_err(|e| anyhow::anyhow!("road audio synthesiser: {e}"))?;
        // pre-rendered: under emulation a live synthesiser beside five
        // services cannot keep up with 44.1 kHz; copying samples can
        let mut fbuf = vec![0f32; PLAYER_LOOP_S * PLAYER_RATE as usize];
        let loops: Vec<Vec<i16>> = seg_roads
            .iter()
            .map(|&(road, _)| {
                synth.fill(road, PLAYER_SPEED, &mut fbuf);
                fbuf.iter()
                    .map(|v| (v.clamp(-1.0, 1.0) * f32::from(i16::MAX)).round() as i16)
                    .collect()
            })
            .collect();
        let cname = CString::new(device)?;
        let pcm = PCM::open(&cname, Direction::Playback, false)
            .with_context(|| format!("opening {device} for playback"))?;
        {
            let hwp = HwParams::any(&pcm)?;
            hwp.set_access(Access::RWInterleaved)?;
            hwp.set_format(Format::s16())?;
            hwp.set_channels(1)?;
            hwp.set_rate(PLAYER_RATE, ValueOr::Nearest)?;
            hwp.set_period_size_near(PLAYER_BLOCK as alsa::pcm::Frames, ValueOr::Nearest)?;
            hwp.set_buffer_size_near(8 * PLAYER_BLOCK as alsa::pcm::Frames)?;
            pcm.hw_params(&hwp)
                .with_context(|| format!("{device}: hardware parameters"))?;
            let rate = hwp.get_rate()?;
            if rate != PLAYER_RATE {
                bail!("{device} plays at {rate} Hz, not {PLAYER_RATE}");
            }
        }
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stop2 = std::sync::Arc::clone(&stop);
        let v0 = scn.v0;
        let handle = thread::Builder::new()
            .name("road-audio".into())
            .spawn(move || {
                let mut rep = PlayerReport::default();
                // a microphone does not starve: play at SCHED_FIFO 55 where
                // permitted (root in the VM; between audio-acq's 60 and arte's 50)
                let prio = libc::sched_param { sched_priority: 55 };
                // SAFETY: sets this thread's own policy; prio is a valid sched_param.
                let _ = unsafe {
                    libc::pthread_setschedparam(
                        libc::pthread_self(),
                        libc::SCHED_FIFO,
                        &raw const prio,
                    )
                };
                let io = pcm.io_i16()?;
                let mut ibuf = vec![0i16; PLAYER_BLOCK];
                let mut pos = 0usize;
                let (mut speed, mut x, mut last_ns) = (v0, 0.0f64, mono_ns());
                let mut cur_road = usize::MAX - 1;
                while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
                    while let Some(f) = sock.recv_timeout(Duration::ZERO)? {
                        let id = f.can_id & CAN_SFF_MASK;
                        if id == vs.id && f.len == vs.dlc && vs.crc_ok(&f.data) {
                            speed = vs.si("Speed", &f.data);
                        } else if id == dd.id
                            && f.len == dd.dlc
                            && dd.crc_ok(&f.data)
                            && rep.started_ns.is_none()
                            && dd.value("TorqueDemand", &f.data).abs() > 0.05
                        {
                            rep.started_ns = Some(mono_ns());
                        }
                    }
                    let now = mono_ns();
                    let (t, seg) = match rep.started_ns {
                        Some(t0) => {
                            x += speed.max(0.0) * (now - last_ns) as f64 * 1e-9;
                            let t = (now - t0) as f64 * 1e-9;
                            (t, scn.segment_at(t, x))
                        }
                        None => (0.0, 0),
                    };
                    let fault = rep
                        .started_ns
                        .and_then(|_| {
                            faults
                                .iter()
                                .find(|f| t >= f.from_s && t < f.from_s + f.len_s)
                        })
                        .map(|f| f.kind);
                    last_ns = now;
                    let (road, ref name) = seg_roads[seg];
                    if road != cur_road {
                        cur_road = road;
                        rep.roads.push((now, name.clone()));
                    }
                    rep.max_speed = rep.max_speed.max(speed);
                    let lp = &loops[seg];
                    for o in &mut ibuf {
                        *o = lp[pos % lp.len()];
                        pos += 1;
                    }
                    match fault {
                        Some(MicFaultKind::Silence) => ibuf.fill(0),
                        Some(MicFaultKind::Clip { gain }) => {
                            for o in &mut ibuf {
                                *o = (f64::from(*o) * gain)
                                    .clamp(f64::from(i16::MIN), f64::from(i16::MAX))
                                    as i16;
                            }
                        }
                        None => {}
                    }
                    rep.fault_blocks += u64::from(fault.is_some());
                    let mut off = 0;
                    while off < ibuf.len() {
                        match io.writei(&ibuf[off..]) {
                            Ok(n) => off += n,
                            Err(e) => {
                                rep.xruns += 1;
                                pcm.try_recover(e, true).context("playback recover")?;
                            }
                        }
                    }
                    rep.blocks += 1;
                }
                let _ = pcm.drop();
                Ok(rep)
            })?;
        Ok(Self { stop, handle })
    }

    /// Stops the player and returns its report.
    pub fn finish(self) -> anyhow::Result<PlayerReport> {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("the road-audio player thread panicked"))?
    }
}

// --- services as the drive starts them ----------------------------------------

/// The five services of a drive, in start order, with `grip drive`'s
/// command lines ([`grip_drive::DrivePlan::args`] with its defaults:
/// controller, ARTE on, seed) for `scenario` in `config`, logging to `out`,
/// in iceoryx2 instance `instance`; each service's stdout and stderr go to
/// `<log_dir>/<service>.log`.
pub fn drive_specs(
    config: &Path,
    scenario: &str,
    out: &Path,
    instance: &str,
    log_dir: &Path,
) -> anyhow::Result<Vec<grip_drive::ProcSpec>> {
    let dir = grip_config::ConfigDir::new(config);
    let roads = dir.roads()?;
    let scn = dir.scenario_with(scenario, &roads)?;
    let plan = grip_drive::DrivePlan::new(config, scenario, scn.duration, out, instance);
    let bin = grip_io::binaries::bin_dir()?.path;
    Ok(grip_drive::Service::START_ORDER
        .iter()
        .map(|s| {
            s.spec(&bin, &plan.args(*s))
                .output(grip_drive::Output::File(
                    log_dir.join(format!("{}.log", s.name())),
                ))
        })
        .collect())
}

/// Starts `specs` in order under grip-drive's supervisor, each awaited for
/// `READY=1` (up to `ready` each), left to the test to signal, kill and
/// stop one by one; dropping the supervisor kills what still runs.
pub fn start_services(
    specs: &[grip_drive::ProcSpec],
    instance: &str,
    ready: Duration,
) -> anyhow::Result<grip_drive::Supervisor> {
    let mut sup = grip_drive::Supervisor::new(instance)?;
    for s in specs {
        sup.start(s, ready)?;
    }
    Ok(sup)
}

/// The pid of a child of `parent` whose command name is `comm`, if one runs.
pub fn child_pid(parent: u32, comm: &str) -> Option<u32> {
    for e in fs::read_dir("/proc").ok()?.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        // "pid (comm) state ppid ..."; comm may contain spaces, so split at the last ')'
        let (Some(l), Some(r)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = &stat[l + 1..r];
        let ppid = stat[r + 1..]
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse::<u32>().ok());
        if name == comm && ppid == Some(parent) {
            return Some(pid);
        }
    }
    None
}

/// Sends `sig` to process `pid`.
pub fn kill_pid(pid: u32, sig: libc::c_int) -> anyhow::Result<()> {
    let p = libc::pid_t::try_from(pid).context("pid out of range")?;
    // SAFETY: kill(2) on a pid the caller found among its own children.
    cvt(unsafe { libc::kill(p, sig) }).with_context(|| format!("kill({pid}, {sig})"))?;
    Ok(())
}

/// `CAN_INV_FILTER`: set on a filter's id, the filter passes the frames
/// that do *not* match (linux/can.h).
pub const CAN_INV_FILTER: u32 = 0x2000_0000;

/// Deletes the vcan interface `iface` (`ip link del`, as unplugging a
/// USB-CAN adapter does to its interface); with `busybox ip` where there is
/// no `ip` (the HIL VM). Needs root.
pub fn delete_vcan(iface: &str) -> anyhow::Result<()> {
    ip(&["link", "del", "dev", iface])
}

/// Creates the vcan interface `iface` and sets it up (`ip link add dev
/// IFACE type vcan; ip link set up IFACE`). Needs root.
pub fn create_vcan(iface: &str) -> anyhow::Result<()> {
    ip(&["link", "add", "dev", iface, "type", "vcan"])?;
    set_link_up(iface, true)
}

/// Puts a vcan interface back: [`RestoreVcan::restore`] re-creates it
/// (and sets it up) if it is missing, and dropping the guard does the same,
/// so a test that deletes `vcan0` leaves it for the tests after it in the
/// same VM whatever happens (an error, a panic).
#[derive(Debug)]
pub struct RestoreVcan {
    iface: String,
}

impl RestoreVcan {
    /// A guard for `iface` (take it before deleting the interface).
    pub fn new(iface: &str) -> Self {
        Self {
            iface: iface.to_owned(),
        }
    }

    /// Re-creates the interface if it is missing, and checks that it is up.
    pub fn restore(&self) -> anyhow::Result<()> {
        if !Path::new("/sys/class/net").join(&self.iface).exists() {
            create_vcan(&self.iface)?;
        }
        require_can_iface(&self.iface)
    }
}

impl Drop for RestoreVcan {
    fn drop(&mut self) {
        if let Err(e) = self.restore() {
            eprintln!("could not re-create {}: {e:#}", self.iface);
        }
    }
}

/// Runs `ip ARGS` (or `busybox ip ARGS`), failing with its output.
fn ip(args: &[&str]) -> anyhow::Result<()> {
    let out = match Command::new("ip").args(args).output() {
        Err(e) if e.kind() == io::ErrorKind::NotFound => Command::new("busybox")
            .arg("ip")
            .args(args)
            .output()
            .context("neither ip nor busybox found")?,
        r => r.context("running ip")?,
    };
    anyhow::ensure!(
        out.status.success(),
        "ip {}: {} {}",
        args.join(" "),
        out.status,
        String::from_utf8_lossy(&out.stderr).trim()
    );
    Ok(())
}

/// Sets network interface `iface` up or down (`SIOCSIFFLAGS`, as `ip link
/// set IFACE up|down`; needs root, which the HIL VM has).
pub fn set_link_up(iface: &str, up: bool) -> anyhow::Result<()> {
    // SAFETY: a plain datagram socket, closed by OwnedFd.
    let fd = cvt(unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM, 0) })
        .context("socket(AF_INET)")?;
    // SAFETY: fd is a new, valid descriptor we own.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    // SAFETY: all-zero is a valid ifreq.
    let mut req: libc::ifreq = unsafe { mem::zeroed() };
    anyhow::ensure!(
        iface.len() < libc::IFNAMSIZ,
        "interface name {iface} too long"
    );
    for (d, s) in req.ifr_name.iter_mut().zip(iface.bytes()) {
        *d = s as libc::c_char;
    }
    // SAFETY: SIOCGIFFLAGS fills ifr_ifru.ifru_flags of a valid ifreq.
    cvt(unsafe { libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFFLAGS, &raw mut req) })
        .with_context(|| format!("SIOCGIFFLAGS {iface}"))?;
    // SAFETY: the kernel wrote the flags member.
    let mut flags = unsafe { req.ifr_ifru.ifru_flags };
    let up_flag = libc::IFF_UP as libc::c_short;
    flags = if up {
        flags | up_flag
    } else {
        flags & !up_flag
    };
    req.ifr_ifru.ifru_flags = flags;
    // SAFETY: SIOCSIFFLAGS reads the valid ifreq.
    cvt(unsafe { libc::ioctl(fd.as_raw_fd(), libc::SIOCSIFFLAGS, &raw const req) })
        .with_context(|| format!("SIOCSIFFLAGS {iface} {}", if up { "up" } else { "down" }))?;
    Ok(())
}

/// Mounts a tmpfs of `bytes` at `dir` (created if missing; needs root,
/// which the HIL VM has): a small disk that a test can fill.
pub fn mount_tmpfs(dir: &Path, bytes: u64) -> anyhow::Result<()> {
    fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let target = CString::new(dir.as_os_str().as_encoded_bytes())?;
    let opts = CString::new(format!("size={bytes}"))?;
    // SAFETY: valid NUL-terminated strings for mount(2).
    cvt(unsafe {
        libc::mount(
            c"tmpfs".as_ptr(),
            target.as_ptr(),
            c"tmpfs".as_ptr(),
            0,
            opts.as_ptr().cast(),
        )
    })
    .with_context(|| {
        format!(
            "mounting a {bytes}-byte tmpfs on {} (needs root)",
            dir.display()
        )
    })?;
    Ok(())
}

/// Unmounts `dir` (lazily: files still open stay readable to their holders).
pub fn unmount(dir: &Path) -> anyhow::Result<()> {
    let target = CString::new(dir.as_os_str().as_encoded_bytes())?;
    // SAFETY: a valid NUL-terminated path.
    cvt(unsafe { libc::umount2(target.as_ptr(), libc::MNT_DETACH) })
        .with_context(|| format!("unmounting {}", dir.display()))?;
    Ok(())
}

/// Bytes free for an unprivileged writer on the file system holding `dir`.
pub fn free_bytes(dir: &Path) -> anyhow::Result<u64> {
    let p = CString::new(dir.as_os_str().as_encoded_bytes())?;
    // SAFETY: all-zero is a valid statvfs; p is NUL-terminated.
    let mut st: libc::statvfs = unsafe { mem::zeroed() };
    // SAFETY: as above.
    cvt(unsafe { libc::statvfs(p.as_ptr(), &raw mut st) })
        .with_context(|| format!("statvfs {}", dir.display()))?;
    Ok(st.f_bavail * st.f_frsize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn sine_has_its_frequency_and_level() {
        let x = sine_i16(1000.0, 48_000, 0.5, 48_000);
        let f = zero_crossing_frequency(&x, 48_000).unwrap();
        assert!((f - 1000.0).abs() < 0.01, "{f}");
        let r = rms(&x);
        assert!((r - 0.5 / 2f64.sqrt()).abs() < 1e-4, "{r}");
    }

    #[test]
    fn silence_has_no_frequency() {
        assert_eq!(zero_crossing_frequency(&[0; 1000], 48_000), None);
        assert_eq!(rms(&[]), 0.0);
    }

    #[test]
    fn raw_frame_layout_matches_the_kernel() {
        assert_eq!(mem::size_of::<RawFrame>(), 16);
        assert_eq!(
            mem::size_of::<RawFrame>(),
            mem::size_of::<libc::can_frame>()
        );
        assert!(RawFrame::new(0x123, &[0; 9]).is_err());
        let f = RawFrame::new(0x123, &[1, 2, 3]).unwrap();
        assert_eq!(f.payload(), &[1, 2, 3]);
    }

    fn own_bus() -> Dbc {
        Dbc::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/own-bus.dbc")).unwrap()
    }

    #[test]
    fn motorola_fields_are_walked_as_the_dbc_numbers_their_bits() {
        let d = own_bus();
        let m = d.by_name("MotorStatus").unwrap();
        // CRC 7|8@0: byte 0; Counter 11|4@0: the low nibble of byte 1;
        // CmdTimeout 15|1@0: bit 7 of byte 1; TorqueActual 23|16@0: bytes
        // 2 (high) and 3 (low); MotorSpeed 39|16@0: bytes 4 and 5
        assert_eq!(m.crc_byte, 0);
        let data = [0xAB, 0x8A, 0xFF, 0x9C, 0x01, 0x2C, 0x00, 0x00];
        assert_eq!(m.counter(&data), 0x0A);
        assert_eq!(m.value("CmdTimeout", &data), 1.0);
        assert_eq!(m.value("Ready", &data), 0.0);
        assert_eq!(m.sig("TorqueActual").unwrap().raw(&data), -100);
        assert!((m.value("TorqueActual", &data) + 10.0).abs() < 1e-9);
        assert_eq!(m.value("MotorSpeed", &data), 300.0);
        let si = m.si("MotorSpeed", &data);
        assert!(
            (si - 300.0 * std::f64::consts::PI / 30.0).abs() < 1e-9,
            "{si}"
        );
        // and written back the same way
        let mut w = [0u8; 8];
        m.sig("MotorSpeed").unwrap().put(&mut w, -2.0);
        assert_eq!(w, [0, 0, 0, 0, 0xFF, 0xFE, 0, 0]);
        m.sig("Counter").unwrap().put(&mut w, 5.0);
        assert_eq!(w[1], 0x05);
        // a Motorola field that runs past byte 7 is refused
        assert!(field_bits(63, 16, true).is_none());
        assert!(field_bits(56, 9, false).is_none());
        assert_eq!(
            field_bits(7, 8, true).unwrap(),
            (0..8).rev().collect::<Vec<_>>()
        );
        assert_eq!(
            field_bits(3, 8, true).unwrap(),
            vec![3, 2, 1, 0, 15, 14, 13, 12]
        );
    }

    #[test]
    fn the_crc_is_checked_in_whichever_byte_the_dbc_puts_it() {
        let d = own_bus();
        let ws = d.by_name("WheelSpeeds").unwrap();
        assert_eq!(ws.crc_byte, 7);
        let f = ws
            .encode(&[("OmegaDriven", 12.34), ("DrivenValid", 1.0)], 9)
            .unwrap();
        assert_eq!(f[0] & 0x0F, 9, "Counter in bits 0-3");
        assert_eq!(ws.counter(&f), 9);
        assert_eq!(f[7], e2e_crc8(ws.data_id, &f[..7]));
        assert!(ws.crc_ok(&f));
        assert!((ws.value("OmegaDriven", &f) - 12.34).abs() < 1e-9);
        for i in 0..8 {
            let mut bad = f;
            bad[i] ^= 0x10;
            assert!(!ws.crc_ok(&bad), "byte {i} changed, CRC still good");
        }
        let inv = Dbc::inverter().unwrap();
        assert!(inv.messages.iter().all(|m| m.crc_byte == 0));
        let dd = inv.by_name("DriverDemand").unwrap();
        let f = dd.encode(&[("TorqueDemand", 300.0)], 3).unwrap();
        assert_eq!(f[0], e2e_crc8(dd.data_id, &f[1..]));
    }

    #[test]
    fn a_name_map_gives_the_dbc_grips_names() {
        let names: std::collections::BTreeMap<String, String> = [
            ("TorqueCommand", "MCU_TrqCmd"),
            ("TorqueCommand.TorqueRequest", "TrqReq"),
            ("DriverDemand", "VCU_Demand"),
            ("DriverDemand.TorqueDemand", "TrqDmd"),
        ]
        .into_iter()
        .map(|(a, b)| (a.to_owned(), b.to_owned()))
        .collect();
        let d = own_bus().with_names(&names).unwrap();
        let tc = d.by_name("TorqueCommand").unwrap();
        assert_eq!((tc.id, tc.dbc_name.as_str()), (0x191, "MCU_TrqCmd"));
        assert_eq!(tc.sig("TorqueRequest").unwrap().dbc_name, "TrqReq");
        assert_eq!(d.by_name("DriverDemand").unwrap().id, 0x195);
        assert!(d.by_name("MCU_TrqCmd").is_err());
        let mut wrong = names.clone();
        wrong.insert("MotorStatus".into(), "Nope".into());
        let e = format!("{:#}", own_bus().with_names(&wrong).unwrap_err());
        assert!(e.contains("Nope"), "{e}");
        // the same from a configuration folder's can.toml
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("can.toml"), "interface = \"vcan0\"\n").unwrap();
        let n = set_bus_dbc(
            dir.path(),
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("data/own-bus.dbc"),
            "[dbc_names]\nTorqueCommand = \"MCU_TrqCmd\"\n",
        )
        .unwrap();
        assert_eq!(n, "own-bus.dbc");
        let d = Dbc::for_config(dir.path()).unwrap();
        assert_eq!(d.by_name("TorqueCommand").unwrap().id, 0x191);
        assert_eq!(d.by_id(0x195).unwrap().name, "VCU_Demand");
    }

    proptest! {
        #[test]
        fn intel_fields_decode_as_a_little_endian_shift(data in proptest::array::uniform8(any::<u8>())) {
            // the bit walk gives what the shift it replaced gave, for every
            // signal of the shipped (all Intel) DBC
            let inv = Dbc::inverter().unwrap();
            for m in &inv.messages {
                for s in &m.signals {
                    let start = s.bits[s.bits.len() - 1];
                    let mask = if s.len >= 64 { u64::MAX } else { (1u64 << s.len) - 1 };
                    let v = (u64::from_le_bytes(data) >> start) & mask;
                    let want = if s.signed && s.len < 64 && (v >> (s.len - 1)) & 1 == 1 {
                        (v | !mask) as i64
                    } else {
                        v as i64
                    };
                    prop_assert_eq!(s.raw(&data), want, "{}.{}", m.name, s.name);
                }
            }
        }

        #[test]
        fn every_own_bus_field_reads_back_what_was_written(data in proptest::array::uniform8(any::<u8>()), x in 0.0f64..1.0) {
            for m in &own_bus().messages {
                for s in &m.signals {
                    let mut d = data;
                    let (lo, hi) = if s.signed {
                        (-(1i64 << (s.len - 1)), (1i64 << (s.len - 1)) - 1)
                    } else {
                        (0, (1i64 << s.len) - 1)
                    };
                    let raw = lo + ((hi - lo) as f64 * x) as i64;
                    s.put(&mut d, raw as f64 * s.factor + s.offset);
                    prop_assert_eq!(s.raw(&d), raw, "{}.{}", m.name, s.name);
                    // and no other signal of the message changed
                    for o in m.signals.iter().filter(|o| o.name != s.name) {
                        prop_assert_eq!(o.raw(&d), o.raw(&data), "{} changed {}", s.name, o.name);
                    }
                }
            }
        }

        #[test]
        fn zero_crossings_recover_any_audio_frequency(freq in 50.0f64..8000.0, amp in 0.05f64..1.0) {
            let x = sine_i16(freq, 48_000, amp, 24_000);
            let f = zero_crossing_frequency(&x, 48_000).unwrap();
            prop_assert!((f - freq).abs() < 0.01 * freq.max(100.0) / 100.0, "{} vs {}", f, freq);
        }
    }
}
