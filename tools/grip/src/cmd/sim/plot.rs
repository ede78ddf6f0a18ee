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

/// One column of an entry figure: a caption, the setup it ran on, its trace.
pub struct EntryRun<'a> {
    /// Column caption (variant and vehicle).
    pub label: String,
    /// The setup the run used (roads, dt).
    pub setup: &'a SimSetup,
    /// The run's time series.
    pub trace: &'a Trace,
}

/// First cycle at which the driven wheel is on road `road` after being on
/// another one (or at the start), with its time.
pub fn first_entry(tr: &Trace, road: u32) -> Option<(usize, f64)> {
    (0..tr.len())
        .find(|&k| tr.true_road[k] == road && (k == 0 || tr.true_road[k - 1] != road))
        .map(|k| (k, tr.t[k]))
}

/// A zoom on the first entry of the driven wheel onto `road`, `half_s` each
/// side, one column per run: torque (T_d, T*, T and the road's transmissible
/// torque μ_peak N r), slip (λ, λ_opt of the true road), both over the true
/// road at the wheel, and the road the controller believes (coloured bands)
/// with the belief's confidence. Runs that never reach `road` are left out;
/// none reaching it is an error.
pub fn entry_figure(
    path: &Path,
    runs_in: &[EntryRun<'_>],
    road: usize,
    half_s: f64,
    title: &str,
) -> Res {
    crate::plot::init_fonts();
    let cols_runs: Vec<(&EntryRun<'_>, f64)> = runs_in
        .iter()
        .filter_map(|r| first_entry(r.trace, road as u32).map(|(_, t)| (r, t)))
        .collect();
    if cols_runs.is_empty() {
        return Err("no run reaches the road".into());
    }
    let setup0 = cols_runs[0].0.setup;
    let road_name = setup0.roads().by_index(road).map_or("?", |r| r.name());
    let h = TITLE_H + 3 * PANEL_H + LEGEND_H;
    let w = (700 * cols_runs.len() as u32).max(900);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(TITLE_H);
    top.draw_text(
        title,
        &("sans-serif", 26).into_font().color(&BLACK),
        (20, 15),
    )?;
    let (body, legend) = rest.split_vertically(h - TITLE_H - LEGEND_H);
    let cols = body.split_evenly((1, cols_runs.len()));

    // Common y ranges over the windows.
    let window = |tr: &Trace, te: f64| -> Vec<usize> {
        (0..tr.len())
            .filter(|&k| (tr.t[k] - te).abs() <= half_s)
            .collect()
    };
    let mut q = (0.0f64, 0.0f64);
    let mut l = (0.0f64, 0.0f64);
    for (r, te) in &cols_runs {
        let tr = r.trace;
        for k in window(tr, *te) {
            for v in [tr.torque[k], tr.torque_cmd[k], tr.demand[k]] {
                if v.is_finite() {
                    q = (q.0.min(v), q.1.max(v));
                }
            }
            for v in [tr.lambda[k], tr.lambda_opt_true[k]] {
                if v.is_finite() {
                    l = (l.0.min(v), l.1.max(v));
                }
            }
        }
    }
    let pad = |(lo, hi): (f64, f64)| {
        let span = (hi - lo).max(1e-6);
        (lo - 0.05 * span, hi + 0.12 * span)
    };
    let (q, l) = (pad(q), pad(l));

    for ((r, te), col) in cols_runs.iter().zip(cols.iter()) {
        let tr = r.trace;
        let setup = r.setup;
        let dt = setup.dt();
        let range = (te - half_s, te + half_s);
        let (p1, rr) = col.split_vertically(PANEL_H);
        let (p2, p3) = rr.split_vertically(PANEL_H);
        let true_bands = true_bands(setup, tr, dt);
        let pts = |ys: &[f64]| -> Vec<(f64, f64)> {
            tr.t.iter().copied().zip(ys.iter().copied()).collect()
        };
        // The transmissible torque of the true road at the wheel: μ_peak N r.
        let v = setup.vehicle();
        let n_r = v.normal_force() * v.r;
        let limit: Vec<f64> = tr
            .true_road
            .iter()
            .map(|&i| {
                setup
                    .roads()
                    .by_index(i as usize)
                    .map_or(f64::NAN, |x| x.mu_peak() * n_r)
            })
            .collect();
        let x_desc = format!("t (s); the wheel reaches {road_name} at {te:.3} s");
        crate::plot::road_panel_in(
            &p1,
            range,
            &format!("{}: torque (N m)", r.label),
            &x_desc,
            q,
            &true_bands,
            true,
            &[
                Line {
                    label: "T_d",
                    colour: RGBColor(0, 0, 0),
                    points: pts(&tr.demand),
                },
                Line {
                    label: "μ_peak N r (true road)",
                    colour: RGBColor(0, 150, 0),
                    points: pts(&limit),
                },
                Line {
                    label: "T* (command)",
                    colour: RGBColor(230, 130, 0),
                    points: pts(&tr.torque_cmd),
                },
                Line {
                    label: "T (motor)",
                    colour: RGBColor(0, 0, 200),
                    points: pts(&tr.torque),
                },
            ],
        )?;
        crate::plot::road_panel_in(
            &p2,
            range,
            &format!("{}: slip λ", r.label),
            &x_desc,
            l,
            &true_bands,
            false,
            &[
                Line {
                    label: "λ",
                    colour: RGBColor(200, 0, 0),
                    points: pts(&tr.lambda),
                },
                Line {
                    label: "λ_opt (true road)",
                    colour: RGBColor(0, 120, 0),
                    points: pts(&tr.lambda_opt_true),
                },
            ],
        )?;
        // The believed road as bands, its confidence as the line.
        let belief: Vec<Band> = runs(&tr.est_road)
            .into_iter()
            .filter_map(|(a, b, est)| {
                let i = est? as usize;
                let name = setup.roads().by_index(i).map_or("?", |x| x.name());
                let (t0, t1) = (t_at(tr, a, dt), t_at(tr, b, dt));
                // Label only the bands wide enough to read.
                let wide = t1.min(te + half_s) - t0.max(te - half_s) > 0.08 * half_s;
                Some(Band {
                    t0,
                    t1,
                    colour: road_colour(name, i),
                    label: if wide { name.to_owned() } else { String::new() },
                })
            })
            .collect();
        crate::plot::road_panel_in(
            &p3,
            range,
            &format!("{}: believed road (bands) and confidence", r.label),
            &x_desc,
            (0.0, 1.15),
            &belief,
            true,
            &[Line {
                label: "confidence",
                colour: RGBColor(0, 0, 0),
                points: pts(&tr.confidence),
            }],
        )?;
    }
    legend.draw_text(
        "Top two rows: background = true road under the driven wheel. Bottom row: background = road the controller believes (white: none).",
        &("sans-serif", 17).into_font().color(&BLACK),
        (20, 15),
    )?;
    root.present()?;
    Ok(())
}

/// The true road at the driven wheel as bands.
fn true_bands(setup: &SimSetup, tr: &Trace, dt: f64) -> Vec<Band> {
    runs(&tr.true_road)
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
        .collect()
}
