//! A sheet of rendered shapes: panels in a grid, all at one scale (mm per pixel is the same
//! in every panel, so sizes compare), a caption under each, a title, and a colour bar in mm
//! when colour carries values. PNG, deterministic: the same sheet gives the same bytes.

use std::fmt::Write as _;

use resvg::tiny_skia::{Color, Pixmap, PixmapPaint, Transform};
use thiserror::Error;

use super::camera::{View, extent};
use super::colour::{hex, ramp};
use super::raster::{Colouring, Framing, draw};
use crate::mesh::Mesh;
use crate::report::escape;
use crate::report::png::{FONT_FAMILY, MAX_SIDE, PngError, draw_svg_over};

/// Share of a panel's side the largest shape spans.
const FILL: f64 = 0.86;
const GAP: u32 = 8;
const TITLE: u32 = 30;
const CAPTION: u32 = 20;
const BAR: u32 = 50;

/// Smallest and largest panel side, px.
pub const PANEL_PX: (u32, u32) = (48, 1024);

/// Why a sheet could not be drawn.
#[derive(Debug, Error)]
pub enum RenderError {
    /// Nothing to draw, or a size outside the limits.
    #[error("{0}")]
    Layout(String),
    /// The labels could not be drawn or the PNG encoded.
    #[error(transparent)]
    Png(#[from] PngError),
}

/// One shape in one view.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// The shape (mm, model frame).
    pub mesh: &'a Mesh,
    /// The view it is drawn in.
    pub view: View,
    /// Text under the panel.
    pub caption: String,
    /// Per-vertex values shown as colour on the sheet's colour bar (mm).
    pub values: Option<&'a [f64]>,
}

/// What the colour of panels with values means.
#[derive(Debug, Clone)]
pub struct ColourBar {
    /// Values at the two ends of the ramp (mm).
    pub range: (f64, f64),
    /// What is coloured, with its unit.
    pub label: String,
}

/// Panels in rows of `columns`.
#[derive(Debug, Clone)]
pub struct Sheet<'a> {
    /// Text above the panels.
    pub title: String,
    /// Panels per row (at least 1).
    pub columns: usize,
    /// Side of each square panel, px.
    pub panel_px: u32,
    /// The panels, row by row.
    pub panels: Vec<Panel<'a>>,
    /// Present when some panel has values.
    pub colour_bar: Option<ColourBar>,
}

struct Layout {
    width: u32,
    height: u32,
    columns: u32,
}

impl Sheet<'_> {
    fn layout(&self) -> Result<Layout, RenderError> {
        if self.panels.is_empty() || self.columns == 0 {
            return Err(RenderError::Layout(
                "a sheet needs at least one panel".into(),
            ));
        }
        let (lo, hi) = PANEL_PX;
        if !(lo..=hi).contains(&self.panel_px) {
            return Err(RenderError::Layout(format!(
                "size must be between {lo} and {hi} px, got {}",
                self.panel_px
            )));
        }
        let columns = self.columns.min(self.panels.len()) as u32;
        let rows = self.panels.len().div_ceil(self.columns) as u32;
        let width = columns * self.panel_px + (columns + 1) * GAP;
        let bar = if self.colour_bar.is_some() { BAR } else { 0 };
        let height = TITLE + rows * (self.panel_px + CAPTION + GAP) + GAP + bar;
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(RenderError::Layout(format!(
                "the picture would be {width}×{height} px, more than {MAX_SIDE} px a side: ask for fewer panels or a smaller size"
            )));
        }
        Ok(Layout {
            width,
            height,
            columns,
        })
    }

    /// Pixels per mm shared by every panel: the largest projected shape fills [`FILL`].
    fn px_per_mm(&self) -> f64 {
        let largest = self
            .panels
            .iter()
            .map(|p| {
                let (_, w, h) = extent(p.view, &p.mesh.vertices);
                w.max(h)
            })
            .fold(0.0, f64::max);
        if largest > 0.0 && largest.is_finite() {
            FILL * f64::from(self.panel_px) / largest
        } else {
            1.0
        }
    }

    fn origin(&self, i: usize, layout: &Layout) -> (u32, u32) {
        let (row, column) = ((i as u32) / layout.columns, (i as u32) % layout.columns);
        (
            GAP + column * (self.panel_px + GAP),
            TITLE + row * (self.panel_px + CAPTION + GAP),
        )
    }

    /// The sheet as PNG bytes.
    pub fn render(&self) -> Result<Vec<u8>, RenderError> {
        let layout = self.layout()?;
        let mut pixmap = Pixmap::new(layout.width, layout.height)
            .ok_or_else(|| RenderError::Layout("empty picture".into()))?;
        pixmap.fill(Color::WHITE);
        let px_per_mm = self.px_per_mm();
        for (i, panel) in self.panels.iter().enumerate() {
            let (centre, _, _) = extent(panel.view, &panel.mesh.vertices);
            let colouring = match (&panel.values, &self.colour_bar) {
                (Some(values), Some(bar)) => Some(Colouring {
                    values,
                    range: bar.range,
                }),
                _ => None,
            };
            let framing = Framing { centre, px_per_mm };
            let size = (self.panel_px, self.panel_px);
            let drawn = draw(panel.mesh, colouring.as_ref(), panel.view, framing, size)
                .ok_or_else(|| RenderError::Layout("empty panel".into()))?;
            let (x, y) = self.origin(i, &layout);
            pixmap.draw_pixmap(
                x as i32,
                y as i32,
                drawn.as_ref(),
                &PixmapPaint::default(),
                Transform::identity(),
                None,
            );
        }
        draw_svg_over(&self.labels(&layout, px_per_mm), &mut pixmap)?;
        pixmap
            .encode_png()
            .map_err(|e| RenderError::Png(PngError::Encode(e.to_string())))
    }

    /// Title, captions, a 10 mm scale bar and the colour bar, as SVG over the panels.
    fn labels(&self, layout: &Layout, px_per_mm: f64) -> String {
        let mut svg = format!(
            r##"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" font-family="{FONT_FAMILY}" fill="#222">"##,
            layout.width, layout.height
        );
        // About 9 px a character of the bold title; the scale bar keeps the last ~110 px.
        let room = (layout.width.saturating_sub(GAP + 110) / 9).max(8) as usize;
        let title = if self.title.chars().count() > room {
            let mut t: String = self.title.chars().take(room - 1).collect();
            t.push('…');
            t
        } else {
            self.title.clone()
        };
        let _ = write!(
            svg,
            r#"<text x="{GAP}" y="20" font-size="15" font-weight="bold">{}</text>"#,
            escape(&title)
        );
        let scale_px = 10.0 * px_per_mm;
        let _ = write!(
            svg,
            r##"<rect x="{:.1}" y="14" width="{scale_px:.1}" height="3" fill="#222"/><text x="{:.1}" y="12" font-size="11" text-anchor="end">10 mm</text>"##,
            f64::from(layout.width - GAP) - scale_px,
            f64::from(layout.width - GAP) - scale_px - 4.0,
        );
        for (i, panel) in self.panels.iter().enumerate() {
            let (x, y) = self.origin(i, layout);
            let _ = write!(
                svg,
                r#"<text x="{}" y="{}" font-size="12" text-anchor="middle">{}</text>"#,
                x + self.panel_px / 2,
                y + self.panel_px + 14,
                escape(&panel.caption)
            );
        }
        if let Some(bar) = &self.colour_bar {
            colour_bar(&mut svg, bar, layout);
        }
        svg.push_str("</svg>");
        svg
    }
}

fn colour_bar(svg: &mut String, bar: &ColourBar, layout: &Layout) {
    let top = layout.height - BAR + 6;
    let (x0, width) = (GAP + 40, (layout.width - 2 * GAP - 80).max(40));
    svg.push_str(r#"<defs><linearGradient id="ramp" x1="0" x2="1" y1="0" y2="0">"#);
    for k in 0..=10 {
        let t = f64::from(k) / 10.0;
        let _ = write!(svg, r#"<stop offset="{t}" stop-color="{}"/>"#, hex(ramp(t)));
    }
    let _ = write!(
        svg,
        r##"</linearGradient></defs><rect x="{x0}" y="{top}" width="{width}" height="12" fill="url(#ramp)" stroke="#444" stroke-width="0.5"/>"##
    );
    let (lo, hi) = bar.range;
    for k in 0..=4 {
        let t = f64::from(k) / 4.0;
        let _ = write!(
            svg,
            r#"<text x="{:.1}" y="{}" font-size="11" text-anchor="middle">{:.2}</text>"#,
            f64::from(x0) + t * f64::from(width),
            top + 25,
            lo + t * (hi - lo)
        );
    }
    let _ = write!(
        svg,
        r#"<text x="{}" y="{}" font-size="11" text-anchor="middle">{}</text>"#,
        x0 + width / 2,
        top + 39,
        escape(&bar.label)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};

    fn sheet(mesh: &Mesh, bar: bool) -> Sheet<'_> {
        Sheet {
            title: "Atlas".into(),
            columns: 3,
            panel_px: 120,
            panels: View::ALL
                .into_iter()
                .map(|view| Panel {
                    mesh,
                    view,
                    caption: view.as_str().into(),
                    values: None,
                })
                .collect(),
            colour_bar: bar.then(|| ColourBar {
                range: (0.0, 2.0),
                label: "distance, mm".into(),
            }),
        }
    }

    #[test]
    fn a_sheet_is_a_deterministic_png_of_its_layout() {
        let mesh = phantom::subject(Family::Lv, 1, 0).canonical_mesh();
        let png = sheet(&mesh, false).render().unwrap();
        assert_eq!(png, sheet(&mesh, false).render().unwrap());
        let pixmap = Pixmap::decode_png(&png).unwrap();
        assert_eq!(pixmap.width(), 3 * 120 + 4 * GAP);
        assert_eq!(pixmap.height(), TITLE + 120 + CAPTION + 2 * GAP);
        let with_bar = Pixmap::decode_png(&sheet(&mesh, true).render().unwrap()).unwrap();
        assert_eq!(with_bar.height(), pixmap.height() + BAR);
    }

    #[test]
    fn sizes_outside_the_limits_are_refused() {
        let mesh = phantom::subject(Family::Lv, 1, 0).canonical_mesh();
        let mut s = sheet(&mesh, false);
        s.panel_px = 10;
        assert!(matches!(s.render(), Err(RenderError::Layout(_))));
        s.panel_px = 1000;
        s.columns = 1;
        s.panels = std::iter::repeat_n(s.panels[0].clone(), 9).collect();
        assert!(matches!(s.render(), Err(RenderError::Layout(m)) if m.contains("fewer panels")));
        s.panels.clear();
        assert!(s.render().is_err());
    }
}
