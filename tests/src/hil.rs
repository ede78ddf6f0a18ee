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

/// Where the service binaries are: `$GRIP_BIN_DIR`, else the profile folder
/// this test binary was built into (`target/<profile>`, the parent of `deps/`).
pub fn bin_dir() -> PathBuf {
    if let Some(d) = env::var_os("GRIP_BIN_DIR").filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    env::current_exe()
        .ok()
        .and_then(|exe| exe.parent()?.parent().map(Path::to_path_buf))
        .unwrap_or_else(|| workspace_dir().join("target/debug"))
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
pub fn service_bin(name: &str) -> anyhow::Result<PathBuf> {
    let p = bin_dir().join(name);
    if p.is_file() {
        Ok(p)
    } else {
        bail!(
            "service binary {} not found (GRIP_BIN_DIR={}); tools/hil/run builds \
             the workspace's service binaries, or run `cargo build --bin {name}`",
            p.display(),
            bin_dir().display()
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
            return Err(io::Error::last_os_error())
                .with_context(|| format!("read(can_frame) returned {n}"));
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
        let log = log_dir.join(format!("{label}.log"));
        let out = fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        let err = out.try_clone()?;
        let child = Command::new(program)
            .args(args)
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

    proptest! {
        #[test]
        fn zero_crossings_recover_any_audio_frequency(freq in 50.0f64..8000.0, amp in 0.05f64..1.0) {
            let x = sine_i16(freq, 48_000, amp, 24_000);
            let f = zero_crossing_frequency(&x, 48_000).unwrap();
            prop_assert!((f - freq).abs() < 0.01 * freq.max(100.0) / 100.0, "{} vs {}", f, freq);
        }
    }
}
