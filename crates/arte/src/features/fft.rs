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

    /// Power spectrum |X[k]|², k = 0..=n/2, into `out`: the same values as
    /// `forward` then `norm_sqr`. `spec` (length n/2 + 1) is no longer
    /// needed as scratch and is left untouched.
    pub(crate) fn forward_power(&mut self, x: &[f64], spec: &mut [Complex<f64>], out: &mut [f64]) {
        debug_assert_eq!(spec.len(), self.n / 2 + 1);
        self.forward_power_windowed(x, None, out);
    }

    /// Power spectrum |X[k]|², k = 0..=n/2, of `x · window` (element-wise;
    /// `x` zero-padded to n, `x.len()` ≤ n, `window.len()` = n) into `out`
    /// (length n/2 + 1). The products `x[i]·window[i]` and every later
    /// operation are those of `forward` on the windowed input, so the values
    /// are identical; the windowing is fused into the packing and bins k
    /// and n/2 − k share their even/odd split.
    pub(crate) fn forward_power_windowed(
        &mut self,
        x: &[f64],
        window: Option<&[f64]>,
        out: &mut [f64],
    ) {
        let half = self.n / 2;
        debug_assert!(x.len() <= self.n);
        debug_assert_eq!(out.len(), half + 1);
        let m = x.len().min(self.n);
        let pairs = m / 2;
        let (head, tail) = self.buf.split_at_mut(pairs);
        match window {
            Some(w) => {
                debug_assert_eq!(w.len(), self.n);
                for ((b, xc), wc) in head
                    .iter_mut()
                    .zip(x[..2 * pairs].chunks_exact(2))
                    .zip(w.chunks_exact(2))
                {
                    *b = Complex::new(xc[0] * wc[0], xc[1] * wc[1]);
                }
                if let Some(b) = tail.first_mut() {
                    *b = Complex::new(if m % 2 == 1 { x[m - 1] * w[m - 1] } else { 0.0 }, 0.0);
                }
            }
            None => {
                for (b, xc) in head.iter_mut().zip(x[..2 * pairs].chunks_exact(2)) {
                    *b = Complex::new(xc[0], xc[1]);
                }
                if let Some(b) = tail.first_mut() {
                    *b = Complex::new(if m % 2 == 1 { x[m - 1] } else { 0.0 }, 0.0);
                }
            }
        }
        for b in tail.iter_mut().skip(1) {
            *b = Complex::new(0.0, 0.0);
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        let buf = &self.buf[..half];
        let tw = &self.twiddle[..=half];
        let out = &mut out[..=half];
        let z0 = buf[0];
        out[0] = Complex::new(z0.re + z0.im, 0.0).norm_sqr();
        out[half] = Complex::new(z0.re - z0.im, 0.0).norm_sqr();
        // Bins k and half − k from one even/odd split: with
        // e = (z_k + conj z_{h−k})/2 and o = −i (z_k − conj z_{h−k})/2,
        // bin h−k has exactly conj e and conj o (negation and commutation
        // are exact in IEEE arithmetic).
        for k in 1..=half / 2 {
            let zk = buf[k];
            let zc = buf[half - k].conj();
            let even = (zk + zc) * 0.5;
            let odd = (zk - zc) * Complex::new(0.0, -0.5);
            out[k] = (even + tw[k] * odd).norm_sqr();
            if half - k != k {
                out[half - k] = (even.conj() + tw[half - k] * odd.conj()).norm_sqr();
            }
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

    #[test]
    fn power_paths_equal_forward_norm_sqr() {
        for (n, len) in [
            (64, 50),
            (64, 64),
            (64, 33),
            (1024, 1024),
            (1024, 7),
            (2, 1),
            (8, 0),
        ] {
            let x: Vec<f64> = (0..len)
                .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3 + (i as f64 * 0.2).sin())
                .collect();
            let w: Vec<f64> = (0..n).map(|i| 0.3 + (i as f64 * 0.1).cos().abs()).collect();
            let xw: Vec<f64> = x.iter().zip(&w).map(|(a, b)| a * b).collect();
            let mut r = RealFft::new(n);
            let mut spec = vec![Complex::new(0.0, 0.0); n / 2 + 1];
            r.forward(&xw, &mut spec);
            let want: Vec<f64> = spec.iter().map(|s| s.norm_sqr()).collect();
            let mut got = vec![0.0; n / 2 + 1];
            r.forward_power_windowed(&x, Some(&w), &mut got);
            assert_eq!(got, want, "windowed, n {n}, len {len}");
            r.forward(&x, &mut spec);
            let want: Vec<f64> = spec.iter().map(|s| s.norm_sqr()).collect();
            let mut got = vec![0.0; n / 2 + 1];
            r.forward_power(&x, &mut spec, &mut got);
            assert_eq!(got, want, "plain, n {n}, len {len}");
        }
    }
}
