//! `GET /metrics` (Prometheus exposition text) and the middleware that times every request
//! by its matched route.

use std::time::Instant;

use axum::extract::{MatchedPath, Request, State};
use axum::http::header::CONTENT_TYPE;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use crate::telemetry::{self, HTTP_ACTIVE_REQUESTS, HTTP_REQUEST_DURATION, QueueGauges};

/// Content type of the Prometheus text exposition format.
const EXPOSITION: &str = "text/plain; version=0.0.4; charset=utf-8";

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new().routes(routes!(metrics))
}

/// Prometheus metrics of this process: request durations by route, job run and fit stage
/// times, cohort members drawn, and the queue (jobs by status and model type, age of the
/// oldest queued job) read from the database.
#[utoipa::path(get, path = "/metrics", tag = "ops",
    responses((status = 200, description = "Prometheus text exposition format",
        body = String, content_type = "text/plain")))]
async fn metrics(State(state): State<AppState>) -> Response {
    let queue = match state.store.queue_stats().await {
        Ok(q) => Some(QueueGauges {
            jobs: q
                .jobs
                .into_iter()
                .map(|j| (j.status, j.kind, j.model_type, j.count))
                .collect(),
            oldest_queued_seconds: q.oldest_queued_seconds,
        }),
        Err(e) => {
            tracing::error!(error = %e, "queue gauges unavailable");
            None
        }
    };
    (
        [(CONTENT_TYPE, EXPOSITION)],
        telemetry::render(queue.as_ref()),
    )
        .into_response()
}

/// Lowers the active-requests gauge however the request ends (also when it is dropped).
struct Active;

impl Active {
    fn start() -> Self {
        metrics::gauge!(HTTP_ACTIVE_REQUESTS).increment(1.0);
        Self
    }
}

impl Drop for Active {
    fn drop(&mut self) {
        metrics::gauge!(HTTP_ACTIVE_REQUESTS).decrement(1.0);
    }
}

/// Records the duration of every request under its route pattern (`/v1/jobs/{id}`), or
/// `unmatched` for paths no route serves, so that label values stay few.
pub(super) async fn record_request(request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_owned(), |m| m.as_str().to_owned());
    let method = request.method().as_str().to_owned();
    let _active = Active::start();
    let started = Instant::now();
    let response = next.run(request).await;
    metrics::histogram!(HTTP_REQUEST_DURATION, "method" => method, "route" => route,
        "status" => response.status().as_u16().to_string())
    .record(started.elapsed().as_secs_f64());
    response
}
