//! Plots as self-contained SVG: violins of value distributions with reference intervals,
//! and line charts. Deterministic output (fixed sizes, fixed number formatting).

use std::fmt::Write;

use super::escape;
use super::ticks::round_ticks;
use crate::eval::kde::silverman_bandwidth;
use crate::eval::stats::{quantile_sorted, sorted};

/// Plot width in px.
pub const WIDTH: f64 = 560.0;
/// Plot height in px.
pub const HEIGHT: f64 = 320.0;
/// Margins in px: left (axis labels), right, top (title), bottom.
const MARGIN: [f64; 4] = [64.0, 16.0, 32.0, 40.0];
/// Points at which a violin's density is evaluated.
const VIOLIN_POINTS: usize = 64;
/// Fonts of the text: the pages' own, so a plot looks the same alone as on its page.
const FONT_FAMILY: &str = "system-ui, sans-serif";
/// Series and group colours.
const PALETTE: [&str; 6] = [
    "#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860",
];

/// A named set of values drawn as one violin.
pub struct Group<'a> {
    /// Label under the violin.
    pub label: &'a str,
    /// The values (any unit; the plot states it).
    pub values: &'a [f64],
}

/// A reference interval drawn across the plot.
pub struct Band<'a> {
    /// Legend text.
    pub label: &'a str,
    /// `[low, high]`.
    pub interval: [f64; 2],
}

/// Maps values in `[lo, hi]` to pixels `[p_lo, p_hi]`.
#[derive(Clone, Copy)]
struct Scale {
    lo: f64,
    hi: f64,
    p_lo: f64,
    p_hi: f64,
}

impl Scale {
    fn new(lo: f64, hi: f64, p_lo: f64, p_hi: f64) -> Self {
        let (lo, hi) = if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, lo + 0.5)
        };
        Self { lo, hi, p_lo, p_hi }
    }

    fn at(&self, v: f64) -> f64 {
        self.p_lo + (v - self.lo) / (self.hi - self.lo) * (self.p_hi - self.p_lo)
    }
}

/// Opens an `<svg class="plot">` with its title.
fn open(out: &mut String, title: &str) {
    let _ = write!(
        out,
        r#"<svg class="plot" xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="{FONT_FAMILY}" role="img"><title>{t}</title><text x="{x}" y="20" text-anchor="middle" font-size="14" font-weight="bold">{t}</text>"#,
        t = escape(title),
        x = WIDTH / 2.0,
    );
}

/// A vertical value axis with ticks at round values, labelled with `label`.
fn y_axis(out: &mut String, y: Scale, label: &str) {
    let x0 = MARGIN[0];
    let _ = write!(
        out,
        r##"<line x1="{x0}" y1="{}" x2="{x0}" y2="{}" stroke="#333"/>"##,
        y.p_hi, y.p_lo
    );
    for (v, text) in round_ticks(y.lo, y.hi, 4) {
        let p = y.at(v);
        let _ = write!(
            out,
            r##"<line x1="{}" y1="{p:.1}" x2="{x0}" y2="{p:.1}" stroke="#333"/><text x="{}" y="{:.1}" text-anchor="end" font-size="11">{text}</text>"##,
            x0 - 4.0,
            x0 - 6.0,
            p + 4.0,
        );
    }
    let _ = write!(
        out,
        r#"<text x="14" y="{:.1}" transform="rotate(-90 14 {:.1})" text-anchor="middle" font-size="12">{}</text>"#,
        (y.p_lo + y.p_hi) / 2.0,
        (y.p_lo + y.p_hi) / 2.0,
        escape(label)
    );
}

/// Label of an axis end: whole numbers without decimals (epoch 3, not 3.00).
fn tick(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-2..1e5).contains(&a) {
        format!("{v:.2e}")
    } else if a >= 100.0 || v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

/// Value range of the groups and bands, padded by 5%.
fn value_range(groups: &[Group<'_>], bands: &[Band<'_>]) -> (f64, f64) {
    let values = groups.iter().flat_map(|g| g.values.iter().copied());
    let ends = bands.iter().flat_map(|b| b.interval);
    let (lo, hi) = values
        .chain(ends)
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = 0.05 * (hi - lo).max(1e-9);
    (lo - pad, hi + pad)
}

/// Violins of `groups` on one value axis (`unit`), with `bands` drawn as shaded intervals
/// and bracketed on the right.
pub fn violin_plot(title: &str, unit: &str, groups: &[Group<'_>], bands: &[Band<'_>]) -> String {
    let mut out = String::new();
    open(&mut out, title);
    let (lo, hi) = value_range(groups, bands);
    let y = Scale::new(lo, hi, HEIGHT - MARGIN[3], MARGIN[2]);
    let bracket_space = 26.0 * bands.len() as f64;
    let plot_right = WIDTH - MARGIN[1] - bracket_space;
    for (i, band) in bands.iter().enumerate() {
        draw_band(&mut out, y, band, i, plot_right);
    }
    y_axis(&mut out, y, unit);
    let slot = (plot_right - MARGIN[0]) / groups.len().max(1) as f64;
    for (i, group) in groups.iter().enumerate() {
        let centre = MARGIN[0] + slot * (i as f64 + 0.5);
        draw_violin(
            &mut out,
            y,
            group,
            centre,
            0.4 * slot,
            PALETTE[i % PALETTE.len()],
        );
    }
    out.push_str("</svg>");
    out
}

fn draw_band(out: &mut String, y: Scale, band: &Band<'_>, i: usize, plot_right: f64) {
    let colour = PALETTE[(i + 2) % PALETTE.len()];
    let (top, bottom) = (y.at(band.interval[1]), y.at(band.interval[0]));
    let x = plot_right + 8.0 + 26.0 * i as f64;
    let _ = write!(
        out,
        r#"<rect class="band" x="{x0}" y="{top:.1}" width="{w:.1}" height="{h:.1}" fill="{colour}" fill-opacity="0.07"/><path d="M{xa:.1} {top:.1}H{x:.1}V{bottom:.1}H{xa:.1}" stroke="{colour}" stroke-width="2" fill="none"/><text x="{xt:.1}" y="{ym:.1}" transform="rotate(90 {xt:.1} {ym:.1})" text-anchor="middle" font-size="10" fill="{colour}">{label}</text>"#,
        x0 = MARGIN[0],
        w = plot_right - MARGIN[0],
        h = (bottom - top).max(0.0),
        xa = x - 5.0,
        xt = x + 6.0,
        ym = (top + bottom) / 2.0,
        label = escape(band.label),
    );
}

fn draw_violin(
    out: &mut String,
    y: Scale,
    group: &Group<'_>,
    centre: f64,
    half_width: f64,
    colour: &str,
) {
    let values: Vec<f64> = group
        .values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let label_y = HEIGHT - MARGIN[3] + 16.0;
    let _ = write!(
        out,
        r#"<text x="{centre:.1}" y="{label_y:.1}" text-anchor="middle" font-size="12">{} (n = {})</text>"#,
        escape(group.label),
        values.len()
    );
    if values.is_empty() {
        return;
    }
    let s = sorted(&values);
    if let Some(outline) = violin_outline(&s, y, centre, half_width) {
        let _ = write!(
            out,
            r#"<path class="violin" d="{outline}" fill="{colour}" fill-opacity="0.45" stroke="{colour}"/>"#
        );
    }
    let (q1, median, q3) = (
        quantile_sorted(&s, 0.25),
        quantile_sorted(&s, 0.5),
        quantile_sorted(&s, 0.75),
    );
    let (lo, hi) = (s[0], s[s.len() - 1]);
    let _ = write!(
        out,
        r##"<line x1="{centre:.1}" y1="{:.1}" x2="{centre:.1}" y2="{:.1}" stroke="#222"/><rect x="{:.1}" y="{:.1}" width="8" height="{:.1}" fill="#222"/><circle cx="{centre:.1}" cy="{:.1}" r="3" fill="#fff"/>"##,
        y.at(hi),
        y.at(lo),
        centre - 4.0,
        y.at(q3),
        (y.at(q1) - y.at(q3)).max(1.0),
        y.at(median),
    );
}

/// The closed outline of a Gaussian-KDE violin, or `None` for fewer than two distinct values.
fn violin_outline(sorted: &[f64], y: Scale, centre: f64, half_width: f64) -> Option<String> {
    let bandwidth = silverman_bandwidth(sorted).ok().filter(|b| *b > 0.0)?;
    let (lo, hi) = (
        sorted[0] - 2.0 * bandwidth,
        sorted[sorted.len() - 1] + 2.0 * bandwidth,
    );
    let (lo, hi) = (lo.max(y.lo), hi.min(y.hi));
    let grid: Vec<f64> = (0..VIOLIN_POINTS)
        .map(|i| lo + (hi - lo) * i as f64 / (VIOLIN_POINTS - 1) as f64)
        .collect();
    let density: Vec<f64> = grid
        .iter()
        .map(|g| {
            sorted
                .iter()
                .map(|v| (-0.5 * ((g - v) / bandwidth).powi(2)).exp())
                .sum::<f64>()
        })
        .collect();
    let top = density.iter().copied().fold(0.0, f64::max);
    if top <= 0.0 {
        return None;
    }
    let mut d = String::new();
    for (g, f) in grid.iter().zip(&density) {
        let cmd = if d.is_empty() { 'M' } else { 'L' };
        let _ = write!(
            d,
            "{cmd}{:.1} {:.1}",
            centre + half_width * f / top,
            y.at(*g)
        );
    }
    for (g, f) in grid.iter().zip(&density).rev() {
        let _ = write!(d, "L{:.1} {:.1}", centre - half_width * f / top, y.at(*g));
    }
    d.push('Z');
    Some(d)
}

/// A named series of `(x, y)` points.
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// Points in drawing order.
    pub points: &'a [(f64, f64)],
}

/// Line chart of `series` with labelled axes.
pub fn line_plot(title: &str, x_label: &str, y_label: &str, series: &[Series<'_>]) -> String {
    let mut out = String::new();
    open(&mut out, title);
    let all = series.iter().flat_map(|s| s.points.iter());
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in all.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
    }
    if !x_lo.is_finite() {
        (x_lo, x_hi, y_lo, y_hi) = (0.0, 1.0, 0.0, 1.0);
    }
    let x = Scale::new(x_lo, x_hi, MARGIN[0], WIDTH - MARGIN[1]);
    let y = Scale::new(y_lo.min(0.0), y_hi, HEIGHT - MARGIN[3], MARGIN[2]);
    y_axis(&mut out, y, y_label);
    let base = HEIGHT - MARGIN[3];
    let _ = write!(
        out,
        r##"<line x1="{}" y1="{base}" x2="{}" y2="{base}" stroke="#333"/><text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="12">{}</text><text x="{}" y="{:.1}" font-size="11">{}</text><text x="{}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
        MARGIN[0],
        WIDTH - MARGIN[1],
        (MARGIN[0] + WIDTH - MARGIN[1]) / 2.0,
        HEIGHT - 6.0,
        escape(x_label),
        MARGIN[0],
        base + 14.0,
        tick(x.lo),
        WIDTH - MARGIN[1],
        base + 14.0,
        tick(x.hi),
    );
    for (i, s) in series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let mut d = String::new();
        for &(px, py) in s
            .points
            .iter()
            .filter(|(a, b)| a.is_finite() && b.is_finite())
        {
            let cmd = if d.is_empty() { 'M' } else { 'L' };
            let _ = write!(d, "{cmd}{:.1} {:.1}", x.at(px), y.at(py));
        }
        let _ = write!(
            out,
            r#"<path class="series" d="{d}" fill="none" stroke="{colour}" stroke-width="2"/><text x="{:.1}" y="{:.1}" font-size="11" fill="{colour}">{}</text>"#,
            MARGIN[0] + 8.0,
            MARGIN[2] + 14.0 * (i as f64 + 1.0),
            escape(s.label)
        );
    }
    out.push_str("</svg>");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_end_labels_drop_decimals_of_whole_numbers() {
        assert_eq!(tick(3.0), "3");
        assert_eq!(tick(2.5), "2.50");
        assert_eq!(tick(1234.4), "1234");
    }

    #[test]
    fn violin_plot_draws_each_group_and_band() {
        let training = [100.0, 104.0, 96.0, 110.0, 90.0];
        let cohort = [101.0, 99.0, 108.0, 94.0];
        let svg = violin_plot(
            "volume_ml",
            "ml",
            &[
                Group {
                    label: "training",
                    values: &training,
                },
                Group {
                    label: "cohort",
                    values: &cohort,
                },
            ],
            &[
                Band {
                    label: "range",
                    interval: [90.0, 110.0],
                },
                Band {
                    label: "mean ± 2σ",
                    interval: [85.0, 115.0],
                },
            ],
        );
        assert!(svg.starts_with("<svg class=\"plot\"") && svg.ends_with("</svg>"));
        assert_eq!(svg.matches("class=\"violin\"").count(), 2);
        assert_eq!(svg.matches("class=\"band\"").count(), 2);
        assert!(svg.contains("training (n = 5)") && svg.contains("mean ± 2σ"));
        // The band's top edge sits at 115 on a 85..115 axis padded by 5%: near the top margin.
        let y = Scale::new(83.5, 116.5, HEIGHT - MARGIN[3], MARGIN[2]);
        assert!(
            (y.at(115.0) - (MARGIN[2] + 1.5 / 33.0 * (HEIGHT - MARGIN[2] - MARGIN[3]))).abs()
                < 1e-9
        );
    }

    #[test]
    fn text_is_escaped_and_empty_input_does_not_fail() {
        let svg = violin_plot(
            "a < b & c",
            "",
            &[Group {
                label: "none",
                values: &[],
            }],
            &[],
        );
        assert!(svg.contains("a &lt; b &amp; c") && !svg.contains("a < b"));
        let line = line_plot("empty", "x", "y", &[]);
        assert!(line.ends_with("</svg>"));
    }

    #[test]
    fn line_plot_has_one_path_per_series() {
        let a = [(1.0, 0.5), (2.0, 0.8), (3.0, 1.0)];
        let b = [(1.0, 2.0), (2.0, 1.0)];
        let svg = line_plot(
            "loss",
            "epoch",
            "loss",
            &[
                Series {
                    label: "train",
                    points: &a,
                },
                Series {
                    label: "other",
                    points: &b,
                },
            ],
        );
        assert_eq!(svg.matches("class=\"series\"").count(), 2);
        assert!(svg.contains("M64.0 ")); // the first point sits on the left margin
    }
}
