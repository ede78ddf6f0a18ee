//! WAV reading and writing for ARTE (hound), shared by `grip dataset`,
//! `grip features`, `grip train`, `grip classify` and the services' file
//! sources. The `grip-arte` crate stays free of file I/O; this is its edge.
//!
//! Reading:
//! - PCM integer (8, 16, 24, 32 bit) and 32-bit float files; integers are
//!   scaled to [−1, 1) by 2^(bits−1).
//! - Several channels are **mixed down** to mono by averaging.
//! - A file at another sample rate is **resampled** to the rate asked for
//!   (windowed-sinc, Blackman window, 32 zero crossings, cut-off at 0.95 of
//!   the lower Nyquist frequency) by [`read_mono_at`]; [`read_mono`] keeps
//!   the file's rate. The result records the original rate and channel count
//!   so callers can report it.
//! - A missing, truncated or non-WAV file is an error naming the file and
//!   the reason.
//!
//! Writing: [`write_mono_i16`] writes 16-bit mono PCM, clamping to [−1, 1].
// Each helper is used by some subcommands; not every binary target uses all.
#![allow(dead_code)]

use anyhow::{Context, Result, bail};
use std::path::Path;

/// Mono audio read from a file.
#[derive(Clone, Debug)]
pub struct Audio {
    /// Sample rate of `samples` (Hz).
    pub sample_rate: u32,
    /// Mono samples in [−1, 1].
    pub samples: Vec<f32>,
    /// The file's own sample rate.
    pub file_rate: u32,
    /// The file's channel count (mixed down to mono).
    pub file_channels: u16,
}

impl Audio {
    /// Duration (s).
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 / f64::from(self.sample_rate)
    }
}

/// Reads a WAV file as mono at its own sample rate.
pub fn read_mono(path: &Path) -> Result<Audio> {
    read_inner(path).with_context(|| format!("reading WAV file {}", path.display()))
}

/// Reads a WAV file as mono at `rate` Hz, resampling if the file has another rate.
pub fn read_mono_at(path: &Path, rate: u32) -> Result<Audio> {
    let mut a = read_mono(path)?;
    if a.sample_rate != rate {
        if rate == 0 {
            bail!("cannot resample {} to 0 Hz", path.display());
        }
        a.samples = resample(&a.samples, a.sample_rate, rate);
        a.sample_rate = rate;
    }
    Ok(a)
}

/// Decodes WAV file bytes already in memory (`grip train` hashes them
/// too), as mono at the file's own rate; errors as [`read_mono`]'s,
/// without the path (the caller adds it).
pub fn decode_mono(bytes: &[u8]) -> Result<Audio> {
    decode(hound::WavReader::new(std::io::Cursor::new(bytes)).map_err(open_error)?)
}

fn read_inner(path: &Path) -> Result<Audio> {
    decode(hound::WavReader::open(path).map_err(open_error)?)
}

fn open_error(e: hound::Error) -> anyhow::Error {
    match e {
        hound::Error::IoError(io) => anyhow::anyhow!("{io}"),
        hound::Error::FormatError(m) => anyhow::anyhow!("not a valid WAV file: {m}"),
        other => anyhow::anyhow!("not a readable WAV file: {other}"),
    }
}

fn decode<R: std::io::Read>(mut reader: hound::WavReader<R>) -> Result<Audio> {
    let spec = reader.spec();
    let ch = spec.channels;
    if ch == 0 {
        bail!("header says 0 channels");
    }
    if spec.sample_rate == 0 {
        bail!("header says sample rate 0 Hz");
    }
    let expected = reader.len() as usize;
    let mut inter: Vec<f32> = Vec::with_capacity(expected);
    let trunc = |got: usize, e: hound::Error| -> anyhow::Error {
        anyhow::anyhow!("truncated or corrupt after {got} of {expected} samples: {e}")
    };
    match spec.sample_format {
        hound::SampleFormat::Int => {
            if !(1..=32).contains(&spec.bits_per_sample) {
                bail!("unsupported PCM sample width {} bits", spec.bits_per_sample);
            }
            let scale = 1.0 / (1u64 << (spec.bits_per_sample - 1)) as f64;
            for s in reader.samples::<i32>() {
                let v = s.map_err(|e| trunc(inter.len(), e))?;
                inter.push((f64::from(v) * scale) as f32);
            }
        }
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                bail!(
                    "unsupported float sample width {} bits (only 32)",
                    spec.bits_per_sample
                );
            }
            for s in reader.samples::<f32>() {
                let v = s.map_err(|e| trunc(inter.len(), e))?;
                inter.push(if v.is_finite() { v } else { 0.0 });
            }
        }
    }
    if inter.len() < expected {
        bail!("truncated: {} of {} samples present", inter.len(), expected);
    }
    let samples = if ch == 1 {
        inter
    } else {
        inter
            .chunks_exact(usize::from(ch))
            .map(|f| f.iter().sum::<f32>() / f32::from(ch))
            .collect()
    };
    Ok(Audio {
        sample_rate: spec.sample_rate,
        samples,
        file_rate: spec.sample_rate,
        file_channels: ch,
    })
}

/// Writes 16-bit mono PCM at `rate`, clamping samples to [−1, 1].
pub fn write_mono_i16(path: &Path, rate: u32, samples: &[f32]) -> Result<()> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec)
        .with_context(|| format!("creating WAV file {}", path.display()))?;
    for &s in samples {
        let v = (f64::from(s).clamp(-1.0, 1.0) * 32767.0).round() as i16;
        w.write_sample(v)
            .with_context(|| format!("writing WAV file {}", path.display()))?;
    }
    w.finalize()
        .with_context(|| format!("finishing WAV file {}", path.display()))?;
    Ok(())
}

/// Band-limited resampling from `from` Hz to `to` Hz: each output sample is
/// Σ_k x[k] · c · sinc(c (u − k)) · w((u − k)/W) at input position
/// u = n · from/to, with cut-off c = 0.95 · min(1, to/from) (of the input
/// Nyquist), Blackman window w over |u − k| < W = 32/c.
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

    #[test]
    fn round_trip_16_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.wav");
        let x = tone(44_100, 440.0, 0.1);
        write_mono_i16(&p, 44_100, &x).unwrap();
        let a = read_mono(&p).unwrap();
        assert_eq!(a.sample_rate, 44_100);
        assert_eq!(a.samples.len(), x.len());
        for (u, v) in a.samples.iter().zip(&x) {
            assert!((u - v).abs() < 1.0 / 32_000.0);
        }
    }

    #[test]
    fn stereo_is_mixed_down() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 44_100,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(&p, spec).unwrap();
        for i in 0..100 {
            w.write_sample(i as i16 * 100).unwrap();
            w.write_sample(-(i as i16) * 50).unwrap();
        }
        w.finalize().unwrap();
        let a = read_mono(&p).unwrap();
        assert_eq!(a.file_channels, 2);
        assert_eq!(a.samples.len(), 100);
        for (i, &s) in a.samples.iter().enumerate() {
            let expect = (i as f32 * 100.0 - i as f32 * 50.0) / 2.0 / 32_768.0;
            assert!((s - expect).abs() < 1e-6, "{i}: {s} vs {expect}");
        }
    }

    #[test]
    fn other_rate_is_resampled() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.wav");
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: 48_000,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut w = hound::WavWriter::create(&p, spec).unwrap();
        for s in tone(48_000, 1000.0, 0.5) {
            w.write_sample(s).unwrap();
        }
        w.finalize().unwrap();
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
    }

    #[test]
    fn downsampling_removes_content_above_the_new_nyquist() {
        let x = tone(44_100, 15_000.0, 0.5);
        let y = resample(&x, 44_100, 16_000);
        let rms = (y[1000..7000].iter().map(|v| v * v).sum::<f32>() / 6000.0).sqrt();
        assert!(rms < 0.01, "15 kHz leaked into 16 kHz output: rms {rms}");
    }

    #[test]
    fn truncated_and_non_wav_files_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cut.wav");
        write_mono_i16(&p, 44_100, &tone(44_100, 440.0, 0.1)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        let e = format!("{:#}", read_mono(&p).unwrap_err());
        assert!(e.contains("cut.wav") && e.contains("truncated"), "{e}");
        let q = dir.path().join("notes.wav");
        std::fs::write(&q, b"this is not audio at all, just text").unwrap();
        let e = format!("{:#}", read_mono(&q).unwrap_err());
        assert!(
            e.contains("notes.wav") && e.contains("not a valid WAV"),
            "{e}"
        );
        let e = format!(
            "{:#}",
            read_mono(&dir.path().join("missing.wav")).unwrap_err()
        );
        assert!(e.contains("missing.wav"), "{e}");
    }
}
