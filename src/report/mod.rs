//! Report pages: self-contained HTML with inline SVG plots (no scripts, no external
//! resources) for cohorts and models, and each plot alone as SVG or PNG. Pure: built from
//! the stored reports.

mod cohort_page;
mod cohort_plots;
mod model_page;
mod model_plots;
mod plot;
pub mod png;
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
.note{color:#555;font-size:0.9em}figure{margin:0}figure>svg{display:block}figcaption{font-size:0.85em;text-align:right}";

/// A complete HTML document.
fn page(title: &str, body: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>{body}</body></html>\n",
        escape(title)
    )
}

/// `mean ± sd` with two decimals.
fn mean_sd(mean: f64, sd: f64) -> String {
    format!("{mean:.2} ± {sd:.2}")
}
