//! CSV exports: `GET /v1/cohorts/{id}/members.csv`, `GET /v1/models/{id}/modes.csv` and
//! `GET /v1/models/{id}/training.csv`.

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::Response;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Path, Query};
use super::meshes::file_response;
use super::models::{FormatQuery, load_model};
use super::reports::stored;
use crate::models::{ModelSummary, ReferencePopulation};
use crate::report::exports::{MeshRow, members_csv, modes_csv, training_csv};

/// Media type of the tables.
const CSV: &str = "text/csv; charset=utf-8";

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(members_table))
        .routes(routes!(modes_table))
        .routes(routes!(training_table))
}

fn csv_response(stem: &str, text: String) -> Response {
    file_response(text.into_bytes(), CSV, "attachment", &format!("{stem}.csv"))
}

/// The cohort's members as CSV, one row per member in member order.
///
/// Columns: `index`, `draw`, `cluster`, every biomarker under its JSON name (`volume_ml`,
/// `area_cm2`, …), `accepted_range`, `accepted_mode`, `accepted_mean`, `near_copy`,
/// `nearest_training_mm`, `nearest_training_mesh_id` and `file`: the member's file name in
/// the cohort archive of the same `format` (the archive holds this table as
/// `members.csv`).
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/members.csv", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id"), FormatQuery),
    responses(
        (status = 200, description = "The members table", content_type = "text/csv", body = String),
        (status = 404, description = "No such cohort (`cohort.not_found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn members_table(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let cohort = state.store.cohort(&id).await?;
    Ok(csv_response(
        &format!("cohort_{id}_members"),
        members_csv(&cohort.members, format.extension()),
    ))
}

/// The PCA modes of a model: `mode`, `eigenvalue_mm2`, `sd_mm`, `explained_variance`,
/// `cumulative_explained_variance`, one row per kept mode. Models without PCA modes answer
/// 404 `export.not_available`.
#[utoipa::path(
    get, path = "/v1/models/{id}/modes.csv", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 200, description = "The modes table", content_type = "text/csv", body = String),
        (status = 404, description = "No such model (`model.not_found`), or a model without PCA modes (`export.not_available`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Stored in a format this release does not read (`model.unsupported_version`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn modes_table(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let record = state.store.model(&id).await?;
    let summary: ModelSummary = stored("summary", record.summary)?;
    let (stored_model, _) = load_model(&state, &id).await?;
    let Some(variances) = stored_model.model.principal_variances_mm2() else {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "export.not_available",
            format!(
                "model {id} is a {} model, which has no PCA modes; modes.csv exists for PCA models (training.csv exists for every model)",
                record.model_type
            ),
        ));
    };
    let cumulative = summary.explained_variance.unwrap_or_default();
    Ok(csv_response(
        &format!("model_{id}_modes"),
        modes_csv(&variances, &cumulative),
    ))
}

/// Every training and held-out mesh of a model.
///
/// Columns: `mesh_id`, `role` (`training` or `holdout`), every biomarker, the reconstruction
/// (`generalisation_*`) and matching (`matching_*`) distances of held-out meshes (HD, ED,
/// ED*, CD in mm, vertex to vertex) and, for models with several atlases, `weight_{m}` per
/// cluster and the winning `cluster`.
#[utoipa::path(
    get, path = "/v1/models/{id}/training.csv", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 200, description = "The meshes table", content_type = "text/csv", body = String),
        (status = 404, description = "No such model (`model.not_found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn training_table(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let record = state.store.model(&id).await?;
    let summary: ModelSummary = stored("summary", record.summary)?;
    let (_, reference) = state.store.model_payload(&id).await?;
    let reference: ReferencePopulation = stored("reference", reference)?;
    let provenance = record.provenance;
    let mut holdout_biomarkers = Vec::with_capacity(provenance.holdout_mesh_ids.len());
    for mesh_id in &provenance.holdout_mesh_ids {
        let mesh = state.store.mesh_geometry(mesh_id).await?;
        let b = reference
            .measure(&mesh)
            .map_err(|e| ApiError::internal(e.to_string()))?;
        holdout_biomarkers.push(b.values());
    }
    let clusters = summary.clusters.as_ref();
    let per_item = &summary.evaluation.per_item;
    let mut rows: Vec<MeshRow<'_>> = provenance
        .training_mesh_ids
        .iter()
        .enumerate()
        .map(|(k, mesh_id)| MeshRow {
            mesh_id,
            role: "training",
            biomarkers: std::array::from_fn(|b| {
                reference
                    .values
                    .get(b)
                    .and_then(|v| v.get(k))
                    .copied()
                    .unwrap_or(f64::NAN)
            }),
            generalisation: None,
            matching: None,
            weights: clusters.and_then(|c| c.training.get(k)).map(Vec::as_slice),
        })
        .collect();
    rows.extend(
        provenance
            .holdout_mesh_ids
            .iter()
            .enumerate()
            .map(|(k, mesh_id)| MeshRow {
                mesh_id,
                role: "holdout",
                biomarkers: holdout_biomarkers[k],
                generalisation: per_item.generalisation.get(k).copied(),
                matching: per_item.matching.get(k).copied(),
                weights: clusters.and_then(|c| c.holdout.get(k)).map(Vec::as_slice),
            }),
    );
    let atlases = clusters.map_or(1, |c| c.priors.len());
    Ok(csv_response(
        &format!("model_{id}_training"),
        training_csv(&rows, atlases),
    ))
}
