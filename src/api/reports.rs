//! Report pages: `GET /v1/cohorts/{id}/report.html` and `GET /v1/models/{id}/report.html`,
//! and the stored data they are drawn from (shared with the single plots of `plots`).

use std::collections::BTreeMap;

use axum::extract::State;
use axum::response::Html;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::Path;
use super::renders::{members_picture, model_picture};
use crate::jobs::cohort::{CohortRequest, model_side};
use crate::mesh::Laterality;
use crate::models::ModelSummary;
use crate::models::cohort::CohortReport;
use crate::models::reference::ReferencePopulation;
use crate::report::{CohortPage, ModelPage, Picture, cohort_page, model_page};

/// Panel side of the pictures on the report pages, px.
const PAGE_PANEL_PX: u32 = 200;
/// Members pictured on a cohort page.
const PAGE_MEMBERS: usize = 8;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(cohort_report))
        .routes(routes!(model_report))
}

/// A JSON value read back from the store; a mismatch is a 500 naming `what`.
pub(super) fn stored<T: serde::de::DeserializeOwned>(
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
/// privacy guard. Self-contained HTML with inline SVG; each plot links to itself alone
/// (`plots/{name}`, as SVG or PNG).
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
    let cohort = CohortData::load(&state, &id).await?;
    let size = cohort
        .member_values
        .values()
        .map(Vec::len)
        .max()
        .unwrap_or(0);
    let indices: Vec<usize> = (0..size.min(PAGE_MEMBERS)).collect();
    let png = members_picture(&state, &id, &indices, None, PAGE_PANEL_PX).await?;
    let pictures = [Picture {
        name: "members".into(),
        caption: format!(
            "the first {} members, anterior view (renders/members)",
            indices.len()
        ),
        png,
    }];
    Ok(Html(cohort_page(&CohortPage {
        pictures: &pictures,
        ..cohort.page()
    })))
}

/// The model's report page: distributions of generalisation, specificity and matching
/// distances, the metric table (vertex-to-vertex and point-to-surface), cumulative explained
/// variance (PCA models), loss curves (trained models) and fit times. Each plot links to
/// itself alone (`plots/{name}`, as SVG or PNG).
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
    let model = ModelData::load(&state, &id).await?;
    let mut pictures = Vec::new();
    let mut names = vec!["atlas", "modes"];
    if !model.mesh_ids.1.is_empty() {
        names.push("reconstruction_0");
    }
    for name in names {
        match model_picture(&state, &id, name, None, PAGE_PANEL_PX).await {
            Ok(png) => pictures.push(Picture {
                name: name.to_owned(),
                caption: format!("renders/{name}"),
                png,
            }),
            Err(e) if e.status() == axum::http::StatusCode::NOT_FOUND => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Html(model_page(&ModelPage {
        pictures: &pictures,
        ..model.page()
    })))
}

/// What a cohort's page and its plots are drawn from.
pub(super) struct CohortData {
    id: String,
    model_id: String,
    report: CohortReport,
    member_values: BTreeMap<String, Vec<f64>>,
    reference: ReferencePopulation,
    laterality: Option<(Laterality, bool)>,
}

impl CohortData {
    /// Reads the cohort, its members' biomarkers and its model's training population.
    pub(super) async fn load(state: &AppState, id: &str) -> Result<Self, ApiError> {
        let cohort = state.store.cohort(id).await?;
        let reference = stored(
            "reference",
            state.store.model_reference(&cohort.model_id).await?,
        )?;
        let request: CohortRequest = stored("request", cohort.request.clone())?;
        let laterality = match request.laterality {
            Some(side) => {
                let model = state.store.model(&cohort.model_id).await?;
                Some((side, request.mirrors_members(model_side(&model.summary))))
            }
            None => None,
        };
        Ok(Self {
            laterality,
            report: stored("report", cohort.report)?,
            member_values: member_values(&cohort.members),
            id: cohort.id,
            model_id: cohort.model_id,
            reference,
        })
    }

    /// The page's inputs.
    pub(super) fn page(&self) -> CohortPage<'_> {
        CohortPage {
            cohort_id: &self.id,
            model_id: &self.model_id,
            report: &self.report,
            member_values: &self.member_values,
            reference: &self.reference,
            pictures: &[],
            laterality: self.laterality,
        }
    }
}

/// What a model's page and its plots are drawn from.
pub(super) struct ModelData {
    id: String,
    model_type: String,
    summary: ModelSummary,
    /// Training then held-out mesh ids, in fit order.
    mesh_ids: (Vec<String>, Vec<String>),
}

impl ModelData {
    /// Reads the model's stored summary.
    pub(super) async fn load(state: &AppState, id: &str) -> Result<Self, ApiError> {
        let model = state.store.model(id).await?;
        Ok(Self {
            summary: stored("summary", model.summary)?,
            id: model.id,
            model_type: model.model_type,
            mesh_ids: (
                model.provenance.training_mesh_ids,
                model.provenance.holdout_mesh_ids,
            ),
        })
    }

    /// The page's inputs.
    pub(super) fn page(&self) -> ModelPage<'_> {
        ModelPage {
            model_id: &self.id,
            model_type: &self.model_type,
            summary: &self.summary,
            training_mesh_ids: &self.mesh_ids.0,
            holdout_mesh_ids: &self.mesh_ids.1,
            pictures: &[],
        }
    }
}
