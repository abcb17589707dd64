//! `bench`'s spread and volume-fidelity tables: each cohort against the training meshes and
//! against fresh phantoms of the generator.

use super::bench_report::{BenchReport, header, row};
use super::tables::{MISSING, mean_std, table};
use crate::eval::fidelity::Fidelity;
use crate::eval::{MeanStd, SummaryStats};

/// Per biomarker and model: the cohort's mean and sd ratios to the training meshes' and its
/// KS statistic against them.
pub(super) fn spread_table(report: &BenchReport) -> String {
    let models = &report.models;
    let names: Vec<&String> = models
        .first()
        .map(|m| m.cohort.report.biomarkers.keys().collect())
        .unwrap_or_default();
    let mut rows: Vec<Vec<String>> = names
        .iter()
        .map(|name| {
            row(
                name,
                models.iter().map(|m| {
                    m.cohort
                        .report
                        .biomarkers
                        .get(*name)
                        .and_then(|b| b.spread)
                        .map_or(MISSING.to_owned(), |s| {
                            format!(
                                "{:.3} / {:.3} / {:.3}",
                                s.mean_ratio, s.sd_ratio, s.ks_statistic
                            )
                        })
                }),
            )
        })
        .collect();
    rows.push(row(
        "near copies, % of members",
        models.iter().map(|m| {
            let r = &m.cohort.report;
            format!(
                "{:.1}",
                100.0 * r.privacy.near_copies as f64 / m.cohort.size.max(1) as f64
            )
        }),
    ));
    rows.push(row(
        "held-out meshes through the model flagged as near copies (about 5% when calibrated)",
        models.iter().map(|m| {
            let h = &m.held_out_privacy;
            let share = |k: usize| 100.0 * k as f64 / h.meshes.max(1) as f64;
            let plain = if h.leave_one_out {
                format!(
                    "; plain threshold: {:.1}%",
                    share(h.flagged_by_nearest_training_shape)
                )
            } else {
                String::new()
            };
            format!(
                "{:.1}% ({} of {}{plain})",
                share(h.flagged),
                h.flagged,
                h.meshes
            )
        }),
    ));
    rows.push(row(
        "folded edges per 1,000 edges (members with a fold, %)",
        models.iter().map(|m| {
            m.cohort.report.folding.map_or(MISSING.to_owned(), |f| {
                format!(
                    "{:.1} ({:.1}%)",
                    f.per_mille,
                    100.0 * f.surfaces_folded as f64 / f.surfaces.max(1) as f64
                )
            })
        }),
    ));
    rows.push(row(
        "joint A^μ, %",
        models
            .iter()
            .map(|m| format!("{:.1}", 100.0 * m.cohort.report.acceptance.mean)),
    ));
    rows.push(row(
        "joint A^μ of fresh phantoms (the population's own), %",
        models
            .iter()
            .map(|m| format!("{:.1}", 100.0 * m.fidelity.fresh_acceptance.mean)),
    ));
    rows.push(row(
        "joint A^μ of the training meshes against their own intervals, %",
        models
            .iter()
            .map(|m| format!("{:.1}", 100.0 * m.fidelity.training_acceptance.mean)),
    ));
    rows.push(row(
        "joint A^μ of a Gaussian with the training biomarkers' mean and covariance, %",
        models
            .iter()
            .map(|m| format!("{:.1}", 100.0 * m.fidelity.gaussian_acceptance.mean)),
    ));
    rows.push(row(
        "distance of the biomarkers from the training mean, 95th percentile: cohort (fresh \
         phantoms; training meshes)",
        models.iter().map(|m| {
            let d = &m.fidelity.distance;
            format!("{:.2} ({:.2}; {:.2})", d.cohort, d.fresh, d.training)
        }),
    ));
    table(&header("mean ratio / sd ratio / KS D", report), &rows)
}

fn fidelity_row(label: &str, volumes: &SummaryStats, f: &Fidelity) -> Vec<String> {
    let v = mean_std(MeanStd {
        mean: volumes.mean,
        std: volumes.sd,
    });
    vec![
        label.to_owned(),
        f.n_synthetic.to_string(),
        v,
        format!("{:.2}", f.wasserstein_1),
        format!("{:.3}", f.ks_statistic),
        format!("{:.3}", f.ks_p_value),
    ]
}

pub(super) fn fidelity_table(report: &BenchReport) -> String {
    let r = &report.fidelity_reference;
    let header = ["sample", "n", "volume ml", "W1 ml", "KS D", "KS p"].map(String::from);
    let generator = MeanStd {
        mean: r.volumes.mean,
        std: r.volumes.sd,
    };
    let mut rows = vec![
        vec![
            "generator: fresh phantoms, exact".to_owned(),
            r.phantoms.to_string(),
            mean_std(generator),
            "–".to_owned(),
            "–".to_owned(),
            "–".to_owned(),
        ],
        fidelity_row(
            "training phantoms, exact",
            &r.training_exact_volumes,
            &r.training_exact,
        ),
        fidelity_row(
            "training meshes, measured",
            &r.training_measured_volumes,
            &r.training_measured,
        ),
    ];
    for m in &report.models {
        let label = format!("{} cohort, measured", m.model);
        rows.push(fidelity_row(
            &label,
            &m.fidelity.synthetic,
            &m.fidelity.fidelity,
        ));
    }
    table(&header, &rows)
}
