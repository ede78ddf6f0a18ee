//! SRC: slip ratio control with the fuzzy optimal-slip estimator
//! (paper §III-B; README.md, "SRC").
//!
//! ```text
//! λ      = (r ω − V) / max(r ω, V, v_eps)                       (measured slip, clamped to [−1, 1])
//! F̂_d    = (LPF(T) − J_w dω/dt) / r,   μ̂ = F̂_d / N           (observer, τ_o = tau_obs)
//! a      = dμ̂/dλ   (SlopeEstimator on LPF_τo(λ) and μ̂)
//! λ*     = ARTE usable ? λ_opt(road)
//!                      : LPF_τref( clamp( fuzzy(λ_f, μ̂, a λ_f/μ̂), λ_min, λ_max ) )
//! K_p    = kp · max(|ω|, v_eps / r) / (1 − λ)     ((1 − λ) clamped to [0.1, 1])
//! K_i    = (e > 0 ? kp_recover : kp) · max(|ω|, v_eps / r) / T_i
//! u      = K_p e + I + K_i e dt,   e = λ* − λ
//! T_PI   = clamp(u, 0, T_d);   I ← T_PI − K_p e                 (tracking anti-windup)
//! T*     = min(T_d, T_PI)
//! ```
//!
//! - The proportional gain is scheduled with the wheel speed and the slip
//!   because the slip's sensitivity to torque near the μ-λ peak is
//!   (1 − λ)/(J_w ω) per N m s: kp = J_w / (2 τ_m) and T_i = 4 τ_m make the
//!   loop the symmetric optimum (Kessler) for that integrator plant with the
//!   motor lag τ_m.
//! - No chassis speed (`v == None`, or non-finite): the control law cannot run;
//!   T* = T_d is passed through, `ControlOutput::passthrough` is true and the
//!   integrator is set to T_d so that the PI resumes bumplessly.
//! - The integrator starts at T_d on the first positive demand (start of the
//!   drive or after coasting), so SRC applies the demand until the slip
//!   exceeds λ*.
//! - `T_d <= 0`: passed through (SRC is a traction controller); the
//!   integrator is reset to 0.
//! - `internal` is λ* (the slip reference in use).

use crate::filters::LowPass;
use crate::fuzzy::{SlopeEstimator, infer};
use crate::observer::DrivingForceObserver;
use crate::params::{ArteUse, SrcParams};
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};
use crate::{limit_to_demand, valid_dt};
use grip_physics::{InvalidField, VehicleParams};

/// Slip ratio controller.
#[derive(Debug, Clone)]
pub struct Src {
    params: SrcParams,
    arte: ArteUse,
    dt: f64,
    r: f64,
    v_eps: f64,
    observer: DrivingForceObserver,
    lambda_lp: LowPass,
    slope: SlopeEstimator,
    reference: LowPass,
    integral: f64,
    pi_active: bool,
}

impl Src {
    /// A controller for `vehicle` at sample time `dt` (s).
    pub fn new(
        params: SrcParams,
        arte: ArteUse,
        vehicle: &VehicleParams,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        params.validate()?;
        arte.validate()?;
        valid_dt(dt)?;
        vehicle.validate()?;
        let mut reference = LowPass::new(params.tau_ref, dt);
        reference.set(params.lambda_min);
        Ok(Self {
            params,
            arte,
            dt,
            r: vehicle.r,
            v_eps: vehicle.v_eps,
            observer: DrivingForceObserver::new(vehicle, params.tau_obs, dt),
            lambda_lp: LowPass::new(params.tau_obs, dt),
            slope: SlopeEstimator::new(params.tau_slope, params.slope_excitation, dt),
            reference,
            integral: 0.0,
            pi_active: false,
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &SrcParams {
        &self.params
    }

    /// Measured slip with the plant's definition (crates/physics/README.md, "Plant"), clamped to [−1, 1].
    pub fn slip(&self, omega: f64, v: f64) -> f64 {
        let rw = self.r * omega;
        let l = (rw - v) / rw.max(v).max(self.v_eps);
        if l.is_nan() { 0.0 } else { l.clamp(-1.0, 1.0) }
    }
}

impl Controller for Src {
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput {
        self.observer.step(m.torque, m.omega);
        let mu_hat = self.observer.mu();
        let known = self.arte.usable(road);

        let Some(v) = m.v.filter(|v| v.is_finite()) else {
            let torque_cmd = limit_to_demand(m.demand, m.demand);
            self.integral = torque_cmd.max(0.0);
            self.pi_active = torque_cmd > 0.0;
            return ControlOutput {
                torque_cmd,
                used_arte: false,
                internal: known.map_or(self.reference.value(), |k| k.lambda_opt),
                mu_hat,
                passthrough: true,
            };
        };

        let lambda = self.slip(m.omega, v);
        let lambda_f = self.lambda_lp.step(lambda);
        let slope_n = self.slope.step(lambda_f, mu_hat);

        // Fuzzy estimate runs every cycle (so it is warm when ARTE drops out).
        let fuzzy_target =
            infer(lambda_f, mu_hat, slope_n).clamp(self.params.lambda_min, self.params.lambda_max);
        let fuzzy_ref = self.reference.step(fuzzy_target);
        let lambda_ref = match known {
            Some(k) => k.lambda_opt,
            None => fuzzy_ref,
        };

        let torque_cmd = if m.demand > 0.0 && m.demand.is_finite() {
            if !self.pi_active {
                // First positive demand (start, or after coasting): start from it.
                self.integral = m.demand;
                self.pi_active = true;
            }
            let e = lambda_ref - lambda;
            // Slip plant (paper eqs. 6-8, corrected): dλ/dt = (1 − λ)/(J_w ω) · T
            // at the peak, so the symmetric optimum is K_p = J_w ω / (2 τ_m (1 − λ)).
            let one_minus = (1.0 - lambda.clamp(0.0, 0.9)).max(0.1);
            let kp = self.params.kp * m.omega.abs().max(self.v_eps / self.r) / one_minus;
            // Below the reference the wheel is coupled to the vehicle (inertia
            // J_w + (M/n) r²), so the recovery uses that plant's gain; above
            // it (slipping), the wheel alone (J_w).
            let ki = if e > 0.0 {
                self.params.kp_recover * m.omega.abs().max(self.v_eps / self.r) / self.params.ti
            } else {
                kp / self.params.ti
            };
            let unsat = kp * e + self.integral + ki * e * self.dt;
            let t_pi = if unsat.is_finite() {
                unsat.clamp(0.0, m.demand)
            } else {
                m.demand
            };
            // Tracking anti-windup: when the output is limited (by the demand
            // or by 0) the integrator takes the value that reproduces the
            // limited output, so the PI leaves the limit at once when the
            // slip error changes sign.
            let i = t_pi - kp * e;
            self.integral = if i.is_finite() { i } else { t_pi };
            limit_to_demand(t_pi, m.demand)
        } else {
            self.pi_active = false;
            self.integral = 0.0;
            limit_to_demand(m.demand, m.demand)
        };

        ControlOutput {
            torque_cmd,
            used_arte: known.is_some(),
            internal: lambda_ref,
            mu_hat,
            passthrough: false,
        }
    }

    fn reset(&mut self) {
        self.observer.reset();
        self.lambda_lp.reset();
        self.slope.reset();
        self.reference.reset();
        self.reference.set(self.params.lambda_min);
        self.integral = 0.0;
        self.pi_active = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slip_definition() {
        let v = VehicleParams::default();
        let c = Src::new(SrcParams::default(), ArteUse::default(), &v, 1e-3).unwrap();
        assert_eq!(c.slip(0.0, 0.0), 0.0);
        let w = 10.0 / v.r;
        assert!((c.slip(w, 9.0) - 0.1).abs() < 1e-12);
        assert!((c.slip(w, 12.5) + 0.2).abs() < 1e-12);
        assert_eq!(c.slip(1e300, 0.0), 1.0);
    }

    #[test]
    fn passes_the_demand_through_without_chassis_speed_and_says_so() {
        let v = VehicleParams::default();
        let mut c = Src::new(SrcParams::default(), ArteUse::default(), &v, 1e-3).unwrap();
        let m = Measurement {
            t: 0.0,
            omega: 50.0,
            v: None,
            torque: 300.0,
            demand: 300.0,
        };
        let out = c.step(&m, None);
        assert_eq!(out.torque_cmd, 300.0);
        assert!(out.passthrough);
        assert!(!out.used_arte);
        // With speed again, the PI starts from the demand (bumpless) and cuts
        // torque for a wheel that spins (λ = 0.5 ≫ λ*).
        let m = Measurement {
            v: Some(0.5 * 50.0 * v.r),
            ..m
        };
        let out = c.step(&m, None);
        assert!(!out.passthrough);
        assert!(out.torque_cmd < 300.0);
    }
}
