//! The ALSA capture source.
//!
//! Opening (`AlsaPcm::open`, prepared; capture starts at the first read,
//! after the real-time set-up, so `mlockall` cannot overrun it): the named PCM, non-blocking, interleaved
//! S16_LE, the configured channel count, **exactly** the configured rate
//! (a device that cannot do it is an error naming the rate it offered; use
//! a `plug:` device to have alsa-lib resample), period and buffer sizes as
//! near as the device allows (the actual ones are logged), time stamps on,
//! type CLOCK_MONOTONIC. A device that does not open is an error naming it,
//! with alsa-lib's reason and the list of capture PCMs alsa-lib knows (the
//! hint API `aplay -L` uses).
//!
//! Reading ([`AlsaSource::read`]): waits for data at most
//! `wait_timeout_ms` per wait (then returns [`Read::Timeout`] so the loop
//! can check its stop flag; the partly filled block is kept), reads what is
//! there until the block is full, and picks the configured channel.
//!
//! **Overruns (xruns)**: an `EPIPE` (overrun) or `ESTRPIPE` (suspend) from
//! wait or read is counted and recovered with `snd_pcm_recover` (which
//! calls `snd_pcm_prepare`, or resumes) followed by `snd_pcm_start`; the
//! samples of the partly filled block are discarded, because they are not
//! contiguous with what follows. Sequence numbers stay contiguous (no block
//! was lost *in transport*); the `xruns` field of every following block
//! shows that audio was lost, and the next block's stamp shows where the
//! stream resumed.
//!
//! **Time stamps**: when the block is complete, `snd_pcm_status` gives the
//! driver's high-resolution time stamp `htstamp` of the last hardware
//! pointer update and `delay` (frames captured but not yet read at that
//! moment). The first sample of the block was captured at
//! `htstamp − (delay + n)/fs`. If the device gives no usable time stamp
//! (zero, or more than 1 s away from CLOCK_MONOTONIC now, e.g. a plugin
//! without time stamps), the stamp is the capture-completion time minus the
//! block duration, `now − n/fs`, and `stamp_fallbacks` counts it.

use std::ffi::CString;

use alsa::pcm::{Access, Format, HwParams, PCM, TstampType};
use alsa::{Direction, ValueOr};
use grip_io::clock::monotonic_now_ns;

use crate::AcqError;
use crate::config::AlsaSection;
use crate::source::{Read, Source, SourceStats};

/// A capture device as [`AlsaSource`] uses it (the real one is [`AlsaPcm`];
/// tests inject faults through a fake).
pub trait CaptureDevice {
    /// Waits up to `timeout_ms` for data; `Ok(false)` on timeout.
    fn wait(&mut self, timeout_ms: u32) -> Result<bool, alsa::Error>;
    /// Reads interleaved frames into `buf` (length a multiple of the channel
    /// count); returns frames read. `EAGAIN` when nothing is there.
    fn read(&mut self, buf: &mut [i16]) -> Result<usize, alsa::Error>;
    /// Recovers from an xrun/suspend error and restarts capture.
    fn recover(&mut self, e: alsa::Error) -> Result<(), alsa::Error>;
    /// Driver time stamp (CLOCK_MONOTONIC ns) and delay (frames) now, if
    /// the device gives them.
    fn timing(&mut self) -> Option<(u64, i64)>;
    /// Starts capture (called by the first read, so that nothing overruns
    /// between opening and the loop, e.g. during `mlockall`).
    fn start(&mut self) -> Result<(), alsa::Error> {
        Ok(())
    }
}

/// An opened, configured, started ALSA capture PCM.
#[derive(Debug)]
pub struct AlsaPcm {
    pcm: PCM,
    /// Device name.
    pub device: String,
    /// Actual period size, frames.
    pub period_frames: usize,
    /// Actual buffer size, frames.
    pub buffer_frames: usize,
}

fn capture_devices() -> String {
    let mut names = Vec::new();
    if let Ok(it) = alsa::device_name::HintIter::new_str(None, "pcm") {
        for h in it {
            if matches!(h.direction, Some(Direction::Playback)) {
                continue;
            }
            if let Some(n) = h.name {
                names.push(n);
            }
        }
    }
    if names.is_empty() {
        "none (alsa-lib lists no capture PCM: no sound card, or no ALSA configuration)".into()
    } else {
        names.join(", ")
    }
}

impl AlsaPcm {
    /// Opens and configures `cfg.device` for capture at `rate` Hz (see the
    /// module docs). Start-up only.
    pub fn open(cfg: &AlsaSection, rate: u32) -> Result<Self, AcqError> {
        let dev = cfg.device.as_str();
        let cname = CString::new(dev).map_err(|_| AcqError::AlsaDevice {
            device: dev.into(),
            reason: "the name contains a NUL byte".into(),
            available: String::new(),
        })?;
        let pcm =
            PCM::open(&cname, Direction::Capture, true).map_err(|e| AcqError::AlsaDevice {
                device: dev.into(),
                reason: e.to_string(),
                available: capture_devices(),
            })?;
        let param = |what: &str, e: alsa::Error| AcqError::AlsaParams {
            device: dev.into(),
            reason: format!("{what}: {e}"),
        };
        let (period, buffer) = {
            let hwp = HwParams::any(&pcm).map_err(|e| param("hw_params_any", e))?;
            hwp.set_access(Access::RWInterleaved)
                .map_err(|e| param("interleaved read/write access", e))?;
            hwp.set_format(Format::s16())
                .map_err(|e| param("sample format S16_LE", e))?;
            hwp.set_channels(cfg.channels)
                .map_err(|e| param(&format!("{} channel(s)", cfg.channels), e))?;
            hwp.set_rate_resample(false)
                .map_err(|e| param("disabling alsa-lib resampling", e))?;
            if let Err(e) = hwp.set_rate(rate, ValueOr::Nearest) {
                let offered = hwp
                    .get_rate_min()
                    .ok()
                    .zip(hwp.get_rate_max().ok())
                    .map(|(a, b)| format!(" (device offers {a}..={b} Hz)"))
                    .unwrap_or_default();
                return Err(param(&format!("rate {rate} Hz{offered}"), e));
            }
            let got = hwp.get_rate().map_err(|e| param("reading the rate", e))?;
            if got != rate {
                return Err(AcqError::AlsaParams {
                    device: dev.into(),
                    reason: format!(
                        "rate {rate} Hz not available, nearest is {got} Hz: set [audio] sample_rate to a rate the device offers (audio-acq turns alsa-lib's resampling off, for plug: devices too)"
                    ),
                });
            }
            hwp.set_period_size_near(cfg.period_frames as alsa::pcm::Frames, ValueOr::Nearest)
                .map_err(|e| param(&format!("period {} frames", cfg.period_frames), e))?;
            hwp.set_buffer_size_near(cfg.buffer_frames as alsa::pcm::Frames)
                .map_err(|e| param(&format!("buffer {} frames", cfg.buffer_frames), e))?;
            pcm.hw_params(&hwp)
                .map_err(|e| param("applying hw params", e))?;
            let cur = pcm
                .hw_params_current()
                .map_err(|e| param("reading hw params", e))?;
            (
                cur.get_period_size().map_err(|e| param("period size", e))? as usize,
                cur.get_buffer_size().map_err(|e| param("buffer size", e))? as usize,
            )
        };
        {
            let swp = pcm.sw_params_current().map_err(|e| param("sw_params", e))?;
            swp.set_avail_min(period as alsa::pcm::Frames)
                .map_err(|e| param("avail_min", e))?;
            swp.set_tstamp_mode(true)
                .map_err(|e| param("time stamp mode", e))?;
            if let Err(e) = swp.set_tstamp_type(TstampType::Monotonic) {
                tracing::warn!(
                    device = dev,
                    "ALSA: cannot select CLOCK_MONOTONIC time stamps ({e}); block stamps will fall back to capture time"
                );
            }
            pcm.sw_params(&swp)
                .map_err(|e| param("applying sw params", e))?;
        }
        // Check the sample format once; reads then use io_unchecked.
        drop(pcm.io_i16().map_err(|e| param("S16 I/O", e))?);
        pcm.prepare().map_err(|e| param("prepare", e))?;
        Ok(Self {
            pcm,
            device: dev.into(),
            period_frames: period,
            buffer_frames: buffer,
        })
    }
}

fn ts_ns(t: &libc::timespec) -> u64 {
    (t.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(t.tv_nsec as u64)
}

impl CaptureDevice for AlsaPcm {
    fn wait(&mut self, timeout_ms: u32) -> Result<bool, alsa::Error> {
        self.pcm.wait(Some(timeout_ms))
    }
    fn read(&mut self, buf: &mut [i16]) -> Result<usize, alsa::Error> {
        // SAFETY: the format was verified as S16 at open (io_i16), and this
        // is the only IO object of the PCM, dropped at the end of the call.
        let io = unsafe { self.pcm.io_unchecked::<i16>() };
        io.readi(buf)
    }
    fn recover(&mut self, e: alsa::Error) -> Result<(), alsa::Error> {
        self.pcm.try_recover(e, true)?;
        // After prepare a capture stream must be started again; recover of
        // a suspend may have resumed it already (then start fails: ignore).
        let _ = self.pcm.start();
        Ok(())
    }
    fn start(&mut self) -> Result<(), alsa::Error> {
        self.pcm.start()
    }
    fn timing(&mut self) -> Option<(u64, i64)> {
        let s = self.pcm.status().ok()?;
        let t = ts_ns(&s.get_htstamp());
        Some((t, s.get_delay()))
    }
}

/// Mono S16 blocks from a [`CaptureDevice`] (see the module docs).
#[derive(Debug)]
pub struct AlsaSource<D: CaptureDevice> {
    dev: D,
    rate: u32,
    channels: usize,
    channel: usize,
    wait_ms: u32,
    inter: Vec<i16>,
    pos: usize,
    xruns: u32,
    stamp_fallbacks: u64,
    started: bool,
}

fn is_xrun(e: &alsa::Error) -> bool {
    matches!(e.errno(), libc::EPIPE | libc::ESTRPIPE)
}

impl<D: CaptureDevice> AlsaSource<D> {
    /// A source reading blocks up to `max_block` frames from `dev`.
    pub fn new(dev: D, cfg: &AlsaSection, rate: u32, max_block: usize) -> Self {
        let channels = cfg.channels.max(1) as usize;
        Self {
            dev,
            rate,
            channels,
            channel: (cfg.channel as usize).min(channels - 1),
            wait_ms: cfg.wait_timeout_ms.max(1),
            inter: vec![0; max_block * channels],
            pos: 0,
            xruns: 0,
            stamp_fallbacks: 0,
            started: false,
        }
    }

    /// The device.
    pub fn device(&self) -> &D {
        &self.dev
    }

    /// Blocks stamped with the fallback (no usable driver time stamp).
    pub fn stamp_fallbacks(&self) -> u64 {
        self.stamp_fallbacks
    }

    fn xrun(&mut self, e: alsa::Error) -> Result<(), AcqError> {
        self.xruns = self.xruns.wrapping_add(1);
        self.pos = 0;
        self.dev.recover(e).map_err(|e| AcqError::AlsaIo {
            what: "recovering from an overrun",
            reason: e.to_string(),
        })
    }
}

impl<D: CaptureDevice> Source for AlsaSource<D> {
    fn sample_rate(&self) -> u32 {
        self.rate
    }

    fn read(&mut self, out: &mut [i16]) -> Result<Read, AcqError> {
        if !self.started {
            self.dev.start().map_err(|e| AcqError::AlsaIo {
                what: "starting capture",
                reason: e.to_string(),
            })?;
            self.started = true;
        }
        let n = out.len().min(self.inter.len() / self.channels);
        let ch = self.channels;
        while self.pos < n {
            match self.dev.wait(self.wait_ms) {
                Ok(true) => {}
                Ok(false) => return Ok(Read::Timeout),
                Err(e) if is_xrun(&e) => {
                    self.xrun(e)?;
                    continue;
                }
                Err(e) => {
                    return Err(AcqError::AlsaIo {
                        what: "waiting for capture data",
                        reason: e.to_string(),
                    });
                }
            }
            match self.dev.read(&mut self.inter[self.pos * ch..n * ch]) {
                Ok(k) => self.pos += k.min(n - self.pos),
                Err(e) if e.errno() == libc::EAGAIN => {}
                Err(e) if is_xrun(&e) => self.xrun(e)?,
                Err(e) => {
                    return Err(AcqError::AlsaIo {
                        what: "reading capture data",
                        reason: e.to_string(),
                    });
                }
            }
        }
        self.pos = 0;
        for (o, f) in out[..n].iter_mut().zip(self.inter.chunks_exact(ch)) {
            *o = f[self.channel];
        }
        let now = monotonic_now_ns();
        let dur = (u128::from(n as u64) * 1_000_000_000 / u128::from(self.rate.max(1))) as u64;
        let stamp_ns = match self.dev.timing() {
            Some((ts, delay)) if ts != 0 && ts.abs_diff(now) < 1_000_000_000 => {
                let back = (i128::from(delay.max(0)) * 1_000_000_000 / i128::from(self.rate.max(1)))
                    as u64;
                ts.saturating_sub(back).saturating_sub(dur)
            }
            _ => {
                self.stamp_fallbacks += 1;
                now.saturating_sub(dur)
            }
        };
        Ok(Read::Block { n, stamp_ns })
    }

    fn stats(&self) -> SourceStats {
        SourceStats {
            xruns: self.xruns,
            ..SourceStats::default()
        }
    }
}
