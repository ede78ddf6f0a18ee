//! Evaluation: cross-validation split by recording, confusion matrices,
//! accuracy, macro-F1, per-class recall and precision.
//!
//! Frames of one recording are strongly correlated (same surface patch,
//! same speed, same noise realisation), so a split that puts frames of one
//! recording on both sides measures memory, not generalisation. Every split
//! here works on *groups* (recording ids): [`stratified_group_kfold`] deals
//! each class's recordings round-robin into `k` folds after a seeded
//! shuffle, so each fold holds about `1/k` of every class's recordings and
//! a recording is in exactly one test fold.

use rand::{SeedableRng, seq::SliceRandom};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// Errors of splitting and scoring.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvalError {
    /// Label and group slices differ in length.
    #[error("{labels} labels but {groups} group ids")]
    Length {
        /// Labels.
        labels: usize,
        /// Group ids.
        groups: usize,
    },
    /// A recording carries frames of two classes.
    #[error(
        "recording {group} has frames of class {a} and of class {b}; a recording must have one class"
    )]
    MixedGroup {
        /// Group id.
        group: usize,
        /// One class.
        a: usize,
        /// Another class.
        b: usize,
    },
    /// Too few recordings of a class for the requested folds.
    #[error(
        "class {class} has {have} recording(s), fewer than the {folds} folds asked for; lower the fold count or add recordings"
    )]
    TooFewGroups {
        /// Class index.
        class: usize,
        /// Its recordings.
        have: usize,
        /// Folds asked for.
        folds: usize,
    },
    /// k < 2.
    #[error("cross-validation needs at least 2 folds, got {0}")]
    FoldCount(usize),
    /// A label is not below the class count.
    #[error("label {label} is not below the class count {n_classes}")]
    BadLabel {
        /// Label.
        label: usize,
        /// Classes.
        n_classes: usize,
    },
}

/// One train/test split (indices into the sample set).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fold {
    /// Training sample indices (ascending).
    pub train: Vec<usize>,
    /// Test sample indices (ascending).
    pub test: Vec<usize>,
}

/// Recordings per class: `class -> sorted group ids`. Checks one class per group.
fn groups_by_class(
    labels: &[usize],
    groups: &[usize],
    n_classes: usize,
) -> Result<Vec<Vec<usize>>, EvalError> {
    if labels.len() != groups.len() {
        return Err(EvalError::Length {
            labels: labels.len(),
            groups: groups.len(),
        });
    }
    let mut class_of: BTreeMap<usize, usize> = BTreeMap::new();
    for (&l, &g) in labels.iter().zip(groups) {
        if l >= n_classes {
            return Err(EvalError::BadLabel {
                label: l,
                n_classes,
            });
        }
        match class_of.get(&g) {
            Some(&c) if c != l => {
                return Err(EvalError::MixedGroup {
                    group: g,
                    a: c,
                    b: l,
                });
            }
            Some(_) => {}
            None => {
                class_of.insert(g, l);
            }
        }
    }
    let mut out = vec![Vec::new(); n_classes];
    for (g, c) in class_of {
        out[c].push(g);
    }
    Ok(out)
}

/// Stratified k-fold over recordings: no recording is ever on both sides.
///
/// Every class must have at least `k` recordings (else each fold could not
/// test every class). Deterministic for `seed`.
pub fn stratified_group_kfold(
    labels: &[usize],
    groups: &[usize],
    n_classes: usize,
    k: usize,
    seed: u64,
) -> Result<Vec<Fold>, EvalError> {
    if k < 2 {
        return Err(EvalError::FoldCount(k));
    }
    let mut per_class = groups_by_class(labels, groups, n_classes)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut fold_of: BTreeMap<usize, usize> = BTreeMap::new();
    let mut next = 0;
    for (class, gs) in per_class.iter_mut().enumerate() {
        if gs.is_empty() {
            continue;
        }
        if gs.len() < k {
            return Err(EvalError::TooFewGroups {
                class,
                have: gs.len(),
                folds: k,
            });
        }
        gs.shuffle(&mut rng);
        for &g in gs.iter() {
            fold_of.insert(g, next % k);
            next += 1;
        }
    }
    let mut folds = vec![
        Fold {
            train: Vec::new(),
            test: Vec::new()
        };
        k
    ];
    for (i, g) in groups.iter().enumerate() {
        let f = fold_of[g];
        for (j, fold) in folds.iter_mut().enumerate() {
            if j == f {
                fold.test.push(i);
            } else {
                fold.train.push(i);
            }
        }
    }
    Ok(folds)
}

/// Holds out about `fraction` of every class's recordings (at least one
/// when the class has two or more) as a validation set, e.g. for the MLP's
/// early stopping. Returns `(train, validation)` sample indices.
pub fn holdout_groups(
    labels: &[usize],
    groups: &[usize],
    n_classes: usize,
    fraction: f64,
    seed: u64,
) -> Result<(Vec<usize>, Vec<usize>), EvalError> {
    let mut per_class = groups_by_class(labels, groups, n_classes)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut held = std::collections::BTreeSet::new();
    for gs in per_class.iter_mut() {
        if gs.len() < 2 {
            continue;
        }
        gs.shuffle(&mut rng);
        let n = ((gs.len() as f64 * fraction).round() as usize).clamp(1, gs.len() - 1);
        held.extend(gs[..n].iter().copied());
    }
    let (mut tr, mut va) = (Vec::new(), Vec::new());
    for (i, g) in groups.iter().enumerate() {
        if held.contains(g) {
            va.push(i)
        } else {
            tr.push(i)
        }
    }
    Ok((tr, va))
}

/// Confusion matrix, `counts[predicted][actual]` (the paper's Tables II/III:
/// rows predicted, columns actual).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Confusion {
    classes: Vec<String>,
    /// Row-major `predicted * k + actual`.
    counts: Vec<u64>,
}

/// Summary scores of a confusion matrix.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Samples scored.
    pub n: u64,
    /// Fraction correct.
    pub accuracy: f64,
    /// Mean per-class recall ("macro accuracy", balanced accuracy).
    pub macro_recall: f64,
    /// Mean per-class F1.
    pub macro_f1: f64,
    /// Recall per class (NaN-free: 0 for a class with no samples).
    pub recall: Vec<f64>,
    /// Precision per class (0 for a class never predicted).
    pub precision: Vec<f64>,
}

impl Confusion {
    /// Empty matrix for these class names.
    pub fn new(classes: Vec<String>) -> Self {
        let k = classes.len();
        Self {
            classes,
            counts: vec![0; k * k],
        }
    }
    /// Class names.
    pub fn classes(&self) -> &[String] {
        &self.classes
    }
    fn k(&self) -> usize {
        self.classes.len()
    }
    /// Counts one decision. Out-of-range indices are ignored (and not counted).
    pub fn add(&mut self, predicted: usize, actual: usize) {
        let k = self.k();
        if predicted < k && actual < k {
            self.counts[predicted * k + actual] += 1;
        }
    }
    /// Adds another matrix over the same classes (e.g. CV folds).
    pub fn merge(&mut self, other: &Confusion) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
    }
    /// Count of (predicted, actual).
    pub fn get(&self, predicted: usize, actual: usize) -> u64 {
        self.counts[predicted * self.k() + actual]
    }
    /// All decisions.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }
    /// Samples whose actual class is `c` (column sum).
    pub fn actual_total(&self, c: usize) -> u64 {
        (0..self.k()).map(|p| self.get(p, c)).sum()
    }
    /// Decisions for `c` (row sum).
    pub fn predicted_total(&self, c: usize) -> u64 {
        (0..self.k()).map(|a| self.get(c, a)).sum()
    }
    /// Predicted `c` but actually another class (row sum minus diagonal).
    pub fn false_positives(&self, c: usize) -> u64 {
        self.predicted_total(c) - self.get(c, c)
    }
    /// Actually `c` but predicted another class (column sum minus diagonal).
    pub fn false_negatives(&self, c: usize) -> u64 {
        self.actual_total(c) - self.get(c, c)
    }
    /// Scores.
    pub fn metrics(&self) -> Metrics {
        let k = self.k();
        let n = self.total();
        let correct: u64 = (0..k).map(|c| self.get(c, c)).sum();
        let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        let recall: Vec<f64> = (0..k)
            .map(|c| ratio(self.get(c, c), self.actual_total(c)))
            .collect();
        let precision: Vec<f64> = (0..k)
            .map(|c| ratio(self.get(c, c), self.predicted_total(c)))
            .collect();
        let present: Vec<usize> = (0..k).filter(|&c| self.actual_total(c) > 0).collect();
        let m = present.len().max(1) as f64;
        let macro_recall = present.iter().map(|&c| recall[c]).sum::<f64>() / m;
        let macro_f1 = present
            .iter()
            .map(|&c| {
                let (p, r) = (precision[c], recall[c]);
                if p + r > 0.0 {
                    2.0 * p * r / (p + r)
                } else {
                    0.0
                }
            })
            .sum::<f64>()
            / m;
        Metrics {
            n,
            accuracy: ratio(correct, n),
            macro_recall,
            macro_f1,
            recall,
            precision,
        }
    }

    /// Markdown table in the layout of the paper's Tables II/III.
    pub fn to_markdown(&self) -> String {
        let k = self.k();
        let mut s = String::from("| predicted \\ actual |");
        for c in &self.classes {
            s.push_str(&format!(" {c} |"));
        }
        s.push_str(" false positive |\n|---|");
        for _ in 0..=k {
            s.push_str("---:|");
        }
        s.push('\n');
        for p in 0..k {
            s.push_str(&format!("| **{}** |", self.classes[p]));
            for a in 0..k {
                if a == p {
                    s.push_str(&format!(" **{}** |", self.get(p, a)));
                } else {
                    s.push_str(&format!(" {} |", self.get(p, a)));
                }
            }
            s.push_str(&format!(" {} |\n", self.false_positives(p)));
        }
        s.push_str("| false negative |");
        for a in 0..k {
            s.push_str(&format!(" {} |", self.false_negatives(a)));
        }
        s.push_str(" |\n");
        s
    }
}

impl fmt::Display for Confusion {
    /// Plain-text table: rows predicted, columns actual, false-positive
    /// column and false-negative row (the paper's Tables II/III).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let k = self.k();
        let w = self
            .classes
            .iter()
            .map(String::len)
            .max()
            .unwrap_or(0)
            .max(9);
        let lead = "predicted \\ actual".len().max(w);
        write!(f, "{:<lead$}", "predicted \\ actual")?;
        for c in &self.classes {
            write!(f, " {c:>w$}")?;
        }
        writeln!(f, " | {:>w$}", "false pos")?;
        for p in 0..k {
            write!(f, "{:<lead$}", self.classes[p])?;
            for a in 0..k {
                write!(f, " {:>w$}", self.get(p, a))?;
            }
            writeln!(f, " | {:>w$}", self.false_positives(p))?;
        }
        write!(f, "{:<lead$}", "false neg")?;
        for a in 0..k {
            write!(f, " {:>w$}", self.false_negatives(a))?;
        }
        writeln!(f, " |")
    }
}

impl fmt::Display for Metrics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "n = {}, accuracy {:.2} %, macro recall {:.2} %, macro-F1 {:.4}",
            self.n,
            100.0 * self.accuracy,
            100.0 * self.macro_recall,
            self.macro_f1
        )
    }
}

/// A labelled feature matrix: row-major `x` (`dim` columns), one class label
/// and one recording id per row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Samples {
    /// Columns.
    pub dim: usize,
    /// Row-major features.
    pub x: Vec<f64>,
    /// Class index per row.
    pub y: Vec<usize>,
    /// Recording id per row.
    pub group: Vec<usize>,
}

impl Samples {
    /// Empty set with `dim` columns.
    pub fn new(dim: usize) -> Self {
        Self {
            dim,
            ..Default::default()
        }
    }
    /// Rows.
    pub fn len(&self) -> usize {
        self.y.len()
    }
    /// No rows.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }
    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }
    /// Appends a row (`row.len()` must equal `dim`).
    pub fn push(&mut self, row: &[f64], y: usize, group: usize) {
        debug_assert_eq!(row.len(), self.dim);
        self.x.extend_from_slice(row);
        self.y.push(y);
        self.group.push(group);
    }
    /// The rows at `idx`, in that order.
    pub fn subset(&self, idx: &[usize]) -> Samples {
        let mut s = Samples::new(self.dim);
        s.x.reserve(idx.len() * self.dim);
        for &i in idx {
            s.push(self.row(i), self.y[i], self.group[i]);
        }
        s
    }
    /// Keeps only the columns `cols` (in that order).
    pub fn select_columns(&self, cols: &[usize]) -> Samples {
        let mut s = Samples::new(cols.len());
        s.x.reserve(self.len() * cols.len());
        for i in 0..self.len() {
            let r = self.row(i);
            s.x.extend(cols.iter().map(|&c| r[c]));
        }
        s.y.clone_from(&self.y);
        s.group.clone_from(&self.group);
        s
    }
    /// Number of distinct recordings.
    pub fn n_groups(&self) -> usize {
        self.group
            .iter()
            .collect::<std::collections::BTreeSet<_>>()
            .len()
    }
}
