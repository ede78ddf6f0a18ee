//! Fuzzy optimal-slip estimator for SRC (Mamdani type).
//!
//! Inputs (all per cycle):
//! - `λ`   the (low-passed) measured slip,
//! - `μ̂`   the observed friction coefficient,
//! - `s_n` the normalised slope of the μ-λ curve at the operating point,
//!   `s_n = (dμ̂/dλ) · λ / μ̂` (dimensionless: 1 in the linear region where
//!   μ ∝ λ, 0 at the peak, negative past it). The slope dμ̂/dλ itself is
//!   estimated online by [`SlopeEstimator`].
//!
//! Output: the optimal-slip estimate λ* itself (absolute). The rule base
//! puts λ* above the current slip while the slope is positive (by how much
//! the friction level allows: low-μ peaks are narrow and close to zero slip),
//! at it where the slope vanishes and below it past the peak. (Before the
//! first comparison the output was a correction Δλ of at most ±0.08 added to
//! the current slip, which made λ* follow a spinning wheel: see README.) This is the "track the adherence
//! gradient without knowing the road" idea of Delli Colli, Tomassi and
//! Scarano (IEEE TPEL 21(3), 2006) expressed as the optimal-slip estimator of
//! the Hori group's SRC (Kataoka, Sado, Sakai, Hori, IEEJ Trans. IA 2001:
//! fuzzy inference of the optimal slip from μ, its slope and λ).
//!
//! Inference: AND = min, implication = min (clipping), aggregation = max,
//! defuzzification = centroid over a fixed grid of [`GRID`] points on
//! [0, 0.5]. Membership functions and the 27-rule table are constants
//! below and are reproduced in `crates/tcs/README.md`. Nothing allocates.

/// A trapezoidal membership function (a, b, c, d): 0 below a, rising to 1 at
/// b, 1 up to c, falling to 0 at d. `a == b` or `c == d` make shoulders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    /// Foot, left.
    pub a: f64,
    /// Shoulder, left.
    pub b: f64,
    /// Shoulder, right.
    pub c: f64,
    /// Foot, right.
    pub d: f64,
}

impl Trapezoid {
    const fn new(a: f64, b: f64, c: f64, d: f64) -> Self {
        Self { a, b, c, d }
    }

    /// Degree of membership of `x`, in [0, 1]. NaN gives 0.
    pub fn grade(&self, x: f64) -> f64 {
        if x.is_nan() {
            return 0.0;
        }
        if x < self.b {
            if x <= self.a {
                0.0
            } else {
                (x - self.a) / (self.b - self.a)
            }
        } else if x <= self.c {
            1.0
        } else if x >= self.d {
            0.0
        } else {
            (self.d - x) / (self.d - self.c)
        }
    }
}

const NEG_INF: f64 = f64::NEG_INFINITY;
const POS_INF: f64 = f64::INFINITY;

/// Slip λ: Small, Medium, Large.
pub const LAMBDA_SETS: [Trapezoid; 3] = [
    Trapezoid::new(NEG_INF, NEG_INF, 0.03, 0.10),
    Trapezoid::new(0.03, 0.10, 0.10, 0.25),
    Trapezoid::new(0.15, 0.30, POS_INF, POS_INF),
];
/// Friction μ̂: Low, Medium, High.
pub const MU_SETS: [Trapezoid; 3] = [
    Trapezoid::new(NEG_INF, NEG_INF, 0.15, 0.40),
    Trapezoid::new(0.15, 0.45, 0.45, 0.80),
    Trapezoid::new(0.50, 0.80, POS_INF, POS_INF),
];
/// Normalised slope s_n: Negative (past the peak), Zero (at the peak), Positive (rising).
pub const SLOPE_SETS: [Trapezoid; 3] = [
    Trapezoid::new(NEG_INF, NEG_INF, -0.3, 0.0),
    Trapezoid::new(-0.3, 0.0, 0.0, 0.3),
    Trapezoid::new(0.0, 0.3, POS_INF, POS_INF),
];

/// Output sets on the optimal-slip estimate λ* itself (absolute, not a
/// correction of the current slip): VS, S, M, ML, L, VL (triangles).
pub const OUT_SETS: [Trapezoid; 6] = [
    Trapezoid::new(0.0, 0.03, 0.03, 0.06),
    Trapezoid::new(0.03, 0.06, 0.06, 0.10),
    Trapezoid::new(0.06, 0.12, 0.12, 0.18),
    Trapezoid::new(0.12, 0.20, 0.20, 0.28),
    Trapezoid::new(0.20, 0.30, 0.30, 0.40),
    Trapezoid::new(0.30, 0.42, 0.42, 0.50),
];
/// Names of the output sets, for the README table and tests.
pub const OUT_NAMES: [&str; 6] = ["VS", "S", "M", "ML", "L", "VL"];

const VS: usize = 0;
const S: usize = 1;
const M: usize = 2;
const ML: usize = 3;
const L: usize = 4;
const VL: usize = 5;

/// Rule table: `RULES[slope][mu][lambda]` = output set index (the estimate
/// of the optimal slip). slope: 0 N, 1 Z, 2 P; mu: 0 L, 1 M, 2 H;
/// lambda: 0 S, 1 M, 2 L. Negative slope: the peak is *below* the current
/// slip; zero: at it; positive: above it, the more so the higher μ̂ (low-μ
/// roads peak near zero slip, high-μ ones at 0.1-0.4).
pub const RULES: [[[usize; 3]; 3]; 3] = [
    // slope N (past the peak): an estimate below the current slip
    [[VS, S, S], [VS, S, M], [S, M, ML]],
    // slope Z (at the peak): about the current slip (a low-μ road's
    // plateau at large slip: its peak is near zero slip)
    [[S, S, S], [S, M, M], [M, ML, L]],
    // slope P (rising): above the current slip, by how much μ̂ allows;
    // rising at large slip on a low-μ road is noise: no such road peaks there
    [[S, M, S], [M, ML, L], [ML, L, VL]],
];

/// Output grid resolution (points on [0, 0.5]).
pub const GRID: usize = 121;
const OUT_LO: f64 = 0.0;
const OUT_HI: f64 = 0.5;

/// Evaluate the rule base: the optimal-slip estimate λ* for (λ, μ̂, s_n).
/// Always finite; 0 when no rule fires (cannot happen for finite inputs:
/// the input sets cover ℝ).
pub fn infer(lambda: f64, mu: f64, slope_n: f64) -> f64 {
    let gl = LAMBDA_SETS.map(|s| s.grade(lambda));
    let gm = MU_SETS.map(|s| s.grade(mu));
    let gs = SLOPE_SETS.map(|s| s.grade(slope_n));
    // Strength of each output set: max over the rules that conclude it.
    let mut strength = [0.0_f64; 6];
    for (i, &ws) in gs.iter().enumerate() {
        for (j, &wm) in gm.iter().enumerate() {
            for (k, &wl) in gl.iter().enumerate() {
                let w = ws.min(wm).min(wl);
                let o = RULES[i][j][k];
                if w > strength[o] {
                    strength[o] = w;
                }
            }
        }
    }
    let mut num = 0.0;
    let mut den = 0.0;
    let step = (OUT_HI - OUT_LO) / (GRID - 1) as f64;
    for g in 0..GRID {
        let x = OUT_LO + step * g as f64;
        let mut y: f64 = 0.0;
        for (o, set) in OUT_SETS.iter().enumerate() {
            if strength[o] > 0.0 {
                y = y.max(set.grade(x).min(strength[o]));
            }
        }
        num += x * y;
        den += y;
    }
    if den > 0.0 { num / den } else { 0.0 }
}

/// Online estimate of the μ-λ slope dμ̂/dλ: exponentially weighted least
/// squares on the increments of the (filtered) λ and μ̂,
///
/// ```text
/// S_xy ← ρ S_xy + Δλ Δμ̂,   S_xx ← ρ S_xx + Δλ²,   ρ = exp(−dt / τ_s)
/// a    = S_xy / S_xx                          (least-squares slope over the window)
/// w    = S_xx / (S_xx + ε)                    (confidence: slip excitation vs threshold ε)
/// s_n  = w · clamp(a λ / max(μ̂, 0.02), −3, 3) + (1 − w) · 1
/// ```
///
/// With little slip excitation (S_xx ≪ ε) the normalised slope falls back to
/// 1, the linear-region value ("assume we are below the peak"): the safe
/// direction for the estimator, because the PI output is capped at the
/// driver's demand anyway, and the one that lets λ* rise above a small
/// operating slip so that SRC does not cut a demand the road carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlopeEstimator {
    rho: f64,
    eps: f64,
    sxy: f64,
    sxx: f64,
    prev: Option<(f64, f64)>,
}

impl SlopeEstimator {
    /// Window time constant `tau` (s), excitation threshold `eps`, sample time `dt` (s).
    pub fn new(tau: f64, eps: f64, dt: f64) -> Self {
        Self {
            rho: (-dt / tau).exp(),
            eps,
            sxy: 0.0,
            sxx: 0.0,
            prev: None,
        }
    }

    /// Update with the current (λ, μ̂); returns the normalised slope s_n.
    pub fn step(&mut self, lambda: f64, mu: f64) -> f64 {
        if let Some((l0, m0)) = self.prev {
            let dl = lambda - l0;
            let dm = mu - m0;
            let sxy = self.rho * self.sxy + dl * dm;
            let sxx = self.rho * self.sxx + dl * dl;
            if sxy.is_finite() && sxx.is_finite() {
                self.sxy = sxy;
                self.sxx = sxx;
            } else {
                self.sxy = 0.0;
                self.sxx = 0.0;
            }
        }
        self.prev = Some((lambda, mu));
        self.normalised(lambda, mu)
    }

    /// Least-squares slope dμ̂/dλ over the window (NaN before any excitation).
    pub fn slope(&self) -> f64 {
        if self.sxx > 0.0 {
            self.sxy / self.sxx
        } else {
            f64::NAN
        }
    }

    /// Confidence weight w = S_xx / (S_xx + ε) in [0, 1).
    pub fn weight(&self) -> f64 {
        self.sxx / (self.sxx + self.eps)
    }

    /// s_n for the operating point (λ, μ̂) with the current window.
    pub fn normalised(&self, lambda: f64, mu: f64) -> f64 {
        let w = self.weight();
        if w.is_nan() || w <= 0.0 {
            return 1.0;
        }
        let s = normalised_slope(self.slope(), lambda, mu);
        w * s + (1.0 - w)
    }

    /// Back to the state at construction.
    pub fn reset(&mut self) {
        self.sxy = 0.0;
        self.sxx = 0.0;
        self.prev = None;
    }
}

/// Normalised slope s_n = a λ / μ̂, with λ floored at 0 and μ̂ at 0.02,
/// clamped to [−3, 3] (NaN → 1, the linear-region value).
pub fn normalised_slope(slope: f64, lambda: f64, mu: f64) -> f64 {
    let s = slope * lambda.max(0.0) / mu.max(0.02);
    if s.is_nan() { 1.0 } else { s.clamp(-3.0, 3.0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_cover_the_real_line() {
        for x in [
            -1e9, -1.0, -0.3, -0.1, 0.0, 0.02, 0.1, 0.2, 0.5, 0.9, 1.0, 1e9,
        ] {
            assert!(
                LAMBDA_SETS.iter().map(|s| s.grade(x)).sum::<f64>() > 0.0,
                "lambda {x}"
            );
            assert!(
                MU_SETS.iter().map(|s| s.grade(x)).sum::<f64>() > 0.0,
                "mu {x}"
            );
            assert!(
                SLOPE_SETS.iter().map(|s| s.grade(x)).sum::<f64>() > 0.0,
                "slope {x}"
            );
        }
    }

    #[test]
    fn the_estimate_points_toward_the_peak_on_both_sides() {
        // Snow-like: low μ, far past the peak (λ = 0.7, negative or flat
        // slope, or no excitation at all): λ* near snow's 0.06, far below λ.
        for sn in [-1.0, -0.2, 0.0] {
            let e = infer(0.7, 0.17, sn);
            assert!((e - 0.06).abs() < 0.015, "s_n {sn}: {e}");
        }
        // With the no-excitation prior (s_n = 1) μ̂ = 0.17 is a little
        // "medium", whose rising-at-large-slip rule says L: still far below.
        let e = infer(0.7, 0.17, 1.0);
        assert!(e < 0.15, "{e}");
        assert!((infer(0.7, 0.12, 1.0) - 0.06).abs() < 0.01);
        // Past the peak on any road: below the current slip.
        for (l, mu) in [(0.12, 0.15), (0.3, 0.6), (0.35, 1.0), (0.5, 0.9)] {
            let e = infer(l, mu, -1.0);
            assert!(e < l - 0.05, "λ {l} μ {mu}: {e}");
        }
        // Rising with high μ̂: above the current slip.
        for l in [0.01, 0.05, 0.1, 0.2, 0.3] {
            let e = infer(l, 1.0, 1.0);
            assert!(e > l + 0.05, "λ {l}: {e}");
        }
        // Asphalt-like linear region at 300 N m (λ 0.011, μ̂ 0.31): above the
        // slip, so SRC does not cut a torque the road carries.
        assert!(infer(0.011, 0.31, 1.0) > 0.05);
        // At the peak: about the current slip.
        let e = infer(0.12, 0.45, 0.0);
        assert!((e - 0.12).abs() < 0.03, "{e}");
        // Monotone in the slope for a fixed operating point.
        let mut last = f64::NEG_INFINITY;
        for k in -30..=30 {
            let d = infer(0.08, 0.5, k as f64 * 0.05);
            assert!(d >= last - 1e-12, "{k}: {d} < {last}");
            last = d;
        }
    }

    #[test]
    fn slope_estimator_recovers_a_curve_and_falls_back_without_excitation() {
        let dt = 1e-3;
        let mut est = SlopeEstimator::new(0.1, 1e-6, dt);
        // No excitation: the linear-region value 1.
        for _ in 0..100 {
            assert_eq!(est.step(0.1, 0.76), 1.0);
        }
        assert!(est.slope().is_nan());
        // λ sweeps across μ = 0.8 − 4 (λ − 0.2)²: slope −8 (λ − 0.2).
        let mut sn = 0.0;
        for k in 0..=400 {
            let l = 0.1 + 0.2 * k as f64 / 400.0;
            sn = est.step(l, 0.8 - 4.0 * (l - 0.2) * (l - 0.2));
        }
        // The window (τ = 0.1 s ≙ 0.05 in λ) centres near λ = 0.25: slope ≈ −0.4.
        let a = est.slope();
        assert!(a < -0.2 && a > -0.8, "{a}");
        assert!(est.weight() > 0.9);
        assert!(sn < 0.0, "{sn}");
        // Linear curve μ = 8 λ: s_n = 1 exactly, slope 8.
        let mut est = SlopeEstimator::new(0.1, 1e-6, dt);
        for k in 0..=400 {
            let l = 0.01 + 0.05 * k as f64 / 400.0;
            sn = est.step(l, 8.0 * l);
        }
        assert!((est.slope() - 8.0).abs() < 1e-9);
        assert!((sn - 1.0).abs() < 1e-9);
    }

    #[test]
    fn normalised_slope_examples() {
        assert_eq!(normalised_slope(10.0, 0.05, 0.5), 1.0);
        assert_eq!(normalised_slope(f64::NAN, 0.05, 0.5), 1.0);
        assert_eq!(normalised_slope(1e9, 0.5, 0.5), 3.0);
    }
}
