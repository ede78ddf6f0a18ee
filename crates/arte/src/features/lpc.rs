//! Linear prediction: biased autocorrelation and the Levinson-Durbin recursion.
//!
//! Convention (MATLAB `lpc`, Makhoul 1975 "Linear prediction: a tutorial
//! review", Proc. IEEE 63(4)): the prediction-error filter is
//! A(z) = 1 + a₁ z⁻¹ + … + a_p z⁻ᵖ, so an AR process
//! `x[n] = φ₁ x[n−1] + φ₂ x[n−2] + e[n]` has a₁ = −φ₁, a₂ = −φ₂.

/// Biased autocorrelation `r[m] = (1/L) Σₙ x[n] x[n+m]`, m = 0..out.len().
pub fn autocorrelation_biased(x: &[f64], out: &mut [f64]) {
    let l = x.len().max(1) as f64;
    for (m, o) in out.iter_mut().enumerate() {
        let mut acc = 0.0;
        if m < x.len() {
            for n in 0..x.len() - m {
                acc += x[n] * x[n + m];
            }
        }
        *o = acc / l;
    }
}

/// Levinson-Durbin: solves the Toeplitz normal equations
/// `Σⱼ aⱼ r[|i−j|] = −r[i]`, i = 1..=p, for a = `a[1..=p]` (`a[0]` is set to 1),
/// with p = `a.len() − 1` and `r.len()` ≥ p + 1. `scratch` must have length
/// ≥ p + 1. Returns the final prediction-error power.
///
/// Degenerate input (`r[0]` ≤ 0, non-finite, or a reflection coefficient with
/// |k| ≥ 1 from round-off) stops the recursion: the remaining coefficients
/// are 0, so the result is always finite. Allocates nothing.
pub fn levinson_durbin(r: &[f64], a: &mut [f64], scratch: &mut [f64]) -> f64 {
    let p = a.len().saturating_sub(1);
    a.fill(0.0);
    if a.is_empty() {
        return 0.0;
    }
    a[0] = 1.0;
    let r0 = r.first().copied().unwrap_or(0.0);
    if !(r0.is_finite() && r0 > 0.0) || r.len() < p + 1 {
        return r0.max(0.0);
    }
    let mut err = r0;
    for i in 1..=p {
        let mut acc = r[i];
        for j in 1..i {
            acc += a[j] * r[i - j];
        }
        let k = -acc / err;
        if !k.is_finite() || k.abs() >= 1.0 {
            break;
        }
        scratch[..i].copy_from_slice(&a[..i]);
        for j in 1..i {
            a[j] = scratch[j] + k * scratch[i - j];
        }
        a[i] = k;
        err *= 1.0 - k * k;
        if err <= r0 * 1e-14 {
            break;
        }
    }
    err
}
