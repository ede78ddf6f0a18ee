//! `grip roads`: the road catalogue as a table; `--plot FILE.png` draws every
//! mu-lambda curve over λ ∈ [0, 1] with its peak marked.

use std::path::PathBuf;

use anyhow::Context;
use grip_config::ConfigDir;
use grip_physics::{FrictionModel, Road, RoadCatalogue};
use plotters::prelude::*;

use super::Ctx;

#[derive(clap::Args)]
pub struct Args {
    /// Draw all mu-lambda curves (λ from 0 to 1) to this PNG file (in a
    /// folder that exists; an existing file only with `--force`).
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Overwrite an existing `--plot` file.
    #[arg(long)]
    pub force: bool,
    /// Roads file to read instead of `<config-dir>/roads.toml`.
    #[arg(long, value_name = "FILE")]
    pub roads: Option<PathBuf>,
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    let dir = ConfigDir::new(&ctx.config_dir);
    let path = args.roads.unwrap_or_else(|| dir.roads_path());
    if let Some(png) = &args.plot {
        if !png
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            anyhow::bail!(
                "--plot {}: the figure is a PNG image; give a file name ending in .png",
                png.display()
            );
        }
        super::train::check_output_file("--plot", png, args.force)?;
    }
    let roads = grip_config::load_roads(&path)?;
    print!("{}", table(&roads));
    if let Some(png) = args.plot {
        plot(&roads, &png).with_context(|| format!("drawing {}", png.display()))?;
        eprintln!("wrote {}", png.display());
    }
    Ok(())
}

/// Model parameters as one short string.
fn params(m: &FrictionModel) -> String {
    match m {
        FrictionModel::Burckhardt { c1, c2, c3 } => format!("c1={c1} c2={c2} c3={c3}"),
        FrictionModel::Pacejka { b, c, d, e } => format!("B={b} C={c} D={d} E={e}"),
        FrictionModel::Table { slip, .. } => {
            format!(
                "{} points, slip {}..{}",
                slip.len(),
                slip[0],
                slip[slip.len() - 1]
            )
        }
    }
}

/// The catalogue as an aligned text table.
fn table(roads: &RoadCatalogue) -> String {
    let rows: Vec<[String; 6]> = roads
        .iter()
        .map(|r| {
            [
                r.name().to_owned(),
                r.label().to_owned(),
                r.model().kind().to_owned(),
                params(r.model()),
                format!("{:.3}", r.lambda_opt()),
                format!("{:.3}", r.mu_peak()),
            ]
        })
        .collect();
    let head = [
        "name",
        "label",
        "model",
        "parameters",
        "lambda_opt",
        "mu_peak",
    ];
    let mut w = head.map(str::len);
    for row in &rows {
        for (k, cell) in row.iter().enumerate() {
            w[k] = w[k].max(cell.chars().count());
        }
    }
    let line = |cells: [&str; 6]| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            let pad = w[k] - c.chars().count();
            if k >= 4 {
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            } else {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            }
            if k < 5 {
                s.push_str("  ");
            }
        }
        s.trim_end().to_owned() + "\n"
    };
    let mut out = line(head);
    out.push_str(&line(
        w.map(|n| "-".repeat(n)).each_ref().map(String::as_str),
    ));
    for row in &rows {
        out.push_str(&line(row.each_ref().map(String::as_str)));
    }
    out.push_str(
        "lambda_opt of a curve without an interior maximum on [0, 1] (ice) is the smallest slip reaching 99 % of mu_peak.\n",
    );
    out
}

fn plot(roads: &RoadCatalogue, png: &std::path::Path) -> anyhow::Result<()> {
    crate::plot::init_fonts();
    let root = BitMapBackend::new(png, (1200, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let y_max = roads.iter().map(Road::mu_peak).fold(0.0, f64::max) * 1.5; // headroom for the legend
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Friction coefficient vs slip (grip road catalogue)",
            ("sans-serif", 28),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..1.0, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("slip ratio λ")
        .y_desc("friction coefficient μ")
        .axis_desc_style(("sans-serif", 22))
        .label_style(("sans-serif", 18))
        .draw()?;
    let n = 1000;
    for (i, road) in roads.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let style = ShapeStyle::from(&color).stroke_width(3);
        let pts = (0..=n).map(|k| {
            let l = k as f64 / n as f64;
            (l, road.mu(l))
        });
        chart
            .draw_series(LineSeries::new(pts, style))?
            .label(format!(
                "{} (λopt {:.3}, μpeak {:.2})",
                road.label(),
                road.lambda_opt(),
                road.mu_peak()
            ))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        let peak = (road.lambda_opt(), road.mu(road.lambda_opt()));
        chart.draw_series(std::iter::once(Circle::new(peak, 7, color.filled())))?;
        chart.draw_series(std::iter::once(Circle::new(peak, 7, BLACK.stroke_width(1))))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 18))
        .draw()?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cat() -> RoadCatalogue {
        RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("ice", 0.05, 306.39, 0.0)
                .unwrap()
                .with_label("Ice"),
        ])
        .unwrap()
    }

    #[test]
    fn table_lists_every_road_with_optimum() {
        let t = table(&cat());
        assert!(t.lines().next().unwrap().starts_with("name"));
        let asphalt = t.lines().find(|l| l.starts_with("asphalt")).unwrap();
        assert!(
            asphalt.contains("burckhardt")
                && asphalt.contains("0.170")
                && asphalt.contains("1.170"),
            "{asphalt}"
        );
        assert!(t.contains("Ice"));
    }

    #[test]
    fn plot_writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("roads.png");
        plot(&cat(), &png).unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
    }

    /// A `--plot` name that is not a PNG's is refused before the table,
    /// naming the option (plotters' own error came after the table).
    #[test]
    fn a_plot_name_not_png_is_refused_first() {
        let dir = tempfile::tempdir().unwrap();
        let ctx = Ctx {
            config_dir_given: false,
            config_dir: std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
        };
        let txt = dir.path().join("x.txt");
        let e = run(
            &ctx,
            Args {
                plot: Some(txt.clone()),
                roads: None,
                force: false,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--plot") && e.contains("ending in .png"), "{e}");
        assert!(!txt.exists());
    }

    #[test]
    fn bad_roads_file_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("roads.toml"),
            "[[road]]\nname = \"a\"\nmodel = \"burckhardt\"\nc1 = -1.0\nc2 = 1.0\nc3 = 0.0\n",
        )
        .unwrap();
        let ctx = Ctx {
            config_dir_given: false,
            config_dir: dir.path().to_owned(),
        };
        let e = run(
            &ctx,
            Args {
                plot: None,
                roads: None,
                force: false,
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("road[0].c1"), "{e}");
    }
}
