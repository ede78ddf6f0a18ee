//! Multi-layer perceptron trained by Levenberg-Marquardt (paper §II.D).
//!
//! The network: `n_in` inputs, any number of hidden layers of tanh units,
//! and one output per class, either softmax (default) or logistic. Targets
//! are one-hot. Training minimises the sum of squared errors
//! `SSE = sum_n sum_k (y_nk - t_nk)^2` with the Levenberg-Marquardt step
//! `dw = -(J^T J + mu I)^-1 J^T e`, where `J = d y / d w` is computed
//! analytically (one back-propagation per output, per sample).
//!
//! What it mirrors: the paper trained its [4, 3, 2] network with MATLAB's
//! `trainlm`. The defaults of [`LmConfig`] are `trainlm`'s: `mu = 0.001`,
//! `mu_dec = 0.1`, `mu_inc = 10`, `mu_max = 1e10`, 1000 epochs at most,
//! performance goal 0, minimum gradient 1e-7, and early stop after 6
//! consecutive validation failures (the best-validation weights are
//! returned, as MATLAB does). Like `trainlm`, the damping term is `mu I`
//! (Levenberg), not `mu diag(J^T J)`. Weights are initialised by
//! Nguyen-Widrow (MATLAB's `initnw`) for the tanh layers and seeded uniform
//! `[-0.5, 0.5]` for the output layer; the RNG is ChaCha8 from `seed`, so a
//! run is bit-for-bit reproducible.
//!
//! Memory: the Jacobian is never stored whole. `J^T J` (`W x W`) and `J^T e`
//! are accumulated over chunks of [`JAC_CHUNK`] samples, so memory is
//! `O(W^2 + JAC_CHUNK * n_out * W)` whatever the dataset size. Time per
//! epoch is `O(N * n_out * W^2)`; [`LmConfig::max_rows`] caps `N` by a
//! seeded, class-stratified subsample chosen once before training.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng, seq::SliceRandom};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Samples per Jacobian chunk when accumulating `J^T J`.
pub const JAC_CHUNK: usize = 64;

/// Output non-linearity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputKind {
    /// Softmax over all outputs: outputs sum to 1.
    Softmax,
    /// Independent logistic units; probabilities are the outputs normalised to sum 1.
    Logistic,
}

/// Errors of MLP construction and training.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MlpError {
    /// A layer has no units.
    #[error("layer {layer} has 0 units; every layer needs at least one")]
    EmptyLayer {
        /// Index in `sizes` (0 = input).
        layer: usize,
    },
    /// The network needs an input and an output layer.
    #[error("an MLP needs at least an input and an output layer, got {0} layer sizes")]
    TooFewLayers(usize),
    /// Flat sample buffer length is not a multiple of the dimension.
    #[error("sample buffer has {len} values, not a multiple of the input dimension {dim}")]
    BadShape {
        /// Buffer length.
        len: usize,
        /// Input dimension.
        dim: usize,
    },
    /// Labels and samples differ in count.
    #[error("{samples} samples but {labels} labels")]
    LabelCount {
        /// Number of samples.
        samples: usize,
        /// Number of labels.
        labels: usize,
    },
    /// A label is not a valid class index.
    #[error("label {label} at sample {index} is not below the class count {n_classes}")]
    BadLabel {
        /// Sample index.
        index: usize,
        /// The label.
        label: usize,
        /// Number of classes.
        n_classes: usize,
    },
    /// A feature value is NaN or infinite.
    #[error("feature {feature} of sample {index} is not finite ({value})")]
    NotFinite {
        /// Sample index.
        index: usize,
        /// Feature index.
        feature: usize,
        /// The value.
        value: f64,
    },
    /// No training samples.
    #[error("no training samples")]
    Empty,
    /// Weight vector length does not match the architecture.
    #[error("{got} weights given, the architecture {sizes:?} needs {expected}")]
    WeightCount {
        /// Layer sizes.
        sizes: Vec<usize>,
        /// Expected count.
        expected: usize,
        /// Given count.
        got: usize,
    },
    /// The architecture's weight count does not fit a `usize`.
    #[error("the architecture {sizes:?} needs more weights than can be counted")]
    TooManyWeights {
        /// Layer sizes.
        sizes: Vec<usize>,
    },
    /// A weight is NaN or infinite.
    #[error("weight {0} is not finite")]
    WeightNotFinite(usize),
    /// Too many weights for Levenberg-Marquardt, whose step solves a
    /// weights × weights system ([`LM_MAX_WEIGHTS`]).
    #[error(
        "the network {sizes:?} (input, hidden layers, output) has {weights} weights; Levenberg-Marquardt training solves a {weights} x {weights} system ({:.1} GiB), so at most {LM_MAX_WEIGHTS} weights: fewer or smaller hidden layers (the paper's 4,3,2 has under a hundred)",
        lm_gib(*.weights)
    )]
    TooManyForLm {
        /// Layer sizes.
        sizes: Vec<usize>,
        /// Their weight count.
        weights: usize,
    },
}

/// The most weights [`train_lm`] trains: its step solves a weights ×
/// weights system (5000: 0.19 GiB; a 256,256 network on 20 features has
/// 72 000, 39 GiB, and aborted the process).
pub const LM_MAX_WEIGHTS: usize = 5000;

/// The size of Levenberg-Marquardt's system for `weights` weights, GiB.
fn lm_gib(weights: usize) -> f64 {
    (weights as f64) * (weights as f64) * 8.0 / f64::from(1u32 << 30)
}

/// A feed-forward network: tanh hidden layers, softmax or logistic outputs.
///
/// Weight layout: layer by layer; in a layer of `n_out` units fed by `n_in`
/// values, unit `j` owns `n_in` weights followed by its bias, i.e. weight
/// `(j, i)` is at `offset + j * (n_in + 1) + i` and the bias at
/// `offset + j * (n_in + 1) + n_in`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    sizes: Vec<usize>,
    output: OutputKind,
    weights: Vec<f64>,
}

/// Pre-sized buffers for allocation-free forward passes.
#[derive(Clone, Debug)]
pub struct MlpScratch {
    /// Activations per layer, `acts[0]` = input copy, last = outputs.
    acts: Vec<Vec<f64>>,
    /// Back-propagated deltas per non-input layer.
    deltas: Vec<Vec<f64>>,
}

/// The weight count of `sizes`; `None` if it does not fit a `usize` (a
/// crafted model file).
fn n_weights_for(sizes: &[usize]) -> Option<usize> {
    sizes.windows(2).try_fold(0usize, |n, w| {
        w[0].checked_add(1)?.checked_mul(w[1])?.checked_add(n)
    })
}

/// The layer sizes `[dim, hidden..., n_classes]` of the network
/// [`train_lm`] would fit, or its refusal: more than [`LM_MAX_WEIGHTS`]
/// weights ([`MlpError::TooManyForLm`]), or a count that does not fit a
/// `usize`. For a caller that checks before the features are extracted
/// (`grip train --hidden`), with the fit's own words.
pub fn check_lm_size(
    dim: usize,
    hidden: &[usize],
    n_classes: usize,
) -> Result<Vec<usize>, MlpError> {
    let sizes: Vec<usize> = std::iter::once(dim)
        .chain(hidden.iter().copied())
        .chain(std::iter::once(n_classes))
        .collect();
    match n_weights_for(&sizes) {
        Some(w) if w <= LM_MAX_WEIGHTS => Ok(sizes),
        Some(weights) => Err(MlpError::TooManyForLm { sizes, weights }),
        None => Err(MlpError::TooManyWeights { sizes }),
    }
}

impl Mlp {
    /// Build from layer sizes `[n_in, h1, ..., n_out]` and a weight vector.
    pub fn from_weights(
        sizes: Vec<usize>,
        output: OutputKind,
        weights: Vec<f64>,
    ) -> Result<Self, MlpError> {
        if sizes.len() < 2 {
            return Err(MlpError::TooFewLayers(sizes.len()));
        }
        if let Some(layer) = sizes.iter().position(|&s| s == 0) {
            return Err(MlpError::EmptyLayer { layer });
        }
        let Some(expected) = n_weights_for(&sizes) else {
            return Err(MlpError::TooManyWeights { sizes });
        };
        if weights.len() != expected {
            return Err(MlpError::WeightCount {
                sizes,
                expected,
                got: weights.len(),
            });
        }
        if let Some(i) = weights.iter().position(|w| !w.is_finite()) {
            return Err(MlpError::WeightNotFinite(i));
        }
        Ok(Self {
            sizes,
            output,
            weights,
        })
    }

    /// Nguyen-Widrow initialisation (tanh layers) from a seeded RNG; the
    /// output layer is uniform in `[-0.5, 0.5]`.
    pub fn init(
        n_in: usize,
        hidden: &[usize],
        n_out: usize,
        output: OutputKind,
        seed: u64,
    ) -> Result<Self, MlpError> {
        let mut sizes = Vec::with_capacity(hidden.len() + 2);
        sizes.push(n_in);
        sizes.extend_from_slice(hidden);
        sizes.push(n_out);
        let n = n_weights_for(&sizes).ok_or_else(|| MlpError::TooManyWeights {
            sizes: sizes.clone(),
        })?;
        let zeros = vec![0.0; n];
        let mut net = Self::from_weights(sizes, output, zeros)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n_layers = net.sizes.len() - 1;
        let mut off = 0;
        for l in 0..n_layers {
            let (fan_in, units) = (net.sizes[l], net.sizes[l + 1]);
            let stride = fan_in + 1;
            if l + 1 < n_layers {
                // Nguyen & Widrow (1990): random directions scaled to norm
                // beta = 0.7 H^(1/n), biases uniform in [-beta, beta].
                let beta = 0.7 * (units as f64).powf(1.0 / fan_in as f64);
                for j in 0..units {
                    let w = &mut net.weights[off + j * stride..off + (j + 1) * stride];
                    for v in w[..fan_in].iter_mut() {
                        *v = rng.random_range(-0.5..0.5);
                    }
                    let norm = w[..fan_in]
                        .iter()
                        .map(|v| v * v)
                        .sum::<f64>()
                        .sqrt()
                        .max(1e-12);
                    for v in w[..fan_in].iter_mut() {
                        *v *= beta / norm;
                    }
                    w[fan_in] = rng.random_range(-beta..beta);
                }
            } else {
                for v in net.weights[off..off + units * stride].iter_mut() {
                    *v = rng.random_range(-0.5..0.5);
                }
            }
            off += units * stride;
        }
        Ok(net)
    }

    /// Layer sizes `[n_in, h1, ..., n_out]`.
    pub fn sizes(&self) -> &[usize] {
        &self.sizes
    }
    /// Input dimension.
    pub fn n_in(&self) -> usize {
        self.sizes[0]
    }
    /// Output count (classes).
    pub fn n_out(&self) -> usize {
        self.sizes[self.sizes.len() - 1]
    }
    /// Output non-linearity.
    pub fn output_kind(&self) -> OutputKind {
        self.output
    }
    /// The flat weight vector (layout in the type docs).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
    /// Number of weights and biases.
    pub fn n_weights(&self) -> usize {
        self.weights.len()
    }

    /// Buffers sized for this network.
    pub fn scratch(&self) -> MlpScratch {
        MlpScratch {
            acts: self.sizes.iter().map(|&s| vec![0.0; s]).collect(),
            deltas: self.sizes[1..].iter().map(|&s| vec![0.0; s]).collect(),
        }
    }

    fn forward_with(weights: &[f64], sizes: &[usize], output: OutputKind, s: &mut MlpScratch) {
        let n_layers = sizes.len() - 1;
        let mut off = 0;
        for l in 0..n_layers {
            let (fan_in, units) = (sizes[l], sizes[l + 1]);
            let stride = fan_in + 1;
            let (lo, hi) = s.acts.split_at_mut(l + 1);
            let input = &lo[l];
            let out = &mut hi[0];
            for j in 0..units {
                let w = &weights[off + j * stride..off + (j + 1) * stride];
                let mut z = w[fan_in];
                for i in 0..fan_in {
                    z += w[i] * input[i];
                }
                out[j] = z;
            }
            if l + 1 < n_layers {
                for v in out.iter_mut() {
                    *v = v.tanh();
                }
            } else {
                match output {
                    OutputKind::Softmax => {
                        let m = out.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        let mut sum = 0.0;
                        for v in out.iter_mut() {
                            *v = (*v - m).exp();
                            sum += *v;
                        }
                        for v in out.iter_mut() {
                            *v /= sum;
                        }
                    }
                    OutputKind::Logistic => {
                        for v in out.iter_mut() {
                            *v = 1.0 / (1.0 + (-*v).exp());
                        }
                    }
                }
            }
            off += units * stride;
        }
    }

    /// Raw network outputs for `x` into `out` (length `n_out`). No allocation.
    ///
    /// Panics if `x.len() != n_in` or `out.len() != n_out` (a programming
    /// error: callers size buffers from the model).
    pub fn forward(&self, x: &[f64], s: &mut MlpScratch, out: &mut [f64]) {
        s.acts[0].copy_from_slice(x);
        Self::forward_with(&self.weights, &self.sizes, self.output, s);
        out.copy_from_slice(&s.acts[self.sizes.len() - 1]);
    }

    /// Class probabilities: softmax outputs as they are, logistic outputs
    /// normalised to sum 1. No allocation.
    pub fn predict_proba(&self, x: &[f64], s: &mut MlpScratch, out: &mut [f64]) {
        self.forward(x, s, out);
        if self.output == OutputKind::Logistic {
            let sum: f64 = out.iter().sum();
            if sum > 0.0 {
                for v in out.iter_mut() {
                    *v /= sum;
                }
            } else {
                let u = 1.0 / out.len() as f64;
                out.fill(u);
            }
        }
    }

    /// Jacobian of the outputs w.r.t. the weights at `x`: `jac` is
    /// `n_out x n_weights`, row-major (`jac[k * W + w] = d y_k / d w`).
    /// Also leaves the outputs in `y`. Analytic: one backward pass per output.
    pub fn output_jacobian(&self, x: &[f64], s: &mut MlpScratch, y: &mut [f64], jac: &mut [f64]) {
        s.acts[0].copy_from_slice(x);
        Self::forward_with(&self.weights, &self.sizes, self.output, s);
        let n_out = self.n_out();
        let w = self.n_weights();
        y.copy_from_slice(&s.acts[self.sizes.len() - 1]);
        for k in 0..n_out {
            self.backprop_output(k, s, &mut jac[k * w..(k + 1) * w]);
        }
    }

    /// d y_k / d w into `row` (length W), from the activations in `s`.
    fn backprop_output(&self, k: usize, s: &mut MlpScratch, row: &mut [f64]) {
        let n_layers = self.sizes.len() - 1;
        let yl = &s.acts[n_layers];
        // Output layer delta: d y_k / d z_j.
        {
            let d = &mut s.deltas[n_layers - 1];
            match self.output {
                OutputKind::Softmax => {
                    for j in 0..d.len() {
                        let kd = if j == k { 1.0 } else { 0.0 };
                        d[j] = yl[k] * (kd - yl[j]);
                    }
                }
                OutputKind::Logistic => {
                    d.fill(0.0);
                    d[k] = yl[k] * (1.0 - yl[k]);
                }
            }
        }
        // Walk layers backwards; offsets computed from the end.
        let mut end = self.weights.len();
        for l in (0..n_layers).rev() {
            let (fan_in, units) = (self.sizes[l], self.sizes[l + 1]);
            let stride = fan_in + 1;
            let off = end - units * stride;
            let input = &s.acts[l];
            {
                let d = &s.deltas[l];
                for j in 0..units {
                    let r = &mut row[off + j * stride..off + (j + 1) * stride];
                    for i in 0..fan_in {
                        r[i] = d[j] * input[i];
                    }
                    r[fan_in] = d[j];
                }
            }
            if l > 0 {
                let (lo, hi) = s.deltas.split_at_mut(l);
                let prev = &mut lo[l - 1];
                let d = &hi[0];
                for i in 0..fan_in {
                    let mut acc = 0.0;
                    for j in 0..units {
                        acc += self.weights[off + j * stride + i] * d[j];
                    }
                    let a = input[i];
                    prev[i] = (1.0 - a * a) * acc;
                }
            }
            end = off;
        }
    }

    /// Sum of squared errors against one-hot targets over a sample set.
    pub fn sse(&self, x: &[f64], y: &[usize]) -> f64 {
        let mut s = self.scratch();
        sse_with(&self.weights, &self.sizes, self.output, x, y, &mut s)
    }
}

fn sse_with(
    weights: &[f64],
    sizes: &[usize],
    output: OutputKind,
    x: &[f64],
    y: &[usize],
    s: &mut MlpScratch,
) -> f64 {
    let dim = sizes[0];
    let last = sizes.len() - 1;
    let mut sse = 0.0;
    for (n, &label) in y.iter().enumerate() {
        s.acts[0].copy_from_slice(&x[n * dim..(n + 1) * dim]);
        Mlp::forward_with(weights, sizes, output, s);
        for (k, &v) in s.acts[last].iter().enumerate() {
            let t = if k == label { 1.0 } else { 0.0 };
            sse += (v - t) * (v - t);
        }
    }
    sse
}

/// Levenberg-Marquardt settings; defaults are MATLAB `trainlm`'s.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmConfig {
    /// Hidden layer sizes (paper: `[4, 3, 2]`).
    pub hidden: Vec<usize>,
    /// Output non-linearity.
    pub output: OutputKind,
    /// Maximum epochs (`trainlm`: 1000).
    pub epochs: usize,
    /// Stop when the training MSE is at or below this (`trainlm`: 0).
    pub goal: f64,
    /// Stop when the MSE gradient norm `||2 J^T e|| / (N n_out)` is below this (`trainlm`: 1e-7).
    pub min_grad: f64,
    /// Initial damping (`trainlm`: 0.001).
    pub mu: f64,
    /// Damping factor after an accepted step (`trainlm`: 0.1).
    pub mu_dec: f64,
    /// Damping factor after a rejected step (`trainlm`: 10).
    pub mu_inc: f64,
    /// Stop when the damping exceeds this (`trainlm`: 1e10).
    pub mu_max: f64,
    /// Consecutive validation failures before early stop (`trainlm`: 6).
    pub max_fail: usize,
    /// Cap on training rows used by LM (seeded stratified subsample); 0 = no cap.
    pub max_rows: usize,
    /// Seed for initialisation and subsampling.
    pub seed: u64,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            hidden: vec![4, 3, 2],
            output: OutputKind::Softmax,
            epochs: 1000,
            goal: 0.0,
            min_grad: 1e-7,
            mu: 1e-3,
            mu_dec: 0.1,
            mu_inc: 10.0,
            mu_max: 1e10,
            max_fail: 6,
            max_rows: 4000,
            seed: 1,
        }
    }
}

/// Why LM stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// Training MSE reached the goal.
    Goal,
    /// Maximum epochs reached.
    Epochs,
    /// Gradient below `min_grad`.
    MinGradient,
    /// Damping above `mu_max`.
    MuMax,
    /// Validation failed `max_fail` times in a row.
    Validation,
}

impl core::fmt::Display for StopReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Goal => "the training error reached its goal",
            Self::Epochs => "the epoch limit",
            Self::MinGradient => "a gradient below min_grad",
            Self::MuMax => "damping above mu_max",
            Self::Validation => "the validation error rose max_fail times in a row",
        })
    }
}

/// What happened during training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmReport {
    /// Epochs run.
    pub epochs: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// Training MSE at the start and after every epoch (accepted steps only lower it).
    pub train_mse: Vec<f64>,
    /// Validation MSE at the start and after every epoch (empty without validation data).
    pub val_mse: Vec<f64>,
    /// Epoch whose weights were returned (best validation, or the last).
    pub best_epoch: usize,
    /// Damping at the end.
    pub final_mu: f64,
    /// Rows actually used for the LM Jacobian.
    pub rows_used: usize,
}

impl LmReport {
    /// Whether the returned weights are the initial (random) ones: with
    /// validation data, no epoch lowered the validation error (best epoch
    /// 0, so epoch 0's weights were restored); without, no step lowered
    /// the training error (or no epoch ran). Not when the initial weights
    /// already met the goal.
    pub fn kept_initial_weights(&self) -> bool {
        if self.stop == StopReason::Goal && self.epochs == 0 {
            return false;
        }
        if !self.val_mse.is_empty() {
            return self.best_epoch == 0;
        }
        match (self.train_mse.first(), self.train_mse.last()) {
            (Some(first), Some(last)) => last >= first,
            _ => true,
        }
    }
}

/// Checks a flat sample set; returns the sample count.
pub(crate) fn check_samples(
    x: &[f64],
    dim: usize,
    y: &[usize],
    n_classes: usize,
) -> Result<usize, MlpError> {
    if dim == 0 || !x.len().is_multiple_of(dim) {
        return Err(MlpError::BadShape { len: x.len(), dim });
    }
    let n = x.len() / dim;
    if n != y.len() {
        return Err(MlpError::LabelCount {
            samples: n,
            labels: y.len(),
        });
    }
    if n == 0 {
        return Err(MlpError::Empty);
    }
    for (index, &label) in y.iter().enumerate() {
        if label >= n_classes {
            return Err(MlpError::BadLabel {
                index,
                label,
                n_classes,
            });
        }
    }
    if let Some(p) = x.iter().position(|v| !v.is_finite()) {
        return Err(MlpError::NotFinite {
            index: p / dim,
            feature: p % dim,
            value: x[p],
        });
    }
    Ok(n)
}

/// Seeded, class-stratified subsample of at most `cap` row indices (sorted).
pub(crate) fn stratified_subsample(
    y: &[usize],
    n_classes: usize,
    cap: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    if cap == 0 || y.len() <= cap {
        return (0..y.len()).collect();
    }
    let mut by_class: Vec<Vec<usize>> = vec![Vec::new(); n_classes];
    for (i, &c) in y.iter().enumerate() {
        by_class[c].push(i);
    }
    let mut out = Vec::with_capacity(cap);
    for rows in by_class.iter_mut() {
        let take = ((rows.len() as f64) * cap as f64 / y.len() as f64).round() as usize;
        rows.shuffle(rng);
        out.extend_from_slice(&rows[..take.min(rows.len()).max(rows.len().min(1))]);
    }
    out.sort_unstable();
    out
}

/// Train an MLP by Levenberg-Marquardt on flat row-major samples `x`
/// (`dim` columns) with labels `y < n_classes`; `val` (same layout) drives
/// early stopping. Deterministic for `cfg.seed`.
pub fn train_lm(
    cfg: &LmConfig,
    n_classes: usize,
    dim: usize,
    x: &[f64],
    y: &[usize],
    val: Option<(&[f64], &[usize])>,
) -> Result<(Mlp, LmReport), MlpError> {
    check_samples(x, dim, y, n_classes)?;
    if let Some((vx, vy)) = val {
        check_samples(vx, dim, vy, n_classes)?;
    }
    check_lm_size(dim, &cfg.hidden, n_classes)?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x9E37_79B9_7F4A_7C15);
    let rows = stratified_subsample(y, n_classes, cfg.max_rows, &mut rng);
    let mut tx = Vec::with_capacity(rows.len() * dim);
    let mut ty = Vec::with_capacity(rows.len());
    for &r in &rows {
        tx.extend_from_slice(&x[r * dim..(r + 1) * dim]);
        ty.push(y[r]);
    }
    let mut net = Mlp::init(dim, &cfg.hidden, n_classes, cfg.output, cfg.seed)?;
    let report = lm_loop(cfg, &mut net, &tx, &ty, val)?;
    Ok((net, report))
}

fn lm_loop(
    cfg: &LmConfig,
    net: &mut Mlp,
    x: &[f64],
    y: &[usize],
    val: Option<(&[f64], &[usize])>,
) -> Result<LmReport, MlpError> {
    let n = y.len();
    let dim = net.n_in();
    let n_out = net.n_out();
    let w = net.n_weights();
    let denom = (n * n_out) as f64;
    let mut s = net.scratch();
    let mut jtj = DMatrix::<f64>::zeros(w, w);
    let mut jte = DVector::<f64>::zeros(w);
    let mut jc = DMatrix::<f64>::zeros(JAC_CHUNK * n_out, w);
    let mut ec = DVector::<f64>::zeros(JAC_CHUNK * n_out);
    let mut yk = vec![0.0; n_out];
    let mut jrow = vec![0.0; n_out * w];
    let mut trial = vec![0.0; w];

    let mut mu = cfg.mu;
    let mut perf = sse_with(&net.weights, &net.sizes, net.output, x, y, &mut s) / denom;
    let mut train_mse = vec![perf];
    let mut val_mse = Vec::new();
    let val_denom = val.map(|(_, vy)| (vy.len() * n_out) as f64).unwrap_or(1.0);
    let mut best_val = f64::INFINITY;
    let mut best_w = net.weights.clone();
    let mut best_epoch = 0;
    let mut fails = 0;
    if let Some((vx, vy)) = val {
        best_val = sse_with(&net.weights, &net.sizes, net.output, vx, vy, &mut s) / val_denom;
        val_mse.push(best_val);
    }
    let mut epoch = 0;
    let stop = loop {
        if perf <= cfg.goal {
            break StopReason::Goal;
        }
        if epoch >= cfg.epochs {
            break StopReason::Epochs;
        }
        if mu > cfg.mu_max {
            break StopReason::MuMax;
        }
        // Accumulate J^T J and J^T e chunk by chunk.
        jtj.fill(0.0);
        jte.fill(0.0);
        let mut start = 0;
        while start < n {
            let m = JAC_CHUNK.min(n - start);
            let rows = m * n_out;
            jc.fill(0.0);
            ec.fill(0.0);
            for (r, sample) in (start..start + m).enumerate() {
                net.output_jacobian(
                    &x[sample * dim..(sample + 1) * dim],
                    &mut s,
                    &mut yk,
                    &mut jrow,
                );
                for k in 0..n_out {
                    let row = r * n_out + k;
                    for c in 0..w {
                        jc[(row, c)] = jrow[k * w + c];
                    }
                    let t = if k == y[sample] { 1.0 } else { 0.0 };
                    ec[row] = yk[k] - t;
                }
            }
            let jv = jc.rows(0, rows);
            let ev = ec.rows(0, rows);
            jtj.gemm_tr(1.0, &jv, &jv, 1.0);
            jte.gemv_tr(1.0, &jv, &ev, 1.0);
            start += m;
        }
        let grad = 2.0 * jte.norm() / denom;
        if grad < cfg.min_grad {
            break StopReason::MinGradient;
        }
        // Try steps with growing damping until one lowers the SSE.
        let mut accepted = false;
        while mu <= cfg.mu_max {
            let mut a = jtj.clone();
            for i in 0..w {
                a[(i, i)] += mu;
            }
            if let Some(ch) = a.cholesky() {
                let step = ch.solve(&jte);
                for i in 0..w {
                    trial[i] = net.weights[i] - step[i];
                }
                let p2 = sse_with(&trial, &net.sizes, net.output, x, y, &mut s) / denom;
                if p2.is_finite() && p2 < perf {
                    net.weights.copy_from_slice(&trial);
                    perf = p2;
                    mu *= cfg.mu_dec;
                    accepted = true;
                    break;
                }
            }
            mu *= cfg.mu_inc;
        }
        epoch += 1;
        train_mse.push(perf);
        if let Some((vx, vy)) = val {
            let v = sse_with(&net.weights, &net.sizes, net.output, vx, vy, &mut s) / val_denom;
            val_mse.push(v);
            if v < best_val {
                best_val = v;
                best_w.copy_from_slice(&net.weights);
                best_epoch = epoch;
                fails = 0;
            } else if v > best_val {
                fails += 1;
            }
            if fails >= cfg.max_fail {
                break StopReason::Validation;
            }
        }
        if !accepted {
            break StopReason::MuMax;
        }
    };
    if val.is_some() {
        net.weights.copy_from_slice(&best_w);
    } else {
        best_epoch = epoch;
    }
    Ok(LmReport {
        epochs: epoch,
        stop,
        train_mse,
        val_mse,
        best_epoch,
        final_mu: mu,
        rows_used: n,
    })
}
