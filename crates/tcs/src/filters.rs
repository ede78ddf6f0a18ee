//! Discrete first-order filters used by the controllers and observers.
//!
//! All are discretised with the backward-Euler (implicit) rule at a fixed
//! sample time `dt`, which keeps them stable for any `tau > 0` and any
//! `dt > 0` (no aliasing of the pole outside the unit circle):
//!
//! - low-pass `1 / (tau s + 1)`:  `y[k] = y[k-1] + a (x[k] - y[k-1])`, `a = dt / (tau + dt)`
//! - high-pass `tau s / (tau s + 1)`: `y[k] = b (y[k-1] + x[k] - x[k-1])`, `b = tau / (tau + dt)`
//! - filtered derivative `s / (tau s + 1)`: `y[k] = b y[k-1] + (x[k] - x[k-1]) / (tau + dt)`
//!
//! `tau = 0` makes the low-pass a pass-through and the derivative a plain
//! backward difference. None of them allocates.

/// First-order low-pass `1 / (tau s + 1)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass {
    a: f64,
    y: f64,
    primed: bool,
}

impl LowPass {
    /// A low-pass with time constant `tau` (s) at sample time `dt` (s).
    /// The first sample primes the state (no start-up transient from 0).
    pub fn new(tau: f64, dt: f64) -> Self {
        Self {
            a: dt / (tau + dt),
            y: 0.0,
            primed: false,
        }
    }

    /// Filter one sample.
    pub fn step(&mut self, x: f64) -> f64 {
        if self.primed {
            self.y += self.a * (x - self.y);
        } else {
            self.y = x;
            self.primed = true;
        }
        self.y
    }

    /// Current output.
    pub fn value(&self) -> f64 {
        self.y
    }

    /// Set the state (and mark it primed).
    pub fn set(&mut self, y: f64) {
        self.y = y;
        self.primed = true;
    }

    /// Forget the state; the next sample primes it again.
    pub fn reset(&mut self) {
        self.y = 0.0;
        self.primed = false;
    }
}

/// First-order high-pass `tau s / (tau s + 1)`, starting from zero output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HighPass {
    b: f64,
    x_prev: f64,
    y: f64,
    primed: bool,
}

impl HighPass {
    /// A high-pass with time constant `tau` (s) at sample time `dt` (s).
    /// The first sample gives zero output (the filter starts at rest on it).
    pub fn new(tau: f64, dt: f64) -> Self {
        Self {
            b: tau / (tau + dt),
            x_prev: 0.0,
            y: 0.0,
            primed: false,
        }
    }

    /// Filter one sample.
    pub fn step(&mut self, x: f64) -> f64 {
        if self.primed {
            self.y = self.b * (self.y + x - self.x_prev);
        } else {
            self.y = 0.0;
            self.primed = true;
        }
        self.x_prev = x;
        self.y
    }

    /// Forget the state.
    pub fn reset(&mut self) {
        self.x_prev = 0.0;
        self.y = 0.0;
        self.primed = false;
    }
}

/// Filtered ("dirty") derivative `s / (tau s + 1)`, starting from zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilteredDerivative {
    b: f64,
    g: f64,
    x_prev: f64,
    y: f64,
    primed: bool,
}

impl FilteredDerivative {
    /// A derivative filtered with time constant `tau` (s), cut-off
    /// `1 / (2 pi tau)` Hz, at sample time `dt` (s).
    pub fn new(tau: f64, dt: f64) -> Self {
        Self {
            b: tau / (tau + dt),
            g: 1.0 / (tau + dt),
            x_prev: 0.0,
            y: 0.0,
            primed: false,
        }
    }

    /// Differentiate one sample.
    pub fn step(&mut self, x: f64) -> f64 {
        if self.primed {
            self.y = self.b * self.y + self.g * (x - self.x_prev);
        } else {
            self.y = 0.0;
            self.primed = true;
        }
        self.x_prev = x;
        self.y
    }

    /// Current output.
    pub fn value(&self) -> f64 {
        self.y
    }

    /// Forget the state.
    pub fn reset(&mut self) {
        self.x_prev = 0.0;
        self.y = 0.0;
        self.primed = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn low_pass_step_response_matches_first_order() {
        let dt = 1e-3;
        let tau = 0.05;
        let mut f = LowPass::new(tau, dt);
        f.set(0.0);
        let mut y = 0.0;
        for _ in 0..50 {
            y = f.step(1.0);
        }
        // After one time constant: 1 - e^-1 = 0.632 (backward Euler is within 1 %).
        assert!((y - 0.632).abs() < 0.01, "{y}");
    }

    #[test]
    fn high_pass_removes_constant_and_passes_fast_change() {
        let dt = 1e-3;
        let mut f = HighPass::new(1.0, dt);
        assert_eq!(f.step(5.0), 0.0);
        let mut y = 0.0;
        for _ in 0..10_000 {
            y = f.step(5.0);
        }
        assert!(y.abs() < 1e-9);
        // A step of 1 passes almost fully at once.
        let y = f.step(6.0);
        assert!((y - 0.999).abs() < 1e-3, "{y}");
    }

    #[test]
    fn derivative_of_a_ramp_converges_to_the_slope() {
        let dt = 1e-3;
        let mut d = FilteredDerivative::new(0.01, dt);
        let mut y = 0.0;
        for k in 0..200 {
            y = d.step(3.0 * k as f64 * dt);
        }
        assert!((y - 3.0).abs() < 1e-6, "{y}");
    }
}
