//! Vehicle parameters (paper Table IV; README.md, "Plant").

use crate::validate::{self, InvalidField};

/// Parameters of the vehicle and its driven wheel. Defaults are the paper's
/// Table IV plus the choices in README.md, "Plant" (n = 4 driven wheels).
///
/// Deserialises from TOML (`[vehicle]` in `config/vehicle.toml`); a missing
/// field takes its default, an unknown one is an error. Call
/// [`VehicleParams::validate`] after loading.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleParams {
    /// Vehicle mass M, kg.
    pub mass: f64,
    /// Driven wheels sharing the vehicle, n (the wheel carries M/n).
    pub n_driven: f64,
    /// Wheel + shaft inertia J_w, kg m^2.
    pub j_w: f64,
    /// Tyre radius r, m.
    pub r: f64,
    /// Wheel mass m, kg. Informational: it is part of M and is not used
    /// separately by the quarter-vehicle plant (the paper lists it in Table IV).
    pub m_wheel: f64,
    /// Motor torque lag tau_m, s (first order).
    pub tau_m: f64,
    /// Rolling resistance coefficient C_rr.
    pub c_rr: f64,
    /// Air density rho, kg/m^3.
    pub rho: f64,
    /// Drag area C_d A, m^2.
    pub c_d_a: f64,
    /// Speed floor in the slip denominator, m/s.
    pub v_eps: f64,
    /// Motor torque limit, N m (|T| is clamped to this).
    pub torque_max: f64,
    /// Share of the vehicle's weight carried by the driven wheels together,
    /// (0, 1]: the driven wheel's normal force is N = share · M g / n. 1
    /// (default: every wheel driven, n = 4, the paper's set-up) gives
    /// N = M g / n; a rear-driven car with n = 2 and 50 % on the rear axle
    /// has 0.5.
    pub driven_load_share: f64,
    /// Where the microphone hears the road, m along the path ahead of the
    /// driven (controlled) wheel's contact patch: 0 (default) = at the
    /// driven wheel, the paper's set-up; a front-wheel-arch microphone on a
    /// rear-driven car hears the road one wheelbase ahead. Not used by the
    /// plant; the simulator, plant-sim's ground truth, audio-acq's synthetic
    /// source and the preview queue of the controllers use it.
    pub mic_lead_m: f64,
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self {
            mass: 1400.0,
            n_driven: 4.0,
            j_w: 0.6,
            r: 0.28,
            m_wheel: 10.0,
            tau_m: 0.05,
            c_rr: 0.015,
            rho: 1.2,
            c_d_a: 0.7,
            v_eps: 0.1,
            torque_max: 1000.0,
            driven_load_share: 1.0,
            mic_lead_m: 0.0,
        }
    }
}

impl VehicleParams {
    /// Mass carried by one driven wheel, M/n, kg.
    pub fn mass_share(&self) -> f64 {
        self.mass / self.n_driven
    }
    /// Cycles of `dt` it takes, rolling at `v0` m/s, to cover the
    /// microphone's lead (`mic_lead_m`): `⌈lead / (v0 dt)⌉`, 0 without a lead
    /// or from standstill. The pre-roll of `grip sim` and plant-sim: the car
    /// rolls this far before the scenario's x = 0, so that the microphone has
    /// heard the road from 0 to the lead when the wheel gets there.
    pub fn pre_roll_cycles(&self, v0: f64, dt: f64) -> u64 {
        let lead = self.mic_lead_m;
        if lead > 0.0 && v0 > 0.0 && dt > 0.0 {
            (lead / (v0 * dt)).ceil() as u64
        } else {
            0
        }
    }
    /// Normal force on the driven wheel, N = share · M g / n
    /// ([`VehicleParams::driven_load_share`]; M g / n by default).
    pub fn normal_force(&self) -> f64 {
        self.driven_load_share * self.mass * crate::G / self.n_driven
    }
    /// Inertia of the vehicle share reflected to the wheel, J_w + (M/n) r^2 (paper eq. 2).
    pub fn j_model(&self) -> f64 {
        self.j_w + self.mass_share() * self.r * self.r
    }

    /// Check ranges (NaN and infinities fail everywhere): mass, j_w, r,
    /// v_eps, torque_max > 0; n_driven >= 1; m_wheel in [0, mass); tau_m,
    /// c_rr, rho, c_d_a >= 0.
    pub fn validate(&self) -> Result<(), InvalidField> {
        validate::positive("mass", self.mass)?;
        if !(self.n_driven.is_finite() && self.n_driven >= 1.0) {
            return Err(InvalidField::new(
                "n_driven",
                format!("must be >= 1 (got {})", self.n_driven),
            ));
        }
        validate::positive("j_w", self.j_w)?;
        validate::positive("r", self.r)?;
        validate::non_negative("m_wheel", self.m_wheel)?;
        if self.m_wheel >= self.mass {
            return Err(InvalidField::new(
                "m_wheel",
                format!(
                    "must be smaller than the vehicle mass {} (got {})",
                    self.mass, self.m_wheel
                ),
            ));
        }
        validate::non_negative("tau_m", self.tau_m)?;
        validate::in_range("c_rr", self.c_rr, 0.0, 1.0)?;
        validate::non_negative("rho", self.rho)?;
        validate::non_negative("c_d_a", self.c_d_a)?;
        validate::positive("v_eps", self.v_eps)?;
        validate::positive("torque_max", self.torque_max)?;
        if !(self.driven_load_share > 0.0 && self.driven_load_share <= 1.0) {
            return Err(InvalidField::new(
                "driven_load_share",
                format!("must be in (0, 1] (got {})", self.driven_load_share),
            ));
        }
        validate::in_range("mic_lead_m", self.mic_lead_m, 0.0, 20.0)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_match_models_md() {
        let p = VehicleParams::default();
        p.validate().unwrap();
        // README.md, "Plant": N = M g / 4 = 3433 N; snow carries 0.19 * N * r = 183 N m.
        assert!((p.normal_force() - 3433.5).abs() < 0.1);
        assert!((0.19 * p.normal_force() * p.r - 182.7).abs() < 0.5);
    }

    #[test]
    fn bad_values_fail_with_the_field_named() {
        type Mutation = fn(&mut VehicleParams);
        let cases: [(&str, Mutation); 9] = [
            ("driven_load_share", |p| p.driven_load_share = 0.0),
            ("driven_load_share", |p| p.driven_load_share = f64::NAN),
            ("mic_lead_m", |p| p.mic_lead_m = -1.0),
            ("mass", |p| p.mass = -5.0),
            ("mass", |p| p.mass = f64::NAN),
            ("r", |p| p.r = 0.0),
            ("n_driven", |p| p.n_driven = 0.5),
            ("v_eps", |p| p.v_eps = 0.0),
            ("m_wheel", |p| p.m_wheel = 2000.0),
        ];
        for (field, f) in cases {
            let mut p = VehicleParams::default();
            f(&mut p);
            assert_eq!(p.validate().unwrap_err().field, field);
        }
    }
}
