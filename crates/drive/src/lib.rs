//! grip's drive library: everything about a drive that is not a service.
//!
//! - [`bus`]: the vehicle bus of a log (`grip/can/bus`): per-id statistics
//!   and the candump export (`grip inspect`).
//! - [`log`]: a drive's MCAP log read back, typed ([`DriveLog`]): topics,
//!   metadata, attachments, the reader's report (truncation, bad messages).
//! - [`roads`]: the road catalogue a drive ran with
//!   ([`DriveLog::road_catalogue`]: the log's attached `roads.toml`).
//! - [`summary`]: the drive summary and metrics computed from a log alone
//!   ([`summarize`]; `grip drive` and `grip inspect` print it).
//! - [`services`]: the five services, their start and stop order and base
//!   command lines (the systemd units' `ExecStart=`).
//! - [`supervisor`]: the one service supervisor ([`Supervisor`], [`Proc`]):
//!   start in order, `READY=1`, death watch, stop, exit codes,
//!   kill-on-drop.
//! - [`plan`]: a drive's command lines ([`DrivePlan`]) and running one
//!   ([`run_services`]).
//!
//! Used by `grip drive`, `grip inspect`, `grip replay`, the end-to-end tests
//! (`tests/e2e_drive.rs`) and the HIL tests (`tests/src/hil.rs`).
#![warn(missing_docs)]

pub mod bus;
pub mod log;
pub mod plan;
pub mod roads;
pub mod services;
pub mod summary;
pub mod supervisor;

pub use log::{DriveLog, LoadOptions, LogError};
pub use plan::{
    DriveOutcome, DrivePlan, MissingBinaries, check_binaries, new_instance, run_services,
    vehicle_for,
};
pub use roads::LogRoads;
pub use services::Service;
pub use summary::{Summary, summarize};
pub use supervisor::{Output, Proc, ProcSpec, SuperviseError, Supervisor, describe_status};
