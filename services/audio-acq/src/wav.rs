//! The WAV file source: the whole file is read at start-up through
//! `grip_io::wav` (the one WAV reader of grip: mixdown to mono, windowed-sinc
//! resampling to the configured rate, errors naming the file), converted to
//! S16 here; the loop then only copies, paced in real time by [`Pacer`].

use std::path::Path;

use grip_io::clock::Clock;
pub use grip_io::wav::WavError;
use grip_io::wav::{Audio, WavErrorKind};

use crate::AcqError;
use crate::source::{Pacer, Read, Source, SourceStats, f32_to_i16};

/// Reads `path` as mono S16 at `rate` Hz: [`grip_io::wav::read_channel_at`]
/// (channel `channel`, or the average of all channels for `None`;
/// resampled if the file has another rate), then [`f32_to_i16`]. A file
/// without samples is an error (there is nothing to play).
pub fn read_mono_i16(path: &Path, rate: u32, channel: Option<u16>) -> Result<Audio<i16>, WavError> {
    let channel = channel.map_or(grip_io::wav::Channel::Average, grip_io::wav::Channel::One);
    let audio = grip_io::wav::read_channel_at(path, rate, channel)?;
    if audio.samples.is_empty() {
        return Err(WavErrorKind::NoSamples.at(path));
    }
    Ok(audio.map(f32_to_i16))
}

/// The warning for a file recorded at `file_rate` Hz played at `rate` Hz:
/// upsampled, it has nothing above `file_rate / 2`, where a model trained
/// at `rate` listens too (an 11 025 Hz recording played at 48 kHz was
/// classified as snow throughout, and nothing said why). `None` when the
/// file's rate is the rate or above it.
pub fn upsampled_note(path: &Path, file_rate: u32, rate: u32) -> Option<String> {
    (file_rate < rate).then(|| {
        format!(
            "WAV {}: recorded at {file_rate} Hz, played at audio-acq's {rate} Hz (upsampled): nothing above {} Hz is in it, where arte's model, trained at {rate} Hz, listens too; its estimates on this file mean little. Record at {rate} Hz or more",
            path.display(),
            file_rate / 2
        )
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A file below the service's rate is said to be upsampled, with the
    /// band it lacks; at or above the rate (downsampled: the band is
    /// there) nothing is said.
    #[test]
    fn an_upsampled_file_is_said() {
        let p = Path::new("gravel.wav");
        let w = upsampled_note(p, 11_025, 48_000).unwrap();
        assert!(
            w.starts_with("WAV gravel.wav: recorded at 11025 Hz, played at audio-acq's 48000 Hz (upsampled): nothing above 5512 Hz is in it"),
            "{w}"
        );
        assert_eq!(upsampled_note(p, 48_000, 48_000), None);
        assert_eq!(upsampled_note(p, 96_000, 48_000), None);
    }
}
