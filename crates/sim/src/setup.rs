//! [`SimSetup`]: everything a run needs, validated once.

use grip_physics::{RoadCatalogue, Scenario, SensorParams, VehicleParams, plant};
use grip_tcs::{ControllersConfig, RoadKnowledge};

use crate::SimError;
use crate::estimator::{Estimate, KnowledgeConfig};

/// What ARTE's road table gives the controller for one catalogue road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadInfo {
    /// Optimal slip of the road's mu-lambda curve.
    pub lambda_opt: f64,
    /// Peak friction coefficient.
    pub mu_peak: f64,
    /// MTTE relaxation factor: configured, or 1 − λ_opt.
    pub alpha: f64,
}

/// Vehicle, sensors, roads, scenario, controller parameters and the
/// road-knowledge rule of a simulation; immutable once built, shared by all
/// runs (and threads) of a batch.
#[derive(Debug, Clone)]
pub struct SimSetup {
    vehicle: VehicleParams,
    sensors: SensorParams,
    roads: RoadCatalogue,
    scenario: Scenario,
    controllers: ControllersConfig,
    road_info: Vec<RoadInfo>,
    max_substep: f64,
    dt: f64,
    cycles: usize,
}

impl SimSetup {
    /// Validate and assemble. The controller period is
    /// `controllers.loop_.dt()`; the run has `round(duration / dt)` cycles.
    /// The plant's internal step is [`plant::DEFAULT_MAX_SUBSTEP`] until
    /// [`SimSetup::set_max_substep`].
    pub fn new(
        vehicle: VehicleParams,
        sensors: SensorParams,
        roads: RoadCatalogue,
        scenario: Scenario,
        controllers: ControllersConfig,
        knowledge: &KnowledgeConfig,
    ) -> Result<Self, SimError> {
        vehicle
            .validate()
            .map_err(|e| SimError::from_field("vehicle", e))?;
        sensors
            .validate()
            .map_err(|e| SimError::from_field("sensors", e))?;
        controllers
            .validate()
            .map_err(|e| SimError::from_field("controllers", e))?;
        knowledge.validate(&roads)?;
        for (i, s) in scenario.segments.iter().enumerate() {
            let ok = roads
                .by_index(s.road)
                .is_some_and(|r| r.name() == s.road_name);
            if !ok {
                return Err(SimError::invalid(
                    format!("scenario.segment[{i}].road"),
                    format!(
                        "road `{}` (index {}) is not in this catalogue (known: {})",
                        s.road_name,
                        s.road,
                        roads.names()
                    ),
                ));
            }
        }
        let dt = controllers.loop_.dt();
        let cycles_f = (scenario.duration / dt).round();
        if !(1.0..=1e9).contains(&cycles_f) {
            return Err(SimError::invalid(
                "scenario.duration",
                format!("gives {cycles_f} controller cycles at dt = {dt} s (need 1 ..= 1e9)"),
            ));
        }
        let road_info = roads
            .iter()
            .map(|r| {
                let lambda_opt = r.lambda_opt();
                RoadInfo {
                    lambda_opt,
                    mu_peak: r.mu_peak(),
                    alpha: knowledge
                        .alpha
                        .get(r.name())
                        .copied()
                        .unwrap_or(1.0 - lambda_opt),
                }
            })
            .collect();
        Ok(Self {
            vehicle,
            sensors,
            roads,
            scenario,
            controllers,
            road_info,
            max_substep: plant::DEFAULT_MAX_SUBSTEP,
            dt,
            cycles: cycles_f as usize,
        })
    }

    /// Set the plant's internal integration step bound (s, finite, > 0).
    pub fn set_max_substep(&mut self, h: f64) -> Result<(), SimError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(SimError::invalid(
                "max_substep",
                format!("must be a finite number > 0 s (got {h})"),
            ));
        }
        self.max_substep = h;
        Ok(())
    }

    /// The same setup with other sensor parameters (validated).
    pub fn with_sensors(mut self, sensors: SensorParams) -> Result<Self, SimError> {
        sensors
            .validate()
            .map_err(|e| SimError::from_field("sensors", e))?;
        self.sensors = sensors;
        Ok(self)
    }

    /// Vehicle parameters.
    pub fn vehicle(&self) -> &VehicleParams {
        &self.vehicle
    }
    /// Sensor parameters.
    pub fn sensors(&self) -> &SensorParams {
        &self.sensors
    }
    /// Road catalogue.
    pub fn roads(&self) -> &RoadCatalogue {
        &self.roads
    }
    /// Scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }
    /// Controller parameters.
    pub fn controllers(&self) -> &ControllersConfig {
        &self.controllers
    }
    /// Per catalogue road: λ_opt, mu_peak, α.
    pub fn road_info(&self) -> &[RoadInfo] {
        &self.road_info
    }
    /// Plant sub-step bound, s.
    pub fn max_substep(&self) -> f64 {
        self.max_substep
    }
    /// Controller period, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Controller cycles per run.
    pub fn cycles(&self) -> usize {
        self.cycles
    }
    /// Simulated time per run, s (cycles · dt).
    pub fn sim_time(&self) -> f64 {
        self.cycles as f64 * self.dt
    }

    /// The road knowledge an estimate gives at time `t`: the estimated road's
    /// λ_opt, mu_peak and α from the catalogue, the estimate's confidence, and
    /// age `t − t_stamp`. An index outside the catalogue gives NaN values,
    /// which the controllers' fallback rule rejects.
    pub fn knowledge(&self, est: &Estimate, t: f64) -> RoadKnowledge {
        let info = self
            .road_info
            .get(est.road_index)
            .copied()
            .unwrap_or(RoadInfo {
                lambda_opt: f64::NAN,
                mu_peak: f64::NAN,
                alpha: f64::NAN,
            });
        RoadKnowledge {
            lambda_opt: info.lambda_opt,
            mu_peak: info.mu_peak,
            alpha: info.alpha,
            confidence: est.confidence,
            age: t - est.t_stamp,
        }
    }
}
