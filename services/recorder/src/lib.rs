//! grip service `recorder`: every topic of `grip_msgs::topics::ALL` to MCAP.
//!
//! - [`config`]: `config/recorder.toml` ([`RecorderConfig`]).
//! - [`stats`]: per-topic counters, gaps by sequence number (CAN: by alive
//!   counter).
//! - [`bus`]: the vehicle bus read off the bus itself (`recorder.toml`'s
//!   `bus`) onto the MCAP channel `grip/can/bus`.
//! - [`cycle`]: the receive thread, the bounded queue and the writing loop.
//! - [`run()`]: the service: config, the log file and its run metadata,
//!   `READY=1`, the loop until stopped, the summary; [`check()`]: its
//!   start-up refusals alone (the `--attach` files, `recorder.toml`), which
//!   `grip drive` runs before any service starts.
//! - [`parts`]: the run's log files: rotation (`max_file_mib`,
//!   `max_file_s`), and a new file after a write error (a full disk).
//! - [`retention`]: which old logs of `out_dir` to delete (the budget
//!   `max_total_mib`, the free-space floor `min_free_mib`), and deleting them.
//! - [`monitor`]: publishers per topic and the watchdog's stall line (the
//!   recorder has no helper thread: see the module).
//!
//! See `services/README.md` ("recorder / drive / inspect / systemd").
#![warn(missing_docs)]

pub mod bus;
pub mod config;
pub mod cycle;
pub mod monitor;
pub mod parts;
pub mod retention;
#[cfg(test)]
mod revision;
pub mod run;
pub mod stats;

pub use config::RecorderConfig;
pub use cycle::{Msg, RECORDED, Subscribers, Summary};
pub use retention::{Limits, Retention, parse_log_name, plan};
pub use run::{ConfigFile, GIT_REV, Options, RunError, check, config_files, run, write_run_info};
pub use stats::{CanCounterTracker, RecvStats, SeqTracker, TopicStats};
