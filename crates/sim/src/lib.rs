//! grip-sim: the offline closed-loop simulator (see README.md in this crate).
//!
//! One run couples, per controller cycle (default 1 kHz):
//!
//! ```text
//!   scenario ──road, grade, T_d──► plant (sub-stepped, grip-physics) ──true state──► sensors (seeded)
//!                                    ▲                                                  │ ω, V, T (noisy, delayed)
//!                                    │ T*                                               ▼
//!                                controller (grip-tcs) ◄── RoadKnowledge ◄── RoadEstimator (frames of 0.1 s)
//! ```
//!
//! - [`Sim`]: one run, stepped cycle by cycle ([`Sim::step`] allocates
//!   nothing); [`run`] drives it to the end.
//! - [`RoadEstimator`]: the road-estimate source the loop asks every cycle.
//!   [`ConfusionArte`] implements it with a seeded confusion matrix (the
//!   paper's Table II by default), [`PerfectArte`] with the true road, and
//!   [`AcousticArte`] with the real acoustic chain of grip-arte (synthetic
//!   tyre-road audio through the streaming estimator). [`InLoopProbe`]
//!   wraps any of them and records decisions and delays ([`InLoopStats`]).
//! - [`SimSetup`]: vehicle, sensors, roads, scenario, controllers and the
//!   road-knowledge rule, validated once.
//! - [`batch::run_batch`]: many (variant, seed) runs on worker threads,
//!   deterministic whatever the thread count.
//! - [`report`]: statistics over seeds, the Table-V style table, CSV output.
//! - [`ideal`]: the ideal controller (a perfect preview, no slip
//!   dynamics, the motor's lag kept), the reference `grip sim --ideal`
//!   reports beside the simulated ones.
//! - [`speeds`]: `grip sim --arte acoustic`'s note on the speeds the model
//!   was trained at (the time the acoustic chain heard outside them).
//!
//! See `README.md` in this crate for the design and the results.
#![warn(missing_docs)]

pub mod acoustic;
pub mod batch;
pub mod estimator;
pub mod ideal;
pub mod probe;
pub mod random;
pub mod report;
pub mod setup;
pub mod sim;
pub mod speeds;
pub mod trace;
pub mod variant;

pub use acoustic::{AcousticArte, AcousticConfig, SoundAs};
pub use batch::{Job, run_batch, run_batch_with};
pub use estimator::{
    ArteConfig, ConfusionArte, ConfusionConfig, Estimate, PerfectArte, RoadEstimator,
};
pub use probe::{InLoopProbe, InLoopStats};
pub use random::{RandomSpec, SCENARIO_STREAM, sounding_roads};
pub use setup::SimSetup;
pub use sim::{ArteStats, RunResult, Sim, run};
pub use trace::Trace;
pub use variant::{UnknownVariant, Variant};

/// Errors of the simulator: invalid setup or configuration. The run itself
/// cannot fail once the setup is valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A parameter is out of range; `field` names it (dotted path).
    #[error("field `{field}`: {reason}")]
    Invalid {
        /// Dotted path of the offending field.
        field: String,
        /// What is wrong, with the value.
        reason: String,
    },
}

impl SimError {
    /// A new `Invalid` error.
    pub fn invalid(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Invalid {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The offending field.
    pub fn field(&self) -> &str {
        match self {
            Self::Invalid { field, .. } => field,
        }
    }
}

impl SimError {
    /// From a physics/tcs validation error, prefixed with `prefix` (e.g. `vehicle`).
    pub fn from_field(prefix: &str, e: grip_physics::InvalidField) -> Self {
        let e = if prefix.is_empty() {
            e
        } else {
            e.prefixed(prefix)
        };
        Self::invalid(e.field, e.reason)
    }
}

/// SplitMix64 finaliser: derives independent sub-seeds (sensor noise, ARTE
/// draws) from one run seed, so that every variant of a seed sees the same
/// sensor noise and the same ARTE draws.
pub fn sub_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed
        .wrapping_add(stream.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
