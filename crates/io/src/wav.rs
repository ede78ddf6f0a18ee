//! WAV files (hound underneath): the one reader and writer of grip. The
//! `grip` CLI (`dataset`, `features`, `train`, `classify`) and audio-acq's
//! file source (`WavSource`) read through it, `grip dataset synth` writes
//! through it, so a recording decodes to the same samples offline and live.
//!
//! Reading:
//! - PCM integer (8, 16, 24, 32 bit) and 32-bit float files; integers are
//!   scaled to [−1, 1) by 2^(bits−1); float samples beyond full scale are
//!   clamped to [−1, 1] and non-finite ones (NaN, ±∞) are read as 0, both
//!   counted in [`Audio::clamped`] / [`Audio::non_finite`] and logged as a
//!   warning naming the file (`tracing::warn!`).
//! - `WAVE_FORMAT_EXTENSIBLE` (tag 0xFFFE) integer files whose valid bits are
//!   fewer than the container's (24 valid bits in 32, 20 in 24, ...): the
//!   valid bits are the container's most significant ones (the Microsoft
//!   spec), so each container sample is read as a signed integer of the
//!   container width, shifted right by container − valid bits and scaled by
//!   2^(valid−1). hound would take the low bytes instead, so these samples
//!   are read here (the fmt chunk found by a chunk walk of our own that
//!   honours RIFF pad bytes). A file whose padding bits (below the valid
//!   ones) are not all zero is refused: its samples are not laid out as the
//!   spec says (a writer that right-aligned them), and no reading of it is
//!   sure. A plain-PCM file (tag 1) with 24 bits in 4-byte containers
//!   (arecord's S24_LE) keeps the low 3 bytes, as it is written.
//! - Refused with [`WavErrorKind::Layout`]: integer containers wider than
//!   4 bytes, valid bits above the container width, and plain-PCM widths
//!   hound cannot read (e.g. 16 bits in 4-byte containers).
//! - Several channels are **mixed down** to mono by averaging, or one of
//!   them is taken ([`Channel`]: [`read_channel`], [`decode_channel`],
//!   [`read_channel_at`]; a channel beyond the file's count is
//!   [`WavErrorKind::NoSuchChannel`]). The live ALSA source publishes one
//!   channel; averaging a stereo pair whose channels are in opposite phase
//!   cancels the signal (to silence, where the pair is exactly opposite).
//! - A file at another sample rate is **resampled** to the rate asked for by
//!   [`read_mono_at`] ([`resample`]); [`read_mono`] and [`decode_mono`] keep
//!   the file's rate. The result, an [`Audio`], records the file's own rate
//!   and channel count so callers can report them.
//! - Every refusal is a [`WavError`] naming the file and the reason
//!   ([`WavErrorKind`]): cannot open, not a WAV file, 0 channels, sample
//!   rate 0, unsupported sample width, corrupt data. A data chunk whose
//!   declared length the file does not hold (0: not finalised; 0xFFFFFFFF
//!   or beyond the end: a streaming length, a cut file) is read as far as
//!   the file goes, with a warning ([`Audio::data_declared`]).
//!
//! Writing: [`write_mono_i16`] writes 16-bit mono PCM, clamping to [−1, 1].
//!
//! The resampler lives here, beside the file reader, rather than in the
//! pure DSP crate grip-arte: its only use is reading a file recorded at
//! another rate (offline, or once at audio-acq's start-up; the live audio
//! path never resamples, the arte service counts a rate mismatch instead),
//! and grip-io depending on grip-arte for it would pull the feature and
//! classifier crate (rustfft, nalgebra) into every service.

use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Mono audio decoded from a WAV file. `S` is the sample type: `f32` in
/// [−1, 1] as read; a consumer that needs another format converts with
/// [`Audio::map`] (audio-acq: S16).
#[derive(Clone, Debug, PartialEq)]
pub struct Audio<S = f32> {
    /// Sample rate of `samples`, Hz.
    pub sample_rate: u32,
    /// Mono samples (the channels averaged, or the one asked for:
    /// [`Channel`]).
    pub samples: Vec<S>,
    /// The file's own sample rate, Hz.
    pub file_rate: u32,
    /// The file's channel count (made mono by [`Channel`]).
    pub file_channels: u16,
    /// Float samples beyond full scale, clamped to [−1, 1] (counted per
    /// channel sample, before the mixdown; 0 for integer files).
    pub clamped: usize,
    /// Non-finite float samples (NaN, ±∞), read as 0.
    pub non_finite: usize,
    /// The data chunk's length as the header declared it, bytes, when the
    /// file did not hold that (0: a recording not finalised; 0xFFFFFFFF
    /// or more than is there: a streaming length, or a cut file): the
    /// whole sample frames the file holds were read instead, with a
    /// warning. `None`: the header's length was the file's.
    pub data_declared: Option<u64>,
}

impl<S> Audio<S> {
    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 / f64::from(self.sample_rate)
    }

    /// The same audio with every sample converted by `f`.
    pub fn map<T>(self, f: impl FnMut(S) -> T) -> Audio<T> {
        Audio {
            sample_rate: self.sample_rate,
            samples: self.samples.into_iter().map(f).collect(),
            file_rate: self.file_rate,
            file_channels: self.file_channels,
            clamped: self.clamped,
            non_finite: self.non_finite,
            data_declared: self.data_declared,
        }
    }
}

/// A WAV file that cannot be read or written: the file and why.
#[derive(Debug, thiserror::Error)]
#[error("WAV file {}: {kind}", path.display())]
pub struct WavError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub kind: WavErrorKind,
}

/// Why a WAV file cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum WavErrorKind {
    /// The file does not open or its header cannot be read.
    #[error("cannot open: {0}")]
    Open(std::io::Error),
    /// The bytes are not a WAV file (no RIFF/WAVE header, bad chunks).
    #[error("not a valid WAV file: {0}")]
    NotWav(&'static str),
    /// hound refuses the file for another reason.
    #[error("not a readable WAV file: {0}")]
    Unreadable(hound::Error),
    /// The header says 0 channels.
    #[error("header says 0 channels")]
    NoChannels,
    /// The header says sample rate 0.
    #[error("header says sample rate 0 Hz")]
    NoSampleRate,
    /// Integer PCM wider than 32 bits (or 0 bits).
    #[error("unsupported PCM sample width {0} bits")]
    IntWidth(u16),
    /// A sample layout that cannot be read correctly (see the module docs).
    #[error("unsupported sample layout: {0}")]
    Layout(String),
    /// Float samples other than 32-bit.
    #[error("unsupported float sample width {0} bits (only 32)")]
    FloatWidth(u16),
    /// A sample could not be decoded.
    #[error("truncated or corrupt after {got} of {expected} samples: {error}")]
    Corrupt {
        /// Samples decoded before the failure.
        got: usize,
        /// Samples the header announces.
        expected: usize,
        /// hound's reason.
        error: hound::Error,
    },
    /// Fewer samples than the header announces.
    #[error("truncated: {got} of {expected} samples present")]
    Truncated {
        /// Samples present.
        got: usize,
        /// Samples the header announces.
        expected: usize,
    },
    /// A channel beyond the file's channel count was asked for.
    #[error("has {channels} channel(s); channel {channel} (0-based) does not exist")]
    NoSuchChannel {
        /// The channel asked for (0-based).
        channel: u16,
        /// The file's channel count.
        channels: u16,
    },
    /// The file holds no samples (for a caller that needs some).
    #[error("has no samples")]
    NoSamples,
    /// Resampling to 0 Hz was asked for.
    #[error("cannot resample to 0 Hz")]
    ZeroTargetRate,
    /// Resampling would multiply the samples by more than
    /// [`MAX_UPSAMPLE`] (a header claiming, say, 1 Hz: a 1 MB file would
    /// ask for about 96 GB at 48 kHz).
    #[error(
        "header says sample rate {from} Hz: resampling to {to} Hz would multiply the samples by more than {MAX_UPSAMPLE} (a recording of road noise has a rate of kHz)"
    )]
    RateTooLow {
        /// The file's rate, Hz.
        from: u32,
        /// The rate asked for, Hz.
        to: u32,
    },
    /// The file cannot be created.
    #[error("cannot create: {0}")]
    Create(hound::Error),
    /// A sample or the header cannot be written.
    #[error("cannot write: {0}")]
    Write(hound::Error),
}

impl WavErrorKind {
    /// This reason, for `path`.
    pub fn at(self, path: &Path) -> WavError {
        WavError {
            path: path.to_owned(),
            kind: self,
        }
    }

    fn open(e: hound::Error) -> Self {
        match e {
            hound::Error::IoError(io) => Self::Open(io),
            hound::Error::FormatError(m) => Self::NotWav(m),
            other => Self::Unreadable(other),
        }
    }
}

/// Which channels of a file make its mono signal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Channel {
    /// The average of all channels (a mono file's only one).
    #[default]
    Average,
    /// This channel alone (0-based).
    One(u16),
}

/// Reads a WAV file as mono (channels averaged) at its own sample rate.
pub fn read_mono(path: &Path) -> Result<Audio, WavError> {
    read_channel(path, Channel::Average)
}

/// Reads a WAV file's channel `channel` (or their average) at its own
/// sample rate.
pub fn read_channel(path: &Path, channel: Channel) -> Result<Audio, WavError> {
    let mut file = std::fs::File::open(path).map_err(|e| WavErrorKind::Open(e).at(path))?;
    // what the file can hold bounds the samples reserved for (0: unknown,
    // no reservation)
    let size = file.metadata().map_or(0, |m| m.len());
    let fmt = find_fmt(&mut file);
    let rewind = |f: &mut std::fs::File| {
        f.seek(SeekFrom::Start(0))
            .map_err(|e| WavErrorKind::Open(e).at(path))
    };
    rewind(&mut file)?;
    let short = short_data(&mut file, size);
    rewind(&mut file)?;
    let reader = Patched {
        inner: std::io::BufReader::new(file),
        pos: 0,
        at: short.map_or(u64::MAX - 4, |d| d.length_at),
        bytes: short.map_or([0; 4], |d| (d.present as u32).to_le_bytes()),
    };
    hound::WavReader::new(reader)
        .map_err(WavErrorKind::open)
        .and_then(|r| decode(r, fmt, size, channel))
        .map(|a| note_short(warn_clamped(a, path), short, path))
        .map_err(|k| k.at(path))
}

/// The most [`read_mono_at`] multiplies a file's samples by when it
/// resamples (8 kHz telephone audio to 96 kHz is 12).
pub const MAX_UPSAMPLE: u64 = 16;

/// Reads a WAV file as mono (channels averaged) at `rate` Hz, resampling
/// ([`resample`]) if the file has another rate.
pub fn read_mono_at(path: &Path, rate: u32) -> Result<Audio, WavError> {
    read_channel_at(path, rate, Channel::Average)
}

/// [`read_channel`] at `rate` Hz, resampling ([`resample`]) if the file has
/// another rate.
pub fn read_channel_at(path: &Path, rate: u32, channel: Channel) -> Result<Audio, WavError> {
    let mut a = read_channel(path, channel)?;
    if a.sample_rate != rate {
        if rate == 0 {
            return Err(WavErrorKind::ZeroTargetRate.at(path));
        }
        if u64::from(rate) > MAX_UPSAMPLE * u64::from(a.sample_rate) {
            return Err(WavErrorKind::RateTooLow {
                from: a.sample_rate,
                to: rate,
            }
            .at(path));
        }
        a.samples = resample(&a.samples, a.sample_rate, rate);
        a.sample_rate = rate;
    }
    Ok(a)
}

/// Decodes the bytes of a WAV file already in memory (`grip train` hashes
/// them too) as mono at the file's own rate; `path` names the file in errors.
pub fn decode_mono(bytes: &[u8], path: &Path) -> Result<Audio, WavError> {
    decode_channel(bytes, path, Channel::Average)
}

/// [`decode_mono`], taking `channel` (or the average).
pub fn decode_channel(bytes: &[u8], path: &Path, channel: Channel) -> Result<Audio, WavError> {
    let fmt = find_fmt(&mut std::io::Cursor::new(bytes));
    let short = short_data(&mut std::io::Cursor::new(bytes), bytes.len() as u64);
    let patched;
    let bytes = match short {
        Some(d) => {
            let mut b = bytes.to_vec();
            let at = d.length_at as usize;
            b[at..at + 4].copy_from_slice(&(d.present as u32).to_le_bytes());
            patched = b;
            &patched[..]
        }
        None => bytes,
    };
    hound::WavReader::new(std::io::Cursor::new(bytes))
        .map_err(WavErrorKind::open)
        .and_then(|r| decode(r, fmt, bytes.len() as u64, channel))
        .map(|a| note_short(a, short, path))
        .map(|a| warn_clamped(a, path))
        .map_err(|k| k.at(path))
}

/// Logs the float samples of `a` that were clamped or read as 0.
fn warn_clamped(a: Audio, path: &Path) -> Audio {
    if a.clamped > 0 || a.non_finite > 0 {
        tracing::warn!(
            "WAV file {}: {} float samples beyond full scale clamped to [-1, 1], {} non-finite samples read as 0",
            path.display(),
            a.clamped,
            a.non_finite
        );
    }
    a
}

/// `WAVE_FORMAT_EXTENSIBLE`.
const TAG_EXTENSIBLE: u16 = 0xFFFE;

/// The fields of the fmt chunk hound does not hand on.
#[derive(Clone, Copy, Debug)]
struct Fmt {
    /// wFormatTag.
    tag: u16,
    /// nChannels.
    channels: u16,
    /// nBlockAlign.
    block_align: u16,
    /// wValidBitsPerSample of an EXTENSIBLE chunk (None: other tags, or a
    /// chunk too short to hold it).
    valid_bits: Option<u16>,
}

/// Walks the RIFF chunks of a WAVE file (honouring the pad byte after an
/// odd-length chunk) to its fmt chunk. None when the bytes are not a WAVE
/// file or hold no fmt chunk before the data: hound then says why.
fn find_fmt<R: Read + Seek>(r: &mut R) -> Option<Fmt> {
    let mut head = [0u8; 12];
    r.read_exact(&mut head).ok()?;
    if &head[..4] != b"RIFF" || &head[8..] != b"WAVE" {
        return None;
    }
    loop {
        let mut ch = [0u8; 8];
        r.read_exact(&mut ch).ok()?;
        let len = u32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]);
        match &ch[..4] {
            b"fmt " => {
                let mut b = [0u8; 40];
                let n = (len as usize).min(40);
                r.read_exact(&mut b[..n]).ok()?;
                if n < 16 {
                    return None;
                }
                let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
                let tag = u16_at(0);
                let extensible = tag == TAG_EXTENSIBLE && n >= 20 && u16_at(16) >= 22 && n >= 40;
                return Some(Fmt {
                    tag,
                    channels: u16_at(2),
                    block_align: u16_at(12),
                    valid_bits: extensible.then(|| u16_at(18)),
                });
            }
            b"data" => return None,
            _ => {
                let skip = i64::from(len) + i64::from(len & 1);
                r.seek(SeekFrom::Current(skip)).ok()?;
            }
        }
    }
}

/// What a WAV file's header says, read without decoding its samples
/// ([`header`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WavHeader {
    /// Sample rate, Hz (> 0).
    pub sample_rate: u32,
    /// Channels (> 0).
    pub channels: u16,
    /// Sample frames in the data chunk, as far as the file holds them: a
    /// data size of 0 (an unfinalised recording) or one beyond the end of
    /// the file (a streaming length) counts the frames that are there.
    pub frames: u64,
}

impl WavHeader {
    /// Length, s.
    pub fn duration_s(&self) -> f64 {
        self.frames as f64 / f64::from(self.sample_rate)
    }
}

/// The header of the WAV file at `path` (rate, channels, frames), from its
/// RIFF chunks (the pad byte after an odd-length chunk honoured), without
/// decoding the samples. Errors name the file.
pub fn header(path: &Path) -> Result<WavHeader, WavError> {
    let mut f = std::fs::File::open(path).map_err(|e| WavErrorKind::Open(e).at(path))?;
    let file_len = f
        .metadata()
        .map_err(|e| WavErrorKind::Open(e).at(path))?
        .len();
    let d = walk_to_data(&mut f, file_len).map_err(|k| k.at(path))?;
    Ok(WavHeader {
        sample_rate: d.rate,
        channels: d.channels,
        frames: d.present / u64::from(d.block),
    })
}

/// The data chunk of a RIFF/WAVE stream, as [`walk_to_data`] finds it.
#[derive(Clone, Copy, Debug)]
struct DataChunk {
    rate: u32,
    channels: u16,
    block: u16,
    /// Where the chunk's length field is in the stream.
    length_at: u64,
    /// The length it declares, bytes.
    declared: u64,
    /// The bytes of the stream after the length field.
    rest: u64,
    /// The bytes of whole sample frames the stream holds for it: the
    /// declared length, or for a length of 0 (not finalised) or beyond the
    /// end (a streaming length, a cut file) what is there.
    present: u64,
}

/// Walks the RIFF chunks of `f` (`file_len` bytes; the pad byte after an
/// odd-length chunk honoured) to the data chunk, reading only the fmt
/// chunk's rate, channels and block size.
fn walk_to_data<R: Read + Seek>(f: &mut R, file_len: u64) -> Result<DataChunk, WavErrorKind> {
    let bad = WavErrorKind::NotWav;
    let mut head = [0u8; 12];
    f.read_exact(&mut head)
        .map_err(|_| bad("shorter than a RIFF header"))?;
    if &head[..4] != b"RIFF" || &head[8..] != b"WAVE" {
        return Err(bad("no RIFF/WAVE header"));
    }
    let mut fmt: Option<(u32, u16, u16)> = None;
    let mut pos = 12u64;
    loop {
        let mut ch = [0u8; 8];
        f.read_exact(&mut ch).map_err(|_| bad("no `data` chunk"))?;
        let size = u64::from(u32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]));
        let body = pos + 8;
        match &ch[..4] {
            b"fmt " => {
                let mut b = [0u8; 16];
                f.read_exact(&mut b)
                    .map_err(|_| bad("short `fmt ` chunk"))?;
                let rate = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
                let channels = u16::from_le_bytes([b[2], b[3]]);
                let block = u16::from_le_bytes([b[12], b[13]]);
                if channels == 0 {
                    return Err(WavErrorKind::NoChannels);
                }
                if rate == 0 {
                    return Err(WavErrorKind::NoSampleRate);
                }
                if block == 0 {
                    return Err(bad("block size 0"));
                }
                fmt = Some((rate, channels, block));
            }
            b"data" => {
                let (rate, channels, block) =
                    fmt.ok_or_else(|| bad("`data` chunk before the `fmt ` chunk"))?;
                let rest = file_len.saturating_sub(body);
                let bytes = if size == 0 || size > rest { rest } else { size };
                return Ok(DataChunk {
                    rate,
                    channels,
                    block,
                    length_at: pos + 4,
                    declared: size,
                    rest,
                    present: bytes - bytes % u64::from(block),
                });
            }
            _ => {}
        }
        pos = body + size + (size & 1);
        f.seek(SeekFrom::Start(pos)).map_err(WavErrorKind::Open)?;
    }
}

/// The data chunk's length to read with instead of the header's, when the
/// stream (`file_len` bytes) does not hold what the header declares (0: a
/// recording not finalised; 0xFFFFFFFF or beyond the end: a streaming
/// length, or a cut file): `Some(chunk)`, whose `present` is the length.
/// `None` when the length is right, or the chunks cannot be walked (the
/// reader then says why).
fn short_data<R: Read + Seek>(f: &mut R, file_len: u64) -> Option<DataChunk> {
    let d = walk_to_data(f, file_len).ok()?;
    (d.declared == 0 || d.declared > d.rest)
        .then_some(d)
        .filter(|d| u32::try_from(d.present).is_ok())
}

/// A reader that gives 4 bytes of the stream (at `at`) as `bytes`: the
/// data chunk's length, set to what the file holds ([`short_data`]).
struct Patched<R> {
    inner: R,
    pos: u64,
    at: u64,
    bytes: [u8; 4],
}

impl<R: Read> Read for Patched<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for (i, b) in self.bytes.iter().enumerate() {
            let p = self.at + i as u64;
            if p >= self.pos && p < self.pos + n as u64 {
                buf[(p - self.pos) as usize] = *b;
            }
        }
        self.pos += n as u64;
        Ok(n)
    }
}

/// The warning for a file read with its data chunk's length set to what it
/// holds, and the audio marked so.
fn note_short(mut a: Audio, d: Option<DataChunk>, path: &Path) -> Audio {
    if let Some(d) = d {
        let why = if d.declared == 0 {
            "0 (a recording not finalised)".to_owned()
        } else {
            format!(
                "{} bytes, more than the {} the file holds after it (a streaming length, or a cut file)",
                d.declared, d.present
            )
        };
        tracing::warn!(
            "WAV file {}: its header gives the data chunk a length of {why}: read the {} whole sample frames ({:.3} s) the file holds",
            path.display(),
            d.present / u64::from(d.block),
            (d.present / u64::from(d.block)) as f64 / f64::from(d.rate)
        );
        a.data_declared = Some(d.declared);
    }
    a
}

/// How the integer samples of a file are read.
#[derive(Clone, Copy, Debug, PartialEq)]
enum IntLayout {
    /// By hound: plain PCM, or EXTENSIBLE with as many valid bits as the
    /// container has.
    Hound,
    /// By [`read_left_aligned`]: EXTENSIBLE, `valid` bits left-aligned in
    /// `bytes`-byte containers.
    LeftAligned { bytes: u16, valid: u16 },
}

/// The layout of an integer file, or why it cannot be read correctly.
fn int_layout(spec: &hound::WavSpec, fmt: Option<Fmt>) -> Result<IntLayout, WavErrorKind> {
    let Some(f) = fmt else {
        // hound read a header our walk did not find: its own reading stands
        return Ok(IntLayout::Hound);
    };
    if f.channels != spec.channels || f.channels == 0 {
        return Err(WavErrorKind::NotWav("fmt chunk read two ways"));
    }
    let bytes = f.block_align / f.channels;
    let bits = spec.bits_per_sample;
    if bytes > 4 {
        return Err(WavErrorKind::Layout(format!(
            "{}-byte integer containers (at most 4)",
            bytes
        )));
    }
    if f.tag == TAG_EXTENSIBLE {
        let container = bytes * 8;
        // hound takes 0 valid bits for wBitsPerSample; so do we
        let valid = match f.valid_bits {
            Some(v) if v > 0 => v,
            _ => bits,
        };
        if valid != bits {
            return Err(WavErrorKind::NotWav("fmt chunk read two ways"));
        }
        if valid > container {
            return Err(WavErrorKind::Layout(format!(
                "{valid} valid bits in {container}-bit containers"
            )));
        }
        if valid < container {
            return Ok(IntLayout::LeftAligned { bytes, valid });
        }
    }
    match (bytes, bits) {
        (1, 8) | (2, 16) | (3, 24) | (4, 24) | (4, 32) => Ok(IntLayout::Hound),
        _ => Err(WavErrorKind::Layout(format!(
            "{bits}-bit integer samples in {bytes}-byte containers (format tag {:#06x})",
            f.tag
        ))),
    }
}

/// Reads `expected` integer samples of `valid` bits left-aligned in
/// `bytes`-byte little-endian containers from `r` (positioned at the data),
/// scaled to [−1, 1), into `out`. 8-bit containers are unsigned (offset
/// 128), wider ones two's complement. Refuses non-zero padding bits.
fn read_left_aligned<R: Read>(
    r: &mut R,
    bytes: u16,
    valid: u16,
    expected: usize,
    out: &mut Vec<f32>,
) -> Result<(), WavErrorKind> {
    let width = usize::from(bytes);
    let shift = u32::from(bytes * 8 - valid);
    // in u32: 1 valid bit in 32 shifts by 31, whose i32 mask overflowed
    let pad_mask = ((1u32 << shift) - 1) as i32;
    let scale = 1.0 / (1u64 << (valid - 1)) as f64;
    let mut buf = vec![0u8; width * 8192];
    while out.len() < expected {
        let want = (expected - out.len()).min(8192) * width;
        let got = read_full(r, &mut buf[..want]).map_err(|e| WavErrorKind::Corrupt {
            got: out.len(),
            expected,
            error: hound::Error::IoError(e),
        })?;
        for c in buf[..got - got % width].chunks_exact(width) {
            // the container as a signed integer in the top bits of an i32
            let mut w = [0u8; 4];
            w[4 - width..].copy_from_slice(c);
            if width == 1 {
                w[3] ^= 0x80;
            }
            let v = i32::from_le_bytes(w) >> (32 - 8 * width as u32);
            if v & pad_mask != 0 {
                return Err(WavErrorKind::Layout(format!(
                    "WAVE_FORMAT_EXTENSIBLE with {valid} valid bits in {}-bit containers, but sample {} has non-zero padding bits below the valid ones: the samples are not left-aligned as the format requires",
                    bytes * 8,
                    out.len()
                )));
            }
            out.push((f64::from(v >> shift) * scale) as f32);
        }
        if got < want {
            break;
        }
    }
    Ok(())
}

/// Reads until `buf` is full or the end of `r`; how many bytes were read.
fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Decodes `reader`, from a file of `file_bytes` bytes whose fmt chunk is
/// `fmt` (our own reading of it), to the mono signal `channel` says: the
/// samples are reserved for up to what the file can hold, not what its
/// header claims (a data-chunk length of 0xFFFFFFFF would ask for 17 GB).
fn decode<R: std::io::Read>(
    mut reader: hound::WavReader<R>,
    fmt: Option<Fmt>,
    file_bytes: u64,
    channel: Channel,
) -> Result<Audio, WavErrorKind> {
    let spec = reader.spec();
    let ch = spec.channels;
    if ch == 0 {
        return Err(WavErrorKind::NoChannels);
    }
    if let Channel::One(c) = channel
        && c >= ch
    {
        return Err(WavErrorKind::NoSuchChannel {
            channel: c,
            channels: ch,
        });
    }
    if spec.sample_rate == 0 {
        return Err(WavErrorKind::NoSampleRate);
    }
    let expected = reader.len() as usize;
    let sample_bytes = u64::from(spec.bits_per_sample.div_ceil(8).max(1));
    let fits = usize::try_from(file_bytes / sample_bytes).unwrap_or(usize::MAX);
    let mut inter: Vec<f32> = Vec::with_capacity(expected.min(fits));
    let (mut clamped, mut non_finite) = (0usize, 0usize);
    let corrupt = |got: usize, error: hound::Error| WavErrorKind::Corrupt {
        got,
        expected,
        error,
    };
    match spec.sample_format {
        hound::SampleFormat::Int => {
            if !(1..=32).contains(&spec.bits_per_sample) {
                return Err(WavErrorKind::IntWidth(spec.bits_per_sample));
            }
            match int_layout(&spec, fmt)? {
                IntLayout::Hound => {
                    let scale = 1.0 / (1u64 << (spec.bits_per_sample - 1)) as f64;
                    for s in reader.samples::<i32>() {
                        let v = s.map_err(|e| corrupt(inter.len(), e))?;
                        inter.push((f64::from(v) * scale) as f32);
                    }
                }
                IntLayout::LeftAligned { bytes, valid } => {
                    // hound has read the header up to the data; it cannot
                    // give the raw containers, so they are read here
                    let mut r = reader.into_inner();
                    read_left_aligned(&mut r, bytes, valid, expected, &mut inter)?;
                }
            }
        }
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                return Err(WavErrorKind::FloatWidth(spec.bits_per_sample));
            }
            for s in reader.samples::<f32>() {
                let v = s.map_err(|e| corrupt(inter.len(), e))?;
                // over-full-scale values clamped (and counted), as the S16
                // conversion does: the mixdown's sum of huge samples stays
                // finite
                inter.push(if !v.is_finite() {
                    non_finite += 1;
                    0.0
                } else if v.abs() > 1.0 {
                    clamped += 1;
                    v.clamp(-1.0, 1.0)
                } else {
                    v
                });
            }
        }
    }
    if inter.len() < expected {
        return Err(WavErrorKind::Truncated {
            got: inter.len(),
            expected,
        });
    }
    let samples = match channel {
        _ if ch == 1 => inter,
        Channel::Average => inter
            .chunks_exact(usize::from(ch))
            .map(|f| f.iter().sum::<f32>() / f32::from(ch))
            .collect(),
        Channel::One(c) => inter
            .chunks_exact(usize::from(ch))
            .map(|f| f[usize::from(c)])
            .collect(),
    };
    Ok(Audio {
        sample_rate: spec.sample_rate,
        samples,
        file_rate: spec.sample_rate,
        file_channels: ch,
        clamped,
        non_finite,
        data_declared: None,
    })
}

/// Writes 16-bit mono PCM at `rate`, clamping samples to [−1, 1].
pub fn write_mono_i16(path: &Path, rate: u32, samples: &[f32]) -> Result<(), WavError> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w =
        hound::WavWriter::create(path, spec).map_err(|e| WavErrorKind::Create(e).at(path))?;
    for &s in samples {
        let v = (f64::from(s).clamp(-1.0, 1.0) * 32767.0).round() as i16;
        w.write_sample(v)
            .map_err(|e| WavErrorKind::Write(e).at(path))?;
    }
    w.finalize().map_err(|e| WavErrorKind::Write(e).at(path))
}

/// Band-limited resampling from `from` Hz to `to` Hz (windowed sinc,
/// Blackman window, 32 zero crossings, cut-off 0.95 of the lower Nyquist
/// frequency): each output sample is
/// `Σ_k x[k] · c · sinc(c (u − k)) · w((u − k)/W)` at input position
/// u = n · from/to, with cut-off c = 0.95 · min(1, to/from) (of the input
/// Nyquist), Blackman window w over |u − k| < W = 32/c. Returns `x`
/// unchanged when the rates are equal, either is 0, or `x` is empty.
/// Allocates its output: offline and start-up use only.
pub fn resample(x: &[f32], from: u32, to: u32) -> Vec<f32> {
    if from == to || x.is_empty() || from == 0 || to == 0 {
        return x.to_vec();
    }
    let ratio = f64::from(from) / f64::from(to);
    let c = 0.95 * (1.0 / ratio).min(1.0);
    let half = 32.0 / c;
    let n_out = (x.len() as u64 * u64::from(to) / u64::from(from)) as usize;
    let pi = std::f64::consts::PI;
    (0..n_out)
        .map(|n| {
            let u = n as f64 * ratio;
            let k0 = (u - half).ceil().max(0.0) as usize;
            let k1 = ((u + half).floor() as usize).min(x.len() - 1);
            let mut acc = 0.0;
            for (k, &xk) in x.iter().enumerate().take(k1 + 1).skip(k0) {
                let d = u - k as f64;
                let s = if d.abs() < 1e-12 {
                    1.0
                } else {
                    (pi * c * d).sin() / (pi * c * d)
                };
                let t = d / half; // in (−1, 1)
                let w = 0.42 + 0.5 * (pi * t).cos() + 0.08 * (2.0 * pi * t).cos();
                acc += f64::from(xk) * c * s * w;
            }
            acc as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(rate: u32, f: f64, secs: f64) -> Vec<f32> {
        (0..(f64::from(rate) * secs) as usize)
            .map(|n| {
                (0.5 * (2.0 * std::f64::consts::PI * f * n as f64 / f64::from(rate)).sin()) as f32
            })
            .collect()
    }

    fn write_spec<S: hound::Sample + Copy>(p: &Path, spec: hound::WavSpec, samples: &[S]) {
        let mut w = hound::WavWriter::create(p, spec).unwrap();
        for &s in samples {
            w.write_sample(s).unwrap();
        }
        w.finalize().unwrap();
    }

    fn spec(channels: u16, rate: u32, bits: u16, float: bool) -> hound::WavSpec {
        hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: bits,
            sample_format: if float {
                hound::SampleFormat::Float
            } else {
                hound::SampleFormat::Int
            },
        }
    }

    #[test]
    fn round_trip_16_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.wav");
        let x = tone(44_100, 440.0, 0.1);
        write_mono_i16(&p, 44_100, &x).unwrap();
        let a = read_mono(&p).unwrap();
        assert_eq!(
            (a.sample_rate, a.file_rate, a.file_channels),
            (44_100, 44_100, 1)
        );
        assert_eq!(a.samples.len(), x.len());
        for (u, v) in a.samples.iter().zip(&x) {
            assert!((u - v).abs() < 1.0 / 32_000.0);
        }
        // the same bytes decoded in memory give the same audio
        let b = decode_mono(&std::fs::read(&p).unwrap(), &p).unwrap();
        assert_eq!(a, b);
        assert!((a.duration_s() - 0.1).abs() < 1e-4);
    }

    #[test]
    fn writing_clamps_to_full_scale() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.wav");
        write_mono_i16(&p, 8000, &[2.0, -2.0, 0.5]).unwrap();
        let raw: Vec<i16> = hound::WavReader::open(&p)
            .unwrap()
            .samples::<i16>()
            .map(Result::unwrap)
            .collect();
        assert_eq!(raw, [32767, -32767, 16384]);
    }

    #[test]
    fn stereo_is_mixed_down() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.wav");
        let inter: Vec<i16> = (0..100i16).flat_map(|i| [i * 100, -i * 50]).collect();
        write_spec(&p, spec(2, 44_100, 16, false), &inter);
        let a = read_mono(&p).unwrap();
        assert_eq!(a.file_channels, 2);
        assert_eq!(a.samples.len(), 100);
        for (i, &s) in a.samples.iter().enumerate() {
            let expect = (i as f32 * 100.0 - i as f32 * 50.0) / 2.0 / 32_768.0;
            assert!((s - expect).abs() < 1e-6, "{i}: {s} vs {expect}");
        }
    }

    /// One channel of a stereo file, by number (0-based), read, decoded in
    /// memory and resampled alike; averaging a pair in opposite phase
    /// gives silence; a channel beyond the file's count is an error naming
    /// the file and its channel count.
    #[test]
    fn one_channel_is_taken_by_number() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("pair.wav");
        let inter: Vec<i16> = (0..100i16).flat_map(|i| [i * 100, -i * 100]).collect();
        write_spec(&p, spec(2, 8000, 16, false), &inter);
        let left = read_channel(&p, Channel::One(0)).unwrap();
        let right = decode_channel(&std::fs::read(&p).unwrap(), &p, Channel::One(1)).unwrap();
        assert_eq!(left.file_channels, 2);
        for (i, (l, r)) in left.samples.iter().zip(&right.samples).enumerate() {
            assert_eq!(
                (*l, *r),
                (i as f32 * 100.0 / 32768.0, -(i as f32) * 100.0 / 32768.0)
            );
        }
        assert!(read_mono(&p).unwrap().samples.iter().all(|&v| v == 0.0));
        let up = read_channel_at(&p, 16_000, Channel::One(0)).unwrap();
        assert_eq!((up.sample_rate, up.samples.len()), (16_000, 200));
        let e = read_channel(&p, Channel::One(2)).unwrap_err().to_string();
        assert!(
            e.contains("pair.wav") && e.contains("has 2 channel(s)") && e.contains("channel 2"),
            "{e}"
        );
    }

    #[test]
    fn integer_widths_scale_to_unit_range_and_non_finite_floats_read_as_zero() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("w24.wav");
        write_spec(&p, spec(1, 8000, 24, false), &[-(1i32 << 23), 1 << 22, 0]);
        assert_eq!(read_mono(&p).unwrap().samples, [-1.0, 0.5, 0.0]);
        let p = dir.path().join("w8.wav");
        write_spec(&p, spec(1, 8000, 8, false), &[-128i8, 64, 127]);
        assert_eq!(read_mono(&p).unwrap().samples, [-1.0, 0.5, 127.0 / 128.0]);
        let p = dir.path().join("nan.wav");
        write_spec(
            &p,
            spec(1, 8000, 32, true),
            &[0.25f32, f32::NAN, f32::INFINITY, -0.5],
        );
        assert_eq!(read_mono(&p).unwrap().samples, [0.25, 0.0, 0.0, -0.5]);
    }

    /// Found by fuzzing (fuzz/README.md): a float file's samples beyond
    /// full scale came through as read (2.96 from the fuzzer's file), and
    /// the stereo mixdown of two samples near `f32::MAX` summed to +∞,
    /// although decoded audio is documented finite and in [−1, 1].
    #[test]
    fn float_samples_beyond_full_scale_are_clamped_and_the_mixdown_stays_finite() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("over.wav");
        write_spec(&p, spec(1, 16000, 32, true), &[2.964_591f32, -7.0, 0.5]);
        assert_eq!(read_mono(&p).unwrap().samples, [1.0, -1.0, 0.5]);
        let p = dir.path().join("max.wav");
        write_spec(
            &p,
            spec(2, 16000, 32, true),
            &[f32::MAX, f32::MAX, -f32::MAX, 0.0],
        );
        assert_eq!(read_mono(&p).unwrap().samples, [1.0, -0.5]);
    }

    #[test]
    fn other_rate_is_resampled() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.wav");
        write_spec(&p, spec(1, 48_000, 32, true), &tone(48_000, 1000.0, 0.5));
        let a = read_mono_at(&p, 44_100).unwrap();
        assert_eq!((a.sample_rate, a.file_rate), (44_100, 48_000));
        assert_eq!(a.samples.len(), 22_050);
        // Compare with the ideal 1 kHz tone at 44.1 kHz away from the edges.
        let ideal = tone(44_100, 1000.0, 0.5);
        let err = a.samples[2000..20_000]
            .iter()
            .zip(&ideal[2000..20_000])
            .map(|(u, v)| (u - v).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 0.01, "max error {err}");
        let e = read_mono_at(&p, 0).unwrap_err();
        assert!(matches!(e.kind, WavErrorKind::ZeroTargetRate), "{e}");
    }

    /// A header claiming a rate of a few Hz is refused by name, not
    /// resampled into a buffer the size of the ratio (1 Hz to 48 kHz: 48 000
    /// samples out per sample in).
    #[test]
    fn a_rate_far_below_the_target_is_refused_not_upsampled() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("one_hertz.wav");
        write_mono_i16(&p, 1, &[0.1; 1000]).unwrap();
        let e = read_mono_at(&p, 48_000).unwrap_err();
        assert!(
            matches!(
                e.kind,
                WavErrorKind::RateTooLow {
                    from: 1,
                    to: 48_000
                }
            ),
            "{e}"
        );
        let text = e.to_string();
        assert!(
            text.contains("one_hertz.wav") && text.contains("1 Hz"),
            "{text}"
        );
        // 8 kHz telephone audio still goes to 96 kHz
        let p = dir.path().join("phone.wav");
        write_mono_i16(&p, 8_000, &[0.1; 800]).unwrap();
        assert_eq!(read_mono_at(&p, 96_000).unwrap().samples.len(), 9_600);
    }

    #[test]
    fn downsampling_removes_content_above_the_new_nyquist() {
        let x = tone(44_100, 15_000.0, 0.5);
        let y = resample(&x, 44_100, 16_000);
        let rms = (y[1000..7000].iter().map(|v| v * v).sum::<f32>() / 6000.0).sqrt();
        assert!(rms < 0.01, "15 kHz leaked into 16 kHz output: rms {rms}");
        assert_eq!(resample(&x[..10], 44_100, 44_100), x[..10]);
        assert_eq!(resample(&x[..10], 44_100, 0), x[..10]);
    }

    /// `header` reads rate, channels and frames; an unset data size counts
    /// what the file holds; a non-WAV file is named.
    #[test]
    fn the_header_gives_rate_channels_and_frames_without_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.wav");
        write_mono_i16(&p, 22050, &vec![0.25; 4410]).unwrap();
        let h = header(&p).unwrap();
        assert_eq!((h.sample_rate, h.channels, h.frames), (22050, 1, 4410));
        assert!((h.duration_s() - 0.2).abs() < 1e-12);
        // an unfinalised recording (data size 0): the frames that are there
        let mut b = std::fs::read(&p).unwrap();
        let d = b.windows(4).position(|w| w == b"data").unwrap();
        b[d + 4..d + 8].copy_from_slice(&0u32.to_le_bytes());
        std::fs::write(&p, &b).unwrap();
        assert_eq!(header(&p).unwrap().frames, 4410);
        // not a WAV file: named
        std::fs::write(&p, b"hello").unwrap();
        let e = header(&p).unwrap_err().to_string();
        assert!(e.contains("a.wav"), "{e}");
    }

    /// The fmt chunk is found behind an odd-length chunk and its pad byte.
    #[test]
    fn the_chunk_walk_honours_pad_bytes() {
        let mut f = b"RIFF\0\0\0\0WAVEodd \x03\0\0\0abc\0".to_vec();
        f.extend_from_slice(b"fmt \x28\0\0\0\xfe\xff\x02\0");
        f.extend_from_slice(&[
            0x80, 0xbb, 0, 0, 0, 0xee, 0x02, 0, 8, 0, 32, 0, 22, 0, 24, 0,
        ]);
        f.extend_from_slice(&[0; 20]);
        let fmt = find_fmt(&mut std::io::Cursor::new(&f)).unwrap();
        assert_eq!(
            (fmt.tag, fmt.channels, fmt.block_align, fmt.valid_bits),
            (TAG_EXTENSIBLE, 2, 8, Some(24))
        );
        // no pad byte: the walk misses the fmt chunk and says nothing
        let mut g = f.clone();
        g.remove(23);
        assert!(find_fmt(&mut std::io::Cursor::new(&g)).is_none());
    }

    #[test]
    fn map_converts_samples_and_keeps_the_rates() {
        let a = Audio {
            sample_rate: 8000,
            samples: vec![0.5f32, -1.0],
            file_rate: 16_000,
            file_channels: 2,
            clamped: 0,
            non_finite: 0,
            data_declared: None,
        };
        let b = a.map(|s| (s * 2.0) as i32);
        assert_eq!(b.samples, [1, -2]);
        assert_eq!(
            (b.sample_rate, b.file_rate, b.file_channels),
            (8000, 16_000, 2)
        );
    }

    #[test]
    fn every_refusal_names_the_file_and_the_reason() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cut.wav");
        write_mono_i16(&p, 44_100, &tone(44_100, 440.0, 0.1)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let whole = read_mono(&p).unwrap();
        assert_eq!(whole.data_declared, None);
        // a cut file: the whole sample frames it holds, read with a
        // warning (it was refused, "truncated", and a dataset with one
        // such file could not be trained on; found in a newcomer's trial)
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        let cut = read_mono(&p).unwrap();
        assert_eq!(cut.samples.len(), 2194);
        assert_eq!(cut.samples[..], whole.samples[..2194]);
        assert_eq!(cut.data_declared, Some(8820));
        // the same in memory
        let cut = decode_mono(&bytes[..bytes.len() / 2], &p).unwrap();
        assert_eq!((cut.samples.len(), cut.data_declared), (2194, Some(8820)));
        // a recording not finalised (lengths 0) and a streaming length
        // (0xFFFFFFFF): the samples that are there
        for (riff, data) in [(0u32, 0u32), (u32::MAX, u32::MAX)] {
            let mut b = bytes.clone();
            b[4..8].copy_from_slice(&riff.to_le_bytes());
            b[40..44].copy_from_slice(&data.to_le_bytes());
            std::fs::write(&p, &b).unwrap();
            let a = read_mono(&p).unwrap_or_else(|e| panic!("{data:#x}: {e}"));
            assert_eq!(a.samples, whole.samples, "{data:#x}");
            assert_eq!(a.data_declared, Some(u64::from(data)));
            let m = decode_mono(&b, &p).unwrap();
            assert_eq!(
                (m.samples, m.data_declared),
                (whole.samples.clone(), Some(u64::from(data)))
            );
            assert_eq!(header(&p).unwrap().frames, 4410);
        }

        let q = dir.path().join("notes.wav");
        std::fs::write(&q, b"this is not audio at all, just text").unwrap();
        let e = read_mono(&q).unwrap_err().to_string();
        assert!(
            e.contains("notes.wav") && e.contains("not a valid WAV"),
            "{e}"
        );

        let e = read_mono(&dir.path().join("missing.wav"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("missing.wav") && e.contains("cannot open"),
            "{e}"
        );

        // headers patched in a valid 16-bit mono file: fmt chunk fields at
        // tag + 8 (format), + 10 (channels), + 12 (rate), + 22 (bits)
        let z = dir.path().join("valid.wav");
        write_mono_i16(&z, 8000, &[0.0; 4]).unwrap();
        let valid = std::fs::read(&z).unwrap();
        let fmt = valid.windows(4).position(|w| w == b"fmt ").unwrap();
        let patched = |at: usize, bytes: &[u8]| {
            let mut b = valid.clone();
            b[fmt + at..fmt + at + bytes.len()].copy_from_slice(bytes);
            b
        };
        // (hound refuses most of these itself; its reason is passed on)
        let cases = [
            ("zero_ch.wav", patched(10, &[0, 0]), "zero channels"),
            (
                "rate0.wav",
                patched(12, &[0, 0, 0, 0, 0, 0, 0, 0]),
                "sample rate 0 Hz",
            ),
            ("int40.wav", patched(22, &[40, 0]), "not a valid WAV file"),
            ("float16.wav", patched(8, &[3, 0]), "not 32"),
        ];
        for (name, bytes, reason) in cases {
            let e = decode_mono(&bytes, Path::new(name))
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with(&format!("WAV file {name}: ")) && e.contains(reason),
                "{e}"
            );
        }
        let e = write_mono_i16(&dir.path().join("no/such/dir.wav"), 8000, &[0.0]).unwrap_err();
        assert!(matches!(e.kind, WavErrorKind::Create(_)), "{e}");
        assert!(e.to_string().contains("dir.wav"), "{e}");
    }
}
