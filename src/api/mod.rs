//! HTTP API: routes, handlers, auth, problem+json errors and the OpenAPI document.
//!
//! Every handler is registered once through `utoipa_axum`, so routing and the
//! documentation cannot drift apart.

pub mod auth;
mod cohort_files;
mod cohorts;
mod common_responses;
mod datasets;
pub mod error;
mod events;
mod exports;
pub mod extract;
mod jobs;
mod meshes;
mod metrics;
mod models;
mod octet;
mod ops;
mod plots;
mod renders;
mod reports;
pub mod upload;
mod vocabulary;

use std::sync::Arc;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::{HeaderName, Request};
use tokio::net::TcpListener;
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityScheme};
use utoipa_axum::router::OpenApiRouter;
use utoipa_swagger_ui::SwaggerUi;

use crate::config::{Config, WorkerConfig};
use crate::jobs::{WorkerPool, WorkerSettings};
use crate::mesh::io::Limits;
use crate::mesh::validate::IngestOptions;
use crate::store::Store;
use auth::Tokens;
use error::ApiError;

/// Header carrying the request id, set when the client sends none.
pub const REQUEST_ID_HEADER: &str = "x-request-id";

/// Shared state of the handlers: cheap to clone.
#[derive(Clone)]
pub struct AppState {
    /// The database.
    pub store: Store,
    /// Bearer tokens (none: the API is open).
    pub tokens: Arc<Tokens>,
    /// Largest accepted mesh, in vertices.
    pub max_vertices: usize,
    /// Notified when a job is queued, so idle workers start at once.
    pub wake: Arc<Notify>,
    /// Largest cohort drawn inside its request and listed inline.
    pub sync_cohort_max: usize,
}

impl AppState {
    /// State for a configuration and an opened store.
    pub fn new(config: &Config, store: Store, wake: Arc<Notify>) -> Self {
        Self {
            store,
            tokens: Arc::new(Tokens {
                admin: config.admin_token.clone(),
                read: config.read_token.clone(),
            }),
            max_vertices: config.max_vertices,
            wake,
            sync_cohort_max: config.sync_cohort_max,
        }
    }

    /// Validation options for uploads.
    pub fn ingest_options(&self) -> IngestOptions {
        IngestOptions {
            limits: Limits {
                max_vertices: self.max_vertices,
                max_faces: self.max_vertices.saturating_mul(4),
            },
            ..IngestOptions::default()
        }
    }
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "cohortforge",
        description = "Generative models of anatomical shape from surface meshes, served as \
                       virtual cohorts for in-silico clinical trials. Errors are \
                       application/problem+json with a stable `code`.",
    ),
    modifiers(&BearerAuth),
    tags(
        (name = "datasets", description = "Collections of meshes of one organ"),
        (name = "meshes", description = "Upload, inspect and download surface meshes"),
        (name = "jobs", description = "Queued fits of shape models, with progress"),
        (name = "models", description = "Fitted shape models with provenance and evaluation"),
        (name = "cohorts", description = "Virtual cohorts sampled from models, with acceptance reports"),
        (name = "ops", description = "Probes"),
    )
)]
struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(Http::new(HttpAuthScheme::Bearer)),
        );
        openapi.security = Some(vec![utoipa::openapi::security::SecurityRequirement::new(
            "bearer",
            Vec::<String>::new(),
        )]);
    }
}

fn api_routes() -> (OpenApiRouter<AppState>, OpenApiRouter<AppState>) {
    let v1 = OpenApiRouter::new()
        .merge(datasets::router())
        .merge(meshes::router())
        .merge(jobs::router())
        .merge(models::router())
        .merge(cohorts::router())
        .merge(reports::router())
        .merge(plots::router())
        .merge(renders::router())
        .merge(exports::router());
    (v1, ops::router().merge(metrics::router()))
}

/// The OpenAPI document of the service.
pub fn openapi() -> utoipa::openapi::OpenApi {
    let (v1, ops) = api_routes();
    let (_, mut spec) = OpenApiRouter::<AppState>::with_openapi(ApiDoc::openapi())
        .merge(v1)
        .merge(ops)
        .split_for_parts();
    finish_spec(&mut spec);
    spec
}

/// What the handlers' annotations leave out: octet-stream beside every binary type and the
/// error responses whole classes of operations share.
fn finish_spec(spec: &mut utoipa::openapi::OpenApi) {
    octet::declare_octet_stream(spec);
    common_responses::declare_common_responses(spec);
}

/// The complete HTTP application.
pub fn app(state: AppState, max_body_bytes: usize) -> Router {
    crate::telemetry::init();
    let (v1, ops) = api_routes();
    let v1 = v1.layer(axum::middleware::from_fn_with_state(
        state.clone(),
        auth::require_token,
    ));
    let (router, mut spec) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(v1)
        .merge(ops)
        .split_for_parts();
    finish_spec(&mut spec);
    let request_id = HeaderName::from_static(REQUEST_ID_HEADER);
    router
        .merge(SwaggerUi::new("/docs").url("/openapi.json", spec))
        .fallback(|| async { ApiError::no_route() })
        .method_not_allowed_fallback(|| async { ApiError::method_not_allowed() })
        .with_state(state)
        .layer(axum::middleware::from_fn(octet::octet_stream_when_preferred))
        .layer(axum::middleware::from_fn(metrics::record_request))
        .layer(DefaultBodyLimit::max(max_body_bytes))
        .layer(PropagateRequestIdLayer::new(request_id.clone()))
        .layer(
            TraceLayer::new_for_http().make_span_with(|request: &Request<_>| {
                let id = request
                    .headers()
                    .get(REQUEST_ID_HEADER)
                    .and_then(|v| v.to_str().ok())
                    .unwrap_or("-");
                tracing::info_span!("request", method = %request.method(), uri = %request.uri(), request_id = %id)
            }),
        )
        .layer(SetRequestIdLayer::new(request_id, MakeRequestUuid))
}

/// Serves the application on a bound listener until `shutdown` is cancelled.
pub async fn serve(
    listener: TcpListener,
    config: &Config,
    store: Store,
    wake: Arc<Notify>,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    let state = AppState::new(config, store, wake);
    let app = app(state, config.max_body_bytes);
    axum::serve(listener, app)
        .with_graceful_shutdown(async move { shutdown.cancelled().await })
        .await
}

/// Runs the whole service on a bound listener: `config.workers` training workers and the
/// HTTP API, until `shutdown` is cancelled; then waits for the workers to stop (a running
/// job is handed back to the queue).
pub async fn run(
    listener: TcpListener,
    config: &Config,
    store: Store,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    let (pool, wake) = start_pool(&store, config.workers, config.lease_seconds, &shutdown)?;
    let served = serve(listener, config, store, wake, shutdown.clone()).await;
    shutdown.cancel();
    let _ = tokio::task::spawn_blocking(move || pool.join()).await;
    served
}

/// Starts `workers` job workers on the current runtime with leases of `lease_seconds`, and
/// the notifier that wakes them when a job is queued.
fn start_pool(
    store: &Store,
    workers: usize,
    lease_seconds: u64,
    shutdown: &CancellationToken,
) -> std::io::Result<(WorkerPool, Arc<Notify>)> {
    let wake = Arc::new(Notify::new());
    let settings = WorkerSettings {
        lease: std::time::Duration::from_secs(lease_seconds),
        ..WorkerSettings::default()
    };
    let pool = WorkerPool::start(
        store.clone(),
        workers,
        tokio::runtime::Handle::current(),
        wake.clone(),
        shutdown.clone(),
        settings,
    )?;
    Ok((pool, wake))
}

/// Runs a worker process: `config.workers` workers that poll the shared database for jobs,
/// and on `listener` only the probes and `/metrics`, until `shutdown` is cancelled; then
/// waits for the workers (a running job is handed back to the queue).
pub async fn run_workers(
    listener: TcpListener,
    config: &WorkerConfig,
    store: Store,
    shutdown: CancellationToken,
) -> std::io::Result<()> {
    crate::telemetry::init();
    let (pool, wake) = start_pool(&store, config.workers, config.lease_seconds, &shutdown)?;
    let state = AppState::new(&Config::local(config.database.clone()), store, wake);
    let (router, _) = OpenApiRouter::new()
        .merge(ops::router())
        .merge(metrics::router())
        .split_for_parts();
    let app = router
        .fallback(|| async { ApiError::no_route() })
        .with_state(state)
        .layer(axum::middleware::from_fn(metrics::record_request));
    let on_stop = shutdown.clone();
    let served = axum::serve(listener, app)
        .with_graceful_shutdown(async move { on_stop.cancelled().await })
        .await;
    shutdown.cancel();
    let _ = tokio::task::spawn_blocking(move || pool.join()).await;
    served
}
