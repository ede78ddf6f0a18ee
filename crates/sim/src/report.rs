//! Statistics over seeds, the Table-V style report, and `summary.csv`.

use std::fmt::Write as _;
use std::io::{self, Write};

use crate::sim::RunResult;
use crate::variant::Variant;

/// One reported quantity of a run.
#[derive(Debug, Clone, Copy)]
pub struct Column {
    /// CSV column name.
    pub key: &'static str,
    /// Table heading.
    pub label: &'static str,
    /// Unit for the table ("" for none).
    pub unit: &'static str,
    /// Decimals in the table.
    pub decimals: usize,
    /// The value of a run.
    pub get: fn(&RunResult) -> f64,
}

/// The quantities in the table and in `summary.csv`, in order.
pub const COLUMNS: [Column; 9] = [
    Column {
        key: "slip_deviation",
        label: "slip dev.",
        unit: "",
        decimals: 4,
        get: |r| r.metrics.slip_deviation,
    },
    Column {
        key: "max_torque",
        label: "max torque",
        unit: "N m",
        decimals: 1,
        get: |r| r.metrics.max_torque,
    },
    Column {
        key: "torque_effort",
        label: "effort",
        unit: "N m",
        decimals: 1,
        get: |r| r.metrics.torque_effort,
    },
    Column {
        key: "mean_accel",
        label: "mean accel",
        unit: "m/s²",
        decimals: 3,
        get: |r| r.metrics.mean_accel,
    },
    Column {
        key: "distance",
        label: "distance",
        unit: "m",
        decimals: 2,
        get: |r| r.metrics.distance,
    },
    Column {
        key: "energy",
        label: "∫Tω dt",
        unit: "J",
        decimals: 0,
        get: |r| r.metrics.energy,
    },
    Column {
        key: "kinetic_energy_gain",
        label: "ΔKE",
        unit: "J",
        decimals: 0,
        get: |r| r.metrics.kinetic_energy_gain,
    },
    Column {
        key: "final_speed_kmh",
        label: "V end",
        unit: "km/h",
        decimals: 2,
        get: |r| r.final_state.v * 3.6,
    },
    Column {
        key: "arte_accuracy",
        label: "ARTE acc.",
        unit: "",
        decimals: 3,
        get: |r| r.arte.accuracy(),
    },
];

/// The torque command's smoothness (`grip_tcs::metrics`): in the table
/// after [`COLUMNS`], in `summary.csv` appended after every older column.
pub const COMMAND_COLUMNS: [Column; 3] = [
    Column {
        key: "cmd_tv_per_s",
        label: "cmd TV",
        unit: "N m/s",
        decimals: 0,
        get: |r| r.metrics.cmd_tv_per_s,
    },
    Column {
        key: "cmd_hf_rms",
        label: "cmd >20 Hz",
        unit: "N m",
        decimals: 2,
        get: |r| r.metrics.cmd_hf_rms,
    },
    Column {
        key: "cmd_hf_share",
        label: ">20 Hz share",
        unit: "",
        decimals: 3,
        get: |r| r.metrics.cmd_hf_share,
    },
];

/// [`COLUMNS`] then [`COMMAND_COLUMNS`]: what [`VariantSummary::stats`] holds.
pub fn all_columns() -> impl Iterator<Item = &'static Column> {
    COLUMNS.iter().chain(COMMAND_COLUMNS.iter())
}

/// Mean and sample standard deviation (n − 1) of the finite values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stat {
    /// Mean (NaN with no finite value).
    pub mean: f64,
    /// Sample standard deviation (0 with one value, NaN with none).
    pub std: f64,
    /// Number of finite values.
    pub n: usize,
}

impl Stat {
    /// Statistics of the finite values in `xs`.
    pub fn of(xs: impl IntoIterator<Item = f64>) -> Self {
        let v: Vec<f64> = xs.into_iter().filter(|x| x.is_finite()).collect();
        let n = v.len();
        if n == 0 {
            return Self {
                mean: f64::NAN,
                std: f64::NAN,
                n,
            };
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Self { mean, std, n }
    }
}

/// One variant over all its seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantSummary {
    /// Which variant.
    pub variant: Variant,
    /// Number of runs (seeds).
    pub runs: usize,
    /// One [`Stat`] per entry of [`all_columns`] ([`COLUMNS`], then
    /// [`COMMAND_COLUMNS`]).
    pub stats: Vec<Stat>,
    /// Fraction of cycles in which the controller used ARTE, mean over runs.
    pub arte_usage: f64,
    /// Runs with a non-finite plant state or rejected metric samples.
    pub unhealthy_runs: usize,
}

impl VariantSummary {
    /// The statistics of column `key`.
    pub fn stat(&self, key: &str) -> Option<Stat> {
        all_columns()
            .position(|c| c.key == key)
            .and_then(|i| self.stats.get(i).copied())
    }
}

/// Group `results` by variant (in order of first appearance) and compute
/// mean ± std over seeds of every column.
pub fn summarize(results: &[RunResult]) -> Vec<VariantSummary> {
    let mut variants: Vec<Variant> = Vec::new();
    for r in results {
        if !variants.contains(&r.variant) {
            variants.push(r.variant);
        }
    }
    variants
        .into_iter()
        .map(|v| {
            let runs: Vec<&RunResult> = results.iter().filter(|r| r.variant == v).collect();
            VariantSummary {
                variant: v,
                runs: runs.len(),
                stats: all_columns()
                    .map(|c| Stat::of(runs.iter().map(|r| (c.get)(r))))
                    .collect(),
                arte_usage: Stat::of(runs.iter().map(|r| r.arte.usage())).mean,
                unhealthy_runs: runs
                    .iter()
                    .filter(|r| r.non_finite_cycles > 0 || r.metrics.rejected > 0)
                    .count(),
            }
        })
        .collect()
}

/// The runs whose plant state went non-finite (a `non_finite_cycles` of
/// [`RunResult`] above 0: their figures are no figures), as the one line
/// `grip sim` fails with (exit 1, after its report and files are written):
/// how many, and each by variant and seed; `None` when every run stayed
/// finite.
pub fn non_finite_runs(results: &[RunResult]) -> Option<String> {
    non_finite_line(results.len(), non_finite_of(results))
}

/// The runs whose plant state went non-finite, as (how many, their listing
/// by variant and seed with each one's count of such cycles: "mfc seed 1
/// (2399 cycles), src seed 1 (12 cycles)"); `None` when every run stayed
/// finite. The listing of [`non_finite_runs`] and of `grip sim --sweep`'s
/// points.
pub fn non_finite_listing(results: &[RunResult]) -> Option<(usize, String)> {
    listing(non_finite_of(results))
}

fn non_finite_of(results: &[RunResult]) -> impl Iterator<Item = (Variant, u64, u64)> + '_ {
    results
        .iter()
        .filter(|r| r.non_finite_cycles > 0)
        .map(|r| (r.variant, r.seed, r.non_finite_cycles))
}

fn listing(bad: impl Iterator<Item = (Variant, u64, u64)>) -> Option<(usize, String)> {
    let bad: Vec<String> = bad
        .map(|(v, seed, n)| format!("{v} seed {seed} ({n} cycles)"))
        .collect();
    (!bad.is_empty()).then(|| (bad.len(), bad.join(", ")))
}

fn non_finite_line(runs: usize, bad: impl Iterator<Item = (Variant, u64, u64)>) -> Option<String> {
    listing(bad).map(|(n, list)| {
        format!(
            "{n} of {runs} runs had a non-finite plant state (their figures are not numbers; non_finite_cycles in summary.csv): {list}"
        )
    })
}

/// Relative change of the mean, (with − without) / |without|, in percent
/// (NaN when the baseline mean is 0 or missing).
pub fn relative_change(with: Stat, without: Stat) -> f64 {
    if without.mean.is_finite() && without.mean != 0.0 {
        100.0 * (with.mean - without.mean) / without.mean.abs()
    } else {
        f64::NAN
    }
}

fn fmt_stat(s: Stat, decimals: usize) -> String {
    if s.n == 0 {
        "-".to_owned()
    } else {
        format!("{:.*} ± {:.*}", decimals, s.mean, decimals, s.std)
    }
}

fn pad(s: &str, w: usize) -> String {
    let n = s.chars().count();
    if n >= w {
        s.to_owned()
    } else {
        format!("{}{s}", " ".repeat(w - n))
    }
}

/// The main table: one row per variant, mean ± std over seeds for every column.
pub fn format_table(summaries: &[VariantSummary]) -> String {
    let mut heads: Vec<String> = vec!["variant".into()];
    heads.extend(all_columns().map(|c| {
        if c.unit.is_empty() {
            c.label.to_owned()
        } else {
            format!("{} ({})", c.label, c.unit)
        }
    }));
    heads.push("ARTE used".into());
    let mut rows: Vec<Vec<String>> = Vec::new();
    for s in summaries {
        let mut row = vec![s.variant.label().to_owned()];
        for (c, st) in all_columns().zip(&s.stats) {
            row.push(fmt_stat(*st, c.decimals));
        }
        row.push(if s.variant.arte {
            format!("{:.1} %", 100.0 * s.arte_usage)
        } else {
            "-".into()
        });
        rows.push(row);
    }
    render(&heads, &rows)
}

/// Relative change of each ARTE variant's means against its baseline.
pub fn format_relative(summaries: &[VariantSummary]) -> String {
    // the first seven columns and the command's total variation
    let cols: Vec<(usize, &Column)> = all_columns()
        .enumerate()
        .filter(|(i, _)| *i < 7 || *i == COLUMNS.len())
        .collect();
    let mut heads: Vec<String> = vec!["ARTE vs base".into()];
    heads.extend(cols.iter().map(|(_, c)| c.label.to_owned()));
    let mut rows = Vec::new();
    for s in summaries.iter().filter(|s| s.variant.arte) {
        let Some(base) = summaries.iter().find(|b| b.variant == s.variant.baseline()) else {
            continue;
        };
        let mut row = vec![format!("{} / {}", s.variant.label(), base.variant.label())];
        for &(i, _) in &cols {
            let r = relative_change(s.stats[i], base.stats[i]);
            row.push(if r.is_finite() {
                format!("{r:+.1} %")
            } else {
                "-".into()
            });
        }
        rows.push(row);
    }
    render(&heads, &rows)
}

/// The paper's Table V: (variant, slip deviation, max torque, normalised area).
pub const PAPER_TABLE_V: [(Variant, f64, f64, f64); 6] = [
    (Variant::ALL[0], 0.4224, 686.80, 212.30),
    (Variant::ALL[1], 0.0654, 300.00, 258.21),
    (Variant::ALL[2], 0.1278, 188.58, 43.10),
    (Variant::ALL[3], 0.4672, 450.29, 173.48),
    (Variant::ALL[4], 0.0237, 300.00, 33.44),
    (Variant::ALL[5], 0.0522, 147.11, 26.83),
];

/// Ours (means) beside the paper's Table V for the three columns it has,
/// with the relative change against the baseline in both.
pub fn format_paper_comparison(summaries: &[VariantSummary]) -> String {
    let heads: Vec<String> = [
        "variant",
        "slip dev. ours",
        "paper",
        "max T ours",
        "paper",
        "effort ours",
        "paper",
        "Δslip ours",
        "Δslip paper",
    ]
    .map(str::to_owned)
    .to_vec();
    let mut rows = Vec::new();
    for (v, p_slip, p_max, p_eff) in PAPER_TABLE_V {
        let ours = summaries.iter().find(|s| s.variant == v);
        let get = |key: &str| ours.and_then(|s| s.stat(key)).map_or(f64::NAN, |s| s.mean);
        let (d_ours, d_paper) = if v.arte {
            let base_ours = summaries
                .iter()
                .find(|s| s.variant == v.baseline())
                .and_then(|s| s.stat("slip_deviation"));
            let d_ours = match (ours.and_then(|s| s.stat("slip_deviation")), base_ours) {
                (Some(a), Some(b)) => relative_change(a, b),
                _ => f64::NAN,
            };
            let p_base = PAPER_TABLE_V
                .iter()
                .find(|x| x.0 == v.baseline())
                .map_or(f64::NAN, |x| x.1);
            (d_ours, 100.0 * (p_slip - p_base) / p_base)
        } else {
            (f64::NAN, f64::NAN)
        };
        let num = |x: f64, d: usize| {
            if x.is_finite() {
                format!("{x:.d$}")
            } else {
                "-".into()
            }
        };
        let pct = |x: f64| {
            if x.is_finite() {
                format!("{x:+.1} %")
            } else {
                "".into()
            }
        };
        rows.push(vec![
            v.label().to_owned(),
            num(get("slip_deviation"), 4),
            num(p_slip, 4),
            num(get("max_torque"), 1),
            num(p_max, 2),
            num(get("torque_effort"), 1),
            num(p_eff, 2),
            pct(d_ours),
            pct(d_paper),
        ]);
    }
    render(&heads, &rows)
}

pub(crate) fn render(heads: &[String], rows: &[Vec<String>]) -> String {
    let ncol = heads.len();
    let mut w: Vec<usize> = heads.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate().take(ncol) {
            w[i] = w[i].max(c.chars().count());
        }
    }
    let mut out = String::new();
    let line = |out: &mut String, cells: &[String]| {
        for (i, c) in cells.iter().enumerate() {
            if i == 0 {
                let n = c.chars().count();
                let _ = write!(out, "{c}{}", " ".repeat(w[0].saturating_sub(n)));
            } else {
                let _ = write!(out, "  {}", pad(c, w[i]));
            }
        }
        out.push('\n');
    };
    line(&mut out, heads);
    let total: usize = w.iter().sum::<usize>() + 2 * (ncol - 1);
    out.push_str(&"-".repeat(total));
    out.push('\n');
    for r in rows {
        line(&mut out, r);
    }
    out
}

/// Header of `summary.csv`.
pub fn summary_header() -> String {
    let mut h = String::from("variant,seed");
    for c in COLUMNS {
        h.push(',');
        h.push_str(c.key);
    }
    h.push_str(",arte_usage,arte_frames,duration,samples,rejected,non_finite_cycles");
    for c in COMMAND_COLUMNS {
        h.push(',');
        h.push_str(c.key);
    }
    h
}

/// `summary.csv`: one row per run (variant, seed), every column of
/// [`COLUMNS`] plus ARTE usage and health counters, then (appended later,
/// so that older readers keep their column positions) [`COMMAND_COLUMNS`]. Floats in shortest
/// round-trip form; NaN as an empty field.
pub fn write_summary_csv<W: Write>(w: &mut W, results: &[RunResult]) -> io::Result<()> {
    writeln!(w, "{}", summary_header())?;
    for r in results {
        write!(w, "{},{}", r.variant.name(), r.seed)?;
        for c in COLUMNS {
            let x = (c.get)(r);
            if x.is_nan() {
                write!(w, ",")?;
            } else {
                write!(w, ",{x}")?;
            }
        }
        write!(
            w,
            ",{},{},{},{},{},{}",
            r.arte.usage(),
            r.arte.frames,
            r.metrics.duration,
            r.metrics.samples,
            r.metrics.rejected,
            r.non_finite_cycles
        )?;
        for c in COMMAND_COLUMNS {
            let x = (c.get)(r);
            if x.is_nan() {
                write!(w, ",")?;
            } else {
                write!(w, ",{x}")?;
            }
        }
        writeln!(w)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats() {
        let s = Stat::of([1.0, 2.0, 3.0, f64::NAN]);
        assert_eq!(s.n, 3);
        assert!((s.mean - 2.0).abs() < 1e-12);
        assert!((s.std - 1.0).abs() < 1e-12);
        assert!(Stat::of([]).mean.is_nan());
        assert_eq!(Stat::of([4.0]).std, 0.0);
        let a = Stat {
            mean: 0.4,
            std: 0.0,
            n: 1,
        };
        let b = Stat {
            mean: 1.0,
            std: 0.0,
            n: 1,
        };
        assert!((relative_change(a, b) + 60.0).abs() < 1e-9);
    }

    #[test]
    fn paper_reductions() {
        // SRC: 0.0654 -> 0.0237 is -63.8 %; MTTE: 0.1278 -> 0.0522 is -59.2 %.
        let src = 100.0 * (PAPER_TABLE_V[4].1 - PAPER_TABLE_V[1].1) / PAPER_TABLE_V[1].1;
        let mtte = 100.0 * (PAPER_TABLE_V[5].1 - PAPER_TABLE_V[2].1) / PAPER_TABLE_V[2].1;
        assert!((src + 63.76).abs() < 0.01, "{src}");
        assert!((mtte + 59.15).abs() < 0.01, "{mtte}");
    }

    #[test]
    fn non_finite_runs_are_named() {
        assert_eq!(non_finite_line(6, std::iter::empty()), None);
        let mfc: Variant = "mfc".parse().unwrap();
        let mtte_arte: Variant = "mtte-arte".parse().unwrap();
        assert_eq!(
            non_finite_line(6, [(mfc, 1, 2399), (mtte_arte, 3, 12)].into_iter()).as_deref(),
            Some(
                "2 of 6 runs had a non-finite plant state (their figures are not numbers; non_finite_cycles in summary.csv): mfc seed 1 (2399 cycles), mtte-arte seed 3 (12 cycles)"
            )
        );
    }
}
