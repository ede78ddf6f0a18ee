//! The capture sample formats audio-acq reads from ALSA, the `[alsa]
//! format` setting that chooses among them, and their conversion to the
//! pipeline's mono S16 samples.
//!
//! | format | bytes | what it is | to S16 |
//! |---|---|---|---|
//! | `S16_LE` | 2 | signed 16 bit | as is |
//! | `S32_LE` | 4 | signed 32 bit | the upper 16 bits (`x >> 16`, rounds down) |
//! | `S24_3LE` | 3 | signed 24 bit, packed in 3 bytes | the upper 16 of the 24 bits |
//! | `S24_LE` | 4 | signed 24 bit in the low 3 bytes of 32 (the top byte is padding and ignored) | sign-extended, then the upper 16 of the 24 bits |
//! | `FLOAT_LE` | 4 | IEEE 754 single, full scale ±1.0 | `round(x · 32768)`, clamped to −32768..=32767 (values beyond ±1.0 saturate; NaN → 0) |
//!
//! The integer conversions drop the low bits (no rounding, no dither), as
//! alsa-lib's own linear conversion does, so they give the samples a
//! `plughw:` device converting to S16_LE would give; the float scale,
//! 32768, is alsa-lib's too (S16 → FLOAT → S16 is exact), rounded to
//! nearest. Every conversion is a pure function of the sample's bytes: no
//! allocation, no panic, on any input.

use serde::{Deserialize, Serialize};

/// A capture sample format audio-acq can read (little-endian, signed or
/// float; what USB and automotive codecs commonly offer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SampleFormat {
    /// Signed 16 bit.
    S16Le,
    /// Signed 32 bit.
    S32Le,
    /// Signed 24 bit packed in 3 bytes.
    S24_3Le,
    /// Signed 24 bit in the low 3 bytes of a 4-byte word.
    S24Le,
    /// 32-bit float, full scale ±1.0.
    FloatLe,
}

impl SampleFormat {
    /// The order `format = "auto"` tries them in: S16_LE first (no
    /// conversion, and what audio-acq always used), then the wider integer
    /// formats, float last.
    pub const PREFERENCE: [SampleFormat; 5] = [
        SampleFormat::S16Le,
        SampleFormat::S32Le,
        SampleFormat::S24_3Le,
        SampleFormat::S24Le,
        SampleFormat::FloatLe,
    ];

    /// ALSA's name (`S16_LE`, `S24_3LE`, ...).
    pub fn name(self) -> &'static str {
        match self {
            SampleFormat::S16Le => "S16_LE",
            SampleFormat::S32Le => "S32_LE",
            SampleFormat::S24_3Le => "S24_3LE",
            SampleFormat::S24Le => "S24_LE",
            SampleFormat::FloatLe => "FLOAT_LE",
        }
    }

    /// Bytes one sample takes in an interleaved buffer.
    pub fn bytes(self) -> usize {
        match self {
            SampleFormat::S16Le => 2,
            SampleFormat::S24_3Le => 3,
            SampleFormat::S32Le | SampleFormat::S24Le | SampleFormat::FloatLe => 4,
        }
    }

    /// The `alsa` crate's value.
    pub fn alsa(self) -> alsa::pcm::Format {
        use alsa::pcm::Format;
        match self {
            SampleFormat::S16Le => Format::S16LE,
            SampleFormat::S32Le => Format::S32LE,
            SampleFormat::S24_3Le => Format::S243LE,
            SampleFormat::S24Le => Format::S24LE,
            SampleFormat::FloatLe => Format::FloatLE,
        }
    }
}

impl std::fmt::Display for SampleFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `[alsa] format`: `"auto"` (the first of [`SampleFormat::PREFERENCE`]
/// the device offers) or one format, which the device must offer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum FormatSetting {
    /// The first of S16_LE, S32_LE, S24_3LE, S24_LE, FLOAT_LE the device offers.
    #[default]
    #[serde(rename = "auto")]
    Auto,
    /// S16_LE.
    #[serde(rename = "S16_LE")]
    S16Le,
    /// S32_LE.
    #[serde(rename = "S32_LE")]
    S32Le,
    /// S24_3LE.
    #[serde(rename = "S24_3LE")]
    S24_3Le,
    /// S24_LE.
    #[serde(rename = "S24_LE")]
    S24Le,
    /// FLOAT_LE.
    #[serde(rename = "FLOAT_LE")]
    FloatLe,
}

impl FormatSetting {
    /// The one format asked for, or `None` for `"auto"`.
    pub fn fixed(self) -> Option<SampleFormat> {
        match self {
            FormatSetting::Auto => None,
            FormatSetting::S16Le => Some(SampleFormat::S16Le),
            FormatSetting::S32Le => Some(SampleFormat::S32Le),
            FormatSetting::S24_3Le => Some(SampleFormat::S24_3Le),
            FormatSetting::S24Le => Some(SampleFormat::S24Le),
            FormatSetting::FloatLe => Some(SampleFormat::FloatLe),
        }
    }
}

/// S16_LE bytes to S16.
#[inline]
pub fn s16_from_s16_le(b: [u8; 2]) -> i16 {
    i16::from_le_bytes(b)
}

/// S32_LE bytes to S16: the upper 16 bits.
#[inline]
pub fn s16_from_s32_le(b: [u8; 4]) -> i16 {
    (i32::from_le_bytes(b) >> 16) as i16
}

/// S24_3LE bytes (24 bits packed) to S16: the upper 16 of the 24 bits.
#[inline]
pub fn s16_from_s24_3le(b: [u8; 3]) -> i16 {
    i16::from_le_bytes([b[1], b[2]])
}

/// S24_LE bytes (24 bits in the low 3 bytes of 32) to S16: the top byte is
/// ignored (drivers leave it zero or sign-extended), the 24 bits are
/// sign-extended and their upper 16 kept.
#[inline]
pub fn s16_from_s24_le(b: [u8; 4]) -> i16 {
    ((u32::from_le_bytes(b) << 8) as i32 >> 16) as i16
}

/// A float sample (full scale ±1.0) to S16: `round(x · 32768)` clamped to
/// −32768..=32767; NaN → 0.
#[inline]
pub fn s16_from_float(x: f32) -> i16 {
    let v = (f64::from(x) * 32768.0).round();
    if v.is_nan() {
        0
    } else {
        v.clamp(-32768.0, 32767.0) as i16
    }
}

/// FLOAT_LE bytes to S16 ([`s16_from_float`]).
#[inline]
pub fn s16_from_float_le(b: [u8; 4]) -> i16 {
    s16_from_float(f32::from_le_bytes(b))
}

#[inline]
fn pick<const N: usize>(
    raw: &[u8],
    channels: usize,
    channel: usize,
    out: &mut [i16],
    conv: impl Fn([u8; N]) -> i16,
) -> usize {
    let frame = N * channels;
    if channel >= channels {
        return 0;
    }
    let at = channel * N;
    let mut n = 0;
    for (o, f) in out.iter_mut().zip(raw.chunks_exact(frame)) {
        let mut b = [0u8; N];
        b.copy_from_slice(&f[at..at + N]);
        *o = conv(b);
        n += 1;
    }
    n
}

/// Converts channel `channel` of the interleaved frames in `raw` (format
/// `fmt`, `channels` per frame) into `out`, as many frames as both hold;
/// returns how many. Nothing (0) if `channel >= channels`. Allocates
/// nothing.
pub fn extract_channel(
    fmt: SampleFormat,
    raw: &[u8],
    channels: usize,
    channel: usize,
    out: &mut [i16],
) -> usize {
    match fmt {
        SampleFormat::S16Le => pick(raw, channels, channel, out, s16_from_s16_le),
        SampleFormat::S32Le => pick(raw, channels, channel, out, s16_from_s32_le),
        SampleFormat::S24_3Le => pick(raw, channels, channel, out, s16_from_s24_3le),
        SampleFormat::S24Le => pick(raw, channels, channel, out, s16_from_s24_le),
        SampleFormat::FloatLe => pick(raw, channels, channel, out, s16_from_float_le),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn s16_is_unchanged() {
        for v in [i16::MIN, -1, 0, 1, 12_345, i16::MAX] {
            assert_eq!(s16_from_s16_le(v.to_le_bytes()), v);
        }
    }

    #[test]
    fn s32_keeps_the_upper_16_bits() {
        let c = |v: i32| s16_from_s32_le(v.to_le_bytes());
        assert_eq!(c(i32::MIN), i16::MIN);
        assert_eq!(c(i32::MAX), i16::MAX);
        assert_eq!(c(0), 0);
        assert_eq!(c(0x0000_FFFF), 0, "low bits dropped");
        assert_eq!(c(-1), -1, "rounds down, like alsa-lib");
        assert_eq!(c(0x4000_0000), 16_384);
        assert_eq!(c(-0x4000_0000), -16_384);
        // every S16 value shifted up comes back exactly
        for v in [i16::MIN, -12_345, -1, 0, 1, 23_456, i16::MAX] {
            assert_eq!(c(i32::from(v) << 16 | 0xABCD), v);
        }
    }

    #[test]
    fn s24_3le_packed_to_s16() {
        let c = |v: i32| {
            let b = v.to_le_bytes();
            s16_from_s24_3le([b[0], b[1], b[2]])
        };
        assert_eq!(c(0x7F_FFFF), i16::MAX, "24-bit maximum");
        assert_eq!(c(-0x80_0000), i16::MIN, "24-bit minimum");
        assert_eq!(c(0), 0);
        assert_eq!(c(0xFF), 0, "low byte dropped");
        assert_eq!(c(-1), -1);
        assert_eq!(c(-0x40_0000), -16_384, "negative 24-bit");
        assert_eq!(c(0x40_0000), 16_384);
        assert_eq!(s16_from_s24_3le([0x00, 0x00, 0x80]), i16::MIN);
        assert_eq!(s16_from_s24_3le([0xFF, 0xFF, 0x7F]), i16::MAX);
    }

    #[test]
    fn s24_le_is_sign_extended_and_its_top_byte_ignored() {
        let c = |v: u32| s16_from_s24_le(v.to_le_bytes());
        assert_eq!(c(0x007F_FFFF), i16::MAX, "24-bit maximum 0x7FFFFF");
        assert_eq!(c(0x0080_0000), i16::MIN, "0x800000 is the 24-bit minimum");
        assert_eq!(c(0xFF80_0000), i16::MIN, "sign-extended the same");
        assert_eq!(c(0x00FF_FFFF), -1, "negative 24-bit, zero top byte");
        assert_eq!(c(0xFFFF_FFFF), -1, "negative 24-bit, sign-extended");
        assert_eq!(c(0x00C0_0000), -16_384, "negative 24-bit");
        assert_eq!(c(0xABC0_0000), -16_384, "garbage in the top byte ignored");
        assert_eq!(c(0x0040_0000), 16_384);
        assert_eq!(c(0x7F00_0000), 0, "only padding set");
        assert_eq!(c(0x0000_00FF), 0, "low byte dropped");
        // i32::MIN's low 24 bits are zero
        assert_eq!(s16_from_s24_le(i32::MIN.to_le_bytes()), 0);
    }

    #[test]
    fn float_scales_by_32768_and_saturates_beyond_full_scale() {
        let c = |x: f32| s16_from_float_le(x.to_le_bytes());
        assert_eq!(c(0.0), 0);
        assert_eq!(c(-0.0), 0);
        assert_eq!(c(0.5), 16_384);
        assert_eq!(c(-0.5), -16_384);
        assert_eq!(c(-1.0), i16::MIN);
        assert_eq!(c(1.0), i16::MAX, "+1.0 saturates at 32767");
        assert_eq!(c(1.5), i16::MAX, "beyond +1.0 clamped");
        assert_eq!(c(-7.0), i16::MIN, "beyond -1.0 clamped");
        assert_eq!(c(f32::MAX), i16::MAX);
        assert_eq!(c(f32::MIN), i16::MIN);
        assert_eq!(c(f32::INFINITY), i16::MAX);
        assert_eq!(c(f32::NEG_INFINITY), i16::MIN);
        assert_eq!(c(f32::NAN), 0);
        assert_eq!(c(1.0 / 32768.0), 1);
        assert_eq!(c(0.4 / 32768.0), 0, "rounded to nearest");
        // what alsa-lib's S16 -> FLOAT conversion makes comes back exactly
        for v in [i16::MIN, -12_345, -1, 0, 1, 23_456, i16::MAX] {
            assert_eq!(c(f32::from(v) / 32768.0), v);
        }
    }

    #[test]
    fn extract_channel_picks_one_channel_of_each_format() {
        // 3 frames, 2 channels: channel 0 = 1000·k, channel 1 = −1000·k − 1
        let vals = |ch: usize| -> Vec<i16> {
            (0..3)
                .map(|k| if ch == 0 { 1000 * k } else { -1000 * k - 1 })
                .collect()
        };
        for fmt in SampleFormat::PREFERENCE {
            let mut raw = Vec::new();
            for k in 0..3 {
                for ch in 0..2 {
                    let v = vals(ch)[k];
                    match fmt {
                        SampleFormat::S16Le => raw.extend_from_slice(&v.to_le_bytes()),
                        SampleFormat::S32Le => {
                            raw.extend_from_slice(&(i32::from(v) << 16 | 0x1234).to_le_bytes())
                        }
                        SampleFormat::S24_3Le => {
                            raw.extend_from_slice(&(i32::from(v) << 8 | 0x56).to_le_bytes()[..3])
                        }
                        SampleFormat::S24Le => {
                            let w = (i32::from(v) << 8 | 0x56) as u32 & 0x00FF_FFFF;
                            raw.extend_from_slice(&w.to_le_bytes())
                        }
                        SampleFormat::FloatLe => {
                            raw.extend_from_slice(&(f32::from(v) / 32768.0).to_le_bytes())
                        }
                    }
                }
            }
            assert_eq!(raw.len(), 3 * 2 * fmt.bytes(), "{fmt}");
            for ch in 0..2 {
                let mut out = [7i16; 4];
                assert_eq!(extract_channel(fmt, &raw, 2, ch, &mut out), 3, "{fmt}");
                assert_eq!(&out[..3], &vals(ch)[..], "{fmt} channel {ch}");
                assert_eq!(out[3], 7, "{fmt}: nothing written beyond the frames");
            }
            // a shorter output, a partial frame, a bad channel: no panic
            let mut out = [0i16; 2];
            assert_eq!(extract_channel(fmt, &raw, 2, 1, &mut out), 2);
            assert_eq!(
                extract_channel(fmt, &raw[..raw.len() - 1], 2, 0, &mut [0; 4]),
                2
            );
            assert_eq!(extract_channel(fmt, &raw, 2, 2, &mut [0; 4]), 0);
            assert_eq!(extract_channel(fmt, &raw, 0, 0, &mut [0; 4]), 0);
        }
    }

    #[test]
    fn names_sizes_and_settings() {
        let names: Vec<&str> = SampleFormat::PREFERENCE.iter().map(|f| f.name()).collect();
        assert_eq!(names, ["S16_LE", "S32_LE", "S24_3LE", "S24_LE", "FLOAT_LE"]);
        for f in SampleFormat::PREFERENCE {
            assert_eq!(f.alsa().to_string(), f.name(), "alsa crate agrees");
            assert_eq!(
                f.alsa().physical_width().unwrap() as usize,
                8 * f.bytes(),
                "{f}"
            );
        }
        assert_eq!(FormatSetting::default(), FormatSetting::Auto);
        assert_eq!(FormatSetting::Auto.fixed(), None);
        assert_eq!(FormatSetting::S24_3Le.fixed(), Some(SampleFormat::S24_3Le));
    }
}
