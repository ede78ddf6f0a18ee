//! grip-arte: acoustic road-type estimation (paper §II; the crate README).
//!
//! Pure: no file, clock or thread I/O. Reading WAV files and writing model
//! files happens in the callers (`grip`, the `arte` service); this crate
//! works on sample slices and byte buffers.
//!
//! Layout (one owner per module while the crate is being built):
//! - `synth`: synthetic tyre-road audio per road, rain and passing-car noise;
//!   the `[synth.aliases]` rule (`synth::SynthAliases::resolve`).
//! - `features`: the paper's 20 features (LPC, power spectrum, cepstrum), the
//!   richer set, `FeatureConfig`, and the `FeatureExtractor` (plan once, reuse).
//! - `select`: pruning by least intra-class variance, Kullback-Leibler report.
//! - `stream`: the streaming estimator (blocks in, a decision per hop).
//! - `stream_eval`: its evaluation on road-change recordings (false switches,
//!   what a gated controller is given, bootstrap intervals).
//! - `mlp`, `svm`: classifiers (Levenberg-Marquardt MLP, SMO SVM).
//! - `model`: the versioned, checksummed model file, standardisation inside.
//! - `eval`: cross-validation by recording, confusion matrices, macro-F1.
//! - `speeds`: the vehicle speeds a model was trained at (`meta.speeds`)
//!   and how much of a drive or simulation ran outside them (notes only).
//! - `calib`: confidence calibration of the stream's decisions, ECE, reliability.
//! - `quality`: when audio is not fit to classify (silence, clipping,
//!   overruns): one rule for the arte service and the offline commands.
#![warn(missing_docs)]

pub mod calib;
pub mod eval;
pub mod features;
pub mod mlp;
pub mod model;
pub mod quality;
pub mod select;
pub mod speeds;
pub mod stream;
pub mod stream_eval;
pub mod svm;
pub mod synth;
