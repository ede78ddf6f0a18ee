//! `grip inspect --plot DIR`: `drive.png` (speeds, slip and torque over the
//! bands of the road under the driven wheel, the torque panel (torques at
//! one driven wheel, after the gear, as all of grip's) with the torque cap
//! the loop's road belief put in force, then four strips: the road at the
//! microphone, ARTE's estimate (those below the loop's confidence gate
//! pale and hatched), the loop's road belief (what the controller acted
//! on) and the road under the wheel) and `timing.png` (wake-up latency
//! histogram of the control loop over the whole log, as its title says).
//!
//! Every trace stays in its panel: [`crate::plot::clip_trace`] clamps it to
//! the panel's y range (the key says so when it did) and
//! [`crate::plot::draw_trace`] draws it segment by segment.
//!
//! Time runs from the scenario start (marked) when the log shows it, else
//! from the first message; the x range is that of the data the log holds
//! (ground truth and cycle records), so a log without ground truth (from
//! the car) still shows the command, and its slip panel the slip the loop
//! measured (`grip_drive::summary::measured::slip`) instead of the truth's. The title names the log, its run and
//! when it was recorded (or generated).

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use plotters::prelude::*;

use super::export::TimeBase;
use crate::plot::{
    Area, Band, CLAMPED, PlotResult as Res, clip_trace, draw_bands, draw_trace, init_fonts,
    road_colour, runs,
};
use grip_drive::DriveLog;
use grip_drive::summary::{Gate, GateFrom, Percentiles};

const W: u32 = 1600;
const TITLE_H: u32 = 80;
const PANEL_H: u32 = 330;
/// Height of the strips (and of their key: the roads, 8 a column, then the
/// gate's entry).
const STRIPS_H: u32 = 290;
/// Width of the key column at the right of every panel (outside the data).
const LEGEND_W: u32 = 210;
/// Width of the y labels (and of the strips' row names).
const LABEL_W: u32 = 100;

const ROW_MIC: f64 = 3.0;
const ROW_ARTE: f64 = 2.0;
const ROW_BELIEF: f64 = 1.0;
const ROW_WHEEL: f64 = 0.0;
const ROWS: f64 = 4.0;

/// The torque cap's colour in the torque panel.
const CAP_COLOUR: RGBColor = RGBColor(190, 0, 190);

/// The torque panel's caption and y axis: grip's torques are those of ONE
/// driven wheel, after the gear (`vehicle.toml` `torque_max`: the motor's
/// limit × gear ratio ÷ n_driven), not the motor's.
const TORQUE_CAPTION: &str = "wheel torque, one driven wheel (N m; motor × gear ratio ÷ n_driven): tcs-loop's demand T_d, command T* and road-belief cap; T";
const TORQUE_AXIS: &str = "wheel torque, one driven wheel (N m)";

/// How strongly a road's colour fills a strip (and its key's swatch):
/// mixed with white, opaque, so that ARTE's overlapping frames (each from
/// its frame's start to its publication) show the key's colour, not a
/// darker one where two translucent fills overlap.
const STRIP_SHARE: f64 = 0.85;
/// The same for ARTE's estimates below the loop's confidence gate (drawn
/// hatched besides).
const BELOW_GATE_SHARE: f64 = 0.3;
/// Spacing of the hatching of estimates below the gate, pixels.
const HATCH_PX: f64 = 7.0;

/// `c` mixed with white: `share` of `c`, as an opaque colour.
fn on_white(c: RGBColor, share: f64) -> RGBColor {
    let m = |x: u8| (255.0 - share * (255.0 - f64::from(x))).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// The loop's confidence gate (`controllers.toml` `[arte] min_confidence`:
/// the controller takes no estimate less confident) as the summary takes
/// it, and where it came from ([`grip_drive::summary::gate_of`]: for a
/// replay's log the gate the replay ran, or that the replay changed it).
fn gate_of(log: &DriveLog) -> Gate {
    grip_drive::summary::gate_of(log)
}

/// The gate's lines in the key.
trait GateKey {
    /// The key's lines beside the hatched swatch (the key column holds
    /// about 25 characters).
    fn key(&self) -> [String; 3];
}

impl GateKey for Gate {
    fn key(&self) -> [String; 3] {
        [
            "ARTE, below the gate:".to_owned(),
            format!("confidence < {}", self.min_confidence),
            match self.from {
                GateFrom::Log => "(log's controllers.toml)",
                GateFrom::Default => "(default: not in the log)",
                GateFrom::ReplayChanged => "(source's; replay changed)",
                GateFrom::Replay => "(the replay's, as it ran)",
                GateFrom::Unknown => "(unknown: its default)",
            }
            .to_owned(),
        ]
    }
}

/// The drive's series, times on [`TimeBase::axis`].
struct Series {
    tb: TimeBase,
    /// x range of the figure.
    span: (f64, f64),
    /// Ground truth.
    t: Vec<f64>,
    v: Vec<f64>,
    r_omega: Vec<f64>,
    lambda: Vec<f64>,
    torque: Vec<f64>,
    wheel: Vec<String>,
    mic: Vec<String>,
    /// Cycle records.
    ct: Vec<f64>,
    demand: Vec<f64>,
    cmd: Vec<f64>,
    meas_torque: Vec<f64>,
    meas_r_omega: Vec<f64>,
    /// Cycles with a valid measured vehicle speed, and that speed.
    cvt: Vec<f64>,
    meas_v: Vec<f64>,
    /// Cycles with a measured slip λ_m (`grip_drive::summary::measured`:
    /// valid V, max(r ω, V) at least its floor), and that slip.
    clt: Vec<f64>,
    meas_lambda: Vec<f64>,
    /// ARTE: (frame start, publication, class name or "").
    est: Vec<(f64, f64, String)>,
    /// Per estimate: its confidence below the loop's gate.
    below_gate: Vec<bool>,
    /// The loop's confidence gate.
    gate: Gate,
    /// The loop's road belief ([`belief_runs`]).
    belief: Vec<(f64, f64, String)>,
    /// The torque cap in force per cycle record, N m (NaN: none).
    cap: Vec<f64>,
    /// Every road name in the figure, sorted (the colour palette's order).
    names: Vec<String>,
}

/// The smallest and largest of `ns`.
fn lohi(ns: impl Iterator<Item = u64>) -> Option<(u64, u64)> {
    ns.fold(None, |acc, n| {
        Some(acc.map_or((n, n), |(a, b): (u64, u64)| (a.min(n), b.max(n))))
    })
}

/// The x range of the figure on `tb`'s axis: from the first to the last
/// ground-truth sample or cycle record, else estimate or CAN frame.
fn x_span(log: &DriveLog, tb: &TimeBase) -> (f64, f64) {
    let main = log
        .truth
        .iter()
        .map(|g| g.stamp_ns)
        .chain(log.cycles.iter().map(|c| c.stamp_ns));
    let other = log
        .roads
        .iter()
        .map(|e| e.stamp_ns)
        .chain(log.can.iter().map(|c| c.stamp_ns));
    let Some((lo, hi)) = lohi(main).or_else(|| lohi(other)) else {
        return (0.0, 1.0);
    };
    let (lo, hi) = (tb.axis(lo), tb.axis(hi));
    (lo, hi.max(lo + 1e-3))
}

/// The loop's road belief (`belief_road` of tcs-loop's cycle records, the
/// road its controller acted on, named by the road catalogue attached to
/// the log, else `road #i`): (from, to, name or "" for no belief), one run
/// per stretch of cycles with the same belief, each up to the next run's
/// first cycle. Empty when no cycle holds a belief (ARTE off, or a log
/// whose records do not carry it).
fn belief_runs(log: &DriveLog, tb: &TimeBase) -> Vec<(f64, f64, String)> {
    if log
        .cycles
        .iter()
        .all(|c| c.belief_road == grip_msgs::NO_CLASS)
    {
        return Vec::new();
    }
    let catalogue = super::export::catalogue_names(log).unwrap_or_default();
    let names: Vec<String> = log
        .cycles
        .iter()
        .map(|c| match c.belief_road {
            grip_msgs::NO_CLASS => String::new(),
            i => usize::try_from(i)
                .ok()
                .and_then(|i| catalogue.get(i))
                .cloned()
                .unwrap_or_else(|| format!("road #{i}")),
        })
        .collect();
    let t = |k: usize| tb.axis(log.cycles[k].stamp_ns);
    runs(&names)
        .into_iter()
        .map(|(a, b, name)| (t(a), t(b.min(names.len() - 1)), name))
        .collect()
}

fn series(log: &DriveLog, r: f64, v_eps: f64) -> Series {
    let tb = TimeBase::of(log);
    let x = |ns: u64| tb.axis(ns);
    let name = |n: Option<&str>| n.unwrap_or("?").to_owned();
    let valid_v: Vec<_> = log.cycles.iter().filter(|c| c.v_valid != 0).collect();
    // the measured section's rule (no slip in the loop's safe state, ...)
    let slips: Vec<(f64, f64)> = log
        .cycles
        .iter()
        .filter_map(|c| {
            grip_drive::summary::measured::cycle_slip(r, v_eps, c)
                .ok()
                .map(|l| (x(c.stamp_ns), l))
        })
        .collect();
    let est: Vec<(f64, f64, String)> = log
        .roads
        .iter()
        .map(|e| {
            (
                x(e.frame_t0_ns),
                x(e.stamp_ns),
                if e.class_index == grip_msgs::NO_CLASS {
                    String::new()
                } else {
                    name(e.class_name())
                },
            )
        })
        .collect();
    let gate = gate_of(log);
    // a confidence that is no number is below any gate (the loop ignores
    // the estimate)
    let below_gate: Vec<bool> = log
        .roads
        .iter()
        .map(|e| !(e.confidence.is_finite() && e.confidence >= gate.min_confidence))
        .collect();
    let wheel: Vec<String> = log.truth.iter().map(|g| name(g.road_name())).collect();
    let mic: Vec<String> = log.truth.iter().map(|g| name(g.mic_road_name())).collect();
    let belief = belief_runs(log, &tb);
    let mut names: Vec<String> = wheel
        .iter()
        .chain(&mic)
        .chain(est.iter().map(|e| &e.2))
        .chain(belief.iter().map(|b| &b.2))
        .filter(|n| !n.is_empty())
        .cloned()
        .collect();
    names.sort();
    names.dedup();
    Series {
        tb,
        span: x_span(log, &tb),
        t: log.truth.iter().map(|g| x(g.stamp_ns)).collect(),
        v: log.truth.iter().map(|g| g.v).collect(),
        r_omega: log.truth.iter().map(|g| r * g.omega).collect(),
        lambda: log.truth.iter().map(|g| g.lambda).collect(),
        torque: log.truth.iter().map(|g| g.torque).collect(),
        wheel,
        mic,
        ct: log.cycles.iter().map(|c| x(c.stamp_ns)).collect(),
        demand: log.cycles.iter().map(|c| c.demand).collect(),
        cmd: log.cycles.iter().map(|c| c.torque_cmd).collect(),
        meas_torque: log.cycles.iter().map(|c| c.torque).collect(),
        meas_r_omega: log.cycles.iter().map(|c| r * c.omega).collect(),
        cvt: valid_v.iter().map(|c| x(c.stamp_ns)).collect(),
        meas_v: valid_v.iter().map(|c| c.v).collect(),
        clt: slips.iter().map(|p| p.0).collect(),
        meas_lambda: slips.iter().map(|p| p.1).collect(),
        est,
        below_gate,
        gate,
        belief,
        cap: log.cycles.iter().map(|c| c.torque_cap).collect(),
        names,
    }
}

impl Series {
    fn has_truth(&self) -> bool {
        !self.t.is_empty()
    }

    fn colour(&self, road: &str) -> RGBColor {
        let idx = self.names.iter().position(|n| n == road).unwrap_or(0);
        road_colour(road, idx)
    }

    /// A strip's (and the key's) opaque fill of `road` ("": none, white).
    fn strip_fill(&self, road: &str) -> RGBColor {
        if road.is_empty() {
            WHITE
        } else {
            on_white(self.colour(road), STRIP_SHARE)
        }
    }

    /// Bands of a per-truth-sample road sequence.
    fn bands(&self, roads: &[String]) -> Vec<Band> {
        let t_end = self.t.last().copied().unwrap_or(self.span.1);
        runs(roads)
            .into_iter()
            .map(|(a, b, road)| Band {
                t0: self.t[a],
                t1: self.t.get(b).copied().unwrap_or(t_end),
                colour: self.colour(&road),
                label: road,
            })
            .collect()
    }
}

fn range(xs: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = xs
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-6);
    (lo - 0.05 * span, hi + 0.08 * span)
}

/// A key entry at the right of a panel.
enum Key {
    Line(String, RGBColor),
    Text(String),
}

/// The key column `area` (outside the data): one entry per row.
fn key(area: &Area<'_>, top: i32, entries: &[Key]) -> Res {
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    for (i, e) in entries.iter().enumerate() {
        let y = top + 22 * i as i32;
        match e {
            Key::Line(label, c) => {
                area.draw(&PathElement::new(
                    vec![(10, y + 8), (38, y + 8)],
                    c.stroke_width(3),
                ))?;
                area.draw_text(label, &font, (46, y))?;
            }
            Key::Text(t) => area.draw_text(t, &font, (10, y))?,
        }
    }
    Ok(())
}

/// A panel of `s` titled `caption`, its y axis described by `y_desc`
/// (None: the caption says it): the bands of the road under the driven
/// wheel drawn pale behind (named if `label_roads`), the scenario start
/// marked, `lines`
/// (label, times, values, colour) on top, clamped to the y range, their
/// key at the right (a line clamped to the axis said so, one with samples
/// but no finite value named as absent), and `note` written across the
/// panel (e.g. that the data is missing).
fn panel(
    area: &Area<'_>,
    s: &Series,
    (caption, y_desc): (&str, Option<&str>),
    (y_lo, y_hi): (f64, f64),
    label_roads: bool,
    lines: &[(&str, &[f64], &[f64], RGBColor)],
    note: Option<&str>,
) -> Res {
    let (plot, side) = area.split_horizontally(W - LEGEND_W);
    let (t_lo, t_hi) = s.span;
    let span = t_hi - t_lo;
    let mut chart = ChartBuilder::on(&plot)
        .margin(8)
        .caption(caption, ("sans-serif", 20))
        .x_label_area_size(34)
        .y_label_area_size(LABEL_W)
        .build_cartesian_2d(t_lo..t_hi, y_lo..y_hi)?;
    draw_bands(
        &mut chart,
        &s.bands(&s.wheel),
        (t_lo, t_hi),
        (y_lo, y_hi),
        label_roads,
    )?;
    if s.tb.scenario_ns.is_some() && (t_lo..=t_hi).contains(&0.0) {
        chart.draw_series(LineSeries::new(
            [(0.0, y_lo), (0.0, y_hi)],
            BLACK.mix(0.7).stroke_width(1),
        ))?;
        if label_roads {
            chart.draw_series(std::iter::once(Text::new(
                "scenario start",
                (0.005 * span, y_hi - 0.12 * (y_hi - y_lo)),
                ("sans-serif", 15).into_font().color(&BLACK),
            )))?;
        }
    }
    let mut mesh = chart.configure_mesh();
    mesh.disable_mesh()
        .x_desc(s.tb.axis_label())
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15));
    if let Some(d) = y_desc {
        mesh.y_desc(d);
    }
    mesh.draw()?;
    let mut entries: Vec<Key> = Vec::new();
    for &(label, ts, ys, c) in lines {
        if ts.is_empty() {
            continue;
        }
        let trace = clip_trace(
            ts.iter().copied().zip(ys.iter().copied()),
            (t_lo, t_hi),
            (y_lo, y_hi),
        );
        draw_trace(&mut chart, &trace, c)?;
        if trace.runs.is_empty() {
            entries.push(Key::Text(format!("{label}: none")));
        } else {
            entries.push(Key::Line(label.to_owned(), c));
            if trace.clamped {
                entries.push(Key::Text(format!("   {CLAMPED}")));
            }
        }
    }
    if let Some(note) = note {
        chart.draw_series(std::iter::once(Text::new(
            note.to_owned(),
            (t_lo + 0.3 * span, (y_lo + y_hi) / 2.0),
            ("sans-serif", 22).into_font().color(&BLACK),
        )))?;
    }
    if label_roads && s.has_truth() {
        entries.extend(
            ["", "background: the road", "under the driven wheel"].map(|t| Key::Text(t.into())),
        );
    }
    key(&side, 40, &entries)
}

/// The hatching (`/`, [`HATCH_PX`] apart, 45° on screen) of the box
/// `[t0, t1] × [y0, y1]` of a chart whose x axis starts at `t_lo`, with
/// `px` pixels per unit of x and of y: segments in the chart's
/// coordinates, anchored at the axis' start so that neighbouring boxes'
/// lines continue.
fn hatch(
    (t0, t1): (f64, f64),
    (y0, y1): (f64, f64),
    t_lo: f64,
    (px_x, px_y): (f64, f64),
) -> Vec<[(f64, f64); 2]> {
    let (a, b) = ((t0 - t_lo) * px_x, (t1 - t_lo) * px_x);
    let h = (y1 - y0) * px_y;
    let mut out = Vec::new();
    if !(px_x > 0.0 && px_y > 0.0 && b > a && h > 0.0) {
        return out;
    }
    // a line from (u, bottom) up to (u + h, top), pixels from the axis'
    // start, cut to [a, b]
    let mut u = ((a - h) / HATCH_PX).floor() * HATCH_PX;
    while u < b {
        let (s0, s1) = ((a - u).max(0.0), (b - u).min(h));
        if s1 > s0 {
            let p = |s: f64| (t_lo + (u + s) / px_x, y0 + s / px_y);
            out.push([p(s0), p(s1)]);
        }
        u += HATCH_PX;
    }
    out
}

/// The four road strips: the road at the microphone (what ARTE hears),
/// ARTE's estimate (from its frame's start to its publication, each over
/// the one before; those whose confidence is below the loop's gate pale
/// and hatched), the loop's road belief (what the controller acted on:
/// [`belief_runs`]; a note when the cycle records hold none) and the road
/// under the driven wheel, with the colour key at the right (the strips'
/// own opaque colours) and the gate's entry under it.
fn strips(area: &Area<'_>, s: &Series) -> Res {
    let (plot, side) = area.split_horizontally(W - LEGEND_W);
    let (t_lo, t_hi) = s.span;
    let mut chart = ChartBuilder::on(&plot)
        .margin(8)
        .caption(
            "roads: at the microphone (what ARTE hears, judged against), ARTE's estimate (audio frame's start to publication), the loop's belief (what tcs-loop's controller acted on), under the wheel; white: none",
            ("sans-serif", 15),
        )
        .x_label_area_size(34)
        .y_label_area_size(LABEL_W)
        .build_cartesian_2d(t_lo..t_hi, 0.0..ROWS)?;
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let px = (
        f64::from(xr.end - xr.start) / (t_hi - t_lo),
        f64::from(yr.end - yr.start) / ROWS,
    );
    let row = |row: f64, t0: f64, t1: f64, fill: ShapeStyle| {
        Rectangle::new(
            [(t0.max(t_lo), row + 0.12), (t1.min(t_hi), row + 0.88)],
            fill,
        )
    };
    for (r, roads) in [(ROW_MIC, &s.mic), (ROW_WHEEL, &s.wheel)] {
        chart.draw_series(
            s.bands(roads)
                .into_iter()
                .filter(|b| b.t1 > t_lo && b.t0 < t_hi)
                .map(|b| row(r, b.t0, b.t1, s.strip_fill(&b.label).filled())),
        )?;
    }
    chart.draw_series(
        s.belief
            .iter()
            .filter(|(t0, t1, _)| *t1 > t_lo && *t0 < t_hi)
            .map(|(t0, t1, name)| row(ROW_BELIEF, *t0, *t1, s.strip_fill(name).filled())),
    )?;
    // ARTE's estimates in order, each drawn over the one before (opaque:
    // the key's colours where frames overlap)
    for ((t0, t1, name), &below) in s.est.iter().zip(&s.below_gate) {
        if !(*t1 > t_lo && *t0 < t_hi) {
            continue;
        }
        if name.is_empty() || !below {
            chart.draw_series(std::iter::once(row(
                ROW_ARTE,
                *t0,
                *t1,
                s.strip_fill(name).filled(),
            )))?;
            continue;
        }
        let c = s.colour(name);
        chart.draw_series(std::iter::once(row(
            ROW_ARTE,
            *t0,
            *t1,
            on_white(c, BELOW_GATE_SHARE).filled(),
        )))?;
        chart.draw_series(
            hatch(
                (t0.max(t_lo), t1.min(t_hi)),
                (ROW_ARTE + 0.12, ROW_ARTE + 0.88),
                t_lo,
                px,
            )
            .into_iter()
            .map(|seg| PathElement::new(seg.to_vec(), c.stroke_width(1))),
        )?;
    }
    if s.belief.is_empty() {
        chart.draw_series(std::iter::once(Text::new(
            "no road belief in the cycle records (ARTE off, or a log whose records do not carry it)",
            (t_lo + 0.01 * (t_hi - t_lo), ROW_BELIEF + 0.72),
            ("sans-serif", 15).into_font().color(&BLACK),
        )))?;
    }
    if !s.has_truth() {
        for r in [ROW_MIC, ROW_WHEEL] {
            chart.draw_series(std::iter::once(Text::new(
                "no ground truth in this log",
                (t_lo + 0.01 * (t_hi - t_lo), r + 0.72),
                ("sans-serif", 15).into_font().color(&BLACK),
            )))?;
        }
    }
    for r in [ROW_MIC, ROW_ARTE, ROW_BELIEF, ROW_WHEEL] {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t_lo, r + 0.12), (t_hi, r + 0.88)],
            BLACK.stroke_width(1),
        )))?;
    }
    if s.tb.scenario_ns.is_some() && (t_lo..=t_hi).contains(&0.0) {
        chart.draw_series(LineSeries::new(
            [(0.0, 0.0), (0.0, ROWS)],
            BLACK.mix(0.7).stroke_width(1),
        ))?;
    }
    chart
        .configure_mesh()
        .disable_mesh()
        .y_labels(0)
        .x_desc(s.tb.axis_label())
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    // the rows' names, in the y label area
    let base = area.get_base_pixel();
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    for (r, label) in [
        (ROW_MIC, "microphone"),
        (ROW_ARTE, "ARTE"),
        (ROW_BELIEF, "loop belief"),
        (ROW_WHEEL, "wheel"),
    ] {
        let (_, py) = chart.backend_coord(&(t_lo, r + 0.5));
        area.draw_text(label, &font, (14, py - base.1 - 8))?;
    }
    // colour key: the strips' own fills
    let mut names: Vec<&str> = s.names.iter().map(String::as_str).collect();
    if s.est.iter().chain(&s.belief).any(|e| e.2.is_empty()) {
        names.push("");
    }
    let rows_per_col = 8;
    let swatch = |x: i32, y: i32, fill: RGBColor| -> Res {
        side.draw(&Rectangle::new([(x, y), (x + 16, y + 16)], fill.filled()))?;
        side.draw(&Rectangle::new(
            [(x, y), (x + 16, y + 16)],
            BLACK.stroke_width(1),
        ))?;
        Ok(())
    };
    for (i, name) in names.iter().enumerate() {
        let x = 10 + 100 * (i / rows_per_col) as i32;
        let y = 36 + 22 * (i % rows_per_col) as i32;
        swatch(x, y, s.strip_fill(name))?;
        side.draw_text(
            if name.is_empty() { "none" } else { name },
            &font,
            (x + 22, y),
        )?;
    }
    // the gate's entry (for a log with estimates): a swatch as the strip
    // draws an estimate below it
    if s.est.is_empty() {
        return Ok(());
    }
    let y = 36 + 22 * names.len().min(rows_per_col) as i32 + 6;
    let grey = RGBColor(110, 110, 110);
    swatch(10, y, on_white(grey, BELOW_GATE_SHARE))?;
    for [(x0, y0), (x1, y1)] in hatch((10.0, 26.0), (0.0, 16.0), 0.0, (1.0, 1.0)) {
        let p = |x: f64, h: f64| (x.round() as i32, y + 16 - h.round() as i32);
        side.draw(&PathElement::new(
            vec![p(x0, y0), p(x1, y1)],
            grey.stroke_width(1),
        ))?;
    }
    for (k, line) in s.gate.key().iter().enumerate() {
        side.draw_text(line, &font, (32, y + 17 * k as i32))?;
    }
    Ok(())
}

/// The title of `drive.png`: the log's file name and run (controller, ARTE,
/// scenario, vehicle, seed), then whether it was recorded or generated,
/// when, and the code's revision.
pub fn title_of(log: &DriveLog) -> (String, String) {
    // a replay's own controller and ARTE switch (`grip.run` is its source's)
    let replay = log.metadata.get("grip.replay");
    let get = |k: &str| {
        replay
            .filter(|_| k == "controller" || k == "arte")
            .and_then(|m| m.get(k))
            .or_else(|| log.run.get(k))
            .map(String::as_str)
    };
    let file = log.path.file_name().map_or_else(
        || log.path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut run = Vec::new();
    if let Some(c) = get("controller") {
        run.push(c.to_uppercase());
    }
    if let Some(a) = get("arte") {
        run.push(format!("ARTE {a}"));
    }
    if let Some(s) = get("scenario") {
        run.push(format!("scenario {s}"));
    }
    // `grip drive --vehicle FILE` records the file; without it the drive ran
    // with the configuration's vehicle.toml. A replay that ran another
    // vehicle than its source's (its record's `vehicle`, the file it
    // attached as replay/vehicle.toml) is titled with that one.
    let replayed = replay
        .and_then(|m| m.get("vehicle"))
        .filter(|v| {
            !v.is_empty()
                && log
                    .attachments
                    .contains_key(grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT)
        })
        .map(String::as_str);
    let vehicle = replayed
        .or_else(|| get("vehicle"))
        .map_or("vehicle.toml", |p| {
            p.rsplit(['/', '\\']).next().unwrap_or(p)
        });
    if !log.run.is_empty() {
        let whose = if replayed.is_some() {
            " (the replay's)"
        } else {
            ""
        };
        run.push(format!("vehicle {vehicle}{whose}"));
    }
    if let Some(s) = get("seed") {
        run.push(format!("seed {s}"));
    }
    // the model arte ran (arte-svc.toml's `model`, or a replay's)
    if let Some(m) = grip_drive::summary::model_of(log) {
        let name = m.name.rsplit(['/', '\\']).next().unwrap_or(&m.name);
        run.push(format!(
            "model {name} ({})",
            grip_drive::summary::short_sha(m.sha256.as_ref())
        ));
    }
    let line1 = if run.is_empty() {
        format!("{file}: no run metadata (grip.run)")
    } else {
        format!("{file}: {}", run.join(", "))
    };

    let generated = get("source") == Some("generated");
    let clock = log.metadata.get("grip.clock");
    let num = |k: &str| {
        clock
            .and_then(|m| m.get(k))
            .and_then(|v| v.parse::<i128>().ok())
    };
    // log times are CLOCK_MONOTONIC on a drive (wall = log time -
    // monotonic_ns + realtime_ns); a generated log's are scripted, so only
    // the moment its file was created is wall time
    let wall_ns = match (num("realtime_ns"), num("monotonic_ns")) {
        (Some(real), _) if generated => Some(real),
        (Some(real), Some(mono)) => Some(i128::from(log.first_stamp_ns()) - mono + real),
        _ => None,
    };
    let when = wall_ns.map(|ns| {
        let secs = i64::try_from(ns.div_euclid(1_000_000_000)).unwrap_or(0);
        let tod = secs.rem_euclid(86_400);
        format!(
            "{} {:02}:{:02}:{:02} UTC",
            crate::cmd::train::civil_date(secs),
            tod / 3600,
            tod / 60 % 60,
            tod % 60
        )
    });
    let mut line2 = vec![match (generated, when) {
        (true, Some(w)) => format!("generated {w} by grip generate (simulated, scripted clock)"),
        (true, None) => "generated by grip generate (simulated, scripted clock)".to_owned(),
        (false, Some(w)) => format!("recorded {w}"),
        (false, None) => "recording date not in the log".to_owned(),
    }];
    if let Some(rev) = get("git_revision") {
        line2.push(format!("revision {}", rev.get(..10).unwrap_or(rev)));
    }
    if let Some(v) = get("version") {
        line2.push(format!("grip {v}"));
    }
    (line1, line2.join(", "))
}

/// Draws drive.png's figure onto `root` (W × [`drive_height`]).
fn draw_drive(root: &Area<'_>, log: &DriveLog, r: f64, v_eps: f64) -> Res {
    let s = series(log, r, v_eps);
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(TITLE_H);
    let (line1, line2) = title_of(log);
    top.draw_text(
        &line1,
        &("sans-serif", 24).into_font().color(&BLACK),
        (20, 10),
    )?;
    top.draw_text(
        &line2,
        &("sans-serif", 17).into_font().color(&BLACK),
        (20, 46),
    )?;
    let (p1, r1) = rest.split_vertically(PANEL_H);
    let (p2, r2) = r1.split_vertically(PANEL_H);
    let (p3, p4) = r2.split_vertically(PANEL_H);
    let truth = s.has_truth();
    if truth {
        panel(
            &p1,
            &s,
            ("speeds (m/s, ground truth)", None),
            range(s.v.iter().chain(&s.r_omega).copied()),
            true,
            &[
                ("V", &s.t, &s.v, RGBColor(0, 0, 200)),
                ("r ω", &s.t, &s.r_omega, RGBColor(200, 0, 0)),
            ],
            None,
        )?;
    } else {
        panel(
            &p1,
            &s,
            (
                "speeds (m/s, measured by tcs-loop: the log has no ground truth)",
                None,
            ),
            range(s.meas_v.iter().chain(&s.meas_r_omega).copied()),
            true,
            &[
                ("V measured", &s.cvt, &s.meas_v, RGBColor(0, 0, 200)),
                ("r ω measured", &s.ct, &s.meas_r_omega, RGBColor(200, 0, 0)),
            ],
            None,
        )?;
    }
    if truth {
        panel(
            &p2,
            &s,
            ("slip λ (ground truth)", None),
            range(s.lambda.iter().copied().chain([0.0])),
            false,
            &[("λ", &s.t, &s.lambda, RGBColor(200, 0, 0))],
            None,
        )?;
    } else {
        // the loop's own measurement (no ground truth in the log), with
        // the spin events' threshold
        let lvl = grip_drive::summary::measured::SPIN_LAMBDA;
        let (lo, hi) = range(s.meas_lambda.iter().copied().chain([0.0, lvl]));
        let level = [s.span.0, s.span.1];
        panel(
            &p2,
            &s,
            (
                "slip λ_m measured by tcs-loop ((r ω − V) / max(r ω, V, v_eps), V valid, max(r ω, V) ≥ 1 m/s, out of the safe state; the log has no ground truth)",
                None,
            ),
            (lo, hi),
            false,
            &[
                ("λ_m measured", &s.clt, &s.meas_lambda, RGBColor(200, 0, 0)),
                (
                    "spin level 0.2",
                    &level,
                    &[lvl, lvl],
                    RGBColor(120, 120, 120),
                ),
            ],
            s.meas_lambda
                .is_empty()
                .then_some("no measured slip: no valid V at or above 1 m/s"),
        )?;
    }
    let (t_label, t_times, t_values) = if truth {
        ("T, wheel (plant)", &s.t, &s.torque)
    } else {
        ("T, wheel (measured)", &s.ct, &s.meas_torque)
    };
    let caption = format!(
        "{TORQUE_CAPTION} {}",
        if truth { "from the plant" } else { "measured" }
    );
    panel(
        &p3,
        &s,
        (&caption, Some(TORQUE_AXIS)),
        range(
            s.demand
                .iter()
                .chain(&s.cmd)
                .chain(t_values)
                .copied()
                .chain([0.0]),
        ),
        false,
        &[
            ("cap (belief)", &s.ct, &s.cap, CAP_COLOUR),
            ("T_d", &s.ct, &s.demand, RGBColor(0, 0, 0)),
            ("T*", &s.ct, &s.cmd, RGBColor(230, 130, 0)),
            (t_label, t_times, t_values, RGBColor(0, 0, 200)),
        ],
        None,
    )?;
    strips(&p4, &s)?;
    Ok(())
}

/// Height of drive.png.
const fn drive_height() -> u32 {
    TITLE_H + 3 * PANEL_H + STRIPS_H
}

fn drive_png(path: &Path, log: &DriveLog, r: f64, v_eps: f64) -> Res {
    let root = BitMapBackend::new(path, (W, drive_height())).into_drawing_area();
    draw_drive(&root, log, r, v_eps)?;
    root.present()?;
    Ok(())
}

/// The title of `timing.png`, three lines: the log and what the histogram
/// covers (every cycle record: the whole log, start-up and stop included,
/// and its span on the drive figure's time axis), its figures (`p` of the
/// wake-up latencies, `over` of them above `top_us`), and that the
/// summary's loop timing leads with the scenario window's figures.
fn timing_title(log: &DriveLog, p: &Percentiles, over: u64, top_us: i64) -> [String; 3] {
    let tb = TimeBase::of(log);
    let file = log
        .path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let span = match lohi(log.cycles.iter().map(|c| c.stamp_ns)) {
        Some((a, b)) => format!(
            "every cycle record, t {:.2} to {:.2} s from {}",
            tb.axis(a),
            tb.axis(b),
            if tb.scenario_ns.is_some() {
                "the scenario start"
            } else {
                "the first message"
            }
        ),
        None => "no cycle records".to_owned(),
    };
    [
        format!(
            "{file}: tcs-loop wake-up latency over the WHOLE LOG (start-up, hold and stop included)"
        ),
        format!(
            "{span}: {} cycles, p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, {over} above {top_us} µs",
            p.n,
            p.p50 as f64 / 1e3,
            p.p99 as f64 / 1e3,
            p.max as f64 / 1e3,
        ),
        "grip inspect's summary leads with the scenario window's figures (\"during the scenario\"), a part of these cycles"
            .to_owned(),
    ]
}

/// Height of timing.png's title.
const TIMING_TITLE_H: u32 = 76;

fn timing_png(path: &Path, log: &DriveLog) -> Res {
    let mut lat: Vec<i64> = log.cycles.iter().map(|c| c.wakeup_latency_ns).collect();
    let p = Percentiles::of(&mut lat);
    // bins of 2 µs up to max(200 µs, 1.5 × p99.9); the rest counted as overflow
    let top_us = ((p.p999 as f64 / 1e3 * 1.5).max(200.0)).ceil() as i64;
    let bin_us = 2i64.max(top_us / 150);
    let nb = (top_us / bin_us + 1) as usize;
    let mut counts = vec![0u64; nb];
    let mut over = 0u64;
    for &l in &lat {
        let b = (l.max(0) / 1000 / bin_us) as usize;
        if b < nb {
            counts[b] += 1;
        } else {
            over += 1;
        }
    }
    let ymax = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    let root = BitMapBackend::new(path, (1200, 600 + TIMING_TITLE_H)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(TIMING_TITLE_H);
    for (k, (line, size)) in timing_title(log, &p, over, nb as i64 * bin_us)
        .iter()
        .zip([18, 15, 15])
        .enumerate()
    {
        top.draw_text(
            line,
            &("sans-serif", size).into_font().color(&BLACK),
            (16, 10 + 22 * k as i32),
        )?;
    }
    let mut chart = ChartBuilder::on(&rest)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(
            0f64..(nb as i64 * bin_us) as f64,
            (0.5f64..ymax * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("wake-up latency (µs)")
        .y_desc("cycles (log scale)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    chart.draw_series(
        counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, &c)| {
                let x0 = (i as i64 * bin_us) as f64;
                Rectangle::new(
                    [(x0, 0.5), (x0 + bin_us as f64, c as f64)],
                    RGBColor(40, 90, 180).filled(),
                )
            }),
    )?;
    root.present()?;
    Ok(())
}

/// Writes `drive.png` and `timing.png` into `dir` (created); `r` and
/// `v_eps` of the drive's vehicle (r ω, and the measured slip of a log
/// without ground truth).
pub fn write_plots(log: &DriveLog, dir: &Path, r: f64, v_eps: f64) -> anyhow::Result<Vec<PathBuf>> {
    init_fonts();
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("creating {}: {e}", dir.display()))?;
    let a = dir.join("drive.png");
    drive_png(&a, log, r, v_eps).map_err(|e| anyhow!("drawing {}: {e}", a.display()))?;
    let b = dir.join("timing.png");
    timing_png(&b, log).map_err(|e| anyhow!("drawing {}: {e}", b.display()))?;
    Ok(vec![a, b])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::export::test_log::{self, MS, START, T0};

    /// drive.png of `log` as RGB pixels.
    fn render(log: &DriveLog) -> Vec<u8> {
        init_fonts();
        let mut buf = vec![0u8; (W * drive_height() * 3) as usize];
        {
            let root =
                BitMapBackend::with_buffer(&mut buf, (W, drive_height())).into_drawing_area();
            draw_drive(&root, log, test_log::R, 0.1).unwrap();
            root.present().unwrap();
        }
        buf
    }

    /// Pixels of colour `c` in rows `ys` and columns `xs`.
    fn count(buf: &[u8], c: RGBColor, ys: std::ops::Range<u32>, xs: std::ops::Range<u32>) -> usize {
        ys.flat_map(|y| xs.clone().map(move |x| ((y * W + x) * 3) as usize))
            .filter(|&i| buf[i..i + 3] == [c.0, c.1, c.2])
            .count()
    }

    /// A log without ground truth (from the car) is plotted over its cycle
    /// records: the command T* is drawn across the torque panel's data
    /// area (the drawing used a 0-1 s range from a time origin of 0 before,
    /// and drew nothing).
    #[test]
    fn a_log_without_ground_truth_still_shows_the_command() {
        let log = test_log::drive_without_truth();
        let tb = TimeBase::of(&log);
        assert_eq!(tb.scenario_ns, None);
        let (lo, hi) = x_span(&log, &tb);
        let (c0, c1) = (log.cycles[0].stamp_ns, log.cycles.last().unwrap().stamp_ns);
        assert!(lo <= tb.axis(c0) && hi >= tb.axis(c1), "{lo}..{hi}");
        assert!((hi - lo - 2.999).abs() < 1e-9, "{lo}..{hi}");

        let buf = render(&log);
        // the torque panel, left of the key column: the command's orange
        let top = TITLE_H + 2 * PANEL_H;
        let orange = RGBColor(230, 130, 0);
        for (x0, x1) in [(LABEL_W + 20, W / 3), (W / 3, 2 * W / 3)] {
            let n = count(&buf, orange, top..top + PANEL_H, x0..x1);
            assert!(n > 100, "columns {x0}..{x1}: {n} pixels of the command");
        }
        // the slip panel: the measured slip λ_m (red), not an empty panel
        let top = TITLE_H + PANEL_H;
        let red = RGBColor(200, 0, 0);
        for (x0, x1) in [(LABEL_W + 20, W / 3), (W / 3, 2 * W / 3)] {
            let n = count(&buf, red, top..top + PANEL_H, x0..x1);
            assert!(
                n > 100,
                "columns {x0}..{x1}: {n} pixels of the measured slip"
            );
        }
    }

    /// A command chattering between 0 and 300 N m from one cycle to the
    /// next (t 0.05-0.1 s, as a user's drive did) stays in the torque
    /// panel: plotters' 2 px polyline drew its sharp turns as spikes up
    /// into the slip panel and down below 0 N m into the road strips.
    #[test]
    fn a_chattering_command_stays_in_its_panel() {
        let mut log = test_log::drive();
        for c in &mut log.cycles {
            let t = c.stamp_ns as f64 * 1e-9 - START as f64 * 1e-9;
            c.torque_cmd = if (0.05..0.1).contains(&t) && c.seq % 2 == 0 {
                0.0
            } else {
                300.0
            };
        }
        let buf = render(&log);
        let orange = RGBColor(230, 130, 0);
        let top = TITLE_H + 2 * PANEL_H;
        assert!(count(&buf, orange, top..top + PANEL_H, 0..W) > 1000);
        // nothing above the torque panel (the slip panel), nothing below
        // it (the strips)
        let above = count(&buf, orange, 0..top, 0..W);
        let below = count(&buf, orange, top + PANEL_H..drive_height(), 0..W);
        assert_eq!((above, below), (0, 0), "pixels of T* out of its panel");
        // nor below 0 N m: the lowest orange row is the row of 0 N m (the
        // chattering's bottom), where the held command (0 N m before the
        // start) runs too
        let rows: Vec<u32> = (top..top + PANEL_H)
            .filter(|&y| count(&buf, orange, y..y + 1, LABEL_W..W - LEGEND_W) > 0)
            .collect();
        let lowest = *rows.last().unwrap();
        let mut held = test_log::drive();
        for c in &mut held.cycles {
            c.torque_cmd = if c.stamp_ns < START { 0.0 } else { 300.0 };
        }
        let held_rows: Vec<u32> = {
            let b = render(&held);
            (top..top + PANEL_H)
                .filter(|&y| count(&b, orange, y..y + 1, LABEL_W..W - LEGEND_W) > 0)
                .collect()
        };
        assert!(
            lowest <= *held_rows.last().unwrap(),
            "T* drawn down to row {lowest}, 0 N m is at {held_rows:?}"
        );
    }

    /// The loop's road belief (the cycle records' `belief_road`, named by
    /// the attached catalogue) is a run per stretch of cycles: none before
    /// the first estimate, then the estimates' roads, asphalt, snow, the one
    /// wrong asphalt and asphalt again; none at all without beliefs.
    #[test]
    fn the_loops_belief_runs_follow_the_cycle_records() {
        let log = test_log::drive();
        let tb = TimeBase::of(&log);
        let runs = belief_runs(&log, &tb);
        let names: Vec<&str> = runs.iter().map(|r| r.2.as_str()).collect();
        assert_eq!(names, ["", "asphalt", "snow", "asphalt", "snow", "asphalt"]);
        // the first estimate at T0 + 120 ms; the runs tile the records
        assert!((runs[1].0 - tb.axis(T0 + 120 * MS)).abs() < 1e-9);
        for w in runs.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
        assert_eq!(
            runs.last().unwrap().1,
            tb.axis(log.cycles.last().unwrap().stamp_ns)
        );
        // the wrong estimate's belief, from its publication
        assert!((runs[3].0 - tb.axis(test_log::WRONG_AT)).abs() < 1e-9);
        // without the catalogue: by index
        let mut bare = test_log::drive();
        bare.attachments.clear();
        assert_eq!(belief_runs(&bare, &tb)[2].2, "road #2");
        // ARTE off: no belief
        let mut off = test_log::drive();
        for c in &mut off.cycles {
            c.belief_road = grip_msgs::NO_CLASS;
        }
        assert!(belief_runs(&off, &tb).is_empty());
    }

    /// drive.png draws the loop's belief in the road strips (and the torque
    /// cap in force in the torque panel): the same drive with beliefs and
    /// caps differs from it without them in both, where the figure drew
    /// neither before.
    #[test]
    fn the_belief_and_the_cap_are_drawn() {
        let mut with = test_log::drive();
        for c in &mut with.cycles {
            // the snow belief's cap inside the axis, asphalt's beyond it
            c.torque_cap = match c.belief_road {
                2 => 120.0,
                0 => 900.0,
                _ => f64::NAN,
            };
        }
        let mut without = test_log::drive();
        for c in &mut without.cycles {
            c.belief_road = grip_msgs::NO_CLASS;
            c.torque_cap = f64::NAN;
        }
        let (a, b) = (render(&with), render(&without));
        let top = TITLE_H + 3 * PANEL_H;
        let differ = |rows: std::ops::Range<u32>, xs: std::ops::Range<u32>| {
            rows.flat_map(|y| xs.clone().map(move |x| ((y * W + x) * 3) as usize))
                .filter(|&i| a[i..i + 3] != b[i..i + 3])
                .count()
        };
        let strips = differ(top..drive_height(), LABEL_W..W - LEGEND_W);
        assert!(strips > 20_000, "{strips} pixels of the belief's strip");
        // the cap: in the torque panel's data, and its key
        let panel = TITLE_H + 2 * PANEL_H;
        let n = count(
            &a,
            CAP_COLOUR,
            panel..panel + PANEL_H,
            LABEL_W..W - LEGEND_W,
        );
        assert!(n > 500, "{n} pixels of the cap");
        assert_eq!(
            count(&b, CAP_COLOUR, panel..panel + PANEL_H, 0..W),
            0,
            "no cap in the records: none drawn"
        );
    }

    /// With ground truth, the x axis counts from the scenario start (the
    /// summary's clock) and covers the hold and the pre-roll before it.
    #[test]
    fn the_axis_counts_from_the_scenario_start() {
        let log = test_log::drive();
        let tb = TimeBase::of(&log);
        assert_eq!(tb.scenario_ns, Some(START));
        assert_eq!(tb.axis(START), 0.0);
        let (lo, hi) = x_span(&log, &tb);
        assert!(
            (lo + 1.29).abs() < 1e-9 && (hi - 1.71).abs() < 1e-9,
            "{lo}..{hi}"
        );
        assert!(tb.axis_label().contains("scenario start"));
        let buf = render(&log);
        let top = TITLE_H + 2 * PANEL_H;
        let n = count(
            &buf,
            RGBColor(230, 130, 0),
            top..top + PANEL_H,
            LABEL_W + 20..W / 3,
        );
        assert!(n > 100, "{n} pixels of the command");
    }

    /// The title names the log, its run and when it was recorded; a
    /// generated log is called so.
    #[test]
    fn the_title_says_which_drive() {
        let mut log = test_log::drive();
        let (a, b) = title_of(&log);
        assert_eq!(
            a,
            "front-mic-drive.mcap: MTTE, ARTE on, scenario paper, vehicle front-mic.toml, seed 7"
        );
        assert_eq!(
            b,
            "recorded 2026-12-05 00:33:51 UTC, revision 0123456789, grip 0.1.0"
        );
        // 1.29 s after the first message's wall time, on a drive's clock
        log.metadata
            .get_mut("grip.clock")
            .unwrap()
            .insert("monotonic_ns".into(), (T0 - 1290 * MS).to_string());
        assert!(
            title_of(&log)
                .1
                .starts_with("recorded 2026-12-05 00:33:52 UTC")
        );
        // the model arte ran, from the attached arte-svc.toml
        log.attachments.insert(
            "arte-svc.toml".into(),
            b"model = \"models/mine.model\"\n".to_vec(),
        );
        log.attachments
            .insert("models/mine.model".into(), b"weights".to_vec());
        let sha = grip_digest::sha256_hex(b"weights");
        assert!(
            title_of(&log)
                .0
                .ends_with(&format!(", seed 7, model mine.model ({})", &sha[..12])),
            "{}",
            title_of(&log).0
        );
        // a replay that ran another vehicle: that one, said so; a replay
        // record without the attachment (the source's vehicle) changes
        // nothing
        let mut replay = grip_io::mcaplog::MetadataMap::new();
        replay.insert("vehicle".to_owned(), "cars/mine.toml".to_owned());
        log.metadata.insert("grip.replay".into(), replay);
        assert!(
            title_of(&log)
                .0
                .contains(", vehicle front-mic.toml, seed 7")
        );
        log.attachments.insert(
            grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT.into(),
            b"[vehicle]\n".to_vec(),
        );
        assert!(
            title_of(&log)
                .0
                .contains(", vehicle mine.toml (the replay's), seed 7"),
            "{}",
            title_of(&log).0
        );
        log.metadata.remove("grip.replay");
        log.attachments
            .remove(grip_drive::plan::REPLAY_VEHICLE_ATTACHMENT);
        log.run.insert("source".into(), "generated".into());
        log.run.insert("clock".into(), "scripted".into());
        let (_, b) = title_of(&log);
        assert!(
            b.starts_with(
                "generated 2026-12-05 00:33:51 UTC by grip generate (simulated, scripted clock)"
            ),
            "{b}"
        );
        log.run.clear();
        log.metadata.clear();
        log.attachments.clear();
        let (a, b) = title_of(&log);
        assert_eq!(a, "front-mic-drive.mcap: no run metadata (grip.run)");
        assert_eq!(b, "recording date not in the log");
    }

    /// The shipped controllers.toml (its `[arte] min_confidence` 0.6).
    fn shipped_controllers() -> Vec<u8> {
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/controllers.toml"))
            .unwrap()
    }

    /// Pixels of the strips (below the three panels, under their caption,
    /// above their x axis' labels, left of the key) within 2 of colour `c`
    /// in every channel.
    fn near_in_strips(buf: &[u8], c: RGBColor) -> usize {
        let top = TITLE_H + 3 * PANEL_H;
        (top + 30..drive_height() - 40)
            .flat_map(|y| (LABEL_W..W - LEGEND_W).map(move |x| ((y * W + x) * 3) as usize))
            .filter(|&i| {
                buf[i..i + 3]
                    .iter()
                    .zip([c.0, c.1, c.2])
                    .all(|(a, b)| a.abs_diff(b) <= 2)
            })
            .count()
    }

    /// ARTE's frames overlap (each drawn from its frame's start to its
    /// publication, 20 ms after the next frame's start here): the strip is
    /// drawn in the key's opaque colours, where its translucent fills drew
    /// the overlaps darker than the key's swatches (and the strips of the
    /// microphone and the wheel).
    #[test]
    fn arte_keeps_the_keys_colours_where_its_frames_overlap() {
        let buf = render(&test_log::drive());
        for road in ["asphalt", "snow"] {
            let c = road_colour(road, 0);
            // one translucent 0.85 fill over another
            let doubled = on_white(c, 1.0 - 0.15 * 0.15);
            assert_eq!(near_in_strips(&buf, doubled), 0, "{road}: darker overlaps");
            assert!(
                near_in_strips(&buf, on_white(c, STRIP_SHARE)) > 5000,
                "{road}"
            );
        }
        // the key's swatch is the strips' colour
        let snow = on_white(road_colour("snow", 0), STRIP_SHARE);
        let key = (TITLE_H + 3 * PANEL_H..drive_height())
            .flat_map(|y| (W - LEGEND_W..W).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let i = ((y * W + x) * 3) as usize;
                buf[i..i + 3] == [snow.0, snow.1, snow.2]
            })
            .count();
        assert!(key > 100, "{key} pixels of snow's swatch");
    }

    /// The loop's gate as the summary reads it: the log's controllers.toml,
    /// else the default; a replay that changed it says so.
    #[test]
    fn the_gate_is_the_logs_controllers_toml() {
        let mut log = test_log::drive();
        assert_eq!(
            gate_of(&log),
            Gate {
                min_confidence: grip_tcs::ArteUse::default().min_confidence,
                from: GateFrom::Default
            }
        );
        log.attachments
            .insert("controllers.toml".into(), shipped_controllers());
        assert_eq!(gate_of(&log).min_confidence, 0.6);
        assert_eq!(gate_of(&log).from, GateFrom::Log);
        let text = String::from_utf8(shipped_controllers()).unwrap();
        let mine = text.replace("min_confidence = 0.6", "min_confidence = 0.85");
        assert_ne!(mine, text, "the shipped file's gate line");
        log.attachments
            .insert("controllers.toml".into(), mine.into_bytes());
        assert_eq!(gate_of(&log).min_confidence, 0.85);
        assert_eq!(
            gate_of(&log).key(),
            [
                "ARTE, below the gate:",
                "confidence < 0.85",
                "(log's controllers.toml)"
            ]
        );
        log.metadata.insert(
            "grip.replay".into(),
            [
                ("source", "a.mcap"),
                (
                    "changes",
                    "controllers.toml: [arte] min_confidence 0.85 -> 0.5",
                ),
            ]
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect(),
        );
        assert_eq!(gate_of(&log).from, GateFrom::ReplayChanged);
    }

    /// A replay's log that records the gate its tcs-loop ran: the key
    /// gives that gate, as the summary does (`grip_drive::summary::gate_of`,
    /// the one rule), not the source's copied into the log with "(source's;
    /// replay changed)".
    #[test]
    fn the_gate_of_a_replay_is_the_one_it_ran() {
        let mut log = test_log::drive();
        let text = String::from_utf8(shipped_controllers()).unwrap();
        log.attachments.insert(
            "controllers.toml".into(),
            text.replace("min_confidence = 0.6", "min_confidence = 0.85")
                .into_bytes(),
        );
        log.metadata.insert(
            "grip.replay".into(),
            [
                ("source", "a.mcap"),
                (
                    "changes",
                    "controllers.toml: [arte] min_confidence 0.85 -> 0.5",
                ),
                ("min_confidence", "0.5"),
            ]
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect(),
        );
        assert_eq!(
            gate_of(&log).key(),
            [
                "ARTE, below the gate:",
                "confidence < 0.5",
                "(the replay's, as it ran)"
            ]
        );
        assert_eq!(
            gate_of(&log).min_confidence,
            grip_drive::summary::min_confidence_of(&log).0
        );
    }

    /// Estimates whose confidence is below the loop's gate are drawn pale
    /// and hatched (they were drawn as the confident ones): the same drive
    /// with every snow estimate at 0.5 against the shipped gate 0.6 has
    /// pale snow, and hatching in snow's colour, in the ARTE strip; at
    /// 0.9 none.
    #[test]
    fn estimates_below_the_gate_are_pale_and_hatched() {
        let with_conf = |conf: f64| {
            let mut log = test_log::drive();
            log.attachments
                .insert("controllers.toml".into(), shipped_controllers());
            for e in &mut log.roads {
                if e.class_name() == Some("snow") {
                    e.confidence = conf;
                }
            }
            log
        };
        let snow = road_colour("snow", 0);
        let pale = on_white(snow, BELOW_GATE_SHARE);
        let (low, high) = (render(&with_conf(0.5)), render(&with_conf(0.9)));
        assert!(near_in_strips(&low, pale) > 2000, "pale snow");
        assert!(near_in_strips(&low, snow) > 100, "snow's hatching");
        assert_eq!(near_in_strips(&high, pale), 0);
        assert_eq!(near_in_strips(&high, snow), 0);
        // a confidence that is no number is below any gate
        let s = series(&with_conf(f64::NAN), test_log::R, 0.1);
        assert!(s.below_gate.iter().any(|b| *b));
    }

    /// The hatching: 45° on screen, its lines [`HATCH_PX`] apart, inside
    /// its box, continuing across neighbouring boxes.
    #[test]
    fn the_hatching_stays_in_its_box() {
        // 10 px per unit of x, 20 per unit of y: a 40 × 20 px box
        let segs = hatch((1.0, 5.0), (2.0, 3.0), 0.0, (10.0, 20.0));
        assert!(segs.len() >= 8, "{segs:?}");
        for [(x0, y0), (x1, y1)] in &segs {
            for (x, y) in [(x0, y0), (x1, y1)] {
                assert!((1.0 - 1e-9..=5.0 + 1e-9).contains(x), "{segs:?}");
                assert!((2.0 - 1e-9..=3.0 + 1e-9).contains(y), "{segs:?}");
            }
            // 45° on screen: as many pixels up as across
            assert!(((x1 - x0) * 10.0 - (y1 - y0) * 20.0).abs() < 1e-9);
        }
        // the box next to it continues the lines: the same line starts
        let starts = |segs: &[[(f64, f64); 2]]| -> Vec<f64> {
            segs.iter()
                .map(|[(x, y), _]| ((x * 10.0 - (y - 2.0) * 20.0) / HATCH_PX).round())
                .collect()
        };
        let next = hatch((5.0, 9.0), (2.0, 3.0), 0.0, (10.0, 20.0));
        let (a, b) = (starts(&segs), starts(&next));
        assert!(b.iter().any(|u| a.contains(u)), "{a:?} {b:?}");
        assert!(hatch((1.0, 1.0), (2.0, 3.0), 0.0, (10.0, 20.0)).is_empty());
    }

    /// The torque panel says its torques are one driven wheel's, after the
    /// gear (vehicle.toml's `torque_max`), on its y axis too; it said
    /// "motor torque T".
    #[test]
    fn the_torque_panel_is_one_driven_wheels() {
        assert!(TORQUE_CAPTION.starts_with("wheel torque, one driven wheel (N m"));
        assert!(!TORQUE_CAPTION.contains("motor torque"));
        assert_eq!(TORQUE_AXIS, "wheel torque, one driven wheel (N m)");
        // the axis description: text at the left edge of the torque panel,
        // none at the speed panel's (which has no description)
        let buf = render(&test_log::drive());
        let dark = |top: u32| {
            (top + 40..top + PANEL_H - 40)
                .flat_map(|y| (0..24).map(move |x| ((y * W + x) * 3) as usize))
                .filter(|&i| buf[i..i + 3].iter().all(|&v| v < 100))
                .count()
        };
        assert!(dark(TITLE_H + 2 * PANEL_H) > 100, "no y description");
        assert_eq!(dark(TITLE_H), 0);
    }

    /// timing.png's title says it covers every cycle record (the whole log,
    /// and its span on the drive figure's axis), not the scenario window the
    /// summary leads with.
    #[test]
    fn the_timing_title_says_what_it_covers() {
        let log = test_log::drive();
        let mut lat: Vec<i64> = log.cycles.iter().map(|c| c.wakeup_latency_ns).collect();
        let p = Percentiles::of(&mut lat);
        let t = timing_title(&log, &p, 0, 200);
        assert_eq!(
            t[0],
            "front-mic-drive.mcap: tcs-loop wake-up latency over the WHOLE LOG (start-up, hold and stop included)"
        );
        assert!(
            t[1].starts_with(
                "every cycle record, t -1.29 to 1.71 s from the scenario start: 3000 cycles, p50 0.0 µs"
            ),
            "{}",
            t[1]
        );
        assert!(t[2].contains("scenario window"), "{}", t[2]);
        let t = timing_title(&test_log::drive_without_truth(), &p, 0, 200);
        assert!(
            t[1].starts_with("every cycle record, t 0.00 to 3.00 s from the first message"),
            "{}",
            t[1]
        );
    }
}
