//! Figures in the manner of the paper's Fig. 10/11: one column per
//! controller, stacked panels of speeds (V, r ω), slip (λ and λ_opt of the
//! true road) and torque (T_d, T*, T) over coloured road bands; for ARTE
//! variants a strip of the estimated road under each column.

use std::path::Path;

use grip_sim::{RunResult, SimSetup, Trace};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::plot::{road_colour, runs};

const W: u32 = 1900;
const PANEL_H: u32 = 330;
const STRIP_H: u32 = 70;
const TITLE_H: u32 = 60;
const LEGEND_H: u32 = 50;

fn t_at(tr: &Trace, k: usize, dt: f64) -> f64 {
    if k < tr.len() {
        tr.t[k]
    } else {
        tr.t.last().copied().unwrap_or(0.0) + dt
    }
}

fn finite_max(xs: impl Iterator<Item = f64>) -> f64 {
    xs.filter(|x| x.is_finite())
        .fold(f64::NEG_INFINITY, f64::max)
}

fn finite_min(xs: impl Iterator<Item = f64>) -> f64 {
    xs.filter(|x| x.is_finite()).fold(f64::INFINITY, f64::min)
}

type Res = Result<(), Box<dyn std::error::Error>>;

/// Draw one figure for `runs` (one run per controller, same seed) to `path`.
pub fn figure(path: &Path, setup: &SimSetup, runs_in: &[&RunResult], title: &str) -> Res {
    crate::plot::init_fonts();
    let traces: Vec<(&RunResult, &Trace)> = runs_in
        .iter()
        .filter_map(|r| r.trace.as_ref().map(|t| (*r, t)))
        .collect();
    if traces.is_empty() {
        return Ok(());
    }
    let with_strip = traces.iter().any(|(r, _)| r.variant.arte);
    let h = TITLE_H + 3 * PANEL_H + if with_strip { STRIP_H } else { 0 } + LEGEND_H;
    let root = BitMapBackend::new(path, (W, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(TITLE_H);
    top.draw_text(
        &format!("MFC, SRC and MTTE {title}"),
        &("sans-serif", 30).into_font().color(&BLACK),
        (20, 15),
    )?;
    let (body, legend) = rest.split_vertically(h - TITLE_H - LEGEND_H);
    let cols = body.split_evenly((1, traces.len()));

    // Common y ranges per row, so the columns compare at a glance.
    let all = || traces.iter().map(|(_, t)| *t);
    let v_max = finite_max(all().flat_map(|t| t.v.iter().chain(&t.r_omega).copied()));
    let v_min = finite_min(all().flat_map(|t| t.v.iter().chain(&t.r_omega).copied()));
    let l_max = finite_max(all().flat_map(|t| t.lambda.iter().chain(&t.lambda_opt_true).copied()));
    let l_min = finite_min(all().flat_map(|t| t.lambda.iter().copied()));
    let q_max = finite_max(all().flat_map(|t| {
        t.torque
            .iter()
            .chain(&t.torque_cmd)
            .chain(&t.demand)
            .copied()
    }));
    let q_min = finite_min(all().flat_map(|t| t.torque.iter().chain(&t.torque_cmd).copied()));
    let pad = |lo: f64, hi: f64| {
        let span = (hi - lo).max(1e-6);
        (lo - 0.05 * span, hi + 0.08 * span)
    };
    let (v_lo, v_hi) = pad(v_min.min(0.0).max(v_min - 1.0), v_max);
    let (l_lo, l_hi) = pad(l_min.min(0.0), l_max.min(1.0));
    let (q_lo, q_hi) = pad(q_min.min(0.0), q_max);

    for ((run, tr), col) in traces.iter().zip(cols.iter()) {
        let (p1, r1) = col.split_vertically(PANEL_H);
        let (p2, r2) = r1.split_vertically(PANEL_H);
        let (p3, p4) = r2.split_vertically(PANEL_H);
        let name = run.variant.label();
        panel(
            &p1,
            setup,
            tr,
            &format!("{name}: speeds (m/s)"),
            (v_lo, v_hi),
            true,
            &[
                ("V", &tr.v, RGBColor(0, 0, 200)),
                ("r ω", &tr.r_omega, RGBColor(200, 0, 0)),
            ],
        )?;
        panel(
            &p2,
            setup,
            tr,
            &format!("{name}: slip λ"),
            (l_lo, l_hi),
            false,
            &[
                ("λ", &tr.lambda, RGBColor(200, 0, 0)),
                (
                    "λ_opt (true road)",
                    &tr.lambda_opt_true,
                    RGBColor(0, 120, 0),
                ),
            ],
        )?;
        panel(
            &p3,
            setup,
            tr,
            &format!("{name}: torque (N m)"),
            (q_lo, q_hi),
            false,
            &[
                ("T_d", &tr.demand, RGBColor(0, 0, 0)),
                ("T*", &tr.torque_cmd, RGBColor(230, 130, 0)),
                ("T", &tr.torque, RGBColor(0, 0, 200)),
            ],
        )?;
        if with_strip {
            strip(&p4, setup, tr)?;
        }
    }

    // Road colour legend.
    let mut x = 20;
    legend.draw_text(
        "roads:",
        &("sans-serif", 20).into_font().color(&BLACK),
        (x, 15),
    )?;
    x += 80;
    let mut shown: Vec<usize> = traces
        .iter()
        .flat_map(|(_, t)| {
            t.true_road
                .iter()
                .map(|&i| i as usize)
                .chain(t.est_road.iter().flatten().map(|&i| i as usize))
        })
        .collect();
    shown.sort_unstable();
    shown.dedup();
    for i in shown {
        let Some(road) = setup.roads().by_index(i) else {
            continue;
        };
        let c = road_colour(road.name(), i);
        legend.draw(&Rectangle::new(
            [(x, 12), (x + 30, 36)],
            c.mix(0.6).filled(),
        ))?;
        legend.draw_text(
            road.label(),
            &("sans-serif", 20).into_font().color(&BLACK),
            (x + 38, 15),
        )?;
        x += 48 + 11 * road.label().chars().count() as i32;
    }
    if with_strip {
        legend.draw_text(
            "strip: road estimated by ARTE as given to the controller (white: none yet)",
            &("sans-serif", 18).into_font().color(&BLACK),
            (x + 20, 16),
        )?;
    }
    root.present()?;
    Ok(())
}

#[allow(clippy::type_complexity)]
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    setup: &SimSetup,
    tr: &Trace,
    caption: &str,
    (y_lo, y_hi): (f64, f64),
    label_roads: bool,
    series: &[(&str, &Vec<f64>, RGBColor)],
) -> Res {
    let dt = setup.dt();
    let t_end = t_at(tr, tr.len(), dt);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .caption(caption, ("sans-serif", 20))
        .x_label_area_size(34)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, y_lo..y_hi)?;
    // Road bands.
    for (a, b, road) in runs(&tr.true_road) {
        let i = road as usize;
        let name = setup.roads().by_index(i).map_or("?", |r| r.name());
        let c = road_colour(name, i);
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t_at(tr, a, dt), y_lo), (t_at(tr, b, dt), y_hi)],
            c.mix(0.25).filled(),
        )))?;
        if label_roads {
            let label = setup.roads().by_index(i).map_or("?", |r| r.name());
            chart.draw_series(std::iter::once(Text::new(
                label.to_owned(),
                (t_at(tr, a, dt) + 0.01 * t_end, y_hi - 0.02 * (y_hi - y_lo)),
                ("sans-serif", 15).into_font().color(&BLACK),
            )))?;
        }
    }
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("t (s)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    // At most ~2000 points per series.
    let step = (tr.len() / 2000).max(1);
    for (label, ys, colour) in series {
        let c = *colour;
        chart
            .draw_series(LineSeries::new(
                (0..tr.len())
                    .step_by(step)
                    .filter(|&k| ys[k].is_finite())
                    .map(|k| (tr.t[k], ys[k].clamp(y_lo, y_hi))),
                c.stroke_width(2),
            ))?
            .label(*label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .margin(8)
        .label_font(("sans-serif", 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

fn strip(area: &DrawingArea<BitMapBackend<'_>, Shift>, setup: &SimSetup, tr: &Trace) -> Res {
    let dt = setup.dt();
    let t_end = t_at(tr, tr.len(), dt);
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(8)
        .x_label_area_size(0)
        .y_label_area_size(60)
        .caption("ARTE estimate", ("sans-serif", 15))
        .build_cartesian_2d(0.0..t_end, 0.0..1.0)?;
    for (a, b, est) in runs(&tr.est_road) {
        let fill = match est {
            Some(i) => {
                let i = i as usize;
                let name = setup.roads().by_index(i).map_or("?", |r| r.name());
                road_colour(name, i).mix(0.85).filled()
            }
            None => WHITE.filled(),
        };
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t_at(tr, a, dt), 0.0), (t_at(tr, b, dt), 1.0)],
            fill,
        )))?;
    }
    // Cycles where the controller ignored the knowledge: a black tick row.
    for (a, b, used) in runs(&tr.used_arte) {
        if !used {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(t_at(tr, a, dt), 0.0), (t_at(tr, b, dt), 0.15)],
                BLACK.filled(),
            )))?;
        }
    }
    chart.draw_series(std::iter::once(Rectangle::new(
        [(0.0, 0.0), (t_end, 1.0)],
        BLACK.stroke_width(1),
    )))?;
    Ok(())
}
