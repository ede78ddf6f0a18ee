//! `grip inspect --plot DIR`: `drive.png` (speeds, slip, torque over the
//! true-road bands, and a strip of ARTE's estimate, in the manner of the
//! offline simulator's figures) and `timing.png` (wake-up latency histogram
//! of the control loop).

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use plotters::prelude::*;

use crate::plot::{
    Area, Band, Line, PlotResult as Res, estimate_strip, init_fonts, road_colour, road_panel, runs,
};
use grip_drive::DriveLog;
use grip_drive::summary::Percentiles;

const W: u32 = 1600;
const PANEL_H: u32 = 330;
const STRIP_H: u32 = 80;
const TITLE_H: u32 = 50;

struct Series {
    t: Vec<f64>,
    v: Vec<f64>,
    r_omega: Vec<f64>,
    lambda: Vec<f64>,
    torque: Vec<f64>,
    road: Vec<String>,
    ct: Vec<f64>,
    demand: Vec<f64>,
    cmd: Vec<f64>,
    est: Vec<(f64, f64, String)>,
}

fn series(log: &DriveLog, r: f64) -> Series {
    let t0 = log.truth.first().map_or(0, |g| g.stamp_ns);
    let rel = |ns: u64| (ns as i128 - t0 as i128) as f64 * 1e-9;
    Series {
        t: log.truth.iter().map(|g| rel(g.stamp_ns)).collect(),
        v: log.truth.iter().map(|g| g.v).collect(),
        r_omega: log.truth.iter().map(|g| r * g.omega).collect(),
        lambda: log.truth.iter().map(|g| g.lambda).collect(),
        torque: log.truth.iter().map(|g| g.torque).collect(),
        road: log
            .truth
            .iter()
            .map(|g| g.road_name().unwrap_or("?").to_owned())
            .collect(),
        ct: log.cycles.iter().map(|c| rel(c.stamp_ns)).collect(),
        demand: log.cycles.iter().map(|c| c.demand).collect(),
        cmd: log.cycles.iter().map(|c| c.torque_cmd).collect(),
        est: log
            .roads
            .iter()
            .map(|e| {
                (
                    rel(e.frame_t0_ns),
                    rel(e.stamp_ns),
                    if e.class_index == grip_msgs::NO_CLASS {
                        String::new()
                    } else {
                        e.class_name().unwrap_or("?").to_owned()
                    },
                )
            })
            .collect(),
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

/// The true-road bands of `s` (colours by name, else by sorted position).
fn bands(s: &Series) -> Vec<Band> {
    let t_end = s.t.last().copied().unwrap_or(1.0);
    let mut names = s.road.clone();
    names.sort();
    names.dedup();
    runs(&s.road)
        .into_iter()
        .map(|(a, b, road)| {
            let idx = names.iter().position(|n| *n == road).unwrap_or(0);
            Band {
                t0: s.t[a],
                t1: s.t.get(b).copied().unwrap_or(t_end),
                colour: road_colour(&road, idx),
                label: road,
            }
        })
        .collect()
}

/// A panel of `s` with its road bands and `lines` (label, times, values, colour).
fn panel(
    area: &Area<'_>,
    s: &Series,
    caption: &str,
    y: (f64, f64),
    label_roads: bool,
    lines: &[(&str, &[f64], &[f64], RGBColor)],
) -> Res {
    let lines: Vec<Line<'_>> = lines
        .iter()
        .map(|&(label, ts, ys, colour)| Line {
            label,
            colour,
            points: ts.iter().copied().zip(ys.iter().copied()).collect(),
        })
        .collect();
    road_panel(
        area,
        s.t.last().copied().unwrap_or(1.0),
        caption,
        "t (s, from the first ground-truth sample)",
        y,
        &bands(s),
        label_roads,
        &lines,
    )
}

/// ARTE's estimates as a strip (colours as the road bands).
fn strip(area: &Area<'_>, s: &Series) -> Res {
    let mut names: Vec<String> = s.road.clone();
    names.extend(s.est.iter().map(|e| e.2.clone()));
    names.sort();
    names.dedup();
    let spans: Vec<_> = s
        .est
        .iter()
        .map(|(t0, t1, name)| {
            let colour = (!name.is_empty()).then(|| {
                let idx = names.iter().position(|n| n == name).unwrap_or(0);
                road_colour(name, idx)
            });
            (*t0, *t1, colour)
        })
        .collect();
    estimate_strip(
        area,
        s.t.last().copied().unwrap_or(1.0),
        "ARTE estimate (from the frame's start to its publication; white: no class)",
        &spans,
        &[],
    )
}

fn drive_png(path: &Path, log: &DriveLog, r: f64, title: &str) -> Res {
    let s = series(log, r);
    let h = TITLE_H + 3 * PANEL_H + STRIP_H;
    let root = BitMapBackend::new(path, (W, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, rest) = root.split_vertically(TITLE_H);
    top.draw_text(
        title,
        &("sans-serif", 26).into_font().color(&BLACK),
        (20, 12),
    )?;
    let (p1, r1) = rest.split_vertically(PANEL_H);
    let (p2, r2) = r1.split_vertically(PANEL_H);
    let (p3, p4) = r2.split_vertically(PANEL_H);
    panel(
        &p1,
        &s,
        "speeds (m/s, ground truth)",
        range(s.v.iter().chain(&s.r_omega).copied()),
        true,
        &[
            ("V", &s.t, &s.v, RGBColor(0, 0, 200)),
            ("r ω", &s.t, &s.r_omega, RGBColor(200, 0, 0)),
        ],
    )?;
    panel(
        &p2,
        &s,
        "slip λ (ground truth)",
        range(s.lambda.iter().copied().chain([0.0])),
        false,
        &[("λ", &s.t, &s.lambda, RGBColor(200, 0, 0))],
    )?;
    panel(
        &p3,
        &s,
        "torque (N m): demand and command from tcs-loop, T from the plant",
        range(
            s.demand
                .iter()
                .chain(&s.cmd)
                .chain(&s.torque)
                .copied()
                .chain([0.0]),
        ),
        false,
        &[
            ("T_d", &s.ct, &s.demand, RGBColor(0, 0, 0)),
            ("T*", &s.ct, &s.cmd, RGBColor(230, 130, 0)),
            ("T", &s.t, &s.torque, RGBColor(0, 0, 200)),
        ],
    )?;
    strip(&p4, &s)?;
    root.present()?;
    Ok(())
}

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
    let root = BitMapBackend::new(path, (1200, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let caption = format!(
        "tcs-loop wake-up latency: {} cycles, p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, {} above {} µs",
        p.n,
        p.p50 as f64 / 1e3,
        p.p99 as f64 / 1e3,
        p.max as f64 / 1e3,
        over,
        nb as i64 * bin_us
    );
    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .caption(caption, ("sans-serif", 18))
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

/// Writes `drive.png` and `timing.png` into `dir` (created).
pub fn write_plots(
    log: &DriveLog,
    dir: &Path,
    r: f64,
    title: &str,
) -> anyhow::Result<Vec<PathBuf>> {
    init_fonts();
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("creating {}: {e}", dir.display()))?;
    let a = dir.join("drive.png");
    drive_png(&a, log, r, title).map_err(|e| anyhow!("drawing {}: {e}", a.display()))?;
    let b = dir.join("timing.png");
    timing_png(&b, log).map_err(|e| anyhow!("drawing {}: {e}", b.display()))?;
    Ok(vec![a, b])
}
