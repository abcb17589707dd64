//! The plots of a cohort page: one violin per biomarker, named by the biomarker's key
//! (e.g. `volume_ml`). The page and the single-plot download draw them with the same
//! function.

use super::cohort_page::CohortPage;
use super::plot::PlotError;
use super::svg::{Band, Group, violin_plot};
use crate::models::cohort::BiomarkerReport;

/// The names of the cohort's plots, in page order.
pub fn cohort_plot_names(c: &CohortPage<'_>) -> Vec<String> {
    c.report.biomarkers.keys().cloned().collect()
}

/// The plot called `name` as SVG.
///
/// # Errors
/// [`PlotError::Unknown`] when the cohort reports no biomarker of that name.
pub fn cohort_plot(c: &CohortPage<'_>, name: &str) -> Result<String, PlotError> {
    match c.report.biomarkers.get(name) {
        Some(b) => Ok(biomarker_violin(c, name, b)),
        None => Err(PlotError::Unknown {
            name: name.to_owned(),
            available: cohort_plot_names(c),
        }),
    }
}

/// The training population against the cohort for one biomarker, with the range,
/// mode ± 3B and mean ± 2σ intervals.
pub(super) fn biomarker_violin(c: &CohortPage<'_>, name: &str, b: &BiomarkerReport) -> String {
    let training = c
        .reference
        .names
        .iter()
        .position(|n| n == name)
        .and_then(|i| c.reference.values.get(i))
        .map_or(&[][..], Vec::as_slice);
    let cohort = c.member_values.get(name).map_or(&[][..], Vec::as_slice);
    let groups = [
        Group {
            label: "training",
            values: training,
        },
        Group {
            label: "cohort",
            values: cohort,
        },
    ];
    let bands = [
        Band {
            label: "range",
            interval: b.intervals.range,
        },
        Band {
            label: "mode ± 3B",
            interval: b.intervals.mode,
        },
        Band {
            label: "mean ± 2σ",
            interval: b.intervals.mean,
        },
    ];
    violin_plot(name, &b.unit, &groups, &bands)
}
