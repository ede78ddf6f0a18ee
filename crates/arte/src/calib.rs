//! Confidence calibration of the streaming estimator's decisions.
//!
//! The streaming estimator's smoothed posterior of the decided road is
//! overconfident: the HMM treats frames that overlap by 75 % as independent
//! evidence, so its posterior saturates (crate README, "What the controller
//! is given"). A [`Calibration`] maps that posterior `p` of the decided road
//! to a confidence `c` that is right as often as it says, fitted on
//! held-out decisions of the stream itself (every decision against the true
//! road at its time), i.e. on what the controller receives.
//!
//! Mappings (all monotone non-decreasing in `p`, values in [0, 1]):
//!
//! - [`Calibration::Identity`]: `c = p` (a model without calibration).
//! - [`Calibration::Temperature`]: `c = σ(logit(p) / T)`, temperature
//!   scaling of the decided road's odds (one parameter).
//! - [`Calibration::Platt`]: `c = σ(a · logit(p) + b)`, `a ≥ 0` (Platt
//!   scaling; two parameters).
//! - [`Calibration::Isotonic`]: piecewise-linear through knots `(x_i, y_i)`
//!   fitted by pool-adjacent-violators, constant outside the knots.
//!
//! `logit(p)` clamps `p` to [1e-12, 1 − 1e-12]. [`Calibration::apply`]
//! allocates nothing.
//!
//! Measuring calibration: [`Reliability`] counts decisions in equal-width
//! confidence bins and gives the expected calibration error
//! ECE = Σ_b (n_b / N) · |accuracy_b − mean confidence_b|.

use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// Errors of calibration maps and their fitting.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CalibError {
    /// A parameter of a map is out of range.
    #[error("calibration: field `{field}`: {reason}")]
    Invalid {
        /// Field.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// Fitting data unusable.
    #[error("calibration data: {0}")]
    Data(String),
}

/// How a calibration is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// [`Calibration::Temperature`].
    Temperature,
    /// [`Calibration::Platt`].
    Platt,
    /// [`Calibration::Isotonic`].
    Isotonic,
}

impl Method {
    /// All methods, in the order they are reported.
    pub const ALL: [Method; 3] = [Method::Temperature, Method::Platt, Method::Isotonic];

    /// Parses `temperature`, `platt` or `isotonic`.
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "temperature" => Some(Method::Temperature),
            "platt" => Some(Method::Platt),
            "isotonic" => Some(Method::Isotonic),
            _ => None,
        }
    }

    /// The name [`Method::from_name`] parses.
    pub fn name(self) -> &'static str {
        match self {
            Method::Temperature => "temperature",
            Method::Platt => "platt",
            Method::Isotonic => "isotonic",
        }
    }
}

/// A monotone map from the decided road's smoothed posterior to a
/// calibrated confidence. See the module docs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Calibration {
    /// `c = p`.
    Identity,
    /// `c = σ(logit(p) / t)`.
    Temperature {
        /// Temperature, > 0 (> 1 lowers confidence).
        t: f64,
    },
    /// `c = σ(a · logit(p) + b)`.
    Platt {
        /// Slope, ≥ 0.
        a: f64,
        /// Offset.
        b: f64,
    },
    /// Piecewise-linear through `(x[i], y[i])`; `y[0]` below `x[0]`, the
    /// last `y` above the last `x`.
    Isotonic {
        /// Knots, strictly increasing, in [0, 1].
        x: Vec<f64>,
        /// Values, non-decreasing, in [0, 1].
        y: Vec<f64>,
    },
}

const EPS: f64 = 1e-12;

fn logit(p: f64) -> f64 {
    let p = p.clamp(EPS, 1.0 - EPS);
    (p / (1.0 - p)).ln()
}

fn sigmoid(z: f64) -> f64 {
    if z >= 0.0 {
        1.0 / (1.0 + (-z).exp())
    } else {
        let e = z.exp();
        e / (1.0 + e)
    }
}

impl Calibration {
    /// Whether this is the identity map.
    pub fn is_identity(&self) -> bool {
        matches!(self, Calibration::Identity)
    }

    /// The calibrated confidence of posterior `p` (NaN is read as 0).
    /// Allocates nothing.
    pub fn apply(&self, p: f64) -> f64 {
        let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
        match self {
            Calibration::Identity => p,
            Calibration::Temperature { t } => sigmoid(logit(p) / t),
            Calibration::Platt { a, b } => sigmoid(a * logit(p) + b),
            Calibration::Isotonic { x, y } => {
                let n = x.len();
                let i = x.partition_point(|&xi| xi <= p);
                if i == 0 {
                    y[0]
                } else if i == n {
                    y[n - 1]
                } else {
                    let (x0, x1, y0, y1) = (x[i - 1], x[i], y[i - 1], y[i]);
                    y0 + (y1 - y0) * (p - x0) / (x1 - x0)
                }
            }
        }
    }

    /// Checks the parameters (finite, in range, monotone).
    pub fn validate(&self) -> Result<(), CalibError> {
        let bad = |field, reason: String| Err(CalibError::Invalid { field, reason });
        match self {
            Calibration::Identity => Ok(()),
            Calibration::Temperature { t } => {
                if !(t.is_finite() && *t > 0.0) {
                    return bad("t", format!("{t} is not a finite positive temperature"));
                }
                Ok(())
            }
            Calibration::Platt { a, b } => {
                if !(a.is_finite() && *a >= 0.0) {
                    return bad(
                        "a",
                        format!("{a} is not finite and >= 0 (the map must not fall)"),
                    );
                }
                if !b.is_finite() {
                    return bad("b", format!("{b} is not finite"));
                }
                Ok(())
            }
            Calibration::Isotonic { x, y } => {
                if x.is_empty() || x.len() != y.len() {
                    return bad(
                        "x",
                        format!(
                            "{} knots and {} values; need as many, at least one",
                            x.len(),
                            y.len()
                        ),
                    );
                }
                if let Some(i) = x
                    .iter()
                    .position(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
                {
                    return bad("x", format!("knot {i} = {} is not in [0, 1]", x[i]));
                }
                if let Some(i) = y
                    .iter()
                    .position(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
                {
                    return bad("y", format!("value {i} = {} is not in [0, 1]", y[i]));
                }
                if let Some(i) = x.windows(2).position(|w| w[1] <= w[0]) {
                    return bad("x", format!("knots {i} and {} are not increasing", i + 1));
                }
                if let Some(i) = y.windows(2).position(|w| w[1] < w[0]) {
                    return bad("y", format!("values {i} and {} decrease", i + 1));
                }
                Ok(())
            }
        }
    }

    /// Fits a map by `method` to decisions with posterior `p[i]` that were
    /// right (`right[i]`) or not. Deterministic.
    ///
    /// - Temperature: minimises the log loss over ln T (golden section on
    ///   T in [0.01, 1000]).
    /// - Platt: minimises the log loss over (a, b) by Newton's method with
    ///   backtracking (a kept ≥ 0).
    /// - Isotonic: pool-adjacent-violators on the decisions sorted by `p`,
    ///   then neighbouring blocks pooled until each holds at least 0.5 %
    ///   of the decisions (and at least 20); each block gives a knot at its
    ///   mean posterior with value (right + 1) / (n + 2).
    pub fn fit(method: Method, p: &[f64], right: &[bool]) -> Result<Self, CalibError> {
        if p.len() != right.len() {
            return Err(CalibError::Data(format!(
                "{} confidences but {} outcomes",
                p.len(),
                right.len()
            )));
        }
        if p.is_empty() {
            return Err(CalibError::Data("no decisions to fit on".into()));
        }
        if let Some(i) = p.iter().position(|v| !v.is_finite()) {
            return Err(CalibError::Data(format!("confidence {i} is not finite")));
        }
        let c = match method {
            Method::Temperature => fit_temperature(p, right),
            Method::Platt => fit_platt(p, right),
            Method::Isotonic => fit_isotonic(p, right),
        };
        c.validate()?;
        Ok(c)
    }

    /// Short description, e.g. `temperature T = 2.31`.
    pub fn describe(&self) -> String {
        match self {
            Calibration::Identity => "identity (none)".into(),
            Calibration::Temperature { t } => format!("temperature T = {t:.4}"),
            Calibration::Platt { a, b } => format!("Platt a = {a:.4}, b = {b:.4}"),
            Calibration::Isotonic { x, .. } => format!("isotonic, {} knots", x.len()),
        }
    }
}

/// Mean log loss of confidences `c` against outcomes.
fn log_loss(c: impl Iterator<Item = f64>, right: &[bool]) -> f64 {
    let mut s = 0.0;
    for (ci, &r) in c.zip(right) {
        let ci = ci.clamp(EPS, 1.0 - EPS);
        s -= if r { ci.ln() } else { (1.0 - ci).ln() };
    }
    s / right.len().max(1) as f64
}

fn fit_temperature(p: &[f64], right: &[bool]) -> Calibration {
    let l: Vec<f64> = p.iter().map(|&v| logit(v)).collect();
    let loss = |ln_t: f64| {
        let t = ln_t.exp();
        log_loss(l.iter().map(|&z| sigmoid(z / t)), right)
    };
    // Golden-section search on ln T.
    let (mut a, mut b) = (0.01f64.ln(), 1000.0f64.ln());
    let g = (5.0f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (loss(x1), loss(x2));
    for _ in 0..100 {
        if f1 <= f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = loss(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = loss(x2);
        }
    }
    Calibration::Temperature {
        t: ((a + b) / 2.0).exp(),
    }
}

fn fit_platt(p: &[f64], right: &[bool]) -> Calibration {
    let l: Vec<f64> = p.iter().map(|&v| logit(v)).collect();
    let loss = |a: f64, b: f64| log_loss(l.iter().map(|&z| sigmoid(a * z + b)), right);
    let (mut a, mut b) = (1.0, 0.0);
    let mut f = loss(a, b);
    for _ in 0..100 {
        // Gradient and Hessian of the mean log loss.
        let (mut ga, mut gb, mut haa, mut hab, mut hbb) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&z, &r) in l.iter().zip(right) {
            let c = sigmoid(a * z + b);
            let e = c - f64::from(u8::from(r));
            let w = (c * (1.0 - c)).max(1e-12);
            ga += e * z;
            gb += e;
            haa += w * z * z;
            hab += w * z;
            hbb += w;
        }
        let n = l.len() as f64;
        let (ga, gb, haa, hab, hbb) = (ga / n, gb / n, haa / n + 1e-9, hab / n, hbb / n + 1e-9);
        let det = haa * hbb - hab * hab;
        if !(det.is_finite() && det > 0.0) {
            break;
        }
        let da = -(hbb * ga - hab * gb) / det;
        let db = -(haa * gb - hab * ga) / det;
        let mut step = 1.0;
        let mut improved = false;
        while step > 1e-10 {
            let (na, nb) = ((a + step * da).max(0.0), b + step * db);
            let nf = loss(na, nb);
            if nf < f {
                improved = f - nf > 1e-15;
                a = na;
                b = nb;
                f = nf;
                break;
            }
            step /= 2.0;
        }
        if !improved {
            break;
        }
    }
    Calibration::Platt { a, b }
}

fn fit_isotonic(p: &[f64], right: &[bool]) -> Calibration {
    let mut idx: Vec<usize> = (0..p.len()).collect();
    idx.sort_by(|&i, &j| p[i].total_cmp(&p[j]));
    // Pool-adjacent-violators. Blocks: (sum p, right, n); merge backwards
    // while the accuracy does not rise.
    let mut blocks: Vec<(f64, f64, f64)> = Vec::new();
    for &i in &idx {
        blocks.push((p[i].clamp(0.0, 1.0), f64::from(u8::from(right[i])), 1.0));
        while blocks.len() > 1 {
            let (s1, r1, n1) = blocks[blocks.len() - 1];
            let (s0, r0, n0) = blocks[blocks.len() - 2];
            if r0 / n0 >= r1 / n1 {
                blocks.pop();
                let last = blocks.len() - 1;
                blocks[last] = (s0 + s1, r0 + r1, n0 + n1);
            } else {
                break;
            }
        }
    }
    // Every knot pools at least ISOTONIC_MIN_SHARE of the decisions (and
    // ISOTONIC_MIN_BLOCK): merging neighbours of a non-decreasing sequence
    // keeps it non-decreasing, and a knot stands on enough decisions to
    // mean something. The last block joins its predecessor if short.
    let min_n = (ISOTONIC_MIN_SHARE * p.len() as f64).max(ISOTONIC_MIN_BLOCK);
    let mut pooled: Vec<(f64, f64, f64)> = Vec::new();
    let mut acc: Option<(f64, f64, f64)> = None;
    for b in blocks {
        let a = match acc {
            Some(a) => (a.0 + b.0, a.1 + b.1, a.2 + b.2),
            None => b,
        };
        if a.2 >= min_n {
            pooled.push(a);
            acc = None;
        } else {
            acc = Some(a);
        }
    }
    if let Some(a) = acc {
        match pooled.last_mut() {
            Some(l) => *l = (l.0 + a.0, l.1 + a.1, l.2 + a.2),
            None => pooled.push(a),
        }
    }
    // Knot at the block's mean posterior; value its accuracy with one
    // pseudo-success and one pseudo-failure (Laplace), so no knot claims
    // certainty (0 or 1) from a finite sample; a running maximum keeps the
    // values non-decreasing after that shrinkage.
    let (mut x, mut y): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for (s, r, n) in pooled {
        let xm = (s / n).clamp(0.0, 1.0);
        let ym = ((r + 1.0) / (n + 2.0)).max(y.last().copied().unwrap_or(0.0));
        match x.last() {
            // Equal mean posteriors: one knot, the higher value.
            Some(&xl) if xm <= xl => {
                if let Some(yl) = y.last_mut() {
                    *yl = yl.max(ym);
                }
            }
            _ => {
                x.push(xm);
                y.push(ym);
            }
        }
    }
    Calibration::Isotonic { x, y }
}

/// Each isotonic knot pools at least this share of the fitting decisions ...
pub const ISOTONIC_MIN_SHARE: f64 = 0.005;
/// ... and at least this many.
pub const ISOTONIC_MIN_BLOCK: f64 = 20.0;

/// The calibration a model carries for its streaming estimator, with where
/// it came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StreamCalibration {
    /// The map applied to the decided road's smoothed posterior.
    pub map: Calibration,
    /// The stream settings it was fitted with (hop, smoothing); the map
    /// corrects those settings' overconfidence and is only right for them.
    pub stream: crate::stream::StreamConfig,
    /// Where it was fitted (set, decisions, ECE before and after, command).
    pub notes: Vec<String>,
    /// The recordings it was fitted on, by content: the first 16 hex
    /// digits of each file's SHA-256, sorted, without repeats (as the
    /// model's `meta.training_files`). `grip dataset delay` says when it
    /// measures on them (its calibration figures are then in-sample).
    /// Calibrations written before this field existed have it empty (and
    /// it is then not written, so their bytes are unchanged).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
}

/// Accuracy against confidence in equal-width bins over [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Reliability {
    /// Per bin: (decisions, sum of confidences, right).
    bins: Vec<(u64, f64, u64)>,
}

/// One bin of a [`Reliability`] table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReliabilityBin {
    /// Lower edge.
    pub lo: f64,
    /// Upper edge.
    pub hi: f64,
    /// Decisions in the bin.
    pub n: u64,
    /// Their mean confidence (NaN if empty).
    pub mean_confidence: f64,
    /// Their share right (NaN if empty).
    pub accuracy: f64,
}

impl Reliability {
    /// `n_bins` equal-width bins (at least 1). Bin `b` holds confidences in
    /// [b/n, (b+1)/n); 1.0 is in the last bin.
    pub fn new(n_bins: usize) -> Self {
        Self {
            bins: vec![(0, 0.0, 0); n_bins.max(1)],
        }
    }
    /// Number of bins.
    pub fn n_bins(&self) -> usize {
        self.bins.len()
    }
    /// Counts one decision of confidence `c` (clamped to [0, 1]; NaN as 0).
    pub fn add(&mut self, c: f64, right: bool) {
        let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
        let k = self.bins.len();
        let b = ((c * k as f64) as usize).min(k - 1);
        let bin = &mut self.bins[b];
        bin.0 += 1;
        bin.1 += c;
        bin.2 += u64::from(right);
    }
    /// Adds another table with the same number of bins.
    pub fn merge(&mut self, other: &Reliability) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            a.0 += b.0;
            a.1 += b.1;
            a.2 += b.2;
        }
    }
    /// Decisions counted.
    pub fn total(&self) -> u64 {
        self.bins.iter().map(|b| b.0).sum()
    }
    /// The bins.
    pub fn bins(&self) -> Vec<ReliabilityBin> {
        let k = self.bins.len() as f64;
        self.bins
            .iter()
            .enumerate()
            .map(|(i, &(n, s, r))| ReliabilityBin {
                lo: i as f64 / k,
                hi: (i + 1) as f64 / k,
                n,
                mean_confidence: if n > 0 { s / n as f64 } else { f64::NAN },
                accuracy: if n > 0 { r as f64 / n as f64 } else { f64::NAN },
            })
            .collect()
    }
    /// Expected calibration error Σ_b (n_b / N) |accuracy_b − mean
    /// confidence_b|; `None` without decisions.
    pub fn ece(&self) -> Option<f64> {
        let n = self.total();
        (n > 0).then(|| {
            self.bins
                .iter()
                .filter(|b| b.0 > 0)
                .map(|&(_, s, r)| (r as f64 - s).abs() / n as f64)
                .sum()
        })
    }
    /// Markdown table: bin, decisions, share, mean confidence, accuracy,
    /// gap; empty bins are left out.
    pub fn to_markdown(&self) -> String {
        let n = self.total().max(1) as f64;
        let mut s = String::from(
            "| confidence | decisions | share | mean confidence | right | gap |\n|---|---:|---:|---:|---:|---:|\n",
        );
        for b in self.bins().iter().filter(|b| b.n > 0) {
            let _ = writeln!(
                s,
                "| {:.1}-{:.1} | {} | {:.1} % | {:.3} | {:.1} % | {:+.3} |",
                b.lo,
                b.hi,
                b.n,
                100.0 * b.n as f64 / n,
                b.mean_confidence,
                100.0 * b.accuracy,
                b.accuracy - b.mean_confidence
            );
        }
        s
    }
}

/// What a gate on the confidence lets through: (share of decisions with
/// confidence ≥ `gate`, share of those that are right); `None` for an empty
/// set; the second is `None` when nothing passes.
pub fn gate_stats(c: &[f64], right: &[bool], gate: f64) -> Option<(f64, Option<f64>)> {
    if c.is_empty() {
        return None;
    }
    let (mut pass, mut ok) = (0usize, 0usize);
    for (&ci, &r) in c.iter().zip(right) {
        if ci >= gate {
            pass += 1;
            ok += usize::from(r);
        }
    }
    Some((
        pass as f64 / c.len() as f64,
        (pass > 0).then(|| ok as f64 / pass as f64),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ece_by_hand() {
        // 10 bins. Bin 0.9-1.0: 4 decisions at 0.95, 3 right: gap
        // |0.75 − 0.95| = 0.2. Bin 0.5-0.6: 0.55 twice, 1 right: gap 0.05.
        // ECE = (4 · 0.2 + 2 · 0.05) / 6 = 0.15.
        let mut r = Reliability::new(10);
        for right in [true, true, true, false] {
            r.add(0.95, right);
        }
        r.add(0.55, true);
        r.add(0.55, false);
        assert_eq!(r.total(), 6);
        assert!((r.ece().unwrap() - 0.15).abs() < 1e-12, "{:?}", r.ece());
        let bins = r.bins();
        assert_eq!(bins.len(), 10);
        assert_eq!((bins[9].n, bins[5].n, bins[0].n), (4, 2, 0));
        assert!((bins[9].accuracy - 0.75).abs() < 1e-12);
        // 1.0 falls in the last bin, 0.0 in the first.
        let mut e = Reliability::new(10);
        e.add(1.0, true);
        e.add(0.0, false);
        assert_eq!(e.ece(), Some(0.0));
        assert_eq!((e.bins()[9].n, e.bins()[0].n), (1, 1));
        assert_eq!(Reliability::new(10).ece(), None);
    }

    #[test]
    fn isotonic_by_hand() {
        // 20 decisions at each of 0.1, 0.2, 0.3, 0.4 with 0, 12, 8 and 20
        // right. PAV: (0.1: 0/20) | (0.2: 12/20, 0.3: 8/20 pooled to
        // 0.25: 20/40) | (0.4: 20/20). Every block holds >= 20 decisions.
        // Values (r + 1) / (n + 2): 1/22, 21/42, 21/22.
        let mut p = Vec::new();
        let mut r = Vec::new();
        for (v, n_right) in [(0.3, 8), (0.1, 0), (0.4, 20), (0.2, 12)] {
            for i in 0..20 {
                p.push(v);
                r.push(i < n_right);
            }
        }
        let c = Calibration::fit(Method::Isotonic, &p, &r).unwrap();
        let Calibration::Isotonic { x, y } = &c else {
            panic!("not isotonic: {c:?}")
        };
        assert_eq!(x.len(), 3);
        for (a, b) in x.iter().zip([0.1, 0.25, 0.4]) {
            assert!((a - b).abs() < 1e-12, "{x:?}");
        }
        for (a, b) in y.iter().zip([1.0 / 22.0, 0.5, 21.0 / 22.0]) {
            assert!((a - b).abs() < 1e-12, "{y:?}");
        }
        assert_eq!(c.apply(0.05), 1.0 / 22.0);
        // halfway between the first two knots
        assert!((c.apply(0.175) - (1.0 / 22.0 + 0.5) / 2.0).abs() < 1e-12);
        assert_eq!(c.apply(0.9), 21.0 / 22.0);
        // Blocks shorter than 20 decisions are pooled with their neighbour:
        // 10 at 0.1 (0 right), 10 at 0.2 (all right) give one knot.
        let p2 = [[0.1; 10], [0.2; 10]].concat();
        let r2: Vec<bool> = (0..20).map(|i| i >= 10).collect();
        let Calibration::Isotonic { x, y } = Calibration::fit(Method::Isotonic, &p2, &r2).unwrap()
        else {
            panic!("not isotonic")
        };
        assert_eq!(x.len(), 1);
        assert!((x[0] - 0.15).abs() < 1e-12 && (y[0] - 11.0 / 22.0).abs() < 1e-12);
    }

    /// Decisions whose true accuracy at posterior p is σ(0.5 logit(p) − 0.3)
    /// (overconfident), seeded.
    fn overconfident(n: usize) -> (Vec<f64>, Vec<bool>) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut p, mut r) = (Vec::new(), Vec::new());
        for _ in 0..n {
            let pi: f64 = 0.5 + 0.4999 * rng.random::<f64>();
            let q = sigmoid(0.5 * logit(pi) - 0.3);
            p.push(pi);
            r.push(rng.random::<f64>() < q);
        }
        (p, r)
    }

    fn ece_of(c: &Calibration, p: &[f64], r: &[bool]) -> f64 {
        let mut t = Reliability::new(10);
        for (&pi, &ri) in p.iter().zip(r) {
            t.add(c.apply(pi), ri);
        }
        t.ece().unwrap()
    }

    #[test]
    fn fits_correct_an_overconfident_source() {
        let (p, r) = overconfident(20_000);
        let before = ece_of(&Calibration::Identity, &p, &r);
        assert!(before > 0.1, "{before}");
        let Calibration::Platt { a, b } = Calibration::fit(Method::Platt, &p, &r).unwrap() else {
            panic!("not Platt")
        };
        assert!(
            (a - 0.5).abs() < 0.05 && (b + 0.3).abs() < 0.08,
            "a {a} b {b}"
        );
        for m in Method::ALL {
            let c = Calibration::fit(m, &p, &r).unwrap();
            let after = ece_of(&c, &p, &r);
            // Temperature has no offset, so it cannot fit this source exactly.
            let limit = if m == Method::Temperature {
                before / 2.0
            } else {
                0.03
            };
            assert!(after < limit, "{m:?}: ECE {after} (before {before})");
        }
        let Calibration::Temperature { t } = Calibration::fit(Method::Temperature, &p, &r).unwrap()
        else {
            panic!("not temperature")
        };
        assert!(t > 1.5, "overconfidence needs T > 1, got {t}");
    }

    #[test]
    fn maps_are_monotone_and_within_the_unit_interval() {
        let (p, r) = overconfident(5_000);
        let mut maps = vec![
            Calibration::Identity,
            Calibration::Temperature { t: 3.0 },
            Calibration::Temperature { t: 0.5 },
            Calibration::Platt { a: 0.4, b: -2.0 },
            Calibration::Platt { a: 0.0, b: 1.0 },
        ];
        for m in Method::ALL {
            maps.push(Calibration::fit(m, &p, &r).unwrap());
        }
        for c in &maps {
            c.validate().unwrap();
            let mut prev = c.apply(0.0);
            for i in 0..=10_000 {
                let v = c.apply(f64::from(i) / 10_000.0);
                assert!((0.0..=1.0).contains(&v), "{c:?}: {v}");
                assert!(v >= prev, "{c:?} falls at {i}");
                prev = v;
            }
            assert!((0.0..=1.0).contains(&c.apply(f64::NAN)));
        }
    }

    #[test]
    fn bad_maps_and_data_are_refused() {
        let bad = [
            Calibration::Temperature { t: 0.0 },
            Calibration::Temperature { t: f64::NAN },
            Calibration::Platt { a: -1.0, b: 0.0 },
            Calibration::Platt {
                a: 1.0,
                b: f64::INFINITY,
            },
            Calibration::Isotonic {
                x: vec![],
                y: vec![],
            },
            Calibration::Isotonic {
                x: vec![0.5, 0.4],
                y: vec![0.1, 0.2],
            },
            Calibration::Isotonic {
                x: vec![0.4, 0.5],
                y: vec![0.3, 0.2],
            },
            Calibration::Isotonic {
                x: vec![0.4],
                y: vec![1.5],
            },
        ];
        for c in bad {
            assert!(c.validate().is_err(), "{c:?}");
        }
        assert!(Calibration::fit(Method::Platt, &[], &[]).is_err());
        assert!(Calibration::fit(Method::Platt, &[0.5], &[true, false]).is_err());
        assert!(Calibration::fit(Method::Isotonic, &[f64::NAN], &[true]).is_err());
    }

    #[test]
    fn gate_stats_count_what_passes() {
        let c = [0.95, 0.92, 0.5, 0.99];
        let r = [true, false, true, true];
        assert_eq!(gate_stats(&c, &r, 0.9), Some((0.75, Some(2.0 / 3.0))));
        assert_eq!(gate_stats(&c, &r, 0.999), Some((0.0, None)));
        assert_eq!(gate_stats(&[], &[], 0.9), None);
    }
}
