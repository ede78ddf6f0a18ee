//! The interface every controller implements. Shared by the offline
//! simulator, the live `tcs-loop` service and replay.

/// What the controller sees in one cycle: measured, noisy, quantised
/// signals, never the plant's true state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measurement {
    /// Time of this cycle, s (monotonic, from the caller's clock).
    pub t: f64,
    /// Driven-wheel angular speed omega, rad/s (wheel-speed sensor).
    pub omega: f64,
    /// Chassis speed V, m/s, when a source exists (a non-driven wheel);
    /// only SRC needs it. `None` when not available.
    pub v: Option<f64>,
    /// Motor torque reported by the inverter, N m.
    pub torque: f64,
    /// Driver's torque demand T_d, N m.
    pub demand: f64,
}

/// The road knowledge ARTE gives the controller (from the road class's
/// mu-lambda table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadKnowledge {
    /// Optimal slip of the estimated road.
    pub lambda_opt: f64,
    /// Peak friction coefficient of the estimated road.
    pub mu_peak: f64,
    /// MTTE relaxation factor for this road (default 1 - lambda_opt).
    pub alpha: f64,
    /// Classifier confidence in [0, 1].
    pub confidence: f64,
    /// Age of the estimate at this cycle, s.
    pub age: f64,
}

/// What a controller decides in one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlOutput {
    /// Torque command T*, N m. Never above the driver's demand except where
    /// a controller documents otherwise (MFC's model correction).
    pub torque_cmd: f64,
    /// True when the road knowledge was fresh and confident and used this
    /// cycle; false when the controller ran its no-ARTE behaviour.
    pub used_arte: bool,
    /// Controller-specific internal signal for logs and plots: MFC's model
    /// speed omega_M (rad/s), SRC's slip reference lambda*, MTTE's T_max (N m).
    pub internal: f64,
    /// Estimated friction coefficient mu-hat from the driving-force observer
    /// (NaN when the controller has none).
    pub mu_hat: f64,
    /// True when the controller could not run its control law this cycle and
    /// passed the driver's demand through unchanged (SRC without a chassis
    /// speed `Measurement::v`). False in normal operation.
    pub passthrough: bool,
}

/// A traction controller: a plain struct with a `step` at the controller
/// rate. Implementations allocate nothing in `step`.
pub trait Controller {
    /// One control cycle. `road` is ARTE's latest knowledge, if any; the
    /// controller falls back to its no-ARTE behaviour when it is `None`,
    /// older than its configured maximum age, or less confident than its
    /// configured threshold.
    fn step(&mut self, m: &Measurement, road: Option<&RoadKnowledge>) -> ControlOutput;
    /// Back to the state at construction (start of a drive).
    fn reset(&mut self);
}
