//! The WAV file source: the whole file is read at start-up (hound), mixed
//! down to mono, resampled to the configured rate, converted to S16; the
//! loop then only copies, paced in real time by [`Pacer`].
//!
//! Reading follows `tools/grip/src/wav.rs` (same mixdown and the same
//! windowed-sinc resampler), with `thiserror` errors naming the file.

use std::path::{Path, PathBuf};

use grip_io::clock::Clock;

use crate::AcqError;
use crate::source::{Pacer, Read, Source, SourceStats, f32_to_i16};

/// Why a WAV file could not be used.
#[derive(Debug, thiserror::Error)]
#[error("WAV file {}: {reason}", path.display())]
pub struct WavError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub reason: String,
}

/// Mono audio read from a file, at the rate asked for.
#[derive(Debug, Clone)]
pub struct MonoAudio {
    /// Samples, S16.
    pub samples: Vec<i16>,
    /// The file's own rate, Hz.
    pub file_rate: u32,
    /// The file's channel count (mixed down by averaging).
    pub file_channels: u16,
}

/// Reads `path` as mono S16 at `rate` Hz (mixdown by averaging; resampled
/// if the file has another rate). Integer PCM of 1..=32 bits and 32-bit
/// float are accepted. An empty file is an error.
pub fn read_mono_i16(path: &Path, rate: u32) -> Result<MonoAudio, WavError> {
    let err = |reason: String| WavError {
        path: path.to_owned(),
        reason,
    };
    let mut reader = hound::WavReader::open(path).map_err(|e| {
        err(match e {
            hound::Error::IoError(io) => format!("cannot open: {io}"),
            hound::Error::FormatError(m) => format!("not a valid WAV file: {m}"),
            other => format!("not a readable WAV file: {other}"),
        })
    })?;
    let spec = reader.spec();
    let ch = spec.channels;
    if ch == 0 {
        return Err(err("header says 0 channels".into()));
    }
    if spec.sample_rate == 0 {
        return Err(err("header says sample rate 0 Hz".into()));
    }
    let expected = reader.len() as usize;
    let mut inter: Vec<f32> = Vec::with_capacity(expected);
    match spec.sample_format {
        hound::SampleFormat::Int => {
            if !(1..=32).contains(&spec.bits_per_sample) {
                return Err(err(format!(
                    "unsupported PCM sample width {} bits",
                    spec.bits_per_sample
                )));
            }
            let scale = 1.0 / (1u64 << (spec.bits_per_sample - 1)) as f64;
            for s in reader.samples::<i32>() {
                let v = s.map_err(|e| {
                    err(format!(
                        "truncated or corrupt after {} of {expected} samples: {e}",
                        inter.len()
                    ))
                })?;
                inter.push((f64::from(v) * scale) as f32);
            }
        }
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                return Err(err(format!(
                    "unsupported float sample width {} bits (only 32)",
                    spec.bits_per_sample
                )));
            }
            for s in reader.samples::<f32>() {
                let v = s.map_err(|e| {
                    err(format!(
                        "truncated or corrupt after {} of {expected} samples: {e}",
                        inter.len()
                    ))
                })?;
                inter.push(if v.is_finite() { v } else { 0.0 });
            }
        }
    }
    if inter.len() < expected {
        return Err(err(format!(
            "truncated: {} of {expected} samples present",
            inter.len()
        )));
    }
    let mono: Vec<f32> = if ch == 1 {
        inter
    } else {
        inter
            .chunks_exact(usize::from(ch))
            .map(|f| f.iter().sum::<f32>() / f32::from(ch))
            .collect()
    };
    let mono = if spec.sample_rate != rate {
        resample(&mono, spec.sample_rate, rate)
    } else {
        mono
    };
    if mono.is_empty() {
        return Err(err("has no samples".into()));
    }
    Ok(MonoAudio {
        samples: mono.into_iter().map(f32_to_i16).collect(),
        file_rate: spec.sample_rate,
        file_channels: ch,
    })
}

/// Band-limited resampling from `from` Hz to `to` Hz (windowed sinc,
/// Blackman window, 32 zero crossings, cut-off 0.95 of the lower Nyquist
/// frequency); identical to `grip`'s `wav::resample`. Start-up only.
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
                let t = d / half;
                let w = 0.42 + 0.5 * (pi * t).cos() + 0.08 * (2.0 * pi * t).cos();
                acc += f64::from(xk) * c * s * w;
            }
            acc as f32
        })
        .collect()
}

/// Plays samples in memory, once or looped, paced in real time.
#[derive(Debug)]
pub struct WavSource<C: Clock> {
    samples: Vec<i16>,
    pos: usize,
    looped: bool,
    rate: u32,
    pacer: Pacer<C>,
}

impl<C: Clock> WavSource<C> {
    /// A source over `samples` at `rate` Hz. `max_lag_ns`: see [`Pacer`].
    pub fn new(samples: Vec<i16>, rate: u32, looped: bool, clock: C, max_lag_ns: u64) -> Self {
        Self {
            samples,
            pos: 0,
            looped,
            rate,
            pacer: Pacer::new(clock, rate, max_lag_ns),
        }
    }
}

impl<C: Clock> Source for WavSource<C> {
    fn sample_rate(&self) -> u32 {
        self.rate
    }

    fn read(&mut self, out: &mut [i16]) -> Result<Read, AcqError> {
        if self.samples.is_empty() || (!self.looped && self.pos >= self.samples.len()) {
            return Ok(Read::End);
        }
        let mut n = 0;
        while n < out.len() {
            if self.pos >= self.samples.len() {
                if self.looped {
                    self.pos = 0;
                } else {
                    break;
                }
            }
            let k = (out.len() - n).min(self.samples.len() - self.pos);
            out[n..n + k].copy_from_slice(&self.samples[self.pos..self.pos + k]);
            n += k;
            self.pos += k;
        }
        let stamp_ns = self.pacer.wait_block(n);
        Ok(Read::Block { n, stamp_ns })
    }

    fn stats(&self) -> SourceStats {
        SourceStats {
            xruns: self.pacer.resyncs(),
            ..SourceStats::default()
        }
    }
}
