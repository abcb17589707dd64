//! Virtual cohorts: sample from a model with an acceptance report, at once or on the worker
//! pool; page through members; cancel a cohort being drawn.

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use serde::Serialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, PageQuery, Paginated, Path, Query};
use crate::eval::Biomarkers;
use crate::geometry::pca::Sampling;
use crate::jobs::cohort::{
    CohortRequest, MAX_COHORT_SIZE, MemberSummary, draw_cohort, load_source, model_side,
};
use crate::models::ModelError;
use crate::models::conditional::Target;
use crate::models::progress::Silent;
use crate::store::StoreError;
use crate::store::cohorts::{CohortRecord, NewCohortJob};
use crate::store::jobs::{JobProgress, JobStatus};

/// Times a worker may start a cohort job before it is failed.
const MAX_ATTEMPTS: i64 = 3;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(create_cohort))
        .routes(routes!(get_cohort))
        .routes(routes!(list_members))
        .routes(routes!(cancel_cohort))
        .merge(super::cohort_files::router())
}

/// A cohort with its status, acceptance report and (while it is small) its members.
#[derive(Debug, Serialize, ToSchema)]
pub struct CohortView {
    /// Identifier.
    pub id: String,
    /// Model it was drawn from.
    pub model_id: String,
    /// `queued` or `running` while the workers draw it, then `succeeded`, `failed` or
    /// `cancelled`; a cohort answered with 201 is `succeeded` at once.
    pub status: JobStatus,
    /// Progress of the drawing (members drawn of `size`), for a cohort drawn by the workers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub progress: Option<JobProgress>,
    /// Why drawing failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Members asked for.
    pub size: usize,
    /// Members drawn and stored (`size` once succeeded).
    pub member_count: usize,
    /// Seed used.
    pub seed: u64,
    /// The request with defaults filled in.
    #[schema(value_type = CohortRequest)]
    pub request: serde_json::Value,
    /// The acceptance report, once drawn: `biomarkers.<name>` (reference statistics,
    /// intervals, synthetic statistics, acceptance rates, spread against the training
    /// set), `acceptance` (joint rates), `privacy`, `clusters`, `targets`.
    #[schema(value_type = Option<crate::models::cohort::CohortReport>)]
    pub report: Option<serde_json::Value>,
    /// The members in order, inline while the cohort has at most the server's inline limit
    /// (default 1,000); page through `/v1/cohorts/{id}/members` otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<MemberSummary>>)]
    pub members: Option<Vec<serde_json::Value>>,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
    /// When drawing ended (RFC 3339, UTC).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finished_at: Option<String>,
}

impl CohortView {
    /// The view of a record; `members` are listed when the record carries them.
    pub fn new(r: CohortRecord, with_members: bool) -> Self {
        Self {
            seed: r
                .request
                .get("seed")
                .and_then(serde_json::Value::as_u64)
                .unwrap_or(0),
            status: r.status,
            progress: r.progress.filter(|_| r.job_id.is_some()),
            error: r.error,
            size: r.size,
            member_count: r.member_count,
            id: r.id,
            model_id: r.model_id,
            request: r.request,
            report: Some(r.report).filter(|v| !v.is_null()),
            members: with_members.then_some(r.members),
            created_at: r.created_at,
            finished_at: r.finished_at,
        }
    }
}

fn check_target(name: &str, target: &Target) -> Result<(), ApiError> {
    let field = format!("targets.{name}");
    if !Biomarkers::NAMES.contains(&name) {
        return Err(ApiError::invalid_field(
            &field,
            format!(
                "'{name}' is not a biomarker; use one of {}",
                Biomarkers::NAMES.join(", ")
            ),
        ));
    }
    let finite = |v: Option<f64>| v.is_none_or(f64::is_finite);
    let problem = match *target {
        Target::Interval {
            min: None,
            max: None,
        } => {
            Some("give min, max or both (an interval), or mean and sd (a distribution)".to_owned())
        }
        Target::Interval { min, max } if !finite(min) || !finite(max) => {
            Some("min and max must be numbers".to_owned())
        }
        Target::Interval {
            min: Some(lo),
            max: Some(hi),
        } if lo > hi => Some(format!("min {lo} is above max {hi}")),
        Target::Distribution { mean, sd } if !(mean.is_finite() && sd > 0.0 && sd.is_finite()) => {
            Some(format!(
                "a distribution needs a finite mean and an sd above 0, got sd {sd}"
            ))
        }
        _ => None,
    };
    problem.map_or(Ok(()), |p| {
        Err(ApiError::invalid_field(&field, format!("{field}: {p}")))
    })
}

fn check_request(body: &CohortRequest) -> Result<(), ApiError> {
    for (name, target) in &body.targets {
        check_target(name, target)?;
    }
    if !body.targets.is_empty() && body.sampling != Sampling::Gaussian {
        return Err(ApiError::invalid_field(
            "sampling",
            "targets condition the model's Gaussian: leave sampling at gaussian",
        ));
    }
    if !(1..=MAX_COHORT_SIZE).contains(&body.size) {
        return Err(ApiError::invalid_field(
            "size",
            format!(
                "size must be between 1 and {MAX_COHORT_SIZE}, got {}",
                body.size
            ),
        ));
    }
    Ok(())
}

/// A cohort may ask for a side only of a model that knows the side of its shapes.
async fn check_side_known(state: &AppState, model_id: &str) -> Result<(), ApiError> {
    let record = state.store.model(model_id).await?;
    match model_side(&record.summary) {
        Some(_) => Ok(()),
        None => Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "cohort.laterality_unknown",
            format!(
                "model {model_id} does not know which side its shapes are, so it cannot serve \
                 members of a given side: leave laterality out, or fit a model with \
                 \"mirror\": true on meshes whose laterality is given"
            ),
        )
        .with("field", "laterality")),
    }
}

/// 422 for a cohort the model cannot draw; an unreachable target names its field and the
/// range the model reaches.
fn cohort_failed(e: ModelError) -> ApiError {
    let problem = ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, e.code(), e.to_string());
    match e {
        ModelError::TargetUnreachable {
            biomarker,
            low,
            high,
            ..
        } => problem
            .with("field", format!("targets.{biomarker}"))
            .with("reachable", serde_json::json!({"min": low, "max": high})),
        _ => problem,
    }
}

/// Whether the client asked for an asynchronous answer (RFC 7240 `Prefer: respond-async`).
fn prefers_async(headers: &HeaderMap) -> bool {
    headers
        .get_all("prefer")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|p| p.split(';').next().unwrap_or("").trim() == "respond-async")
}

fn location(id: &str) -> HeaderMap {
    let mut headers = HeaderMap::new();
    if let Ok(location) = HeaderValue::from_str(&format!("/v1/cohorts/{id}")) {
        headers.insert(header::LOCATION, location);
    }
    headers
}

/// Sample a virtual cohort from a model.
///
/// A cohort of at most the server's limit (default 1,000 members) is drawn inside the
/// request and answered 201 with its members. A larger one, or any request sent with
/// `Prefer: respond-async`, is queued for the workers and answered 202 with the cohort in
/// status `queued`: poll `GET /v1/cohorts/{id}` (status, progress) until it is `succeeded`.
#[utoipa::path(
    post, path = "/v1/models/{id}/cohorts", tag = "cohorts",
    params(
        ("id" = String, Path, description = "Model id"),
        ("Prefer" = Option<String>, Header, description = "`respond-async` to have the cohort drawn by the workers whatever its size (RFC 7240)"),
    ),
    request_body = CohortRequest,
    responses(
        (status = 201, description = "The cohort, drawn", body = CohortView, headers(("Location" = String, description = "URL of the cohort"))),
        (status = 202, description = "The cohort, queued for the workers", body = CohortView, headers(("Location" = String, description = "URL of the cohort"), ("Preference-Applied" = String, description = "`respond-async` when the header asked for it"))),
        (status = 400, description = "The body is not JSON (`request.malformed_json`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such model (`model.not_found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The model was stored in a format this release does not read (`model.unsupported_version`)", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "The body is not sent as application/json (`request.unsupported_media_type`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid field (`request.invalid_field`), too few accepted draws (`cohort.acceptance_unreachable`), a target the model cannot reach (`cohort.target_unreachable`), or a side asked of a model that does not know its own (`cohort.laterality_unknown`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn create_cohort(
    State(state): State<AppState>,
    Path(model_id): Path<String>,
    headers: HeaderMap,
    Json(body): Json<CohortRequest>,
) -> Result<(StatusCode, HeaderMap, Json<CohortView>), ApiError> {
    check_request(&body)?;
    if body.laterality.is_some() {
        check_side_known(&state, &model_id).await?;
    }
    let request = serde_json::to_value(&body).map_err(|e| ApiError::internal(e.to_string()))?;
    let asked_async = prefers_async(&headers);
    if asked_async || body.size > state.sync_cohort_max {
        let id = state
            .store
            .queue_cohort(NewCohortJob {
                model_id,
                request,
                size: body.size,
                seed: body.seed,
                max_attempts: MAX_ATTEMPTS,
            })
            .await?;
        state.wake.notify_one();
        let mut headers = location(&id);
        if asked_async {
            headers.insert(
                "preference-applied",
                HeaderValue::from_static("respond-async"),
            );
        }
        let cohort = state.store.cohort_head(&id).await?;
        return Ok((
            StatusCode::ACCEPTED,
            headers,
            Json(CohortView::new(cohort, false)),
        ));
    }
    let source = load_source(&state.store, &model_id)
        .await
        .map_err(|e| ApiError::from_run(&model_id, e))?;
    let drawn = tokio::task::spawn_blocking(move || draw_cohort(&source, &body, &mut Silent))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
        .map_err(cohort_failed)?;
    crate::telemetry::record_members_drawn("sync", drawn.members.len());
    let id = state
        .store
        .insert_cohort(&model_id, request, drawn.report, drawn.members)
        .await?;
    let cohort = state.store.cohort(&id).await?;
    Ok((
        StatusCode::CREATED,
        location(&id),
        Json(CohortView::new(cohort, true)),
    ))
}

/// Get a cohort: its status, report and counts, with its members inline while it is small.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id")),
    responses(
        (status = 200, description = "The cohort", body = CohortView),
        (status = 404, description = "No such cohort (`cohort.not_found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_cohort(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<CohortView>, ApiError> {
    let head = state.store.cohort_head(&id).await?;
    let inline = head.status == JobStatus::Succeeded && head.member_count <= state.sync_cohort_max;
    let record = match inline {
        true => state.store.cohort(&id).await?,
        false => head,
    };
    Ok(Json(CohortView::new(record, inline)))
}

/// A page of a cohort's members, in order.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/members", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id"), PageQuery),
    responses(
        (status = 200, description = "A page of members", body = Paginated<MemberSummary>),
        (status = 400, description = "Unreadable query (`request.invalid_query`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such cohort (`cohort.not_found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The cohort is not drawn (`cohort.not_ready`, with its `cohort_status`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "limit or offset out of range (`request.invalid_field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn list_members(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<PageQuery>,
) -> Result<Json<Paginated<MemberSummary>>, ApiError> {
    let page = q.page()?;
    let (values, total) = state.store.cohort_members(&id, page).await?;
    let items = values
        .into_iter()
        .map(serde_json::from_value)
        .collect::<Result<Vec<MemberSummary>, _>>()
        .map_err(|e| ApiError::from(StoreError::Corrupt(format!("cohort member: {e}"))))?;
    Ok(Json(Paginated::new(items, total, page)))
}

/// Cancel a cohort being drawn by the workers: a queued one at once, a running one after its
/// current batch of draws. Nothing of a cancelled cohort's members is kept.
#[utoipa::path(
    post, path = "/v1/cohorts/{id}/cancel", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id")),
    responses(
        (status = 202, description = "Cancellation requested (status `cancelled` when it was queued)", body = CohortView),
        (status = 404, description = "No such cohort (`cohort.not_found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The cohort is already drawn, failed or cancelled (`cohort.already_finished`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn cancel_cohort(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<(StatusCode, Json<CohortView>), ApiError> {
    let head = state.store.cohort_head(&id).await?;
    let finished = |status: &str| {
        ApiError::new(
            StatusCode::CONFLICT,
            "cohort.already_finished",
            format!("cohort {id} is already {status} and cannot be cancelled"),
        )
        .with("cohort_status", status.to_owned())
    };
    let job_id = match (&head.job_id, head.status.is_final()) {
        (Some(job_id), false) => job_id.clone(),
        _ => return Err(finished(head.status.as_str())),
    };
    match state.store.cancel_job(&job_id).await {
        Ok(_) => {}
        Err(StoreError::JobFinished { status, .. }) => return Err(finished(status)),
        Err(e) => return Err(e.into()),
    }
    let cohort = state.store.cohort_head(&id).await?;
    Ok((StatusCode::ACCEPTED, Json(CohortView::new(cohort, false))))
}
