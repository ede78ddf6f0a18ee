//! The ARTE model file: classes, feature config, standardiser, classifier
//! and training metadata in one versioned, checksummed file.
//!
//! Format (versions 1 and 2):
//!
//! ```text
//! GRIP-ARTE-MODEL v2 sha256=<64 lower-case hex digits of the payload>\n
//! <payload: compact JSON of `Model`>
//! ```
//!
//! Version 2 adds one field at the end of the payload, `calibration` (a
//! [`StreamCalibration`]: the map from the streaming estimator's smoothed
//! posterior to a calibrated confidence, and what it was fitted on); a
//! version 2 file must have it. A model without calibration is written as
//! version 1, exactly as before calibration existed, and version 1 files
//! load with no calibration: [`Model::calibration`] is `None`, the
//! streaming estimator then reports the raw smoothed posterior (identity),
//! and callers can say so. Any other version is refused, naming it.
//!
//! Optional fields of `meta` (`training_files`, `speeds`: the vehicle
//! speeds of the training recordings, [`crate::speeds`]) are written only
//! when present and read as absent from files written before them, in
//! either version: such a file loads, and writes back byte-identical.
//!
//! The checksum covers the payload bytes exactly as stored. Floats are
//! written by `serde_json` in shortest round-trip form and parsed with its
//! `float_roundtrip` feature, so `to_bytes → from_bytes → to_bytes` is
//! byte-identical and predictions of a reloaded model are bit-identical.
//!
//! [`Model::from_bytes`] refuses, each with its own [`ModelError`]: a file
//! that is not a model (bad magic), an unknown format version, a checksum
//! mismatch (corrupt or truncated), bad JSON, and any inconsistency (class
//! count vs classifier outputs, feature count vs feature config vs
//! standardiser vs classifier inputs, non-finite numbers). The caller adds
//! the path to the message.
//!
//! Standardisation lives in the model: `z_i = (x_i − mean_i) / std_i` with
//! the training-set mean and standard deviation (a std below 1e-12 is stored
//! as 1, so a constant feature maps to 0 instead of dividing by zero).
//!
//! Paper7's selected feature indices are `feature_config.selection` (the
//! extractor computes exactly the selected columns), so a model needs no
//! separate selection field.

use grip_digest::sha256_hex;
use serde::{Deserialize, Serialize};

use crate::calib::{CalibError, StreamCalibration};
use crate::eval::{Confusion, Metrics, Samples, holdout_groups, stratified_group_kfold};
use crate::features::{FeatureConfig, FeatureError, FeatureSet, N_PAPER20};
use crate::mlp::{LmConfig, LmReport, Mlp, MlpError, MlpScratch, stratified_subsample, train_lm};
use crate::select::{paper7_config, select_paper7};
use crate::speeds::{SpeedRange, TrainingSpeeds};
use crate::svm::{Kernel, Svm, SvmConfig, SvmError, SvmReport, SvmScratch};

/// File magic, first token of the header line.
pub const MAGIC: &str = "GRIP-ARTE-MODEL";
/// The newest format version this code writes and reads (a model with a
/// confidence calibration).
pub const FORMAT_VERSION: u32 = 2;
/// The format of a model without calibration (read and written as before).
pub const FORMAT_VERSION_UNCALIBRATED: u32 = 1;

/// Errors of model files, fitting and prediction.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// No header line, or the file is empty.
    #[error("not a grip ARTE model: {0}")]
    NotAModel(String),
    /// Header names a version this code does not know.
    #[error(
        "model format version {found} is not supported (this build reads versions {FORMAT_VERSION_UNCALIBRATED} and {FORMAT_VERSION})"
    )]
    UnknownVersion {
        /// Version found.
        found: String,
    },
    /// Payload checksum does not match the header.
    #[error(
        "checksum mismatch: header says sha256={expected}, payload hashes to {actual} (file corrupt or truncated)"
    )]
    Checksum {
        /// From the header.
        expected: String,
        /// Computed.
        actual: String,
    },
    /// Payload is not valid JSON for a model.
    #[error("model payload is not valid: {0}")]
    Json(String),
    /// Payload parsed but its parts disagree.
    #[error("model is inconsistent: field `{field}`: {reason}")]
    Mismatch {
        /// Offending field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// Confidence calibration invalid.
    #[error("model field `calibration`: {0}")]
    Calib(CalibError),
    /// Feature config invalid.
    #[error("model field `feature_config`: {0}")]
    Features(FeatureError),
    /// MLP problem.
    #[error("MLP: {0}")]
    Mlp(MlpError),
    /// SVM problem.
    #[error("SVM: {0}")]
    Svm(SvmError),
    /// Evaluation/split problem.
    #[error("{0}")]
    Eval(crate::eval::EvalError),
    /// Feature vector of the wrong length given to a predictor.
    #[error("feature vector has {got} values, the model expects {expected}")]
    FeatureCount {
        /// Given.
        got: usize,
        /// Expected.
        expected: usize,
    },
    /// Output slice of the wrong length.
    #[error("probability output has {got} slots, the model has {expected} classes")]
    OutputCount {
        /// Given.
        got: usize,
        /// Expected.
        expected: usize,
    },
    /// A feature value is NaN or infinite.
    #[error("feature {index} is not finite")]
    NotFinite {
        /// Feature index.
        index: usize,
    },
}

// The variants that wrap another crate error say its reason in their own
// text (`MLP: 5 weights given, ...`), so the wrapped error is not also
// their `source`: `{:#}` (anyhow) and error chains would print the reason
// twice. Hence `From` by hand, not `#[from]` (which makes it the source).
macro_rules! model_error_from {
    ($($variant:ident($ty:ty)),* $(,)?) => {$(
        impl From<$ty> for ModelError {
            fn from(e: $ty) -> Self {
                Self::$variant(e)
            }
        }
    )*};
}
model_error_from!(
    Calib(CalibError),
    Features(FeatureError),
    Mlp(MlpError),
    Svm(SvmError),
    Eval(crate::eval::EvalError),
);

/// Per-feature standardisation fitted on the training set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Standardiser {
    /// Means.
    pub mean: Vec<f64>,
    /// Standard deviations (population), floored: below [`MIN_STD`] stored
    /// as 1.
    pub std: Vec<f64>,
}

/// The smallest standard deviation a standardiser holds: [`Standardiser::fit`]
/// stores a smaller one as 1, and a model file with one is refused.
pub const MIN_STD: f64 = 1e-12;

impl Standardiser {
    /// Fits means and standard deviations of the rows of `s`.
    pub fn fit(s: &Samples) -> Self {
        let (d, n) = (s.dim, s.len().max(1) as f64);
        let mut mean = vec![0.0; d];
        for i in 0..s.len() {
            for (m, v) in mean.iter_mut().zip(s.row(i)) {
                *m += v;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n);
        let mut var = vec![0.0; d];
        for i in 0..s.len() {
            for ((acc, v), m) in var.iter_mut().zip(s.row(i)).zip(&mean) {
                *acc += (v - m) * (v - m);
            }
        }
        let std = var
            .iter()
            .map(|v| (v / n).sqrt())
            .map(|s| if s < MIN_STD { 1.0 } else { s })
            .collect();
        Self { mean, std }
    }
    /// `out_i = (x_i − mean_i) / std_i`.
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] = (x[i] - self.mean[i]) / self.std[i];
        }
    }
    /// Standardised copy of a sample set.
    pub fn transform(&self, s: &Samples) -> Samples {
        let mut t = s.clone();
        for row in t.x.chunks_exact_mut(s.dim.max(1)) {
            for (i, v) in row.iter_mut().enumerate() {
                *v = (*v - self.mean[i]) / self.std[i];
            }
        }
        t
    }
}

/// The trained classifier.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Classifier {
    /// Levenberg-Marquardt MLP.
    Mlp(Mlp),
    /// One-vs-one RBF SVM.
    Svm(Svm),
}

impl Classifier {
    fn dims(&self) -> (usize, usize) {
        match self {
            Classifier::Mlp(m) => (m.n_in(), m.n_out()),
            Classifier::Svm(s) => (s.dim(), s.n_classes()),
        }
    }
    /// Short description, e.g. `MLP [7, 4, 3, 2, 4]` or `SVM RBF γ=0.1, 812 SVs`.
    pub fn describe(&self) -> String {
        match self {
            Classifier::Mlp(m) => format!(
                "MLP {:?} ({:?} outputs, {} weights)",
                m.sizes(),
                m.output_kind(),
                m.n_weights()
            ),
            Classifier::Svm(s) => match s.kernel() {
                Kernel::Rbf { gamma } => format!(
                    "SVM one-vs-one, RBF gamma={gamma}, {} support vectors",
                    s.n_sv()
                ),
                Kernel::Linear => format!("SVM one-vs-one, linear, {} support vectors", s.n_sv()),
            },
        }
    }
}

/// Cross-validation summary stored with a model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalSummary {
    /// What was evaluated (e.g. "5-fold CV by recording", "held-out data/test").
    pub what: String,
    /// Scores.
    pub metrics: Metrics,
    /// Confusion matrix (rows predicted, columns actual).
    pub confusion: Confusion,
}

/// Where a model came from. Not used for prediction.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrainingMeta {
    /// Training seed.
    pub seed: u64,
    /// SHA-256 over the training dataset (definition: the trainer's docs).
    pub dataset_hash: String,
    /// Training date, `YYYY-MM-DD` (UTC).
    pub date: String,
    /// Profile/name, e.g. "paper" or "default".
    pub profile: String,
    /// The command that produced the model.
    pub command: String,
    /// Training frames and recordings.
    pub n_frames: usize,
    /// Recordings.
    pub n_recordings: usize,
    /// Free-form facts (chosen hyper-parameters, stop reason, ...).
    pub notes: Vec<String>,
    /// Cross-validation result.
    pub cv: Option<EvalSummary>,
    /// The training recordings by content: the first 16 hex digits
    /// (64 bits) of each training file's SHA-256, sorted, without
    /// repeats. `grip calibrate` refuses calibration recordings that are
    /// among them, wherever they lie. Models written before this field
    /// existed have it empty (and it is then not written, so their bytes
    /// are unchanged).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub training_files: Vec<String>,
    /// The vehicle speeds of the training recordings, km/h: the slowest
    /// and fastest `speed_kmh` of the training manifest among the
    /// recordings that gave frames (`grip train`; None when a recording
    /// has no speed). Models written before this field existed have none
    /// (and it is then not written, so their bytes are unchanged);
    /// [`Model::training_speeds`] then reads `grip train`'s note on them,
    /// if there is one ([`crate::speeds`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speeds: Option<SpeedRange>,
}

/// A trained road-type classifier, everything needed to go from a frame's
/// feature vector to class probabilities.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    version: u32,
    classes: Vec<String>,
    feature_config: FeatureConfig,
    standardiser: Standardiser,
    classifier: Classifier,
    /// Training metadata.
    pub meta: TrainingMeta,
    /// Confidence calibration of the streaming estimator (format v2 only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    calibration: Option<StreamCalibration>,
}

impl Model {
    /// Assembles and validates a model.
    pub fn new(
        classes: Vec<String>,
        feature_config: FeatureConfig,
        standardiser: Standardiser,
        classifier: Classifier,
        meta: TrainingMeta,
    ) -> Result<Self, ModelError> {
        let m = Self {
            version: FORMAT_VERSION_UNCALIBRATED,
            classes,
            feature_config,
            standardiser,
            classifier,
            meta,
            calibration: None,
        };
        m.validate()?;
        Ok(m)
    }

    /// Class names, index = class id.
    pub fn classes(&self) -> &[String] {
        &self.classes
    }
    /// The features this model was trained on.
    pub fn feature_config(&self) -> &FeatureConfig {
        &self.feature_config
    }
    /// The standardiser.
    pub fn standardiser(&self) -> &Standardiser {
        &self.standardiser
    }
    /// The classifier.
    pub fn classifier(&self) -> &Classifier {
        &self.classifier
    }
    /// Feature-vector length.
    pub fn dim(&self) -> usize {
        self.standardiser.mean.len()
    }
    /// The vehicle speeds the model was trained at: `meta.speeds`, else
    /// `grip train`'s note on them in `meta.notes` (a model written before
    /// `meta.speeds`), else not recorded ([`crate::speeds`]).
    pub fn training_speeds(&self) -> TrainingSpeeds {
        if let Some(r) = self.meta.speeds {
            return TrainingSpeeds::Recorded(r);
        }
        self.meta
            .notes
            .iter()
            .find_map(|n| SpeedRange::from_note(n))
            .map_or(TrainingSpeeds::NotRecorded, TrainingSpeeds::FromNote)
    }

    /// The streaming estimator's confidence calibration; `None` for a model
    /// without one (a version 1 file): the stream's confidence is then the
    /// raw smoothed posterior.
    pub fn calibration(&self) -> Option<&StreamCalibration> {
        self.calibration.as_ref()
    }
    /// The file format version this model is written in (1 without
    /// calibration, 2 with).
    pub fn format_version(&self) -> u32 {
        self.version
    }
    /// This model with `calibration` (or without, for `None`); the format
    /// version follows. The classifier and everything else are unchanged.
    pub fn with_calibration(
        mut self,
        calibration: Option<StreamCalibration>,
    ) -> Result<Self, ModelError> {
        self.version = if calibration.is_some() {
            FORMAT_VERSION
        } else {
            FORMAT_VERSION_UNCALIBRATED
        };
        self.calibration = calibration;
        self.validate()?;
        Ok(self)
    }

    /// Checks every cross-field invariant.
    pub fn validate(&self) -> Result<(), ModelError> {
        let mm = |field, reason: String| Err(ModelError::Mismatch { field, reason });
        match (self.version, &self.calibration) {
            (FORMAT_VERSION_UNCALIBRATED, None) => {}
            (FORMAT_VERSION, Some(c)) => {
                c.map.validate()?;
                if !(c.stream.hop_s.is_finite() && c.stream.hop_s > 0.0) {
                    return mm(
                        "calibration.stream.hop_s",
                        format!("{} is not a positive time", c.stream.hop_s),
                    );
                }
            }
            (FORMAT_VERSION_UNCALIBRATED, Some(_)) => {
                return mm(
                    "calibration",
                    format!(
                        "present in a version {FORMAT_VERSION_UNCALIBRATED} model; calibration needs version {FORMAT_VERSION}"
                    ),
                );
            }
            (FORMAT_VERSION, None) => {
                return mm(
                    "calibration",
                    format!("missing; a version {FORMAT_VERSION} model carries one"),
                );
            }
            (v, _) => {
                return Err(ModelError::UnknownVersion {
                    found: v.to_string(),
                });
            }
        }
        if let Some(r) = &self.meta.speeds
            && !r.is_valid()
        {
            return mm(
                "meta.speeds",
                format!(
                    "min_kmh {} and max_kmh {} are not speeds with 0 <= min <= max",
                    r.min_kmh, r.max_kmh
                ),
            );
        }
        if self.classes.len() < 2 {
            return mm(
                "classes",
                format!(
                    "{} class(es); a classifier needs at least 2",
                    self.classes.len()
                ),
            );
        }
        for (i, c) in self.classes.iter().enumerate() {
            if c.trim().is_empty() {
                return mm("classes", format!("class {i} has an empty name"));
            }
            if self.classes[..i].contains(c) {
                return mm("classes", format!("class `{c}` appears twice"));
            }
        }
        self.feature_config.validate()?;
        let dim = self.feature_config.dim();
        let st = &self.standardiser;
        if st.mean.len() != dim || st.std.len() != dim {
            return mm(
                "standardiser",
                format!(
                    "{} means and {} stds, but the feature config gives {dim} features",
                    st.mean.len(),
                    st.std.len()
                ),
            );
        }
        if let Some(i) = st.mean.iter().position(|v| !v.is_finite()) {
            return mm("standardiser.mean", format!("entry {i} is not finite"));
        }
        // the writer stores a std below MIN_STD as 1; a smaller one would
        // blow a feature up to infinity
        if let Some(i) = st
            .std
            .iter()
            .position(|v| !(v.is_finite() && *v >= MIN_STD))
        {
            return mm(
                "standardiser.std",
                format!(
                    "entry {i} = {:?} is not finite and at least {MIN_STD:e}",
                    st.std[i]
                ),
            );
        }
        match &self.classifier {
            Classifier::Mlp(m) => {
                Mlp::from_weights(m.sizes().to_vec(), m.output_kind(), m.weights().to_vec())?;
            }
            Classifier::Svm(s) => s.validate()?,
        }
        let (n_in, n_out) = self.classifier.dims();
        if n_in != dim {
            return mm(
                "classifier",
                format!("takes {n_in} inputs, the feature config gives {dim} features"),
            );
        }
        if n_out != self.classes.len() {
            return mm(
                "classifier",
                format!("has {n_out} outputs for {} classes", self.classes.len()),
            );
        }
        Ok(())
    }

    /// Serialises to the versioned, checksummed file format.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ModelError> {
        let payload = serde_json::to_vec(self).map_err(|e| ModelError::Json(e.to_string()))?;
        let mut out = format!(
            "{MAGIC} v{} sha256={}\n",
            self.version,
            sha256_hex(&payload)
        )
        .into_bytes();
        out.extend_from_slice(&payload);
        Ok(out)
    }

    /// Parses and validates a model file (see the module docs for what is refused).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ModelError> {
        let nl = bytes.iter().position(|&b| b == b'\n').ok_or_else(|| {
            ModelError::NotAModel(if bytes.is_empty() {
                "file is empty".into()
            } else {
                "no header line (truncated, or not a model file)".into()
            })
        })?;
        let header = std::str::from_utf8(&bytes[..nl])
            .map_err(|_| ModelError::NotAModel("header line is not UTF-8".into()))?;
        let mut tok = header.split_whitespace();
        if tok.next() != Some(MAGIC) {
            let shown: String = header.chars().take(40).collect();
            return Err(ModelError::NotAModel(format!(
                "header must start with `{MAGIC}`, found `{shown}`"
            )));
        }
        let ver = tok.next().unwrap_or("");
        let header_version = match ver {
            "v1" => FORMAT_VERSION_UNCALIBRATED,
            "v2" => FORMAT_VERSION,
            _ => {
                return Err(ModelError::UnknownVersion {
                    found: ver.trim_start_matches('v').to_string(),
                });
            }
        };
        let expected = tok
            .next()
            .and_then(|t| t.strip_prefix("sha256="))
            .ok_or_else(|| ModelError::NotAModel("header has no `sha256=` checksum".into()))?;
        let payload = &bytes[nl + 1..];
        let actual = sha256_hex(payload);
        if !expected.eq_ignore_ascii_case(&actual) {
            return Err(ModelError::Checksum {
                expected: expected.to_string(),
                actual,
            });
        }
        let m: Model =
            serde_json::from_slice(payload).map_err(|e| ModelError::Json(e.to_string()))?;
        m.validate()?;
        if m.version != header_version {
            return Err(ModelError::Mismatch {
                field: "version",
                reason: format!(
                    "the header says version {header_version}, the payload {}",
                    m.version
                ),
            });
        }
        Ok(m)
    }

    /// A predictor owning a copy of this model and pre-sized scratch.
    pub fn predictor(&self) -> Predictor {
        Predictor::new(self.clone())
    }

    /// Confusion matrix of this model on `data` (features in this model's
    /// layout; for a Paper7 model, Paper20 rows are accepted and the
    /// model's selection is applied).
    pub fn evaluate(&self, data: &Samples) -> Result<Confusion, ModelError> {
        self.evaluate_smoothed(data, 1)
    }

    /// As [`Model::evaluate`], but each frame's decision is the argmax of
    /// the class probabilities averaged over the last `window` frames of the
    /// same recording (causal moving average; `window` 1 = per frame).
    /// Rows of one recording must be consecutive and in time order, as the
    /// trainer extracts them. Shows what a streaming estimator that smooths
    /// over `window` frames (latency `window` × hop) can reach.
    pub fn evaluate_smoothed(
        &self,
        data: &Samples,
        window: usize,
    ) -> Result<Confusion, ModelError> {
        let window = window.max(1);
        let picked;
        let data = if self.feature_config.set == FeatureSet::Paper7
            && data.dim == N_PAPER20
            && self.dim() != N_PAPER20
        {
            picked = data.select_columns(&self.feature_config.selection);
            &picked
        } else {
            data
        };
        let k = self.classes.len();
        let mut p = self.predictor();
        let mut probs = vec![0.0; k];
        let mut hist: Vec<f64> = Vec::with_capacity(data.len() * k);
        let mut conf = Confusion::new(self.classes.clone());
        let mut rec_start = 0;
        let mut avg = vec![0.0; k];
        for i in 0..data.len() {
            if i > 0 && data.group[i] != data.group[i - 1] {
                rec_start = i;
            }
            p.predict_proba(data.row(i), &mut probs)?;
            hist.extend_from_slice(&probs);
            let from = rec_start.max((i + 1).saturating_sub(window));
            avg.fill(0.0);
            for j in from..=i {
                for (a, v) in avg.iter_mut().zip(&hist[j * k..(j + 1) * k]) {
                    *a += v;
                }
            }
            let mut best = 0;
            for c in 1..k {
                if avg[c] > avg[best] {
                    best = c;
                }
            }
            conf.add(best, data.y[i]);
        }
        Ok(conf)
    }
}

/// Allocation-free prediction: the model plus scratch buffers.
#[derive(Clone, Debug)]
pub struct Predictor {
    model: Model,
    z: Vec<f64>,
    mlp: Option<MlpScratch>,
    svm: Option<SvmScratch>,
}

impl Predictor {
    /// Sizes all buffers for `model`.
    pub fn new(model: Model) -> Self {
        let (mlp, svm) = match &model.classifier {
            Classifier::Mlp(m) => (Some(m.scratch()), None),
            Classifier::Svm(s) => (None, Some(s.scratch())),
        };
        let z = vec![0.0; model.dim()];
        Self { model, z, mlp, svm }
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Class probabilities of one feature vector into `out` (one per class,
    /// summing to 1); returns the most probable class (ties: lower index).
    /// A classifier output with a non-finite value or summing to 0 is
    /// replaced by the uniform distribution (class 0). Allocates nothing.
    pub fn predict_proba(
        &mut self,
        features: &[f64],
        out: &mut [f64],
    ) -> Result<usize, ModelError> {
        let dim = self.z.len();
        if features.len() != dim {
            return Err(ModelError::FeatureCount {
                got: features.len(),
                expected: dim,
            });
        }
        let k = self.model.classes.len();
        if out.len() != k {
            return Err(ModelError::OutputCount {
                got: out.len(),
                expected: k,
            });
        }
        if let Some(index) = features.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::NotFinite { index });
        }
        self.model.standardiser.apply(features, &mut self.z);
        match (&self.model.classifier, &mut self.mlp, &mut self.svm) {
            (Classifier::Mlp(m), Some(s), _) => m.predict_proba(&self.z, s, out),
            (Classifier::Svm(m), _, Some(s)) => m.predict_proba(&self.z, s, out),
            _ => unreachable!("scratch built for the classifier kind"),
        }
        // a classifier that says nothing usable (NaN, infinite, all zero:
        // e.g. extreme weights of a crafted model) gives no information
        // rather than a NaN confidence downstream
        let sum: f64 = out.iter().sum();
        let usable = sum > 0.0 && out.iter().all(|p| p.is_finite());
        if !usable {
            out.fill(1.0 / k as f64);
        }
        let mut best = 0;
        for (i, &p) in out.iter().enumerate() {
            if p > out[best] {
                best = i;
            }
        }
        Ok(best)
    }
}

/// How to train the classifier of a model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClassifierSpec {
    /// Levenberg-Marquardt MLP; `val_fraction` of each class's recordings is
    /// held out for early stopping (none if a class has a single recording).
    Mlp {
        /// LM settings (architecture, trainlm defaults, seed).
        lm: LmConfig,
        /// Fraction of recordings per class for validation (MATLAB's default split is 0.15).
        val_fraction: f64,
    },
    /// One-vs-one SVM on at most `max_per_class` frames per class (seeded
    /// stratified subsample; SMO is `O(n²)` in memory per pair).
    Svm {
        /// C, kernel, tolerances.
        cfg: SvmConfig,
        /// Frame cap per class.
        max_per_class: usize,
    },
}

/// What fitting did.
#[derive(Clone, Debug, PartialEq)]
pub enum FitReport {
    /// LM report.
    Mlp(LmReport),
    /// SVM report.
    Svm(SvmReport),
}

/// Fits standardiser and classifier on `train` (features in
/// `feature_config`'s layout, labels index `classes`). Deterministic.
///
/// For a Paper7 config, `train` may hold Paper20 rows: the paper's pruning
/// ([`select_paper7`]) then runs on `train` and the model stores the chosen
/// indices in its `feature_config.selection`.
pub fn fit(
    classes: &[String],
    feature_config: &FeatureConfig,
    spec: &ClassifierSpec,
    train: &Samples,
) -> Result<(Model, FitReport), ModelError> {
    fit_with_split(classes, feature_config, spec, train).map(|(m, r, _)| (m, r))
}

/// Which frames a fit trained on and which it held out for validation
/// (row indices of the samples given to [`fit_with_split`], whole
/// recordings on each side).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FitSplit {
    /// Frames of the training recordings (the MLP's `max_rows` and the
    /// SVM's `max_per_class` subsample from these).
    pub train: Vec<usize>,
    /// Frames of the recordings held out for the MLP's early stopping
    /// (empty for the SVM, with `val_fraction` 0, or when every class has
    /// a single recording).
    pub val: Vec<usize>,
}

/// [`fit`], also returning the split of `train` into training and
/// validation frames (for [`FitCheck`]).
pub fn fit_with_split(
    classes: &[String],
    feature_config: &FeatureConfig,
    spec: &ClassifierSpec,
    train: &Samples,
) -> Result<(Model, FitReport, FitSplit), ModelError> {
    feature_config.validate()?;
    // Paper7 from Paper20 rows: prune on this training set (so that in
    // cross-validation the selection never sees the test fold).
    let selected;
    let (feature_config, train) = if feature_config.set == FeatureSet::Paper7
        && train.dim == N_PAPER20
    {
        let sel =
            select_paper7(&train.x, &train.y, classes.len()).map_err(|e| ModelError::Mismatch {
                field: "feature_config.selection",
                reason: e.to_string(),
            })?;
        selected = (
            paper7_config(feature_config, sel.clone()),
            train.select_columns(&sel),
        );
        (&selected.0, &selected.1)
    } else {
        (feature_config, train)
    };
    if train.dim != feature_config.dim() {
        return Err(ModelError::Mismatch {
            field: "feature_config",
            reason: format!(
                "training rows have {} features, the config gives {}",
                train.dim,
                feature_config.dim()
            ),
        });
    }
    let k = classes.len();
    let st = Standardiser::fit(train);
    let z = st.transform(train);
    let (classifier, report, split) = match spec {
        ClassifierSpec::Mlp { lm, val_fraction } => {
            let (tr, va) = if *val_fraction > 0.0 {
                holdout_groups(&z.y, &z.group, k, *val_fraction, lm.seed)?
            } else {
                ((0..z.len()).collect(), Vec::new())
            };
            let t = z.subset(&tr);
            let v = z.subset(&va);
            let val = if v.is_empty() {
                None
            } else {
                Some((v.x.as_slice(), v.y.as_slice()))
            };
            let (net, rep) = train_lm(lm, k, z.dim, &t.x, &t.y, val)?;
            let split = FitSplit { train: tr, val: va };
            (Classifier::Mlp(net), FitReport::Mlp(rep), split)
        }
        ClassifierSpec::Svm { cfg, max_per_class } => {
            let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(
                cfg.seed ^ 0x5356_4D00,
            );
            let cap = max_per_class.saturating_mul(k);
            let rows = stratified_subsample(&z.y, k, cap, &mut rng);
            let t = z.subset(&rows);
            let (svm, rep) = Svm::train(cfg, k, z.dim, &t.x, &t.y)?;
            let split = FitSplit {
                train: (0..z.len()).collect(),
                val: Vec::new(),
            };
            (Classifier::Svm(svm), FitReport::Svm(rep), split)
        }
    };
    let meta = TrainingMeta {
        n_frames: train.len(),
        n_recordings: train.n_groups(),
        ..Default::default()
    };
    let model = Model::new(
        classes.to_vec(),
        feature_config.clone(),
        st,
        classifier,
        meta,
    )?;
    Ok((model, report, split))
}

/// What a fitted model does on the frames of its own fit: the figures of
/// the model that is written (cross-validation scores other models, fitted
/// without the test recordings), and whether the fit is worth writing
/// ([`FitCheck::problems`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FitCheck {
    /// The model on its training frames ([`FitSplit::train`]).
    pub train: Confusion,
    /// Recordings among the training frames.
    pub train_recordings: usize,
    /// The model on its validation frames; `None` when none were held out.
    pub val: Option<Confusion>,
    /// Recordings among the validation frames.
    pub val_recordings: usize,
    /// The most common class of the training frames (ties: the lower
    /// index) and its frame count: always answering it is right that
    /// often.
    pub majority: (usize, u64),
    /// An iterative trainer that returned its initial weights (LM: the
    /// report's epochs, stop and whether validation data drove it).
    pub kept_initial: Option<KeptInitial>,
}

/// An LM fit that returned its initial weights ([`LmReport::kept_initial_weights`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeptInitial {
    /// Epochs run.
    pub epochs: usize,
    /// Why it stopped.
    pub stop: crate::mlp::StopReason,
    /// Whether validation data drove early stopping (best epoch 0), or
    /// no step lowered the training error.
    pub validated: bool,
}

/// Why a fitted model is not worth writing ([`FitCheck::problems`]).
#[derive(Clone, Debug, PartialEq)]
pub enum PoorFit {
    /// The trainer never improved on its random initial weights: the model
    /// is the untrained initial network.
    KeptInitialWeights(KeptInitial),
    /// On its own training frames the model is right no more often than
    /// always answering the most common class.
    NoBetterThanMajority {
        /// Training frames classified right.
        correct: u64,
        /// Training frames.
        frames: u64,
        /// The most common class.
        class: String,
        /// Its training frames.
        majority: u64,
    },
}

impl core::fmt::Display for PoorFit {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let pct = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
        match self {
            Self::KeptInitialWeights(k) if k.validated => write!(
                f,
                "the final fit never improved on its random initial weights: no Levenberg-Marquardt epoch lowered the validation error (best epoch 0 of {}, stopped at {}), so the model is the untrained initial network",
                k.epochs, k.stop
            ),
            Self::KeptInitialWeights(k) if k.epochs == 0 => write!(
                f,
                "the final fit ran no Levenberg-Marquardt epoch (the epoch limit is 0), so the model is the untrained initial network"
            ),
            Self::KeptInitialWeights(k) => write!(
                f,
                "the final fit never improved on its random initial weights: no Levenberg-Marquardt step lowered the training error in {} epoch(s) (stopped at {}), so the model is the untrained initial network",
                k.epochs, k.stop
            ),
            Self::NoBetterThanMajority {
                correct,
                frames,
                class,
                majority,
            } => write!(
                f,
                "on its own training frames the model is right {correct} of {frames} times ({:.1} %), no better than always answering `{class}`, the most common class ({majority} of {frames}, {:.1} %)",
                pct(*correct, *frames),
                pct(*majority, *frames)
            ),
        }
    }
}

impl FitCheck {
    /// Scores `model` (fitted by [`fit_with_split`] on `data`, which gave
    /// `report` and `split`) on its training and validation frames. An
    /// index of `split` outside `data`, or no training frame, is an error.
    pub fn new(
        model: &Model,
        report: &FitReport,
        data: &Samples,
        split: &FitSplit,
    ) -> Result<Self, ModelError> {
        let n = data.len();
        if let Some(&i) = split.train.iter().chain(&split.val).find(|&&i| i >= n) {
            return Err(ModelError::Mismatch {
                field: "split",
                reason: format!("frame {i} of a split of {n} frames"),
            });
        }
        if split.train.is_empty() {
            return Err(ModelError::Mismatch {
                field: "split",
                reason: "no training frame".into(),
            });
        }
        let tr = data.subset(&split.train);
        let train = model.evaluate(&tr)?;
        let (val, val_recordings) = if split.val.is_empty() {
            (None, 0)
        } else {
            let va = data.subset(&split.val);
            (Some(model.evaluate(&va)?), va.n_groups())
        };
        let mut counts = vec![0u64; model.classes().len()];
        for &c in &tr.y {
            if let Some(n) = counts.get_mut(c) {
                *n += 1;
            }
        }
        let mut majority = (0, 0);
        for (c, &k) in counts.iter().enumerate() {
            if k > majority.1 {
                majority = (c, k);
            }
        }
        let kept_initial = match report {
            FitReport::Mlp(r) if r.kept_initial_weights() => Some(KeptInitial {
                epochs: r.epochs,
                stop: r.stop,
                validated: !r.val_mse.is_empty(),
            }),
            _ => None,
        };
        Ok(Self {
            train,
            train_recordings: tr.n_groups(),
            val,
            val_recordings,
            majority,
            kept_initial,
        })
    }

    /// Training frames the model classifies right.
    pub fn train_correct(&self) -> u64 {
        (0..self.train.classes().len())
            .map(|c| self.train.get(c, c))
            .sum()
    }

    /// Why the model is not worth writing; empty when it is: the trainer
    /// kept its initial weights, or on its training frames the model is
    /// right no more often than always answering the most common class.
    pub fn problems(&self) -> Vec<PoorFit> {
        let mut out = Vec::new();
        if let Some(k) = self.kept_initial {
            out.push(PoorFit::KeptInitialWeights(k));
        }
        let correct = self.train_correct();
        if correct <= self.majority.1 {
            out.push(PoorFit::NoBetterThanMajority {
                correct,
                frames: self.train.total(),
                class: self.train.classes()[self.majority.0].clone(),
                majority: self.majority.1,
            });
        }
        out
    }
}

/// k-fold cross-validation split by recording: fits on each training side,
/// scores the held-out recordings, and sums the confusion matrices.
pub fn cross_validate(
    classes: &[String],
    feature_config: &FeatureConfig,
    spec: &ClassifierSpec,
    data: &Samples,
    folds: usize,
    seed: u64,
) -> Result<Confusion, ModelError> {
    cross_validate_with(classes, feature_config, spec, data, folds, seed, |_, _| {})
}

/// [`cross_validate`], calling `done(k, folds)` after the k-th fold (for a
/// progress bar: a fold fits a whole model).
pub fn cross_validate_with(
    classes: &[String],
    feature_config: &FeatureConfig,
    spec: &ClassifierSpec,
    data: &Samples,
    folds: usize,
    seed: u64,
    mut done: impl FnMut(usize, usize),
) -> Result<Confusion, ModelError> {
    let split = stratified_group_kfold(&data.y, &data.group, classes.len(), folds, seed)?;
    let mut total = Confusion::new(classes.to_vec());
    for (k, f) in split.iter().enumerate() {
        let (model, _) = fit(classes, feature_config, spec, &data.subset(&f.train))?;
        total.merge(&model.evaluate(&data.subset(&f.test))?);
        done(k + 1, split.len());
    }
    Ok(total)
}

/// One point of an SVM grid search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridPoint {
    /// C.
    pub c: f64,
    /// γ.
    pub gamma: f64,
    /// CV scores.
    pub metrics: Metrics,
}

/// Grid search of the SVM's C and γ by cross-validation split by recording;
/// the best macro-F1 wins (ties: the earlier grid point, i.e. smaller C,
/// then smaller γ when the grids are ascending). Returns the winning config
/// and every point.
pub fn grid_search_svm(
    classes: &[String],
    feature_config: &FeatureConfig,
    base: &SvmConfig,
    max_per_class: usize,
    cs: &[f64],
    gammas: &[f64],
    data: &Samples,
    folds: usize,
    seed: u64,
    mut progress: impl FnMut(&GridPoint),
) -> Result<(SvmConfig, Vec<GridPoint>), ModelError> {
    let mut points = Vec::new();
    let mut best: Option<(f64, SvmConfig)> = None;
    for &c in cs {
        for &gamma in gammas {
            let cfg = SvmConfig {
                c,
                kernel: Kernel::Rbf { gamma },
                ..base.clone()
            };
            let spec = ClassifierSpec::Svm {
                cfg: cfg.clone(),
                max_per_class,
            };
            let conf = cross_validate(classes, feature_config, &spec, data, folds, seed)?;
            let metrics = conf.metrics();
            let score = metrics.macro_f1;
            let p = GridPoint { c, gamma, metrics };
            progress(&p);
            points.push(p);
            if best.as_ref().is_none_or(|(s, _)| score > *s) {
                best = Some((score, cfg));
            }
        }
    }
    let (_, cfg) = best.ok_or(ModelError::Mismatch {
        field: "grid",
        reason: "empty C or gamma grid".into(),
    })?;
    Ok((cfg, points))
}
