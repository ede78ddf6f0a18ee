//! SRC: slip ratio control with the fuzzy optimal-slip estimator
//! (paper §III-B; README.md, "SRC").
//!
//! ```text
//! λ      = (r ω − V) / max(r ω, V, v_f)                         (measured slip, clamped to [−1, 1])
//! F̂_d    = (LPF(T) − J_w dω/dt) / r,   μ̂ = F̂_d / N           (observer, τ_o = tau_obs)
//! a      = dμ̂/dλ   (SlopeEstimator on LPF_τo(λ) and μ̂)
//! λ*     = ARTE usable ? λ_opt(road)
//!                      : LPF_τref( clamp( fuzzy(λ_f, μ̂, a λ_f/μ̂), λ_min, λ_max ) )
//! K_p    = kp · max(|ω|, v_f / r) / (1 − λ)       ((1 − λ) clamped to [0.1, 1])
//! K_i    = (e > 0 ? kp_recover : kp) · max(|ω|, v_f / r) / T_i
//! u      = K_p e + I + K_i e dt,   e = λ* − λ
//! T_PI   = clamp(u, 0, T_d);   I ← T_PI − K_p e                 (tracking anti-windup)
//! T*     = min(T_d, T_PI)
//! v_f    = max(v_eps, v_launch)
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
//!   drive or after coasting), and every rise of the demand while the slip
//!   is below λ* (e > 0) is added to it, so SRC applies the demand, a
//!   ramped one too, until the slip exceeds λ*. A constant demand, the
//!   paper's only case, is unaffected.
//! - **Pulling away** (`v_launch`, not in the paper, whose controllers are
//!   for 10-30 km/h): below `v_launch` the slip's denominator and the gain
//!   schedule's speed are floored at it, so at a crawl SRC controls the
//!   speed difference r ω − V against λ* · v_launch instead of a ratio of
//!   two sensor noises (over the `v_eps` = 0.1 m/s floor the measured slip
//!   jitters by about 0.2 at a few cm/s, far above λ*). Above `v_launch`
//!   the law is the paper's.
//! - `T_d <= 0`: passed through (SRC is a traction controller); the
//!   integrator is reset to 0.
//! - `internal` is λ* (the slip reference in use).

use crate::filters::LowPass;
use crate::fuzzy::{SlopeEstimator, infer};
use crate::observer::DrivingForceObserver;
use crate::params::{ArteUse, SrcParams};
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};
use crate::{DemandRise, limit_to_demand, valid_dt};
use grip_physics::{InvalidField, VehicleParams};

/// Slip ratio controller.
#[derive(Debug, Clone)]
pub struct Src {
    params: SrcParams,
    arte: ArteUse,
    dt: f64,
    r: f64,
    /// The slip denominator's floor, m/s: the vehicle's `v_eps`, or
    /// `v_launch` if higher.
    slip_floor: f64,
    observer: DrivingForceObserver,
    lambda_lp: LowPass,
    slope: SlopeEstimator,
    reference: LowPass,
    integral: f64,
    pi_active: bool,
    /// The demand's rise since the previous cycle (passed into the
    /// integrator while the slip is below the reference).
    rise: DemandRise,
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
            slip_floor: vehicle.v_eps.max(params.v_launch),
            observer: DrivingForceObserver::new(vehicle, params.tau_obs, dt),
            lambda_lp: LowPass::new(params.tau_obs, dt),
            slope: SlopeEstimator::new(params.tau_slope, params.slope_excitation, dt),
            reference,
            integral: 0.0,
            pi_active: false,
            rise: DemandRise::default(),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &SrcParams {
        &self.params
    }

    /// Measured slip with the plant's definition (crates/physics/README.md,
    /// "Plant"), its denominator floored at `v_launch` if that is above the
    /// vehicle's `v_eps`, clamped to [−1, 1].
    pub fn slip(&self, omega: f64, v: f64) -> f64 {
        let rw = self.r * omega;
        let l = (rw - v) / rw.max(v).max(self.slip_floor);
        if l.is_nan() { 0.0 } else { l.clamp(-1.0, 1.0) }
    }
}

impl Controller for Src {
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput {
        self.observer.step(m.torque, m.omega);
        let mu_hat = self.observer.mu();
        let known = self.arte.usable(road);
        let rise = self.rise.step(m.demand);

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
            let e = lambda_ref - lambda;
            if !self.pi_active {
                // First positive demand (start, or after coasting): start from it.
                self.integral = m.demand;
                self.pi_active = true;
            } else if e > 0.0 && rise > 0.0 {
                // The driver asks for more while the wheel slips less than
                // the reference: the rise passes, as the first demand did
                // (a ramped pedal is a sequence of small steps; without this
                // the command followed it only at the recovery gain's rate).
                // A constant demand never gets here.
                self.integral += rise;
            }
            // Slip plant (paper eqs. 6-8, corrected): dλ/dt = (1 − λ)/(J_w ω) · T
            // at the peak, so the symmetric optimum is K_p = J_w ω / (2 τ_m (1 − λ)).
            let one_minus = (1.0 - lambda.clamp(0.0, 0.9)).max(0.1);
            let kp = self.params.kp * m.omega.abs().max(self.slip_floor / self.r) / one_minus;
            // Below the reference the wheel is coupled to the vehicle (inertia
            // J_w + (M/n) r²), so the recovery uses that plant's gain; above
            // it (slipping), the wheel alone (J_w).
            let ki = if e > 0.0 {
                self.params.kp_recover * m.omega.abs().max(self.slip_floor / self.r)
                    / self.params.ti
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
        self.rise = DemandRise::default();
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

    /// A car pulling away from rest on a gripping road (wheel and car share
    /// one inertia, 0.3 % slip), the motor a 50 ms lag, wheel speed and car
    /// speed read with uniform noise of +-0.05 rad/s and +-0.02 m/s; the
    /// demand ramps 0 -> 220 N m over 0.3 s and is then held for 0.7 s.
    /// Returns the commands.
    fn pull_away(p: SrcParams) -> Vec<f64> {
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Src::new(p, ArteUse::default(), &v, dt).unwrap();
        let (mut omega, mut torque) = (0.0f64, 0.0);
        let mut seed = 12345u64;
        let mut noise = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        (0..1000)
            .map(|k| {
                let demand = (220.0 * (k + 1) as f64 / 300.0).min(220.0);
                let m = Measurement {
                    t: k as f64 * dt,
                    omega: omega + 0.05 * noise(),
                    v: Some((omega * v.r * 0.997 + 0.02 * noise()).max(0.0)),
                    torque,
                    demand,
                };
                let out = c.step(&m, None);
                torque += dt / 0.05 * (out.torque_cmd - torque);
                omega += dt * torque / v.j_model();
                out.torque_cmd
            })
            .collect()
    }

    #[test]
    fn a_car_pulls_away_from_rest_with_a_ramped_pedal() {
        // The command follows the ramp and holds the demand: the rises pass
        // while the slip is under the reference, and below v_launch the
        // slip is a speed difference over v_launch, not sensor noise over
        // v_eps.
        let cmds = pull_away(SrcParams::default());
        let late = cmds[300..].iter().copied().fold(f64::INFINITY, f64::min);
        assert!(late > 0.95 * 220.0, "least command after the ramp {late}");
        // With the paper's slip at every speed (v_launch 0) the same noise
        // reads as slip far above lambda*, the PI cuts and the rises stop.
        let p = SrcParams {
            v_launch: 0.0,
            ..SrcParams::default()
        };
        let cut = pull_away(p);
        let mean = cut[300..].iter().sum::<f64>() / 700.0;
        assert!(mean < 0.8 * 220.0, "mean command after the ramp {mean}");
    }

    #[test]
    fn a_rising_demand_does_not_pass_while_the_wheel_slips_above_the_reference() {
        // 10 m/s, the wheel at 30 % slip (far above any lambda*): a rising
        // demand is not passed on, the PI cuts.
        let v = VehicleParams::default();
        let mut c = Src::new(SrcParams::default(), ArteUse::default(), &v, 1e-3).unwrap();
        let mut out = ControlOutput::default();
        for k in 0..200 {
            let m = Measurement {
                t: k as f64 * 1e-3,
                omega: 10.0 / 0.7 / v.r,
                v: Some(10.0),
                torque: 100.0,
                demand: 100.0 + k as f64,
            };
            out = c.step(&m, None);
        }
        assert!(out.torque_cmd < 100.0, "{}", out.torque_cmd);
    }
}
