//! grip-io: every adapter between the pure grip crates and the outside
//! world. This is the only crate that touches SocketCAN, iceoryx2 ports,
//! MCAP and WAV files or the OS scheduler.
//!
//! - [`can`]: the inverter protocol (`config/inverter.dbc`) with E2E
//!   protection, and the CAN transports (SocketCAN, simulated bus over iceoryx2).
//! - [`ipc`]: iceoryx2 nodes, typed publishers/subscribers, dead-node cleanup.
//! - [`mcaplog`]: MCAP writer and reader for the grip payloads.
//! - [`rt`]: SCHED_FIFO, mlockall, affinity, cpu_dma_latency, periodic
//!   timer with latency statistics.
//! - [`clock`]: injected monotonic time (real and manual).
//! - [`systemd`]: `sd_notify` readiness/status/stopping and the
//!   heartbeat-gated watchdog every service uses.
//! - [`service`]: the skeleton of every service's `main` (tracing,
//!   signals, exit codes, its own TOML) and its helper thread
//!   ([`service::monitor`]).
//! - [`wav`]: WAV reading (mixdown, resampling) and writing, for the CLI and
//!   audio-acq's file source.
//! - [`binaries`]: where the service binaries are (`$GRIP_BIN_DIR` or beside
//!   the running executable), for `grip drive` and the workspace tests.
//!
//! See `crates/io/README.md` for the protocol tables and measured figures.
#![warn(missing_docs)]

// a road's name, as roads.toml may give it, fits the messages' name field
const _: () = assert!(grip_physics::road::NAME_MAX_BYTES == grip_msgs::NAME_LEN);

pub mod binaries;
pub mod can;
pub mod clock;
pub mod ipc;
pub mod mcaplog;
pub mod rt;
pub mod service;
pub mod systemd;
pub mod wav;
