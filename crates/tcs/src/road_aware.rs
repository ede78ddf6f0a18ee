//! Road knowledge ahead of and under the wheel, for the "with ARTE"
//! variants of all three controllers: the preview queue, the road belief,
//! and the torque they allow. The same code runs in `grip sim` and in the
//! live tcs-loop.
//!
//! Every cycle [`RoadAware::step`]:
//!
//! 1. looks up the road under the wheel and the next one ahead in the
//!    [`PreviewQueue`] at the loop's odometer (acoustic decisions are
//!    queued by [`RoadAware::decision`] at the place the microphone heard
//!    them, `mic_lead_m` ahead of the wheel);
//! 2. fuses the acoustic estimate of the road under the wheel with the
//!    wheel's slip evidence ([`RoadBelief`]) while the decision stream is
//!    alive (a decision within `[arte] max_age_s`);
//! 3. hands the controller the [`RoadKnowledge`] of the most probable road
//!    (its probability as the confidence, age 0: the belief is this
//!    cycle's), which the controller's own fallback rule accepts or not;
//! 4. and a torque cap: what the believed road transmits,
//!    `cap_share · μ_peak · N · r` (the μ-λ curves are flat near their peaks,
//!    so a cap below the peak holds the slip where μ reaches about that
//!    share of μ_peak: nearly all the traction at much less slip); while the
//!    measured slip is beyond `recover_slip_factor · λ_opt` (the wheel
//!    spins) `recover_share · μ_peak · N · r` so that it regains grip; and,
//!    when the next road ahead carries less and the wheel reaches it within
//!    `horizon_s` (enough for the motor's lag), that road's cap already.
//!    On a road that carries more, the cap is released when the wheel
//!    arrives (the queue places a grippier road at the latest point it can
//!    begin).
//!
//! The cap is applied as `T* = min(T*_controller, cap)`: the controllers
//! stay as they are and still react to slip themselves (a TCS that is
//! preconditioned, not replaced). The variants without ARTE never see this.

use grip_physics::{InvalidField, RoadCatalogue, VehicleParams};
use serde::Deserialize;

use crate::fusion::{FusionParams, RoadBelief};
use crate::knowledge::RoadTable;
use crate::params::{ArteUse, in_range, positive};
use crate::preview::{PreviewQueue, PreviewView};
use crate::types::{Measurement, RoadKnowledge};

/// `[preview]` of `controllers.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewParams {
    /// Torque cap on a believed road, share of its μ_peak · N · r, (0, 1.5].
    pub cap_share: f64,
    /// Cap while the wheel spins, share of μ_peak · N · r, (0, 1.5].
    pub recover_share: f64,
    /// The wheel spins when the measured slip exceeds this many λ_opt of
    /// the believed road, >= 1.
    pub recover_slip_factor: f64,
    /// A lower-friction road ahead caps the torque once the wheel will reach
    /// it within this time, s (>= 0; a few motor lags).
    pub horizon_s: f64,
}

impl Default for PreviewParams {
    fn default() -> Self {
        Self {
            cap_share: 0.95,
            recover_share: 0.7,
            recover_slip_factor: 1.5,
            horizon_s: 0.2,
        }
    }
}

impl PreviewParams {
    /// Ranges (NaN fails).
    pub fn validate(&self) -> Result<(), InvalidField> {
        in_range("cap_share", self.cap_share, 1e-3, 1.5)?;
        in_range("recover_share", self.recover_share, 1e-3, 1.5)?;
        in_range("recover_slip_factor", self.recover_slip_factor, 1.0, 100.0)?;
        in_range("horizon_s", self.horizon_s, 0.0, 10.0)?;
        Ok(())
    }
}

/// What [`RoadAware::step`] gives for one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guidance {
    /// The knowledge for the controller (the believed road).
    pub knowledge: Option<RoadKnowledge>,
    /// Catalogue index of the believed road and its probability.
    pub belief: (usize, f64),
    /// Torque the road allows, N m (`f64::INFINITY`: no cap).
    pub torque_cap: f64,
    /// The acoustic queue at the wheel: road under it and the next ahead
    /// with its distance, m.
    pub view: PreviewView,
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct RoadAware {
    table: RoadTable,
    belief: RoadBelief,
    queue: PreviewQueue,
    p: PreviewParams,
    arte: ArteUse,
    nr: f64,
    r: f64,
    lead: f64,
    last_decision: f64,
}

impl RoadAware {
    /// For `roads` (with their knowledge `table`), `vehicle` (its
    /// `mic_lead_m`, N and r), the controllers' `[arte]`, `[preview]` and
    /// `[fusion]`, at sample time `dt`. Errors name the field.
    pub fn new(
        roads: &RoadCatalogue,
        table: RoadTable,
        vehicle: &VehicleParams,
        arte: ArteUse,
        preview: PreviewParams,
        fusion: FusionParams,
        dt: f64,
    ) -> Result<Self, InvalidField> {
        preview.validate().map_err(|e| e.prefixed("preview"))?;
        positive("dt", dt)?;
        let belief =
            RoadBelief::new(roads, vehicle, fusion, dt).map_err(|e| e.prefixed("fusion"))?;
        Ok(Self {
            table,
            belief,
            queue: PreviewQueue::new(),
            p: preview,
            arte,
            nr: vehicle.normal_force() * vehicle.r,
            r: vehicle.r,
            lead: vehicle.mic_lead_m,
            last_decision: f64::NEG_INFINITY,
        })
    }

    /// Start of a drive.
    pub fn reset(&mut self) {
        self.belief.reset();
        self.queue.clear();
        self.last_decision = f64::NEG_INFINITY;
    }

    /// The microphone's lead, m.
    pub fn lead(&self) -> f64 {
        self.lead
    }

    /// An acoustic decision for catalogue road `road` with `confidence`,
    /// available at `stamp` (s), heard while the loop's odometer went from
    /// `x_from` to `x_to` (m; the lead is added here). Allocation-free.
    pub fn decision(&mut self, road: usize, confidence: f64, stamp: f64, x_from: f64, x_to: f64) {
        let new = self.table.info(road).mu_peak;
        let last = self
            .queue
            .entries()
            .last()
            .map_or(f64::INFINITY, |e| self.table.info(e.road).mu_peak);
        let carries_less = new < last || new.is_nan() || last.is_nan();
        self.queue.push(
            road,
            confidence,
            stamp,
            x_from + self.lead,
            x_to + self.lead,
            carries_less,
        );
        self.last_decision = stamp;
    }

    /// One cycle at time `m.t` and odometer `x` (m). Allocation-free.
    pub fn step(&mut self, m: &Measurement, x: f64) -> Guidance {
        let view = self.queue.view(x);
        let alive = m.t - self.last_decision <= self.arte.max_age_s;
        self.belief
            .set_acoustic(view.here.filter(|_| alive).map(|e| (e.road, e.confidence)));
        self.belief.step(m);
        let (road, prob) = self.belief.best();
        let info = self.table.info(road);
        let knowledge = info.knowledge(prob, 0.0);
        let usable = self.arte.usable(Some(&knowledge)).is_some();
        let mut cap = f64::INFINITY;
        if usable {
            let (_, lambda) = self.belief.measured();
            let spinning = lambda > self.p.recover_slip_factor * info.lambda_opt;
            let share = if spinning {
                self.p.recover_share
            } else {
                self.p.cap_share
            };
            cap = share * info.mu_peak * self.nr;
        }
        if alive && let Some((next, d)) = view.next {
            let v = m.v.unwrap_or(self.r * m.omega).max(0.1);
            let next_info = self.table.info(next.road);
            let lower = next_info.mu_peak < if usable { info.mu_peak } else { f64::INFINITY };
            if d / v <= self.p.horizon_s && lower && next.confidence >= self.arte.min_confidence {
                cap = cap.min(self.p.cap_share * next_info.mu_peak * self.nr);
            }
        }
        Guidance {
            knowledge: Some(knowledge),
            belief: (road, prob),
            torque_cap: cap,
            view,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::knowledge::KnowledgeConfig;
    use grip_physics::Road;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
        ])
        .unwrap()
    }

    fn aware(lead: f64) -> RoadAware {
        let roads = roads();
        let v = VehicleParams {
            mic_lead_m: lead,
            ..Default::default()
        };
        RoadAware::new(
            &roads,
            RoadTable::new(&roads, &KnowledgeConfig::default()).unwrap(),
            &v,
            ArteUse::default(),
            PreviewParams::default(),
            FusionParams::default(),
            1e-3,
        )
        .unwrap()
    }

    /// 5 m/s at 1 % slip with the torque `road` transmits there.
    fn cruise(t: f64, road: usize) -> Measurement {
        let lambda: f64 = 0.01;
        let mu = roads()[road].mu(lambda);
        Measurement {
            t,
            omega: 5.0 / (1.0 - lambda) / 0.28,
            v: Some(5.0),
            torque: mu * VehicleParams::default().normal_force() * 0.28,
            demand: 300.0,
        }
    }

    fn run(a: &mut RoadAware, t0: f64, x0: f64, road: usize, cycles: usize) -> Guidance {
        let mut g = None;
        for k in 0..cycles {
            let t = t0 + k as f64 * 1e-3;
            g = Some(a.step(&cruise(t, road), x0 + 5.0 * (t - t0)));
        }
        g.unwrap()
    }

    #[test]
    fn snow_ahead_caps_the_torque_before_the_wheel_arrives() {
        let mut a = aware(2.77);
        a.decision(0, 0.95, 0.0, -2.77, 0.5); // asphalt from the start
        a.decision(1, 0.95, 0.1, 0.5, 1.0); // snow from 0.5 + 2.77 m
        let snow_cap = 0.95 * 0.19 * 3433.5 * 0.28;
        // 0.1 s of cruising on asphalt up to x = 2.0 (1.27 m = 0.25 s ahead
        // at 5 m/s): not yet.
        let g = run(&mut a, 0.1, 1.5, 0, 100);
        assert_eq!(g.belief.0, 0, "{g:?}");
        assert_eq!(g.view.next.unwrap().0.road, 1);
        assert!(g.torque_cap > 500.0, "{g:?}");
        // At x = 2.4 (0.87 m = 0.17 s ahead): capped to what snow carries.
        let g = run(&mut a, 0.2, 2.0, 0, 81);
        assert!((g.torque_cap - snow_cap).abs() < 5.0, "{g:?}");
        // On the snow the belief follows the acoustic estimate.
        a.decision(1, 0.95, 0.3, 0.8, 1.3);
        let g = run(&mut a, 0.3, 3.3, 1, 150);
        assert_eq!(g.belief.0, 1, "{g:?}");
        assert!((g.torque_cap - snow_cap).abs() < 5.0, "{g:?}");
    }

    #[test]
    fn a_dead_decision_stream_gives_no_acoustic_knowledge() {
        let mut a = aware(0.0);
        a.decision(1, 0.95, 0.0, 0.0, 0.5);
        let g = run(&mut a, 0.01, 0.6, 1, 40);
        assert_eq!(g.belief.0, 1);
        assert!(g.torque_cap < 200.0, "{g:?}");
        // No decision for 5 s: the acoustic prior is gone; on a road that
        // neither curve rules out at 1 % slip the belief stays uncertain.
        let g = run(&mut a, 5.0, 25.0, 1, 1);
        assert!(g.belief.1 < 0.999, "{g:?}");
    }
}
