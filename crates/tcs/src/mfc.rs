//! MFC: Hori's model following control (paper §III-A; README.md, "MFC").
//!
//! ```text
//! ω_M[k+1] = ω_M[k] + dt · T[k] / J_model          (model wheel: 1 / (J_model s))
//! e[k]     = HPF_τ₂( ω[k] − ω_M[k] )               (τ₂ = tau_hpf, backward Euler)
//! e_f[k]   = LPF_τf( e[k] )                         (τ_f = tau_noise; 0: e_f = e)
//! T*[k]    = clamp( T_d − K_MFC · e_f[k],  0,  T_d )  for T_d > 0
//! ```
//!
//! The low-pass on the error is not the paper's: it keeps K_MFC (177 N m
//! s/rad) from turning wheel-speed noise into a chattering command. It acts
//! on ω − ω_M, i.e. on the wheel and on the model alike, so the model's own
//! motion never shows up as a lagged error; what it delays is the slip
//! itself, by τ_f, which adds to the motor lag τ₁ in the paper's bound (4)
//! (README.md, "MFC: the noise filter").
//!
//! - `T` is the torque the inverter reports (`Measurement::torque`), so model
//!   and wheel are driven by the same torque as in the paper's eq. (3).
//! - `J_model = J_w + (M/n) r²` without ARTE (paper eq. 2);
//!   with usable road knowledge `J_w + (M/n) r² (1 − λ_opt)` (paper §IV).
//! - ω_M starts at the first measured ω (the drive may start rolling).
//! - The clamp to `[0, T_d]` drops Hori's model *addition* (when the wheel is
//!   slower than the model the raw law would exceed the demand); a TCS here
//!   only ever reduces the driver's demand (README.md, "Controllers").
//! - `T_d <= 0` (coasting, regeneration) is passed through; the model and
//!   the filter keep running so that the next positive demand starts from a
//!   consistent state.

use crate::filters::{HighPass, LowPass};
use crate::params::{ArteUse, MfcParams};
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};
use crate::{limit_to_demand, valid_dt};
use grip_physics::{InvalidField, VehicleParams};

/// Model following controller.
#[derive(Debug, Clone)]
pub struct Mfc {
    params: MfcParams,
    arte: ArteUse,
    dt: f64,
    j_w: f64,
    share_r2: f64,
    hpf: HighPass,
    /// `None` with tau_noise = 0 (the paper's MFC, bit for bit).
    lpf: Option<LowPass>,
    omega_model: f64,
    started: bool,
    /// The last filtered speed error, rad/s (held over a measurement that
    /// is no number).
    last_e: f64,
}

impl Mfc {
    /// A controller for `vehicle` at sample time `dt` (s). Parameters are
    /// validated here too (the loader already did; this keeps direct
    /// construction safe).
    pub fn new(
        params: MfcParams,
        arte: ArteUse,
        vehicle: &VehicleParams,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        params.validate()?;
        arte.validate()?;
        valid_dt(dt)?;
        vehicle.validate()?;
        Ok(Self {
            params,
            arte,
            dt,
            j_w: vehicle.j_w,
            share_r2: vehicle.mass_share() * vehicle.r * vehicle.r,
            hpf: HighPass::new(params.tau_hpf, dt),
            lpf: (params.tau_noise > 0.0).then(|| LowPass::new(params.tau_noise, dt)),
            omega_model: 0.0,
            started: false,
            last_e: 0.0,
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &MfcParams {
        &self.params
    }

    /// Model inertia for a given slip assumption: J_w + (M/n) r² (1 − λ).
    pub fn j_model(&self, lambda: f64) -> f64 {
        self.j_w + self.share_r2 * (1.0 - lambda)
    }
}

impl Controller for Mfc {
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput {
        let known = self.arte.usable(road);
        let j_model = self.j_model(known.map_or(0.0, |k| k.lambda_opt));
        // A wheel speed that is no number leaves the filters as they are and
        // the command at the last error: fed to them it stayed in their state
        // for good, and the command at 0 N m from then on.
        let e = if !m.omega.is_finite() {
            self.last_e
        } else {
            if !self.started {
                self.omega_model = m.omega;
                self.started = true;
            }
            let e = self.hpf.step(m.omega - self.omega_model);
            match self.lpf.as_mut() {
                Some(f) => f.step(e),
                None => e,
            }
        };
        self.last_e = e;
        let candidate = m.demand - self.params.k_mfc * e;
        let torque_cmd = limit_to_demand(candidate, m.demand);
        let out = ControlOutput {
            torque_cmd,
            used_arte: known.is_some(),
            internal: self.omega_model,
            mu_hat: f64::NAN,
            passthrough: false,
        };
        // Advance the model with this cycle's torque (explicit Euler of 1/(J s)).
        let next = self.omega_model + self.dt * m.torque / j_model;
        if next.is_finite() {
            self.omega_model = next;
        } else {
            // Absurd inputs: restart the model on the next measurement.
            self.reset();
        }
        out
    }

    fn reset(&mut self) {
        self.hpf.reset();
        if let Some(f) = self.lpf.as_mut() {
            f.reset();
        }
        self.omega_model = 0.0;
        self.started = false;
        self.last_e = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meas(omega: f64, torque: f64, demand: f64) -> Measurement {
        Measurement {
            t: 0.0,
            omega,
            v: None,
            torque,
            demand,
        }
    }

    #[test]
    fn no_slip_no_correction() {
        // A wheel whose speed follows the model exactly: the command is the demand.
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mfc::new(MfcParams::default(), ArteUse::default(), &v, dt).unwrap();
        let mut omega = 10.0;
        for _ in 0..2000 {
            let out = c.step(&meas(omega, 300.0, 300.0), None);
            assert!((out.torque_cmd - 300.0).abs() < 1e-6, "{}", out.torque_cmd);
            assert!(!out.used_arte);
            omega += dt * 300.0 / v.j_model();
        }
    }

    #[test]
    fn one_wheel_speed_that_is_no_number_does_not_latch_the_command() {
        // A gripping wheel that follows the model, one NaN sample at 0.1 s:
        // the command holds over it and is the demand again after it
        // (before, the NaN stayed in the filters and the command at 0 N m).
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mfc::new(MfcParams::default(), ArteUse::default(), &v, dt).unwrap();
        let mut omega = 10.0;
        for k in 0..400 {
            let w = if k == 100 { f64::NAN } else { omega };
            let out = c.step(&meas(w, 300.0, 300.0), None).torque_cmd;
            assert!((out - 300.0).abs() < 1e-6, "{k}: {out}");
            omega += dt * 300.0 / v.j_model();
        }
    }

    #[test]
    fn a_spinning_wheel_gets_its_torque_cut() {
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mfc::new(MfcParams::default(), ArteUse::default(), &v, dt).unwrap();
        let mut omega = 10.0;
        let mut last = 300.0;
        for _ in 0..200 {
            last = c.step(&meas(omega, 300.0, 300.0), None).torque_cmd;
            // The real wheel is much lighter than the model (spinning on ice).
            omega += dt * 150.0 / v.j_w;
        }
        // After 0.2 s the (high-passed) speed error is tens of rad/s; with
        // K_MFC = 177 N m s/rad even 1.7 rad/s cuts the whole demand.
        assert!(last < 1.0, "{last}");
        // With the first comparison's gain (2.5, the bound at the free-
        // spinning wheel) the same error cut only ~110 N m.
        let p = MfcParams {
            k_mfc: 2.5,
            tau_hpf: 1.0,
            tau_noise: 0.0,
        };
        let mut c = Mfc::new(p, ArteUse::default(), &v, dt).unwrap();
        let mut omega = 10.0;
        for _ in 0..200 {
            last = c.step(&meas(omega, 300.0, 300.0), None).torque_cmd;
            omega += dt * 150.0 / v.j_w;
        }
        assert!(last < 220.0 && last > 100.0, "{last}");
    }

    #[test]
    fn arte_changes_the_model_inertia() {
        let v = VehicleParams::default();
        let dt = 1e-3;
        let k = RoadKnowledge {
            lambda_opt: 0.2,
            mu_peak: 1.0,
            alpha: 0.8,
            confidence: 1.0,
            age: 0.0,
        };
        let mut c = Mfc::new(MfcParams::default(), ArteUse::default(), &v, dt).unwrap();
        let out = c.step(&meas(0.0, 100.0, 100.0), Some(&k));
        assert!(out.used_arte);
        let out = c.step(&meas(0.0, 100.0, 100.0), Some(&k));
        let expected = dt * 100.0 / (v.j_w + v.mass_share() * v.r * v.r * 0.8);
        assert!((out.internal - expected).abs() < 1e-12);
    }

    /// Uniform noise in [-a, a] from a fixed xorshift stream (σ = a/√3).
    fn noise(state: &mut u64, a: f64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        a * (2.0 * (*state >> 11) as f64 / (1u64 << 53) as f64 - 1.0)
    }

    fn p(tau_noise: f64) -> MfcParams {
        MfcParams {
            tau_noise,
            ..MfcParams::default()
        }
    }

    #[test]
    fn the_noise_filter_cuts_the_chatter_of_a_gripping_wheel() {
        // A wheel that follows the model, measured with σ = 0.05 rad/s of
        // white noise (the shipped sensor's): the command's total variation
        // over 2 s with and without the 4 ms low-pass on the error.
        let v = VehicleParams::default();
        let dt = 1e-3;
        let tv = |tau_noise: f64| {
            let mut c = Mfc::new(p(tau_noise), ArteUse::default(), &v, dt).unwrap();
            let mut s = 0x9E37_79B9_7F4A_7C15u64;
            let (mut omega, mut prev, mut tv) = (10.0, 300.0, 0.0);
            for _ in 0..2000 {
                let a = 0.05 * 3f64.sqrt();
                let cmd = c
                    .step(&meas(omega + noise(&mut s, a), 300.0, 300.0), None)
                    .torque_cmd;
                tv += (cmd - prev).abs();
                prev = cmd;
                omega += dt * 300.0 / v.j_model();
            }
            tv / 2.0
        };
        let (raw, filtered) = (tv(0.0), tv(0.004));
        // Unfiltered: K σ = 8.9 N m of jitter, about half of it clipped at
        // T_d: about 3 kN m/s. The 4 ms filter passes a fifth of each
        // sample's noise and averages the rest away.
        assert!(raw > 2000.0, "{raw}");
        // (2890 -> 190 N m/s here)
        assert!(filtered < raw / 10.0, "{raw} -> {filtered}");
    }

    #[test]
    fn the_noise_filter_delays_a_slip_cut_by_about_its_time_constant() {
        // A wheel that starts to spin at 0.1 s: the cycle at which the
        // command falls below half the demand, with and without the filter.
        let v = VehicleParams::default();
        let dt = 1e-3;
        let cut_at = |tau_noise: f64| {
            let mut c = Mfc::new(p(tau_noise), ArteUse::default(), &v, dt).unwrap();
            let mut omega = 10.0;
            for k in 0..400 {
                let cmd = c.step(&meas(omega, 300.0, 300.0), None).torque_cmd;
                if cmd < 150.0 {
                    return k;
                }
                let j = if k < 100 { v.j_model() } else { v.j_w };
                omega += dt * 300.0 / j;
            }
            usize::MAX
        };
        let (raw, filtered) = (cut_at(0.0), cut_at(0.004));
        // 102 -> 105 cycles: 3 ms later with τ_f = 4 ms
        assert!((100..110).contains(&raw), "{raw}");
        assert!(filtered > raw && filtered <= raw + 4, "{raw} -> {filtered}");
    }
}
