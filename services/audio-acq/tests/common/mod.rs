//! A fake capture device for every sample format audio-acq reads, shared
//! by `sources.rs` and `no_alloc.rs`.

use grip_audio_acq::alsa_src::CaptureDevice;
use grip_audio_acq::format::SampleFormat;

/// The S16 value of frame `i`, channel `ch` that [`FormatFake`] encodes: a
/// ramp over the whole S16 range (both extremes included), different per
/// channel.
pub fn expected(i: u64, ch: usize) -> i16 {
    let v = (i.wrapping_mul(797) + ch as u64 * 20_011) % 65_536;
    (v as i64 - 32_768) as i16
}

/// Writes `v` in `fmt` into `out` (`fmt.bytes()` long), with low bits and
/// padding that the conversion to S16 must drop (`junk`).
pub fn encode(fmt: SampleFormat, v: i16, junk: u8, out: &mut [u8]) {
    let w = i32::from(v);
    match fmt {
        SampleFormat::S16Le => out.copy_from_slice(&v.to_le_bytes()),
        SampleFormat::S32Le => {
            out.copy_from_slice(&(w << 16 | i32::from(junk) << 8 | i32::from(junk)).to_le_bytes())
        }
        SampleFormat::S24_3Le => {
            out.copy_from_slice(&(w << 8 | i32::from(junk)).to_le_bytes()[..3])
        }
        SampleFormat::S24Le => {
            // 24 bits low-aligned; the top byte is padding (junk here)
            let low = (w << 8 | i32::from(junk)) as u32 & 0x00FF_FFFF;
            out.copy_from_slice(&(low | u32::from(junk) << 24).to_le_bytes())
        }
        SampleFormat::FloatLe => out.copy_from_slice(&(f32::from(v) / 32_768.0).to_le_bytes()),
    }
}

/// Delivers [`expected`] in `format`, `channels` per frame, at most `chunk`
/// frames per read; allocates nothing per read.
pub struct FormatFake {
    pub format: SampleFormat,
    pub channels: usize,
    pub chunk: usize,
    pub next: u64,
}

impl CaptureDevice for FormatFake {
    fn format(&self) -> SampleFormat {
        self.format
    }
    fn wait(&mut self, _timeout_ms: u32) -> Result<bool, alsa::Error> {
        Ok(true)
    }
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, alsa::Error> {
        let b = self.format.bytes();
        let frames = (buf.len() / (b * self.channels)).min(self.chunk);
        for f in buf.chunks_exact_mut(b * self.channels).take(frames) {
            for (ch, s) in f.chunks_exact_mut(b).enumerate() {
                let junk = (self.next as u8).wrapping_mul(37) | 1;
                encode(self.format, expected(self.next, ch), junk, s);
            }
            self.next += 1;
        }
        Ok(frames)
    }
    fn recover(&mut self, _e: alsa::Error) -> Result<(), alsa::Error> {
        Ok(())
    }
    fn timing(&mut self) -> Option<(u64, i64)> {
        None
    }
}
