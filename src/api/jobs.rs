//! `/v1/jobs`: submit fit jobs, follow their progress, cancel them.

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, PageQuery, Paginated, Path, Query};
use crate::jobs::split::holdout_split;
use crate::models::{ModelError, ModelParams, ModelType};
use crate::store::jobs::{Job, JobKind, JobStatus, NewJob};

/// Default share of meshes held out for evaluation.
pub const DEFAULT_HOLDOUT_FRACTION: f64 = 0.2;
/// Largest share of meshes that may be held out.
pub const MAX_HOLDOUT_FRACTION: f64 = 0.9;
/// Times a worker may start a job (crashes included) before it is failed.
pub const MAX_ATTEMPTS: i64 = 3;
/// Longest accepted Idempotency-Key.
const MAX_IDEMPOTENCY_KEY: usize = 200;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(submit_job, list_jobs))
        .routes(routes!(get_job))
        .routes(routes!(cancel_job))
        .routes(routes!(super::events::job_events))
}

/// Body of `POST /v1/jobs`.
#[derive(Debug, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SubmitJob {
    /// Dataset to fit.
    pub dataset_id: String,
    /// Model type: `rsmp`, `asmg`, `atlas-r-asmg` or `matlas-r-asmg`.
    #[schema(example = "rsmp")]
    pub model_type: String,
    /// Model parameters; omitted ones take their defaults (see the model's documentation).
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: serde_json::Value,
    /// Random seed (default 0): the same seed and data give the same model.
    #[serde(default)]
    pub seed: u64,
    /// Share of the meshes held out for evaluation, 0–0.9 (default 0.2).
    pub holdout_fraction: Option<f64>,
}

/// Query of `GET /v1/jobs`.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct JobsQuery {
    /// Only jobs with this status.
    pub status: Option<JobStatus>,
    /// Only jobs of this kind: `fit`, or `cohort` (large cohorts drawn by the workers).
    pub kind: Option<JobKind>,
    /// Items per page (1–500, default 50).
    #[param(minimum = 1, maximum = 500)]
    pub limit: Option<i64>,
    /// Items to skip (default 0).
    #[param(minimum = 0)]
    pub offset: Option<i64>,
}

fn model_error(err: ModelError) -> ApiError {
    match err {
        ModelError::InvalidParams { field, message } => {
            let field = if field.is_empty() {
                "params".to_owned()
            } else {
                format!("params.{field}")
            };
            ApiError::invalid_field(&field, format!("{field}: {message}"))
        }
        other => ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            other.code(),
            other.to_string(),
        ),
    }
}

fn request_hash(body: &SubmitJob, params: &serde_json::Value, holdout: f64) -> String {
    let canonical = serde_json::json!({
        "dataset_id": body.dataset_id, "model_type": body.model_type,
        "params": params, "seed": body.seed, "holdout_fraction": holdout,
    });
    hex::encode(Sha256::digest(canonical.to_string().as_bytes()))
}

fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    let Some(value) = headers.get("idempotency-key") else {
        return Ok(None);
    };
    let key = value
        .to_str()
        .ok()
        .filter(|k| k.bytes().all(|b| b.is_ascii_graphic()))
        .ok_or_else(|| {
            ApiError::new(
                StatusCode::BAD_REQUEST,
                "request.invalid_header",
                "Idempotency-Key must be visible ASCII without spaces",
            )
        })?;
    if key.is_empty() || key.len() > MAX_IDEMPOTENCY_KEY {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "request.invalid_header",
            format!("Idempotency-Key must be 1 to {MAX_IDEMPOTENCY_KEY} characters long"),
        ));
    }
    Ok(Some(key.to_owned()))
}

/// Checks a submission against the dataset: enough meshes, template present.
async fn check_dataset(
    state: &AppState,
    body: &SubmitJob,
    params: &ModelParams,
    holdout: f64,
) -> Result<(), ApiError> {
    let meshes = state
        .store
        .dataset_mesh_keys(&body.dataset_id)
        .await
        .map_err(|e| match e {
            crate::store::StoreError::NotFound { .. } => ApiError::invalid_field(
                "dataset_id",
                format!(
                    "dataset_id: no dataset has the id {}; create one with POST /v1/datasets",
                    body.dataset_id
                ),
            ),
            other => other.into(),
        })?;
    let ids: Vec<String> = meshes.into_iter().map(|m| m.id).collect();
    let templates = params.template_mesh_ids();
    if let Some(t) = templates.iter().find(|t| !ids.iter().any(|id| id == *t)) {
        let field = format!("params.{}", params.template_field());
        return Err(ApiError::invalid_field(
            &field,
            format!("{field}: mesh {t} is not in dataset {}", body.dataset_id),
        ));
    }
    let (training, _) = holdout_split(&ids, holdout, body.seed, &templates);
    let required = params.model_type().min_training_meshes();
    if training.len() < required {
        return Err(model_error(ModelError::TooFewMeshes {
            required,
            found: training.len(),
        }));
    }
    Ok(())
}

/// Queue a fit job.
#[utoipa::path(
    post, path = "/v1/jobs", tag = "jobs",
    request_body = SubmitJob,
    params(("Idempotency-Key" = Option<String>, Header, description = "Retrying with the same key returns the same job (1–200 visible ASCII characters)", min_length = 1, max_length = 200, pattern = r"^[\x21-\x7e]+$")),
    responses(
        (status = 202, description = "Queued (or the job already created with this Idempotency-Key)", body = Job,
         headers(("Location" = String, description = "URL of the job"))),
        (status = 409, description = "Idempotency-Key reused for another request", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid field (named in `field`) or too few meshes", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn submit_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Json(body): Json<SubmitJob>,
) -> Result<(StatusCode, HeaderMap, Json<Job>), ApiError> {
    let key = idempotency_key(&headers)?;
    let model_type = ModelType::parse_name(&body.model_type)
        .map_err(|e| ApiError::invalid_field("model_type", e.to_string()))?;
    let params = model_type.parse_params(&body.params).map_err(model_error)?;
    let holdout = body.holdout_fraction.unwrap_or(DEFAULT_HOLDOUT_FRACTION);
    if !(0.0..=MAX_HOLDOUT_FRACTION).contains(&holdout) {
        return Err(ApiError::invalid_field(
            "holdout_fraction",
            format!("holdout_fraction must be between 0 and {MAX_HOLDOUT_FRACTION}, got {holdout}"),
        ));
    }
    if body.seed > i64::MAX as u64 {
        return Err(ApiError::invalid_field(
            "seed",
            format!("seed must be at most {}", i64::MAX),
        ));
    }
    check_dataset(&state, &body, &params, holdout).await?;
    let params_json = params.to_json();
    let new = NewJob {
        dataset_id: body.dataset_id.clone(),
        model_type: model_type.as_str().to_owned(),
        request_hash: request_hash(&body, &params_json, holdout),
        params: params_json,
        seed: body.seed,
        holdout_fraction: holdout,
        max_attempts: MAX_ATTEMPTS,
        idempotency_key: key,
    };
    let (job, created) = state.store.submit_job(new).await?;
    if created {
        state.wake.notify_one();
    }
    let mut headers = HeaderMap::new();
    if let Ok(location) = HeaderValue::from_str(&format!("/v1/jobs/{}", job.id)) {
        headers.insert(header::LOCATION, location);
    }
    Ok((StatusCode::ACCEPTED, headers, Json(job)))
}

/// List jobs, newest first.
#[utoipa::path(
    get, path = "/v1/jobs", tag = "jobs", params(JobsQuery),
    responses((status = 200, description = "A page of jobs", body = Paginated<Job>))
)]
async fn list_jobs(
    State(state): State<AppState>,
    Query(q): Query<JobsQuery>,
) -> Result<Json<Paginated<Job>>, ApiError> {
    let page = PageQuery {
        limit: q.limit,
        offset: q.offset,
    }
    .page()?;
    let (items, total) = state.store.jobs(q.status, q.kind, page).await?;
    Ok(Json(Paginated::new(items, total, page)))
}

/// Get a job with its progress.
#[utoipa::path(
    get, path = "/v1/jobs/{id}", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = Job),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Job>, ApiError> {
    Ok(Json(state.store.job(&id).await?))
}

/// Cancel a job: a queued job at once, a running one at its next checkpoint.
#[utoipa::path(
    post, path = "/v1/jobs/{id}/cancel", tag = "jobs",
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 202, description = "Cancellation requested (status `cancelled` when it was queued)", body = Job),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The job already ended", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn cancel_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<(StatusCode, Json<Job>), ApiError> {
    Ok((
        StatusCode::ACCEPTED,
        Json(state.store.cancel_job(&id).await?),
    ))
}
