//! One closed-loop run: [`Sim`] (stepped cycle by cycle) and [`run`].
//!
//! Cycle k (t = k dt), in this order:
//!
//! 1. The scenario gives the true road and grade at (t, x) and the demand T_d(t).
//! 2. The sensors sample the plant's true state (noise, quantisation, delay).
//! 3. ARTE variants: the latest estimate so far (from frames that ended at or
//!    before t) becomes [`RoadKnowledge`](grip_tcs::RoadKnowledge) with age t − t_stamp; other
//!    variants get `None`.
//! 4. The controller computes T* from the measurement and the knowledge.
//! 5. The cycle is recorded (trace, metrics) with the plant's true values at t.
//! 6. ARTE variants: the estimator hears the cycle [t, t + dt) on the true
//!    road; a frame that completes yields the estimate used from cycle k + 1.
//! 7. The plant advances by dt with T* held (sub-stepped inside the plant).
//!
//! The estimate a controller sees is therefore causal: based on the road up
//! to t, never on the road ahead.

use grip_physics::{Plant, PlantState, Sensors};
use grip_tcs::{
    AnyController, Controller, Measurement, Metrics, MetricsAccumulator, RoadAware, Sample,
};

use crate::estimator::RoadEstimator;
use crate::probe::InLoopStats;
use crate::setup::SimSetup;
use crate::trace::Trace;
use crate::variant::Variant;
use crate::{SimError, sub_seed};

/// Sub-seed stream of the sensor noise.
pub const SENSOR_STREAM: u64 = 1;
/// Sub-seed stream of the road estimator.
pub const ARTE_STREAM: u64 = 2;

/// How well the road estimator did in a run (ARTE variants only; zeros otherwise).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArteStats {
    /// Decisions received.
    pub frames: u64,
    /// Decisions equal to the true road at the cycle they arrived.
    pub correct: u64,
    /// Cycles in which the controller used the knowledge.
    pub used_cycles: u64,
    /// Cycles in the run.
    pub cycles: u64,
}

impl ArteStats {
    /// correct / frames (NaN with no frame).
    pub fn accuracy(&self) -> f64 {
        if self.frames == 0 {
            f64::NAN
        } else {
            self.correct as f64 / self.frames as f64
        }
    }
    /// used_cycles / cycles.
    pub fn usage(&self) -> f64 {
        if self.cycles == 0 {
            0.0
        } else {
            self.used_cycles as f64 / self.cycles as f64
        }
    }
}

/// The outcome of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// Which variant.
    pub variant: Variant,
    /// The run seed.
    pub seed: u64,
    /// The metrics (`grip_tcs::metrics`).
    pub metrics: Metrics,
    /// Road-estimator statistics.
    pub arte: ArteStats,
    /// Final true plant state.
    pub final_state: PlantState,
    /// The farthest the wheel got, m: the largest plant position `x` a
    /// cycle ran at (a car that rolls back ends short of it), by which
    /// [`SimSetup::unreached`] tells the distance segments never reached.
    pub farthest_x: f64,
    /// Cycles in which the plant state was not finite (should be 0).
    pub non_finite_cycles: u64,
    /// The time series, when recorded.
    pub trace: Option<Trace>,
    /// What the estimator recorded about this run
    /// ([`RoadEstimator::take_stats`]; ARTE variants with a recording
    /// estimator such as [`crate::InLoopProbe`], else `None`).
    pub inloop: Option<InLoopStats>,
}

/// One closed-loop run in progress. Build with [`Sim::new`], call
/// [`Sim::step`] until it returns false, then [`Sim::finish`].
/// `step` allocates nothing.
pub struct Sim<'a> {
    setup: &'a SimSetup,
    variant: Variant,
    seed: u64,
    estimator: &'a mut dyn RoadEstimator,
    plant: Plant,
    sensors: Sensors,
    controller: AnyController,
    aware: Option<RoadAware>,
    x_odo: f64,
    /// The estimator's clock minus the run's (the pre-roll, s).
    t_pre: f64,
    metrics: MetricsAccumulator,
    trace: Option<Trace>,
    arte: ArteStats,
    non_finite: u64,
    farthest_x: f64,
    k: usize,
}

impl std::fmt::Debug for Sim<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sim")
            .field("variant", &self.variant)
            .field("seed", &self.seed)
            .field("estimator", &self.estimator.name())
            .field("k", &self.k)
            .finish_non_exhaustive()
    }
}

impl<'a> Sim<'a> {
    /// A run of `variant` with `seed` on `setup`. ARTE variants reset the
    /// estimator with a sub-seed of `seed`; other variants never consult it
    /// (so a costly reset, such as the acoustic chain's, is skipped).
    /// With `record_trace` the trace is preallocated for the whole run.
    pub fn new(
        setup: &'a SimSetup,
        variant: Variant,
        seed: u64,
        estimator: &'a mut dyn RoadEstimator,
        record_trace: bool,
    ) -> Result<Self, SimError> {
        let vehicle = *setup.vehicle();
        let mut plant = Plant::new(vehicle, PlantState::rolling(setup.scenario().v0, vehicle.r))
            .map_err(|e| SimError::from_field("vehicle", e))?;
        plant
            .set_max_substep(setup.max_substep())
            .map_err(|e| SimError::from_field("", e))?;
        let sensors = Sensors::new(*setup.sensors(), sub_seed(seed, SENSOR_STREAM))
            .map_err(|e| SimError::from_field("sensors", e))?;
        let controller =
            AnyController::new(variant.kind, setup.controllers(), &vehicle, setup.dt())
                .map_err(|e| SimError::from_field("controllers", e))?;
        let mut aware = if variant.arte {
            Some(
                RoadAware::new(
                    variant.kind,
                    setup.roads(),
                    setup.road_table().clone(),
                    &vehicle,
                    setup.controllers(),
                    setup.dt(),
                )
                .map_err(|e| SimError::from_field("controllers", e))?,
            )
        } else {
            None
        };
        let mut t_pre = 0.0;
        if variant.arte {
            estimator.reset(sub_seed(seed, ARTE_STREAM));
            if let Some(a) = aware.as_mut() {
                t_pre = pre_roll(setup, estimator, a);
            }
        }
        Ok(Self {
            setup,
            variant,
            seed,
            estimator,
            plant,
            sensors,
            controller,
            aware,
            x_odo: 0.0,
            t_pre,
            metrics: MetricsAccumulator::new(&vehicle),
            trace: record_trace.then(|| Trace::with_capacity(setup.cycles())),
            arte: ArteStats {
                cycles: setup.cycles() as u64,
                ..ArteStats::default()
            },
            non_finite: 0,
            farthest_x: f64::NEG_INFINITY,
            k: 0,
        })
    }

    /// Cycles done so far.
    pub fn cycle(&self) -> usize {
        self.k
    }

    /// The plant (true state).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// One controller cycle (see the module docs). Returns false, doing
    /// nothing, once the run's cycles are done. Allocation-free.
    pub fn step(&mut self) -> bool {
        let setup = self.setup;
        if self.k >= setup.cycles() {
            return false;
        }
        let dt = setup.dt();
        let t = self.k as f64 * dt;
        let s = *self.plant.state();
        let scenario = setup.scenario();
        let seg = scenario.segment_at(t, s.x);
        self.farthest_x = self.farthest_x.max(s.x);
        let road_idx = scenario.segments[seg].road;
        let road = &setup.roads()[road_idx];
        let grade = scenario.segments[seg].grade_rad();
        let demand = scenario.demand_at(t);

        let reading = self.sensors.sample(&s, dt);
        let m = Measurement {
            t,
            omega: reading.omega,
            v: reading.v,
            torque: reading.torque,
            demand,
        };
        // The loop's own odometer, from what it measures.
        let v_odo = grip_tcs::odometer_speed(
            reading.v,
            reading.omega,
            setup.vehicle().r,
            setup.controllers().preview.standstill_mps,
        );
        let (guidance, out) = match self.aware.as_mut() {
            Some(a) => {
                let (g, out) = a.control(&mut self.controller, &m, self.x_odo);
                (Some(g), out)
            }
            None => (None, self.controller.step(&m, None)),
        };

        let lambda = self.plant.slip_of(s.omega, s.v);
        let finite = s.omega.is_finite() && s.v.is_finite() && s.torque.is_finite();
        if !finite {
            self.non_finite += 1;
        }
        self.metrics.push(&Sample {
            dt,
            lambda,
            torque: s.torque,
            omega: s.omega,
            v: s.v,
            torque_cmd: out.torque_cmd,
        });
        if out.used_arte {
            self.arte.used_cycles += 1;
        }
        if let Some(tr) = self.trace.as_mut() {
            tr.t.push(t);
            tr.v.push(s.v);
            tr.omega.push(s.omega);
            tr.r_omega.push(setup.vehicle().r * s.omega);
            tr.lambda.push(lambda);
            tr.torque.push(s.torque);
            tr.torque_cmd.push(out.torque_cmd);
            tr.demand.push(demand);
            tr.mu.push(road.mu(lambda));
            tr.mu_hat.push(out.mu_hat);
            tr.internal.push(out.internal);
            tr.true_road.push(road_idx as u32);
            tr.lambda_opt_true.push(road.lambda_opt());
            tr.est_road.push(guidance.map(|g| g.belief.0 as u32));
            tr.confidence
                .push(guidance.map_or(f64::NAN, |g| g.belief.1));
            tr.used_arte.push(out.used_arte);
        }

        if let Some(aware) = self.aware.as_mut() {
            // The microphone hears the road `mic_lead_m` ahead of the wheel.
            let mic_seg = scenario.segment_at(t, s.x + setup.vehicle().mic_lead_m);
            let mic_road = scenario.segments[mic_seg].road;
            if let Some(e) = self.estimator.update(t + self.t_pre, dt, mic_road, s.v) {
                self.arte.frames += 1;
                if e.road_index == mic_road {
                    self.arte.correct += 1;
                }
                let stamp = e.t_stamp - self.t_pre;
                let x_to = self.x_odo + v_odo * (stamp - t).max(0.0);
                let x_from = x_to - v_odo * e.frame_s;
                aware.decision(e.road_index, e.confidence, stamp, x_from, x_to);
            }
        }
        self.x_odo += v_odo * dt;

        self.plant.step(dt, out.torque_cmd, road, grade);
        self.k += 1;
        true
    }

    /// Run the remaining cycles and return the result.
    pub fn finish(mut self) -> RunResult {
        while self.step() {}
        let inloop = if self.variant.arte {
            self.estimator.take_stats()
        } else {
            None
        };
        RunResult {
            variant: self.variant,
            seed: self.seed,
            metrics: self.metrics.finish(),
            arte: self.arte,
            final_state: *self.plant.state(),
            farthest_x: self.farthest_x,
            non_finite_cycles: self.non_finite,
            trace: self.trace,
            inloop,
        }
    }
}

/// With the microphone `mic_lead_m` ahead of the driven wheel, the road the
/// wheel meets in its first `mic_lead_m` metres was heard before the run
/// began. The pre-roll plays that approach: the car rolling at the
/// scenario's initial speed until the wheel is at 0, the microphone hearing
/// the scenario's first `mic_lead_m` metres, its decisions queued at their
/// places. Returns the pre-roll's length (the estimator's clock is ahead of
/// the run's by it); 0 without a lead.
fn pre_roll(setup: &SimSetup, estimator: &mut dyn RoadEstimator, aware: &mut RoadAware) -> f64 {
    let lead = aware.lead();
    let dt = setup.dt();
    let v0 = setup.pre_roll_speed();
    let n = setup.pre_roll_cycles();
    if n == 0 {
        return 0.0;
    }
    let t_pre = n as f64 * dt;
    let scenario = setup.scenario();
    for k in 0..n {
        let t = k as f64 * dt;
        let x_wheel = v0 * (t - t_pre);
        let mic_road = scenario.segments[scenario.segment_at(0.0, x_wheel + lead)].road;
        if let Some(e) = estimator.update(t, dt, mic_road, v0) {
            let x_to = v0 * (e.t_stamp - t_pre);
            aware.decision(
                e.road_index,
                e.confidence,
                e.t_stamp - t_pre,
                x_to - v0 * e.frame_s,
                x_to,
            );
        }
    }
    t_pre
}

/// Run `variant` with `seed` on `setup` from start to end, recording the
/// trace. The estimator is only consulted by ARTE variants. Fails only on an
/// invalid setup (which [`SimSetup::new`] already rules out).
pub fn run(
    setup: &SimSetup,
    variant: Variant,
    seed: u64,
    estimator: &mut dyn RoadEstimator,
) -> Result<RunResult, SimError> {
    Ok(Sim::new(setup, variant, seed, estimator, true)?.finish())
}
