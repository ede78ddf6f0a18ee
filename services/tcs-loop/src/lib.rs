//! grip service `tcs-loop`: the traction-control loop.
//!
//! - [`config`]: `config/tcs-loop.toml` ([`TcsLoopConfig`]).
//! - [`cycle`]: [`TcsLoop`], one cycle (`cycle(&tick, &clock, bus, road, sink)` per
//!   [`CycleTick`]),
//!   drivable from tests with a manual clock and in-memory ports.
//! - [`ports`]: the road-estimate source and the recorder sink as traits,
//!   with the iceoryx2 implementations.
//! - [`run()`]: the service: load config, open ports, real-time set-up,
//!   periodic timer, `READY=1`, loop until stopped.
//! - [`monitor`]: the non-real-time helper thread (watchdog, transitions
//!   and counters logged), on [`grip_io::service::monitor`].
//!
//! See `services/README.md` ("tcs-loop / plant-sim") for the command line,
//! readiness, safe state and measured latency.
#![warn(missing_docs)]

pub mod config;
pub mod cycle;
pub mod monitor;
pub mod ports;
pub mod run;

pub use config::{SafetyConfig, TcsLoopConfig};
pub use cycle::{CycleTick, MAX_ROADS_PER_CYCLE, MAX_RX_PER_CYCLE, ROLE, SharedStatus, TcsLoop};
pub use ports::{NoRoad, NullSink, ROAD_BUFFER, RecordSink, RoadSource};
pub use run::{
    LoadedConfig, Options, RunError, RunSummary, build, check, load, run, start_warnings,
};
