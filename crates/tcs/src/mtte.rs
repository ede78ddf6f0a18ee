//! MTTE: maximum transmissible torque estimation (Yin, Oh, Hori, IEEE TIE
//! 56(6), 2009; paper §III-C). No chassis speed needed.
//!
//! ```text
//! F̂_d    = (LPF(T) − J_w dω/dt) / r                          (observer, τ_o = tau_obs)
//! α      = ARTE usable ? RoadKnowledge::alpha : alpha (config)
//! T_raw  = ( J_w / (α (M/n) r) + r ) · F̂_d
//! T_max  = max( LPF_τ₁(T_raw), T_floor ),   T_floor = mu_floor · N · r
//! T*     = min(T_d, T_max)   (and >= 0 for T_d > 0)
//! ```
//!
//! α is the relaxation factor: the chassis acceleration over the wheel's
//! circumferential acceleration that the controller tolerates
//! (dV/dt = α r dω/dt). At constant slip λ the true ratio is 1 − λ, so the
//! torque limit rises while λ < 1 − α and falls once λ > 1 − α: the
//! equilibrium slip is 1 − α, which is why ARTE's α defaults to 1 − λ_opt.
//!
//! **Start-up.** From standstill with T = 0 the observer sees F̂_d = 0 and
//! the raw limit is 0; the limit can only grow by the factor
//! (J_w/α + (M/n) r²)/(J_w/(1−λ) + (M/n) r²) (≈ 1.002 for the default
//! vehicle) per loop time constant, so a pure MTTE would hold the car at
//! standstill. The limit therefore never drops below T_floor, the torque the
//! lowest-friction catalogued road (ice, mu_peak 0.05) carries, so the floor
//! alone cannot spin the wheel on any catalogued road; the LPF state starts at
//! T_floor and is kept >= T_floor. See README for why this is our choice and
//! not a verified detail of the original.
//!
//! **A ramped pedal** (`spin_share`, not in the paper, whose demands are
//! constant). The limiter starts inactive only at the first positive demand;
//! a demand that rises from there (a driver's pedal) would meet the limit's
//! slow growth and stay near T_floor. So every rise of the demand passes into
//! T_max while the wheel grips, i.e. takes no more than `spin_share` of the
//! torque to spin itself up (J_w dω/dt <= spin_share · LPF(T) from the
//! observer; 1-2 % while it grips), and the low-pass does not pull the limit
//! down meanwhile. A constant demand never passes anything (the paper's
//! drives are unchanged); once the wheel spins, MTTE's own law takes over.
//!
//! `internal` is T_max (N m); `mu_hat` is μ̂.

use crate::filters::LowPass;
use crate::observer::DrivingForceObserver;
use crate::params::{ArteUse, MtteParams};
use crate::types::{ControlOutput, Controller, Measurement, RoadKnowledge};
use crate::{DemandRise, limit_to_demand, valid_dt};
use grip_physics::{InvalidField, VehicleParams};

/// Maximum transmissible torque estimation controller.
#[derive(Debug, Clone)]
pub struct Mtte {
    params: MtteParams,
    arte: ArteUse,
    j_w: f64,
    r: f64,
    mass_share: f64,
    floor: f64,
    observer: DrivingForceObserver,
    lpf: LowPass,
    /// The torque command of the previous cycle (the torque reference the
    /// observer is fed with); `None` before the first positive demand.
    last_cmd: Option<f64>,
    /// The demand's rise since the previous cycle.
    rise: DemandRise,
}

impl Mtte {
    /// A controller for `vehicle` at sample time `dt` (s).
    pub fn new(
        params: MtteParams,
        arte: ArteUse,
        vehicle: &VehicleParams,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        params.validate()?;
        arte.validate()?;
        valid_dt(dt)?;
        vehicle.validate()?;
        let floor = params.mu_floor * vehicle.normal_force() * vehicle.r;
        Ok(Self {
            params,
            arte,
            j_w: vehicle.j_w,
            r: vehicle.r,
            mass_share: vehicle.mass_share(),
            floor,
            observer: DrivingForceObserver::new(vehicle, params.tau_obs, dt),
            lpf: LowPass::new(params.tau_lpf, dt),
            last_cmd: None,
            rise: DemandRise::default(),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &MtteParams {
        &self.params
    }

    /// The start-up floor T_floor = mu_floor · N · r, N m.
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// The factor T_max / F̂_d = J_w / (α (M/n) r) + r, m.
    pub fn gain(&self, alpha: f64) -> f64 {
        self.j_w / (alpha * self.mass_share * self.r) + self.r
    }
}

impl Controller for Mtte {
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput {
        let known = self.arte.usable(road);
        let alpha = known.map_or(self.params.alpha, |k| k.alpha);
        let positive = m.demand > 0.0 && m.demand.is_finite();
        // The observer's torque input is the torque *reference* of the last
        // cycle (Hori-group disturbance observers; the paper's eq. (11)).
        // Before the first positive demand (start of a drive, or after
        // coasting or braking, when T* = T_d passes through) the reference
        // is the demand itself, so the limiter starts inactive.
        if positive && self.last_cmd.is_none() {
            // A new positive demand: restart the estimator as at the start
            // of a drive (both filters prime on this sample).
            self.observer.reset();
            self.lpf.reset();
        }
        let t_ref = self.last_cmd.unwrap_or(m.demand);
        let previous = self.lpf.value();
        let rise = self.rise.step(m.demand);
        let f_hat = self.observer.step(t_ref, m.omega);
        let raw = self.gain(alpha) * f_hat;
        let filtered = self.lpf.step(raw);
        let mut t_max = if filtered.is_finite() {
            filtered.max(self.floor)
        } else {
            self.floor
        };
        // The driver asks for more while the wheel grips (it takes no more
        // than spin_share of the torque to spin itself up, J_w dω/dt <=
        // spin_share · LPF(T); gripping, the car's share of the inertia
        // leaves it 1-2 %): the rise passes into the limit, as the first
        // demand did, and the limit is not pulled down meanwhile (the raw
        // limit trails a rising command by the filters' lag, not because
        // the road carries less). A ramped pedal is a sequence of small
        // steps; without this the limit grew only by the (1/α − 1) J_w
        // share of the torque per τ₁ and a ramp from 0 stayed at T_floor.
        // A constant demand never gets here.
        if self.last_cmd.is_some()
            && rise > 0.0
            && self.r * self.observer.force()
                >= (1.0 - self.params.spin_share) * self.observer.torque()
            && previous.is_finite()
        {
            // Never above the demand by this rule: a pedal pumped while
            // the wheel grips must not ratchet the limit up, far from where
            // a spin would have to pull it down from.
            t_max = t_max.max((previous + rise).min(m.demand));
        }
        self.lpf.set(t_max);
        let torque_cmd = limit_to_demand(t_max.min(m.demand), m.demand);
        self.last_cmd = if positive { Some(torque_cmd) } else { None };
        ControlOutput {
            torque_cmd,
            used_arte: known.is_some(),
            internal: t_max,
            mu_hat: self.observer.mu(),
            passthrough: false,
        }
    }

    fn reset(&mut self) {
        self.observer.reset();
        self.lpf.reset();
        self.last_cmd = None;
        self.rise = DemandRise::default();
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
    fn the_limiter_starts_inactive_at_standstill() {
        // Before the first estimate the limiter passes the demand (the
        // observer is fed the torque reference, which is the demand), so
        // MTTE does not hold a car at standstill, and on a gripping wheel
        // T_max stays above the demand.
        let v = VehicleParams::default();
        let mut c = Mtte::new(MtteParams::default(), ArteUse::default(), &v, 1e-3).unwrap();
        let floor = 0.05 * v.normal_force() * v.r;
        assert!((c.floor() - floor).abs() < 1e-9);
        let out = c.step(&meas(0.0, 0.0, 300.0), None);
        assert_eq!(out.torque_cmd, 300.0);
        assert!(out.internal > 300.0, "{}", out.internal);
        // A wheel that grips (it accelerates with the whole share's inertia):
        // the demand is delivered for the whole second.
        let mut omega = 0.0;
        for _ in 0..1000 {
            let out = c.step(&meas(omega, 300.0, 300.0), None);
            assert_eq!(out.torque_cmd, 300.0);
            omega += 1e-3 * 300.0 / v.j_model();
        }
    }

    #[test]
    fn steady_force_gives_the_papers_limit() {
        let v = VehicleParams::default();
        let p = MtteParams::default();
        let mut c = Mtte::new(p, ArteUse::default(), &v, 1e-3).unwrap();
        // Constant speed, demand 200 below the limit: the reference is 200,
        // F̂_d = 200 / r, T_max = (J_w / (α m r) + r) · 200 / r.
        let mut out = ControlOutput::default();
        for _ in 0..2000 {
            out = c.step(&meas(20.0, 200.0, 200.0), None);
        }
        let expected = (v.j_w / (p.alpha * v.mass_share() * v.r) + v.r) * 200.0 / v.r;
        assert!(
            (out.internal - expected).abs() < 1e-6,
            "{} vs {expected}",
            out.internal
        );
        assert_eq!(out.torque_cmd, 200.0);
        // A smaller demand wins.
        let out = c.step(&meas(20.0, 200.0, 100.0), None);
        assert_eq!(out.torque_cmd, 100.0);
    }

    #[test]
    fn a_spinning_wheel_is_limited_to_what_the_road_transmits() {
        // Wheel alone on a road that transmits F = 500 N (r F = 140 N m);
        // the demand 300 N m spins it up. The first-order motor lag (50 ms)
        // sits between command and wheel torque. T_max falls to about r F
        // and the wheel acceleration almost stops.
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mtte::new(MtteParams::default(), ArteUse::default(), &v, dt).unwrap();
        let f = 500.0;
        let (mut omega, mut torque) = (10.0, 0.0);
        let mut out = ControlOutput::default();
        for _ in 0..3000 {
            out = c.step(&meas(omega, torque, 300.0), None);
            torque += dt / 0.05 * (out.torque_cmd - torque);
            omega += dt * (torque - v.r * f) / v.j_w;
        }
        let rf = v.r * f;
        assert!(
            (out.torque_cmd - rf).abs() < 0.05 * rf,
            "{} vs {rf}",
            out.torque_cmd
        );
    }

    #[test]
    fn arte_alpha_is_used() {
        let v = VehicleParams::default();
        let mut a = Mtte::new(MtteParams::default(), ArteUse::default(), &v, 1e-3).unwrap();
        let k = RoadKnowledge {
            lambda_opt: 0.4,
            mu_peak: 1.0,
            alpha: 0.6,
            confidence: 1.0,
            age: 0.0,
        };
        let mut out = ControlOutput::default();
        for _ in 0..2000 {
            out = a.step(&meas(20.0, 200.0, 200.0), Some(&k));
        }
        assert!(out.used_arte);
        let expected = (v.j_w / (0.6 * v.mass_share() * v.r) + v.r) * 200.0 / v.r;
        assert!((out.internal - expected).abs() < 1e-6);
    }

    /// The wheel with the whole share's inertia (it grips) or alone on a road
    /// that transmits `f_road` N (it spins once the torque passes r F), the
    /// motor a 50 ms lag; the demand ramps from 0 to `top` N m over `rise_s`
    /// and is then held, 1.5 s in all. Returns the commands.
    fn ramp(p: MtteParams, f_road: Option<f64>, top: f64, rise_s: f64) -> Vec<f64> {
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mtte::new(p, ArteUse::default(), &v, dt).unwrap();
        let (mut omega, mut torque) = (3.0 / v.r, 0.0);
        (0..1500)
            .map(|k| {
                let demand = (top * (k + 1) as f64 * dt / rise_s).min(top);
                let out = c.step(&meas(omega, torque, demand), None);
                torque += dt / 0.05 * (out.torque_cmd - torque);
                omega += dt
                    * match f_road {
                        None => torque / v.j_model(),
                        Some(f) => (torque - v.r * f) / v.j_w,
                    };
                out.torque_cmd
            })
            .collect()
    }

    #[test]
    fn a_ramped_demand_passes_while_the_wheel_grips() {
        // Gripping: the command follows the ramp (within the first cycle's
        // lag) and holds the demand after it.
        let cmds = ramp(MtteParams::default(), None, 220.0, 0.3);
        for (k, c) in cmds.iter().enumerate() {
            let demand = (220.0 * (k + 1) as f64 * 1e-3 / 0.3).min(220.0);
            assert!(*c >= demand - 1.0, "cycle {k}: {c} against {demand}");
        }
        // Without the rise passing (spin_share 0), the limit stays near the
        // start-up floor (ice's 48 N m): the car would not pull away.
        let p = MtteParams {
            spin_share: 0.0,
            ..MtteParams::default()
        };
        let stuck = ramp(p, None, 220.0, 0.3);
        assert!(stuck[1499] < 60.0, "{}", stuck[1499]);
    }

    #[test]
    fn a_ramped_demand_does_not_pass_into_a_spinning_wheel() {
        // On a road that transmits 500 N (r F = 140 N m) a ramp to 300 N m
        // over 1 s spins the wheel once the motor passes r F (at about
        // 0.5 s); the rise stops passing a little later (the motor's and the
        // observer's lag, then the 10 % share) and the limit falls to about
        // r F, as after a step.
        let v = VehicleParams::default();
        let rf = v.r * 500.0;
        let cmds = ramp(MtteParams::default(), Some(500.0), 300.0, 1.0);
        let end = cmds[1499];
        assert!((end - rf).abs() < 0.05 * rf, "{end} vs {rf}");
        let peak = cmds.iter().copied().fold(0.0, f64::max);
        assert!(peak < 1.4 * rf, "peak command {peak} against r F = {rf}");
        // Were every rise to pass (any share), the command would follow the
        // ramp to the demand before the limit came down.
        let p = MtteParams {
            spin_share: 1.0,
            ..MtteParams::default()
        };
        let blind = ramp(p, Some(500.0), 300.0, 1.0);
        let blind_peak = blind.iter().copied().fold(0.0, f64::max);
        assert!(blind_peak > 1.8 * rf, "{blind_peak}");
    }

    #[test]
    fn a_pumped_pedal_does_not_ratchet_the_limit_above_the_demand() {
        // Gripping, the demand pumped 150 <-> 250 N m every 20 ms for 1 s:
        // the rises pass, but the limit never ends up above the largest
        // demand by more than MTTE's own margin.
        let v = VehicleParams::default();
        let dt = 1e-3;
        let mut c = Mtte::new(MtteParams::default(), ArteUse::default(), &v, dt).unwrap();
        let (mut omega, mut torque) = (3.0 / v.r, 0.0);
        let mut top = 0.0f64;
        for k in 0..1000 {
            let demand = if (k / 20) % 2 == 0 { 250.0 } else { 150.0 };
            let out = c.step(&meas(omega, torque, demand), None);
            torque += dt / 0.05 * (out.torque_cmd - torque);
            omega += dt * torque / v.j_model();
            top = top.max(out.internal);
        }
        assert!(top < 1.05 * 250.0, "limit rose to {top} N m");
    }
}
