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

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

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
