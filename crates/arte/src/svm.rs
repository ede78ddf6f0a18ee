//! Support vector machine: C-SVC trained by SMO, one-vs-one, probabilities.
//!
//! - Binary solver ([`smo`]): the dual `min ½ aᵀQa − eᵀa`, `0 ≤ a ≤ C`,
//!   `yᵀa = 0`, `Q_ij = y_i y_j K(x_i, x_j)`, solved by sequential minimal
//!   optimisation with the second-order working-set selection of Fan, Chen &
//!   Lin (JMLR 6, 2005), "WSS 2" — a line-by-line port of LIBSVM's `Solver`
//!   (Chang & Lin, 2011) without shrinking. Stopping: the maximal violating
//!   pair gap `m(a) − M(a) < tol` (LIBSVM `-e`, default 1e-3). Kernel columns
//!   are cached (FIFO, bounded by `cache_mb`).
//! - Multi-class: one-vs-one (Knerr et al. 1990, as LIBSVM): one binary SVM
//!   per pair of classes; support vectors are stored once and shared.
//! - Probabilities: per pair, a Platt sigmoid `P(a | a or b, f) = 1 / (1 +
//!   exp(A f + B))` fitted on decision values obtained by internal k-fold
//!   cross-validation (Platt 1999, with the Newton method of Lin, Lin & Weng
//!   2007, as LIBSVM's `sigmoid_train`); pairwise probabilities are coupled
//!   into class probabilities by Wu, Lin & Weng (JMLR 5, 2004) method 2
//!   (LIBSVM's `multiclass_probability`). The predicted class is the argmax
//!   of the coupled probabilities; one-vs-one votes are available too.
//!
//! C and γ are not chosen here: the training pipeline grid-searches them on
//! cross-validation folds split by recording (see `crates/arte/README.md`).

use rand::{SeedableRng, seq::SliceRandom};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

use crate::mlp::{MlpError, check_samples};

/// LIBSVM's `TAU`: guard for non-positive curvature.
const TAU: f64 = 1e-12;

/// Kernel function.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum Kernel {
    /// `K(u, v) = u·v`.
    Linear,
    /// `K(u, v) = exp(−γ |u − v|²)`.
    Rbf {
        /// γ > 0.
        gamma: f64,
    },
}

impl Kernel {
    /// Evaluates the kernel.
    #[inline]
    pub fn eval(&self, u: &[f64], v: &[f64]) -> f64 {
        match *self {
            Kernel::Linear => u.iter().zip(v).map(|(a, b)| a * b).sum(),
            Kernel::Rbf { gamma } => {
                let d2: f64 = u.iter().zip(v).map(|(a, b)| (a - b) * (a - b)).sum();
                (-gamma * d2).exp()
            }
        }
    }
}

/// Errors of SVM training and construction.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SvmError {
    /// Bad samples (shape, labels, non-finite values).
    #[error(transparent)]
    Samples(#[from] MlpError),
    /// A class has no training samples.
    #[error("class {0} has no training samples; one-vs-one needs every class")]
    EmptyClass(usize),
    /// Fewer than two classes.
    #[error("an SVM needs at least 2 classes, got {0}")]
    TooFewClasses(usize),
    /// A hyper-parameter is out of range.
    #[error("SVM parameter {name} = {value} is invalid: {reason}")]
    BadParam {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Why.
        reason: &'static str,
    },
    /// A stored model is inconsistent.
    #[error("SVM model is inconsistent: {0}")]
    Inconsistent(String),
}

/// Result of the binary solver.
#[derive(Clone, Debug, PartialEq)]
pub struct BinarySolution {
    /// Dual variables `a_i` in `[0, C]`.
    pub alpha: Vec<f64>,
    /// Offset: the decision function is `Σ a_i y_i K(x_i, x) − rho`.
    pub rho: f64,
    /// Dual objective `½ aᵀQa − eᵀa` at the end.
    pub objective: f64,
    /// SMO iterations.
    pub iterations: usize,
    /// Final maximal-violation gap `m(a) − M(a)`.
    pub gap: f64,
    /// Whether `max_iter` stopped it before `gap < tol`.
    pub hit_max_iter: bool,
}

struct KernelCache<'a> {
    x: &'a [f64],
    dim: usize,
    n: usize,
    kernel: Kernel,
    cols: Vec<Option<Box<[f64]>>>,
    order: VecDeque<usize>,
    capacity: usize,
}

impl<'a> KernelCache<'a> {
    fn new(x: &'a [f64], dim: usize, kernel: Kernel, cache_mb: usize) -> Self {
        let n = x.len() / dim;
        let capacity = ((cache_mb << 20) / (8 * n.max(1))).max(2);
        Self {
            x,
            dim,
            n,
            kernel,
            cols: vec![None; n],
            order: VecDeque::new(),
            capacity,
        }
    }
    fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }
    fn ensure(&mut self, i: usize, keep: usize) {
        if self.cols[i].is_some() {
            return;
        }
        while self.order.len() >= self.capacity {
            let Some(old) = self.order.pop_front() else {
                break;
            };
            if old == keep {
                self.order.push_back(old);
                if self.order.len() == 1 {
                    break;
                }
                continue;
            }
            self.cols[old] = None;
        }
        let xi = self.row(i);
        let col: Box<[f64]> = (0..self.n)
            .map(|k| self.kernel.eval(xi, self.row(k)))
            .collect();
        self.cols[i] = Some(col);
        self.order.push_back(i);
    }
    fn col(&self, i: usize) -> &[f64] {
        self.cols[i].as_deref().unwrap_or(&[])
    }
}

/// Solves the binary C-SVC dual for samples `x` (row-major, `dim` columns)
/// with labels `y ∈ {+1, −1}`. LIBSVM's `Solver::Solve` with WSS 2, no shrinking.
pub fn smo(
    x: &[f64],
    dim: usize,
    y: &[f64],
    c: f64,
    kernel: Kernel,
    tol: f64,
    max_iter: usize,
    cache_mb: usize,
) -> BinarySolution {
    let l = y.len();
    let mut cache = KernelCache::new(x, dim, kernel, cache_mb);
    let qd: Vec<f64> = (0..l)
        .map(|i| kernel.eval(cache.row(i), cache.row(i)))
        .collect();
    let mut alpha = vec![0.0; l];
    let mut g = vec![-1.0; l];
    let is_upper = |a: f64| a >= c;
    let is_lower = |a: f64| a <= 0.0;
    let mut iter = 0;
    let mut gap;
    let mut hit = false;
    loop {
        // Working set selection (WSS 2).
        let mut gmax = f64::NEG_INFINITY;
        let mut gmax2 = f64::NEG_INFINITY;
        let mut imax = usize::MAX;
        for t in 0..l {
            if y[t] > 0.0 {
                if !is_upper(alpha[t]) && -g[t] >= gmax {
                    gmax = -g[t];
                    imax = t;
                }
            } else if !is_lower(alpha[t]) && g[t] >= gmax {
                gmax = g[t];
                imax = t;
            }
        }
        let mut jmin = usize::MAX;
        let mut obj_min = f64::INFINITY;
        if imax != usize::MAX {
            cache.ensure(imax, usize::MAX);
            let ki = cache.col(imax);
            let yi = y[imax];
            for j in 0..l {
                if y[j] > 0.0 {
                    if !is_lower(alpha[j]) {
                        let gd = gmax + g[j];
                        if g[j] >= gmax2 {
                            gmax2 = g[j];
                        }
                        if gd > 0.0 {
                            let quad = qd[imax] + qd[j] - 2.0 * yi * y[j] * ki[j];
                            let od = -(gd * gd) / if quad > 0.0 { quad } else { TAU };
                            if od <= obj_min {
                                jmin = j;
                                obj_min = od;
                            }
                        }
                    }
                } else if !is_upper(alpha[j]) {
                    let gd = gmax - g[j];
                    if -g[j] >= gmax2 {
                        gmax2 = -g[j];
                    }
                    if gd > 0.0 {
                        let quad = qd[imax] + qd[j] + 2.0 * yi * y[j] * ki[j];
                        let od = -(gd * gd) / if quad > 0.0 { quad } else { TAU };
                        if od <= obj_min {
                            jmin = j;
                            obj_min = od;
                        }
                    }
                }
            }
        }
        gap = gmax + gmax2;
        if gap < tol || jmin == usize::MAX {
            break;
        }
        if iter >= max_iter {
            hit = true;
            break;
        }
        iter += 1;
        let (i, j) = (imax, jmin);
        cache.ensure(j, i);
        cache.ensure(i, j);
        let ki = cache.col(i);
        let kj = cache.col(j);
        let qij = y[i] * y[j] * ki[j];
        let (oi, oj) = (alpha[i], alpha[j]);
        if y[i] != y[j] {
            let mut quad = qd[i] + qd[j] + 2.0 * qij;
            if quad <= 0.0 {
                quad = TAU;
            }
            let delta = (-g[i] - g[j]) / quad;
            let diff = alpha[i] - alpha[j];
            alpha[i] += delta;
            alpha[j] += delta;
            if diff > 0.0 {
                if alpha[j] < 0.0 {
                    alpha[j] = 0.0;
                    alpha[i] = diff;
                }
            } else if alpha[i] < 0.0 {
                alpha[i] = 0.0;
                alpha[j] = -diff;
            }
            if diff > 0.0 {
                // C_i - C_j = 0 for C-SVC with equal costs.
                if alpha[i] > c {
                    alpha[i] = c;
                    alpha[j] = c - diff;
                }
            } else if alpha[j] > c {
                alpha[j] = c;
                alpha[i] = c + diff;
            }
        } else {
            let mut quad = qd[i] + qd[j] - 2.0 * qij;
            if quad <= 0.0 {
                quad = TAU;
            }
            let delta = (g[i] - g[j]) / quad;
            let sum = alpha[i] + alpha[j];
            alpha[i] -= delta;
            alpha[j] += delta;
            if sum > c {
                if alpha[i] > c {
                    alpha[i] = c;
                    alpha[j] = sum - c;
                }
            } else if alpha[j] < 0.0 {
                alpha[j] = 0.0;
                alpha[i] = sum;
            }
            if sum > c {
                if alpha[j] > c {
                    alpha[j] = c;
                    alpha[i] = sum - c;
                }
            } else if alpha[i] < 0.0 {
                alpha[i] = 0.0;
                alpha[j] = sum;
            }
        }
        let dai = alpha[i] - oi;
        let daj = alpha[j] - oj;
        for k in 0..l {
            g[k] += y[k] * (y[i] * ki[k] * dai + y[j] * kj[k] * daj);
        }
    }
    // rho (LIBSVM calculate_rho).
    let (mut ub, mut lb, mut sum_free, mut n_free) =
        (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
    for i in 0..l {
        let yg = y[i] * g[i];
        if is_upper(alpha[i]) {
            if y[i] < 0.0 {
                ub = ub.min(yg);
            } else {
                lb = lb.max(yg);
            }
        } else if is_lower(alpha[i]) {
            if y[i] > 0.0 {
                ub = ub.min(yg);
            } else {
                lb = lb.max(yg);
            }
        } else {
            n_free += 1;
            sum_free += yg;
        }
    }
    let rho = if n_free > 0 {
        sum_free / n_free as f64
    } else {
        (ub + lb) / 2.0
    };
    let objective = 0.5
        * alpha
            .iter()
            .zip(&g)
            .map(|(a, gi)| a * (gi - 1.0))
            .sum::<f64>();
    BinarySolution {
        alpha,
        rho,
        objective,
        iterations: iter,
        gap,
        hit_max_iter: hit,
    }
}

/// Platt sigmoid fit (Lin, Lin & Weng 2007; LIBSVM `sigmoid_train`):
/// returns `(A, B)` with `P(+1 | f) = 1 / (1 + exp(A f + B))`.
pub fn sigmoid_train(dec: &[f64], positive: &[bool]) -> (f64, f64) {
    let prior1 = positive.iter().filter(|&&p| p).count() as f64;
    let prior0 = positive.len() as f64 - prior1;
    let (max_iter, min_step, sigma, eps) = (100, 1e-10, 1e-12, 1e-5);
    let hi = (prior1 + 1.0) / (prior1 + 2.0);
    let lo = 1.0 / (prior0 + 2.0);
    let t: Vec<f64> = positive.iter().map(|&p| if p { hi } else { lo }).collect();
    let mut a = 0.0;
    let mut b = ((prior0 + 1.0) / (prior1 + 1.0)).ln();
    let f = |a: f64, b: f64| -> f64 {
        dec.iter()
            .zip(&t)
            .map(|(&d, &ti)| {
                let fab = d * a + b;
                if fab >= 0.0 {
                    ti * fab + (-fab).exp().ln_1p()
                } else {
                    (ti - 1.0) * fab + fab.exp().ln_1p()
                }
            })
            .sum()
    };
    let mut fval = f(a, b);
    for _ in 0..max_iter {
        let (mut h11, mut h22, mut h21, mut g1, mut g2) = (sigma, sigma, 0.0, 0.0, 0.0);
        for (&d, &ti) in dec.iter().zip(&t) {
            let fab = d * a + b;
            let (p, q) = if fab >= 0.0 {
                let e = (-fab).exp();
                (e / (1.0 + e), 1.0 / (1.0 + e))
            } else {
                let e = fab.exp();
                (1.0 / (1.0 + e), e / (1.0 + e))
            };
            let d2 = p * q;
            h11 += d * d * d2;
            h22 += d2;
            h21 += d * d2;
            let d1 = ti - p;
            g1 += d * d1;
            g2 += d1;
        }
        if g1.abs() < eps && g2.abs() < eps {
            break;
        }
        let det = h11 * h22 - h21 * h21;
        let da = -(h22 * g1 - h21 * g2) / det;
        let db = -(-h21 * g1 + h11 * g2) / det;
        let gd = g1 * da + g2 * db;
        let mut step = 1.0;
        while step >= min_step {
            let (na, nb) = (a + step * da, b + step * db);
            let nf = f(na, nb);
            if nf < fval + 1e-4 * step * gd {
                a = na;
                b = nb;
                fval = nf;
                break;
            }
            step /= 2.0;
        }
        if step < min_step {
            break;
        }
    }
    (a, b)
}

/// [`Svm::kernel_values`] body: `out[i] = K(sv_i, x)` from the
/// dimension-major support vectors `by_dim` (`x.len()` rows of `out.len()`).
#[inline(always)]
fn kernel_values_generic(kernel: Kernel, by_dim: &[f64], x: &[f64], out: &mut [f64]) {
    let n = out.len();
    if n == 0 {
        return;
    }
    out.fill(0.0);
    // Four dimensions per pass over `out`, each added in dimension order.
    let term = |v: f64, xj: f64| match kernel {
        Kernel::Linear => v * xj,
        Kernel::Rbf { .. } => (v - xj) * (v - xj),
    };
    let mut cols = by_dim.chunks_exact(n).zip(x);
    loop {
        match (cols.next(), cols.next(), cols.next(), cols.next()) {
            (Some((c0, &x0)), Some((c1, &x1)), Some((c2, &x2)), Some((c3, &x3))) => {
                for ((((o, &v0), &v1), &v2), &v3) in out.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3)
                {
                    *o = (((*o + term(v0, x0)) + term(v1, x1)) + term(v2, x2)) + term(v3, x3);
                }
            }
            (a, b, c, _) => {
                for (col, xj) in [a, b, c].into_iter().flatten() {
                    for (o, &v) in out.iter_mut().zip(col) {
                        *o += term(v, *xj);
                    }
                }
                break;
            }
        }
    }
    if let Kernel::Rbf { gamma } = kernel {
        for o in out.iter_mut() {
            *o *= -gamma;
        }
        if out.iter().all(|a| EXP_FAST_RANGE.contains(a)) {
            for o in out.iter_mut() {
                *o = exp_in_range(*o);
            }
        } else {
            for o in out.iter_mut() {
                *o = if EXP_FAST_RANGE.contains(o) {
                    exp_in_range(*o)
                } else {
                    o.exp()
                };
            }
        }
    }
}

/// [`kernel_values_generic`] compiled for AVX2 (same operations, wider
/// vectors; no FMA contraction, so the same rounding).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn kernel_values_avx2(kernel: Kernel, by_dim: &[f64], x: &[f64], out: &mut [f64]) {
    kernel_values_generic(kernel, by_dim, x, out);
}

/// Arguments for which [`exp_in_range`] is valid (its result and 2^k are
/// normal numbers).
const EXP_FAST_RANGE: std::ops::RangeInclusive<f64> = -708.0..=709.0;

/// `e^x` for x in [`EXP_FAST_RANGE`], relative error below 1e-15 (a few
/// ulp; unit test against `f64::exp`). Branch-free, so a loop of it
/// vectorises; outside the range the result is meaningless.
///
/// Method (Cody & Waite reduction, as fdlibm's `exp`): x = k·ln2 + r with
/// k = round(x/ln2), |r| ≤ ln2/2, ln2 split into a high part with trailing
/// zero bits (k·LN2_HI exact) and a low part; e^r by its Taylor series to
/// r¹³ (truncation ≤ (ln2/2)¹⁴/14! ≈ 4e-18); 2^k built from its bits.
#[inline(always)]
fn exp_in_range(x: f64) -> f64 {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    // fdlibm's ln2_hi = 6.93147180369123816490e-01 and ln2_lo = 1.90821492927058770002e-10.
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    // 1.5·2^52: adding it rounds to an integer kept in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let t = x * LOG2E + SHIFT;
    let kf = t - SHIFT;
    let k = t.to_bits().wrapping_sub(SHIFT.to_bits()) as i64;
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    const C: [f64; 14] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let mut p = C[13];
    for &c in C[..13].iter().rev() {
        p = p * r + c;
    }
    // k in [−1022, 1023] here, so 2^k is a normal number.
    p * f64::from_bits(((k + 1023) as u64) << 52)
}

#[inline]
fn sigmoid_predict(dec: f64, a: f64, b: f64) -> f64 {
    let fab = dec * a + b;
    if fab >= 0.0 {
        (-fab).exp() / (1.0 + (-fab).exp())
    } else {
        1.0 / (1.0 + fab.exp())
    }
}

/// One binary machine of the one-vs-one ensemble: class `a` (+1) vs `b` (−1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairModel {
    /// Positive class.
    pub a: usize,
    /// Negative class.
    pub b: usize,
    /// Indices into [`Svm`]'s support vectors.
    pub sv: Vec<u32>,
    /// `a_i y_i` per support vector.
    pub coef: Vec<f64>,
    /// Offset.
    pub rho: f64,
    /// Platt `A`.
    pub prob_a: f64,
    /// Platt `B`.
    pub prob_b: f64,
}

/// Multi-class one-vs-one SVM.
///
/// Serialised as its stored fields; deserialising goes through
/// `SvmStored` and rebuilds the derived dimension-major copy of the
/// support vectors, so every `Svm` value has it from construction on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "SvmStored")]
pub struct Svm {
    kernel: Kernel,
    dim: usize,
    n_classes: usize,
    /// Support vectors, row-major, `dim` columns.
    sv: Vec<f64>,
    pairs: Vec<PairModel>,
    /// The support vectors transposed (`dim` rows of `n_sv`), so the kernel
    /// loop runs across support vectors with contiguous loads. Derived from
    /// `sv` (private, never changed after construction) by [`by_dim`];
    /// not serialised.
    #[serde(skip)]
    sv_by_dim: Vec<f64>,
}

/// The stored fields of an [`Svm`] (same names and order as its
/// serialised form), for deserialising.
#[derive(Deserialize)]
struct SvmStored {
    kernel: Kernel,
    dim: usize,
    n_classes: usize,
    sv: Vec<f64>,
    pairs: Vec<PairModel>,
}

impl From<SvmStored> for Svm {
    fn from(s: SvmStored) -> Self {
        Self {
            sv_by_dim: by_dim(&s.sv, s.dim),
            kernel: s.kernel,
            dim: s.dim,
            n_classes: s.n_classes,
            sv: s.sv,
            pairs: s.pairs,
        }
    }
}

/// Row-major `sv` (`dim` columns) transposed to dimension-major. A length
/// that is not a multiple of `dim` (a corrupt file, refused afterwards by
/// [`Svm::validate`]) leaves the remainder out.
fn by_dim(sv: &[f64], dim: usize) -> Vec<f64> {
    let dim = dim.max(1);
    let n = sv.len() / dim;
    let mut t = vec![0.0; n * dim];
    for (i, row) in sv.chunks_exact(dim).enumerate() {
        for (j, &v) in row.iter().enumerate() {
            t[j * n + i] = v;
        }
    }
    t
}

/// SVM training settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SvmConfig {
    /// Box constraint C.
    pub c: f64,
    /// Kernel.
    pub kernel: Kernel,
    /// Stopping tolerance on the violating-pair gap (LIBSVM: 1e-3).
    pub tol: f64,
    /// SMO iteration cap per binary problem.
    pub max_iter: usize,
    /// Kernel cache size per binary problem (MiB).
    pub cache_mb: usize,
    /// Internal CV folds for the Platt decision values (LIBSVM: 5); 0 = fit
    /// on training decision values (biased, faster).
    pub prob_folds: usize,
    /// Seed of the Platt CV shuffle.
    pub seed: u64,
}

impl Default for SvmConfig {
    fn default() -> Self {
        Self {
            c: 10.0,
            kernel: Kernel::Rbf { gamma: 0.1 },
            tol: 1e-3,
            max_iter: 10_000_000,
            cache_mb: 200,
            prob_folds: 5,
            seed: 1,
        }
    }
}

/// Training statistics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SvmReport {
    /// Unique support vectors.
    pub n_sv: usize,
    /// SMO iterations summed over pairs (final machines only).
    pub iterations: usize,
    /// Pairs that hit the iteration cap.
    pub capped_pairs: usize,
}

/// Scratch for allocation-free prediction.
#[derive(Clone, Debug)]
pub struct SvmScratch {
    kvals: Vec<f64>,
    r: Vec<f64>,
    q: Vec<f64>,
    qp: Vec<f64>,
    votes: Vec<u32>,
}

fn check_cfg(cfg: &SvmConfig) -> Result<(), SvmError> {
    if !(cfg.c.is_finite() && cfg.c > 0.0) {
        return Err(SvmError::BadParam {
            name: "c",
            value: cfg.c,
            reason: "must be finite and > 0",
        });
    }
    if let Kernel::Rbf { gamma } = cfg.kernel
        && !(gamma.is_finite() && gamma > 0.0)
    {
        return Err(SvmError::BadParam {
            name: "gamma",
            value: gamma,
            reason: "must be finite and > 0",
        });
    }
    if !(cfg.tol.is_finite() && cfg.tol > 0.0) {
        return Err(SvmError::BadParam {
            name: "tol",
            value: cfg.tol,
            reason: "must be finite and > 0",
        });
    }
    Ok(())
}

fn decision(x: &[f64], dim: usize, alpha_y: &[f64], rho: f64, kernel: Kernel, q: &[f64]) -> f64 {
    let mut s = -rho;
    for (i, &ay) in alpha_y.iter().enumerate() {
        if ay != 0.0 {
            s += ay * kernel.eval(&x[i * dim..(i + 1) * dim], q);
        }
    }
    s
}

/// Trains a binary machine on rows `x` with `y` ±1 and returns `(alpha_y, rho, solution)`.
fn binary_fit(
    x: &[f64],
    dim: usize,
    y: &[f64],
    cfg: &SvmConfig,
) -> (Vec<f64>, f64, BinarySolution) {
    let sol = smo(
        x,
        dim,
        y,
        cfg.c,
        cfg.kernel,
        cfg.tol,
        cfg.max_iter,
        cfg.cache_mb,
    );
    let ay = sol.alpha.iter().zip(y).map(|(a, yi)| a * yi).collect();
    (ay, sol.rho, sol)
}

/// Platt decision values by internal k-fold CV (LIBSVM `svm_binary_svc_probability`).
fn cv_decisions(
    x: &[f64],
    dim: usize,
    y: &[f64],
    cfg: &SvmConfig,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let l = y.len();
    let k = cfg.prob_folds;
    let mut dec = vec![0.0; l];
    if k < 2 || l < 2 * k {
        let (ay, rho, _) = binary_fit(x, dim, y, cfg);
        for i in 0..l {
            dec[i] = decision(x, dim, &ay, rho, cfg.kernel, &x[i * dim..(i + 1) * dim]);
        }
        return dec;
    }
    let mut perm: Vec<usize> = (0..l).collect();
    perm.shuffle(rng);
    for f in 0..k {
        let (beg, end) = (f * l / k, (f + 1) * l / k);
        let mut tx = Vec::with_capacity((l - (end - beg)) * dim);
        let mut ty = Vec::with_capacity(l - (end - beg));
        for (p, &i) in perm.iter().enumerate() {
            if p < beg || p >= end {
                tx.extend_from_slice(&x[i * dim..(i + 1) * dim]);
                ty.push(y[i]);
            }
        }
        let pos = ty.iter().filter(|&&v| v > 0.0).count();
        for &i in &perm[beg..end] {
            dec[i] = if pos == 0 {
                -1.0
            } else if pos == ty.len() {
                1.0
            } else {
                0.0
            };
        }
        if pos == 0 || pos == ty.len() {
            continue;
        }
        let (ay, rho, _) = binary_fit(&tx, dim, &ty, cfg);
        for &i in &perm[beg..end] {
            dec[i] = decision(&tx, dim, &ay, rho, cfg.kernel, &x[i * dim..(i + 1) * dim]);
        }
    }
    dec
}

impl Svm {
    /// Trains a one-vs-one SVM on row-major `x` (`dim` columns), labels `y < n_classes`.
    pub fn train(
        cfg: &SvmConfig,
        n_classes: usize,
        dim: usize,
        x: &[f64],
        y: &[usize],
    ) -> Result<(Self, SvmReport), SvmError> {
        check_cfg(cfg)?;
        if n_classes < 2 {
            return Err(SvmError::TooFewClasses(n_classes));
        }
        check_samples(x, dim, y, n_classes)?;
        let mut by_class: Vec<Vec<usize>> = vec![Vec::new(); n_classes];
        for (i, &c) in y.iter().enumerate() {
            by_class[c].push(i);
        }
        if let Some(c) = by_class.iter().position(Vec::is_empty) {
            return Err(SvmError::EmptyClass(c));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let mut sv_of: Vec<Option<u32>> = vec![None; y.len()];
        let mut sv = Vec::new();
        let mut pairs = Vec::new();
        let mut report = SvmReport {
            n_sv: 0,
            iterations: 0,
            capped_pairs: 0,
        };
        for a in 0..n_classes {
            for b in a + 1..n_classes {
                let idx: Vec<usize> = by_class[a].iter().chain(&by_class[b]).copied().collect();
                let mut px = Vec::with_capacity(idx.len() * dim);
                let mut py = Vec::with_capacity(idx.len());
                for &i in &idx {
                    px.extend_from_slice(&x[i * dim..(i + 1) * dim]);
                    py.push(if y[i] == a { 1.0 } else { -1.0 });
                }
                let (prob_a, prob_b) = {
                    let dec = cv_decisions(&px, dim, &py, cfg, &mut rng);
                    let pos: Vec<bool> = py.iter().map(|&v| v > 0.0).collect();
                    sigmoid_train(&dec, &pos)
                };
                let (ay, rho, sol) = binary_fit(&px, dim, &py, cfg);
                report.iterations += sol.iterations;
                report.capped_pairs += usize::from(sol.hit_max_iter);
                let mut pm = PairModel {
                    a,
                    b,
                    sv: Vec::new(),
                    coef: Vec::new(),
                    rho,
                    prob_a,
                    prob_b,
                };
                for (k, &coef) in ay.iter().enumerate() {
                    if coef != 0.0 {
                        let orig = idx[k];
                        let id = match sv_of[orig] {
                            Some(id) => id,
                            None => {
                                let id = (sv.len() / dim) as u32;
                                sv.extend_from_slice(&x[orig * dim..(orig + 1) * dim]);
                                sv_of[orig] = Some(id);
                                id
                            }
                        };
                        pm.sv.push(id);
                        pm.coef.push(coef);
                    }
                }
                pairs.push(pm);
            }
        }
        report.n_sv = sv.len() / dim;
        Ok((
            Self {
                kernel: cfg.kernel,
                dim,
                n_classes,
                sv_by_dim: by_dim(&sv, dim),
                sv,
                pairs,
            },
            report,
        ))
    }

    /// Checks internal consistency (used after deserialising).
    pub fn validate(&self) -> Result<(), SvmError> {
        let bad = |m: String| Err(SvmError::Inconsistent(m));
        if self.n_classes < 2 {
            return bad(format!("{} classes", self.n_classes));
        }
        if self.dim == 0 || !self.sv.len().is_multiple_of(self.dim) {
            return bad(format!(
                "{} support-vector values for dimension {}",
                self.sv.len(),
                self.dim
            ));
        }
        let n_sv = self.sv.len() / self.dim;
        let Some(want) = self
            .n_classes
            .checked_mul(self.n_classes - 1)
            .map(|n| n / 2)
        else {
            return bad(format!(
                "{} classes: too many for one-vs-one pair machines",
                self.n_classes
            ));
        };
        if self.pairs.len() != want {
            return bad(format!(
                "{} pair machines for {} classes (need {want})",
                self.pairs.len(),
                self.n_classes
            ));
        }
        if let Kernel::Rbf { gamma } = self.kernel
            && !(gamma.is_finite() && gamma > 0.0)
        {
            return bad(format!("gamma {gamma}"));
        }
        if self.sv.iter().any(|v| !v.is_finite()) {
            return bad("non-finite support vector".into());
        }
        // want = n(n-1)/2 machines are in memory, so n·n cannot overflow
        let mut first: Vec<Option<usize>> = vec![None; self.n_classes * self.n_classes];
        for (k, p) in self.pairs.iter().enumerate() {
            if p.a >= self.n_classes || p.b >= self.n_classes || p.a == p.b {
                return bad(format!("pair {k} has classes {} and {}", p.a, p.b));
            }
            // each unordered pair of classes exactly once: as many machines
            // as pairs and none twice means none is missing (a missing one
            // would leave its pairwise probabilities at 0, and the coupling
            // would divide by zero)
            let (lo, hi) = (p.a.min(p.b), p.a.max(p.b));
            let slot = &mut first[lo * self.n_classes + hi];
            if let Some(j) = *slot {
                return bad(format!(
                    "field `pairs`: pair {k} is a second machine for classes {lo} and {hi} (the first is pair {j}); each pair of classes needs exactly one"
                ));
            }
            *slot = Some(k);
            if p.sv.len() != p.coef.len() {
                return bad(format!(
                    "pair {k}: {} indices but {} coefficients",
                    p.sv.len(),
                    p.coef.len()
                ));
            }
            if p.sv.iter().any(|&i| i as usize >= n_sv) {
                return bad(format!("pair {k} refers to a support vector beyond {n_sv}"));
            }
            if !(p.rho.is_finite() && p.prob_a.is_finite() && p.prob_b.is_finite())
                || p.coef.iter().any(|c| !c.is_finite())
            {
                return bad(format!("pair {k} has a non-finite coefficient"));
            }
        }
        Ok(())
    }

    /// Input dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }
    /// Number of classes.
    pub fn n_classes(&self) -> usize {
        self.n_classes
    }
    /// Number of unique support vectors.
    pub fn n_sv(&self) -> usize {
        self.sv.len() / self.dim
    }
    /// The pair machines.
    pub fn pairs(&self) -> &[PairModel] {
        &self.pairs
    }
    /// The kernel.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Buffers sized for this model.
    pub fn scratch(&self) -> SvmScratch {
        let k = self.n_classes;
        SvmScratch {
            kvals: vec![0.0; self.n_sv()],
            r: vec![0.0; k * k],
            q: vec![0.0; k * k],
            qp: vec![0.0; k],
            votes: vec![0; k],
        }
    }

    /// `K(sv_i, x)` for every support vector into `s.kvals`. From the
    /// dimension-major copy of the support vectors: each `|sv_i − x|²` (or
    /// `sv_i·x`) is summed over the dimensions in the same order as
    /// [`Kernel::eval`], so it is the same number; the loop runs across
    /// support vectors (contiguous, vectorised). The RBF `exp` is
    /// [`exp_in_range`] (a few ulp; `f64::exp` outside its range). On
    /// x86-64 CPUs with AVX2 the same code is compiled for AVX2 (four f64
    /// per instruction) and chosen at run time.
    fn kernel_values(&self, x: &[f64], s: &mut SvmScratch) {
        let by_dim = &self.sv_by_dim;
        debug_assert_eq!(s.kvals.len(), self.n_sv(), "a scratch of another model");
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked on the line above),
            // the only requirement of a `target_feature(enable = "avx2")` fn.
            unsafe { kernel_values_avx2(self.kernel, by_dim, x, &mut s.kvals) };
            return;
        }
        kernel_values_generic(self.kernel, by_dim, x, &mut s.kvals);
    }

    /// `Σ coef_i K(sv_i, x) − rho`, summed with four interleaved partial sums.
    fn pair_decision(&self, p: &PairModel, kvals: &[f64]) -> f64 {
        let mut a = [0.0f64; 4];
        let (mut ii, mut ci) = (p.sv.chunks_exact(4), p.coef.chunks_exact(4));
        for (ic, cc) in (&mut ii).zip(&mut ci) {
            for j in 0..4 {
                a[j] += cc[j] * kvals[ic[j] as usize];
            }
        }
        let mut s = (a[0] + a[2]) + (a[1] + a[3]);
        for (&i, &c) in ii.remainder().iter().zip(ci.remainder()) {
            s += c * kvals[i as usize];
        }
        s - p.rho
    }

    /// Decision values of every pair machine (order of [`Svm::pairs`]) into `out`.
    pub fn decision_values(&self, x: &[f64], s: &mut SvmScratch, out: &mut [f64]) {
        self.kernel_values(x, s);
        for (o, p) in out.iter_mut().zip(&self.pairs) {
            *o = self.pair_decision(p, &s.kvals);
        }
    }

    /// One-vs-one voting (LIBSVM `svm_predict`): the class with most votes,
    /// ties to the lower index.
    pub fn predict_vote(&self, x: &[f64], s: &mut SvmScratch) -> usize {
        self.kernel_values(x, s);
        s.votes.fill(0);
        for p in &self.pairs {
            let d = self.pair_decision(p, &s.kvals);
            s.votes[if d > 0.0 { p.a } else { p.b }] += 1;
        }
        let mut best = 0;
        for (c, &v) in s.votes.iter().enumerate() {
            if v > s.votes[best] {
                best = c;
            }
        }
        best
    }

    /// Class probabilities by Platt scaling + pairwise coupling. No allocation.
    pub fn predict_proba(&self, x: &[f64], s: &mut SvmScratch, out: &mut [f64]) {
        let k = self.n_classes;
        self.kernel_values(x, s);
        let min_prob = 1e-7;
        for p in &self.pairs {
            let d = self.pair_decision(p, &s.kvals);
            let r = sigmoid_predict(d, p.prob_a, p.prob_b).clamp(min_prob, 1.0 - min_prob);
            s.r[p.a * k + p.b] = r;
            s.r[p.b * k + p.a] = 1.0 - r;
        }
        couple(k, &s.r, &mut s.q, &mut s.qp, out);
    }
}

/// Wu, Lin & Weng (2004) method 2 (LIBSVM `multiclass_probability`):
/// class probabilities `p` from pairwise `r[i*k+j] = P(i | i or j)`.
fn couple(k: usize, r: &[f64], q: &mut [f64], qp: &mut [f64], p: &mut [f64]) {
    let max_iter = 100.max(k);
    let eps = 0.005 / k as f64;
    for t in 0..k {
        p[t] = 1.0 / k as f64;
        q[t * k + t] = 0.0;
        for j in 0..t {
            q[t * k + t] += r[j * k + t] * r[j * k + t];
            q[t * k + j] = q[j * k + t];
        }
        for j in t + 1..k {
            q[t * k + t] += r[j * k + t] * r[j * k + t];
            q[t * k + j] = -r[j * k + t] * r[t * k + j];
        }
    }
    for _ in 0..max_iter {
        let mut pqp = 0.0;
        for t in 0..k {
            qp[t] = 0.0;
            for j in 0..k {
                qp[t] += q[t * k + j] * p[j];
            }
            pqp += p[t] * qp[t];
        }
        let max_err = (0..k).map(|t| (qp[t] - pqp).abs()).fold(0.0, f64::max);
        if max_err < eps {
            break;
        }
        for t in 0..k {
            let diff = (-qp[t] + pqp) / q[t * k + t];
            p[t] += diff;
            pqp = (pqp + diff * (diff * q[t * k + t] + 2.0 * qp[t])) / (1.0 + diff) / (1.0 + diff);
            for j in 0..k {
                qp[j] = (qp[j] + diff * q[t * k + j]) / (1.0 + diff);
                p[j] /= 1.0 + diff;
            }
        }
    }
}

#[cfg(test)]
mod exp_tests {
    use super::{EXP_FAST_RANGE, exp_in_range};

    #[test]
    fn exp_in_range_matches_libm_to_1e15() {
        let (lo, hi) = (*EXP_FAST_RANGE.start(), *EXP_FAST_RANGE.end());
        let n = 2_000_000;
        let mut worst = 0.0f64;
        for i in 0..=n {
            // A grid over the whole range plus a dense one over the kernel's usual [−40, 0].
            for x in [
                lo + (hi - lo) * i as f64 / n as f64,
                -40.0 * i as f64 / n as f64,
            ] {
                let (a, b) = (exp_in_range(x), x.exp());
                worst = worst.max(((a - b) / b).abs());
            }
        }
        assert!(worst < 1e-15, "worst relative error {worst:e}");
        assert_eq!(exp_in_range(0.0), 1.0);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernel_values_equal_generic_ones() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return; // nothing to compare on this CPU
        }
        let (n, dim) = (37, 11);
        let by_dim: Vec<f64> = (0..n * dim)
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3 - 0.5)
            .collect();
        let x: Vec<f64> = (0..dim).map(|j| 0.1 * j as f64 - 0.4).collect();
        for kernel in [
            super::Kernel::Rbf { gamma: 0.3 },
            super::Kernel::Rbf { gamma: 900.0 },
            super::Kernel::Linear,
        ] {
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            super::kernel_values_generic(kernel, &by_dim, &x, &mut a);
            // SAFETY: AVX2 support checked above.
            unsafe { super::kernel_values_avx2(kernel, &by_dim, &x, &mut b) };
            assert_eq!(a, b, "{kernel:?}");
        }
    }
}
