//! `/v1/datasets`: create, list, get, delete.

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use serde::Deserialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, PageQuery, Paginated, Path, Query};
use crate::store::datasets::Dataset;

/// Longest dataset name, in characters.
const MAX_NAME_CHARS: usize = 200;
/// Longest organ label, in characters.
const MAX_ORGAN_CHARS: usize = 64;

/// Body of `POST /v1/datasets`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CreateDataset {
    /// Name of the dataset (1–200 characters).
    #[schema(
        example = "lv-phantoms",
        min_length = 1,
        max_length = 200,
        pattern = r"^[^\x00-\x1f\x7f-\x9f]*[^\s\x00-\x1f\x7f-\x9f][^\x00-\x1f\x7f-\x9f]*$"
    )]
    pub name: String,
    /// Organ the meshes show (1–64 characters), e.g. "lv", "liver", "kidney".
    #[schema(
        example = "lv",
        min_length = 1,
        max_length = 64,
        pattern = r"^[^\x00-\x1f\x7f-\x9f]*[^\s\x00-\x1f\x7f-\x9f][^\x00-\x1f\x7f-\x9f]*$"
    )]
    pub organ: String,
    /// Simplify every uploaded mesh to about this many vertices unless the upload says
    /// otherwise (at least 8; none: keep meshes as uploaded).
    #[schema(example = 2000, minimum = 8, maximum = 1_000_000)]
    pub target_vertices: Option<i64>,
}

/// Checks a free-text field: not blank, not too long, no control characters.
pub(crate) fn check_label(field: &str, value: &str, max_chars: usize) -> Result<(), ApiError> {
    if value.trim().is_empty() {
        return Err(ApiError::invalid_field(
            field,
            format!("{field} must not be empty"),
        ));
    }
    if value.chars().count() > max_chars {
        return Err(ApiError::invalid_field(
            field,
            format!("{field} must be at most {max_chars} characters long"),
        ));
    }
    if value.chars().any(char::is_control) {
        return Err(ApiError::invalid_field(
            field,
            format!("{field} must not contain control characters"),
        ));
    }
    Ok(())
}

/// Checks a simplification target: at least the smallest surface, at most the vertex limit.
pub(crate) fn check_target_vertices(target: i64, max_vertices: usize) -> Result<(), ApiError> {
    let min = crate::mesh::simplify::MIN_TARGET_VERTICES as i64;
    if target < min || target > max_vertices as i64 {
        return Err(ApiError::invalid_field(
            "target_vertices",
            format!("target_vertices must be between {min} and {max_vertices}, got {target}"),
        ));
    }
    Ok(())
}

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(create_dataset, list_datasets))
        .routes(routes!(get_dataset, delete_dataset))
}

/// Create an empty dataset.
#[utoipa::path(
    post, path = "/v1/datasets", tag = "datasets",
    request_body = CreateDataset,
    responses(
        (status = 201, description = "Dataset created", body = Dataset,
         headers(("Location" = String, description = "URL of the new dataset"))),
        (status = 422, description = "Invalid field", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn create_dataset(
    State(state): State<AppState>,
    Json(body): Json<CreateDataset>,
) -> Result<(StatusCode, HeaderMap, Json<Dataset>), ApiError> {
    check_label("name", &body.name, MAX_NAME_CHARS)?;
    check_label("organ", &body.organ, MAX_ORGAN_CHARS)?;
    if let Some(target) = body.target_vertices {
        check_target_vertices(target, state.max_vertices)?;
    }
    let dataset = state
        .store
        .create_dataset(body.name.trim(), body.organ.trim(), body.target_vertices)
        .await?;
    let mut headers = HeaderMap::new();
    if let Ok(location) = HeaderValue::from_str(&format!("/v1/datasets/{}", dataset.id)) {
        headers.insert(header::LOCATION, location);
    }
    Ok((StatusCode::CREATED, headers, Json(dataset)))
}

/// List datasets, oldest first.
#[utoipa::path(
    get, path = "/v1/datasets", tag = "datasets",
    params(PageQuery),
    responses((status = 200, description = "A page of datasets", body = Paginated<Dataset>))
)]
async fn list_datasets(
    State(state): State<AppState>,
    Query(query): Query<PageQuery>,
) -> Result<Json<Paginated<Dataset>>, ApiError> {
    let page = query.page()?;
    let (items, total) = state.store.datasets(page).await?;
    Ok(Json(Paginated::new(items, total, page)))
}

/// Get one dataset with its mesh count.
#[utoipa::path(
    get, path = "/v1/datasets/{id}", tag = "datasets",
    params(("id" = String, Path, description = "Dataset id")),
    responses(
        (status = 200, description = "The dataset", body = Dataset),
        (status = 404, description = "No such dataset", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_dataset(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Dataset>, ApiError> {
    Ok(Json(state.store.dataset(&id).await?))
}

/// Delete a dataset and all its meshes.
#[utoipa::path(
    delete, path = "/v1/datasets/{id}", tag = "datasets",
    params(("id" = String, Path, description = "Dataset id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 404, description = "No such dataset", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn delete_dataset(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    state.store.delete_dataset(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}
