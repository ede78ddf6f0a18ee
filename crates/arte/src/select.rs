//! Feature selection by least intra-class variance, and the Kullback-Leibler
//! separability report (paper §II.C).
//!
//! **Pruning.** For feature j, with classes c = 1..K, class means μ_cj, the
//! overall mean μ_j and N samples:
//!
//! ```text
//! pooled intra-class variance  W_j = (1/N) Σ_c Σ_{i∈c} (x_ij − μ_cj)²
//! total variance               T_j = (1/N) Σ_i (x_ij − μ_j)²
//! ratio                        ρ_j = W_j / T_j   (0: perfectly class-coherent, 1: no class information)
//! ```
//!
//! ρ_j is scale-free (1 − ρ_j is the correlation ratio η² of the one-way
//! ANOVA), so LPC, power-spectrum and cepstrum coefficients are comparable.
//! Within each group the features with the smallest ρ are kept: for the
//! paper, 3 of the 10 LPC, 2 of the 5 power-spectrum and 2 of the 5 cepstrum
//! coefficients. The chosen Paper20 indices go into
//! [`FeatureConfig::selection`], so they are stored with the model.
//!
//! **Separability.** Each class is modelled as a Gaussian N(μ_c, Σ_c) in the
//! feature space; the report gives the symmetric Kullback-Leibler divergence
//! D(a, b) = KL(a‖b) + KL(b‖a), with
//! KL(a‖b) = ½ [tr(Σ_b⁻¹Σ_a) + (μ_b−μ_a)ᵀ Σ_b⁻¹ (μ_b−μ_a) − d + ln(det Σ_b / det Σ_a)].
//! Each Σ_c gets a ridge of 1e-6 times the mean total variance on its
//! diagonal so that constant or collinear features stay finite.

use crate::features::{FeatureConfig, FeatureSet, N_CEP, N_LPC, N_PAPER20, N_PS};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Errors of selection and the KL report.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SelectError {
    /// No rows, or the matrix length is not rows × dim.
    #[error("feature matrix: {0}")]
    Shape(String),
    /// A label is not below the class count.
    #[error("label {label} at row {row} is not below the class count {n_classes}")]
    Label {
        /// Row.
        row: usize,
        /// Label found.
        label: usize,
        /// Classes.
        n_classes: usize,
    },
    /// A class has too few rows.
    #[error("class {class} has {rows} rows; need at least {need}")]
    TooFew {
        /// Class index.
        class: usize,
        /// Rows found.
        rows: usize,
        /// Needed.
        need: usize,
    },
    /// A value is NaN or infinite.
    #[error("feature value at row {row}, column {col} is not finite")]
    NotFinite {
        /// Row.
        row: usize,
        /// Column.
        col: usize,
    },
    /// A group range or count is invalid.
    #[error("selection group {0}")]
    Group(String),
}

fn check(
    x: &[f64],
    dim: usize,
    y: &[usize],
    n_classes: usize,
    need: usize,
) -> Result<Vec<usize>, SelectError> {
    if dim == 0 || y.is_empty() || x.len() != y.len() * dim {
        return Err(SelectError::Shape(format!(
            "{} values for {} rows of {} columns",
            x.len(),
            y.len(),
            dim
        )));
    }
    let mut counts = vec![0usize; n_classes];
    for (row, &label) in y.iter().enumerate() {
        if label >= n_classes {
            return Err(SelectError::Label {
                row,
                label,
                n_classes,
            });
        }
        counts[label] += 1;
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(SelectError::NotFinite {
            row: i / dim,
            col: i % dim,
        });
    }
    for (class, &rows) in counts.iter().enumerate() {
        if rows < need {
            return Err(SelectError::TooFew { class, rows, need });
        }
    }
    Ok(counts)
}

/// ρ_j = pooled intra-class variance / total variance for every column
/// (1 for a constant column). `x` is row-major (rows × dim).
pub fn variance_ratios(
    x: &[f64],
    dim: usize,
    y: &[usize],
    n_classes: usize,
) -> Result<Vec<f64>, SelectError> {
    let counts = check(x, dim, y, n_classes, 1)?;
    let n = y.len() as f64;
    let mut class_mean = vec![0.0; n_classes * dim];
    let mut mean = vec![0.0; dim];
    for (row, &c) in x.chunks_exact(dim).zip(y) {
        for j in 0..dim {
            class_mean[c * dim + j] += row[j] / counts[c] as f64;
            mean[j] += row[j] / n;
        }
    }
    let mut w = vec![0.0; dim];
    let mut t = vec![0.0; dim];
    for (row, &c) in x.chunks_exact(dim).zip(y) {
        for j in 0..dim {
            w[j] += (row[j] - class_mean[c * dim + j]).powi(2);
            t[j] += (row[j] - mean[j]).powi(2);
        }
    }
    Ok(w.iter()
        .zip(&t)
        .map(|(&w, &t)| {
            if t > 1e-300 {
                (w / t).clamp(0.0, 1.0)
            } else {
                1.0
            }
        })
        .collect())
}

/// Keeps, in each group (a column range and how many to keep), the columns
/// with the smallest ρ; ties go to the lower index. Returns the kept column
/// indices in ascending order.
pub fn select_by_groups(
    x: &[f64],
    dim: usize,
    y: &[usize],
    n_classes: usize,
    groups: &[(Range<usize>, usize)],
) -> Result<Vec<usize>, SelectError> {
    let rho = variance_ratios(x, dim, y, n_classes)?;
    let mut keep = Vec::new();
    for (g, (range, k)) in groups.iter().enumerate() {
        if range.end > dim || range.start >= range.end || *k > range.len() {
            return Err(SelectError::Group(format!(
                "{g}: range {range:?} keep {k} does not fit {dim} columns"
            )));
        }
        let mut cols: Vec<usize> = range.clone().collect();
        cols.sort_by(|&a, &b| rho[a].total_cmp(&rho[b]).then(a.cmp(&b)));
        keep.extend_from_slice(&cols[..*k]);
    }
    keep.sort_unstable();
    keep.dedup();
    Ok(keep)
}

/// The paper's pruning: from Paper20 rows, keep 3 LPC, 2 power-spectrum and
/// 2 cepstrum coefficients with the least intra-class variance ratio.
pub fn select_paper7(x: &[f64], y: &[usize], n_classes: usize) -> Result<Vec<usize>, SelectError> {
    let groups = [
        (0..N_LPC, 3),
        (N_LPC..N_LPC + N_PS, 2),
        (N_LPC + N_PS..N_LPC + N_PS + N_CEP, 2),
    ];
    select_by_groups(x, N_PAPER20, y, n_classes, &groups)
}

/// A Paper7 feature config with the given selection, other fields from `base`.
pub fn paper7_config(base: &FeatureConfig, selection: Vec<usize>) -> FeatureConfig {
    FeatureConfig {
        set: FeatureSet::Paper7,
        selection,
        ..base.clone()
    }
}

/// Symmetric KL divergences between Gaussian class models.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KlReport {
    /// Class count K.
    pub n_classes: usize,
    /// K × K row-major, D(a, b) = KL(a‖b) + KL(b‖a); 0 on the diagonal.
    pub divergence: Vec<f64>,
}

impl KlReport {
    /// D(a, b).
    pub fn get(&self, a: usize, b: usize) -> f64 {
        self.divergence[a * self.n_classes + b]
    }

    /// The smallest off-diagonal divergence and its pair: the hardest pair to separate.
    pub fn closest_pair(&self) -> Option<(usize, usize, f64)> {
        let k = self.n_classes;
        let mut best: Option<(usize, usize, f64)> = None;
        for a in 0..k {
            for b in a + 1..k {
                let d = self.get(a, b);
                if best.is_none_or(|(_, _, v)| d < v) {
                    best = Some((a, b, d));
                }
            }
        }
        best
    }

    /// A Markdown table with the given class names.
    pub fn to_markdown(&self, names: &[String]) -> String {
        let k = self.n_classes;
        let name = |i: usize| names.get(i).cloned().unwrap_or_else(|| i.to_string());
        let mut s = String::from("| symmetric KL |");
        for b in 0..k {
            s.push_str(&format!(" {} |", name(b)));
        }
        s.push_str("\n|---|");
        s.push_str(&"---:|".repeat(k));
        s.push('\n');
        for a in 0..k {
            s.push_str(&format!("| **{}** |", name(a)));
            for b in 0..k {
                s.push_str(&format!(" {:.1} |", self.get(a, b)));
            }
            s.push('\n');
        }
        s
    }
}

/// Fits a Gaussian per class and returns the symmetric KL matrix. Each class
/// needs at least 2 rows.
pub fn kl_report(
    x: &[f64],
    dim: usize,
    y: &[usize],
    n_classes: usize,
) -> Result<KlReport, SelectError> {
    let counts = check(x, dim, y, n_classes, 2)?;
    let n = y.len() as f64;
    let mut means = vec![DVector::<f64>::zeros(dim); n_classes];
    let mut total_mean = DVector::<f64>::zeros(dim);
    for (row, &c) in x.chunks_exact(dim).zip(y) {
        let r = DVector::from_column_slice(row);
        means[c] += &r / counts[c] as f64;
        total_mean += &r / n;
    }
    let mut covs = vec![DMatrix::<f64>::zeros(dim, dim); n_classes];
    let mut total_var = 0.0;
    for (row, &c) in x.chunks_exact(dim).zip(y) {
        let d = DVector::from_column_slice(row) - &means[c];
        covs[c] += &d * d.transpose() / (counts[c] - 1) as f64;
        total_var +=
            (DVector::from_column_slice(row) - &total_mean).norm_squared() / (n * dim as f64);
    }
    let ridge = 1e-6 * total_var.max(1e-300);
    let mut inv = Vec::with_capacity(n_classes);
    let mut logdet = Vec::with_capacity(n_classes);
    for cov in &mut covs {
        for j in 0..dim {
            cov[(j, j)] += ridge;
        }
        let ch = cov.clone().cholesky().ok_or_else(|| {
            SelectError::Shape("class covariance is not positive definite".into())
        })?;
        logdet.push(2.0 * ch.l().diagonal().iter().map(|v| v.ln()).sum::<f64>());
        inv.push(ch.inverse());
    }
    let kl = |a: usize, b: usize| -> f64 {
        let dm = &means[b] - &means[a];
        let tr = (&inv[b] * &covs[a]).trace();
        let maha = (dm.transpose() * &inv[b] * &dm)[(0, 0)];
        0.5 * (tr + maha - dim as f64 + logdet[b] - logdet[a])
    };
    let mut divergence = vec![0.0; n_classes * n_classes];
    for a in 0..n_classes {
        for b in 0..n_classes {
            if a != b {
                divergence[a * n_classes + b] = kl(a, b) + kl(b, a);
            }
        }
    }
    Ok(KlReport {
        n_classes,
        divergence,
    })
}
