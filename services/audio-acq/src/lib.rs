//! grip service `audio-acq`: mono PCM from a microphone (ALSA), a WAV file
//! or the tyre-road synthesiser, in blocks of `block_samples`, published as
//! `grip_msgs::AudioBlock` on topic `grip_msgs::topics::AUDIO`.
//!
//! - [`config`]: the `audio-acq.toml` file.
//! - [`source`]: the [`Source`] trait and the real-time [`source::Pacer`].
//! - [`alsa_src`], [`wav`], [`synth`]: the three sources; [`format`](mod@format): the
//!   ALSA capture sample formats and their conversion to S16.
//! - [`cycle`]: [`AcqLoop`], one block per [`AcqLoop::step`] (source →
//!   block → sink); allocation-free (`tests/no_alloc.rs`).
//! - [`run()`]: the service (ports, real-time set-up, readiness, watchdog,
//!   stop on SIGTERM/SIGINT), called by `main.rs`.
//! - [`monitor`]: the non-real-time helper thread (watchdog, transitions
//!   and counters logged), on [`grip_io::service::monitor`].
//! - [`error`]: what stops the service ([`AcqError`]).
//!
//! See `services/README.md`, section "audio-acq / arte", for behaviour,
//! time stamps, overruns and measured figures.
#![warn(missing_docs)]

pub mod alsa_src;
pub mod config;
pub mod cycle;
pub mod error;
pub mod format;
pub mod monitor;
pub mod run;
pub mod source;
pub mod synth;
pub mod wav;

pub use config::{AcqConfig, SourceKind};
pub use cycle::{AcqLoop, AcqStatus, BlockSink, Step};
pub use error::AcqError;
pub use run::{Options, RunSummary, run};
pub use source::{Read, Source, SourceStats};
