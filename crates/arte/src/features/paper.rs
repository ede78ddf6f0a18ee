//! The paper's 20 features: 10 LPC, 5 power-spectrum, 5 real-cepstrum
//! coefficients of one Hamming-windowed frame (exact definitions in the
//! crate README, "Features").

use super::fft::RealFft;
use super::lpc::levinson_durbin;
use super::{FeatureConfig, N_CEP, N_LPC, N_PS, fast_ln, hamming};
use rustfft::num_complex::Complex;

pub(crate) struct Paper {
    window: Vec<f64>,
    frame_len: usize,
    fft: RealFft,
    xw: Vec<f64>,
    spec: Vec<Complex<f64>>,
    power: Vec<f64>,
    /// |H(f_k)|² of the pre-filter per bin.
    h2: Vec<f64>,
    /// Pre-filtered power.
    pf: Vec<f64>,
    /// cos(2π k m / N) · w_k for m = 0..=N_LPC, k = 0..=N/2, where w_k is the
    /// one-sided weight (1 at k = 0 and N/2, else 2), row-major by m.
    cos_tab: Vec<f64>,
    /// Bin ranges [lo, hi) of the 5 power-spectrum bands.
    bands: [(usize, usize); N_PS],
    r: Vec<f64>,
    a: Vec<f64>,
    lev_scratch: Vec<f64>,
    logmag: Vec<f64>,
}

impl Paper {
    pub(crate) fn new(cfg: &FeatureConfig, frame_len: usize) -> Self {
        let nfft = (frame_len + N_LPC).next_power_of_two().max(64);
        let nb = nfft / 2 + 1;
        let fs = f64::from(cfg.sample_rate);
        let df = fs / nfft as f64;
        let h2: Vec<f64> = (0..nb)
            .map(|k| {
                let f = k as f64 * df;
                let hp = match cfg.prefilter.highpass_hz {
                    Some(_) if f <= 0.0 => 0.0,
                    Some(fc) => 1.0 / (1.0 + (fc / f).powi(4)),
                    None => 1.0,
                };
                let lp = match cfg.prefilter.lowpass_hz {
                    Some(fc) => 1.0 / (1.0 + (f / fc).powi(8)),
                    None => 1.0,
                };
                hp * lp
            })
            .collect();
        let mut cos_tab = vec![0.0; (N_LPC + 1) * nb];
        for m in 0..=N_LPC {
            for k in 0..nb {
                let w = if k == 0 || k == nb - 1 { 1.0 } else { 2.0 };
                let ph = 2.0 * std::f64::consts::PI * ((k * m) % nfft) as f64 / nfft as f64;
                cos_tab[m * nb + k] = w * ph.cos();
            }
        }
        // Power-spectrum bands: 5 geometric bands between the pre-filter
        // edges (or 100 Hz and 0.45·fs when open).
        let lo = cfg.prefilter.highpass_hz.unwrap_or(100.0);
        let hi = cfg.prefilter.lowpass_hz.unwrap_or(0.45 * fs);
        let mut bands = [(0usize, 0usize); N_PS];
        let ratio = (hi / lo).powf(1.0 / N_PS as f64);
        for (i, b) in bands.iter_mut().enumerate() {
            let f0 = lo * ratio.powi(i as i32);
            let f1 = lo * ratio.powi(i as i32 + 1);
            let k0 = ((f0 / df).round() as usize).min(nb - 1);
            let k1 = ((f1 / df).round() as usize).clamp(k0 + 1, nb);
            *b = (k0, k1);
        }
        Self {
            window: hamming(frame_len),
            frame_len,
            fft: RealFft::new(nfft),
            xw: vec![0.0; frame_len],
            spec: vec![Complex::new(0.0, 0.0); nb],
            power: vec![0.0; nb],
            h2,
            pf: vec![0.0; nb],
            cos_tab,
            bands,
            r: vec![0.0; N_LPC + 1],
            a: vec![0.0; N_LPC + 1],
            lev_scratch: vec![0.0; N_LPC + 1],
            logmag: vec![0.0; nb],
        }
    }

    pub(crate) fn nfft(&self) -> usize {
        self.fft.len()
    }

    pub(crate) fn power(&self) -> &[f64] {
        &self.power
    }

    /// `x`: DC-removed frame (length frame_len); `out`: 20 values.
    pub(crate) fn extract(&mut self, x: &[f64], out: &mut [f64]) {
        let nb = self.power.len();
        let nfft = self.fft.len() as f64;
        for i in 0..self.frame_len {
            self.xw[i] = x[i] * self.window[i];
        }
        self.fft
            .forward_power(&self.xw, &mut self.spec, &mut self.power);
        let mut total = 0.0;
        for k in 0..nb {
            self.pf[k] = self.power[k] * self.h2[k];
            total += self.pf[k];
        }
        // LPC: biased autocorrelation of the pre-filtered windowed frame by
        // Wiener-Khinchin (exact, no circular aliasing since nfft ≥ L + p).
        let norm = 1.0 / (nfft * self.frame_len as f64);
        for m in 0..=N_LPC {
            let row = &self.cos_tab[m * nb..(m + 1) * nb];
            let mut acc = 0.0;
            for k in 0..nb {
                acc += self.pf[k] * row[k];
            }
            self.r[m] = acc * norm;
        }
        // Tiny white-noise floor (−100 dB) keeps the recursion well posed.
        self.r[0] *= 1.0 + 1e-10;
        levinson_durbin(&self.r, &mut self.a, &mut self.lev_scratch);
        out[..N_LPC].copy_from_slice(&self.a[1..=N_LPC]);
        // Power spectrum: log band-power fractions (dB).
        let mut band_total = 0.0;
        for &(k0, k1) in &self.bands {
            band_total += self.pf[k0..k1].iter().sum::<f64>();
        }
        let eps = 1e-12 * band_total + 1e-300;
        for (i, &(k0, k1)) in self.bands.iter().enumerate() {
            let p: f64 = self.pf[k0..k1].iter().sum();
            out[N_LPC + i] = 10.0 * ((p + eps) / (band_total + N_PS as f64 * eps)).log10();
        }
        // Real cepstrum of the pre-filtered spectrum: c[n] = IDFT(ln|X_f|)[n].
        let floor = 1e-10 * total / nb as f64 + 1e-300;
        for k in 0..nb {
            self.logmag[k] = 0.5 * fast_ln(self.pf[k] + floor);
        }
        cepstrum_from_logmag(
            &self.logmag,
            &self.cos_tab,
            nfft,
            &mut out[N_LPC + N_PS..N_LPC + N_PS + N_CEP],
        );
    }
}

/// c[n] = (1/N) Σ_{k=0}^{N−1} L[k] cos(2πkn/N) for n = 1..=out.len(), from the
/// one-sided log magnitude L[0..=N/2] (even symmetry) and the weighted cosine
/// table (row m holds w_k cos(2πkm/N)).
fn cepstrum_from_logmag(logmag: &[f64], cos_tab: &[f64], nfft: f64, out: &mut [f64]) {
    let nb = logmag.len();
    for (i, o) in out.iter_mut().enumerate() {
        let n = i + 1;
        let row = &cos_tab[n * nb..(n + 1) * nb];
        let mut acc = 0.0;
        for k in 0..nb {
            acc += logmag[k] * row[k];
        }
        *o = acc / nfft;
    }
}

/// The real cepstrum c[0..n_out] = IDFT(ln|DFT(x)|) of `x` zero-padded to
/// `nfft` (even, ≥ x.len()), no window. A floor of 1e-12 times the mean
/// magnitude keeps ln finite. Reference implementation (allocates) for tests
/// and tools; the extractor uses the same formula on the windowed frame.
pub fn real_cepstrum(x: &[f64], nfft: usize, n_out: usize) -> Vec<f64> {
    let nfft = nfft.max(x.len()).max(2).next_multiple_of(2);
    let nb = nfft / 2 + 1;
    let mut fft = RealFft::new(nfft);
    let mut spec = vec![Complex::new(0.0, 0.0); nb];
    fft.forward(x, &mut spec);
    let mean: f64 = spec.iter().map(|c| c.norm()).sum::<f64>() / nb as f64;
    let logmag: Vec<f64> = spec
        .iter()
        .map(|c| (c.norm() + 1e-12 * mean + 1e-300).ln())
        .collect();
    (0..n_out)
        .map(|n| {
            let mut acc = 0.0;
            for (k, l) in logmag.iter().enumerate() {
                let w = if k == 0 || k == nb - 1 { 1.0 } else { 2.0 };
                acc += w
                    * l
                    * (2.0 * std::f64::consts::PI * ((k * n) % nfft) as f64 / nfft as f64).cos();
            }
            acc / nfft as f64
        })
        .collect()
}
