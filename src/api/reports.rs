//! Report pages: `GET /v1/cohorts/{id}/report.html` and `GET /v1/models/{id}/report.html`.

use std::collections::BTreeMap;

use axum::extract::State;
use axum::response::Html;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::Path;
use crate::models::ModelSummary;
use crate::models::cohort::CohortReport;
use crate::models::reference::ReferencePopulation;
use crate::report::{CohortPage, ModelPage, cohort_page, model_page};

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(cohort_report))
        .routes(routes!(model_report))
}

fn stored<T: serde::de::DeserializeOwned>(
    what: &str,
    value: serde_json::Value,
) -> Result<T, ApiError> {
    serde_json::from_value(value).map_err(|e| ApiError::internal(format!("stored {what}: {e}")))
}

/// Each biomarker's values over the members, from their stored summaries.
fn member_values(members: &[serde_json::Value]) -> BTreeMap<String, Vec<f64>> {
    let mut values: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for m in members {
        if let Some(biomarkers) = m.get("biomarkers").and_then(|b| b.as_object()) {
            for (name, v) in biomarkers {
                if let Some(v) = v.as_f64() {
                    values.entry(name.clone()).or_default().push(v);
                }
            }
        }
    }
    values
}

/// The cohort's report page: a violin plot per biomarker (training population against the
/// cohort, with the range, mode ± 3B and mean ± 2σ intervals), the acceptance table and the
/// privacy guard. Self-contained HTML with inline SVG.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/report.html", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id")),
    responses(
        (status = 200, description = "The report page", content_type = "text/html", body = String),
        (status = 404, description = "No such cohort", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn cohort_report(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Html<String>, ApiError> {
    let cohort = state.store.cohort(&id).await?;
    let reference: ReferencePopulation = stored(
        "reference",
        state.store.model_reference(&cohort.model_id).await?,
    )?;
    let report: CohortReport = stored("report", cohort.report)?;
    let values = member_values(&cohort.members);
    Ok(Html(cohort_page(&CohortPage {
        cohort_id: &cohort.id,
        model_id: &cohort.model_id,
        report: &report,
        member_values: &values,
        reference: &reference,
    })))
}

/// The model's report page: distributions of generalisation, specificity and matching
/// distances, the metric table (vertex-to-vertex and point-to-surface), cumulative explained
/// variance (PCA models), loss curves (trained models) and fit times.
#[utoipa::path(
    get, path = "/v1/models/{id}/report.html", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 200, description = "The report page", content_type = "text/html", body = String),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn model_report(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Html<String>, ApiError> {
    let model = state.store.model(&id).await?;
    let summary: ModelSummary = stored("summary", model.summary)?;
    Ok(Html(model_page(&ModelPage {
        model_id: &model.id,
        model_type: &model.model_type,
        summary: &summary,
    })))
}
