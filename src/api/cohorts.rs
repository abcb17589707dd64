//! Virtual cohorts: sample from a model with an acceptance report; download members.

use std::collections::BTreeMap;
use std::io::Write;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, Path, Query};
use super::meshes::{MeshFile, mesh_file_response};
use super::models::{FormatQuery, load_model};
use crate::eval::Biomarkers;
use crate::geometry::pca::Sampling;
use crate::mesh;
use crate::models::cohort::{CohortSpec, Criterion, Member, TrainingIndex, sample_cohort_given};
use crate::models::conditional::{Conditional, Target};
use crate::models::{ModelError, ReferencePopulation};
use crate::report::exports::{member_file_name, members_csv};
use crate::store::cohorts::{CohortRecord, NewMember};

/// Largest cohort.
pub const MAX_COHORT_SIZE: usize = 10_000;
/// Draws allowed per wanted member with `only_accepted`.
pub const DRAWS_PER_MEMBER: usize = 20;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(create_cohort))
        .routes(routes!(get_cohort))
        .routes(routes!(download_member))
        .routes(routes!(download_archive))
}

/// Acceptance settings of a cohort request.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AcceptanceRequest {
    /// Criterion used by `only_accepted`: `range`, `mode` or `mean` (default).
    #[serde(default)]
    #[schema(value_type = String, example = "mean")]
    pub criterion: Criterion,
}

/// Body of `POST /v1/models/{id}/cohorts`.
#[derive(Debug, Clone, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CreateCohort {
    /// Members wanted (1–10,000).
    pub size: usize,
    /// Seed (default 0): the same model, seed and request give identical members.
    #[serde(default)]
    pub seed: u64,
    /// `gaussian` (default; coefficients clipped at 3 sd) or `uniform`.
    #[serde(default)]
    #[schema(value_type = String, example = "gaussian")]
    pub sampling: Sampling,
    /// Acceptance criterion.
    #[serde(default)]
    pub acceptance: AcceptanceRequest,
    /// Keep drawing until `size` members pass the criterion on every biomarker (at most
    /// 20 draws per member).
    #[serde(default)]
    pub only_accepted: bool,
    /// Draw again instead of keeping a member that is a near copy of a training shape
    /// (nearer than the model's privacy threshold).
    #[serde(default)]
    pub exclude_near_copies: bool,
    /// Targets by biomarker name (`volume_ml`, `area_cm2`, …): an interval
    /// `{"min": 120, "max": 160}` (either end may be left out) that every member meets, or a
    /// distribution `{"mean": 140, "sd": 10}` the members follow. Members are drawn from the
    /// model's Gaussian conditioned on the targets; a target the model cannot reach is a
    /// 422 `cohort.target_unreachable` naming the reachable range.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    #[schema(value_type = Object, example = json!({"volume_ml": {"min": 120, "max": 160}}))]
    pub targets: BTreeMap<String, Target>,
}

/// A cohort with its acceptance report and members.
#[derive(Debug, Serialize, ToSchema)]
pub struct CohortView {
    /// Identifier.
    pub id: String,
    /// Model it was drawn from.
    pub model_id: String,
    /// Number of members.
    pub size: usize,
    /// Seed used.
    pub seed: u64,
    /// The request with defaults filled in.
    #[schema(value_type = Object)]
    pub request: serde_json::Value,
    /// `biomarkers.<name>`: reference statistics, intervals, synthetic statistics and
    /// acceptance rates `{range, mode, mean}`; `acceptance`: joint rates over all biomarkers;
    /// `clusters`: per cluster (atlas) `{cluster, count, share, acceptance, biomarkers}`.
    #[schema(value_type = Object)]
    pub report: serde_json::Value,
    /// `{index, draw, cluster, biomarkers, accepted: {range, mode, mean},
    /// nearest_training_mm, nearest_training_mesh_id, near_copy}` per member.
    #[schema(value_type = Vec<Object>)]
    pub members: Vec<serde_json::Value>,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
}

impl From<CohortRecord> for CohortView {
    fn from(r: CohortRecord) -> Self {
        Self {
            size: r.members.len(),
            seed: r
                .request
                .get("seed")
                .and_then(serde_json::Value::as_u64)
                .unwrap_or(0),
            id: r.id,
            model_id: r.model_id,
            request: r.request,
            report: r.report,
            members: r.members,
            created_at: r.created_at,
        }
    }
}

fn member_summary(m: &Member, training_ids: &[String]) -> serde_json::Value {
    let biomarkers: serde_json::Map<String, serde_json::Value> = m
        .biomarkers
        .iter()
        .map(|(name, value)| (name.to_owned(), value.into()))
        .collect();
    serde_json::json!({
        "index": m.index,
        "draw": m.draw,
        "cluster": m.cluster,
        "biomarkers": biomarkers,
        "accepted": m.accepted,
        "nearest_training_mm": m.nearest_training.distance_mm,
        "nearest_training_mesh_id": training_ids.get(m.nearest_training.index),
        "near_copy": m.near_copy,
    })
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

fn check_request(body: &CreateCohort) -> Result<(), ApiError> {
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

/// Sample a virtual cohort from a model.
#[utoipa::path(
    post, path = "/v1/models/{id}/cohorts", tag = "cohorts",
    params(("id" = String, Path, description = "Model id")),
    request_body = CreateCohort,
    responses(
        (status = 201, description = "The cohort", body = CohortView, headers(("Location" = String, description = "URL of the cohort"))),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The model was stored in a format this release does not read (model.unsupported_version)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid field (`request.invalid_field`), too few accepted draws (`cohort.acceptance_unreachable`), or a target the model cannot reach (`cohort.target_unreachable`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn create_cohort(
    State(state): State<AppState>,
    Path(model_id): Path<String>,
    Json(body): Json<CreateCohort>,
) -> Result<(StatusCode, HeaderMap, Json<CohortView>), ApiError> {
    check_request(&body)?;
    let (stored, reference) = load_model(&state, &model_id).await?;
    let training_ids = state
        .store
        .model(&model_id)
        .await?
        .provenance
        .training_mesh_ids;
    let reference: ReferencePopulation = serde_json::from_value(reference)
        .map_err(|e| ApiError::internal(format!("model {model_id} reference: {e}")))?;
    let spec = CohortSpec {
        size: body.size,
        seed: body.seed,
        sampling: body.sampling,
        criterion: body.acceptance.criterion,
        only_accepted: body.only_accepted,
        exclude_near_copies: body.exclude_near_copies,
        max_draws: body.size.saturating_mul(DRAWS_PER_MEMBER),
    };
    let targets: Vec<(String, Target)> = body.targets.clone().into_iter().collect();
    let (members, report) = tokio::task::spawn_blocking(move || {
        let shapes = stored.training.normalised_f64();
        let training = TrainingIndex::new(&shapes, &stored.training.privacy)?;
        let model = stored.model.as_ref();
        let conditional = match targets.is_empty() {
            true => None,
            false => Some(Conditional::new(model, &targets, spec.seed)?),
        };
        sample_cohort_given(model, &reference, &training, &spec, conditional.as_ref())
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?
    .map_err(cohort_failed)?;
    let report = serde_json::to_value(&report).map_err(|e| ApiError::internal(e.to_string()))?;
    let request = serde_json::to_value(&body).map_err(|e| ApiError::internal(e.to_string()))?;
    let new_members = members
        .iter()
        .map(|m| NewMember {
            index: m.index,
            summary: member_summary(m, &training_ids),
            mesh: m.mesh.clone(),
        })
        .collect();
    let id = state
        .store
        .insert_cohort(&model_id, request, report, new_members)
        .await?;
    let cohort = state.store.cohort(&id).await?;
    let mut headers = HeaderMap::new();
    if let Ok(location) = HeaderValue::from_str(&format!("/v1/cohorts/{id}")) {
        headers.insert(header::LOCATION, location);
    }
    Ok((StatusCode::CREATED, headers, Json(cohort.into())))
}

/// Get a cohort with its report and members.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id")),
    responses(
        (status = 200, description = "The cohort", body = CohortView),
        (status = 404, description = "No such cohort", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_cohort(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<CohortView>, ApiError> {
    Ok(Json(state.store.cohort(&id).await?.into()))
}

/// Download one member's mesh.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/members/{index}/file", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id"), ("index" = i64, Path, description = "Member index, from 0"), FormatQuery),
    responses(
        (status = 200, description = "The member's mesh", content(
            (MeshFile = "model/obj"), (MeshFile = "model/stl"),
            (MeshFile = "application/x-ply"), (MeshFile = "application/vnd.vtk"))),
        (status = 404, description = "No such cohort or member", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_member(
    State(state): State<AppState>,
    Path((id, index)): Path<(String, i64)>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let mesh = state.store.cohort_member_mesh(&id, index).await?;
    let cohort: CohortView = state.store.cohort(&id).await?.into();
    let bytes = mesh::io::write_with_provenance(&mesh, format, &provenance(&cohort, index));
    Ok(mesh_file_response(
        &format!("member_{index:05}"),
        format,
        bytes,
    ))
}

/// The line kept inside member files (VTK's title line): where the member came from.
fn provenance(cohort: &CohortView, index: i64) -> String {
    format!(
        "cohortforge member model={} cohort={} seed={} index={index}, coordinates in mm",
        cohort.model_id, cohort.id, cohort.seed
    )
}

/// Zip of every member (in the chosen format), `members.csv` and `report.json`.
fn archive(
    cohort: &CohortView,
    meshes: &[mesh::Mesh],
    format: mesh::Format,
) -> Result<Vec<u8>, std::io::Error> {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .last_modified_time(zip::DateTime::default());
    zip.start_file("report.json", options)?;
    zip.write_all(&serde_json::to_vec_pretty(&serde_json::json!({
        "model_id": cohort.model_id, "request": cohort.request,
        "report": cohort.report, "members": cohort.members,
    }))?)?;
    zip.start_file("members.csv", options)?;
    zip.write_all(members_csv(&cohort.members, format.extension()).as_bytes())?;
    for (i, m) in meshes.iter().enumerate() {
        zip.start_file(member_file_name(i, format.extension()), options)?;
        let index = i64::try_from(i).unwrap_or(i64::MAX);
        zip.write_all(&mesh::io::write_with_provenance(
            m,
            format,
            &provenance(cohort, index),
        ))?;
    }
    Ok(zip.finish()?.into_inner())
}

/// Download the whole cohort as a zip archive.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/archive", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id"), FormatQuery),
    responses(
        (status = 200, description = "Zip of member meshes, members.csv and report.json", content((MeshFile = "application/zip"))),
        (status = 404, description = "No such cohort", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_archive(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let cohort: CohortView = state.store.cohort(&id).await?.into();
    let meshes = state.store.cohort_meshes(&id).await?;
    let bytes = tokio::task::spawn_blocking(move || archive(&cohort, &meshes, format))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
        .map_err(|e| ApiError::internal(e.to_string()))?;
    let mut response = bytes.into_response();
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/zip"),
    );
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"cohort_{id}.zip\"")) {
        headers.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(response)
}
