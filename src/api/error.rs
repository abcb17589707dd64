//! Errors as `application/problem+json` (RFC 9457), mapped from library errors in one place.

use std::borrow::Cow;

use axum::extract::multipart::MultipartError;
use axum::extract::rejection::{BytesRejection, JsonRejection, PathRejection, QueryRejection};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::mesh::MeshError;
use crate::report::{PlotError, PlotFormat};
use crate::store::StoreError;

/// Media type of every error body.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// An error body: what went wrong and what to do about it.
#[derive(Debug, Serialize, ToSchema)]
pub struct Problem {
    /// URI naming the kind of problem: `urn:cohortforge:problem:<code>`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Short summary of the kind of problem.
    pub title: String,
    /// HTTP status code.
    pub status: u16,
    /// What went wrong in this request and how to fix it.
    pub detail: String,
    /// Stable machine-readable code, e.g. `mesh.parse_error`.
    pub code: String,
    /// Further fields for some codes (e.g. `existing_mesh_id`, `part`).
    #[serde(flatten)]
    #[schema(value_type = Object)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// An error on its way to becoming a problem+json response.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    code: Cow<'static, str>,
    detail: String,
    extra: serde_json::Map<String, serde_json::Value>,
}

impl ApiError {
    /// An error with a status, a stable code and a sentence for the user.
    pub fn new(
        status: StatusCode,
        code: impl Into<Cow<'static, str>>,
        detail: impl Into<String>,
    ) -> Self {
        Self {
            status,
            code: code.into(),
            detail: detail.into(),
            extra: serde_json::Map::new(),
        }
    }

    /// Adds a field to the problem body.
    pub fn with(mut self, key: &str, value: impl Into<serde_json::Value>) -> Self {
        self.extra.insert(key.to_owned(), value.into());
        self
    }

    /// 422 for a request field with an invalid value.
    pub fn invalid_field(field: &str, detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.invalid_field",
            detail,
        )
        .with("field", field)
    }

    /// 500 for a failure that is not the client's fault; the detail goes to the log only.
    pub fn internal(detail: impl Into<String>) -> Self {
        tracing::error!(detail = %detail.into(), "internal error");
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal.error",
            "the service failed to complete the request; try again later",
        )
    }

    /// A stored model that cannot be read: 409 `model.unsupported_version` when another
    /// release wrote it in a format this one does not read, 500 when it is damaged.
    pub fn unreadable_model(id: &str, err: crate::models::ModelError) -> Self {
        match err {
            crate::models::ModelError::UnsupportedVersion { .. } => Self::new(
                StatusCode::CONFLICT,
                err.code(),
                format!("model {id}: {err}"),
            ),
            other => Self::internal(format!("model {id}: {other}")),
        }
    }

    /// A failure to read or draw from model `model_id`: its stored form, the store, or a
    /// cohort member that no longer comes out of it as first drawn (409
    /// `cohort.not_reproducible`).
    pub fn from_run(model_id: &str, err: crate::jobs::run::RunError) -> Self {
        use crate::jobs::run::RunError;
        match err {
            RunError::Model(e) => Self::unreadable_model(model_id, e),
            RunError::Store(e) => e.into(),
            RunError::Invalid(e) => Self::internal(e),
            e @ RunError::NotReproducible { .. } => Self::new(
                StatusCode::CONFLICT,
                "cohort.not_reproducible",
                e.to_string(),
            ),
        }
    }

    /// 404 for a path that matches no route.
    pub fn no_route() -> Self {
        Self::new(
            StatusCode::NOT_FOUND,
            "request.no_route",
            "no endpoint has this path; see /docs for the list of endpoints",
        )
    }

    /// 405 for a known path with another method.
    pub fn method_not_allowed() -> Self {
        Self::new(
            StatusCode::METHOD_NOT_ALLOWED,
            "request.method_not_allowed",
            "this endpoint does not support the HTTP method used; see /docs",
        )
    }

    /// 400 for a plot format other than those of [`PlotFormat`].
    pub fn unsupported_plot_format(name: &str) -> Self {
        Self::new(
            StatusCode::BAD_REQUEST,
            "plot.unsupported_format",
            format!(
                "format '{name}' is not a plot format; use {}",
                PlotFormat::NAMES.join(" or ")
            ),
        )
        .with("field", "format")
    }

    /// The HTTP status.
    pub fn status(&self) -> StatusCode {
        self.status
    }

    /// The stable code.
    pub fn code(&self) -> &str {
        &self.code
    }

    fn problem(self) -> Problem {
        Problem {
            kind: format!("urn:cohortforge:problem:{}", self.code),
            title: self.status.canonical_reason().unwrap_or("Error").to_owned(),
            status: self.status.as_u16(),
            detail: self.detail,
            code: self.code.into_owned(),
            extra: self.extra,
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if self.status.is_server_error() {
            tracing::error!(code = %self.code, detail = %self.detail, "request failed");
        } else {
            tracing::info!(status = self.status.as_u16(), code = %self.code, "request refused");
        }
        let status = self.status;
        let body = serde_json::to_vec(&self.problem()).unwrap_or_default();
        let mut response = (status, body).into_response();
        response
            .headers_mut()
            .insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        response
    }
}

/// Status for each mesh error code.
fn mesh_status(err: &MeshError) -> StatusCode {
    match err.code() {
        "mesh.too_large" => StatusCode::PAYLOAD_TOO_LARGE,
        "mesh.unsupported_format" => StatusCode::UNSUPPORTED_MEDIA_TYPE,
        _ => StatusCode::UNPROCESSABLE_ENTITY,
    }
}

impl From<MeshError> for ApiError {
    fn from(err: MeshError) -> Self {
        Self::new(mesh_status(&err), err.code(), err.to_string())
    }
}

impl From<StoreError> for ApiError {
    fn from(err: StoreError) -> Self {
        match err {
            StoreError::NotFound { entity, ref id } => Self::new(
                StatusCode::NOT_FOUND,
                format!("{entity}.not_found"),
                format!("no {entity} has the id {id}; list them to find the right one"),
            ),
            StoreError::DuplicateMesh {
                ref existing_id,
                ref existing_name,
            } => Self::new(
                StatusCode::CONFLICT,
                "mesh.duplicate",
                format!(
                    "the dataset already holds this geometry as mesh {existing_id} \
                     (\"{existing_name}\"); nothing was stored"
                ),
            )
            .with("existing_mesh_id", existing_id.clone()),
            StoreError::IdempotencyMismatch { ref existing_id } => Self::new(
                StatusCode::CONFLICT,
                "job.idempotency_conflict",
                format!(
                    "this Idempotency-Key was already used for a different request (job \
                     {existing_id}); use a new key for a new request"
                ),
            )
            .with("existing_job_id", existing_id.clone()),
            StoreError::JobFinished { ref id, status } => Self::new(
                StatusCode::CONFLICT,
                "job.already_finished",
                format!("job {id} is already {status} and cannot be cancelled"),
            ),
            StoreError::CohortNotReady { ref id, status } => Self::new(
                StatusCode::CONFLICT,
                "cohort.not_ready",
                match status {
                    "queued" | "running" => format!(
                        "cohort {id} is still {status}; poll GET /v1/cohorts/{id} until its \
                         status is succeeded"
                    ),
                    _ => format!("cohort {id} ended {status} and has no members; see its error"),
                },
            )
            .with("cohort_status", status),
            other => {
                tracing::error!(error = %other, "storage failure");
                Self::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    "internal.storage",
                    "the database failed to complete the request; try again later",
                )
            }
        }
    }
}

impl From<PlotError> for ApiError {
    fn from(err: PlotError) -> Self {
        let available = err.available().to_vec();
        Self::new(StatusCode::NOT_FOUND, err.code(), err.to_string()).with("available", available)
    }
}

impl From<JsonRejection> for ApiError {
    fn from(rejection: JsonRejection) -> Self {
        match rejection {
            JsonRejection::MissingJsonContentType(_) => Self::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "request.unsupported_media_type",
                "send the body as JSON with the header Content-Type: application/json",
            ),
            JsonRejection::JsonSyntaxError(e) => Self::new(
                StatusCode::BAD_REQUEST,
                "request.malformed_json",
                format!("the body is not valid JSON: {}", e.body_text()),
            ),
            JsonRejection::JsonDataError(e) => Self::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "request.invalid_field",
                format!(
                    "the JSON body does not match the expected fields: {}",
                    e.body_text()
                ),
            ),
            other => Self::new(other.status(), "request.unreadable_body", other.body_text()),
        }
    }
}

impl From<QueryRejection> for ApiError {
    fn from(rejection: QueryRejection) -> Self {
        Self::new(
            StatusCode::BAD_REQUEST,
            "request.invalid_query",
            format!("the query string is invalid: {}", rejection.body_text()),
        )
    }
}

impl From<PathRejection> for ApiError {
    fn from(rejection: PathRejection) -> Self {
        Self::new(
            StatusCode::BAD_REQUEST,
            "request.invalid_path",
            rejection.body_text(),
        )
    }
}

impl From<BytesRejection> for ApiError {
    fn from(rejection: BytesRejection) -> Self {
        body_error(rejection.status(), rejection.body_text())
    }
}

impl From<MultipartError> for ApiError {
    fn from(err: MultipartError) -> Self {
        body_error(err.status(), err.body_text())
    }
}

fn body_error(status: StatusCode, text: String) -> ApiError {
    if status == StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::new(
            status,
            "request.body_too_large",
            "the request body is larger than the server accepts (--max-body-bytes); \
             upload fewer or smaller files per request",
        )
    } else {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            "request.unreadable_body",
            format!("the request body could not be read: {text}"),
        )
    }
}
