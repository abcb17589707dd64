//! The plots of a model page and their names:
//!
//! | name | plot | exists when |
//! | --- | --- | --- |
//! | `generalisation` | HD, ED, ED* of held-out reconstructions | the fit held meshes out |
//! | `specificity` | HD, ED, ED* of samples against the nearest training mesh | always |
//! | `matching` | HD, ED, ED* of held-out meshes against their normalised shapes | the fit held meshes out |
//! | `explained_variance` | cumulative explained variance per mode | PCA models |
//! | `loss_<network>`, e.g. `loss_graph_vae` | mean training loss per epoch | trained networks |
//!
//! The page and the single-plot download draw each plot with the same function.

use super::model_page::ModelPage;
use super::plot::PlotError;
use super::svg::{Group, Series, line_plot, violin_plot};
use crate::geometry::distance::SurfaceDistances;
use crate::models::LossCurve;
use crate::models::evaluation::PerItemDistances;

/// Per-item distances of one distribution.
type Distances = fn(&PerItemDistances) -> &[SurfaceDistances];

/// The distance distributions: name, title, and where their per-item distances are.
const DISTRIBUTIONS: [(&str, &str, Distances); 3] = [
    (
        "generalisation",
        "Generalisation (held-out reconstructions)",
        |p| &p.generalisation,
    ),
    (
        "specificity",
        "Specificity (samples against the nearest training mesh)",
        |p| &p.specificity,
    ),
    (
        "matching",
        "Matching (held-out meshes against their normalised shapes)",
        |p| &p.matching,
    ),
];

/// Name of the cumulative explained variance plot.
pub const EXPLAINED_VARIANCE: &str = "explained_variance";

/// Prefix of a loss curve's name; the network's name follows.
pub const LOSS_PREFIX: &str = "loss_";

/// Why a model has no loss curves.
pub(super) const CLOSED_FORM: &str =
    "this model is fitted in closed form (registration and PCA), not by gradient descent";

/// The names of the model's plots, in page order.
pub fn model_plot_names(m: &ModelPage<'_>) -> Vec<String> {
    let s = m.summary;
    let mut names: Vec<String> = DISTRIBUTIONS
        .iter()
        .filter(|(_, _, per)| !per(&s.evaluation.per_item).is_empty())
        .map(|(name, _, _)| (*name).to_owned())
        .collect();
    if s.explained_variance.is_some() {
        names.push(EXPLAINED_VARIANCE.to_owned());
    }
    names.extend(
        s.losses
            .iter()
            .map(|c| format!("{LOSS_PREFIX}{}", c.network)),
    );
    names
}

/// The plot called `name` as SVG.
///
/// # Errors
/// [`PlotError::Unknown`] for a name that is no plot of a model page (or a loss of a
/// network this model does not have); [`PlotError::Unavailable`] for a plot this model
/// lacks, with the reason.
pub fn model_plot(m: &ModelPage<'_>, name: &str) -> Result<String, PlotError> {
    let s = m.summary;
    let unavailable = |reason: String| PlotError::Unavailable {
        name: name.to_owned(),
        reason,
        available: model_plot_names(m),
    };
    if let Some((_, title, per)) = DISTRIBUTIONS.iter().find(|(n, _, _)| *n == name) {
        let pairs = per(&s.evaluation.per_item);
        if !pairs.is_empty() {
            return Ok(distance_violins(title, pairs));
        }
        let reason = if s.holdout_count == 0 && name != "specificity" {
            format!("the model was fitted without held-out meshes, so it has no {name} distances")
        } else {
            format!("the model's evaluation holds no per-item {name} distances")
        };
        return Err(unavailable(reason));
    }
    if name == EXPLAINED_VARIANCE {
        return match &s.explained_variance {
            Some(explained) => Ok(explained_variance_plot(explained)),
            None => Err(unavailable(format!(
                "only PCA models report explained variance, and this {} model has none",
                m.model_type
            ))),
        };
    }
    if let Some(network) = name.strip_prefix(LOSS_PREFIX) {
        if let Some(curve) = s.losses.iter().find(|c| c.network == network) {
            return Ok(loss_plot(curve));
        }
        if s.losses.is_empty() {
            return Err(unavailable(format!(
                "{CLOSED_FORM}, so it has no loss curves"
            )));
        }
    }
    Err(PlotError::Unknown {
        name: name.to_owned(),
        available: model_plot_names(m),
    })
}

/// HD, ED and ED* of one distribution as three violins (mm).
fn distance_violins(title: &str, pairs: &[SurfaceDistances]) -> String {
    let column = |f: fn(&SurfaceDistances) -> f64| pairs.iter().map(f).collect::<Vec<f64>>();
    let (hd, ed, ed_star) = (column(|d| d.hd), column(|d| d.ed), column(|d| d.ed_star));
    violin_plot(
        title,
        "mm",
        &[
            Group {
                label: "HD",
                values: &hd,
            },
            Group {
                label: "ED",
                values: &ed,
            },
            Group {
                label: "ED*",
                values: &ed_star,
            },
        ],
        &[],
    )
}

/// Cumulative explained variance against the number of modes.
fn explained_variance_plot(explained: &[f64]) -> String {
    let points: Vec<(f64, f64)> = explained
        .iter()
        .enumerate()
        .map(|(i, v)| ((i + 1) as f64, *v))
        .collect();
    line_plot(
        "Cumulative explained variance",
        "modes",
        "fraction of variance",
        &[Series {
            label: "cumulative",
            points: &points,
        }],
    )
}

/// One network's mean training loss per epoch.
fn loss_plot(curve: &LossCurve) -> String {
    let points: Vec<(f64, f64)> = curve
        .per_epoch
        .iter()
        .enumerate()
        .map(|(i, v)| ((i + 1) as f64, *v))
        .collect();
    let series = [Series {
        label: "mean loss per epoch",
        points: &points,
    }];
    let title = format!("Training loss: {}", curve.network);
    line_plot(&title, "epoch", "loss", &series)
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;
    use crate::models::ModelSummary;
    use crate::report::model_page;

    /// A trained model without held-out meshes or PCA: specificity and one loss curve.
    fn summary() -> ModelSummary {
        let m = json!({"mean": 1.0, "std": 0.5});
        let d = |hd: f64| json!({"hd": hd, "ed": 1.0, "ed_star": 1.5, "cd": 2.5});
        serde_json::from_value(json!({
            "atlas": {"vertex_count": 100, "face_count": 196},
            "evaluation": {
                "distance": "vertex-to-vertex",
                "generalisation": null,
                "specificity": {"hd": m, "ed": m, "ed_star": m, "cd": m},
                "matching": null,
                "specificity_samples": 3,
                "per_item": {"generalisation": [], "specificity": [d(3.0), d(4.0), d(5.0)], "matching": []},
            },
            "explained_variance": null,
            "n_modes": null,
            "training_count": 3,
            "holdout_count": 0,
            "timings": [],
            "losses": [{"network": "graph_vae", "per_epoch": [3.0, 2.0, 1.5]}],
        }))
        .unwrap()
    }

    fn page(summary: &ModelSummary) -> ModelPage<'_> {
        ModelPage {
            model_id: "m1",
            model_type: "asmg",
            summary,
            training_mesh_ids: &[],
            holdout_mesh_ids: &[],
            pictures: &[],
        }
    }

    #[test]
    fn the_page_shows_exactly_the_named_plots() {
        let s = summary();
        let m = page(&s);
        let names = model_plot_names(&m);
        assert_eq!(names, ["specificity", "loss_graph_vae"]);
        let html = model_page(&m);
        for name in &names {
            let svg = model_plot(&m, name).unwrap();
            assert!(html.contains(&svg), "{name} is not on the page");
            assert!(html.contains(&format!("href=\"plots/{name}\"")));
        }
        assert_eq!(html.matches("<svg class=\"plot\"").count(), names.len());
    }

    #[test]
    fn a_chosen_kl_weight_is_listed_with_every_candidate() {
        use crate::models::beta_choice::{BetaCandidate, BetaChoice};
        let mut s = summary();
        assert!(!model_page(&page(&s)).contains("Generator KL weight"));
        let candidate = |beta, near_copy_fraction, holdout_error_mm| BetaCandidate {
            beta,
            near_copy_fraction,
            holdout_error_mm,
        };
        s.beta_choices = BetaChoice::pick(
            None,
            4,
            100,
            vec![candidate(1.0, 0.4, 3.25), candidate(10.0, 0.035, 3.36)],
        )
        .into_iter()
        .collect();
        let html = model_page(&page(&s));
        assert!(
            html.contains("KL weight β 10 chosen on 4 held-out folds"),
            "{html}"
        );
        assert!(html.contains("<tr><td>1</td><td>40.0%</td><td>3.25</td><td></td></tr>"));
        assert!(html.contains("<tr><td>10</td><td>3.5%</td><td>3.36</td><td>kept</td></tr>"));
    }

    #[test]
    fn the_mirrored_training_meshes_are_named() {
        fn html(s: &ModelSummary, ids: &[String]) -> String {
            model_page(&ModelPage {
                training_mesh_ids: ids,
                ..page(s)
            })
        }
        let mut s = summary();
        let ids = ["a".to_owned(), "b".to_owned(), "c".to_owned()];
        assert!(!html(&s, &ids).contains("mirror images"));
        s.mirrored_training = vec![0, 2];
        let html = html(&s, &ids);
        assert!(
            html.contains("2 of the 3 training meshes were registered as their mirror images"),
            "{html}"
        );
        assert!(
            html.contains("which every member takes: a, c.</p>"),
            "{html}"
        );
        s.laterality = Some(crate::mesh::Laterality::Left);
        let sided = model_page(&ModelPage {
            training_mesh_ids: &ids,
            ..page(&s)
        });
        assert!(
            sided.contains(
                "reference (the patient's left, from the sides given with the meshes), which"
            ),
            "{sided}"
        );
    }

    #[test]
    fn missing_plots_say_why() {
        let s = summary();
        let m = page(&s);
        let reason = |name: &str| match model_plot(&m, name) {
            Err(PlotError::Unavailable {
                reason, available, ..
            }) => {
                assert_eq!(available, model_plot_names(&m));
                reason
            }
            other => panic!("{name}: {other:?}"),
        };
        assert!(reason("generalisation").contains("without held-out meshes"));
        assert!(reason("matching").contains("without held-out meshes"));
        assert!(reason(EXPLAINED_VARIANCE).contains("only PCA models"));
        for name in ["loss_beta_vae", "volume_ml", ""] {
            let e = model_plot(&m, name).unwrap_err();
            assert_eq!(e.code(), "plot.not_found", "{name}");
            assert!(
                e.to_string().ends_with("specificity, loss_graph_vae"),
                "{e}"
            );
        }
        let mut closed_form = summary();
        closed_form.losses.clear();
        let e = model_plot(&page(&closed_form), "loss_graph_vae").unwrap_err();
        assert_eq!(e.code(), "plot.not_available");
        assert!(e.to_string().contains("closed form"), "{e}");
    }
}
