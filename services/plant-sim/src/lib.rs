//! grip service `plant-sim`: the motor inverter, vehicle and road of a
//! scenario on the CAN bus, in real time.
//!
//! - [`config`]: `config/plant-sim.toml` ([`PlantSimConfig`], [`StartOn`]).
//! - [`cycle`]: [`PlantSim`], one cycle (`cycle(&tick, &clock, bus, truth)`
//!   per [`PlantTick`]), drivable from tests with a manual clock.
//! - [`run()`]: the service: load config, open ports, real-time set-up,
//!   periodic timer, `READY=1`, SIGUSR1 start, loop.
//! - [`monitor`]: the non-real-time helper thread (watchdog, transitions
//!   and counters logged), on [`grip_io::service::monitor`].
//!
//! See `services/README.md` ("tcs-loop / plant-sim").
#![warn(missing_docs)]

pub mod config;
pub mod cycle;
pub mod monitor;
pub mod run;

pub use config::{PlantSimConfig, StartOn};
pub use cycle::{
    FAULT_CMD_TIMEOUT, NullTruth, Outcome, Phase, PlantSim, PlantTick, ROLE, TruthSink,
};
pub use run::{Options, RunError, run};
