//! The ALSA capture source.
//!
//! Opening (`AlsaPcm::open`, prepared; capture starts at the first read,
//! after the real-time set-up, so `mlockall` cannot overrun it): the named
//! PCM, non-blocking, interleaved, the configured channel count, the
//! sample format `[alsa] format` asks for (`"auto"`: the first of S16_LE,
//! S32_LE, S24_3LE, S24_LE, FLOAT_LE the device offers; a format it does
//! not offer is an error naming the device, the format and the formats it
//! offers; the choice is logged), **exactly** the configured rate, period
//! and buffer sizes as near as the device allows (the actual ones are
//! logged), time stamps on, type CLOCK_MONOTONIC. A device that does not
//! open is an error naming it, with alsa-lib's reason and the list of
//! capture PCMs alsa-lib knows (the hint API `aplay -L` uses).
//!
//! **Rate.** alsa-lib's resampling is off unless `[alsa] resample = true`
//! (`snd_pcm_hw_params_set_rate_resample`). Off, a device that cannot
//! capture at `[audio] sample_rate` is an error naming the rates it offers,
//! plug devices included (a `plug` PCM then only converts format and
//! channels). On, a plug device (`plughw:CARD,DEV`, `plug:...`, or a
//! `default` that is one) resamples from a rate its hardware has; a `hw:`
//! device never resamples, so with it the flag changes nothing. Resampling
//! costs CPU in the capture thread and filters the audio (alsa-lib's rate
//! converter), so a rate the hardware has natively is better.
//!
//! **Formats** ([`crate::format`]): the device delivers raw interleaved
//! bytes in the chosen format into a buffer sized at start-up; the read
//! path converts the published channel to S16 as it picks it out of the
//! frames, allocating nothing.
//!
//! Reading ([`AlsaSource::read`]): waits for data at most
//! `wait_timeout_ms` per wait (then returns [`Read::Timeout`] so the loop
//! can check its stop flag; the partly filled block is kept), reads what is
//! there until the block is full, and converts the configured channel to
//! S16.
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
use crate::format::{SampleFormat, extract_channel};
use crate::source::{Read, Source, SourceStats};

/// A capture device as [`AlsaSource`] uses it (the real one is [`AlsaPcm`];
/// tests inject faults through a fake).
pub trait CaptureDevice {
    /// The sample format [`CaptureDevice::read`] delivers (fixed once the
    /// device is open; [`AlsaSource::new`] sizes its buffer from it).
    fn format(&self) -> SampleFormat;
    /// Waits up to `timeout_ms` for data; `Ok(false)` on timeout.
    fn wait(&mut self, timeout_ms: u32) -> Result<bool, alsa::Error>;
    /// Reads interleaved frames as raw bytes in [`CaptureDevice::format`]
    /// into `buf` (length a whole number of frames: channels × the
    /// format's bytes); returns frames read. `EAGAIN` when nothing is there.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, alsa::Error>;
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
    /// The sample format it captures in.
    pub format: SampleFormat,
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

/// The formats of alsa-lib's list that `hwp` (its configuration space as
/// restricted so far) still allows, by name; "none" if it allows none.
fn offered_formats(hwp: &HwParams) -> String {
    let names: Vec<String> = Format::all()
        .iter()
        .filter(|f| !matches!(f, Format::Unknown) && hwp.test_format(**f).is_ok())
        .map(|f| f.to_string())
        .collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

/// The sample format `cfg.format` selects on the device (see the module
/// docs); logged. Start-up only.
fn choose_format(hwp: &HwParams, cfg: &AlsaSection, dev: &str) -> Result<SampleFormat, AcqError> {
    let offers = |f: SampleFormat| hwp.test_format(f.alsa()).is_ok();
    let usable: Vec<&str> = SampleFormat::PREFERENCE
        .into_iter()
        .filter(|&f| offers(f))
        .map(SampleFormat::name)
        .collect();
    let remedy = if usable.is_empty() {
        format!(
            "none of them is one audio-acq reads ({}): use a plughw: device, which converts",
            reads_list()
        )
    } else {
        format!(
            "set [alsa] format = \"auto\" or one of {}; or use a plughw: device, which converts",
            usable.join(", ")
        )
    };
    let (format, how) = match cfg.format.fixed() {
        Some(f) if offers(f) => (f, "set by [alsa] format"),
        Some(f) => {
            return Err(AcqError::AlsaParams {
                device: dev.into(),
                reason: format!(
                    "sample format {f} ([alsa] format) is not offered; the device offers: {} ({remedy})",
                    offered_formats(hwp),
                ),
            });
        }
        None => match SampleFormat::PREFERENCE.into_iter().find(|&f| offers(f)) {
            Some(f) => (f, "auto: the first the device offers"),
            None => {
                return Err(AcqError::AlsaParams {
                    device: dev.into(),
                    reason: format!(
                        "no sample format audio-acq reads is offered ([alsa] format = \"auto\"); \
                         the device offers: {} ({remedy})",
                        offered_formats(hwp)
                    ),
                });
            }
        },
    };
    tracing::info!(
        device = dev,
        format = format.name(),
        offered = %offered_formats(hwp),
        "ALSA capture sample format {format} ({how}), converted to S16"
    );
    Ok(format)
}

/// The formats audio-acq reads, in `"auto"`'s order.
fn reads_list() -> String {
    SampleFormat::PREFERENCE
        .iter()
        .map(|f| f.name())
        .collect::<Vec<_>>()
        .join(", ")
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
        let (format, period, buffer) = {
            let hwp = HwParams::any(&pcm).map_err(|e| param("hw_params_any", e))?;
            hwp.set_access(Access::RWInterleaved)
                .map_err(|e| param("interleaved read/write access", e))?;
            hwp.set_channels(cfg.channels)
                .map_err(|e| param(&format!("{} channel(s)", cfg.channels), e))?;
            let format = choose_format(&hwp, cfg, dev)?;
            hwp.set_format(format.alsa())
                .map_err(|e| param(&format!("sample format {format}"), e))?;
            hwp.set_rate_resample(cfg.resample)
                .map_err(|e| param("setting alsa-lib resampling", e))?;
            let rate_hint = if cfg.resample {
                "set [audio] sample_rate to a rate the device offers, or use a plug device \
                 (plughw:CARD,DEV or plug:...), which resamples with [alsa] resample = true; \
                 a hw: device never resamples"
            } else {
                "set [alsa] resample = true with a plug device (plughw:CARD,DEV or plug:...) \
                 to have alsa-lib resample, or set [audio] sample_rate to a rate the device offers"
            };
            if let Err(e) = hwp.set_rate(rate, ValueOr::Nearest) {
                let offered = hwp
                    .get_rate_min()
                    .ok()
                    .zip(hwp.get_rate_max().ok())
                    .map(|(a, b)| format!(" (device offers {a}..={b} Hz)"))
                    .unwrap_or_default();
                return Err(AcqError::AlsaParams {
                    device: dev.into(),
                    reason: format!("rate {rate} Hz{offered}: {e}; {rate_hint}"),
                });
            }
            let got = hwp.get_rate().map_err(|e| param("reading the rate", e))?;
            if got != rate {
                return Err(AcqError::AlsaParams {
                    device: dev.into(),
                    reason: format!(
                        "rate {rate} Hz not available, nearest is {got} Hz: {rate_hint}"
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
            // reads hand the bytes to the conversion of this format
            let got = cur
                .get_format()
                .map_err(|e| param("reading the format", e))?;
            if got != format.alsa() {
                return Err(AcqError::AlsaParams {
                    device: dev.into(),
                    reason: format!("asked for sample format {format}, the device set {got}"),
                });
            }
            (
                format,
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
        pcm.prepare().map_err(|e| param("prepare", e))?;
        Ok(Self {
            pcm,
            device: dev.into(),
            format,
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
    fn format(&self) -> SampleFormat {
        self.format
    }
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, alsa::Error> {
        // raw bytes in the format verified at open; alsa-lib counts frames
        // from the PCM's own frame size. The IO object lives for this call.
        self.pcm.io_bytes().readi(buf)
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

/// Mono S16 blocks from a [`CaptureDevice`] in any [`SampleFormat`] (see
/// the module docs).
#[derive(Debug)]
pub struct AlsaSource<D: CaptureDevice> {
    dev: D,
    rate: u32,
    channels: usize,
    channel: usize,
    wait_ms: u32,
    format: SampleFormat,
    /// Bytes per interleaved frame.
    frame_bytes: usize,
    /// Raw interleaved frames of the block being read, sized at start-up.
    inter: Vec<u8>,
    /// Frames of the block read so far.
    pos: usize,
    xruns: u32,
    stamp_fallbacks: u64,
    started: bool,
}

fn is_xrun(e: &alsa::Error) -> bool {
    matches!(e.errno(), libc::EPIPE | libc::ESTRPIPE)
}

impl<D: CaptureDevice> AlsaSource<D> {
    /// A source reading blocks up to `max_block` frames from `dev`, in the
    /// format `dev` delivers (the buffer for them is allocated here, once).
    pub fn new(dev: D, cfg: &AlsaSection, rate: u32, max_block: usize) -> Self {
        let channels = cfg.channels.max(1) as usize;
        let format = dev.format();
        let frame_bytes = channels * format.bytes();
        Self {
            dev,
            rate,
            channels,
            channel: (cfg.channel as usize).min(channels - 1),
            wait_ms: cfg.wait_timeout_ms.max(1),
            format,
            frame_bytes,
            inter: vec![0; max_block * frame_bytes],
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
        let n = out.len().min(self.inter.len() / self.frame_bytes);
        let fb = self.frame_bytes;
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
            match self.dev.read(&mut self.inter[self.pos * fb..n * fb]) {
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
        extract_channel(
            self.format,
            &self.inter[..n * fb],
            self.channels,
            self.channel,
            &mut out[..n],
        );
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
