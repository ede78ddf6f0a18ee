//! [`SimSetup`]: everything a run needs, validated once.

use grip_physics::{RoadCatalogue, Scenario, SegmentMode, SensorParams, VehicleParams, plant};
use grip_tcs::{ControllersConfig, KnowledgeConfig, RoadTable};

use crate::SimError;

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
    road_table: RoadTable,
    max_substep: f64,
    dt: f64,
    cycles: usize,
}

/// Share of a scenario's total span (m or s) a run may go past its roads
/// before [`SimSetup::beyond_roads`] reports it.
pub const BEYOND_TOLERANCE: f64 = 0.05;

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
        validate(&vehicle, &sensors, &controllers)?;
        let road_table =
            RoadTable::new(&roads, knowledge).map_err(|e| SimError::from_field("knowledge", e))?;
        let cycles = check_scenario(&vehicle, &roads, &scenario, controllers.loop_.dt())?;
        let dt = controllers.loop_.dt();
        Ok(Self {
            vehicle,
            sensors,
            roads,
            scenario,
            controllers,
            road_table,
            max_substep: plant::DEFAULT_MAX_SUBSTEP,
            dt,
            cycles,
        })
    }

    /// The same setup with another scenario (checked as in [`SimSetup::new`]);
    /// `grip sim --scenario random` builds one per seed.
    pub fn with_scenario(&self, scenario: Scenario) -> Result<Self, SimError> {
        let cycles = check_scenario(&self.vehicle, &self.roads, &scenario, self.dt)?;
        Ok(Self {
            scenario,
            cycles,
            ..self.clone()
        })
    }

    /// The same setup with other controller parameters (validated; the
    /// loop rate may change, and the cycle count with it). `grip sim
    /// --sweep` builds one per point of its grid.
    pub fn with_controllers(&self, controllers: ControllersConfig) -> Result<Self, SimError> {
        validate(&self.vehicle, &self.sensors, &controllers)?;
        let dt = controllers.loop_.dt();
        let cycles = check_scenario(&self.vehicle, &self.roads, &self.scenario, dt)?;
        check_substep(self.max_substep, dt)?;
        Ok(Self {
            controllers,
            dt,
            cycles,
            ..self.clone()
        })
    }

    /// The same setup with another vehicle and sensors (validated; a
    /// microphone lead with a time-segment scenario is refused as in
    /// [`SimSetup::new`]). `grip sim --sweep vehicle.KEY=...` builds one per
    /// point.
    pub fn with_vehicle(
        &self,
        vehicle: VehicleParams,
        sensors: SensorParams,
    ) -> Result<Self, SimError> {
        validate(&vehicle, &sensors, &self.controllers)?;
        let cycles = check_scenario(&vehicle, &self.roads, &self.scenario, self.dt)?;
        Ok(Self {
            vehicle,
            sensors,
            cycles,
            ..self.clone()
        })
    }

    /// Set the plant's internal integration step bound (s, finite, > 0,
    /// and at least the controller period over
    /// [`plant::MAX_SUBSTEPS_PER_CALL`]: the plant takes no more sub-steps
    /// per cycle, so a smaller bound would not be honoured).
    pub fn set_max_substep(&mut self, h: f64) -> Result<(), SimError> {
        check_substep(h, self.dt)?;
        self.max_substep = h;
        Ok(())
    }

    /// How far the run whose final plant position is `final_x` (m) went
    /// beyond the scenario's roads, where the last road simply continues:
    /// in m past the sum of the segment lengths (distance segments), or in
    /// s past the sum of the segment durations (time segments); `None`
    /// when it stayed within them or went past them by no more than
    /// [`BEYOND_TOLERANCE`] of that sum (at least 1 m for distance
    /// segments): a scenario whose last road is meant to go on to the end
    /// (the reference scenario's "snow to the end", passed by up to 0.26 m
    /// of its 12.71 m) is not worth a warning; a random sequence that ran
    /// out of roads is.
    pub fn beyond_roads(&self, final_x: f64) -> Option<f64> {
        let span = self.scenario.total_span();
        let (past, tolerance) = match self.scenario.segments_by {
            SegmentMode::Distance => (final_x - span, (BEYOND_TOLERANCE * span).max(1.0)),
            // The last cycle starts at (cycles - 1) dt, on the road of that
            // instant.
            SegmentMode::Time => {
                let last = self.cycles.saturating_sub(1) as f64 * self.dt;
                (last - span, BEYOND_TOLERANCE * span)
            }
        };
        (past > tolerance).then_some(past)
    }

    /// The distance segments a run whose wheel got no farther than
    /// `farthest_x` (m, [`crate::RunResult::farthest_x`]) never reached:
    /// the indices (into the scenario's `segments`) of those that begin
    /// beyond it, in order. Empty for time segments (which of those a run
    /// drives is known before it: the scenario's loaders warn of those
    /// that begin at or after its end, `Scenario::past_the_end`), and for
    /// a `farthest_x` that is not a number.
    pub fn unreached(&self, farthest_x: f64) -> Vec<usize> {
        let sc = &self.scenario;
        if sc.segments_by != SegmentMode::Distance || farthest_x.is_nan() {
            return Vec::new();
        }
        (1..sc.segments.len())
            .filter(|&i| sc.segment_start(i) > farthest_x)
            .collect()
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
    /// The road-knowledge rule: per catalogue road λ_opt, μ_peak, α.
    pub fn road_table(&self) -> &RoadTable {
        &self.road_table
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
    /// Speed of the pre-roll, m/s: the scenario's initial speed, at least
    /// 1 m/s.
    pub fn pre_roll_speed(&self) -> f64 {
        self.scenario.v0.max(1.0)
    }
    /// Cycles of the pre-roll before each run of an ARTE variant (the
    /// microphone hearing the vehicle's `mic_lead_m` at
    /// [`pre_roll_speed`](Self::pre_roll_speed)); 0 without a lead.
    pub fn pre_roll_cycles(&self) -> usize {
        self.vehicle.pre_roll_cycles(self.pre_roll_speed(), self.dt) as usize
    }
    /// Cycles an estimator is stepped per run: the pre-roll and the run.
    pub fn estimator_cycles(&self) -> usize {
        self.pre_roll_cycles() + self.cycles
    }
}

/// Each part's own validation, its errors prefixed with its name.
fn validate(
    vehicle: &VehicleParams,
    sensors: &SensorParams,
    controllers: &ControllersConfig,
) -> Result<(), SimError> {
    vehicle
        .validate()
        .map_err(|e| SimError::from_field("vehicle", e))?;
    sensors
        .validate()
        .map_err(|e| SimError::from_field("sensors", e))?;
    controllers
        .validate()
        .map_err(|e| SimError::from_field("controllers", e))
}

/// Check `scenario` against the catalogue and the vehicle (road names, a
/// time-segment scenario with a microphone lead, the run length) and give
/// the number of controller cycles at period `dt`.
fn check_scenario(
    vehicle: &VehicleParams,
    roads: &RoadCatalogue,
    scenario: &Scenario,
    dt: f64,
) -> Result<usize, SimError> {
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
    // the microphone's lead against time segments, the demand within the
    // motor's limit and the run's cycle count: the one check every reader
    // of a scenario makes (plant-sim's start-up too)
    scenario
        .check_for(vehicle, dt)
        .map_err(|e| SimError::from_field("scenario", e))
}

/// A plant sub-step bound `h` the plant honours at controller period `dt`:
/// finite, > 0, and no more than [`plant::MAX_SUBSTEPS_PER_CALL`] sub-steps
/// per cycle (the plant's own count, `ceil(dt / h)`).
fn check_substep(h: f64, dt: f64) -> Result<(), SimError> {
    if !(h.is_finite() && h > 0.0) {
        return Err(SimError::invalid(
            "max_substep",
            format!("must be a finite number > 0 s (got {h})"),
        ));
    }
    let cap = plant::MAX_SUBSTEPS_PER_CALL;
    if (dt / h).ceil() > cap as f64 {
        return Err(SimError::invalid(
            "max_substep",
            format!(
                "{h:e} s is below what the plant honours: it takes at most {cap} sub-steps per controller cycle of {dt} s, so its smallest sub-step is {:e} s",
                dt / cap as f64
            ),
        ));
    }
    Ok(())
}
