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
            root.draw_text("grip 123", &("sans-serif", 20).into_font().color(&BLACK), (5, 10))
                .unwrap();
            root.present().unwrap();
        }
        assert!(buf.iter().any(|&b| b < 128), "text drew no dark pixels");
    }
}
