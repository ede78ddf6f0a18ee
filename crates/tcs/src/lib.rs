//! grip-tcs: the three traction controllers (MFC, SRC with fuzzy optimal
//! slip, MTTE), their observers and filters, the metrics (`metrics`), and
//! the linear analysis (transfer functions, K_MFC bound, Vinnicombe nu-gap).
//! Pure: no I/O, no clock; every `step` is allocation-free.
#![warn(missing_docs)]

pub mod analysis;
pub mod any;
pub mod filters;
pub mod fusion;
pub mod fuzzy;
pub mod knowledge;
pub mod metrics;
pub mod mfc;
pub mod mtte;
pub mod observer;
pub mod params;
pub mod preview;
pub mod road_aware;
pub mod slip_control;
pub mod types;

pub use any::{AnyController, ControllerKind, UnknownController};
pub use fusion::{FusionParams, RoadBelief};
pub use knowledge::{KnowledgeConfig, RoadInfo, RoadTable};
pub use metrics::{Metrics, MetricsAccumulator, Sample};
pub use mfc::Mfc;
pub use mtte::Mtte;
pub use params::{ArteUse, ControllersConfig, LoopParams, MfcParams, MtteParams, SrcParams};
pub use preview::{PREVIEW_CAPACITY, PreviewQueue, PreviewView, RoadAhead};
pub use road_aware::{Guidance, PreviewParams, PreviewTrade, RoadAware, odometer_speed};
pub use slip_control::Src;
pub use types::{ControlOutput, Controller, Measurement, RoadKnowledge};

/// Final limit shared by all controllers: for a positive demand the command
/// is `candidate` clamped to `[0, T_d]` (NaN → 0, the safe side); a demand
/// `<= 0` is passed through (the controllers are traction controllers);
/// a non-finite demand gives 0.
#[inline]
pub(crate) fn limit_to_demand(candidate: f64, demand: f64) -> f64 {
    if !demand.is_finite() {
        0.0
    } else if demand <= 0.0 {
        demand
    } else if candidate.is_nan() {
        0.0
    } else {
        candidate.clamp(0.0, demand)
    }
}

/// How much a positive demand rose since the previous cycle (SRC and MTTE
/// pass a rise on while the wheel grips: "Pulling away and a ramped pedal"
/// in the README). Call once per cycle; 0 when the demand fell, stayed, or
/// is not a positive finite number, whose cycle counts as a demand of 0.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct DemandRise {
    last: f64,
}

impl DemandRise {
    /// The rise of `demand` over the previous cycle's, N m (>= 0).
    #[inline]
    pub(crate) fn step(&mut self, demand: f64) -> f64 {
        let now = if demand > 0.0 && demand.is_finite() {
            demand
        } else {
            0.0
        };
        let rise = (now - self.last).max(0.0);
        self.last = now;
        rise
    }
}

/// `dt` must be finite and > 0.
pub(crate) fn valid_dt(dt: f64) -> Result<(), grip_physics::InvalidField> {
    if dt.is_finite() && dt > 0.0 {
        Ok(())
    } else {
        Err(grip_physics::InvalidField::new(
            "dt",
            format!("must be a finite number > 0 s (got {dt})"),
        ))
    }
}
