//! Driving-force observer shared by SRC and MTTE (README.md, "Driving-force observer").
//!
//! From the wheel equation `J_w dω/dt = T - r F_d` (F_d includes the rolling
//! resistance, which no wheel-side observer can separate):
//!
//! ```text
//! F̂_d = ( LPF(T) - J_w · s/(τ_o s + 1) ω ) / r,        μ̂ = F̂_d / N,  N = M g / n
//! ```
//!
//! i.e. a first-order disturbance observer: the motor torque and the filtered
//! derivative of ω pass through the same first-order filter (time constant
//! `τ_o`, cut-off `1/(2π τ_o)`), so F̂_d is the true F_d seen through
//! `1/(τ_o s + 1)`. The torque is the one the inverter *reports*
//! (`Measurement::torque`), not the command.

use crate::filters::{FilteredDerivative, LowPass};
use grip_physics::VehicleParams;

/// First-order driving-force observer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrivingForceObserver {
    torque_lp: LowPass,
    omega_dot: FilteredDerivative,
    j_w: f64,
    r: f64,
    normal_force: f64,
    f_hat: f64,
}

impl DrivingForceObserver {
    /// Observer for `vehicle` with filter time constant `tau` (s) at sample time `dt` (s).
    pub fn new(vehicle: &VehicleParams, tau: f64, dt: f64) -> Self {
        Self {
            torque_lp: LowPass::new(tau, dt),
            omega_dot: FilteredDerivative::new(tau, dt),
            j_w: vehicle.j_w,
            r: vehicle.r,
            normal_force: vehicle.normal_force(),
            f_hat: 0.0,
        }
    }

    /// One sample: measured motor torque (N m) and wheel speed (rad/s).
    /// Returns F̂_d (N). A non-finite intermediate (absurd inputs) resets the
    /// observer and returns 0.
    pub fn step(&mut self, torque: f64, omega: f64) -> f64 {
        let t = self.torque_lp.step(torque);
        let w_dot = self.omega_dot.step(omega);
        let f = (t - self.j_w * w_dot) / self.r;
        if f.is_finite() {
            self.f_hat = f;
        } else {
            self.reset();
        }
        self.f_hat
    }

    /// Latest F̂_d, N.
    pub fn force(&self) -> f64 {
        self.f_hat
    }

    /// Latest filtered torque LPF(T), N m (= r F̂_d + J_w dω/dt).
    pub fn torque(&self) -> f64 {
        self.torque_lp.value()
    }

    /// Latest μ̂ = F̂_d / N.
    pub fn mu(&self) -> f64 {
        self.f_hat / self.normal_force
    }

    /// Latest filtered wheel acceleration dω/dt, rad/s².
    pub fn omega_dot(&self) -> f64 {
        self.omega_dot.value()
    }

    /// Back to the state at construction.
    pub fn reset(&mut self) {
        self.torque_lp.reset();
        self.omega_dot.reset();
        self.f_hat = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Synthetic wheel: J_w dω/dt = T - r F with a known, time-varying F
    /// (exact integration of piecewise-constant inputs).
    #[test]
    fn recovers_a_known_force_on_synthetic_data() {
        let v = VehicleParams::default();
        let dt = 1e-3;
        let tau = 0.01;
        let mut obs = DrivingForceObserver::new(&v, tau, dt);
        let mut omega = 10.0;
        let mut worst_late: f64 = 0.0;
        for k in 0..3000 {
            let t = k as f64 * dt;
            let torque = 200.0 + 50.0 * (2.0 * t).sin();
            let force = if t < 1.0 {
                500.0
            } else {
                300.0 + 100.0 * (1.5 * t).sin()
            };
            let f_hat = obs.step(torque, omega);
            // After the observer has settled (5 tau) away from the step at 1 s,
            // F̂ equals F delayed by roughly tau: compare to the lagged truth.
            if (0.1..1.0).contains(&t) {
                worst_late = worst_late.max((f_hat - 500.0).abs());
            }
            if t > 1.2 {
                let lagged = 300.0 + 100.0 * (1.5 * (t - tau)).sin();
                assert!(
                    (f_hat - lagged).abs() < 2.0,
                    "t={t} f_hat={f_hat} lagged={lagged}"
                );
            }
            omega += dt * (torque - v.r * force) / v.j_w;
        }
        assert!(worst_late < 1.0, "steady error {worst_late} N");
        assert!((obs.mu() - obs.force() / v.normal_force()).abs() < 1e-12);
    }

    #[test]
    fn absurd_input_resets_instead_of_poisoning() {
        let v = VehicleParams::default();
        let mut obs = DrivingForceObserver::new(&v, 0.01, 1e-3);
        obs.step(100.0, 1.0);
        assert_eq!(obs.step(f64::MAX, -f64::MAX), 0.0);
        assert!(obs.step(100.0, 1.0).is_finite());
    }
}
