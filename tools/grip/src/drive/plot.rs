//! `grip inspect --plot DIR`: `drive.png` (speeds, slip, torque over the
//! true-road bands, and a strip of ARTE's estimate, in the manner of the
//! offline simulator's figures) and `timing.png` (wake-up latency histogram
//! of the control loop).

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::log::DriveLog;
use super::summary::Percentiles;
use crate::plot::{init_fonts, road_colour, runs};

const W: u32 = 1600;
const PANEL_H: u32 = 330;
const STRIP_H: u32 = 80;
const TITLE_H: u32 = 50;

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type Res = Result<(), Box<dyn std::error::Error>>;

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

fn panel(
    area: &Area<'_>,
    s: &Series,
    caption: &str,
    (y_lo, y_hi): (f64, f64),
    label_roads: bool,
    lines: &[(&str, &[f64], &[f64], RGBColor)],
) -> Res {
    let t_end = s.t.last().copied().unwrap_or(1.0).max(1e-3);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .caption(caption, ("sans-serif", 20))
        .x_label_area_size(34)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, y_lo..y_hi)?;
    let names: Vec<String> = {
        let mut n = s.road.clone();
        n.sort();
        n.dedup();
        n
    };
    for (a, b, road) in runs(&s.road) {
        let idx = names.iter().position(|n| *n == road).unwrap_or(0);
        let ta = s.t[a];
        let tb = s.t.get(b).copied().unwrap_or(t_end);
        chart.draw_series(std::iter::once(Rectangle::new(
            [(ta, y_lo), (tb, y_hi)],
            road_colour(&road, idx).mix(0.25).filled(),
        )))?;
        if label_roads {
            chart.draw_series(std::iter::once(Text::new(
                road.clone(),
                (ta + 0.005 * t_end, y_hi - 0.03 * (y_hi - y_lo)),
                ("sans-serif", 15).into_font().color(&BLACK),
            )))?;
        }
    }
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("t (s, from the first ground-truth sample)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    for (label, ts, ys, colour) in lines {
        let c = *colour;
        let step = (ts.len() / 3000).max(1);
        chart
            .draw_series(LineSeries::new(
                (0..ts.len().min(ys.len()))
                    .step_by(step)
                    .filter(|&k| ys[k].is_finite())
                    .map(|k| (ts[k], ys[k].clamp(y_lo, y_hi))),
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

fn strip(area: &Area<'_>, s: &Series) -> Res {
    let t_end = s.t.last().copied().unwrap_or(1.0).max(1e-3);
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(8)
        .x_label_area_size(0)
        .y_label_area_size(60)
        .caption(
            "ARTE estimate (from the frame's start to its publication; white: no class)",
            ("sans-serif", 15),
        )
        .build_cartesian_2d(0.0..t_end, 0.0..1.0)?;
    let mut names: Vec<String> = s.road.clone();
    names.extend(s.est.iter().map(|e| e.2.clone()));
    names.sort();
    names.dedup();
    for (t0, t1, name) in &s.est {
        let fill = if name.is_empty() {
            WHITE.filled()
        } else {
            let idx = names.iter().position(|n| n == name).unwrap_or(0);
            road_colour(name, idx).mix(0.85).filled()
        };
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t0.max(0.0), 0.0), (t1.min(t_end), 1.0)],
            fill,
        )))?;
    }
    chart.draw_series(std::iter::once(Rectangle::new(
        [(0.0, 0.0), (t_end, 1.0)],
        BLACK.stroke_width(1),
    )))?;
    Ok(())
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
