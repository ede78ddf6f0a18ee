//! grip service `plant-sim`: the motor inverter, vehicle and road of a
//! scenario on the CAN bus, in real time.
//!
//! - [`config`]: `config/plant-sim.toml` ([`PlantSimConfig`], [`StartOn`]).
//! - [`sim`]: [`PlantSim`], one cycle (`cycle(&tick, &clock, bus, truth)`),
//!   drivable from tests with a manual clock.
//! - [`run`]: the service: load config, open ports, real-time set-up,
//!   periodic timer, `READY=1`, SIGUSR1 start, loop.
//! - [`svc`]: systemd notification and the helper thread.
//!
//! See `services/README.md` ("tcs-loop / plant-sim").

pub mod config;
pub mod run;
pub mod sim;
pub mod svc;

pub use config::{PlantSimConfig, StartOn};
pub use run::{Options, RunError, run};
pub use sim::{FAULT_CMD_TIMEOUT, NullTruth, Outcome, Phase, PlantSim, Tick, TruthSink};
