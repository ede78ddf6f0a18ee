//! The Rich set: 43 level-invariant features (for 24 mel bands) that capture
//! what separates tyre-road sounds: spectral shape, within-frame temporal
//! variability, spectral descriptors and impact statistics. Every feature is
//! invariant to the microphone gain (a scale of the signal), so level, which
//! depends on gain and speed, never decides the class. Exact definitions in
//! the crate README ("Features", "Rich").

use super::fft::RealFft;
use super::{FeatureConfig, fast_ln, hann};

/// Number of broad band groups whose within-frame variability is measured.
const N_GROUPS: usize = 6;
/// Scalar features after the mel shape and the group variabilities.
const SCALARS: [&str; 13] = [
    "flux",
    "centroid_khz",
    "spread_khz",
    "rolloff_khz",
    "flatness_db",
    "zcr_khz",
    "crest_db",
    "env_crest_db",
    "diff_kurtosis_ln",
    "env_periodicity",
    "hf_kurtosis_ln",
    "hf_env_crest_db",
    "lf_env_periodicity",
];
const MEL_FMIN: f64 = 50.0;
const MEL_FMAX: f64 = 16_000.0;
/// Optional features of the recorded (never warped) spectrum: ln of the
/// energy share of these bands (Hz) in [`MEL_FMIN`, [`MEL_FMAX`]].
/// Water-film spray and rain are not tyre resonances: their spectra stay
/// put when the speed changes, and at low speed the warped bands no longer
/// reach the top octave where spray and rain differ most.
const FIXED_BANDS: [(f64, f64, &str); 3] = [
    (2_000.0, 4_000.0, "fixed_share_2_4k"),
    (4_000.0, 8_000.0, "fixed_share_4_8k"),
    (8_000.0, 16_000.0, "fixed_share_8_16k"),
];

pub(crate) fn dim(n_mel: usize, fixed_bands: bool) -> usize {
    n_mel + N_GROUPS + SCALARS.len() + if fixed_bands { FIXED_BANDS.len() } else { 0 }
}

pub(crate) fn names(n_mel: usize, fixed_bands: bool) -> Vec<String> {
    let fixed = FIXED_BANDS.iter().filter(|_| fixed_bands);
    (1..=n_mel)
        .map(|i| format!("mel_{i}"))
        .chain((1..=N_GROUPS).map(|i| format!("mel_std_{i}")))
        .chain(SCALARS.iter().map(|s| (*s).to_string()))
        .chain(fixed.map(|b| b.2.to_string()))
        .collect()
}

fn hz_to_mel(f: f64) -> f64 {
    2595.0 * (1.0 + f / 700.0).log10()
}

fn mel_to_hz(m: f64) -> f64 {
    700.0 * (10f64.powf(m / 2595.0) - 1.0)
}

pub(crate) struct Rich {
    fs: f64,
    n_mel: usize,
    frame_len: usize,
    sub_len: usize,
    starts: Vec<usize>,
    window: Vec<f64>,
    fft: RealFft,
    /// Power spectrum of each sub-frame, row-major (n_sub × nb).
    sub_pow: Vec<f64>,
    mean_pow: Vec<f64>,
    /// Mel filters: (first bin, weights) flattened: `mel_start[b]`,
    /// `mel_w[mel_off[b]..mel_off[b+1]]`.
    mel_start: Vec<usize>,
    mel_off: Vec<usize>,
    mel_w: Vec<f64>,
    /// Summed mel weights of each band group, flattened as the mel filters:
    /// `grp_start[g]`, `grp_w[grp_off[g]..grp_off[g+1]]`.
    grp_start: Vec<usize>,
    grp_off: Vec<usize>,
    grp_w: Vec<f64>,
    /// Bin range [k_lo, k_hi) used for the spectral descriptors.
    k_lo: usize,
    k_hi: usize,
    /// Mel band points (Hz) on the normalised frequency axis (n_mel + 2).
    mel_pts: Vec<f64>,
    /// Frequency warp the banks, ranges and filters are built for (1 = none):
    /// a recorded frequency f counts as f · warp.
    warp: f64,
    mel_e: Vec<f64>,
    /// Per sub-frame, log energy of each group (n_sub × N_GROUPS).
    group_log: Vec<f64>,
    norm_prev: Vec<f64>,
    norm_cur: Vec<f64>,
    env_block: usize,
    env: Vec<f64>,
    lag_lo: usize,
    lag_hi: usize,
    /// Band filters (biquad coefficients b0, b1, b2, a1, a2): high-pass 3 kHz, low-pass 400 Hz.
    hp: [f64; 5],
    lp: [f64; 5],
    /// Samples skipped at the frame start while the band filters settle.
    settle: usize,
    lf_block: usize,
    lf_env: Vec<f64>,
    lf_lag_lo: usize,
    lf_lag_hi: usize,
    /// High-pass and low-pass feed-forward parts, then squared outputs (frame_len).
    eh: Vec<f64>,
    el: Vec<f64>,
    /// Bin ranges of [`FIXED_BANDS`] and of their reference range (recorded
    /// frequencies); `None` when the fixed-band features are off.
    fixed: Option<FixedBins>,
}

/// Bin ranges [lo, hi) of the fixed bands and of their reference range.
#[derive(Clone, Copy)]
struct FixedBins {
    bands: [(usize, usize); 3],
    reference: (usize, usize),
}

/// RBJ cookbook biquad, normalised: [b0, b1, b2, a1, a2].
fn biquad(fs: f64, f: f64, highpass: bool) -> [f64; 5] {
    let w0 = 2.0 * std::f64::consts::PI * f.min(0.45 * fs) / fs;
    let (c, al) = (w0.cos(), w0.sin() / (2.0 * std::f64::consts::FRAC_1_SQRT_2));
    let a0 = 1.0 + al;
    let (b0, b1) = if highpass {
        ((1.0 + c) / 2.0, -(1.0 + c))
    } else {
        ((1.0 - c) / 2.0, 1.0 - c)
    };
    [b0 / a0, b1 / a0, b0 / a0, -2.0 * c / a0, (1.0 - al) / a0]
}

/// Max over lags [lo, hi] of the normalised autocorrelation of `e` (de-meaned in place).
///
/// Four lags are accumulated side by side (independent chains, shared
/// loads); each lag's sum still runs over j in increasing order, so every
/// value is the one of the plain per-lag loop.
fn periodicity(e: &mut [f64], lo: usize, hi: usize) -> f64 {
    let n = e.len();
    let mean = e.iter().sum::<f64>() / n.max(1) as f64;
    let mut e0 = 0.0;
    for v in e.iter_mut() {
        *v -= mean;
        e0 += *v * *v;
    }
    let mut best = 0.0f64;
    let positive = e0 > 0.0; // false for NaN too
    if !positive || lo >= n {
        return best;
    }
    let e = &*e;
    // Lags lo..=last, all < n.
    let last = hi.max(lo).min(n - 1);
    let mut lag = lo;
    while lag + 3 <= last {
        // Lag lag+i has n − lag − i terms; the first m are common to all four.
        let m = n - lag - 3;
        let mut acc = [0.0f64; 4];
        for ((((&a, &b0), &b1), &b2), &b3) in e[..m]
            .iter()
            .zip(&e[lag..lag + m])
            .zip(&e[lag + 1..lag + 1 + m])
            .zip(&e[lag + 2..lag + 2 + m])
            .zip(&e[lag + 3..lag + 3 + m])
        {
            acc[0] += a * b0;
            acc[1] += a * b1;
            acc[2] += a * b2;
            acc[3] += a * b3;
        }
        for (i, acc) in acc.iter_mut().enumerate() {
            for j in m..n - lag - i {
                *acc += e[j] * e[j + lag + i];
            }
            best = best.max(*acc / e0);
        }
        lag += 4;
    }
    for lag in lag..=last {
        let acc = e[..n - lag]
            .iter()
            .zip(&e[lag..])
            .fold(0.0, |acc, (a, b)| acc + a * b);
        best = best.max(acc / e0);
    }
    best
}

/// Sum of `v` with four interleaved partial sums (a reassociation of the
/// sequential sum that breaks its add-latency chain).
#[inline]
fn sum4(v: &[f64]) -> f64 {
    let mut a = [0.0f64; 4];
    let mut it = v.chunks_exact(4);
    for c in &mut it {
        a[0] += c[0];
        a[1] += c[1];
        a[2] += c[2];
        a[3] += c[3];
    }
    let mut s = (a[0] + a[2]) + (a[1] + a[3]);
    for &r in it.remainder() {
        s += r;
    }
    s
}

/// (Σ v, Σ v²) with four interleaved partial sums each.
#[inline]
fn sum_sumsq4(v: &[f64]) -> (f64, f64) {
    let (mut a, mut q) = ([0.0f64; 4], [0.0f64; 4]);
    let mut it = v.chunks_exact(4);
    for c in &mut it {
        for i in 0..4 {
            a[i] += c[i];
            q[i] += c[i] * c[i];
        }
    }
    let (mut s, mut s2) = ((a[0] + a[2]) + (a[1] + a[3]), (q[0] + q[2]) + (q[1] + q[3]));
    for &r in it.remainder() {
        s += r;
        s2 += r * r;
    }
    (s, s2)
}

/// Σ w[i]·p[i] with four interleaved partial sums.
#[inline]
fn dot4(w: &[f64], p: &[f64]) -> f64 {
    let mut a = [0.0f64; 4];
    let (mut wi, mut pi) = (w.chunks_exact(4), p.chunks_exact(4));
    for (wc, pc) in (&mut wi).zip(&mut pi) {
        for i in 0..4 {
            a[i] += wc[i] * pc[i];
        }
    }
    let mut s = (a[0] + a[2]) + (a[1] + a[3]);
    for (&a, &b) in wi.remainder().iter().zip(pi.remainder()) {
        s += a * b;
    }
    s
}

/// Running statistics of the time-domain pass (four lanes each).
struct TimeAcc {
    zc: [u32; 4],
    peak: [f64; 4],
    sq: [f64; 4],
    m4: [f64; 4],
}

impl TimeAcc {
    /// Samples `cur[i]` with predecessors `prev[i]` (same length): counts
    /// sign changes, tracks |x| peak and Σx², Σd⁴ of d = cur − prev;
    /// returns Σd².
    #[inline]
    fn run(&mut self, prev: &[f64], cur: &[f64]) -> f64 {
        let mut m2 = [0.0f64; 4];
        let (mut pi, mut ci) = (prev.chunks_exact(4), cur.chunks_exact(4));
        for (p, c) in (&mut pi).zip(&mut ci) {
            for i in 0..4 {
                self.zc[i] += u32::from((c[i] >= 0.0) != (p[i] >= 0.0));
                self.peak[i] = self.peak[i].max(c[i].abs());
                self.sq[i] += c[i] * c[i];
                let d = c[i] - p[i];
                let d2 = d * d;
                m2[i] += d2;
                self.m4[i] += d2 * d2;
            }
        }
        let mut s = (m2[0] + m2[2]) + (m2[1] + m2[3]);
        for (&p, &c) in pi.remainder().iter().zip(ci.remainder()) {
            self.zc[0] += u32::from((c >= 0.0) != (p >= 0.0));
            self.peak[0] = self.peak[0].max(c.abs());
            self.sq[0] += c * c;
            let d = c - p;
            let d2 = d * d;
            s += d2;
            self.m4[0] += d2 * d2;
        }
        s
    }
}

impl Rich {
    pub(crate) fn new(cfg: &FeatureConfig, frame_len: usize) -> Self {
        let fs = f64::from(cfg.sample_rate);
        let sub_len = ((0.023 * fs).round() as usize).next_power_of_two().max(64);
        let hop = sub_len / 2;
        let starts: Vec<usize> = if frame_len <= sub_len {
            vec![0]
        } else {
            let n = (frame_len - sub_len).div_ceil(hop) + 1;
            (0..n)
                .map(|s| ((s * (frame_len - sub_len)) as f64 / (n - 1) as f64).round() as usize)
                .collect()
        };
        let nb = sub_len / 2 + 1;
        let fmax = MEL_FMAX.min(0.5 * fs);
        let (m0, m1) = (hz_to_mel(MEL_FMIN), hz_to_mel(fmax));
        let n_mel = cfg.n_mel;
        let pts: Vec<f64> = (0..n_mel + 2)
            .map(|i| mel_to_hz(m0 + (m1 - m0) * i as f64 / (n_mel + 1) as f64))
            .collect();
        // Worst case of the filter-bank weights over all warps: every band
        // spans its two neighbours' spacing plus rounding, bands past Nyquist
        // one bin each (see `build_banks`).
        let cap = 2 * nb + 4 * n_mel + 8;
        let env_block = ((0.000_725 * fs).round() as usize).max(1);
        let n_env = frame_len / env_block;
        let lag_lo = ((0.004 * fs) / env_block as f64).ceil() as usize;
        let lag_hi = (((0.060 * fs) / env_block as f64).floor() as usize).min(n_env / 2);
        let n_sub = starts.len();
        let lf_block = ((0.002 * fs).round() as usize).max(1);
        let settle = ((0.005 * fs).round() as usize).min(frame_len / 4);
        let n_lf = (frame_len - settle) / lf_block;
        let df = fs / sub_len as f64;
        let bin = |f: f64| ((f.min(0.5 * fs) / df).round() as usize).clamp(1, nb);
        let fixed = cfg.fixed_bands.then(|| {
            let mut b = [(0, 0); 3];
            for (o, &(lo, hi, _)) in b.iter_mut().zip(&FIXED_BANDS) {
                *o = (bin(lo), bin(hi).max(bin(lo)));
            }
            FixedBins {
                bands: b,
                reference: (bin(MEL_FMIN), bin(MEL_FMAX)),
            }
        });
        let mut r = Self {
            fixed,
            hp: [0.0; 5],
            lp: [0.0; 5],
            settle,
            lf_block,
            lf_env: vec![0.0; n_lf.max(1)],
            lf_lag_lo: ((0.004 * fs) / lf_block as f64).ceil() as usize,
            lf_lag_hi: (((0.060 * fs) / lf_block as f64).floor() as usize).min(n_lf / 2),
            fs,
            n_mel,
            frame_len,
            sub_len,
            window: hann(sub_len),
            fft: RealFft::new(sub_len),
            sub_pow: vec![0.0; n_sub * nb],
            mean_pow: vec![0.0; nb],
            mel_start: Vec::with_capacity(n_mel),
            mel_off: Vec::with_capacity(n_mel + 1),
            mel_w: Vec::with_capacity(cap),
            grp_start: Vec::with_capacity(N_GROUPS),
            grp_off: Vec::with_capacity(N_GROUPS + 1),
            grp_w: Vec::with_capacity(cap),
            k_lo: 1,
            k_hi: nb,
            mel_pts: pts,
            warp: f64::NAN,
            mel_e: vec![0.0; n_mel],
            group_log: vec![0.0; n_sub * N_GROUPS],
            norm_prev: vec![0.0; nb],
            norm_cur: vec![0.0; nb],
            env_block,
            env: vec![0.0; n_env.max(1)],
            lag_lo,
            lag_hi,
            starts,
            eh: vec![0.0; frame_len],
            el: vec![0.0; frame_len],
        };
        r.build_banks(1.0);
        r
    }

    /// Sets the frequency warp of the next frames (speed normalisation;
    /// 1 = none). The warp is quantised to steps of 0.25 % so that the
    /// banks are rebuilt only when the speed really changes. Allocates
    /// nothing.
    pub(crate) fn set_warp(&mut self, warp: f64) {
        let w = if warp.is_finite() && warp > 0.0 {
            let step = 0.0025;
            (((warp.ln() / step).round()) * step).exp()
        } else {
            1.0
        };
        let w = if (w - 1.0).abs() < 1e-12 { 1.0 } else { w };
        if w != self.warp {
            self.build_banks(w);
        }
    }

    /// (Re)builds the mel and group filter banks, the descriptor bin range
    /// and the band filters for `warp`: a band defined from f_l to f_h on
    /// the normalised axis covers f_l / warp to f_h / warp in the recorded
    /// spectrum. For warp = 1 these are the plain Rich definitions.
    /// Writes into the buffers reserved by `new` (no allocation).
    fn build_banks(&mut self, warp: f64) {
        let fs = self.fs;
        let nb = self.sub_len / 2 + 1;
        let df = fs / self.sub_len as f64;
        let n_mel = self.n_mel;
        self.mel_start.clear();
        self.mel_off.clear();
        self.mel_off.push(0);
        self.mel_w.clear();
        for b in 0..n_mel {
            let (fl, fc, fh) = (
                self.mel_pts[b] / warp,
                self.mel_pts[b + 1] / warp,
                self.mel_pts[b + 2] / warp,
            );
            let k1 = ((fh / df).ceil() as usize).min(nb - 1);
            let k0 = ((fl / df).floor() as usize).min(k1);
            let at = self.mel_w.len();
            let mut any = false;
            for k in k0..=k1 {
                let f = k as f64 * df;
                let v = if f <= fl || f >= fh {
                    0.0
                } else if f <= fc {
                    (f - fl) / (fc - fl)
                } else {
                    (fh - f) / (fh - fc)
                };
                any |= v != 0.0;
                self.mel_w.push(v);
            }
            if !any {
                // Band narrower than a bin: take the bin nearest its centre.
                let kc = ((fc / df).round() as usize).clamp(k0, k1);
                self.mel_w[at + kc - k0] = 1.0;
            }
            self.mel_start.push(k0);
            self.mel_off.push(self.mel_w.len());
        }
        // Each group's summed weights (the group energy is linear in the power).
        let per = n_mel / N_GROUPS;
        self.grp_start.clear();
        self.grp_off.clear();
        self.grp_off.push(0);
        self.grp_w.clear();
        for g in 0..N_GROUPS {
            let (lo, hi) = (
                g * per,
                if g + 1 == N_GROUPS {
                    n_mel
                } else {
                    (g + 1) * per
                },
            );
            let k0 = self.mel_start[lo..hi].iter().copied().min().unwrap_or(0);
            let k1 = (lo..hi)
                .map(|b| self.mel_start[b] + (self.mel_off[b + 1] - self.mel_off[b]))
                .max()
                .unwrap_or(k0);
            let at = self.grp_w.len();
            self.grp_w.resize(at + (k1 - k0), 0.0);
            for b in lo..hi {
                let (o0, o1) = (self.mel_off[b], self.mel_off[b + 1]);
                for j in 0..o1 - o0 {
                    self.grp_w[at + self.mel_start[b] - k0 + j] += self.mel_w[o0 + j];
                }
            }
            self.grp_start.push(k0);
            self.grp_off.push(self.grp_w.len());
        }
        let fmax = MEL_FMAX.min(0.5 * fs);
        self.k_hi = ((fmax / warp / df).floor() as usize + 1).min(nb);
        self.k_lo = (((MEL_FMIN / warp) / df).ceil() as usize)
            .max(1)
            .min(self.k_hi - 1);
        self.hp = biquad(fs, 3000.0 / warp, true);
        self.lp = biquad(fs, 400.0 / warp, false);
        self.warp = warp;
    }

    pub(crate) fn nfft(&self) -> usize {
        self.sub_len
    }

    pub(crate) fn power(&self) -> &[f64] {
        &self.mean_pow
    }

    fn mel_energies(&self, pow: &[f64], out: &mut [f64]) {
        for (b, o) in out.iter_mut().enumerate().take(self.n_mel) {
            let k0 = self.mel_start[b];
            let w = &self.mel_w[self.mel_off[b]..self.mel_off[b + 1]];
            *o = w
                .iter()
                .zip(&pow[k0..k0 + w.len()])
                .fold(0.0, |acc, (wj, pj)| acc + wj * pj);
        }
    }

    /// `x`: DC-removed frame (length frame_len); `out`: dim values.
    pub(crate) fn extract(&mut self, x: &[f64], out: &mut [f64]) {
        let nb = self.sub_len / 2 + 1;
        let n_sub = self.starts.len();
        let l = self.frame_len;
        let x = &x[..l];
        // Sub-frame power spectra and their mean (Welch).
        self.mean_pow.fill(0.0);
        let inv_sub = 1.0 / n_sub as f64;
        for (row, &st) in self.sub_pow.chunks_exact_mut(nb).zip(&self.starts) {
            let seg = &x[st.min(l)..(st + self.sub_len).min(l)];
            self.fft
                .forward_power_windowed(seg, Some(&self.window), row);
            for (m, &p) in self.mean_pow.iter_mut().zip(row.iter()) {
                *m += p * inv_sub;
            }
        }
        let (k_lo, k_hi) = (self.k_lo, self.k_hi);
        let total: f64 = self.mean_pow[k_lo..k_hi].iter().sum();
        let floor = 1e-10 * total / (k_hi - k_lo) as f64 + 1e-300;

        // 1. Mel shape: ln band energy minus its mean over bands.
        let mut mel_e = std::mem::take(&mut self.mel_e);
        self.mel_energies(&self.mean_pow, &mut mel_e);
        self.mel_e = mel_e;
        let mut mean_log = 0.0;
        for (o, e) in out[..self.n_mel].iter_mut().zip(&self.mel_e) {
            *o = (e + floor).ln();
            mean_log += *o;
        }
        mean_log /= self.n_mel as f64;
        for o in out[..self.n_mel].iter_mut() {
            *o -= mean_log;
        }
        // 2. Within-frame variability: std over sub-frames of the ln energy of
        //    N_GROUPS groups of adjacent mel bands.
        for (row, gl) in self
            .sub_pow
            .chunks_exact(nb)
            .zip(self.group_log.chunks_exact_mut(N_GROUPS))
        {
            for (g, o) in gl.iter_mut().enumerate() {
                let k0 = self.grp_start[g];
                let w = &self.grp_w[self.grp_off[g]..self.grp_off[g + 1]];
                *o = (dot4(w, &row[k0..k0 + w.len()]) + floor).ln();
            }
        }
        for g in 0..N_GROUPS {
            let mut m = 0.0;
            for gl in self.group_log.chunks_exact(N_GROUPS) {
                m += gl[g];
            }
            m *= inv_sub;
            let mut v = 0.0;
            for gl in self.group_log.chunks_exact(N_GROUPS) {
                let d = gl[g] - m;
                v += d * d;
            }
            out[self.n_mel + g] = (v * inv_sub).sqrt();
        }
        let mut i = self.n_mel + N_GROUPS;
        // 3. Spectral flux: mean squared difference of unit-norm magnitude
        //    spectra of consecutive sub-frames.
        let mut flux = 0.0;
        for (s, row) in self.sub_pow.chunks_exact(nb).enumerate() {
            let row = &row[k_lo..k_hi];
            let inv = 1.0 / (sum4(row) + floor).sqrt();
            let cur = &mut self.norm_cur[k_lo..k_hi];
            for (c, &p) in cur.iter_mut().zip(row) {
                *c = p.sqrt() * inv;
            }
            if s > 0 {
                let prev = &self.norm_prev[k_lo..k_hi];
                let mut a = [0.0f64; 4];
                let (mut ci, mut pi) = (cur.chunks_exact(4), prev.chunks_exact(4));
                for (c, p) in (&mut ci).zip(&mut pi) {
                    for j in 0..4 {
                        let e = c[j] - p[j];
                        a[j] += e * e;
                    }
                }
                let mut d = (a[0] + a[2]) + (a[1] + a[3]);
                for (c, p) in ci.remainder().iter().zip(pi.remainder()) {
                    d += (c - p) * (c - p);
                }
                flux += d / (n_sub - 1) as f64;
            }
            std::mem::swap(&mut self.norm_cur, &mut self.norm_prev);
        }
        out[i] = flux;
        i += 1;
        // 4. Spectral descriptors of the mean spectrum over [50 Hz, 16 kHz].
        let df = self.fs / self.sub_len as f64;
        let mp = &self.mean_pow[k_lo..k_hi];
        let (mut p_sum, mut pf_sum, mut ln_sum) = (0.0, 0.0, 0.0);
        for (k, &pk) in (k_lo..).zip(mp) {
            let p = pk + floor;
            p_sum += p;
            pf_sum += p * k as f64 * df;
            ln_sum += fast_ln(p);
        }
        let nk = (k_hi - k_lo) as f64;
        let centroid = pf_sum / p_sum;
        let mut var = 0.0;
        let mut cum = 0.0;
        let mut rolloff = (k_hi - 1) as f64 * df;
        let mut rolled = false;
        for (k, &pk) in (k_lo..).zip(mp) {
            let p = pk + floor;
            let f = k as f64 * df;
            var += p * (f - centroid) * (f - centroid);
            cum += p;
            if !rolled && cum >= 0.85 * p_sum {
                rolloff = f;
                rolled = true;
            }
        }
        // In Hz of the normalised axis (recorded f · warp).
        let w = self.warp;
        out[i] = centroid * w / 1000.0;
        out[i + 1] = (var / p_sum).sqrt() * w / 1000.0;
        out[i + 2] = rolloff * w / 1000.0;
        out[i + 3] = 10.0 * (ln_sum / nk - (p_sum / nk).ln()) / std::f64::consts::LN_10;
        i += 4;
        // 5. Time domain: zero-crossing rate, crest factor, and impact
        //    statistics of the first difference d[n] = x[n] − x[n−1]; the
        //    envelope block j sums d[n]² over n in [j·B, (j+1)·B) (n ≥ 1).
        //    One pass over the frame, envelope block by envelope block.
        let eb = self.env_block;
        let nenv = self.env.len();
        let mut acc = TimeAcc {
            zc: [0; 4],
            peak: [x[0].abs(), 0.0, 0.0, 0.0],
            sq: [x[0] * x[0], 0.0, 0.0, 0.0],
            m4: [0.0; 4],
        };
        let mut m2 = 0.0;
        for (j, env) in self.env.iter_mut().enumerate() {
            let (a, b) = ((j * eb).max(1), ((j + 1) * eb).min(l));
            *env = if a < b {
                acc.run(&x[a - 1..b - 1], &x[a..b])
            } else {
                0.0
            };
            m2 += *env;
        }
        let a = (nenv * eb).max(1);
        if a < l {
            m2 += acc.run(&x[a - 1..l - 1], &x[a..l]);
        }
        let zc = acc.zc.iter().map(|&z| z as usize).sum::<usize>();
        let peak = acc.peak.iter().fold(0.0f64, |a, &b| a.max(b));
        let sq = (acc.sq[0] + acc.sq[2]) + (acc.sq[1] + acc.sq[3]);
        let m4 = (acc.m4[0] + acc.m4[2]) + (acc.m4[1] + acc.m4[3]);
        let rms = (sq / l as f64).sqrt();
        out[i] = zc as f64 / (l - 1) as f64 * self.fs * self.warp / 1000.0;
        let tiny = 1e-30;
        out[i + 1] = 20.0 * ((peak + tiny) / (rms + tiny)).log10();
        let (m2, m4) = (m2 / (l - 1) as f64, m4 / (l - 1) as f64);
        let env_mean = self.env.iter().sum::<f64>() / nenv as f64;
        let env_max = self.env.iter().fold(0.0f64, |a, &b| a.max(b));
        out[i + 2] = 10.0 * ((env_max + tiny) / (env_mean + tiny)).log10();
        out[i + 3] = if m2 > 0.0 {
            (m4 / (m2 * m2)).max(1e-12).ln()
        } else {
            0.0
        };
        // Envelope periodicity: max normalised autocorrelation of the
        // de-meaned envelope over lags 4..60 ms (sett joints, regular impacts).
        out[i + 4] = periodicity(&mut self.env, self.lag_lo, self.lag_hi);
        // Band-limited impulsiveness: the > 3 kHz band (snaps, crunch, drops
        // vs. spray hiss) and the < 400 Hz envelope's periodicity (thumps).
        // Both biquads run as direct form I, y[n] = f[n] − a1·y[n−1] −
        // a2·y[n−2] with the feed-forward part f[n] = b0·x[n] + b1·x[n−1] +
        // b2·x[n−2] computed first (no recursion there, so it vectorises);
        // the same transfer function and zero initial state as the
        // transposed form, with a shorter dependency chain per sample.
        // `eh`/`el` hold f, then the squared outputs.
        let (h, g) = (self.hp, self.lp);
        {
            let (fh, fl) = (&mut self.eh[..l], &mut self.el[..l]);
            fh[0] = h[0] * x[0];
            fl[0] = g[0] * x[0];
            fh[1] = h[0] * x[1] + h[1] * x[0];
            fl[1] = g[0] * x[1] + g[1] * x[0];
            for ((((oh, ol), &x0), &x1), &x2) in fh[2..]
                .iter_mut()
                .zip(fl[2..].iter_mut())
                .zip(&x[2..])
                .zip(&x[1..])
                .zip(x)
            {
                *oh = h[0] * x0 + h[1] * x1 + h[2] * x2;
                *ol = g[0] * x0 + g[1] * x1 + g[2] * x2;
            }
        }
        // Two samples per step from y[n−1], y[n−2]:
        //   y[n]   = f[n] − a1·y[n−1] − a2·y[n−2]
        //   y[n+1] = (f[n+1] − a1·f[n]) + (a1² − a2)·y[n−1] + a1·a2·y[n−2]
        // (y[n] substituted), which halves the recursion's latency per sample.
        let (hc1, hc2) = (h[3] * h[3] - h[4], h[3] * h[4]);
        let (gc1, gc2) = (g[3] * g[3] - g[4], g[3] * g[4]);
        let (mut yh1, mut yh2, mut yl1, mut yl2) = (0.0, 0.0, 0.0, 0.0);
        let mut ph = self.eh.chunks_exact_mut(2);
        let mut pl = self.el.chunks_exact_mut(2);
        for (fh, fl) in (&mut ph).zip(&mut pl) {
            let yh0 = (fh[0] - h[4] * yh2) - h[3] * yh1;
            let yh_1 = ((fh[1] - h[3] * fh[0]) + hc2 * yh2) + hc1 * yh1;
            let yl0 = (fl[0] - g[4] * yl2) - g[3] * yl1;
            let yl_1 = ((fl[1] - g[3] * fl[0]) + gc2 * yl2) + gc1 * yl1;
            (yh2, yh1, yl2, yl1) = (yh0, yh_1, yl0, yl_1);
            fh[0] = yh0 * yh0;
            fh[1] = yh_1 * yh_1;
            fl[0] = yl0 * yl0;
            fl[1] = yl_1 * yl_1;
        }
        for (fh, fl) in ph.into_remainder().iter_mut().zip(pl.into_remainder()) {
            let yh = (*fh - h[4] * yh2) - h[3] * yh1;
            let yl = (*fl - g[4] * yl2) - g[3] * yl1;
            *fh = yh * yh;
            *fl = yl * yl;
        }
        let settle = self.settle;
        let (eh, el) = (&self.eh[settle..], &self.el[settle..]);
        // High band: moments of e = y², and the crest of its block sums.
        let (mut hm2, mut hm4, mut hmax_blk, mut hsum_blk, mut nblk) =
            (0.0, 0.0, 0.0f64, 0.0, 0usize);
        let mut blocks = eh.chunks_exact(eb);
        for c in &mut blocks {
            let (s, s2) = sum_sumsq4(c);
            hmax_blk = hmax_blk.max(s);
            hsum_blk += s;
            hm4 += s2;
            nblk += 1;
        }
        let (rs, rs2) = sum_sumsq4(blocks.remainder());
        hm2 += hsum_blk + rs;
        hm4 += rs2;
        let cnt = eh.len().max(1) as f64;
        let (hm2, hm4) = (hm2 / cnt, hm4 / cnt);
        out[i + 5] = if hm2 > 0.0 {
            (hm4 / (hm2 * hm2)).max(1e-12).ln()
        } else {
            0.0
        };
        let hmean_blk = hsum_blk / nblk.max(1) as f64;
        out[i + 6] = 10.0 * ((hmax_blk + tiny) / (hmean_blk + tiny)).log10();
        // Low band: its energy envelope in blocks of lf_block samples (a
        // frame shorter than one block leaves everything in the first).
        let lfb = self.lf_block;
        if el.len() < lfb {
            self.lf_env.fill(0.0);
            self.lf_env[0] = sum4(el);
        } else {
            for (dst, c) in self.lf_env.iter_mut().zip(el.chunks_exact(lfb)) {
                *dst = sum4(c);
            }
        }
        out[i + 7] = periodicity(&mut self.lf_env, self.lf_lag_lo, self.lf_lag_hi);
        // 6. Optional: energy shares of fixed bands of the recorded spectrum.
        if let Some(FixedBins {
            bands,
            reference: (r0, r1),
        }) = self.fixed
        {
            // (Their own floor, so that nothing here depends on the warp.)
            let mp = &self.mean_pow;
            let total = sum4(&mp[r0..r1]);
            let floor = 1e-10 * total / (r1 - r0).max(1) as f64 + 1e-300;
            for (o, &(b0, b1)) in out[i + 8..].iter_mut().zip(&bands) {
                *o = ((sum4(&mp[b0..b1]) + floor) / (total + floor)).ln();
            }
        }
    }
}
