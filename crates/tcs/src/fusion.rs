//! Road belief: the acoustic estimate fused with what the wheel measures.
//!
//! Acoustics and slip fail in different places. Acoustics says nothing until
//! a frame is decided, and nothing right for a surface it was never trained
//! on (ice). Slip evidence is weak while the wheel transmits little (at small
//! slip the μ-λ curves differ only in their initial slope, which sensor noise
//! blurs), but a friction drop shows in the wheel within a few cycles. The
//! belief over the catalogue's roads is
//!
//! ```text
//!   b(r) ∝ p_ac(r) · exp(S(r))
//! ```
//!
//! - `p_ac`: the acoustic posterior of the road under the wheel: the decided
//!   road gets its (capped) confidence c, every other road (1 − c)/(K − 1);
//!   uniform before any decision.
//! - `S(r)`: slip evidence, a leaky sum (time constant `tau_forget_s`) of
//!   `−weight · (μ̂ − μ_r(λ))² / (2 σ_r²)` per cycle, with μ̂ from the
//!   wheel's torque balance (a first-order driving-force observer,
//!   μ̂ = (T − J_w dω/dt)/(N r)), λ measured from ω and V with the
//!   plant's definition, (rω − V) / max(|rω|, |V|, v_eps) (also rolling
//!   back, V < 0, where the curves, odd in λ, hold as they do forward), and
//!   σ_r² = σ_μ² + (μ_r'(λ) σ_λ)² (a steep curve is blurred by slip noise).
//!   Only cycles with a chassis speed and a finite μ̂ count.
//!
//! A wheel that spins on a road the microphone took for snow drives S(ice)
//! far above S(snow) within tens of cycles, so slip evidence overrides an
//! acoustic estimate that the wheel contradicts; where the wheel says
//! nothing (small slip, all curves alike) the acoustic posterior decides.
//! The most probable road and its probability are what the controller is
//! given. Allocation-free after construction.

use grip_physics::{RoadCatalogue, VehicleParams};

use crate::filters::LowPass;
use crate::observer::DrivingForceObserver;
use crate::types::Measurement;

/// Roads the belief can hold (catalogue size limit).
pub const MAX_BELIEF_ROADS: usize = 16;

/// Parameters of [`RoadBelief`] (`[fusion]` of `controllers.toml`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FusionParams {
    /// Observer filter time constant, s.
    pub tau_obs_s: f64,
    /// Forgetting time constant of the slip evidence, s.
    pub tau_forget_s: f64,
    /// Weight of one cycle's log-likelihood (cycles are correlated through
    /// the observer's filter, so less than 1).
    pub weight: f64,
    /// Friction noise σ_μ.
    pub sigma_mu: f64,
    /// Slip noise σ_λ.
    pub sigma_lambda: f64,
    /// Largest confidence taken from one acoustic decision (an overconfident
    /// classifier cannot outvote the wheel).
    pub max_acoustic_confidence: f64,
    /// Largest lead of the best road's slip evidence over another's, nats:
    /// evidence gathered on one road must not outlast the change to the
    /// next by more than `tau_forget_s · ln(max_evidence / prior ratio)`.
    pub max_evidence: f64,
    /// Slip below which a cycle adds no full evidence (none below half of
    /// it, linear in between): at small slip every curve
    /// fits nearly any friction a noisy, jittery μ̂ shows, and a cap from
    /// such evidence would hold the wheel where it can show nothing else.
    pub min_slip_evidence: f64,
    /// Time constant of a first-order low-pass on the measured slip before
    /// it is compared with the curves, s (0: the raw slip). μ̂ comes
    /// through the observer's filter (`tau_obs_s`); a raw λ beside it is
    /// compared at another moment and with all its noise, which at launch
    /// speeds (σ_λ about 0.009 at 10 km/h with this car's sensors) throws
    /// single cycles far up the curves, where only the flattest (ice) still
    /// fits. Absent from a file: 0 (the belief before this field existed,
    /// so that older drive logs still replay).
    #[serde(default)]
    pub tau_slip_s: f64,
    /// Speed below which a cycle adds no evidence, m/s: the slip's
    /// denominator, the faster of the wheel's rim speed and the car's, must
    /// reach it (none below, full from twice it, linear in between). The
    /// slip's noise grows as one over that speed (at 0.2 m/s, pulling away,
    /// the speed sensors' few cm/s are tens of per cent of slip), and
    /// where a noisy slip lands only ice's flat curve fits; a wheel that
    /// spins is fast and still counts. Absent from a file: 0 (no such
    /// gate; older drive logs replay as recorded).
    #[serde(default)]
    pub min_speed_evidence: f64,
}

impl Default for FusionParams {
    fn default() -> Self {
        Self {
            tau_obs_s: 0.01,
            tau_forget_s: 0.05,
            weight: 0.2,
            sigma_mu: 0.05,
            sigma_lambda: 0.004,
            max_acoustic_confidence: 0.97,
            max_evidence: 10.0,
            min_slip_evidence: 0.02,
            tau_slip_s: 0.002,
            min_speed_evidence: 1.2,
        }
    }
}

impl FusionParams {
    /// How much of one cycle's slip evidence counts, in [0, 1]: the product
    /// of three gates, each a linear ramp (a step would make the closed
    /// loop's result jump with it). Non-finite `lambda` or `speed` give NaN,
    /// which the caller treats as no evidence.
    ///
    /// - **Demand.** A wheel the driver asks nothing of rolls freely: at
    ///   λ ≈ 0 every curve passes through μ = 0, so its slip "evidence" is
    ///   sensor noise (measured in a live drive: 1 s of rolling at 0 N m
    ///   before the pedal took the belief to ice at 0.98, and the ice cap
    ///   then held the wheel on asphalt where it could show nothing else).
    ///   None without a demand; what there is fades.
    /// - **Slip floor.** None below half of `min_slip_evidence`, full from
    ///   it: every curve fits a small slip, where a jittery μ̂ must not
    ///   decide the road.
    /// - **Speed.** None while the slip's denominator, `speed` (the faster
    ///   of rim speed and car speed, m/s), is under `min_speed_evidence`,
    ///   full from twice it: pulling away from rest the slip is mostly
    ///   sensor noise.
    pub fn evidence_weight(&self, demanded: bool, lambda: f64, speed: f64) -> f64 {
        if !demanded {
            return 0.0;
        }
        let floor = self.min_slip_evidence;
        let slip = if floor > 0.0 {
            ((lambda.abs() - 0.5 * floor) / (0.5 * floor)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let v_min = self.min_speed_evidence;
        if v_min > 0.0 {
            slip * ((speed - v_min) / v_min).clamp(0.0, 1.0)
        } else {
            slip
        }
    }

    /// Ranges (NaN fails); `max_evidence` > 0, `min_slip_evidence` in [0, 1].
    pub fn validate(&self) -> Result<(), grip_physics::InvalidField> {
        use crate::params::{in_range, positive};
        positive("tau_obs_s", self.tau_obs_s)?;
        positive("tau_forget_s", self.tau_forget_s)?;
        in_range("weight", self.weight, 0.0, 10.0)?;
        positive("sigma_mu", self.sigma_mu)?;
        in_range("sigma_lambda", self.sigma_lambda, 0.0, 1.0)?;
        in_range("tau_slip_s", self.tau_slip_s, 0.0, 10.0)?;
        in_range("min_speed_evidence", self.min_speed_evidence, 0.0, 100.0)?;
        in_range(
            "max_acoustic_confidence",
            self.max_acoustic_confidence,
            0.0,
            1.0,
        )?;
        // 0 or less would switch the slip evidence off (every road's lead
        // clipped to nothing), NaN would remove the limit.
        positive("max_evidence", self.max_evidence)?;
        // Below 0 there is no slip floor (the "ice trap" of small slip
        // returns); a slip share above 1 cannot occur.
        in_range("min_slip_evidence", self.min_slip_evidence, 0.0, 1.0)?;
        Ok(())
    }
}

/// The slip the belief measures and its denominator, m/s: the plant's
/// slip (rω − V) / max(|rω|, |V|, v_eps) of a wheel of radius `r` at `omega`
/// (rad/s) on a car at `v` (m/s), and max(|rω|, |V|). The magnitudes, so
/// that a car rolling back (V < 0) under a forward demand has the slip its
/// tyre has: over the signed max(rω, V, v_eps) the denominator fell to
/// v_eps there and the slip and its noise grew 10-30 times (the belief went
/// to ice and the spin cut held a hill start at 19-48 N m). Also what
/// [`crate::analysis::sensors`] puts the vehicle's sensors through.
pub fn measured_slip(r: f64, v_eps: f64, omega: f64, v: f64) -> (f64, f64) {
    let rw = r * omega;
    let speed = rw.abs().max(v.abs());
    ((rw - v) / speed.max(v_eps), speed)
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct RoadBelief {
    roads: RoadCatalogue,
    n: usize,
    p: FusionParams,
    observer: DrivingForceObserver,
    /// The slip compared with the curves (`tau_slip_s`; `None`: raw).
    slip_lp: Option<LowPass>,
    normal_force: f64,
    r: f64,
    v_eps: f64,
    decay: f64,
    evidence: [f64; MAX_BELIEF_ROADS],
    belief: [f64; MAX_BELIEF_ROADS],
    acoustic: Option<(usize, f64)>,
    mu_hat: f64,
    lambda: f64,
    warm_up: u32,
    cycles: u32,
    /// The last cycle had a driver demand.
    demanded: bool,
}

impl RoadBelief {
    /// A belief over `roads` (at most [`MAX_BELIEF_ROADS`]; more is an error
    /// naming `roads`) for `vehicle` at sample time `dt` (s).
    pub fn new(
        roads: &RoadCatalogue,
        vehicle: &VehicleParams,
        p: FusionParams,
        dt: f64,
    ) -> Result<Self, grip_physics::InvalidField> {
        p.validate()?;
        if roads.is_empty() || roads.len() > MAX_BELIEF_ROADS {
            return Err(grip_physics::InvalidField::new(
                "roads",
                format!(
                    "the road belief holds 1..={MAX_BELIEF_ROADS} roads (the catalogue has {})",
                    roads.len()
                ),
            ));
        }
        let n = roads.len();
        let mut b = Self {
            roads: roads.clone(),
            n,
            p,
            observer: DrivingForceObserver::new(vehicle, p.tau_obs_s, dt),
            slip_lp: (p.tau_slip_s > 0.0).then(|| LowPass::new(p.tau_slip_s, dt)),
            normal_force: vehicle.normal_force(),
            r: vehicle.r,
            v_eps: vehicle.v_eps,
            decay: (-dt / p.tau_forget_s).exp(),
            evidence: [0.0; MAX_BELIEF_ROADS],
            belief: [0.0; MAX_BELIEF_ROADS],
            acoustic: None,
            mu_hat: f64::NAN,
            lambda: f64::NAN,
            // The observer's filters start from zero: its μ̂ means nothing
            // for the first few time constants.
            warm_up: (3.0 * p.tau_obs_s / dt).ceil().clamp(1.0, 1e6) as u32,
            cycles: 0,
            demanded: false,
        };
        b.normalise();
        Ok(b)
    }

    /// Back to no knowledge (start of a drive).
    pub fn reset(&mut self) {
        self.observer.reset();
        if let Some(lp) = &mut self.slip_lp {
            lp.reset();
        }
        self.evidence = [0.0; MAX_BELIEF_ROADS];
        self.acoustic = None;
        self.mu_hat = f64::NAN;
        self.lambda = f64::NAN;
        self.cycles = 0;
        self.demanded = false;
        self.normalise();
    }

    /// The acoustic estimate of the road under the wheel now (`None`: none).
    pub fn set_acoustic(&mut self, road: Option<(usize, f64)>) {
        self.acoustic = road.filter(|&(i, c)| i < self.n && c.is_finite());
    }

    /// One cycle of slip evidence from the measurement. Allocation-free.
    pub fn step(&mut self, m: &Measurement) {
        let f = self.observer.step(m.torque, m.omega);
        let mu_hat = f / self.normal_force;
        self.mu_hat = mu_hat;
        for e in &mut self.evidence[..self.n] {
            *e *= self.decay;
        }
        let (lambda, speed) = match m.v {
            Some(v) if v.is_finite() && m.omega.is_finite() => {
                measured_slip(self.r, self.v_eps, m.omega, v)
            }
            _ => (f64::NAN, f64::NAN),
        };
        self.lambda = lambda;
        // The slip the curves are asked about: through the same kind of
        // filter as μ̂ (a non-finite slip leaves the filter as it was).
        let lambda = match &mut self.slip_lp {
            Some(lp) if lambda.is_finite() => lp.step(lambda),
            _ => lambda,
        };
        // The pedal after none: the torque builds from 0 through the motor
        // lag, as at the start of a drive, so the start's warm-up applies
        // again (without it, the first cycles of the ramp, at next to no
        // torque, are slip noise: in live drives they put the belief on ice
        // within 10 ms in about one start in three).
        let demanded = m.demand > 0.0;
        if demanded && !self.demanded {
            self.cycles = 0;
        }
        self.demanded = demanded;
        self.cycles = self.cycles.saturating_add(1);
        let excite = self.p.evidence_weight(demanded, lambda, speed);
        if self.cycles > self.warm_up && lambda.is_finite() && excite > 0.0 && mu_hat.is_finite() {
            let s2l = self.p.sigma_lambda * self.p.sigma_lambda;
            let s2m = self.p.sigma_mu * self.p.sigma_mu;
            for (i, road) in self.roads.iter().enumerate().take(self.n) {
                let mu = road.mu(lambda);
                let slope = road.dmu_dlambda(lambda);
                let s2 = s2m + slope * slope * s2l;
                let d = mu_hat - mu;
                // The squared, noise-scaled misfit only: a curve's own
                // noise level (its −½ ln σ² term) would, summed over
                // thousands of correlated cycles that say nothing, pull the
                // belief towards the flattest curves.
                let ll = -0.5 * d * d / s2;
                if ll.is_finite() {
                    self.evidence[i] += excite * self.p.weight * ll;
                }
            }
            let best = self.evidence[..self.n]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            for e in &mut self.evidence[..self.n] {
                *e = (*e - best).max(-self.p.max_evidence);
            }
        }
        self.normalise();
    }

    fn normalise(&mut self) {
        let n = self.n;
        let (ac_road, ac_conf) = match self.acoustic {
            Some((i, c)) => (Some(i), c.clamp(0.0, self.p.max_acoustic_confidence)),
            None => (None, 0.0),
        };
        let other = if n > 1 {
            (1.0 - ac_conf) / (n - 1) as f64
        } else {
            1.0
        };
        let mut max = f64::NEG_INFINITY;
        for i in 0..n {
            let prior = match ac_road {
                Some(a) if a == i => ac_conf.max(other),
                Some(_) => other,
                None => 1.0 / n as f64,
            };
            let l = prior.max(1e-12).ln() + self.evidence[i];
            self.belief[i] = l;
            max = max.max(l);
        }
        let mut sum = 0.0;
        for b in &mut self.belief[..n] {
            *b = (*b - max).exp();
            sum += *b;
        }
        for b in &mut self.belief[..n] {
            *b /= sum;
        }
    }

    /// μ of catalogue road `road` at slip `lambda` (its curve), NaN for
    /// an index outside the belief.
    pub fn mu_of(&self, road: usize, lambda: f64) -> f64 {
        if road < self.n {
            self.roads[road].mu(lambda)
        } else {
            f64::NAN
        }
    }

    /// Probability of each road (catalogue order).
    pub fn probabilities(&self) -> &[f64] {
        &self.belief[..self.n]
    }

    /// The most probable road and its probability.
    pub fn best(&self) -> (usize, f64) {
        let mut best = (0, f64::NEG_INFINITY);
        for (i, &b) in self.belief[..self.n].iter().enumerate() {
            if b > best.1 {
                best = (i, b);
            }
        }
        best
    }

    /// The latest μ̂ (observer) and measured λ (NaN without a speed).
    pub fn measured(&self) -> (f64, f64) {
        (self.mu_hat, self.lambda)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_physics::Road;

    #[test]
    fn evidence_weight_is_the_product_of_its_three_ramps() {
        let p = FusionParams::default(); // slip floor 0.02, speed 1.2 m/s
        let w = |d, l, v| p.evidence_weight(d, l, v);
        // Full: a demand, slip at the floor, speed at twice the minimum.
        assert_eq!(w(true, 0.02, 2.4), 1.0);
        assert_eq!(w(true, -0.05, 10.0), 1.0);
        // Each gate alone closes it.
        assert_eq!(w(false, 0.05, 10.0), 0.0);
        assert_eq!(w(true, 0.01, 10.0), 0.0);
        assert_eq!(w(true, 0.05, 1.2), 0.0);
        // Half-way up each ramp, and both at once multiply.
        assert!((w(true, 0.015, 10.0) - 0.5).abs() < 1e-12);
        assert!((w(true, 0.05, 1.8) - 0.5).abs() < 1e-12);
        assert!((w(true, 0.015, 1.8) - 0.25).abs() < 1e-12);
        // Non-finite input gives NaN, which the caller skips (no evidence).
        assert!(w(true, f64::NAN, 10.0).is_nan());
        assert!(w(true, 0.05, f64::NAN).is_nan());
        // Gates set to 0 are off: only the demand remains.
        let off = FusionParams {
            min_slip_evidence: 0.0,
            min_speed_evidence: 0.0,
            ..p
        };
        assert_eq!(off.evidence_weight(true, 0.0, 0.0), 1.0);
        assert_eq!(off.evidence_weight(false, 0.3, 5.0), 0.0);
    }

    fn roads() -> RoadCatalogue {
        RoadCatalogue::burckhardt(&["asphalt", "snow", "ice"]).unwrap()
    }

    /// Feed steady cycles at slip `lambda` with the torque a road with
    /// friction `mu` transmits (wheel not accelerating relative to the car).
    fn steady(b: &mut RoadBelief, lambda: f64, mu: f64, cycles: usize) {
        let v = VehicleParams::default();
        let speed = 5.0;
        let omega = speed / (1.0 - lambda) / v.r;
        let torque = mu * v.normal_force() * v.r;
        for _ in 0..cycles {
            b.step(&Measurement {
                t: 0.0,
                omega,
                v: Some(speed),
                torque,
                demand: 300.0,
            });
        }
    }

    fn belief() -> RoadBelief {
        belief_with(FusionParams::default())
    }

    /// A belief over [`roads`] with `p`, at 1 kHz.
    fn belief_with(p: FusionParams) -> RoadBelief {
        RoadBelief::new(&roads(), &VehicleParams::default(), p, 1e-3).unwrap()
    }

    /// [`belief`] comparing the raw slip with the curves (`tau_slip_s` 0):
    /// for the gates' tests, whose ±3 % cycle-to-cycle jitter the slip
    /// filter alone would already average away.
    fn belief_raw_slip() -> RoadBelief {
        belief_with(FusionParams {
            tau_slip_s: 0.0,
            ..FusionParams::default()
        })
    }

    #[test]
    fn no_evidence_is_the_acoustic_posterior() {
        let mut b = belief();
        let p = b.probabilities();
        assert!(p.iter().all(|&x| (x - 1.0 / 3.0).abs() < 1e-12));
        b.set_acoustic(Some((1, 0.8)));
        b.step(&Measurement {
            v: None,
            ..Default::default()
        });
        assert_eq!(b.best().0, 1);
        assert!((b.best().1 - 0.8).abs() < 1e-9);
    }

    #[test]
    fn a_spinning_wheel_overrides_a_confident_snow_estimate_on_ice() {
        let mut b = belief();
        b.set_acoustic(Some((1, 0.97)));
        // Ice at 30 % slip transmits 0.05; snow would give 0.175.
        let ice = Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap();
        // 30 cycles of observer warm-up, then 50 ms of spin.
        steady(&mut b, 0.3, ice.mu(0.3), 80);
        let (best, p) = b.best();
        assert_eq!(best, 2, "{:?}", b.probabilities());
        assert!(p > 0.9, "{:?}", b.probabilities());
    }

    #[test]
    fn traction_on_asphalt_rules_out_snow() {
        let mut b = belief();
        b.set_acoustic(Some((1, 0.9)));
        let asphalt = Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap();
        steady(&mut b, 0.03, asphalt.mu(0.03), 100);
        assert_eq!(b.best().0, 0, "{:?}", b.probabilities());
    }

    /// The wheel on stone at 10 km/h held at ice's limit (48 N m, as an ice
    /// cap holds it), so at about 0.6 % slip, the measured slip jittering
    /// by σ ≈ 0.009 (uniform ±0.0155, a fixed sequence; this car's sensors
    /// at that speed), 0.3 s with the slip filter of `tau_slip_s`: the
    /// probability of ice, its mean over the last 0.2 s and its largest.
    fn ice_on_stone_held_at_ice_s_limit(tau_slip_s: f64) -> (f64, f64) {
        let roads = RoadCatalogue::burckhardt(&["stone", "ice"]).unwrap();
        let p = FusionParams {
            tau_slip_s,
            ..FusionParams::default()
        };
        let v = VehicleParams::default();
        let mut b = RoadBelief::new(&roads, &v, p, 1e-3).unwrap();
        let stone = Road::burckhardt("stone", 1.3713, 6.4565, 0.6691).unwrap();
        let speed = 2.78;
        let torque = 0.05 * v.normal_force() * v.r;
        let lo = crate::road_aware::slip_at_share(
            |l| stone.mu(l),
            stone.lambda_opt(),
            stone.mu_peak(),
            0.05 / stone.mu_peak(),
        );
        assert!((0.005..0.008).contains(&lo), "stone carries 0.05 at {lo}");
        let mut seed: u64 = 12345;
        let (mut sum, mut max) = (0.0, 0.0_f64);
        for k in 0..300 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            let measured = lo + 0.0155 * u;
            b.step(&Measurement {
                t: 0.0,
                omega: speed / (1.0 - measured) / v.r,
                v: Some(speed),
                torque,
                demand: 200.0,
            });
            let ice = b.probabilities()[1];
            max = max.max(ice);
            if k >= 100 {
                sum += ice;
            }
        }
        (sum / 200.0, max)
    }

    #[test]
    fn slip_noise_does_not_hold_stone_at_ice_s_limit() {
        // Raw slip: the cycles the noise throws past the evidence floor
        // (2 % "slip" at μ̂ 0.05, which only ice's flat curve fits) keep the
        // belief on ice, and its cap keeps the wheel where it shows nothing
        // else (seen in `grip sim` at 200 N m with front-mic.toml: a launch
        // on stone held at 48 N m for 0.7 s).
        let (raw_mean, _) = ice_on_stone_held_at_ice_s_limit(0.0);
        assert!(raw_mean > 0.9, "raw slip: ice at {raw_mean}");
        // Filtered, few cycles reach the floor: ice stays near the prior's
        // half, under the belief's 0.6 gate on average.
        let tau = FusionParams::default().tau_slip_s;
        let (mean, max) = ice_on_stone_held_at_ice_s_limit(tau);
        assert!(mean < 0.6, "filtered slip: ice at {mean} on average");
        assert!(max < 0.7, "filtered slip: ice at up to {max}");
    }

    /// Pulling away from rest on asphalt at about 0.2 m/s with a little
    /// torque (μ̂ 0.05), the measured slip noisy by ±0.3 (a few cm/s of
    /// speed noise over a slip denominator of 0.2 m/s): the belief over
    /// asphalt, snow and ice after 0.3 s, with the speed gate
    /// `min_speed_evidence` (m/s).
    fn pulling_away(min_speed_evidence: f64, rim_speed: f64) -> (usize, f64) {
        let v = VehicleParams::default();
        let mut b = belief_with(FusionParams {
            min_speed_evidence,
            ..FusionParams::default()
        });
        let torque = 0.05 * v.normal_force() * v.r;
        for k in 0..300u32 {
            let jitter = if k.is_multiple_of(2) { 0.06 } else { -0.02 };
            b.step(&Measurement {
                t: f64::from(k) * 1e-3,
                omega: (rim_speed + jitter) / v.r,
                v: Some(0.2),
                torque,
                demand: 220.0,
            });
        }
        b.best()
    }

    #[test]
    fn pulling_away_from_rest_adds_no_evidence_but_a_spinning_wheel_does() {
        // Without the gate the noise, filtered or not, makes it ice.
        assert_eq!(pulling_away(0.0, 0.2).0, 2, "no gate: ice");
        // With it: under 1 m/s no evidence, the uniform prior stands.
        let (_, p) = pulling_away(1.0, 0.2);
        assert!((p - 1.0 / 3.0).abs() < 1e-9, "gate: {p}");
        // A wheel spinning at 3 m/s rim speed with the car at 0.2 m/s (slip
        // 0.93, a transmitted μ of 0.05): fast enough to count, and ice.
        assert_eq!(pulling_away(1.0, 3.0).0, 2, "a spinning wheel counts");
    }

    /// The car rolling back at 3 m/s (V = −3 m/s) on asphalt under a
    /// 400 N m forward demand (a hill start that rolled back), the wheel
    /// turning with it: rω = V plus the speed sensors' noise (uniform
    /// ±0.03 m/s, a fixed sequence), the motor at 400 N m; asphalt heard at
    /// 0.95. Each cycle: the believed road, and the cap it gives as a share
    /// of asphalt's (μ_peak of the believed road over asphalt's).
    fn rolling_back_under_a_forward_demand() -> Vec<(usize, f64)> {
        let v = VehicleParams::default();
        let mut b = belief();
        b.set_acoustic(Some((0, 0.95)));
        let roads = roads();
        let mut seed: u64 = 777;
        (0..1000u32)
            .map(|k| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
                b.step(&Measurement {
                    t: f64::from(k) * 1e-3,
                    omega: (-3.0 + 0.03 * u) / v.r,
                    v: Some(-3.0),
                    torque: 400.0,
                    demand: 400.0,
                });
                let best = b.best().0;
                (best, roads[best].mu_peak() / roads[0].mu_peak())
            })
            .collect()
    }

    #[test]
    fn a_car_rolling_back_under_a_forward_demand_keeps_asphalt() {
        // The slip is the plant's, (rω − V) / max(|rω|, |V|, v_eps): about
        // 1 % of noise at 3 m/s, under the evidence floor, so the acoustic
        // estimate stands. (Over max(rω, V, v_eps) the denominator was
        // v_eps = 0.1 m/s: 30 % "slip" of noise, and the belief went to a
        // road whose cap held a hill start at 19-48 N m.)
        for (k, (best, cap_share)) in rolling_back_under_a_forward_demand()
            .into_iter()
            .enumerate()
        {
            assert_eq!(best, 0, "cycle {k}: the belief left asphalt");
            assert!(
                cap_share >= 1.0,
                "cycle {k}: cap at {cap_share} of asphalt's"
            );
        }
        let mut b = belief();
        b.step(&Measurement {
            t: 0.0,
            omega: -2.7 / VehicleParams::default().r,
            v: Some(-3.0),
            torque: 400.0,
            demand: 400.0,
        });
        // The wheel 10 % slower backwards than the car: it pushes forward,
        // slip +0.1 as the plant has it.
        assert!((b.measured().1 - 0.1).abs() < 1e-12, "{:?}", b.measured());
    }

    #[test]
    fn small_slip_adds_no_evidence() {
        // 1 % slip with a friction only ice would give at that slip: below
        // the 2 % floor the wheel is not asked, the acoustic estimate stands.
        let mut b = belief();
        b.set_acoustic(Some((0, 0.9)));
        steady(&mut b, 0.01, 0.02, 200);
        assert_eq!(b.best().0, 0, "{:?}", b.probabilities());
        assert!((b.best().1 - 0.9).abs() < 1e-9);
    }

    /// A wheel rolling freely without a demand (0 N m) whose measured slip
    /// jitters by ±3 % (sensor noise at low speed): no evidence, the
    /// acoustic estimate stands; the same jitter with a demand is evidence
    /// (ice fits μ̂ = 0 at 3 % slip), which is what the demand gate stops.
    #[test]
    fn a_freely_rolling_wheel_without_demand_adds_no_evidence() {
        let v = VehicleParams::default();
        let run = |demand: f64| {
            let mut b = belief_raw_slip();
            b.set_acoustic(Some((0, 0.9)));
            for k in 0..1000u32 {
                let lambda = if k.is_multiple_of(2) { 0.03 } else { -0.03 };
                b.step(&Measurement {
                    t: k as f64 * 1e-3,
                    omega: 5.0 / (1.0 - lambda) / v.r,
                    v: Some(5.0),
                    torque: 0.0,
                    demand,
                });
            }
            b.best()
        };
        let (road, p) = run(0.0);
        assert_eq!(road, 0);
        assert!((p - 0.9).abs() < 1e-9, "{p}");
        assert_eq!(run(300.0).0, 2, "with a demand the jitter counts");
    }

    /// The pedal after a coast: for the start's warm-up (3 τ_obs = 30
    /// cycles) the jittering slip at next to no torque adds no evidence, as
    /// at the start of a drive; after it, it does.
    #[test]
    fn the_pedal_after_a_coast_waits_out_the_warm_up() {
        let v = VehicleParams::default();
        let mut b = belief_raw_slip();
        b.set_acoustic(Some((0, 0.9)));
        let mut k = 0u32;
        let mut cycle = |b: &mut RoadBelief, demand: f64| {
            let lambda = if k.is_multiple_of(2) { 0.03 } else { -0.03 };
            k += 1;
            b.step(&Measurement {
                t: f64::from(k) * 1e-3,
                omega: 5.0 / (1.0 - lambda) / v.r,
                v: Some(5.0),
                torque: 0.0,
                demand,
            });
        };
        for _ in 0..500 {
            cycle(&mut b, 0.0);
        }
        for _ in 0..30 {
            cycle(&mut b, 300.0);
        }
        assert_eq!(b.best().0, 0);
        assert!((b.best().1 - 0.9).abs() < 1e-9, "{:?}", b.probabilities());
        for _ in 0..30 {
            cycle(&mut b, 300.0);
        }
        assert_eq!(b.best().0, 2, "{:?}", b.probabilities());
    }

    #[test]
    fn evidence_fades_and_reset_forgets() {
        let mut b = belief();
        let ice = Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap();
        steady(&mut b, 0.3, ice.mu(0.3), 80);
        assert_eq!(b.best().0, 2);
        b.reset();
        assert!((b.best().1 - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn limits_that_would_switch_the_evidence_off_are_refused() {
        // max_evidence <= 0 clips every road's evidence to the same value
        // (no slip evidence at all), NaN removes the limit; a negative
        // min_slip_evidence removes the small-slip floor.
        let bad = [
            ("max_evidence", -1.0, "> 0"),
            ("max_evidence", 0.0, "> 0"),
            ("max_evidence", f64::NAN, "> 0"),
            ("max_evidence", f64::INFINITY, "> 0"),
            ("min_slip_evidence", -0.02, "[0, 1]"),
            ("min_slip_evidence", 1.5, "[0, 1]"),
            ("min_slip_evidence", f64::NAN, "[0, 1]"),
        ];
        for (field, v, want) in bad {
            let mut p = FusionParams::default();
            match field {
                "max_evidence" => p.max_evidence = v,
                _ => p.min_slip_evidence = v,
            }
            let e = p.validate().unwrap_err();
            assert_eq!(e.field, field, "{v}");
            assert!(e.reason.contains(want), "{field} = {v}: {}", e.reason);
            assert!(e.reason.contains(&format!("(got {v})")), "{}", e.reason);
            let e = RoadBelief::new(&roads(), &VehicleParams::default(), p, 1e-3).unwrap_err();
            assert_eq!(e.field, field);
            let c = crate::ControllersConfig {
                fusion: p,
                ..Default::default()
            };
            assert_eq!(c.validate().unwrap_err().field, format!("fusion.{field}"));
        }
        for (max_evidence, min_slip_evidence) in [(1e-3, 0.0), (1e6, 1.0)] {
            FusionParams {
                max_evidence,
                min_slip_evidence,
                ..FusionParams::default()
            }
            .validate()
            .unwrap();
        }
    }

    #[test]
    fn too_many_roads_is_an_error() {
        let many: Vec<Road> = (0..17)
            .map(|i| Road::burckhardt(&format!("r{i}"), 1.0, 20.0, 0.1).unwrap())
            .collect();
        let e = RoadBelief::new(
            &RoadCatalogue::new(many).unwrap(),
            &VehicleParams::default(),
            FusionParams::default(),
            1e-3,
        )
        .unwrap_err();
        assert_eq!(e.field, "roads");
    }
}
