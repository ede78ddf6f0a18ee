//! Vinnicombe's ν-gap between two SISO plants.
//!
//! δ_ν(P1, P2) = sup_ω κ(P1(jω), P2(jω)) if the winding-number condition
//! holds, else 1, with the chordal distance
//!
//! ```text
//! κ(p1, p2) = |p1 - p2| / sqrt((1 + |p1|²)(1 + |p2|²))
//! ```
//!
//! and the condition (Vinnicombe 1993; Zhou & Doyle, *Essentials of Robust
//! Control*, 1998, §17.2)
//!
//! ```text
//! 1 + P2~(jω) P1(jω) ≠ 0 for all ω in [-∞, ∞]   and
//! wno(1 + P2~ P1) + η(P1) - η(P2) - η₀(P2) = 0,
//! ```
//!
//! P2~(s) = P2(-s), η = open right-half-plane poles, η₀ = imaginary-axis
//! poles, wno = winding number about the origin on the Nyquist contour that
//! is indented around imaginary-axis poles so that they lie outside it.
//!
//! **Winding number by the argument principle on polynomials.** With
//! P1 = n1/d1 and P2 = n2/d2 (coprime: common factors are removed first by
//! [`Tf::minreal`]),
//!
//! ```text
//! g(s) = 1 + P2(-s) P1(s) = N(s) / D(s),
//! N(s) = d2(-s) d1(s) + n2(-s) n1(s),   D(s) = d2(-s) d1(s).
//! ```
//!
//! On the indented contour wno(g) = Z - P with Z (P) the roots of N (D) in
//! the open right half plane; roots on the imaginary axis lie outside the
//! indented contour and are not counted, and common roots of N and D in the
//! right half plane add one to both Z and P, so they need no cancellation.
//! The first condition fails when N has an imaginary-axis root that is not
//! matched (with multiplicity) by a root of D, or when g(∞) = 0, i.e.
//! deg N < deg D (a leading coefficient of N that cancels to rounding noise
//! is treated as zero, see [`Poly::add`]). This replaces phase unwrapping on a
//! frequency grid, which needs indentation and can miss fast phase turns.
//! Roots count as "on the axis" within [`super::tf::AXIS_TOL`].
//!
//! **The supremum.** κ is evaluated in homogeneous form,
//! κ = |n1 d2 - n2 d1| / sqrt((|n1|² + |d1|²)(|n2|² + |d2|²)), which is finite
//! at poles (including poles on the axis and at ω = 0) and at ω = ∞ (using
//! the coefficients of the top degree). It is evaluated at ω = 0, ω = ∞, on a
//! log-spaced grid of 50 points per decade from 10⁻⁴ times the smallest to
//! 10⁴ times the largest nonzero pole/zero magnitude (plus every pole/zero
//! magnitude and imaginary part exactly), and each local maximum of the grid
//! is refined by golden-section search in log ω.

use nalgebra::Complex;

use super::AnalysisError;
use super::poly::Poly;
use super::tf::{Half, Tf, half_of};

/// The result of a ν-gap computation.
#[derive(Debug, Clone, PartialEq)]
pub struct NuGap {
    /// δ_ν(P1, P2) in [0, 1].
    pub delta: f64,
    /// sup_ω κ(P1(jω), P2(jω)), whether or not the winding condition holds.
    pub kappa_sup: f64,
    /// Frequency of that supremum, rad/s (`f64::INFINITY` for ω → ∞).
    pub omega_sup: f64,
    /// Whether the winding-number condition (both parts) held.
    pub winding_ok: bool,
    /// Whether 1 + P2~ P1 vanishes somewhere on the imaginary axis or at ∞.
    pub vanishes_on_axis: bool,
    /// wno(1 + P2~ P1) = Z - P.
    pub wno: i64,
    /// η(P1): open right-half-plane poles of P1.
    pub eta1: usize,
    /// η(P2).
    pub eta2: usize,
    /// η₀(P2): imaginary-axis poles of P2.
    pub eta0_2: usize,
    /// Common pole/zero factors removed from P1 and P2 before the computation.
    pub cancelled: usize,
}

/// Chordal distance between two points of the Riemann sphere given in
/// homogeneous form p1 = n1/d1, p2 = n2/d2.
pub fn chordal(n1: Complex<f64>, d1: Complex<f64>, n2: Complex<f64>, d2: Complex<f64>) -> f64 {
    let s1 = n1.norm().max(d1.norm());
    let s2 = n2.norm().max(d2.norm());
    if s1 == 0.0 || s2 == 0.0 || !s1.is_finite() || !s2.is_finite() {
        return 0.0;
    }
    let (n1, d1, n2, d2) = (n1 / s1, d1 / s1, n2 / s2, d2 / s2);
    let num = (n1 * d2 - n2 * d1).norm();
    let den = ((n1.norm_sqr() + d1.norm_sqr()) * (n2.norm_sqr() + d2.norm_sqr())).sqrt();
    if den == 0.0 {
        0.0
    } else {
        (num / den).clamp(0.0, 1.0)
    }
}

/// κ(P1(jω), P2(jω)) at a finite frequency.
pub fn kappa(p1: &Tf, p2: &Tf, omega: f64) -> f64 {
    let s = Complex::new(0.0, omega);
    chordal(
        p1.num.eval_c(s),
        p1.den.eval_c(s),
        p2.num.eval_c(s),
        p2.den.eval_c(s),
    )
}

/// κ(P1(j∞), P2(j∞)).
pub fn kappa_inf(p1: &Tf, p2: &Tf) -> f64 {
    let top = |p: &Tf| {
        let m = p.num.degree().unwrap_or(0).max(p.den.degree().unwrap_or(0));
        (
            Complex::new(p.num.coeff(m), 0.0),
            Complex::new(p.den.coeff(m), 0.0),
        )
    };
    let (n1, d1) = top(p1);
    let (n2, d2) = top(p2);
    chordal(n1, d1, n2, d2)
}

/// The Vinnicombe ν-gap δ_ν(P1, P2); see the module documentation.
pub fn nu_gap(p1: &Tf, p2: &Tf) -> Result<NuGap, AnalysisError> {
    let (p1, c1) = p1.minreal()?;
    let (p2, c2) = p2.minreal()?;
    let eta1 = p1.rhp_poles()?;
    let eta2 = p2.rhp_poles()?;
    let eta0_2 = p2.imag_axis_poles()?;

    // g = 1 + P2(-s) P1(s) = N / D
    let d = p2.den.mirror().mul(&p1.den);
    let n = d.add(&p2.num.mirror().mul(&p1.num));
    let (wno, vanishes) = winding(&n, &d)?;
    let winding_ok = !vanishes && wno + eta1 as i64 - eta2 as i64 - eta0_2 as i64 == 0;

    let (kappa_sup, omega_sup) = sup_kappa(&p1, &p2)?;
    Ok(NuGap {
        delta: if winding_ok { kappa_sup } else { 1.0 },
        kappa_sup,
        omega_sup,
        winding_ok,
        vanishes_on_axis: vanishes,
        wno,
        eta1,
        eta2,
        eta0_2,
        cancelled: c1 + c2,
    })
}

/// (wno(N/D) on the indented contour, whether N/D vanishes on the closed
/// imaginary axis).
fn winding(n: &Poly, d: &Poly) -> Result<(i64, bool), AnalysisError> {
    if n.is_zero() {
        return Ok((0, true));
    }
    let nr = n.roots()?;
    let dr = d.roots()?;
    let z = nr.iter().filter(|&&r| half_of(r) == Half::Right).count() as i64;
    let p = dr.iter().filter(|&&r| half_of(r) == Half::Right).count() as i64;
    // zero at infinity
    let mut vanishes = n.degree() < d.degree();
    // unmatched imaginary-axis roots of N
    let mut d_axis: Vec<Complex<f64>> = dr
        .into_iter()
        .filter(|&r| half_of(r) == Half::Axis)
        .collect();
    for r in nr.into_iter().filter(|&r| half_of(r) == Half::Axis) {
        let hit = d_axis
            .iter()
            .position(|q| (r - q).norm() <= 1e-5 * r.norm().max(q.norm()).max(f64::MIN_POSITIVE));
        match hit {
            Some(i) => {
                d_axis.swap_remove(i);
            }
            None => vanishes = true,
        }
    }
    Ok((z - p, vanishes))
}

/// sup_ω κ and its frequency.
fn sup_kappa(p1: &Tf, p2: &Tf) -> Result<(f64, f64), AnalysisError> {
    let mut marks: Vec<f64> = Vec::new();
    for p in [p1, p2] {
        for r in p.poles()?.into_iter().chain(p.zeros()?) {
            if r.norm() > 0.0 {
                marks.push(r.norm());
            }
            if r.im.abs() > 0.0 {
                marks.push(r.im.abs());
            }
        }
    }
    let (lo, hi) = if marks.is_empty() {
        (1e-4, 1e4)
    } else {
        let mn = marks.iter().copied().fold(f64::INFINITY, f64::min);
        let mx = marks.iter().copied().fold(0.0, f64::max);
        (mn * 1e-4, mx * 1e4)
    };
    let (xlo, xhi) = (lo.log10(), hi.log10());
    let npts = ((xhi - xlo) * 50.0).ceil().max(2.0) as usize;
    let mut xs: Vec<f64> = (0..=npts)
        .map(|i| xlo + (xhi - xlo) * i as f64 / npts as f64)
        .collect();
    xs.extend(marks.iter().map(|m| m.log10()));
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let ks: Vec<f64> = xs.iter().map(|&x| kappa(p1, p2, 10f64.powf(x))).collect();

    let mut best = (kappa(p1, p2, 0.0), 0.0);
    let kinf = kappa_inf(p1, p2);
    if kinf > best.0 {
        best = (kinf, f64::INFINITY);
    }
    for i in 0..xs.len() {
        let left = if i == 0 { f64::NEG_INFINITY } else { ks[i - 1] };
        let right = if i + 1 == xs.len() {
            f64::NEG_INFINITY
        } else {
            ks[i + 1]
        };
        if ks[i] >= left && ks[i] >= right {
            let a = if i == 0 { xs[i] } else { xs[i - 1] };
            let b = if i + 1 == xs.len() { xs[i] } else { xs[i + 1] };
            let (x, k) = golden_max(|x| kappa(p1, p2, 10f64.powf(x)), a, b, xs[i], ks[i]);
            if k > best.0 {
                best = (k, 10f64.powf(x));
            }
        }
    }
    Ok(best)
}

/// Golden-section maximisation of a unimodal f on [a, b]; returns the best
/// point seen (never worse than the seed `(x0, f0)`).
fn golden_max(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, x0: f64, f0: f64) -> (f64, f64) {
    let mut best = (x0, f0);
    if b <= a {
        return best;
    }
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let mut fc = f(c);
    let mut fd = f(d);
    for _ in 0..80 {
        if fc > best.1 {
            best = (c, fc);
        }
        if fd > best.1 {
            best = (d, fd);
        }
        if (b - a).abs() < 1e-12 {
            break;
        }
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    best
}
