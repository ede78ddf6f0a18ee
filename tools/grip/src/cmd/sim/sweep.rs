//! `grip sim --sweep SECTION.KEY=V1,V2,...`: the same batch (scenario,
//! seeds, variants, ARTE source) at every point of a grid of
//! `controllers.toml` values, reported as each ARTE variant's slip
//! deviation, mean acceleration and command variation relative to its
//! baseline: one table, and with `--out` `sweep.csv` and `sweep.png` (slip
//! ratio against acceleration ratio per controller: what a tuning trades).
//! Point 0 is the configuration as loaded; the grid points change only the
//! swept values. Sections `vehicle` and `sensors` are those of the vehicle
//! file (`--vehicle`, default `<config-dir>/vehicle.toml`), every other
//! section that of controllers.toml.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use grip_config::{ConfigDir, parse_controllers, parse_vehicle, read_file};
use grip_sim::report::summarize;
use grip_sim::{Job, RoadEstimator, SimError, SimSetup, Variant, run_batch_with};
use grip_tcs::ControllerKind;
use plotters::prelude::*;

use super::Loaded;

/// Most grid points one sweep may have.
pub const MAX_POINTS: usize = 200;

/// One `--sweep` axis: `SECTION.KEY=V1,V2,...` (or `SECTION.TABLE.KEY`).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The `[section]` of controllers.toml, or `vehicle`/`sensors` of the
    /// vehicle file.
    pub section: String,
    /// The key in it (`TABLE.KEY` for a table inside the section).
    pub key: String,
    /// The values, as TOML values.
    pub values: Vec<toml::Value>,
    /// The values as written.
    pub texts: Vec<String>,
}

impl Axis {
    /// `section.key`.
    pub fn name(&self) -> String {
        format!("{}.{}", self.section, self.key)
    }

    /// Whether it sets a value of the vehicle file (else of controllers.toml).
    pub fn of_vehicle(&self) -> bool {
        VEHICLE_SECTIONS.contains(&self.section.as_str())
    }
}

/// Each key swept once: a key given in two `--sweep`s would have the
/// later value overwrite the earlier at every point while the point's
/// label named both.
pub fn check_axes(axes: &[Axis]) -> anyhow::Result<()> {
    for (i, a) in axes.iter().enumerate() {
        if axes[..i].iter().any(|b| b.name() == a.name()) {
            anyhow::bail!(
                "--sweep {}: given twice; give all its values in one --sweep ({}={})",
                a.name(),
                a.name(),
                axes.iter()
                    .filter(|b| b.name() == a.name())
                    .flat_map(|b| b.texts.iter().map(String::as_str))
                    .collect::<Vec<_>>()
                    .join(",")
            );
        }
    }
    Ok(())
}

/// Axes with the index of their value at one point.
type Set<'a> = Vec<(&'a Axis, usize)>;

/// The sections of a vehicle file.
pub const VEHICLE_SECTIONS: [&str; 2] = ["vehicle", "sensors"];

fn is_name(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Parse one `--sweep` argument (clap's value parser).
pub fn parse_axis(s: &str) -> Result<Axis, String> {
    let usage = "expected SECTION.KEY=V1,V2,... (e.g. preview.cap_share=0.8,0.9,1.0)";
    let (name, list) = s.split_once('=').ok_or_else(|| format!("`{s}`: {usage}"))?;
    // SECTION.KEY, or SECTION.TABLE.KEY for a table inside a section
    // (e.g. preview.src.cap_share, `[preview.src]`).
    let (section, key) = name
        .trim()
        .split_once('.')
        .filter(|(a, b)| {
            let parts = b.split('.').count();
            is_name(a) && parts <= 2 && b.split('.').all(is_name)
        })
        .ok_or_else(|| format!("`{name}`: not a SECTION.KEY of controllers.toml; {usage}"))?;
    let mut values = Vec::new();
    let mut texts = Vec::new();
    for t in list.split(',').map(str::trim) {
        if t.is_empty() {
            return Err(format!("`{s}`: an empty value; {usage}"));
        }
        let v = toml::from_str::<toml::Table>(&format!("v = {t}"))
            .ok()
            .and_then(|mut tab| tab.remove("v"))
            .ok_or_else(|| {
                format!("`{name}={list}`: `{t}` is not a TOML value (a number, true/false or a quoted string)")
            })?;
        values.push(v);
        texts.push(t.to_owned());
    }
    Ok(Axis {
        section: section.to_owned(),
        key: key.to_owned(),
        values,
        texts,
    })
}

/// Every combination of the axes' value indices, the first axis slowest.
pub fn grid(axes: &[Axis]) -> Vec<Vec<usize>> {
    let mut points = vec![Vec::new()];
    for a in axes {
        let mut next = Vec::with_capacity(points.len() * a.values.len());
        for p in &points {
            for i in 0..a.values.len() {
                let mut q = p.clone();
                q.push(i);
                next.push(q);
            }
        }
        points = next;
    }
    points
}

/// `base` (the TOML file named `file`, as a table) with `set`'s values
/// (each axis with the index of its value); the section must exist (a key
/// the file lacks is added, and one the parser does not know is refused by
/// it, naming the key).
pub fn apply(
    base: &toml::Table,
    file: &str,
    set: &[(&Axis, usize)],
) -> Result<toml::Table, String> {
    let mut t = base.clone();
    for &(a, i) in set {
        let sec = t
            .get_mut(&a.section)
            .and_then(toml::Value::as_table_mut)
            .ok_or_else(|| {
                let sections: Vec<&str> = base
                    .iter()
                    .filter(|(_, v)| v.is_table())
                    .map(|(k, _)| k.as_str())
                    .collect();
                format!(
                    "--sweep {}: {file} has no [{}] (its sections: {})",
                    a.name(),
                    a.section,
                    sections.join(", ")
                )
            })?;
        let (sec, key) = match a.key.split_once('.') {
            // A table inside the section: added if the file lacks it.
            Some((sub, key)) => (
                sec.entry(sub)
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                    .as_table_mut()
                    .ok_or_else(|| {
                        format!(
                            "--sweep {}: {}.{sub} in {file} is a value, not a table",
                            a.name(),
                            a.section
                        )
                    })?,
                key,
            ),
            None => (sec, a.key.as_str()),
        };
        sec.insert(key.to_owned(), a.values[i].clone());
    }
    Ok(t)
}

/// `text` (the TOML file `path`) with `set`'s values, written back, and the
/// name to give the result in errors (a line number is one of the rewritten
/// text, not of the file on disk).
fn swept_text(
    path: &Path,
    text: &str,
    set: &[(&Axis, usize)],
) -> anyhow::Result<(PathBuf, String)> {
    let base: toml::Table =
        toml::from_str(text).with_context(|| format!("{}: not a TOML table", path.display()))?;
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let table = apply(&base, &name, set).map_err(anyhow::Error::msg)?;
    let out = toml::to_string(&table).context("--sweep: writing the values back")?;
    Ok((
        PathBuf::from(format!(
            "{} as rewritten with the --sweep values (line numbers are of that text, not of the file)",
            path.display()
        )),
        out,
    ))
}

/// One ARTE variant against its baseline at one point (means over seeds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ratios {
    /// The controller.
    pub kind: ControllerKind,
    /// Baseline, ARTE variant: slip deviation, mean acceleration, command
    /// variation per second.
    pub base: [f64; 3],
    /// See `base`.
    pub arte: [f64; 3],
    /// Runs of either variant with a non-finite state or rejected samples.
    pub unhealthy: usize,
}

impl Ratios {
    /// ARTE / baseline of slip deviation, acceleration, command variation.
    pub fn ratio(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.arte[i] / self.base[i])
    }
}

const KEYS: [&str; 3] = ["slip_deviation", "mean_accel", "cmd_tv_per_s"];

fn ratios(results: &[grip_sim::RunResult], kinds: &[ControllerKind]) -> Vec<Ratios> {
    let sums = summarize(results);
    let find = |v: Variant| sums.iter().find(|s| s.variant == v);
    kinds
        .iter()
        .filter_map(|&kind| {
            let b = find(Variant::new(kind, false))?;
            let a = find(Variant::new(kind, true))?;
            let mean = |s: &grip_sim::report::VariantSummary, k: &str| {
                s.stat(k).map_or(f64::NAN, |st| st.mean)
            };
            Some(Ratios {
                kind,
                base: KEYS.map(|k| mean(b, k)),
                arte: KEYS.map(|k| mean(a, k)),
                unhealthy: a.unhealthy_runs + b.unhealthy_runs,
            })
        })
        .collect()
}

/// A point of the sweep, ready to run: its label, its values (as written,
/// axis order; none for the configuration as loaded) and its setups.
struct Point {
    label: String,
    values: Vec<String>,
    setup: SimSetup,
    per_seed: Vec<(u64, SimSetup)>,
}

/// A point of the sweep: its label and, per controller, the ratios.
struct Row {
    label: String,
    values: Vec<String>,
    ratios: Vec<Ratios>,
}

/// What the sweep needs of `grip sim`'s arguments.
pub struct Request<'a> {
    /// What the run is (`run.toml` in `out`).
    pub record: &'a super::record::RunRecord,
    /// The axes.
    pub axes: &'a [Axis],
    /// The variants (at least one controller with and without ARTE).
    pub variants: &'a [Variant],
    /// The seeds.
    pub seeds: &'a [u64],
    /// Worker threads.
    pub threads: usize,
    /// The vehicle file the setup was loaded from (for `vehicle.*` and
    /// `sensors.*` axes).
    pub vehicle: &'a Path,
    /// Write sweep.csv and sweep.png here.
    pub out: Option<&'a Path>,
    /// `--sweep-target`: slip ratio at most, acceleration ratio at least.
    pub target: Option<(f64, f64)>,
    /// Scenario, vehicle and source, for the report's first line.
    pub describe: String,
    /// The same in one short line, for the figure.
    pub title: String,
}

/// Run the sweep.
pub fn run(
    config_dir: &Path,
    loaded: &Loaded,
    req: &Request<'_>,
    make: &(dyn Fn() -> Result<Box<dyn RoadEstimator>, SimError> + Sync),
) -> anyhow::Result<()> {
    let kinds: Vec<ControllerKind> = [
        ControllerKind::Mfc,
        ControllerKind::Src,
        ControllerKind::Mtte,
    ]
    .into_iter()
    .filter(|&k| {
        req.variants.contains(&Variant::new(k, false))
            && req.variants.contains(&Variant::new(k, true))
    })
    .collect();
    if kinds.is_empty() {
        anyhow::bail!(
            "--sweep compares each ARTE variant with its baseline: --variants must hold at least one controller with and without ARTE (e.g. src,src-arte; default all)"
        );
    }
    check_axes(req.axes)?;
    // counted before the grid is built: six axes of 30 values are 7.3e8
    // points, whose grid did not fit in memory
    let count = req
        .axes
        .iter()
        .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
        .filter(|&n| n <= MAX_POINTS);
    if count.is_none() {
        let shown = req
            .axes
            .iter()
            .map(|a| a.values.len().to_string())
            .collect::<Vec<_>>()
            .join(" x ");
        anyhow::bail!(
            "--sweep: {shown} grid points (the product of the axes' value counts) are more than {MAX_POINTS}"
        );
    }
    let points = grid(req.axes);
    let path = ConfigDir::new(config_dir).file("controllers.toml");
    let text = read_file(&path)?;
    // The files as loaded (errors name their line and field) ...
    let controllers = parse_controllers(&path, &text)?;
    let unreached = unreached(req.axes, &kinds, &controllers.preview);
    let vehicle_text = read_file(req.vehicle)?;
    parse_vehicle(req.vehicle, &vehicle_text)?;
    // ... and every point checked before the first run.
    // the gain checks of the controllers swept (MFC, SRC), each with its
    // answer for the configuration (said by sim.rs before the sweep), in
    // the words of a point's
    let checks: Vec<_> = super::POINT_CHECKS
        .iter()
        .filter(|(kind, _)| req.variants.iter().any(|v| v.kind == *kind))
        .map(|&(_, check)| (check, check(&loaded.setup)))
        .collect();
    let mut setups = vec![Point {
        label: "as configured".into(),
        values: Vec::new(),
        setup: loaded.setup.clone(),
        per_seed: loaded.per_seed.clone(),
    }];
    for p in &points {
        let values: Vec<String> = req
            .axes
            .iter()
            .zip(p)
            .map(|(a, &i)| a.texts[i].clone())
            .collect();
        let label = req
            .axes
            .iter()
            .zip(&values)
            .map(|(a, v)| format!("{} = {v}", a.name()))
            .collect::<Vec<_>>()
            .join(", ");
        let (on_vehicle, on_controllers): (Set<'_>, Set<'_>) = req
            .axes
            .iter()
            .zip(p.iter().copied())
            .partition(|(a, _)| a.of_vehicle());
        let (cpath, ctext) = swept_text(&path, &text, &on_controllers)?;
        let c = parse_controllers(&cpath, &ctext).with_context(|| format!("--sweep {label}"))?;
        let vehicle = if on_vehicle.is_empty() {
            None
        } else {
            let (vpath, vtext) = swept_text(req.vehicle, &vehicle_text, &on_vehicle)?;
            Some(parse_vehicle(&vpath, &vtext).with_context(|| format!("--sweep {label}"))?)
        };
        let build = |s: &SimSetup| -> anyhow::Result<SimSetup> {
            let s = s
                .with_controllers(c)
                .map_err(|e| anyhow::anyhow!("--sweep {label}: {e}"))?;
            match &vehicle {
                Some((v, sens)) => s
                    .with_vehicle(*v, *sens)
                    .map_err(|e| anyhow::anyhow!("--sweep {label}: {e}")),
                None => Ok(s),
            }
        };
        let setup = build(&loaded.setup)?;
        // MFC's gain against bound (4), SRC's gains against their
        // derivation, at this point's gains and vehicle, where the answer
        // is not the configuration's (said before the sweep starts)
        for (check, base) in &checks {
            if let Some(here) = check(&setup).filter(|here| Some(here) != base.as_ref()) {
                eprintln!("warning: --sweep {label}: {here}");
            }
        }
        let per_seed = loaded
            .per_seed
            .iter()
            .map(|(seed, ss)| build(ss).map(|x| (*seed, x)))
            .collect::<anyhow::Result<Vec<_>>>()?;
        setups.push(Point {
            label,
            values,
            setup,
            per_seed,
        });
    }

    if let Some(dir) = req.out {
        super::prepare_out(dir, req.record)?;
    }
    let mut jobs = Job::grid(req.variants, req.seeds, false);
    for j in &mut jobs {
        j.keep_trace = false;
    }
    eprintln!(
        "sweep: {} points (the configuration as loaded, then {} on the grid) x {} runs; {}",
        setups.len(),
        points.len(),
        jobs.len(),
        req.describe
    );
    let bar = indicatif::ProgressBar::new((setups.len() * jobs.len()) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} runs {elapsed_precise} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut rows = Vec::with_capacity(setups.len());
    // Points at which runs went past the end of their roads.
    let mut past_end = Vec::new();
    // Points at which runs went non-finite: the sweep fails naming them,
    // after its report and files are written (as `grip sim` does).
    let mut non_finite = Vec::new();
    for Point {
        label,
        values,
        setup,
        per_seed,
    } in &setups
    {
        let setup_of = |j: &Job| -> &SimSetup {
            per_seed
                .iter()
                .find(|(s, _)| *s == j.seed)
                .map_or(setup, |(_, s)| s)
        };
        let results = run_batch_with(&setup_of, &jobs, req.threads, make, &|_| bar.inc(1))
            .map_err(|e| anyhow::anyhow!("simulation ({label}): {e}"))?;
        let beyond = super::beyond_roads(&results, &|seed| {
            per_seed
                .iter()
                .find(|(s, _)| *s == seed)
                .map_or(setup, |(_, s)| s)
        });
        if beyond.runs > 0 {
            bar.suspend(|| {
                eprintln!(
                    "warning: --sweep point `{label}`: {} of {} runs went up to {:.2} {} past the end of the scenario's roads, where the last road simply continues",
                    beyond.runs,
                    results.len(),
                    beyond.worst,
                    beyond.unit
                );
            });
            past_end.push((label.clone(), beyond));
        }
        if let Some(runs) = non_finite_runs(&results) {
            non_finite.push(format!("#{} `{label}`: {runs}", rows.len()));
        }
        rows.push(Row {
            label: label.clone(),
            values: values.clone(),
            ratios: ratios(&results, &kinds),
        });
    }
    bar.finish_and_clear();

    let mut report = format_report(req, &kinds, &rows);
    for n in &unreached {
        report.push_str(&format!("Note: {n}\n"));
    }
    if !past_end.is_empty() {
        let worst = past_end.iter().map(|(_, b)| b.worst).fold(0.0, f64::max);
        let runs: usize = past_end.iter().map(|(_, b)| b.runs).sum();
        report.push_str(&format!(
            "Note: {runs} runs at {} of {} points went past the end of the scenario's roads (up to {worst:.2} {}), where the last road simply continues (stderr names the points).\n",
            past_end.len(),
            setups.len(),
            past_end[0].1.unit
        ));
    }
    print!("{report}");
    if let Some(dir) = req.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("sweep.csv");
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(&csv).with_context(|| format!("creating {}", csv.display()))?,
        );
        f.write_all(format_csv(req.axes, &rows).as_bytes())
            .and_then(|()| f.flush())
            .with_context(|| format!("writing {}", csv.display()))?;
        std::fs::write(dir.join("sweep.txt"), &report)
            .with_context(|| format!("writing {}", dir.join("sweep.txt").display()))?;
        let png = dir.join("sweep.png");
        figure(&png, req, &kinds, &rows)
            .map_err(|e| anyhow::anyhow!("drawing {}: {e}", png.display()))?;
        eprintln!("wrote {}", dir.display());
    }
    // a run whose plant state went non-finite has no figures: the report
    // and files are written (to look at), and the sweep fails naming the
    // points and their runs
    if let Some(line) = non_finite_points(&non_finite, setups.len()) {
        anyhow::bail!(line);
    }
    Ok(())
}

/// The runs of one point whose plant state went non-finite, each by
/// variant and seed with its count of such cycles ("mfc seed 1 (2399
/// cycles), src seed 1 (12 cycles)" of "2 of 4 runs"); `None` when every
/// run stayed finite.
fn non_finite_runs(results: &[grip_sim::RunResult]) -> Option<String> {
    grip_sim::report::non_finite_listing(results)
        .map(|(n, list)| format!("{n} of {} runs: {list}", results.len()))
}

/// The one line the sweep fails with when runs at some of its `points`
/// points went non-finite (`bad`: each such point's number, label and runs,
/// from [`non_finite_runs`]); `None` when none did.
fn non_finite_points(bad: &[String], points: usize) -> Option<String> {
    (!bad.is_empty()).then(|| {
        format!(
            "--sweep: runs at {} of {points} points had a non-finite plant state (their ratios are not numbers; unhealthy_runs in sweep.csv): {}",
            bad.len(),
            bad.join("; ")
        )
    })
}

/// The shared `[preview]` trade values swept that a controller's own
/// `[preview.<kind>]` overrides (so the sweep does not move that ARTE
/// variant), one sentence each.
fn unreached(
    axes: &[Axis],
    kinds: &[ControllerKind],
    preview: &grip_tcs::PreviewParams,
) -> Vec<String> {
    let mut notes = Vec::new();
    for a in axes.iter().filter(|a| a.section == "preview") {
        for &k in kinds {
            if let Some(v) = preview.trade(k).get(&a.key) {
                let name = k.as_str();
                notes.push(format!(
                    "--sweep {} does not reach {}-ARTE: its own [preview.{name}] {} = {v} wins; sweep preview.{name}.{} for it.",
                    a.name(),
                    name.to_ascii_uppercase(),
                    a.key,
                    a.key
                ));
            }
        }
    }
    notes
}

fn format_report(req: &Request<'_>, kinds: &[ControllerKind], rows: &[Row]) -> String {
    let mut s = format!(
        "\nSweep: {}; {} seeds ({}..={}). Each ARTE variant against its baseline, means over the seeds:\n\
         slip = slip deviation ratio, accel = mean acceleration ratio, TV = command variation ratio.\n\n",
        req.describe,
        req.seeds.len(),
        req.seeds.first().copied().unwrap_or(0),
        req.seeds.last().copied().unwrap_or(0),
    );
    let width = rows.iter().map(|r| r.label.len()).max().unwrap_or(5).max(5);
    s.push_str(&format!("{:>3}  {:<width$}", "#", "point"));
    for k in kinds {
        let l = Variant::new(*k, true).label();
        s.push_str(&format!(" | {l:>9} slip  accel     TV"));
    }
    s.push('\n');
    for (i, r) in rows.iter().enumerate() {
        s.push_str(&format!("{i:>3}  {:<width$}", r.label));
        for q in &r.ratios {
            let [a, b, c] = q.ratio();
            s.push_str(&format!(" | {a:>14.3}x {b:>6.4}x {c:>5.2}x"));
        }
        let bad: usize = r.ratios.iter().map(|q| q.unhealthy).sum();
        if bad > 0 {
            s.push_str(&format!("  ({bad} unhealthy runs)"));
        }
        s.push('\n');
    }
    if let Some((slip, accel)) = req.target {
        s.push_str(&format!(
            "\nTarget (--sweep-target): slip <= {slip}x and accel >= {accel}x. Met:"
        ));
        for k in kinds {
            let met: Vec<String> = rows
                .iter()
                .enumerate()
                .filter(|(_, r)| {
                    r.ratios.iter().any(|q| {
                        let [a, b, _] = q.ratio();
                        q.kind == *k && a <= slip && b >= accel
                    })
                })
                .map(|(i, _)| format!("#{i}"))
                .collect();
            let l = Variant::new(*k, true).label();
            let list = if met.is_empty() {
                "no point".to_owned()
            } else {
                met.join(" ")
            };
            s.push_str(&format!(" {l}: {list};"));
        }
        s.push('\n');
    }
    s
}

fn format_csv(axes: &[Axis], rows: &[Row]) -> String {
    let mut s = String::from("point,label");
    for a in axes {
        s.push(',');
        s.push_str(&a.name());
    }
    s.push_str(",controller,slip_base,slip_arte,slip_ratio,accel_base,accel_arte,accel_ratio,cmd_tv_base,cmd_tv_arte,cmd_tv_ratio,unhealthy_runs\n");
    for (i, r) in rows.iter().enumerate() {
        for q in &r.ratios {
            s.push_str(&format!("{i},\"{}\"", r.label));
            for k in 0..axes.len() {
                s.push(',');
                s.push_str(r.values.get(k).map_or("", String::as_str));
            }
            s.push_str(&format!(",{}", Variant::new(q.kind, false).name()));
            let rt = q.ratio();
            for k in 0..3 {
                s.push_str(&format!(",{},{},{}", q.base[k], q.arte[k], rt[k]));
            }
            s.push_str(&format!(",{}\n", q.unhealthy));
        }
    }
    s
}

type Res = Result<(), Box<dyn std::error::Error>>;

/// Which grid points of a panel carry a label: a point whose label would
/// sit within a label's size (80 x 12 pixels of a `panel` of `(w, h)`
/// pixels over x `x0..x1` and y `0..y1`) of an earlier labelled point's
/// gives it up and is counted with that one. Per point, how many points its
/// label stands for (0: no label of its own).
fn label_counts(
    pts: &[(f64, f64)],
    (x0, x1): (f64, f64),
    y1: f64,
    (w, h): (f64, f64),
) -> Vec<usize> {
    let px = |&(a, s): &(f64, f64)| ((a - x0) / (x1 - x0) * w, s / y1 * h);
    let mut counts = vec![0usize; pts.len()];
    let mut labelled: Vec<(usize, (f64, f64))> = Vec::new();
    for (i, p) in pts.iter().enumerate() {
        let (x, y) = px(p);
        match labelled
            .iter()
            .find(|(_, (lx, ly))| (x - lx).abs() < 80.0 && (y - ly).abs() < 12.0)
        {
            Some(&(j, _)) => counts[j] += 1,
            None => {
                counts[i] = 1;
                labelled.push((i, (x, y)));
            }
        }
    }
    counts
}

/// One panel per controller: slip ratio (y) against acceleration ratio (x)
/// of every point, the loaded configuration marked, the quadrant "no more
/// slip, no less traction" shaded, and the target box if given.
fn figure(path: &Path, req: &Request<'_>, kinds: &[ControllerKind], rows: &[Row]) -> Res {
    crate::plot::init_fonts();
    const PW: u32 = 640;
    const H: u32 = 640;
    let w = PW * kinds.len() as u32;
    let root = BitMapBackend::new(path, (w, H)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(70);
    let (body, bottom) = rest.split_vertically(H - 70 - 30);
    top.draw_text(
        &format!("ARTE variant / its baseline over {} seeds", req.seeds.len()),
        &("sans-serif", 24).into_font().color(&BLACK),
        (15, 8),
    )?;
    top.draw_text(
        &req.title,
        &("sans-serif", 15).into_font().color(&BLACK),
        (15, 42),
    )?;
    let panels = body.split_evenly((1, kinds.len()));
    for (area, &k) in panels.iter().zip(kinds) {
        let pts: Vec<(f64, f64, usize)> = rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.ratios.iter().find(|q| q.kind == k).map(|q| (q, i)))
            .map(|(q, i)| {
                let [s, a, _] = q.ratio();
                (a, s, i)
            })
            .filter(|(a, s, _)| a.is_finite() && s.is_finite())
            .collect();
        let mut xs: Vec<f64> = pts.iter().map(|p| p.0).collect();
        xs.push(1.0);
        let mut ys: Vec<f64> = pts.iter().map(|p| p.1).collect();
        ys.push(1.0);
        if let Some((slip, accel)) = req.target {
            xs.push(accel);
            ys.push(slip);
        }
        let (x0, x1) = xs
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let pad = ((x1 - x0) * 0.1).max(0.005);
        let (x0, x1) = (x0 - pad, x1 + pad);
        let y1 = ys.iter().copied().fold(0.0, f64::max) * 1.08;
        let mut chart = ChartBuilder::on(area)
            .caption(Variant::new(k, true).label(), ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, 0.0..y1)?;
        chart
            .configure_mesh()
            .x_desc("mean acceleration, ARTE / baseline")
            .y_desc("slip deviation, ARTE / baseline")
            .x_labels(6)
            .y_labels(8)
            .label_style(("sans-serif", 14))
            .draw()?;
        // No more slip and no less traction than the baseline.
        chart.draw_series(std::iter::once(Rectangle::new(
            [(1.0_f64.max(x0), 0.0), (x1, 1.0_f64.min(y1))],
            RGBColor(200, 235, 200).filled(),
        )))?;
        if let Some((slip, accel)) = req.target {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(accel.max(x0), 0.0), (x1, slip.min(y1))],
                RGBColor(120, 190, 120).mix(0.5).filled(),
            )))?;
        }
        let grey = RGBColor(120, 120, 120);
        chart.draw_series(DashedLineSeries::new(
            vec![(1.0, 0.0), (1.0, y1)],
            6,
            4,
            grey.stroke_width(1),
        ))?;
        chart.draw_series(DashedLineSeries::new(
            vec![(x0, 1.0), (x1, 1.0)],
            6,
            4,
            grey.stroke_width(1),
        ))?;
        // Grid points that land on one spot share one label ("+k").
        let grid: Vec<(f64, f64)> = pts
            .iter()
            .filter(|p| p.2 != 0)
            .map(|p| (p.0, p.1))
            .collect();
        let panel = (f64::from(PW) - 90.0, f64::from(H - 100) - 90.0);
        let mut counts = label_counts(&grid, (x0, x1), y1, panel).into_iter();
        for &(a, s, i) in &pts {
            // The configuration as loaded: red, labelled below its point;
            // a grid point: blue, its values above right.
            let (colour, size, label, at) = if i == 0 {
                (RED, 8, "as configured".to_owned(), (10, 4))
            } else {
                let label = match counts.next().unwrap_or(1) {
                    0 => String::new(),
                    1 => rows[i].values.join("/"),
                    n => format!("{} (+{})", rows[i].values.join("/"), n - 1),
                };
                (BLUE, 5, label, (7, -16))
            };
            chart.draw_series(std::iter::once(
                EmptyElement::at((a, s))
                    + Circle::new((0, 0), size, colour.filled())
                    + Text::new(label, at, ("sans-serif", 13).into_font().color(&BLACK)),
            ))?;
        }
    }
    let legend = format!(
        "red: the configuration as loaded; blue: the grid ({}); green: no more slip and no less traction than the baseline{}",
        req.axes
            .iter()
            .map(Axis::name)
            .collect::<Vec<_>>()
            .join(" / "),
        req.target.map_or(String::new(), |(s, a)| format!(
            "; dark green: the target (slip <= {s}x, accel >= {a}x)"
        ))
    );
    bottom.draw_text(
        &legend,
        &("sans-serif", 14).into_font().color(&BLACK),
        (15, 6),
    )?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axis_parses_and_bad_ones_are_named() {
        let a = parse_axis("preview.cap_share=0.8, 0.9,1").unwrap();
        assert_eq!(a.name(), "preview.cap_share");
        assert_eq!(a.texts, ["0.8", "0.9", "1"]);
        assert_eq!(a.values[0], toml::Value::Float(0.8));
        assert_eq!(a.values[2], toml::Value::Integer(1));
        for (bad, says) in [
            ("preview.cap_share", "expected SECTION.KEY"),
            ("cap_share=0.8", "not a SECTION.KEY"),
            ("preview.cap share=0.8", "not a SECTION.KEY"),
            ("preview.cap_share=0.8,,1", "an empty value"),
            ("preview.cap_share=0.8,abc", "`abc` is not a TOML value"),
            ("preview.src.x.cap_share=0.8", "not a SECTION.KEY"),
            ("preview.src..cap_share=0.8", "not a SECTION.KEY"),
        ] {
            let e = parse_axis(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn the_grid_is_every_combination_first_axis_slowest() {
        let a = parse_axis("preview.cap_share=0.8,0.9").unwrap();
        let b = parse_axis("preview.slip_share=0.9,0.95,1.0").unwrap();
        let g = grid(&[a, b]);
        assert_eq!(g.len(), 6);
        assert_eq!(g[0], [0, 0]);
        assert_eq!(g[1], [0, 1]);
        assert_eq!(g[5], [1, 2]);
        assert_eq!(grid(&[]), vec![Vec::<usize>::new()]);
    }

    #[test]
    fn a_key_swept_twice_is_refused_naming_it() {
        let axes = [
            parse_axis("vehicle.mass=1000").unwrap(),
            parse_axis("preview.cap_share=0.8").unwrap(),
            parse_axis("vehicle.mass=1200,1600").unwrap(),
        ];
        let e = check_axes(&axes).unwrap_err().to_string();
        assert!(
            e.contains("--sweep vehicle.mass: given twice")
                && e.contains("vehicle.mass=1000,1200,1600"),
            "{e}"
        );
        check_axes(&axes[..2]).unwrap();
        // a per-controller key is another key
        check_axes(&[
            parse_axis("preview.cap_share=0.8").unwrap(),
            parse_axis("preview.src.cap_share=0.8").unwrap(),
        ])
        .unwrap();
    }

    #[test]
    fn apply_sets_the_value_and_names_a_missing_section() {
        let base: toml::Table =
            toml::from_str("[preview]\ncap_share = 1.0\n[mfc]\nk = 1\n").unwrap();
        let a = parse_axis("preview.cap_share=0.7,0.8").unwrap();
        assert!(!a.of_vehicle());
        let t = apply(&base, "controllers.toml", &[(&a, 1)]).unwrap();
        assert_eq!(t["preview"]["cap_share"], toml::Value::Float(0.8));
        assert_eq!(base["preview"]["cap_share"], toml::Value::Float(1.0));
        let b = parse_axis("previw.cap_share=0.7").unwrap();
        let e = apply(&base, "controllers.toml", &[(&b, 0)]).unwrap_err();
        assert!(
            e.contains("controllers.toml has no [previw]") && e.contains("mfc, preview"),
            "{e}"
        );
        // A table inside a section: set where it is, added where it is not.
        let base: toml::Table =
            toml::from_str("[preview]\ncap_share = 1.0\n[preview.src]\ncap_share = 0.9\n").unwrap();
        let c = parse_axis("preview.src.cap_share=0.7,0.8").unwrap();
        assert_eq!(c.name(), "preview.src.cap_share");
        let t = apply(&base, "controllers.toml", &[(&c, 1)]).unwrap();
        assert_eq!(t["preview"]["src"]["cap_share"], toml::Value::Float(0.8));
        assert_eq!(t["preview"]["cap_share"], toml::Value::Float(1.0));
        let m = parse_axis("preview.mfc.slip_share=0.9").unwrap();
        let t = apply(&base, "controllers.toml", &[(&m, 0)]).unwrap();
        assert_eq!(t["preview"]["mfc"]["slip_share"], toml::Value::Float(0.9));
        let v = parse_axis("preview.cap_share.x=0.9").unwrap();
        let e = apply(&base, "controllers.toml", &[(&v, 0)]).unwrap_err();
        assert!(
            e.contains("preview.cap_share in controllers.toml is a value"),
            "{e}"
        );
        assert!(parse_axis("vehicle.mic_lead_m=0,1").unwrap().of_vehicle());
        assert!(parse_axis("sensors.v_noise_std=0.02").unwrap().of_vehicle());
    }

    #[test]
    fn points_on_one_spot_share_a_label() {
        // Three points on one spot, one a label's width away, one far.
        let pts = [
            (1.0, 0.5),
            (1.0, 0.5),
            (1.0005, 0.501),
            (1.02, 0.5),
            (1.0, 0.8),
        ];
        let c = label_counts(&pts, (0.95, 1.05), 1.0, (500.0, 400.0));
        assert_eq!(c, vec![3, 0, 0, 1, 1]);
    }
}
