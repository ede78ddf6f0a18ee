//! Figures in the manner of the paper's Fig. 10/11: one column per
//! controller, stacked panels of speeds (V, r ω), slip (λ and λ_opt of the
//! true road) and torque (T_d, T*, T) over coloured road bands; for ARTE
//! variants a strip of the estimated road under each column.

use std::path::Path;

use grip_sim::{RunResult, SimSetup, Trace};
use plotters::prelude::*;

use crate::plot::{
    Area, Band, Line, PlotResult as Res, estimate_strip, road_colour, road_panel, runs,
};

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
/// A panel of one run: true-road bands (catalogue colours) and `series`
/// (label, values per trace sample, colour).
fn panel(
    area: &Area<'_>,
    setup: &SimSetup,
    tr: &Trace,
    caption: &str,
    y: (f64, f64),
    label_roads: bool,
    series: &[(&str, &Vec<f64>, RGBColor)],
) -> Res {
    let dt = setup.dt();
    let bands: Vec<Band> = runs(&tr.true_road)
        .into_iter()
        .map(|(a, b, road)| {
            let i = road as usize;
            let name = setup.roads().by_index(i).map_or("?", |r| r.name());
            Band {
                t0: t_at(tr, a, dt),
                t1: t_at(tr, b, dt),
                colour: road_colour(name, i),
                label: name.to_owned(),
            }
        })
        .collect();
    let lines: Vec<Line<'_>> = series
        .iter()
        .map(|&(label, ys, colour)| Line {
            label,
            colour,
            points: tr.t.iter().copied().zip(ys.iter().copied()).collect(),
        })
        .collect();
    road_panel(
        area,
        t_at(tr, tr.len(), dt),
        caption,
        "t (s)",
        y,
        &bands,
        label_roads,
        &lines,
    )
}

/// The estimated road of one run, with black ticks where the controller
/// ignored the knowledge.
fn strip(area: &Area<'_>, setup: &SimSetup, tr: &Trace) -> Res {
    let dt = setup.dt();
    let spans: Vec<_> = runs(&tr.est_road)
        .into_iter()
        .map(|(a, b, est)| {
            let colour = est.map(|i| {
                let i = i as usize;
                let name = setup.roads().by_index(i).map_or("?", |r| r.name());
                road_colour(name, i)
            });
            (t_at(tr, a, dt), t_at(tr, b, dt), colour)
        })
        .collect();
    let ignored: Vec<_> = runs(&tr.used_arte)
        .into_iter()
        .filter(|(_, _, used)| !used)
        .map(|(a, b, _)| (t_at(tr, a, dt), t_at(tr, b, dt)))
        .collect();
    estimate_strip(
        area,
        t_at(tr, tr.len(), dt),
        "ARTE estimate",
        &spans,
        &ignored,
    )
}
