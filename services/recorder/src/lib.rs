//! grip service `recorder`: every topic of `grip_msgs::topics::ALL` to MCAP.
//!
//! - [`config`]: `config/recorder.toml` ([`RecorderConfig`]).
//! - [`stats`]: per-topic counters, gaps by sequence number (CAN: by alive
//!   counter).
//! - [`record`]: the receive thread, the bounded queue and the writer
//!   ([`run`]).
//!
//! See `services/README.md` ("recorder / drive / inspect / systemd").

pub mod config;
pub mod record;
pub mod stats;

pub use config::RecorderConfig;
pub use record::{
    ConfigFile, GIT_REV, Msg, Options, RECORDED, RunError, Subscribers, Summary, config_files, run,
    write_run_info,
};
pub use stats::{CanCounterTracker, RecvStats, SeqTracker, TopicStats};
