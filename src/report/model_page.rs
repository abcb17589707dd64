//! `report.html` of a model: distributions of generalisation, specificity and matching
//! distances, the metric tables, cumulative explained variance and loss curves.

use std::fmt::Write;

use super::model_plots::{CLOSED_FORM, model_plot, model_plot_names};
use super::plot::figure;
use super::spread_table::{SpreadRow, spread_table};
use super::{Picture, escape, mean_sd, page, pictures_section};
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
    /// Training mesh ids, in fit order.
    pub training_mesh_ids: &'a [String],
    /// Held-out mesh ids, in fit order.
    pub holdout_mesh_ids: &'a [String],
    /// Rendered shapes (atlases, modes, a reconstruction).
    pub pictures: &'a [Picture],
}

/// The page as HTML; its plots are those of [`model_plot_names`].
pub fn model_page(m: &ModelPage<'_>) -> String {
    let s = m.summary;
    let e = &s.evaluation;
    let mut body = String::new();
    let _ = write!(
        body,
        "<h1>Model {} ({})</h1><p>{}; {} training and {} held-out meshes. Distances in mm, {} (tables also give point-to-surface distances).</p>",
        escape(m.model_id),
        escape(m.model_type),
        atlas_sentence(s),
        s.training_count,
        s.holdout_count,
        escape(&e.distance)
    );
    body.push_str(&metric_table(m));
    body.push_str(&fidelity_section(s));
    body.push_str(&beta_section(s));
    body.push_str(&clusters_section(m));
    body.push_str(&pictures_section(m.pictures));
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

/// The spread of the fit's own seeded cohort, with the small-population note.
fn fidelity_section(s: &ModelSummary) -> String {
    let Some(f) = &s.fidelity else {
        return String::new();
    };
    let units: std::collections::BTreeMap<&str, &str> = crate::eval::Biomarkers::NAMES
        .iter()
        .copied()
        .zip(crate::eval::Biomarkers::UNITS.iter().copied())
        .collect();
    let rows: Vec<SpreadRow<'_>> = f
        .biomarkers
        .iter()
        .map(|(name, spread)| SpreadRow {
            name,
            unit: units.get(name.as_str()).copied().unwrap_or(""),
            spread,
        })
        .collect();
    let sentence = format!(
        "A cohort of {} members (seed {}) against the {} training meshes; {} near copies ({:.1}%).",
        f.members,
        f.seed,
        s.training_count,
        f.near_copies,
        100.0 * f.near_copies as f64 / f.members.max(1) as f64
    );
    let mut out = spread_table(
        "Spread of a cohort against the training population",
        &sentence,
        &rows,
    );
    for sentence in [
        f.acceptance_sentence(),
        f.distance_sentence(),
        f.folding_sentence(),
    ]
    .into_iter()
    .flatten()
    {
        let _ = write!(out, "<p>{}.</p>", escape(&sentence));
    }
    for warning in [f.near_copy_sentence(), f.folding_warning()]
        .into_iter()
        .flatten()
    {
        let _ = write!(out, "<p class=\"note\">{}.</p>", escape(&warning));
    }
    if let Some(note) = &f.population_note {
        let _ = write!(
            out,
            "<p class=\"note\">Small population: {}.</p>",
            escape(note)
        );
    }
    out
}

/// How each generator's KL weight was chosen: a sentence and the candidates' figures.
fn beta_section(s: &ModelSummary) -> String {
    if s.beta_choices.is_empty() {
        return String::new();
    }
    let mut out = String::from("<h2>Generator KL weight</h2>");
    for choice in &s.beta_choices {
        let _ = write!(
            out,
            "<p>{}. Each fold's generator drew {} shapes; a draw is a near copy when it lies \
             nearer to one of that generator's training shapes than their near-copy \
             threshold.</p><table><tr><th>β</th><th>near copies among fold draws</th>\
             <th>held-out error, mm</th><th></th></tr>",
            escape(&choice.outcome()),
            choice.draws_per_fold
        );
        for c in &choice.candidates {
            let kept = if c.beta == choice.chosen { "kept" } else { "" };
            let _ = write!(
                out,
                "<tr><td>{}</td><td>{:.1}%</td><td>{:.2}</td><td>{kept}</td></tr>",
                c.beta,
                100.0 * c.near_copy_fraction,
                c.holdout_error_mm
            );
        }
        out.push_str("</table>");
    }
    out
}

/// "Atlas of N vertices", or "M atlases of N₀, N₁ … vertices".
fn atlas_sentence(s: &ModelSummary) -> String {
    if s.atlases.len() <= 1 {
        return format!("Atlas of {} vertices", s.atlas.vertex_count);
    }
    let counts: Vec<String> = s
        .atlases
        .iter()
        .map(|a| a.vertex_count.to_string())
        .collect();
    format!(
        "{} atlases of {} vertices",
        s.atlases.len(),
        counts.join(", ")
    )
}

/// Which training meshes were registered as their mirror images, and the side of the
/// members when known (empty without either).
fn mirrored_note(m: &ModelPage<'_>) -> String {
    let positions = &m.summary.mirrored_training;
    let side = m.summary.laterality.map_or(String::new(), |side| {
        format!(" (the patient's {side}, from the sides given with the meshes)")
    });
    if positions.is_empty() {
        return match m.summary.laterality {
            Some(_) => format!(
                "<p class=\"note\">Every member is of the side of the training meshes{side}.</p>"
            ),
            None => String::new(),
        };
    }
    let ids: Vec<String> = positions
        .iter()
        .filter_map(|k| m.training_mesh_ids.get(*k).map(|id| escape(id)))
        .collect();
    format!(
        "<p class=\"note\">{} of the {} training meshes were registered as their mirror \
         images (<code>mirror</code>), so that all are learned on the side of the alignment \
         reference{side}, which every member takes: {}.</p>",
        positions.len(),
        m.training_mesh_ids.len(),
        ids.join(", ")
    )
}

/// Each atlas (vertices, faces, Euler characteristic, prior) and, for a multi-atlas
/// model, the soft weight of every mesh in every cluster.
fn clusters_section(m: &ModelPage<'_>) -> String {
    let s = m.summary;
    let atlases = if s.atlases.is_empty() {
        std::slice::from_ref(&s.atlas)
    } else {
        s.atlases.as_slice()
    };
    let prior = |i: usize| {
        s.clusters
            .as_ref()
            .and_then(|c| c.priors.get(i).copied())
            .unwrap_or(1.0 / atlases.len() as f64)
    };
    let mut t = String::from(
        "<h2>Atlases and clusters</h2><table><tr><th>atlas</th><th>vertices</th><th>faces</th><th>Euler characteristic</th><th>prior π</th></tr>",
    );
    for (i, a) in atlases.iter().enumerate() {
        let chi = a
            .euler_characteristic
            .map_or_else(|| "–".to_owned(), |c| c.to_string());
        let _ = write!(
            t,
            "<tr><th>{i}</th><td>{}</td><td>{}</td><td>{chi}</td><td>{:.3}</td></tr>",
            a.vertex_count,
            a.face_count,
            prior(i)
        );
    }
    t.push_str("</table>");
    t.push_str(&mirrored_note(m));
    let Some(c) = &s.clusters else {
        t.push_str("<p class=\"note\">One atlas: every mesh is in cluster 0.</p>");
        return t;
    };
    if let Some(note) = c.thin_cluster_note() {
        let _ = write!(
            t,
            "<p class=\"note\">Few meshes per cluster: {}.</p>",
            escape(&note)
        );
    }
    t.push_str("<p>Soft weight w<sub>km</sub> of each mesh in each cluster (eq. 5.13); the largest is in bold.</p><table class=\"weights\"><tr><th>mesh</th><th>set</th>");
    for i in 0..atlases.len() {
        let _ = write!(t, "<th>cluster {i}</th>");
    }
    t.push_str("</tr>");
    let rows = (m
        .training_mesh_ids
        .iter()
        .zip(&c.training)
        .map(|r| (r, "training")))
    .chain(
        m.holdout_mesh_ids
            .iter()
            .zip(&c.holdout)
            .map(|r| (r, "held out")),
    );
    for ((id, weights), set) in rows {
        let best = crate::models::clusters::winning_cluster(weights);
        let _ = write!(t, "<tr><td>{}</td><td>{set}</td>", escape(id));
        for (i, w) in weights.iter().enumerate() {
            if i == best {
                let _ = write!(t, "<td><b>{w:.3}</b></td>");
            } else {
                let _ = write!(t, "<td>{w:.3}</td>");
            }
        }
        t.push_str("</tr>");
    }
    t.push_str("</table>");
    t
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
