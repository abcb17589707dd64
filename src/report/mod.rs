//! Report pages: self-contained HTML with inline SVG plots (no scripts, no external
//! resources) for cohorts and models, and each plot alone as SVG or PNG. Pure: built from
//! the stored reports.

mod cohort_page;
mod cohort_plots;
pub mod csv;
pub mod exports;
mod model_page;
mod model_plots;
mod plot;
pub mod png;
pub mod render;
mod spread_table;
pub mod svg;
mod ticks;

pub use cohort_page::{CohortPage, cohort_page};
pub use cohort_plots::{cohort_plot, cohort_plot_names};
pub use model_page::{ModelPage, model_page};
pub use model_plots::{EXPLAINED_VARIANCE, LOSS_PREFIX, model_plot, model_plot_names};
pub use plot::{PlotError, PlotFormat};

/// `s` with the HTML/XML special characters escaped.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// Inline style of every page.
const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:24px;color:#222;max-width:1200px}\
table{border-collapse:collapse;margin:12px 0}td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}\
th:first-child,td:first-child{text-align:left}.plots{display:flex;flex-wrap:wrap;gap:12px}\
.note{color:#555;font-size:0.9em}figure{margin:0}figure>svg{display:block}figcaption{font-size:0.85em;text-align:right}figure.render img{display:block;max-width:100%}td.warn{background:#fde2d2}";

/// A complete HTML document.
fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>{body}</body></html>\n",
        escape(title)
    )
}

/// A rendered picture shown on a page.
#[derive(Debug, Clone)]
pub struct Picture {
    /// Its name at the render endpoint (e.g. `atlas`).
    pub name: String,
    /// Text under it.
    pub caption: String,
    /// The PNG.
    pub png: Vec<u8>,
}

/// The pictures as figures with the PNG inline (a `data:` URL: the page stays
/// self-contained).
fn pictures_section(pictures: &[Picture]) -> String {
    use base64::Engine as _;
    if pictures.is_empty() {
        return String::new();
    }
    let mut out = String::from("<h2>Shapes</h2><div class=\"plots\">");
    for p in pictures {
        out.push_str(&format!(
            "<figure class=\"render\" id=\"render-{}\"><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{}</figcaption></figure>",
            escape(&p.name),
            escape(&p.caption),
            base64::engine::general_purpose::STANDARD.encode(&p.png),
            escape(&p.caption)
        ));
    }
    out.push_str("</div>");
    out
}

/// `mean ± sd` with two decimals.
fn mean_sd(mean: f64, sd: f64) -> String {
    format!("{mean:.2} ± {sd:.2}")
}
