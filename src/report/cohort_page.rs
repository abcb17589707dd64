//! `report.html` of a cohort: biomarker violins (training population against the cohort)
//! with the three acceptance intervals, the acceptance table and the privacy guard.

use std::collections::BTreeMap;
use std::fmt::Write;

use super::cohort_plots::biomarker_violin;
use super::plot::figure;
use super::spread_table::{SpreadRow, spread_table};
use super::{Picture, escape, mean_sd, page, pictures_section};
use crate::eval::acceptance::Rates;
use crate::mesh::Laterality;
use crate::models::clusters::ClusterReport;
use crate::models::cohort::CohortReport;
use crate::models::conditional::Target;
use crate::models::reference::ReferencePopulation;

/// What the cohort page shows.
pub struct CohortPage<'a> {
    /// Cohort id.
    pub cohort_id: &'a str,
    /// Model id.
    pub model_id: &'a str,
    /// The stored acceptance report.
    pub report: &'a CohortReport,
    /// Each biomarker's value per member, by biomarker name.
    pub member_values: &'a BTreeMap<String, Vec<f64>>,
    /// The model's training population.
    pub reference: &'a ReferencePopulation,
    /// Rendered members.
    pub pictures: &'a [Picture],
    /// The side of a paired organ the request asked for, and whether the members are served
    /// as mirror images of the model's shapes to be of it.
    pub laterality: Option<(Laterality, bool)>,
}

/// The page as HTML; one plot per biomarker of the report (see [`super::cohort_plot`]).
pub fn cohort_page(c: &CohortPage<'_>) -> String {
    let mut body = String::new();
    let size = c.member_values.values().map(Vec::len).max().unwrap_or(0);
    let _ = write!(
        body,
        "<h1>Virtual cohort {}</h1><p>{size} members drawn from model <code>{}</code> in {} draws.</p>",
        escape(c.cohort_id),
        escape(c.model_id),
        c.report.draws
    );
    if let Some((side, mirrored)) = c.laterality {
        let how = match mirrored {
            true => format!(
                ", served as mirror images of the model's {} shapes",
                side.opposite()
            ),
            false => ", the side of the model's shapes".to_owned(),
        };
        let _ = write!(body, "<p>Every member is a {side} organ{how}.</p>");
    }
    if let Some(note) = &c.report.population_note {
        let _ = write!(
            body,
            "<p class=\"note\">Small population: {}.</p>",
            escape(note)
        );
    }
    body.push_str(&targets_table(c.report));
    body.push_str(&acceptance_table(c.report));
    let rows: Vec<SpreadRow<'_>> = c
        .report
        .biomarkers
        .iter()
        .filter_map(|(name, b)| {
            b.spread.as_ref().map(|spread| SpreadRow {
                name,
                unit: &b.unit,
                spread,
            })
        })
        .collect();
    body.push_str(&spread_table(
        "Spread against the training population",
        "Ratios near 1 and a small KS statistic: the cohort varies like the population; an sd ratio below 1 means a narrower cohort (marked outside 0.85–1.15).",
        &rows,
    ));
    let p = &c.report.privacy;
    let _ = write!(
        body,
        "<h2>Privacy guard</h2><p>{} near copies (nearer than {:.2} mm, the {}th percentile of {}, {}); {} replaced by new draws.</p>",
        p.near_copies,
        p.threshold_mm,
        (p.percentile * 100.0).round(),
        if p.threshold_basis == "leave_one_out_projection" {
            "how far each training shape, projected on the hull of the others, lies from the nearest other (leave-one-out, as the population is small)"
        } else {
            "the training shapes' own nearest-neighbour distances"
        },
        escape(&p.distance),
        p.near_copies_replaced
    );
    if let Some(f) = &c.report.folding {
        let _ = write!(
            body,
            "<h2>Folded surfaces</h2><p>{}: edges whose two triangles face opposite ways, \
             which a volume mesher for a simulation refuses.</p>",
            escape(&f.describe())
        );
    }
    body.push_str(
        "<h2>Biomarkers: training population against the cohort</h2><div class=\"plots\">",
    );
    for (name, b) in &c.report.biomarkers {
        body.push_str(&figure(name, &biomarker_violin(c, name, b)));
    }
    body.push_str("</div>");
    body.push_str(&pictures_section(c.pictures));
    body.push_str(&cluster_table(c.report));
    page(&format!("Cohort {}", c.cohort_id), &body)
}

/// Per cluster (atlas): members, share, joint acceptance and each biomarker's mean ± sd.
fn cluster_table(report: &CohortReport) -> String {
    let mut t = String::from("<h2>Clusters</h2>");
    if report.clusters.is_empty() {
        t.push_str("<p class=\"note\">This cohort was stored before clusters were recorded.</p>");
        return t;
    }
    if report.clusters.len() == 1 {
        t.push_str(
            "<p class=\"note\">The model has a single atlas: every member is in cluster 0.</p>",
        );
    }
    // One column per cluster, so the table stays narrow for any number of biomarkers.
    t.push_str("<table><tr><th></th>");
    for c in &report.clusters {
        let _ = write!(t, "<th>cluster {}</th>", c.cluster);
    }
    t.push_str("</tr>");
    let row = |t: &mut String, label: &str, cell: &dyn Fn(&ClusterReport) -> String| {
        let _ = write!(t, "<tr><th>{label}</th>");
        for c in &report.clusters {
            let _ = write!(t, "<td>{}</td>", cell(c));
        }
        t.push_str("</tr>");
    };
    row(&mut t, "members", &|c| c.count.to_string());
    row(&mut t, "share", &|c| format!("{:.3}", c.share));
    let rate = |f: fn(&Rates) -> f64| {
        move |c: &ClusterReport| {
            c.acceptance
                .as_ref()
                .map_or("–".to_owned(), |a| format!("{:.3}", f(a)))
        }
    };
    row(&mut t, "joint A<sup>r</sup>", &rate(|a| a.range));
    row(&mut t, "joint A<sup>M</sup>", &rate(|a| a.mode));
    row(&mut t, "joint A<sup>μ</sup>", &rate(|a| a.mean));
    for (name, b) in &report.biomarkers {
        let unit = if b.unit.is_empty() {
            String::new()
        } else {
            format!(", {}", escape(&b.unit))
        };
        let label = format!("{}{unit}: mean ± sd", escape(name));
        row(&mut t, &label, &|c| {
            c.biomarkers
                .get(name)
                .map_or("–".to_owned(), |s| mean_sd(s.mean, s.sd))
        });
    }
    t.push_str("</table>");
    t
}

fn acceptance_table(report: &CohortReport) -> String {
    let mut t = String::from(
        "<h2>Acceptance</h2><table><tr><th>biomarker</th><th>unit</th><th>training mean ± sd</th><th>cohort mean ± sd</th><th>A<sup>r</sup> (range)</th><th>A<sup>M</sup> (mode ± 3B)</th><th>A<sup>μ</sup> (mean ± 2σ)</th></tr>",
    );
    for (name, b) in &report.biomarkers {
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>",
            escape(name),
            escape(&b.unit),
            mean_sd(b.reference.mean, b.reference.sd),
            mean_sd(b.synthetic.mean, b.synthetic.sd),
            b.acceptance.range,
            b.acceptance.mode,
            b.acceptance.mean
        );
    }
    let a = &report.acceptance;
    let _ = write!(
        t,
        "<tr><th>joint</th><td></td><td></td><td></td><th>{:.3}</th><th>{:.3}</th><th>{:.3}</th></tr></table>",
        a.range, a.mode, a.mean
    );
    t
}

/// The targets of a conditional cohort and how its members meet them.
fn targets_table(report: &CohortReport) -> String {
    let Some(t) = &report.targets else {
        return String::new();
    };
    let mut out = format!(
        "<h2>Targets</h2><p>Drawn from the {}; {:.2} draws per member.</p><table><tr><th>biomarker</th><th>target</th><th>reachable</th><th>members inside</th><th>members mean ± sd</th></tr>",
        escape(&t.method),
        t.draws_per_member
    );
    for r in &t.targets {
        let target = match r.target {
            Target::Interval { min, max } => format!(
                "[{}, {}]",
                min.map_or("−∞".into(), |v| format!("{v}")),
                max.map_or("∞".into(), |v| format!("{v}"))
            ),
            Target::Distribution { mean, sd } => format!("N({mean}, {sd}²)"),
        };
        let _ = write!(
            out,
            "<tr><td>{} ({})</td><td>{}</td><td>{:.2}–{:.2}</td><td>{:.1}%</td><td>{}</td></tr>",
            escape(&r.biomarker),
            escape(&r.unit),
            escape(&target),
            r.reachable[0],
            r.reachable[1],
            100.0 * r.inside,
            mean_sd(r.mean, r.sd)
        );
    }
    out.push_str("</table><p class=\"note\">Inside: within the interval, or within mean ± 2 sd of a distribution target.</p>");
    out
}
