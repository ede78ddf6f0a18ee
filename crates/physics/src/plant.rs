//! The quarter-vehicle plant (README.md, "Plant"): one driven wheel carrying M/n,
//! a first-order motor lag, the tyre force from the road's mu-lambda curve and
//! the driving resistance.
//!
//! ```text
//! tau_m dT/dt  = T* - T                       T* clamped to ±T_lim(ω)
//! T_lim(ω)     = torque_max, or min(torque_max, power_max/|ω|) with a power limit
//! J_w dω/dt    = T - r F_x
//! (M/n) dV/dt  = F_x - F_dr(V)/n
//! dx/dt        = V
//! F_x          = mu(λ) N,  N = M g cos θ / n
//! λ            = (r ω - V) / max(|r ω|, |V|, v_eps)
//! F_dr(V)      = C_rr M g cos θ · s(V) + ½ ρ C_dA V |V| + M g sin θ
//! s(V)         = V / max(|V|, V_ROLL_REG)
//! ```
//!
//! Rolling resistance acts on the **chassis** (inside F_dr, shared by n), not
//! as a wheel torque, so the wheel equation carries no r F_roll term and the
//! driving-force observers of the controllers see the tyre force F_x alone.
//! Rolling resistance and drag always oppose V: s(V) is a sign function
//! regularised over |V| < [`V_ROLL_REG`] (1 cm/s), so at rest on the flat the
//! resistance is exactly zero and can never push the car backwards; only the
//! grade term M g sin θ can (a car on an uphill with no torque does roll back).
//! The absolute values in the slip denominator extend the paper's formula to
//! reverse motion; for forward driving it is the paper's max(r ω, V, v_eps).
//!
//! Integration: the motor lag is integrated exactly over each call (T* is held
//! for the call). The stiff (ω, V) pair (slip time constant down to ~10 µs near
//! standstill) is integrated with the **linearly implicit (Rosenbrock) Euler**
//! method on sub-steps of at most `max_substep` (default
//! [`DEFAULT_MAX_SUBSTEP`]): `(I - h J) Δy = h f(y)` with the analytic 2x2
//! Jacobian J of the slip coupling, using the exact mean motor torque over the
//! sub-step. It is L-stable on the linearised slip dynamics, so no sub-step size
//! makes it blow up; the sub-step only sets accuracy (see the crate README for
//! the convergence evidence). Position uses the trapezoidal rule.
//! `step` allocates nothing.

use crate::road::Road;
use crate::validate::{self, InvalidField};
use crate::vehicle::VehicleParams;

/// Default upper bound on the internal integration step, s (10 sub-steps per
/// 1 ms controller period).
pub const DEFAULT_MAX_SUBSTEP: f64 = 1e-4;

/// Speed below which rolling resistance is regularised (linear in V), m/s.
pub const V_ROLL_REG: f64 = 0.01;

/// Upper bound on the number of sub-steps in one call (a huge `dt` is then
/// integrated with larger, still stable, sub-steps instead of looping forever).
pub const MAX_SUBSTEPS_PER_CALL: usize = 100_000;

/// The plant's true state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantState {
    /// Driven-wheel angular speed ω, rad/s.
    pub omega: f64,
    /// Vehicle (chassis) speed V, m/s.
    pub v: f64,
    /// Motor torque T (after the lag), N m.
    pub torque: f64,
    /// Distance travelled x, m.
    pub x: f64,
}

impl PlantState {
    /// At rest: everything zero.
    pub fn standstill() -> Self {
        Self::default()
    }

    /// Rolling freely at speed `v` (m/s) with zero slip (ω = v / r), zero
    /// torque, at x = 0.
    pub fn rolling(v: f64, r: f64) -> Self {
        Self {
            omega: v / r,
            v,
            torque: 0.0,
            x: 0.0,
        }
    }
}

/// The quarter-vehicle plant. See the module docs for the equations.
#[derive(Debug, Clone)]
pub struct Plant {
    params: VehicleParams,
    state: PlantState,
    max_substep: f64,
    lambda: f64,
    mu: f64,
    fx: f64,
    derating: bool,
}

/// Per-call constants of the right-hand side.
struct Env<'a> {
    road: &'a Road,
    /// Normal force on the wheel, N.
    n_force: f64,
    /// Rolling resistance magnitude (whole vehicle), N.
    f_roll: f64,
    /// Grade force (whole vehicle), N, positive uphill.
    f_grade: f64,
    /// ½ ρ C_dA.
    k_aero: f64,
}

impl Plant {
    /// A plant with validated `params`, starting at `state` (which must be finite).
    pub fn new(params: VehicleParams, state: PlantState) -> Result<Self, InvalidField> {
        params.validate()?;
        validate::finite("omega", state.omega)?;
        validate::finite("v", state.v)?;
        validate::finite("torque", state.torque)?;
        validate::finite("x", state.x)?;
        let mut p = Self {
            params,
            state,
            max_substep: DEFAULT_MAX_SUBSTEP,
            lambda: 0.0,
            mu: 0.0,
            fx: 0.0,
            derating: false,
        };
        p.lambda = p.slip_of(state.omega, state.v);
        Ok(p)
    }

    /// Set the upper bound on the internal integration step (s, > 0). A
    /// call of [`Plant::step`] takes at most [`MAX_SUBSTEPS_PER_CALL`]
    /// sub-steps, so a bound below `dt / MAX_SUBSTEPS_PER_CALL` is not
    /// honoured for a step of `dt` (`grip-sim` refuses one below its
    /// controller period's).
    pub fn set_max_substep(&mut self, h: f64) -> Result<(), InvalidField> {
        validate::positive("max_substep", h)?;
        self.max_substep = h;
        Ok(())
    }

    /// The upper bound on the internal integration step, s.
    pub fn max_substep(&self) -> f64 {
        self.max_substep
    }

    /// The vehicle parameters.
    pub fn params(&self) -> &VehicleParams {
        &self.params
    }

    /// The true state after the last step.
    pub fn state(&self) -> &PlantState {
        &self.state
    }

    /// Replace the state (e.g. at the start of a run). Non-finite fields are
    /// rejected and the state is left unchanged.
    pub fn set_state(&mut self, state: PlantState) -> Result<(), InvalidField> {
        validate::finite("omega", state.omega)?;
        validate::finite("v", state.v)?;
        validate::finite("torque", state.torque)?;
        validate::finite("x", state.x)?;
        self.state = state;
        self.lambda = self.slip_of(state.omega, state.v);
        self.mu = 0.0;
        self.fx = 0.0;
        Ok(())
    }

    /// Slip λ of the current state.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Friction coefficient mu(λ) used at the end of the last step (0 before any step).
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// Tyre force F_x = mu N at the end of the last step, N (0 before any step).
    pub fn fx(&self) -> f64 {
        self.fx
    }

    /// Whether the last step's command was cut below its value by the power
    /// limit ([`VehicleParams::power_max`]; never without one): what an
    /// inverter reports as derating (plant-sim's `MotorStatus.Derating`).
    pub fn derating(&self) -> bool {
        self.derating
    }

    /// Slip for a given (ω, V).
    #[inline]
    pub fn slip_of(&self, omega: f64, v: f64) -> f64 {
        let u = self.params.r * omega;
        (u - v) / u.abs().max(v.abs()).max(self.params.v_eps)
    }

    /// Advance by `dt` seconds (normally the controller period) with motor
    /// command `torque_cmd` (N m, clamped to ±[`VehicleParams::torque_limit`]
    /// at the wheel speed the call starts from: ±torque_max, less above the
    /// base speed of a drive with a power limit; NaN is treated as 0)
    /// on `road` at grade `grade_rad` (rad, positive uphill; non-finite is
    /// treated as 0, clamped to ±π/2). `dt` that is not finite and > 0 leaves
    /// the plant unchanged. Allocation-free.
    pub fn step(&mut self, dt: f64, torque_cmd: f64, road: &Road, grade_rad: f64) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let p = self.params;
        let limit = p.torque_limit(self.state.omega);
        let cmd = if torque_cmd.is_nan() {
            0.0
        } else {
            torque_cmd.clamp(-limit, limit)
        };
        self.derating = limit < p.torque_max && torque_cmd.abs() > limit;
        let theta = if grade_rad.is_finite() {
            grade_rad.clamp(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2)
        } else {
            0.0
        };
        let (sin_t, cos_t) = theta.sin_cos();
        let weight = p.mass * crate::G;
        let env = Env {
            road,
            n_force: p.driven_load_share * weight * cos_t / p.n_driven,
            f_roll: p.c_rr * weight * cos_t,
            f_grade: weight * sin_t,
            k_aero: 0.5 * p.rho * p.c_d_a,
        };

        let n = ((dt / self.max_substep).ceil() as usize).clamp(1, MAX_SUBSTEPS_PER_CALL);
        let h = dt / n as f64;
        // Exact first-order lag over one sub-step: end value and mean value.
        let (decay, mean_frac) = if p.tau_m > 0.0 {
            let a = (-h / p.tau_m).exp();
            (a, (p.tau_m / h) * (1.0 - a))
        } else {
            (0.0, 0.0)
        };
        for _ in 0..n {
            let t0 = self.state.torque;
            let t_mean = cmd + (t0 - cmd) * mean_frac;
            self.substep(&env, h, t_mean);
            self.state.torque = cmd + (t0 - cmd) * decay;
        }
        let lam = self.slip_of(self.state.omega, self.state.v);
        self.lambda = lam;
        self.mu = road.mu(lam);
        self.fx = self.mu * env.n_force;
    }

    /// One linearly implicit Euler sub-step of (ω, V, x) with mean motor torque `t`.
    #[inline]
    fn substep(&mut self, env: &Env<'_>, h: f64, t: f64) {
        let p = &self.params;
        let (omega, v) = (self.state.omega, self.state.v);
        let r = p.r;
        let m_s = p.mass / p.n_driven;
        let u = r * omega;
        let (au, av) = (u.abs(), v.abs());
        // Slip and its partial derivatives with respect to u = r ω and V.
        let (lam, dl_du, dl_dv) = if au >= av && au >= p.v_eps {
            ((u - v) / au, v * u.signum() / (u * u), -1.0 / au)
        } else if av >= p.v_eps {
            ((u - v) / av, 1.0 / av, -u * v.signum() / (v * v))
        } else {
            ((u - v) / p.v_eps, 1.0 / p.v_eps, -1.0 / p.v_eps)
        };
        let mu = env.road.mu(lam);
        let dmu = env.road.dmu_dlambda(lam);
        let nf = env.n_force;
        let fx = mu * nf;

        let reg = av.max(V_ROLL_REG);
        let f_res = env.f_roll * v / reg + env.k_aero * v * av + env.f_grade;
        let df_res = if av < V_ROLL_REG {
            env.f_roll / V_ROLL_REG
        } else {
            0.0
        } + 2.0 * env.k_aero * av;

        let f_w = (t - r * fx) / p.j_w;
        let f_v = (fx - f_res / p.n_driven) / m_s;
        let dfx_dw = nf * dmu * dl_du * r;
        let dfx_dv = nf * dmu * dl_dv;
        let j11 = -r * dfx_dw / p.j_w;
        let j12 = -r * dfx_dv / p.j_w;
        let j21 = dfx_dw / m_s;
        let j22 = (dfx_dv - df_res / p.n_driven) / m_s;

        let a11 = 1.0 - h * j11;
        let a12 = -h * j12;
        let a21 = -h * j21;
        let a22 = 1.0 - h * j22;
        let det = a11 * a22 - a12 * a21;
        let (dw, dv) = if det.is_finite() && det.abs() > 1e-12 {
            (
                h * (f_w * a22 - a12 * f_v) / det,
                h * (a11 * f_v - a21 * f_w) / det,
            )
        } else {
            (h * f_w, h * f_v)
        };
        let v_new = v + dv;
        self.state.omega = omega + dw;
        self.state.v = v_new;
        self.state.x += 0.5 * h * (v + v_new);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn asphalt() -> Road {
        Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap()
    }
    fn snow() -> Road {
        Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap()
    }

    /// Run `secs` of constant command `cmd` in 1 ms calls with sub-step `h`.
    fn run(h: f64, road: &Road, start: PlantState, cmd: f64, secs: f64, grade: f64) -> PlantState {
        let mut p = Plant::new(VehicleParams::default(), start).unwrap();
        p.set_max_substep(h).unwrap();
        let steps = (secs / 1e-3).round() as usize;
        for _ in 0..steps {
            p.step(1e-3, cmd, road, grade);
        }
        *p.state()
    }

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-9)
    }

    /// Halving the sub-step changes final ω, V, x by well under 1 %.
    fn assert_converged(road: &Road, start: PlantState, cmd: f64, secs: f64, what: &str) {
        let a = run(DEFAULT_MAX_SUBSTEP, road, start, cmd, secs, 0.0);
        let b = run(DEFAULT_MAX_SUBSTEP / 2.0, road, start, cmd, secs, 0.0);
        for (name, x, y) in [
            ("omega", a.omega, b.omega),
            ("v", a.v, b.v),
            ("x", a.x, b.x),
        ] {
            let e = rel(x, y);
            eprintln!(
                "{what}: {name} h={DEFAULT_MAX_SUBSTEP:e}: {x:.6}, h/2: {y:.6}, relative change {e:.2e}"
            );
            assert!(
                e < 1e-3,
                "{what}: {name} changes by {:.3e} relative ({x} vs {y})",
                e
            );
        }
    }

    #[test]
    fn converges_spinning_up_on_snow() {
        let p = VehicleParams::default();
        assert_converged(
            &snow(),
            PlantState::rolling(10.0 / 3.6, p.r),
            300.0,
            1.0,
            "snow",
        );
    }

    #[test]
    fn converges_on_asphalt() {
        let p = VehicleParams::default();
        assert_converged(
            &asphalt(),
            PlantState::rolling(10.0 / 3.6, p.r),
            300.0,
            2.0,
            "asphalt",
        );
    }

    #[test]
    fn converges_from_standstill() {
        assert_converged(
            &asphalt(),
            PlantState::standstill(),
            300.0,
            1.0,
            "standstill asphalt",
        );
        assert_converged(
            &snow(),
            PlantState::standstill(),
            300.0,
            1.0,
            "standstill snow",
        );
    }

    #[test]
    fn snow_spins_asphalt_grips() {
        let p = VehicleParams::default();
        let s0 = PlantState::rolling(10.0 / 3.6, p.r);
        // 300 N m exceeds what snow carries (0.19 N r = 183 N m): the wheel runs away.
        let s = run(DEFAULT_MAX_SUBSTEP, &snow(), s0, 300.0, 1.0, 0.0);
        let mut plant = Plant::new(p, s).unwrap();
        plant.step(1e-3, 300.0, &snow(), 0.0);
        assert!(plant.lambda() > 0.5, "snow slip {}", plant.lambda());
        // On asphalt 300 N m is carried at small slip.
        let a = run(DEFAULT_MAX_SUBSTEP, &asphalt(), s0, 300.0, 1.0, 0.0);
        let mut plant = Plant::new(p, a).unwrap();
        plant.step(1e-3, 300.0, &asphalt(), 0.0);
        assert!(
            plant.lambda() > 0.0 && plant.lambda() < 0.05,
            "asphalt slip {}",
            plant.lambda()
        );
        // Acceleration close to (T/r - resistance)/(M/n + J_w/r^2) after the lag.
        assert!(a.v > s0.v + 0.5);
    }

    #[test]
    fn motor_lag_is_first_order() {
        let p = VehicleParams::default();
        let mut plant = Plant::new(p, PlantState::rolling(5.0, p.r)).unwrap();
        for _ in 0..50 {
            plant.step(1e-3, 200.0, &asphalt(), 0.0);
        }
        // One time constant: 1 - 1/e of the command.
        let expect = 200.0 * (1.0 - (-1.0f64).exp());
        assert!(
            (plant.state().torque - expect).abs() < 1e-9,
            "{}",
            plant.state().torque
        );
    }

    #[test]
    fn torque_is_clamped() {
        let p = VehicleParams::default();
        let mut plant = Plant::new(p, PlantState::standstill()).unwrap();
        for _ in 0..2000 {
            plant.step(1e-3, 1e9, &asphalt(), 0.0);
        }
        assert!(plant.state().torque <= p.torque_max);
        assert!((plant.state().torque - p.torque_max).abs() < 1e-3);
    }

    /// With a power limit the drive gives torque_max to its base speed and
    /// power_max / ω above it (says so as derating); without one it never
    /// derates.
    #[test]
    fn a_power_limit_cuts_the_torque_above_the_base_speed() {
        let power = 30_000.0;
        let p = VehicleParams {
            power_max: Some(power),
            ..VehicleParams::default()
        };
        assert_eq!(p.torque_limit(10.0), p.torque_max);
        assert_eq!(p.torque_limit(-60.0), power / 60.0);
        assert_eq!(p.torque_limit(f64::NAN), p.torque_max);
        // 300 N m: base speed 100 rad/s = 28 m/s on r = 0.28 m
        let mut limited = Plant::new(p, PlantState::rolling(20.0, p.r)).unwrap();
        let free_p = VehicleParams::default();
        let mut free = Plant::new(free_p, PlantState::rolling(20.0, p.r)).unwrap();
        let mut derated_at = None;
        for k in 0..20_000 {
            limited.step(1e-3, 300.0, &asphalt(), 0.0);
            free.step(1e-3, 300.0, &asphalt(), 0.0);
            if derated_at.is_none() && limited.derating() {
                derated_at = Some(k);
                let omega = limited.state().omega;
                assert!(
                    omega * 300.0 > power * 0.999,
                    "derating at ω = {omega} rad/s, below the base speed {}",
                    power / 300.0
                );
            }
            assert!(!free.derating());
            let s = limited.state();
            // the motor's torque follows the falling limit through its lag
            assert!(
                s.torque <= p.torque_limit(s.omega) * 1.02 + 1e-9,
                "T {} above the limit {} at ω {}",
                s.torque,
                p.torque_limit(s.omega),
                s.omega
            );
        }
        assert!(derated_at.is_some(), "never reached the base speed");
        let (l, f) = (limited.state(), free.state());
        assert!(
            l.v < f.v - 5.0,
            "the power limit should cost top speed: {} vs {} m/s",
            l.v,
            f.v
        );
        // settled above the base speed: the wheel's power is the limit
        assert!(
            (l.torque * l.omega - power).abs() < 0.01 * power,
            "P = {} W",
            l.torque * l.omega
        );
    }
    #[test]
    fn standstill_stays_put_and_resistance_never_reverses() {
        let p = VehicleParams::default();
        let mut plant = Plant::new(p, PlantState::standstill()).unwrap();
        for _ in 0..5000 {
            plant.step(1e-3, 0.0, &asphalt(), 0.0);
        }
        assert_eq!(*plant.state(), PlantState::standstill());
        // Coasting down from 2 m/s on the flat: stops, never goes negative.
        let mut plant = Plant::new(p, PlantState::rolling(2.0, p.r)).unwrap();
        let mut min_v = f64::INFINITY;
        for _ in 0..200_000 {
            plant.step(1e-3, 0.0, &asphalt(), 0.0);
            min_v = min_v.min(plant.state().v);
        }
        assert!(min_v > -1e-9, "went backwards: {min_v}");
        assert!(plant.state().v < 0.02, "did not stop: {}", plant.state().v);
    }

    #[test]
    fn no_nan_at_standstill_with_tiny_torques_and_zero_dt() {
        let p = VehicleParams::default();
        let mut plant = Plant::new(p, PlantState::standstill()).unwrap();
        for cmd in [
            1e-12,
            -1e-12,
            0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
        ] {
            for _ in 0..100 {
                plant.step(1e-3, cmd, &snow(), 0.0);
                plant.step(0.0, cmd, &snow(), 0.0);
                plant.step(f64::NAN, cmd, &snow(), f64::NAN);
            }
            let s = plant.state();
            assert!(
                s.omega.is_finite() && s.v.is_finite() && s.torque.is_finite() && s.x.is_finite()
            );
            assert!(plant.lambda().is_finite() && plant.mu().is_finite() && plant.fx().is_finite());
        }
    }

    #[test]
    fn uphill_without_torque_rolls_back_flat_does_not() {
        let grade = (0.10f64).atan(); // 10 %
        let s = run(
            DEFAULT_MAX_SUBSTEP,
            &asphalt(),
            PlantState::standstill(),
            0.0,
            1.0,
            grade,
        );
        assert!(s.v < -0.5, "10 % grade, no torque: v = {}", s.v);
        // Enough torque holds it: M g sin θ r / n ≈ 95 N m plus rolling resistance.
        let s = run(
            DEFAULT_MAX_SUBSTEP,
            &asphalt(),
            PlantState::standstill(),
            200.0,
            1.0,
            grade,
        );
        assert!(s.v > 0.0);
    }

    #[test]
    fn invalid_construction_is_an_error() {
        let p = VehicleParams {
            mass: -1.0,
            ..Default::default()
        };
        assert_eq!(
            Plant::new(p, PlantState::standstill()).unwrap_err().field,
            "mass"
        );
        let s = PlantState {
            omega: f64::NAN,
            ..Default::default()
        };
        assert_eq!(
            Plant::new(VehicleParams::default(), s).unwrap_err().field,
            "omega"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn finite_for_any_finite_input(omega in -200.0f64..200.0, v in -40.0f64..40.0, t in -2000.0f64..2000.0,
                                       cmd in -1e6f64..1e6, dt in 1e-6f64..0.05, grade in -1.5f64..1.5, road_i in 0usize..2) {
            let road = if road_i == 0 { asphalt() } else { snow() };
            let mut plant = Plant::new(VehicleParams::default(), PlantState { omega, v, torque: t, x: 0.0 }).unwrap();
            for _ in 0..20 {
                plant.step(dt, cmd, &road, grade);
            }
            let s = plant.state();
            prop_assert!(s.omega.is_finite() && s.v.is_finite() && s.torque.is_finite() && s.x.is_finite());
            prop_assert!(plant.lambda().abs() <= 2.0 + 1e-9);
        }
    }
}
