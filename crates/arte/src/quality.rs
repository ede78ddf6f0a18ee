//! [`AudioQuality`]: when audio is not fit to classify (the microphone's own
//! faults). One rule for the arte service, which judges each live block
//! before classifying it, and for `grip train`, `grip classify`, `grip
//! dataset delay` and `grip calibrate`, which judge the frames and blocks
//! of recordings by it and leave out what the service would refuse.

/// When a block of audio is not fit to classify: the microphone's own
/// faults. The features are gain-invariant by design (`crates/arte`), so
/// digital silence (a cut cable, a muted input, a stereo pair in opposite
/// phase averaged to mono) still gives a confident class; a clipped input
/// adds harmonics the model never saw; after a capture overrun the samples
/// have holes the frame would straddle. The arte service gives such a
/// block one estimate with `class_index = NO_CLASS` and confidence 0
/// instead of the classifier's, and the estimator restarts at the next
/// good block (no frame or smoothing state carries the bad audio over).
/// tcs-loop then falls back to its no-ARTE behaviour (immediately without
/// the road knowledge, by age with it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AudioQuality {
    /// A block whose RMS is below this (full scale = 1) is silent.
    pub silence_rms: f64,
    /// A block with more than this share of its samples at full scale
    /// (|s| ≥ 32767 in S16, |x| ≥ 32767/32768 as a float) is clipped.
    pub clip_share: f64,
    /// Blocks for this long (by their stamps) after one that reports a new
    /// overrun are not trusted either: a storm of overruns keeps the audio
    /// untrusted instead of yielding estimates between the holes, ns.
    pub xrun_hold_ns: u64,
}

impl Default for AudioQuality {
    /// −80 dBFS (a 16-bit converter's own noise floor is about −90 dBFS; road
    /// noise at the microphone is tens of dB above it), half the samples
    /// clipped (the clean synthetic stone sound of the tests has blocks with
    /// more than a quarter of their samples at full scale), 0.5 s.
    fn default() -> Self {
        Self {
            silence_rms: 1e-4,
            clip_share: 0.5,
            xrun_hold_ns: 500_000_000,
        }
    }
}

/// Why a block was not classified ([`AudioQuality`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadAudio {
    /// Silent.
    Silence,
    /// Clipped.
    Clipping,
    /// A new overrun, or within the hold after one.
    Xrun,
}

impl BadAudio {
    /// Every reason, in the order reports list them.
    pub const ALL: [Self; 3] = [Self::Silence, Self::Clipping, Self::Xrun];

    /// The reason in a word: `silence`, `clipping`, `xrun`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Silence => "silence",
            Self::Clipping => "clipping",
            Self::Xrun => "xrun",
        }
    }
}

impl std::fmt::Display for BadAudio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Full scale of a sample as a float (S16 32767 over 32768): a sample at
/// or beyond it in magnitude is clipped.
const FULL_SCALE: f64 = 32767.0 / 32768.0;

impl AudioQuality {
    /// Judges `x` (S16 samples, as the service receives them); `xrun` =
    /// the block reports a new overrun or lies within the hold after one.
    /// Allocation-free.
    pub fn judge(&self, x: &[i16], xrun: bool) -> Option<BadAudio> {
        if xrun {
            return Some(BadAudio::Xrun);
        }
        self.judge_levels(x.iter().map(|&v| f64::from(v) / 32768.0), x.len())
    }

    /// Judges `x` (float samples in [−1, 1], as `grip_io::wav` decodes a
    /// file) by the same rule as [`Self::judge`]: a 16-bit recording gets
    /// the verdict its S16 samples would get live. Offline audio has no
    /// overruns. Allocation-free.
    pub fn judge_f32(&self, x: &[f32]) -> Option<BadAudio> {
        self.judge_levels(x.iter().map(|&v| f64::from(v)), x.len())
    }

    /// The rule over `n` samples given as levels (full scale = 1).
    fn judge_levels(&self, x: impl Iterator<Item = f64>, n: usize) -> Option<BadAudio> {
        if n == 0 {
            return None;
        }
        let (mut sq, mut clipped) = (0.0f64, 0usize);
        for f in x {
            sq += f * f;
            clipped += usize::from(f.abs() >= FULL_SCALE);
        }
        let rms = (sq / n as f64).sqrt();
        if rms < self.silence_rms {
            Some(BadAudio::Silence)
        } else if clipped as f64 > self.clip_share * n as f64 {
            Some(BadAudio::Clipping)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The S16 and the float reading of a 16-bit recording get the same
    /// verdict, at the thresholds too.
    #[test]
    fn s16_and_float_samples_are_judged_alike() {
        let q = AudioQuality::default();
        let as_f32 = |x: &[i16]| {
            x.iter()
                .map(|&v| f32::from(v) / 32768.0)
                .collect::<Vec<_>>()
        };
        let cases: Vec<(Vec<i16>, Option<BadAudio>)> = vec![
            (vec![0; 1024], Some(BadAudio::Silence)),
            (vec![3; 1024], Some(BadAudio::Silence)),
            (vec![4; 1024], None),
            (
                (0..1024).map(|i| [i16::MAX, -i16::MAX][i % 2]).collect(),
                Some(BadAudio::Clipping),
            ),
            (
                (0..1024)
                    .map(|i| if i < 513 { i16::MIN } else { 1000 })
                    .collect(),
                Some(BadAudio::Clipping),
            ),
            (
                (0..1024)
                    .map(|i| if i < 512 { i16::MAX } else { 1000 })
                    .collect(),
                None,
            ),
            (
                (0..1024)
                    .map(|i| if i % 2 == 0 { 32766 } else { -32766 })
                    .collect(),
                None,
            ),
            (vec![], None),
        ];
        for (x, want) in cases {
            assert_eq!(q.judge(&x, false), want, "{:?}", &x[..x.len().min(4)]);
            assert_eq!(q.judge_f32(&as_f32(&x)), want, "{:?}", &x[..x.len().min(4)]);
        }
        assert_eq!(q.judge(&[1000; 8], true), Some(BadAudio::Xrun));
        assert_eq!(BadAudio::Clipping.to_string(), "clipping");
    }
}
