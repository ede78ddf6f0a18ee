//! The Rich set: 43 level-invariant features (for 24 mel bands) that capture
//! what separates tyre-road sounds: spectral shape, within-frame temporal
//! variability, spectral descriptors and impact statistics. Every feature is
//! invariant to the microphone gain (a scale of the signal), so level, which
//! depends on gain and speed, never decides the class. Exact definitions in
//! the crate README ("Features", "Rich").

use super::fft::RealFft;
use super::{FeatureConfig, fast_ln, hann};
use rustfft::num_complex::Complex;

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

pub(crate) fn dim(n_mel: usize) -> usize {
    n_mel + N_GROUPS + SCALARS.len()
}

pub(crate) fn names(n_mel: usize) -> Vec<String> {
    (1..=n_mel)
        .map(|i| format!("mel_{i}"))
        .chain((1..=N_GROUPS).map(|i| format!("mel_std_{i}")))
        .chain(SCALARS.iter().map(|s| (*s).to_string()))
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
    xs: Vec<f64>,
    spec: Vec<Complex<f64>>,
    /// Power spectrum of each sub-frame, row-major (n_sub × nb).
    sub_pow: Vec<f64>,
    mean_pow: Vec<f64>,
    /// Mel filters: (first bin, weights) flattened: `mel_start[b]`,
    /// `mel_w[mel_off[b]..mel_off[b+1]]`.
    mel_start: Vec<usize>,
    mel_off: Vec<usize>,
    mel_w: Vec<f64>,
    /// Bin range [k_lo, k_hi) used for the spectral descriptors.
    k_lo: usize,
    k_hi: usize,
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
fn periodicity(e: &mut [f64], lo: usize, hi: usize) -> f64 {
    let n = e.len();
    let mean = e.iter().sum::<f64>() / n.max(1) as f64;
    let mut e0 = 0.0;
    for v in e.iter_mut() {
        *v -= mean;
        e0 += *v * *v;
    }
    let mut best = 0.0f64;
    if e0 > 0.0 {
        for lag in lo..=hi.max(lo) {
            if lag >= n {
                break;
            }
            let mut acc = 0.0;
            for j in 0..n - lag {
                acc += e[j] * e[j + lag];
            }
            best = best.max(acc / e0);
        }
    }
    best
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
        let df = fs / sub_len as f64;
        let fmax = MEL_FMAX.min(0.5 * fs);
        let (m0, m1) = (hz_to_mel(MEL_FMIN), hz_to_mel(fmax));
        let n_mel = cfg.n_mel;
        let pts: Vec<f64> = (0..n_mel + 2)
            .map(|i| mel_to_hz(m0 + (m1 - m0) * i as f64 / (n_mel + 1) as f64))
            .collect();
        let mut mel_start = Vec::with_capacity(n_mel);
        let mut mel_off = vec![0];
        let mut mel_w = Vec::new();
        for b in 0..n_mel {
            let (fl, fc, fh) = (pts[b], pts[b + 1], pts[b + 2]);
            let k0 = (fl / df).floor() as usize;
            let k1 = ((fh / df).ceil() as usize).min(nb - 1);
            let mut w: Vec<f64> = (k0..=k1)
                .map(|k| {
                    let f = k as f64 * df;
                    if f <= fl || f >= fh {
                        0.0
                    } else if f <= fc {
                        (f - fl) / (fc - fl)
                    } else {
                        (fh - f) / (fh - fc)
                    }
                })
                .collect();
            if w.iter().all(|&v| v == 0.0) {
                // Band narrower than a bin: take the bin nearest its centre.
                let kc = ((fc / df).round() as usize).clamp(k0, k1);
                w[kc - k0] = 1.0;
            }
            mel_start.push(k0);
            mel_w.extend_from_slice(&w);
            mel_off.push(mel_w.len());
        }
        let env_block = ((0.000_725 * fs).round() as usize).max(1);
        let n_env = frame_len / env_block;
        let lag_lo = ((0.004 * fs) / env_block as f64).ceil() as usize;
        let lag_hi = (((0.060 * fs) / env_block as f64).floor() as usize).min(n_env / 2);
        let n_sub = starts.len();
        let lf_block = ((0.002 * fs).round() as usize).max(1);
        let settle = ((0.005 * fs).round() as usize).min(frame_len / 4);
        let n_lf = (frame_len - settle) / lf_block;
        Self {
            hp: biquad(fs, 3000.0, true),
            lp: biquad(fs, 400.0, false),
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
            xs: vec![0.0; sub_len],
            spec: vec![Complex::new(0.0, 0.0); nb],
            sub_pow: vec![0.0; n_sub * nb],
            mean_pow: vec![0.0; nb],
            mel_start,
            mel_off,
            mel_w,
            k_lo: ((MEL_FMIN / df).ceil() as usize).max(1),
            k_hi: ((fmax / df).floor() as usize + 1).min(nb),
            mel_e: vec![0.0; n_mel],
            group_log: vec![0.0; n_sub * N_GROUPS],
            norm_prev: vec![0.0; nb],
            norm_cur: vec![0.0; nb],
            env_block,
            env: vec![0.0; n_env.max(1)],
            lag_lo,
            lag_hi,
            starts,
        }
    }

    pub(crate) fn nfft(&self) -> usize {
        self.sub_len
    }

    pub(crate) fn power(&self) -> &[f64] {
        &self.mean_pow
    }

    fn mel_energies(&self, pow: &[f64], out: &mut [f64]) {
        for b in 0..self.n_mel {
            let k0 = self.mel_start[b];
            let w = &self.mel_w[self.mel_off[b]..self.mel_off[b + 1]];
            let mut acc = 0.0;
            for (j, &wj) in w.iter().enumerate() {
                acc += wj * pow[k0 + j];
            }
            out[b] = acc;
        }
    }

    /// `x`: DC-removed frame (length frame_len); `out`: dim values.
    pub(crate) fn extract(&mut self, x: &[f64], out: &mut [f64]) {
        let nb = self.sub_len / 2 + 1;
        let n_sub = self.starts.len();
        // Sub-frame power spectra and their mean (Welch).
        self.mean_pow.fill(0.0);
        for s in 0..n_sub {
            let st = self.starts[s];
            for i in 0..self.sub_len {
                self.xs[i] = x.get(st + i).copied().unwrap_or(0.0) * self.window[i];
            }
            let row = &mut self.sub_pow[s * nb..(s + 1) * nb];
            self.fft.forward_power(&self.xs, &mut self.spec, row);
            for k in 0..nb {
                self.mean_pow[k] += row[k] / n_sub as f64;
            }
        }
        let total: f64 = self.mean_pow[self.k_lo..self.k_hi].iter().sum();
        let floor = 1e-10 * total / (self.k_hi - self.k_lo) as f64 + 1e-300;

        // 1. Mel shape: ln band energy minus its mean over bands.
        let mut mel_e = std::mem::take(&mut self.mel_e);
        self.mel_energies(&self.mean_pow, &mut mel_e);
        let mut mean_log = 0.0;
        for (b, e) in mel_e.iter().enumerate() {
            out[b] = (e + floor).ln();
            mean_log += out[b] / self.n_mel as f64;
        }
        for o in out[..self.n_mel].iter_mut() {
            *o -= mean_log;
        }
        // 2. Within-frame variability: std over sub-frames of the ln energy of
        //    N_GROUPS groups of adjacent mel bands.
        let per = self.n_mel / N_GROUPS;
        for s in 0..n_sub {
            let row = &self.sub_pow[s * nb..(s + 1) * nb];
            self.mel_energies(row, &mut mel_e);
            for g in 0..N_GROUPS {
                let lo = g * per;
                let hi = if g + 1 == N_GROUPS {
                    self.n_mel
                } else {
                    lo + per
                };
                let e: f64 = mel_e[lo..hi].iter().sum();
                self.group_log[s * N_GROUPS + g] = (e + floor).ln();
            }
        }
        self.mel_e = mel_e;
        for g in 0..N_GROUPS {
            let mut m = 0.0;
            for s in 0..n_sub {
                m += self.group_log[s * N_GROUPS + g];
            }
            m /= n_sub as f64;
            let mut v = 0.0;
            for s in 0..n_sub {
                let d = self.group_log[s * N_GROUPS + g] - m;
                v += d * d;
            }
            out[self.n_mel + g] = (v / n_sub as f64).sqrt();
        }
        let mut i = self.n_mel + N_GROUPS;
        // 3. Spectral flux: mean squared difference of unit-norm magnitude
        //    spectra of consecutive sub-frames.
        let mut flux = 0.0;
        for s in 0..n_sub {
            let row = &self.sub_pow[s * nb..(s + 1) * nb];
            let mut n2 = 0.0;
            for k in self.k_lo..self.k_hi {
                n2 += row[k];
            }
            let inv = 1.0 / (n2 + floor).sqrt();
            for k in self.k_lo..self.k_hi {
                self.norm_cur[k] = row[k].sqrt() * inv;
            }
            if s > 0 {
                let mut d = 0.0;
                for k in self.k_lo..self.k_hi {
                    let e = self.norm_cur[k] - self.norm_prev[k];
                    d += e * e;
                }
                flux += d / (n_sub - 1) as f64;
            }
            std::mem::swap(&mut self.norm_cur, &mut self.norm_prev);
        }
        out[i] = flux;
        i += 1;
        // 4. Spectral descriptors of the mean spectrum over [50 Hz, 16 kHz].
        let df = self.fs / self.sub_len as f64;
        let (mut p_sum, mut pf_sum, mut ln_sum) = (0.0, 0.0, 0.0);
        for k in self.k_lo..self.k_hi {
            let p = self.mean_pow[k] + floor;
            p_sum += p;
            pf_sum += p * k as f64 * df;
            ln_sum += fast_ln(p);
        }
        let nk = (self.k_hi - self.k_lo) as f64;
        let centroid = pf_sum / p_sum;
        let mut var = 0.0;
        let mut cum = 0.0;
        let mut rolloff = (self.k_hi - 1) as f64 * df;
        let mut rolled = false;
        for k in self.k_lo..self.k_hi {
            let p = self.mean_pow[k] + floor;
            let f = k as f64 * df;
            var += p * (f - centroid) * (f - centroid);
            cum += p;
            if !rolled && cum >= 0.85 * p_sum {
                rolloff = f;
                rolled = true;
            }
        }
        out[i] = centroid / 1000.0;
        out[i + 1] = (var / p_sum).sqrt() / 1000.0;
        out[i + 2] = rolloff / 1000.0;
        out[i + 3] = 10.0 * (ln_sum / nk - (p_sum / nk).ln()) / std::f64::consts::LN_10;
        i += 4;
        // 5. Time domain: zero-crossing rate, crest factor, and impact
        //    statistics of the first difference d[n] = x[n] − x[n−1].
        let l = self.frame_len;
        let mut zc = 0usize;
        let (mut peak, mut sq) = (0.0f64, 0.0);
        for n in 0..l {
            if n > 0 && (x[n] >= 0.0) != (x[n - 1] >= 0.0) {
                zc += 1;
            }
            peak = peak.max(x[n].abs());
            sq += x[n] * x[n];
        }
        let rms = (sq / l as f64).sqrt();
        out[i] = zc as f64 / (l - 1) as f64 * self.fs / 1000.0;
        let tiny = 1e-30;
        out[i + 1] = 20.0 * ((peak + tiny) / (rms + tiny)).log10();
        let (mut m2, mut m4) = (0.0, 0.0);
        let nenv = self.env.len();
        self.env.fill(0.0);
        for n in 1..l {
            let d = x[n] - x[n - 1];
            let d2 = d * d;
            m2 += d2;
            m4 += d2 * d2;
            let j = n / self.env_block;
            if j < nenv {
                self.env[j] += d2;
            }
        }
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
        let (h, g) = (self.hp, self.lp);
        let (mut h1, mut h2, mut g1, mut g2) = (0.0, 0.0, 0.0, 0.0);
        let (mut hm2, mut hm4, mut hmax_blk, mut hblk, mut hsum_blk, mut nblk) =
            (0.0, 0.0, 0.0f64, 0.0, 0.0, 0usize);
        let mut cnt = 0usize;
        self.lf_env.fill(0.0);
        let nlf = self.lf_env.len();
        for n in 0..l {
            let v = x[n];
            let yh = h[0] * v + h1;
            h1 = h[1] * v - h[3] * yh + h2;
            h2 = h[2] * v - h[4] * yh;
            let yl = g[0] * v + g1;
            g1 = g[1] * v - g[3] * yl + g2;
            g2 = g[2] * v - g[4] * yl;
            if n < self.settle {
                continue;
            }
            let k = n - self.settle;
            let e = yh * yh;
            hm2 += e;
            hm4 += e * e;
            cnt += 1;
            hblk += e;
            if (k + 1).is_multiple_of(self.env_block) {
                hmax_blk = hmax_blk.max(hblk);
                hsum_blk += hblk;
                nblk += 1;
                hblk = 0.0;
            }
            let j = k / self.lf_block;
            if j < nlf {
                self.lf_env[j] += yl * yl;
            }
        }
        let (hm2, hm4) = (hm2 / cnt.max(1) as f64, hm4 / cnt.max(1) as f64);
        out[i + 5] = if hm2 > 0.0 {
            (hm4 / (hm2 * hm2)).max(1e-12).ln()
        } else {
            0.0
        };
        let hmean_blk = hsum_blk / nblk.max(1) as f64;
        out[i + 6] = 10.0 * ((hmax_blk + tiny) / (hmean_blk + tiny)).log10();
        out[i + 7] = periodicity(&mut self.lf_env, self.lf_lag_lo, self.lf_lag_hi);
    }
}
