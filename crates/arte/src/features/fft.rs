//! Real-input FFT on top of rustfft: an N-point real transform computed with
//! one N/2-point complex transform (the standard "pack even/odd samples into
//! re/im" method, e.g. Lyons, *Understanding DSP*, 3rd ed., §13.5.2).
//! Planned once; `forward_power` allocates nothing.

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// A planned real FFT of a fixed even length `n`.
pub(crate) struct RealFft {
    n: usize,
    fft: Arc<dyn Fft<f64>>,
    buf: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    /// e^{-2πik/n} for k = 0..n/2.
    twiddle: Vec<Complex<f64>>,
}

impl RealFft {
    /// Plans an `n`-point real FFT; `n` must be even and ≥ 2.
    pub(crate) fn new(n: usize) -> Self {
        assert!(
            n >= 2 && n.is_multiple_of(2),
            "real FFT length must be even"
        );
        let half = n / 2;
        let fft = FftPlanner::<f64>::new().plan_fft_forward(half);
        let scratch = vec![Complex::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        let twiddle = (0..=half)
            .map(|k| {
                let ph = -2.0 * std::f64::consts::PI * k as f64 / n as f64;
                Complex::new(ph.cos(), ph.sin())
            })
            .collect();
        Self {
            n,
            fft,
            buf: vec![Complex::new(0.0, 0.0); half],
            scratch,
            twiddle,
        }
    }

    /// Transform length.
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// Computes the spectrum X[k], k = 0..=n/2, of the real input `x`
    /// (zero-padded to n; `x.len()` ≤ n) into `out` (length n/2 + 1).
    pub(crate) fn forward(&mut self, x: &[f64], out: &mut [Complex<f64>]) {
        let half = self.n / 2;
        debug_assert!(x.len() <= self.n);
        debug_assert_eq!(out.len(), half + 1);
        for (i, b) in self.buf.iter_mut().enumerate() {
            let re = x.get(2 * i).copied().unwrap_or(0.0);
            let im = x.get(2 * i + 1).copied().unwrap_or(0.0);
            *b = Complex::new(re, im);
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        let z0 = self.buf[0];
        out[0] = Complex::new(z0.re + z0.im, 0.0);
        out[half] = Complex::new(z0.re - z0.im, 0.0);
        for k in 1..half {
            let zk = self.buf[k];
            let zc = self.buf[half - k].conj();
            let even = (zk + zc) * 0.5;
            let odd = (zk - zc) * Complex::new(0.0, -0.5);
            out[k] = even + self.twiddle[k] * odd;
        }
    }

    /// Power spectrum |X[k]|², k = 0..=n/2, into `out`, using `spec` as
    /// scratch (length n/2 + 1).
    pub(crate) fn forward_power(&mut self, x: &[f64], spec: &mut [Complex<f64>], out: &mut [f64]) {
        self.forward(x, spec);
        for (o, s) in out.iter_mut().zip(spec.iter()) {
            *o = s.norm_sqr();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_complex_fft() {
        let n = 64;
        let x: Vec<f64> = (0..50)
            .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3 + (i as f64 * 0.2).sin())
            .collect();
        let mut r = RealFft::new(n);
        let mut out = vec![Complex::new(0.0, 0.0); n / 2 + 1];
        r.forward(&x, &mut out);
        let mut full: Vec<Complex<f64>> = (0..n)
            .map(|i| Complex::new(x.get(i).copied().unwrap_or(0.0), 0.0))
            .collect();
        FftPlanner::<f64>::new()
            .plan_fft_forward(n)
            .process(&mut full);
        for k in 0..=n / 2 {
            assert!(
                (out[k] - full[k]).norm() < 1e-9,
                "bin {k}: {} vs {}",
                out[k],
                full[k]
            );
        }
    }
}
