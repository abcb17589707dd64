//! SVG plots rasterised to PNG at their own size, on white.
//!
//! Text is drawn with DejaVu Sans (regular and bold), embedded in the binary: no system
//! font is read, so the PNG looks the same on every machine, with or without fonts
//! installed. Every generic family (`sans-serif`, `serif`, …) and the default family
//! resolve to it, so any `font-family` the plots name falls back to it.

use std::sync::{Arc, LazyLock};

use resvg::tiny_skia::{Color, Pixmap, Transform};
use resvg::usvg::fontdb::{Database, Source};
use resvg::usvg::{Options, Tree};
use thiserror::Error;

/// The family name of the embedded font.
pub const FONT_FAMILY: &str = "DejaVu Sans";

/// Largest side of a raster, in px; plots are a few hundred px wide.
pub const MAX_SIDE: u32 = 8192;

/// Why an SVG could not become a PNG. Plots are drawn by this crate, so each case is a
/// defect of the plot, not of a request.
#[derive(Debug, Error)]
pub enum PngError {
    /// The SVG does not parse, or states no usable size.
    #[error("the plot is not a drawable SVG: {0}")]
    Svg(#[from] resvg::usvg::Error),
    /// The SVG's size is zero or larger than [`MAX_SIDE`].
    #[error("the plot's size {width}×{height} px is outside 1–{MAX_SIDE} px")]
    Size {
        /// Width in px.
        width: u32,
        /// Height in px.
        height: u32,
    },
    /// The pixels could not be encoded.
    #[error("the PNG could not be encoded: {0}")]
    Encode(String),
}

/// The embedded fonts, with every generic family mapped to them; built once.
static FONTS: LazyLock<Arc<Database>> = LazyLock::new(|| {
    let mut db = Database::new();
    for face in [dejavu::sans::regular(), dejavu::sans::bold()] {
        db.load_font_source(Source::Binary(Arc::new(face)));
    }
    db.set_sans_serif_family(FONT_FAMILY);
    db.set_serif_family(FONT_FAMILY);
    db.set_monospace_family(FONT_FAMILY);
    db.set_cursive_family(FONT_FAMILY);
    db.set_fantasy_family(FONT_FAMILY);
    Arc::new(db)
});

fn options() -> Options<'static> {
    Options {
        font_family: FONT_FAMILY.to_owned(),
        fontdb: Arc::clone(&FONTS),
        ..Options::default()
    }
}

/// `svg` drawn over `pixmap` at 1 px per user unit (text with the embedded font).
///
/// # Errors
/// [`PngError::Svg`] when the SVG does not parse.
pub fn draw_svg_over(svg: &str, pixmap: &mut Pixmap) -> Result<(), PngError> {
    let tree = Tree::from_str(svg, &options())?;
    resvg::render(&tree, Transform::identity(), &mut pixmap.as_mut());
    Ok(())
}

/// `svg` rasterised at its own width and height (1 px per user unit) on a white ground.
///
/// # Errors
/// [`PngError`] when the SVG does not parse, has an unusable size, or cannot be encoded.
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>, PngError> {
    let tree = Tree::from_str(svg, &options())?;
    let size = tree.size().to_int_size();
    let (width, height) = (size.width(), size.height());
    let size_error = PngError::Size { width, height };
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(size_error);
    }
    let mut pixmap = Pixmap::new(width, height).ok_or(size_error)?;
    pixmap.fill(Color::WHITE);
    resvg::render(&tree, Transform::identity(), &mut pixmap.as_mut());
    pixmap
        .encode_png()
        .map_err(|e| PngError::Encode(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::svg::{Group, HEIGHT, WIDTH, violin_plot};

    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

    fn decode(png: &[u8]) -> Pixmap {
        assert_eq!(png[..8], SIGNATURE);
        Pixmap::decode_png(png).expect("a PNG")
    }

    /// Pixels darker than mid grey (text and axes; the plots' fills are lighter).
    fn dark_pixels(p: &Pixmap) -> usize {
        p.pixels()
            .iter()
            .filter(|c| u16::from(c.red()) + u16::from(c.green()) + u16::from(c.blue()) < 3 * 96)
            .count()
    }

    #[test]
    fn a_plot_becomes_a_png_of_its_size_that_is_not_blank() {
        let values = [1.0, 2.0, 2.5, 3.0, 4.0];
        let svg = violin_plot(
            "volume_ml",
            "ml",
            &[Group {
                label: "training",
                values: &values,
            }],
            &[],
        );
        let pixmap = decode(&svg_to_png(&svg).unwrap());
        assert_eq!(
            (pixmap.width(), pixmap.height()),
            (WIDTH as u32, HEIGHT as u32)
        );
        let white = pixmap
            .pixels()
            .iter()
            .filter(|c| (c.red(), c.green(), c.blue()) == (255, 255, 255))
            .count();
        let total = pixmap.pixels().len();
        assert!(white < total, "blank");
        assert!(white > total / 2, "the ground is white");
        assert!(dark_pixels(&pixmap) > 0);
    }

    #[test]
    fn text_is_drawn_without_system_fonts() {
        let svg = |text: &str| {
            format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="60" font-family="system-ui, sans-serif">{text}</svg>"#
            )
        };
        let blank = decode(&svg_to_png(&svg("")).unwrap());
        assert_eq!(dark_pixels(&blank), 0);
        for text in [
            r#"<text x="10" y="40" font-size="24">mean ± 2σ</text>"#,
            r#"<text x="10" y="40" font-size="24" font-weight="bold">Title</text>"#,
            r#"<text x="10" y="40" font-size="24" font-family="No Such Font">fallback</text>"#,
        ] {
            let drawn = decode(&svg_to_png(&svg(text)).unwrap());
            assert!(dark_pixels(&drawn) > 50, "no text drawn for {text}");
        }
    }

    #[test]
    fn unusable_svg_is_an_error() {
        assert!(matches!(svg_to_png("not svg"), Err(PngError::Svg(_))));
        let huge = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100000" height="10"/>"#;
        assert!(matches!(svg_to_png(huge), Err(PngError::Size { .. })));
    }
}
