//! `report.html` of a model: distributions of generalisation, specificity and matching
//! distances, the metric tables, cumulative explained variance and loss curves.

use std::fmt::Write;

use super::model_plots::{CLOSED_FORM, model_plot, model_plot_names};
use super::plot::figure;
use super::{escape, mean_sd, page};
use crate::eval::metrics::DistanceSummary;
use crate::models::ModelSummary;

/// What the model page shows.
pub struct ModelPage<'a> {
    /// Model id.
    pub model_id: &'a str,
    /// Model type, e.g. `rsmp`.
    pub model_type: &'a str,
    /// The stored summary (evaluation, timings, explained variance, losses).
    pub summary: &'a ModelSummary,
}

/// The page as HTML; its plots are those of [`model_plot_names`].
pub fn model_page(m: &ModelPage<'_>) -> String {
    let s = m.summary;
    let e = &s.evaluation;
    let mut body = String::new();
    let _ = write!(
        body,
        "<h1>Model {} ({})</h1><p>Atlas of {} vertices; {} training and {} held-out meshes. Distances in mm, {} (tables also give point-to-surface distances).</p>",
        escape(m.model_id),
        escape(m.model_type),
        s.atlas.vertex_count,
        s.training_count,
        s.holdout_count,
        escape(&e.distance)
    );
    body.push_str(&metric_table(m));
    body.push_str("<h2>Distributions</h2><div class=\"plots\">");
    for name in model_plot_names(m) {
        if let Ok(svg) = model_plot(m, &name) {
            body.push_str(&figure(&name, &svg));
        }
    }
    body.push_str("</div>");
    if s.losses.is_empty() {
        let _ = write!(body, "<p class=\"note\">No loss curves: {CLOSED_FORM}.</p>");
    }
    body.push_str(&timing_table(s));
    page(&format!("Model {}", m.model_id), &body)
}

fn summary_cells(s: Option<&DistanceSummary>) -> String {
    match s {
        Some(s) => [s.hd, s.ed, s.ed_star, s.cd]
            .iter()
            .map(|m| format!("<td>{}</td>", mean_sd(m.mean, m.std)))
            .collect(),
        None => "<td colspan=\"4\">no held-out meshes</td>".to_owned(),
    }
}

fn metric_table(m: &ModelPage<'_>) -> String {
    let e = &m.summary.evaluation;
    let surface = e.point_to_surface.as_ref();
    let mut t = String::from(
        "<h2>Quality (mm, mean ± sd)</h2><table><tr><th>metric</th><th>distance</th><th>HD</th><th>ED</th><th>ED*</th><th>CD</th></tr>",
    );
    let rows = [
        (
            "generalisation",
            e.generalisation.as_ref(),
            surface.and_then(|s| s.generalisation.as_ref()),
        ),
        (
            "specificity",
            Some(&e.specificity),
            surface.map(|s| &s.specificity),
        ),
        (
            "matching",
            e.matching.as_ref(),
            surface.and_then(|s| s.matching.as_ref()),
        ),
    ];
    for (name, vertex, on_surface) in rows {
        let _ = write!(
            t,
            "<tr><td>{name}</td><td>{}</td>{}</tr>",
            escape(&e.distance),
            summary_cells(vertex)
        );
        if surface.is_some() {
            let _ = write!(
                t,
                "<tr><td>{name}</td><td>point-to-surface</td>{}</tr>",
                summary_cells(on_surface)
            );
        }
    }
    t.push_str("</table>");
    t
}

fn timing_table(s: &ModelSummary) -> String {
    let mut t = String::from("<h2>Fit time</h2><table><tr><th>stage</th><th>seconds</th></tr>");
    for stage in &s.timings {
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{:.1}</td></tr>",
            escape(&stage.stage),
            stage.seconds
        );
    }
    t.push_str("</table>");
    t
}
