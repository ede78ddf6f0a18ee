//! Plot helpers shared by every subcommand that draws PNGs (plotters, bitmap
//! backend). The font is embedded so plots render on machines without fonts.

use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Register the embedded DejaVu Sans as plotters' "sans-serif" family. Call
/// before drawing any text; cheap after the first call.
pub fn init_fonts() {
    REGISTER.call_once(|| {
        for style in [
            plotters::style::FontStyle::Normal,
            plotters::style::FontStyle::Bold,
            plotters::style::FontStyle::Italic,
            plotters::style::FontStyle::Oblique,
        ] {
            // Registration only fails on a malformed font, and this one is
            // embedded and checked by the test below.
            let _ = plotters::style::register_font("sans-serif", style, FONT);
        }
    });
}

/// Colour of a road band, by road name (falls back to a palette by index).
/// Shared by every figure with road bands (`grip sim`, `grip drive`/`inspect` plots).
pub fn road_colour(name: &str, index: usize) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match name {
        "asphalt" => RGBColor(150, 150, 150),
        "snow" => RGBColor(120, 180, 240),
        "gravel" => RGBColor(225, 175, 90),
        "stone" => RGBColor(170, 110, 80),
        "wet_asphalt" => RGBColor(80, 100, 140),
        "wet_stone" => RGBColor(120, 90, 130),
        "ice" => RGBColor(120, 230, 230),
        _ => {
            const P: [RGBColor; 6] = [
                RGBColor(200, 120, 200),
                RGBColor(120, 200, 120),
                RGBColor(230, 230, 120),
                RGBColor(200, 200, 255),
                RGBColor(255, 180, 180),
                RGBColor(180, 255, 220),
            ];
            P[index % P.len()]
        }
    }
}

/// Runs of equal value: (start index, end index exclusive, value).
pub fn runs<T: Clone + PartialEq>(xs: &[T]) -> Vec<(usize, usize, T)> {
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=xs.len() {
        if k == xs.len() || xs[k] != xs[start] {
            if start < xs.len() {
                out.push((start, k, xs[start].clone()));
            }
            start = k;
        }
    }
    out
}

/// A drawing area of a PNG figure.
pub type Area<'a> =
    plotters::drawing::DrawingArea<plotters::backend::BitMapBackend<'a>, plotters::coord::Shift>;

/// What drawing a figure returns.
pub type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// A coloured stretch of time `[t0, t1)` behind a panel (a road) or in an
/// estimate strip, with its label.
pub struct Band {
    /// Start (s).
    pub t0: f64,
    /// End (s).
    pub t1: f64,
    /// Fill colour (full strength; panels draw it pale).
    pub colour: plotters::style::RGBColor,
    /// Written at the band's start when the panel labels its roads.
    pub label: String,
}

/// A time series of a panel: its legend label, colour and (t, y) points.
pub struct Line<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Colour.
    pub colour: plotters::style::RGBColor,
    /// The samples; a non-finite value breaks the line, the rest are
    /// clamped to the panel's y range (the legend then says so); at most
    /// about 3000 are drawn ([`clip_trace`], [`draw_trace`]).
    pub points: Vec<(f64, f64)>,
}

/// A panel over `[0, t_end]` s: the road `bands` drawn pale behind (their
/// labels written if `label_roads`), the `lines` on top, a legend at the
/// upper right. Shared by `grip sim` and `grip inspect`/`drive` figures.
#[allow(clippy::too_many_arguments)]
pub fn road_panel(
    area: &Area<'_>,
    t_end: f64,
    caption: &str,
    x_desc: &str,
    y: (f64, f64),
    bands: &[Band],
    label_roads: bool,
    lines: &[Line<'_>],
) -> PlotResult {
    road_panel_in(
        area,
        (0.0, t_end.max(1e-3)),
        caption,
        x_desc,
        y,
        bands,
        label_roads,
        lines,
    )
}

/// A chart over time (s) and a value, on a bitmap.
pub type TimeChart<'a, 'b> = plotters::chart::ChartContext<
    'a,
    plotters::backend::BitMapBackend<'b>,
    plotters::coord::cartesian::Cartesian2d<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::types::RangedCoordf64,
    >,
>;

/// `bands` drawn pale behind `chart` over `[t_lo, t_hi]` x `[y_lo, y_hi]`
/// (clipped to it), each named at its start when `label_roads`.
pub fn draw_bands(
    chart: &mut TimeChart<'_, '_>,
    bands: &[Band],
    (t_lo, t_hi): (f64, f64),
    (y_lo, y_hi): (f64, f64),
    label_roads: bool,
) -> PlotResult {
    use plotters::prelude::*;
    let span = t_hi - t_lo;
    for b in bands {
        let (b0, b1) = (b.t0.max(t_lo), b.t1.min(t_hi));
        if b1 <= b0 {
            continue;
        }
        chart.draw_series(std::iter::once(Rectangle::new(
            [(b0, y_lo), (b1, y_hi)],
            b.colour.mix(0.25).filled(),
        )))?;
        if label_roads {
            chart.draw_series(std::iter::once(Text::new(
                b.label.clone(),
                (b0 + 0.005 * span, y_hi - 0.03 * (y_hi - y_lo)),
                ("sans-serif", 15).into_font().color(&BLACK),
            )))?;
        }
    }
    Ok(())
}

/// [`road_panel`] over `[t_lo, t_hi]` s (a zoom); bands and lines are
/// clipped to it.
#[allow(clippy::too_many_arguments)]
pub fn road_panel_in(
    area: &Area<'_>,
    (t_lo, t_hi): (f64, f64),
    caption: &str,
    x_desc: &str,
    (y_lo, y_hi): (f64, f64),
    bands: &[Band],
    label_roads: bool,
    lines: &[Line<'_>],
) -> PlotResult {
    use plotters::prelude::*;
    let t_hi = t_hi.max(t_lo + 1e-3);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .caption(caption, ("sans-serif", 20))
        .x_label_area_size(34)
        .y_label_area_size(60)
        .build_cartesian_2d(t_lo..t_hi, y_lo..y_hi)?;
    draw_bands(&mut chart, bands, (t_lo, t_hi), (y_lo, y_hi), label_roads)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_desc)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    for line in lines {
        let c = line.colour;
        let trace = clip_trace(line.points.iter().copied(), (t_lo, t_hi), (y_lo, y_hi));
        let label = if trace.clamped {
            format!("{} {CLAMPED}", line.label)
        } else {
            line.label.to_owned()
        };
        draw_trace(&mut chart, &trace, c)?
            .label(label)
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

/// What a legend adds to a trace that [`clip_trace`] clamped.
pub const CLAMPED: &str = "(clamped to the axis)";

/// At most about this many samples of a trace are drawn.
const MAX_SAMPLES: usize = 3000;

/// A time series fitted into a panel over `[t_lo, t_hi]` × `[y_lo, y_hi]`
/// ([`clip_trace`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Pieces of the line: runs of consecutive finite samples inside the
    /// time range (a non-finite value, e.g. no torque cap, breaks the
    /// line), every value within the y range.
    pub runs: Vec<Vec<(f64, f64)>>,
    /// A finite value inside the time range lay outside the y range and
    /// was clamped to it (the legend says so: [`CLAMPED`]).
    pub clamped: bool,
}

/// `points` (t, y) fitted into `[t_lo, t_hi]` × `[y_lo, y_hi]`: every
/// k-th sample (at most about 3000 drawn), samples outside the time range
/// left out, non-finite values breaking the line, the rest clamped to the
/// y range.
pub fn clip_trace(
    points: impl ExactSizeIterator<Item = (f64, f64)>,
    (t_lo, t_hi): (f64, f64),
    (y_lo, y_hi): (f64, f64),
) -> Trace {
    let step = (points.len() / MAX_SAMPLES).max(1);
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut run = Vec::new();
    let mut clamped = false;
    for (t, y) in points.step_by(step) {
        if !(t.is_finite() && y.is_finite() && (t_lo..=t_hi).contains(&t)) {
            if !run.is_empty() {
                runs.push(std::mem::take(&mut run));
            }
            continue;
        }
        let yc = y.clamp(y_lo, y_hi);
        clamped |= yc != y;
        run.push((t, yc));
    }
    if !run.is_empty() {
        runs.push(run);
    }
    Trace { runs, clamped }
}

/// Draws `trace` on `chart`, 2 px wide, as separate segments (a lone
/// sample as a dot). One polyline would not stay in the panel: plotters
/// turns a path wider than 1 px into a polygon whose inner corner at a
/// sharp turn is not capped, so a command chattering between 0 and 300
/// N m from one cycle to the next (a near reversal 1 px apart) drew
/// spikes hundreds of pixels long, out of its panel into the ones above
/// and below. A segment's polygon lies within 1 px of the segment, which
/// lies in the y range. Returns the segments' series (for a legend).
pub fn draw_trace<'c, 'a, 'b>(
    chart: &'c mut TimeChart<'a, 'b>,
    trace: &Trace,
    colour: plotters::style::RGBColor,
) -> Result<
    &'c mut plotters::chart::SeriesAnno<'a, plotters::backend::BitMapBackend<'b>>,
    Box<dyn std::error::Error>,
> {
    use plotters::prelude::*;
    let style = colour.stroke_width(2);
    chart.draw_series(
        trace
            .runs
            .iter()
            .filter(|r| r.len() == 1)
            .map(|r| Circle::new(r[0], 1, colour.filled())),
    )?;
    Ok(chart.draw_series(
        trace
            .runs
            .iter()
            .flat_map(|r| r.windows(2))
            .map(|w| PathElement::new(vec![w[0], w[1]], style)),
    )?)
}

/// A strip over `[0, t_end]` s of the estimated road: `spans` filled with
/// their colour (`None`: white, no estimate), `marks` as black ticks along
/// the bottom (e.g. cycles where the controller ignored the estimate).
pub fn estimate_strip(
    area: &Area<'_>,
    t_end: f64,
    caption: &str,
    spans: &[(f64, f64, Option<plotters::style::RGBColor>)],
    marks: &[(f64, f64)],
) -> PlotResult {
    use plotters::prelude::*;
    let t_end = t_end.max(1e-3);
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(8)
        .x_label_area_size(0)
        .y_label_area_size(60)
        .caption(caption, ("sans-serif", 15))
        .build_cartesian_2d(0.0..t_end, 0.0..1.0)?;
    for &(t0, t1, colour) in spans {
        let fill = colour.map_or(WHITE.filled(), |c| c.mix(0.85).filled());
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t0.max(0.0), 0.0), (t1.min(t_end), 1.0)],
            fill,
        )))?;
    }
    for &(t0, t1) in marks {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t0, 0.0), (t1, 0.15)],
            BLACK.filled(),
        )))?;
    }
    chart.draw_series(std::iter::once(Rectangle::new(
        [(0.0, 0.0), (t_end, 1.0)],
        BLACK.stroke_width(1),
    )))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

    /// A trace is fitted into its panel: values beyond the y range clamped
    /// (and flagged, for the key), samples outside the time range left out,
    /// a non-finite value (no torque cap) breaking the line instead of
    /// being bridged.
    #[test]
    fn a_trace_is_clamped_to_its_panel_and_broken_at_gaps() {
        let pts = [
            (-1.0, 5.0),
            (0.0, 50.0),
            (1.0, 400.0),
            (2.0, f64::NAN),
            (3.0, -20.0),
            (4.0, 100.0),
            (5.0, 7.0),
        ];
        let t = super::clip_trace(pts.into_iter(), (0.0, 4.0), (0.0, 300.0));
        assert_eq!(
            t.runs,
            vec![
                vec![(0.0, 50.0), (1.0, 300.0)],
                vec![(3.0, 0.0), (4.0, 100.0)]
            ]
        );
        assert!(t.clamped);
        let t = super::clip_trace(pts.into_iter(), (3.5, 4.5), (0.0, 300.0));
        assert_eq!(t.runs, vec![vec![(4.0, 100.0)]]);
        assert!(!t.clamped, "values outside the time range do not count");
        // at most about 3000 samples of a long trace
        let long = (0..9000).map(|k| (f64::from(k), 1.0));
        let t = super::clip_trace(long, (0.0, 9000.0), (0.0, 2.0));
        assert_eq!(t.runs.len(), 1);
        assert_eq!(t.runs[0].len(), 3000);
    }

    #[test]
    fn embedded_font_renders_text() {
        super::init_fonts();
        let mut buf = vec![0u8; 200 * 50 * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (200, 50)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            root.draw_text(
                "grip 123",
                &("sans-serif", 20).into_font().color(&BLACK),
                (5, 10),
            )
            .unwrap();
            root.present().unwrap();
        }
        assert!(buf.iter().any(|&b| b < 128), "text drew no dark pixels");
    }
}
