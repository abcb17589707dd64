//! A cohort's files: one member's mesh, or every member in a zip archive.

use std::io::Write;

use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Path, Query};
use super::meshes::{MeshFile, mesh_file_response};
use super::models::FormatQuery;
use crate::jobs::cohort::{CohortRequest, load_source, member_shapes, model_side};
use crate::mesh;
use crate::report::exports::{member_file_name, members_csv};
use crate::store::cohorts::{CohortRecord, MemberGeometry};

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(download_member))
        .routes(routes!(download_archive))
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
        (status = 409, description = "The cohort is not drawn (`cohort.not_ready`), or a member no longer comes out of its model as first drawn (`cohort.not_reproducible`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_member(
    State(state): State<AppState>,
    Path((id, index)): Path<(String, i64)>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let cohort = state.store.cohort_head(&id).await?;
    let mesh = member_shapes_of(&state, &cohort, &[index]).await?.remove(0);
    let bytes = mesh::io::write_with_provenance(&mesh, format, &provenance(&cohort, index));
    Ok(mesh_file_response(
        &format!("member_{index:05}"),
        format,
        bytes,
    ))
}

/// The shapes of members `indices` of a drawn cohort: stored, or drawn again from its model.
pub(super) async fn member_shapes_of(
    state: &AppState,
    cohort: &CohortRecord,
    indices: &[i64],
) -> Result<Vec<mesh::Mesh>, ApiError> {
    let mut geometries = Vec::with_capacity(indices.len());
    for &i in indices {
        geometries.push(state.store.cohort_member_geometry(&cohort.id, i).await?);
    }
    shapes(state, cohort, geometries).await
}

async fn shapes(
    state: &AppState,
    cohort: &CohortRecord,
    geometries: Vec<MemberGeometry>,
) -> Result<Vec<mesh::Mesh>, ApiError> {
    let model_id = cohort.model_id.clone();
    let source = match geometries
        .iter()
        .any(|g| matches!(g, MemberGeometry::Redraw { .. }))
    {
        true => Some(
            load_source(&state.store, &model_id)
                .await
                .map_err(|e| ApiError::from_run(&model_id, e))?,
        ),
        false => None,
    };
    let request: CohortRequest = serde_json::from_value(cohort.request.clone())
        .map_err(|e| ApiError::internal(format!("cohort {} request: {e}", cohort.id)))?;
    let model_side = match request.laterality {
        Some(_) => model_side(&state.store.model(&model_id).await?.summary),
        None => None,
    };
    tokio::task::spawn_blocking(move || {
        member_shapes(source.as_ref(), &request, model_side, geometries)
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?
    .map_err(|e| ApiError::from_run(&model_id, e))
}

/// The line kept inside member files (VTK's title line): where the member came from.
fn provenance(cohort: &CohortRecord, index: i64) -> String {
    let seed = cohort
        .request
        .get("seed")
        .and_then(serde_json::Value::as_u64)
        .unwrap_or(0);
    let side = cohort
        .request
        .get("laterality")
        .and_then(serde_json::Value::as_str)
        .map_or(String::new(), |s| format!(" laterality={s}"));
    format!(
        "cohortforge member model={} cohort={} seed={seed} index={index}{side}, coordinates in mm",
        cohort.model_id, cohort.id
    )
}

/// Zip of every member (in the chosen format), `members.csv` and `report.json`.
fn archive(
    cohort: &CohortRecord,
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
        (status = 409, description = "The cohort is not drawn (`cohort.not_ready`), or a member no longer comes out of its model as first drawn (`cohort.not_reproducible`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_archive(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let cohort = state.store.cohort(&id).await?;
    let meshes = shapes(&state, &cohort, state.store.cohort_geometries(&id).await?).await?;
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
