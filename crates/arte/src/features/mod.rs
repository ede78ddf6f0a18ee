//! Acoustic features of one analysis frame (paper §II.C; the crate README, "Features").
//!
//! Three sets, chosen by [`FeatureConfig::set`]:
//! - [`FeatureSet::Paper20`]: 10 LPC, 5 power-spectrum and 5 real-cepstrum
//!   coefficients of the Hamming-windowed, band-pass pre-filtered frame.
//! - [`FeatureSet::Paper7`]: 7 of those 20 (by default 3 LPC + 2 PS + 2
//!   cepstrum), the indices chosen by [`crate::select`] on training data and
//!   stored in [`FeatureConfig::selection`].
//! - [`FeatureSet::Rich`]: 43 level-invariant features (log-mel spectral shape,
//!   within-frame band-energy variability, spectral descriptors, impact
//!   statistics), see `rich.rs` and the crate README for exact definitions.
//!
//! [`FeatureExtractor::new`] plans the FFTs and allocates every buffer once;
//! [`FeatureExtractor::extract`] allocates nothing.

mod fft;
pub mod lpc;
mod paper;
mod rich;

use serde::{Deserialize, Serialize};

pub use paper::real_cepstrum;

/// Which feature vector to compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FeatureSet {
    /// The paper's 20: `lpc_1..lpc_10`, `ps_1..ps_5`, `cep_1..cep_5`.
    Paper20,
    /// The paper's pruned 7: `FeatureConfig::selection` indices into Paper20.
    Paper7,
    /// This project's richer 43-feature set.
    Rich,
}

impl FeatureSet {
    /// Parses `paper20`, `paper7` or `rich` (case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "paper20" => Some(Self::Paper20),
            "paper7" => Some(Self::Paper7),
            "rich" => Some(Self::Rich),
            _ => None,
        }
    }

    /// The lower-case name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper20 => "paper20",
            Self::Paper7 => "paper7",
            Self::Rich => "rich",
        }
    }
}

/// Band-pass pre-filter of the paper sets (paper §II.B: "by a simple
/// band-pass or low-pass filtering, the noise data could be eliminated").
///
/// Applied in the frequency domain as the squared magnitude response of a
/// 2nd-order Butterworth high-pass at `highpass_hz` times a 4th-order
/// Butterworth low-pass at `lowpass_hz`:
/// |H(f)|² = 1/(1 + (f_hp/f)⁴) · 1/(1 + (f/f_lp)⁸).
/// `None` for either edge leaves that side open.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Prefilter {
    /// High-pass corner (Hz): removes engine harmonics and wind rumble.
    pub highpass_hz: Option<f64>,
    /// Low-pass corner (Hz): removes most rain hiss and droplet clicks.
    pub lowpass_hz: Option<f64>,
}

impl Prefilter {
    /// No pre-filtering.
    pub const NONE: Self = Self {
        highpass_hz: None,
        lowpass_hz: None,
    };
}

impl Default for Prefilter {
    /// 150 Hz – 6 kHz.
    fn default() -> Self {
        Self {
            highpass_hz: Some(150.0),
            lowpass_hz: Some(6000.0),
        }
    }
}

/// The default Paper7 selection before fitting: `lpc_1..lpc_3`, `ps_1, ps_2`,
/// `cep_1, cep_2` (indices into Paper20).
pub const DEFAULT_PAPER7: [usize; 7] = [0, 1, 2, 10, 11, 15, 16];

/// Number of LPC coefficients in the paper sets.
pub const N_LPC: usize = 10;
/// Number of power-spectrum coefficients in the paper sets.
pub const N_PS: usize = 5;
/// Number of cepstral coefficients in the paper sets.
pub const N_CEP: usize = 5;
/// Length of the Paper20 vector.
pub const N_PAPER20: usize = N_LPC + N_PS + N_CEP;
/// Length of the Rich vector for the default 24 mel bands.
pub const N_RICH_DEFAULT: usize = 43;

/// Everything that defines a feature vector. Stored inside a model file, so
/// a model always extracts the features it was trained on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeatureConfig {
    /// Sample rate of the audio (Hz). Paper: 44 100.
    pub sample_rate: u32,
    /// Analysis frame length (s). Paper: 0.1.
    pub frame_s: f64,
    /// Which features.
    pub set: FeatureSet,
    /// Pre-filter of the paper sets (the Rich set is computed on the full band).
    #[serde(default)]
    pub prefilter: Prefilter,
    /// Paper7 only: indices into Paper20, fitted by [`crate::select`].
    #[serde(default = "default_selection")]
    pub selection: Vec<usize>,
    /// Rich only: number of mel bands (a multiple of 4, 8..=64).
    #[serde(default = "default_n_mel")]
    pub n_mel: usize,
    /// Rich only: speed normalisation of the frequency axis (`None`: off).
    /// A speed-normalised model needs the vehicle speed of every frame
    /// ([`FeatureExtractor::set_speed`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_norm: Option<SpeedNorm>,
    /// Rich only: append the energy shares of three fixed bands (2-4, 4-8,
    /// 8-16 kHz) of the recorded spectrum, never warped by the speed
    /// normalisation (crate README, "Rich"). Off in older model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub fixed_bands: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// Speed normalisation of the Rich features: the frequency-domain features
/// of a frame heard at speed v are computed as if heard at `ref_kmh`, by
/// reading every analysis frequency f at f · (v / v_ref)^exponent in the
/// recorded spectrum. Tyre-road rolling noise peaks at a frequency that
/// grows as v^κ, κ ≈ 0.1–0.3 (Sandberg & Ejsmont 2002), so an exponent of
/// about 0.25 holds the tyre's noise hump in place across speeds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedNorm {
    /// Reference speed (km/h): at it the features equal the plain ones.
    pub ref_kmh: f64,
    /// Exponent of the frequency warp (0..=1).
    pub exponent: f64,
}

impl SpeedNorm {
    /// Speeds are clamped to this range (km/h) before the warp.
    pub const SPEED_RANGE_KMH: (f64, f64) = (1.0, 250.0);

    /// Frequency scale w = (v_ref / v)^exponent: a recorded frequency f is
    /// read as f · w. `None` or an invalid speed gives 1 (no warp).
    pub fn warp(&self, speed_mps: Option<f64>) -> f64 {
        match speed_mps {
            Some(v) if v.is_finite() && v >= 0.0 => {
                let (lo, hi) = Self::SPEED_RANGE_KMH;
                let kmh = (v * 3.6).clamp(lo, hi);
                (self.ref_kmh / kmh).powf(self.exponent)
            }
            _ => 1.0,
        }
    }
}

fn default_selection() -> Vec<usize> {
    DEFAULT_PAPER7.to_vec()
}

fn default_n_mel() -> usize {
    24
}

impl Default for FeatureConfig {
    /// 44.1 kHz, 0.1 s frames, the Rich set.
    fn default() -> Self {
        Self::new(44_100, FeatureSet::Rich)
    }
}

impl FeatureConfig {
    /// A config with 0.1 s frames and the default pre-filter, selection and mel bands.
    pub fn new(sample_rate: u32, set: FeatureSet) -> Self {
        Self {
            sample_rate,
            frame_s: 0.1,
            set,
            prefilter: Prefilter::default(),
            selection: default_selection(),
            n_mel: default_n_mel(),
            speed_norm: None,
            fixed_bands: false,
        }
    }

    /// Frame length in samples: round(frame_s · sample_rate).
    pub fn frame_len(&self) -> usize {
        (self.frame_s * f64::from(self.sample_rate)).round() as usize
    }

    /// Length of the feature vector.
    pub fn dim(&self) -> usize {
        match self.set {
            FeatureSet::Paper20 => N_PAPER20,
            FeatureSet::Paper7 => self.selection.len(),
            FeatureSet::Rich => rich::dim(self.n_mel, self.fixed_bands),
        }
    }

    /// Column names, in output order.
    pub fn names(&self) -> Vec<String> {
        match self.set {
            FeatureSet::Paper20 => paper20_names(),
            FeatureSet::Paper7 => {
                let all = paper20_names();
                self.selection
                    .iter()
                    .map(|&i| all.get(i).cloned().unwrap_or_default())
                    .collect()
            }
            FeatureSet::Rich => rich::names(self.n_mel, self.fixed_bands),
        }
    }

    /// Checks ranges (NaN fails); the error names the field and the reason.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |field: &'static str, reason: String| {
            Err(FeatureError::InvalidConfig { field, reason })
        };
        if !(4_000..=384_000).contains(&self.sample_rate) {
            return bad(
                "sample_rate",
                format!("{} Hz is outside 4000..=384000", self.sample_rate),
            );
        }
        if !(self.frame_s >= 0.005 && self.frame_s <= 2.0) {
            return bad(
                "frame_s",
                format!("{} s is outside 0.005..=2.0", self.frame_s),
            );
        }
        if self.frame_len() < 64 {
            return bad(
                "frame_s",
                format!("frame of {} samples is shorter than 64", self.frame_len()),
            );
        }
        let nyq = f64::from(self.sample_rate) / 2.0;
        for (field, v) in [
            ("prefilter.highpass_hz", self.prefilter.highpass_hz),
            ("prefilter.lowpass_hz", self.prefilter.lowpass_hz),
        ] {
            if let Some(f) = v
                && !(f > 0.0 && f < nyq)
            {
                return bad(field, format!("{f} Hz is not inside (0, {nyq})"));
            }
        }
        if self.fixed_bands && self.set != FeatureSet::Rich {
            return bad(
                "fixed_bands",
                format!(
                    "fixed-band features are defined for the rich set, not {}",
                    self.set.name()
                ),
            );
        }
        if let Some(n) = &self.speed_norm {
            if self.set != FeatureSet::Rich {
                return bad(
                    "speed_norm",
                    format!(
                        "speed normalisation is defined for the rich set, not {}",
                        self.set.name()
                    ),
                );
            }
            let (lo, hi) = SpeedNorm::SPEED_RANGE_KMH;
            if !(n.ref_kmh >= lo && n.ref_kmh <= hi) {
                return bad(
                    "speed_norm.ref_kmh",
                    format!("{} km/h is outside {lo}..={hi}", n.ref_kmh),
                );
            }
            if !(0.0..=1.0).contains(&n.exponent) {
                return bad(
                    "speed_norm.exponent",
                    format!("{} is outside 0..=1", n.exponent),
                );
            }
        }
        if let (Some(h), Some(l)) = (self.prefilter.highpass_hz, self.prefilter.lowpass_hz)
            && h >= l
        {
            return bad(
                "prefilter",
                format!("highpass_hz {h} must be below lowpass_hz {l}"),
            );
        }
        if self.set == FeatureSet::Paper7 {
            if self.selection.is_empty() || self.selection.len() > N_PAPER20 {
                return bad(
                    "selection",
                    format!("{} indices; need 1..=20", self.selection.len()),
                );
            }
            for (i, &s) in self.selection.iter().enumerate() {
                if s >= N_PAPER20 {
                    return bad(
                        "selection",
                        format!("index {s} is not a Paper20 feature (0..20)"),
                    );
                }
                if self.selection[..i].contains(&s) {
                    return bad("selection", format!("index {s} appears twice"));
                }
            }
        }
        if self.set == FeatureSet::Rich
            && (!(8..=64).contains(&self.n_mel) || !self.n_mel.is_multiple_of(4))
        {
            return bad(
                "n_mel",
                format!("{} is not a multiple of 4 in 8..=64", self.n_mel),
            );
        }
        Ok(())
    }
}

fn paper20_names() -> Vec<String> {
    (1..=N_LPC)
        .map(|i| format!("lpc_{i}"))
        .chain((1..=N_PS).map(|i| format!("ps_{i}")))
        .chain((1..=N_CEP).map(|i| format!("cep_{i}")))
        .collect()
}

/// Errors of feature configuration and extraction.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FeatureError {
    /// A config field is out of range.
    #[error("feature config: field `{field}`: {reason}")]
    InvalidConfig {
        /// The offending field.
        field: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// The frame has more samples than the configured frame length.
    #[error("frame has {got} samples, more than the configured frame length {max}")]
    FrameTooLong {
        /// Samples given.
        got: usize,
        /// Configured frame length.
        max: usize,
    },
    /// The output slice has the wrong length.
    #[error("feature output has length {got}, expected {expected}")]
    OutputLength {
        /// Length given.
        got: usize,
        /// `FeatureConfig::dim()`.
        expected: usize,
    },
}

/// Computes one feature vector per frame. Build once, call `extract` per frame.
pub struct FeatureExtractor {
    cfg: FeatureConfig,
    frame_len: usize,
    dim: usize,
    /// The frame as f64, DC removed (length frame_len).
    x: Vec<f64>,
    paper: Option<paper::Paper>,
    rich: Option<rich::Rich>,
    /// Paper20 scratch for the Paper7 set.
    tmp20: Vec<f64>,
    /// Frequency warp of the next frames ([`SpeedNorm::warp`]; 1 = none).
    warp: f64,
}

impl std::fmt::Debug for FeatureExtractor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FeatureExtractor")
            .field("cfg", &self.cfg)
            .finish_non_exhaustive()
    }
}

impl FeatureExtractor {
    /// Validates the config, plans the FFTs, allocates all buffers.
    pub fn new(cfg: &FeatureConfig) -> Result<Self, FeatureError> {
        cfg.validate()?;
        let frame_len = cfg.frame_len();
        let (paper, rich) = match cfg.set {
            FeatureSet::Paper20 | FeatureSet::Paper7 => {
                (Some(paper::Paper::new(cfg, frame_len)), None)
            }
            FeatureSet::Rich => (None, Some(rich::Rich::new(cfg, frame_len))),
        };
        Ok(Self {
            cfg: cfg.clone(),
            frame_len,
            dim: cfg.dim(),
            x: vec![0.0; frame_len],
            paper,
            rich,
            tmp20: vec![0.0; N_PAPER20],
            warp: 1.0,
        })
    }

    /// Sets the vehicle speed (m/s) of the next frames, for a config with
    /// [`FeatureConfig::speed_norm`]; ignored otherwise. `None` (speed
    /// unknown) or a non-finite or negative speed means no normalisation:
    /// the frame is taken as heard at the reference speed. Allocates nothing.
    pub fn set_speed(&mut self, speed_mps: Option<f64>) {
        self.warp = self.cfg.speed_norm.map_or(1.0, |n| n.warp(speed_mps));
    }

    /// The frequency warp in force ([`SpeedNorm::warp`]; 1 = none).
    pub fn warp(&self) -> f64 {
        self.warp
    }

    /// The config this extractor was built from.
    pub fn config(&self) -> &FeatureConfig {
        &self.cfg
    }

    /// Frame length in samples.
    pub fn frame_len(&self) -> usize {
        self.frame_len
    }

    /// Feature vector length.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Column names.
    pub fn names(&self) -> Vec<String> {
        self.cfg.names()
    }

    /// Extracts the features of `frame` into `out` (length [`Self::dim`]).
    ///
    /// A frame shorter than the frame length is zero-padded at its end;
    /// non-finite samples are replaced by 0; the frame mean (DC) is removed.
    /// Every output is finite for any input. Allocates nothing.
    pub fn extract(&mut self, frame: &[f32], out: &mut [f64]) -> Result<(), FeatureError> {
        if frame.len() > self.frame_len {
            return Err(FeatureError::FrameTooLong {
                got: frame.len(),
                max: self.frame_len,
            });
        }
        if out.len() != self.dim {
            return Err(FeatureError::OutputLength {
                got: out.len(),
                expected: self.dim,
            });
        }
        // Convert (non-finite → 0) and sum with four interleaved partial
        // sums; zero-pad the rest.
        let (head, tail) = self.x.split_at_mut(frame.len());
        tail.fill(0.0);
        let mut acc = [0.0f64; 4];
        let (mut hc, mut fc) = (head.chunks_exact_mut(4), frame.chunks_exact(4));
        for (h, f) in (&mut hc).zip(&mut fc) {
            for i in 0..4 {
                h[i] = if f[i].is_finite() {
                    f64::from(f[i])
                } else {
                    0.0
                };
                acc[i] += h[i];
            }
        }
        let mut sum = (acc[0] + acc[2]) + (acc[1] + acc[3]);
        for (h, &v) in hc.into_remainder().iter_mut().zip(fc.remainder()) {
            *h = if v.is_finite() { f64::from(v) } else { 0.0 };
            sum += *h;
        }
        let n = frame.len().max(1) as f64;
        let mean = sum / n;
        for xi in head.iter_mut() {
            *xi -= mean;
        }
        match self.cfg.set {
            FeatureSet::Paper20 => {
                if let Some(p) = self.paper.as_mut() {
                    p.extract(&self.x, out);
                }
            }
            FeatureSet::Paper7 => {
                if let Some(p) = self.paper.as_mut() {
                    p.extract(&self.x, &mut self.tmp20);
                    for (o, &i) in out.iter_mut().zip(self.cfg.selection.iter()) {
                        *o = self.tmp20[i];
                    }
                }
            }
            FeatureSet::Rich => {
                if let Some(r) = self.rich.as_mut() {
                    r.set_warp(self.warp);
                    r.extract(&self.x, out);
                }
            }
        }
        for o in out.iter_mut() {
            if !o.is_finite() {
                *o = 0.0;
            }
        }
        Ok(())
    }

    /// Extracts the features of every frame of `signal` with the given hop
    /// (samples): frames start at 0, hop, 2·hop, … while a whole frame fits.
    /// Returns the row-major matrix (n_frames × dim). Allocates (offline use).
    pub fn extract_all(&mut self, signal: &[f32], hop: usize) -> Result<Vec<f64>, FeatureError> {
        let hop = hop.max(1);
        let n = frame_count(signal.len(), self.frame_len, hop);
        let mut out = vec![0.0; n * self.dim];
        for (i, row) in out.chunks_exact_mut(self.dim.max(1)).enumerate() {
            let s = i * hop;
            self.extract(&signal[s..s + self.frame_len], row)?;
        }
        Ok(out)
    }

    /// The power spectrum `|X[k]|²` of the last frame, k = 0..=nfft/2 (paper
    /// sets: Hamming-windowed whole frame, before the pre-filter; Rich: the
    /// mean of the sub-frame spectra). Bin k is at `k · bin_hz()`.
    pub fn power_spectrum(&self) -> &[f64] {
        if let Some(p) = &self.paper {
            p.power()
        } else if let Some(r) = &self.rich {
            r.power()
        } else {
            &[]
        }
    }

    /// Frequency spacing of [`Self::power_spectrum`] bins (Hz).
    pub fn bin_hz(&self) -> f64 {
        let n = if let Some(p) = &self.paper {
            p.nfft()
        } else if let Some(r) = &self.rich {
            r.nfft()
        } else {
            1
        };
        f64::from(self.cfg.sample_rate) / n as f64
    }
}

/// Number of whole frames of `frame_len` with hop `hop` in `len` samples.
pub fn frame_count(len: usize, frame_len: usize, hop: usize) -> usize {
    if len < frame_len || hop == 0 {
        0
    } else {
        (len - frame_len) / hop + 1
    }
}

/// Natural logarithm of a positive finite `x` to about 1e-12 relative
/// accuracy, several times faster than `f64::ln` (frexp-style split
/// x = m·2^e with m in [√½, √2), then ln m = 2 atanh((m−1)/(m+1)) by its odd
/// series to t¹⁵). Used for the thousands of per-bin logarithms per frame.
#[inline]
pub(crate) fn fast_ln(x: f64) -> f64 {
    let bits = x.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i64;
    if exp == 0 || exp == 0x7ff {
        return x.ln(); // zero, subnormal, inf, NaN: rare, exact path
    }
    let mut e = exp - 1023;
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    if m > std::f64::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let p = 1.0
        + t2 * (1.0 / 3.0
            + t2 * (1.0 / 5.0
                + t2 * (1.0 / 7.0
                    + t2 * (1.0 / 9.0 + t2 * (1.0 / 11.0 + t2 * (1.0 / 13.0 + t2 / 15.0))))));
    e as f64 * std::f64::consts::LN_2 + 2.0 * t * p
}

/// Periodic-free (symmetric) Hamming window of length n: 0.54 − 0.46 cos(2πi/(n−1)).
pub(crate) fn hamming(n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![1.0];
    }
    (0..n)
        .map(|i| 0.54 - 0.46 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos())
        .collect()
}

/// Periodic Hann window of length n: 0.5 − 0.5 cos(2πi/n).
pub(crate) fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
        .collect()
}

#[cfg(test)]
mod fast_ln_tests {
    #[test]
    fn fast_ln_matches_ln() {
        let mut x = 1e-300f64;
        while x < 1e300 {
            for f in [1.0, 1.1, 1.41, 1.42, 1.7, 1.99] {
                let v = x * f;
                let (a, b) = (super::fast_ln(v), v.ln());
                assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{v}: {a} vs {b}");
            }
            x *= 7.3;
        }
        assert_eq!(super::fast_ln(1.0), 0.0);
    }
}
