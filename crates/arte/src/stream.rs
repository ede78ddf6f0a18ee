//! The streaming estimator: audio blocks of any size in, one decision per hop out.
//!
//! A ring buffer holds the last frame (`FeatureConfig::frame_s`, 0.1 s). Once
//! it is full, every `hop_s` (default 0.025 s) of new audio the frame is
//! unrolled into a scratch buffer, its features extracted, the classifier
//! gives per-class probabilities, and a temporal filter smooths them.
//!
//! **Smoothing: an HMM forward filter with a sticky transition matrix.** The
//! road is the hidden state; it stays with probability `stay` per hop and
//! jumps to any other road with (1 − stay)/(K − 1). Each hop:
//!
//! ```text
//! predict:  p̃_j = stay · p_j + (1 − stay)/(K − 1) · (1 − p_j)
//! update:   p_j ∝ p̃_j · max(q_j, floor)        (q: the classifier's frame posterior)
//! ```
//!
//! Why this and not exponential smoothing: with calibrated posteriors it is
//! the Bayes-optimal filter for a piecewise-constant road, its delay is
//! bounded by design (a change needs the evidence of about
//! ln((K−1)·stay/(1−stay)) / ln(q_new/q_old) frames, one or two hops for a
//! confident classifier), and a single wrong frame of moderate confidence
//! cannot flip it, while exponential smoothing of probabilities trades delay
//! against stability with one constant and lags every change by several
//! time constants. The `floor` bounds how much one overconfident frame can
//! veto a state, so the filter can always recover within a few hops.
//!
//! **Calibration.** The filter's posterior of the decided road is
//! overconfident (overlapping frames are not independent evidence). If the
//! classifier carries a confidence calibration ([`Classify::calibration`];
//! a model file of format v2 does, see [`crate::calib`]), each decision's
//! reported probabilities are calibrated: the decided road gets
//! `c = map(p)`, the other roads share `1 − c` in proportion to their
//! posteriors. The filter itself runs on the uncalibrated posterior (so the
//! decisions, their class and timing, do not change), which the decision
//! also carries (`posterior`). Without calibration the reported
//! probabilities are the posterior itself.
//!
//! Time stamps: samples are counted from the first sample pushed; a decision's
//! frame spans [t_end − frame_s, t_end], and t_end is also the moment the
//! decision becomes available (the hop boundary).
//!
//! `push` allocates nothing (proved by `tests/stream_no_alloc.rs`).

use crate::features::{FeatureConfig, FeatureError, FeatureExtractor};
use serde::{Deserialize, Serialize};

/// A classifier as the streaming estimator needs it.
///
/// Implemented for [`crate::model::Predictor`]; tests implement it for toy
/// classifiers.
pub trait Classify {
    /// Number of classes (length of the probability vector).
    fn n_classes(&self) -> usize;
    /// Length of the feature vector it expects.
    fn n_features(&self) -> usize;
    /// Class probabilities of one feature vector into `out` (length
    /// `n_classes`, summing to 1). Must not allocate.
    fn predict_proba(&mut self, x: &[f64], out: &mut [f64]);
    /// The confidence calibration of the smoothed decisions, if any (see
    /// the module docs); none by default.
    fn calibration(&self) -> Option<&crate::calib::StreamCalibration> {
        None
    }
}

impl Classify for crate::model::Predictor {
    fn n_classes(&self) -> usize {
        self.model().classes().len()
    }
    fn n_features(&self) -> usize {
        self.model().dim()
    }
    fn predict_proba(&mut self, x: &[f64], out: &mut [f64]) {
        // Lengths are checked when the estimator is built and features are
        // always finite, so this cannot fail; if it ever did, the frame
        // carries no information (uniform), which the filter tolerates.
        if crate::model::Predictor::predict_proba(self, x, out).is_err() {
            let k = out.len().max(1) as f64;
            out.fill(1.0 / k);
        }
    }
    fn calibration(&self) -> Option<&crate::calib::StreamCalibration> {
        self.model().calibration()
    }
}

/// Temporal smoothing of the frame posteriors.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Smoothing {
    /// Each decision is the frame's own posterior.
    None,
    /// HMM forward filter (see the module docs).
    Hmm {
        /// Probability of staying on the same road from one hop to the next.
        stay: f64,
        /// Lower bound on a frame's class probability used as likelihood.
        floor: f64,
    },
}

/// Streaming estimator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamConfig {
    /// Time between decisions (s). Rounded to whole samples.
    pub hop_s: f64,
    /// Temporal smoothing.
    pub smoothing: Smoothing,
}

impl Default for StreamConfig {
    /// Hop 0.025 s, HMM with stay 0.9 and floor 0.01 (chosen on a road-change
    /// validation set, crate README "Streaming estimator on road-change
    /// recordings").
    fn default() -> Self {
        Self {
            hop_s: 0.025,
            smoothing: Smoothing::Hmm {
                stay: 0.9,
                floor: 0.01,
            },
        }
    }
}

/// Errors building a streaming estimator.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StreamError {
    /// Feature config invalid.
    #[error(transparent)]
    Features(#[from] FeatureError),
    /// A stream config field is out of range.
    #[error("stream config: field `{field}`: {reason}")]
    InvalidConfig {
        /// Field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// Classifier and features disagree.
    #[error("classifier expects {expected} features, the feature config gives {got}")]
    FeatureCount {
        /// Classifier's.
        expected: usize,
        /// Feature config's.
        got: usize,
    },
}

/// One decision.
#[derive(Debug)]
pub struct Decision<'a> {
    /// 0, 1, 2, … per decision.
    pub seq: u64,
    /// Start of the analysed frame (s since the first sample).
    pub t_start: f64,
    /// End of the analysed frame (s); the decision is available at this time.
    pub t_end: f64,
    /// Most probable class after smoothing (ties: lower index).
    pub class: usize,
    /// What the controller is given: the smoothed class probabilities,
    /// calibrated if the classifier carries a calibration (then
    /// `probs[class]` is the calibrated confidence and the other roads
    /// share the rest in proportion to their posteriors).
    pub probs: &'a [f64],
    /// `probs[class]`: the confidence of the decision.
    pub confidence: f64,
    /// The smoothing filter's own posterior (before calibration; equal to
    /// `probs` without calibration).
    pub posterior: &'a [f64],
    /// Most probable class of this frame alone.
    pub raw_class: usize,
    /// The classifier's probabilities for this frame alone.
    pub raw: &'a [f64],
}

/// Blocks in, decisions out. See the module docs.
pub struct StreamEstimator<C> {
    classifier: C,
    extractor: FeatureExtractor,
    cfg: StreamConfig,
    fs: f64,
    frame_len: usize,
    hop: usize,
    ring: Vec<f32>,
    pos: usize,
    filled: usize,
    since: usize,
    total: u64,
    seq: u64,
    frame: Vec<f32>,
    features: Vec<f64>,
    raw: Vec<f64>,
    post: Vec<f64>,
    out: Vec<f64>,
    started: bool,
}

impl<C> std::fmt::Debug for StreamEstimator<C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamEstimator")
            .field("cfg", &self.cfg)
            .field("seq", &self.seq)
            .finish_non_exhaustive()
    }
}

fn argmax(p: &[f64]) -> usize {
    let mut best = 0;
    for (i, &v) in p.iter().enumerate() {
        if v > p[best] {
            best = i;
        }
    }
    best
}

impl<C: Classify> StreamEstimator<C> {
    /// Builds the extractor and all buffers; checks that the classifier
    /// takes the feature vector the config produces.
    pub fn new(
        classifier: C,
        features: &FeatureConfig,
        cfg: &StreamConfig,
    ) -> Result<Self, StreamError> {
        let extractor = FeatureExtractor::new(features)?;
        if classifier.n_features() != extractor.dim() {
            return Err(StreamError::FeatureCount {
                expected: classifier.n_features(),
                got: extractor.dim(),
            });
        }
        let k = classifier.n_classes();
        if k == 0 {
            return Err(StreamError::InvalidConfig {
                field: "classifier",
                reason: "has no classes".into(),
            });
        }
        let fs = f64::from(features.sample_rate);
        let hop = (cfg.hop_s * fs).round();
        if !(cfg.hop_s > 0.0 && cfg.hop_s <= 10.0 && hop >= 1.0) {
            return Err(StreamError::InvalidConfig {
                field: "hop_s",
                reason: format!("{} s is not in (0, 10] or below one sample", cfg.hop_s),
            });
        }
        if let Smoothing::Hmm { stay, floor } = cfg.smoothing {
            if !(stay > 0.0 && stay < 1.0) {
                return Err(StreamError::InvalidConfig {
                    field: "smoothing.stay",
                    reason: format!("{stay} is not in (0, 1)"),
                });
            }
            if !(floor > 0.0 && floor <= 1.0) {
                return Err(StreamError::InvalidConfig {
                    field: "smoothing.floor",
                    reason: format!("{floor} is not in (0, 1]"),
                });
            }
        }
        let frame_len = extractor.frame_len();
        let dim = extractor.dim();
        Ok(Self {
            classifier,
            extractor,
            cfg: cfg.clone(),
            fs,
            frame_len,
            hop: hop as usize,
            ring: vec![0.0; frame_len],
            pos: 0,
            filled: 0,
            since: 0,
            total: 0,
            seq: 0,
            frame: vec![0.0; frame_len],
            features: vec![0.0; dim],
            raw: vec![1.0 / k as f64; k],
            post: vec![1.0 / k as f64; k],
            out: vec![1.0 / k as f64; k],
            started: false,
        })
    }

    /// Hop in samples.
    pub fn hop_len(&self) -> usize {
        self.hop
    }

    /// Frame in samples.
    pub fn frame_len(&self) -> usize {
        self.frame_len
    }

    /// The classifier.
    pub fn classifier(&self) -> &C {
        &self.classifier
    }

    /// Sets the vehicle speed (m/s) for the frames that complete from now
    /// on, for a speed-normalised model ([`crate::features::SpeedNorm`]);
    /// `None` when unknown (frames are then taken as heard at the model's
    /// reference speed). Ignored by models without speed normalisation.
    /// Allocates nothing.
    pub fn set_speed(&mut self, speed_mps: Option<f64>) {
        self.extractor.set_speed(speed_mps);
    }

    /// The classifier's confidence calibration, if any.
    pub fn calibration(&self) -> Option<&crate::calib::StreamCalibration> {
        self.classifier.calibration()
    }

    /// Whether the classifier's calibration was fitted with other stream
    /// settings (hop, smoothing) than this estimator's: its confidence is
    /// then not calibrated for them. `false` without calibration.
    pub fn calibration_mismatch(&self) -> bool {
        self.classifier
            .calibration()
            .is_some_and(|c| c.stream != self.cfg)
    }

    /// Whether the features depend on the vehicle speed ([`Self::set_speed`]).
    pub fn speed_normalised(&self) -> bool {
        self.extractor.config().speed_norm.is_some()
    }

    /// Forgets all audio and the filter state; the next sample is t = 0.
    pub fn reset(&mut self) {
        let k = self.post.len() as f64;
        self.pos = 0;
        self.filled = 0;
        self.since = 0;
        self.total = 0;
        self.seq = 0;
        self.started = false;
        self.ring.fill(0.0);
        self.post.fill(1.0 / k);
    }

    /// Consumes a block of samples (any length); calls `on_decision` for
    /// every decision that falls due inside it, in order. Returns the number
    /// of decisions. Allocates nothing.
    pub fn push(&mut self, block: &[f32], mut on_decision: impl FnMut(&Decision<'_>)) -> usize {
        let mut emitted = 0;
        let mut rest = block;
        while !rest.is_empty() {
            // Copy up to the next decision point.
            let until = if self.filled < self.frame_len {
                self.frame_len - self.filled
            } else {
                self.hop - self.since
            };
            let n = until.min(rest.len());
            for &s in &rest[..n] {
                self.ring[self.pos] = s;
                self.pos += 1;
                if self.pos == self.frame_len {
                    self.pos = 0;
                }
            }
            rest = &rest[n..];
            self.total += n as u64;
            if self.filled < self.frame_len {
                self.filled += n;
            } else {
                self.since += n;
            }
            let due = if self.filled == self.frame_len && !self.started {
                self.started = true;
                true
            } else {
                self.started && self.since == self.hop
            };
            if due {
                self.since = 0;
                self.decide(&mut on_decision);
                emitted += 1;
            }
        }
        emitted
    }

    fn decide(&mut self, on_decision: &mut impl FnMut(&Decision<'_>)) {
        // Unroll the ring: oldest sample first.
        let (a, b) = self.ring.split_at(self.pos);
        self.frame[..b.len()].copy_from_slice(b);
        self.frame[b.len()..].copy_from_slice(a);
        if self
            .extractor
            .extract(&self.frame, &mut self.features)
            .is_err()
        {
            // Lengths are fixed at construction, so this cannot happen.
            self.features.fill(0.0);
        }
        self.classifier.predict_proba(&self.features, &mut self.raw);
        let k = self.post.len();
        match self.cfg.smoothing {
            Smoothing::None => {
                // a classifier's NaN, infinite or all-zero output says
                // nothing: no road preferred (the HMM below floors it)
                let sum: f64 = self.raw.iter().sum();
                if sum > 0.0 && self.raw.iter().all(|p| p.is_finite()) {
                    self.post.copy_from_slice(&self.raw);
                } else {
                    self.post.fill(1.0 / k as f64);
                }
            }
            Smoothing::Hmm { stay, floor } => {
                let off = if k > 1 {
                    (1.0 - stay) / (k - 1) as f64
                } else {
                    0.0
                };
                let mut sum = 0.0;
                for j in 0..k {
                    let pred = if k > 1 {
                        stay * self.post[j] + off * (1.0 - self.post[j])
                    } else {
                        1.0
                    };
                    let q = if self.raw[j].is_finite() {
                        self.raw[j].max(floor)
                    } else {
                        floor
                    };
                    self.post[j] = pred * q;
                    sum += self.post[j];
                }
                if sum > 0.0 && sum.is_finite() {
                    for p in self.post.iter_mut() {
                        *p /= sum;
                    }
                } else {
                    self.post.fill(1.0 / k as f64);
                }
            }
        }
        let class = argmax(&self.post);
        let p = self.post[class];
        let confidence = match self.classifier.calibration() {
            None => {
                self.out.copy_from_slice(&self.post);
                p
            }
            Some(cal) => {
                let c = cal.map.apply(p);
                let rest = 1.0 - p;
                let others = (k - 1).max(1) as f64;
                for (j, (o, &q)) in self.out.iter_mut().zip(&self.post).enumerate() {
                    *o = if j == class {
                        c
                    } else if rest > 0.0 {
                        q * (1.0 - c) / rest
                    } else {
                        (1.0 - c) / others
                    };
                }
                c
            }
        };
        let t_end = self.total as f64 / self.fs;
        let d = Decision {
            seq: self.seq,
            t_start: t_end - self.frame_len as f64 / self.fs,
            t_end,
            class,
            probs: &self.out,
            confidence,
            posterior: &self.post,
            raw_class: argmax(&self.raw),
            raw: &self.raw,
        };
        on_decision(&d);
        self.seq += 1;
    }
}

/// Detection delays of abrupt road changes.
///
/// `decisions`: (t_end, class) in time order. `changes`: (t_change, new
/// class) in time order; a change's road holds until the next change (or
/// `end`). A change is detected at the first decision with t_end ≥ t_change
/// whose class is the new road and stays the new road for every decision
/// with t_end in [t, t + `hold_s`] (and before the next change). The delay
/// is t_end − t_change; `None` marks a change never detected before the next.
pub fn detection_delays(
    decisions: &[(f64, usize)],
    changes: &[(f64, usize)],
    end: f64,
    hold_s: f64,
) -> Vec<Option<f64>> {
    changes
        .iter()
        .enumerate()
        .map(|(i, &(tc, road))| {
            let t_next = changes.get(i + 1).map_or(end, |c| c.0);
            let window: Vec<&(f64, usize)> = decisions
                .iter()
                .filter(|d| d.0 >= tc && d.0 < t_next)
                .collect();
            for (j, d) in window.iter().enumerate() {
                if d.1 != road {
                    continue;
                }
                let holds = window[j..]
                    .iter()
                    .take_while(|e| e.0 <= d.0 + hold_s)
                    .all(|e| e.1 == road);
                if holds {
                    return Some(d.0 - tc);
                }
            }
            None
        })
        .collect()
}

/// The p-th percentile (0..=100) of `v` by linear interpolation between
/// order statistics; `None` for an empty slice.
pub fn percentile(v: &[f64], p: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mut s: Vec<f64> = v.to_vec();
    s.sort_by(f64::total_cmp);
    let r = (p.clamp(0.0, 100.0) / 100.0) * (s.len() - 1) as f64;
    let lo = r.floor() as usize;
    let hi = r.ceil() as usize;
    if s[lo] == s[hi] {
        // Also keeps ∞ (a missed change) from turning into NaN (∞ − ∞).
        return Some(s[lo]);
    }
    Some(s[lo] + (s[hi] - s[lo]) * (r - lo as f64))
}
