//! grip service `arte`: audio blocks in (topic `grip/audio/block`), road
//! estimates out (topic `grip/arte/road`).
//!
//! - [`config`]: the `arte-svc.toml` file ([`ArteServiceConfig`]).
//! - [`model`]: [`load_model`] ([`load_model_from`]: naming the
//!   configuration field or option that named the file), [`road_table`]: the model file and the road
//!   catalogue entry (λ_opt, μ_peak, α from the road-knowledge rule) of each of its classes,
//!   checked at start-up.
//! - [`cycle`]: [`ArteLoop`], one call per audio block ([`ArteLoop::on_block`]):
//!   sequence and time checks, S16 → f32, the vehicle speed handed to
//!   `grip_arte::stream`'s estimator, one [`RoadEstimate`](grip_msgs::RoadEstimate) per decision.
//!   Allocation-free (`tests/no_alloc.rs`).
//! - [`run()`]: the service: configuration, model, ports, real-time set-up,
//!   readiness, the loop until stopped.
//! - [`monitor`]: the non-real-time helper thread (watchdog, transitions
//!   and counters logged), on [`grip_io::service::monitor`].
//! - [`error`]: what stops the service from starting ([`ArteError`]).
//!
//! **Sample rate**: blocks at another rate than the model's are *refused*
//! (not resampled): they are counted in `rate_mismatch`, an error is logged
//! once naming both rates, and no estimate is published, so tcs-loop falls
//! back to its no-ARTE behaviour. Resampling live would feed the classifier
//! audio whose band limits differ from its training data; the fix is to
//! set audio-acq's `[audio] sample_rate` to the model's rate.
//!
//! **Vehicle speed** (`README.md`, "Vehicle speed"): the newest
//! [`CycleRecord`](grip_msgs::CycleRecord) of tcs-loop (topic `grip/tcs/cycle`) with `v_valid = 1`
//! is kept ([`ArteLoop::on_cycle`], [`ArteLoop::poll_cycles`]); before each
//! block the estimator gets its |v| if the record is at most
//! `input.speed_timeout_s` old, else `None` (frames taken as heard at the
//! model's reference speed). Counted in [`ArteCounters::blocks_with_speed`] /
//! [`ArteCounters::blocks_without_speed`].
#![warn(missing_docs)]

pub mod config;
pub mod cycle;
pub mod error;
pub mod model;
pub mod monitor;
pub mod run;

pub use config::ArteServiceConfig;
pub use cycle::{
    ArteCounters, ArteLoop, AudioQuality, BadAudio, DEFAULT_MAX_LAG_S, DEFAULT_SPEED_TIMEOUT_S,
    EstimateSink, odometer_at,
};
pub use error::{ArteError, ModelSource};
pub use model::{ClassKnowledge, load_model, load_model_from, road_table};
pub use run::{Options, prepare, prepare_with_clock, run};
