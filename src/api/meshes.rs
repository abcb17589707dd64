//! Mesh upload (raw body or multipart), listing, metadata, download and deletion.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, PageQuery, Paginated, Path, Query};
use super::upload::{
    Conversion, InputKind, UploadedFile, convert_all, parse_input_kind, read_multipart,
    unsupported_content_type,
};
use crate::mesh::{self, Format, Laterality};
use crate::segmentation;
use crate::store::meshes::MeshRecord;

/// Longest mesh name, in characters.
const MAX_NAME_CHARS: usize = 200;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(upload_meshes, list_meshes))
        .routes(routes!(get_mesh, update_mesh, delete_mesh))
        .routes(routes!(download_mesh))
}

/// Query of a mesh upload.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct UploadQuery {
    /// File format when the Content-Type does not say it: `obj`, `stl`, `ply`, `vtk`, or
    /// `nifti` for a NIfTI-1 label volume (`.nii` or gzip `.nii.gz`).
    #[param(value_type = Option<super::vocabulary::UploadFormatName>, inline)]
    pub format: Option<String>,
    /// Name of the mesh (raw uploads; multipart parts use their file names; 1–200
    /// characters, no control characters).
    #[param(
        min_length = 1,
        max_length = 200,
        pattern = r"^[^\x00-\x1f\x7f-\x9f]*[^\s\x00-\x1f\x7f-\x9f][^\x00-\x1f\x7f-\x9f]*$"
    )]
    pub name: Option<String>,
    /// NIfTI: the label (default 1) or a comma-separated list of labels forming the structure.
    #[param(pattern = r"^-?[0-9]+(,-?[0-9]+)*$")]
    pub label: Option<String>,
    /// NIfTI: `largest` (default) keeps the largest 6-connected part, `all` keeps every part.
    #[param(value_type = Option<super::vocabulary::ComponentName>, inline)]
    pub component: Option<String>,
    /// NIfTI: fill cavities not connected to the outside (default true).
    pub fill_holes: Option<bool>,
    /// NIfTI: Gaussian smoothing in mm before the surface is extracted (default 1.0; 0: none).
    #[param(minimum = 0.0, maximum = 20.0)]
    pub smooth_sigma_mm: Option<f64>,
    /// NIfTI: size of the isotropic voxels the surface is extracted from, mm (default 1.5).
    #[param(minimum = 0.1, maximum = 20.0)]
    pub voxel_mm: Option<f64>,
    /// Simplify every mesh to about this many vertices by quadric edge collapse, keeping it
    /// closed (default: the dataset's `target_vertices`, else no simplification).
    #[param(minimum = 8, maximum = 1_000_000)]
    pub target_vertices: Option<i64>,
    /// The side of a paired organ every mesh of the upload is (`left` or `right` kidney,
    /// lung, ...); set or change it per mesh later with `PATCH /v1/meshes/{id}`. Models that
    /// learn both sides on one (`mirror`) take it as given instead of reading it from the
    /// shape.
    #[param(value_type = Option<crate::mesh::Laterality>, inline)]
    pub laterality: Option<String>,
}

impl UploadQuery {
    /// Label volume parameters, defaults filled in and checked.
    fn segmentation(&self) -> Result<segmentation::Options, ApiError> {
        let invalid = |e: segmentation::OptionsError| ApiError::invalid_field(e.field, e.message);
        let defaults = segmentation::Options::default();
        let options = segmentation::Options {
            labels: match &self.label {
                Some(text) => segmentation::Options::parse_labels(text).map_err(invalid)?,
                None => defaults.labels,
            },
            component: match &self.component {
                Some(text) => text.parse().map_err(invalid)?,
                None => defaults.component,
            },
            fill_holes: self.fill_holes.unwrap_or(defaults.fill_holes),
            smooth_sigma_mm: self.smooth_sigma_mm.unwrap_or(defaults.smooth_sigma_mm),
            voxel_mm: self.voxel_mm.unwrap_or(defaults.voxel_mm),
        };
        options.check().map_err(invalid)?;
        Ok(options)
    }
}

/// Response of a multipart upload.
#[derive(Debug, Serialize, ToSchema)]
pub struct UploadedMeshes {
    /// The stored meshes, in the order of the parts.
    pub meshes: Vec<MeshRecord>,
}

/// A mesh file in the body (documentation type).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct MeshFile(#[allow(dead_code)] Vec<u8>);

/// Multipart body of an upload (documentation type).
#[derive(ToSchema)]
pub struct MeshFiles {
    /// One part per mesh file; the file name gives the mesh name and the format.
    #[schema(value_type = Vec<String>, format = Binary)]
    #[allow(dead_code)]
    file: Vec<Vec<u8>>,
}

/// Response of an upload: one record for a raw body, `{meshes}` for multipart.
#[derive(Serialize, ToSchema)]
#[serde(untagged)]
pub enum UploadResponse {
    /// Raw body: the stored mesh.
    One(Box<MeshRecord>),
    /// Multipart: every stored mesh.
    Many(UploadedMeshes),
}

/// Query of a mesh download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct DownloadQuery {
    /// Output format: `obj` (default), `stl` (binary), `ply` (binary) or `vtk` (legacy ASCII).
    #[param(value_type = Option<super::vocabulary::MeshFormatName>, inline)]
    pub format: Option<String>,
}

pub(crate) fn parse_format(field: &str, name: &str) -> Result<Format, ApiError> {
    Format::from_name(name).ok_or_else(|| {
        ApiError::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "mesh.unsupported_format",
            format!("{field} '{name}' is not a supported mesh format; use obj, stl, ply or vtk"),
        )
        .with("field", field)
    })
}

fn content_type(headers: &HeaderMap) -> Option<&str> {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
}

pub(super) fn check_name(name: &str) -> Result<(), ApiError> {
    super::datasets::check_label("name", name, MAX_NAME_CHARS)
}

/// Upload one mesh (raw body) or many (multipart `file` parts), all or nothing.
#[utoipa::path(
    post, path = "/v1/datasets/{id}/meshes", tag = "meshes",
    params(("id" = String, Path, description = "Dataset id"), UploadQuery),
    request_body(
        description = "A mesh file (OBJ, STL ASCII/binary, PLY ASCII/binary little-endian, \
                       legacy ASCII VTK polydata), a NIfTI-1 label volume (.nii or .nii.gz; \
                       application/x-nifti, or any type with ?format=nifti) that becomes a \
                       closed surface, or multipart/form-data with one `file` part per file",
        content(
            (MeshFile = "model/obj"), (MeshFile = "model/stl"),
            (MeshFile = "application/x-ply"), (MeshFile = "application/vnd.vtk"),
            (MeshFile = "application/x-nifti"), (MeshFile = "application/gzip"),
            (MeshFiles = "multipart/form-data"),
        )
    ),
    responses(
        (status = 201, description = "Stored: the mesh record (raw upload) or {meshes: [...]} (multipart)", body = UploadResponse),
        (status = 404, description = "No such dataset", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The dataset already holds this geometry", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "Body, mesh or volume too large (`mesh.too_large`, `nifti.too_large`)", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Unknown format (`mesh.unsupported_format`, `nifti.unsupported_format`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "The file is not a usable mesh or label volume (`mesh.*`, `nifti.parse_error`, `nifti.unsupported_datatype`, `nifti.empty_label`, ...)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn upload_meshes(
    State(state): State<AppState>,
    Path(dataset_id): Path<String>,
    Query(query): Query<UploadQuery>,
    request: Request,
) -> Result<Response, ApiError> {
    let dataset = state.store.dataset(&dataset_id).await?;
    let conversion = conversion(&state, &query, dataset.target_vertices)?;
    let ct = content_type(request.headers()).map(str::to_owned);
    let multipart = ct
        .as_deref()
        .is_some_and(|c| c.to_ascii_lowercase().starts_with("multipart/form-data"));
    if multipart {
        let files = read_multipart(&state, &query, request).await?;
        let records = store_files(&state, &dataset_id, conversion, files).await?;
        let body = UploadResponse::Many(UploadedMeshes { meshes: records });
        return Ok((StatusCode::CREATED, Json(body)).into_response());
    }
    let kind = match (&query.format, ct.as_deref()) {
        (Some(f), _) => parse_input_kind(f)?,
        (None, Some(c)) => {
            InputKind::from_content_type(c).ok_or_else(|| unsupported_content_type(Some(c)))?
        }
        (None, None) => return Err(unsupported_content_type(None)),
    };
    let bytes = Bytes::from_request(request, &state).await?;
    let name = query.name.clone().unwrap_or_default();
    if !name.is_empty() {
        check_name(&name)?;
    }
    let file = UploadedFile { name, kind, bytes };
    let mut records = store_files(&state, &dataset_id, conversion, vec![file]).await?;
    let record = records
        .pop()
        .ok_or_else(|| ApiError::internal("the upload stored no mesh"))?;
    let mut headers = HeaderMap::new();
    if let Ok(location) = HeaderValue::from_str(&format!("/v1/meshes/{}", record.id)) {
        headers.insert(header::LOCATION, location);
    }
    Ok((
        StatusCode::CREATED,
        headers,
        Json(UploadResponse::One(Box::new(record))),
    )
        .into_response())
}

/// The parameters of an upload, checked before the body is read.
fn conversion(
    state: &AppState,
    query: &UploadQuery,
    dataset_target: Option<i64>,
) -> Result<Conversion, ApiError> {
    let target = query.target_vertices.or(dataset_target);
    if let Some(t) = target {
        super::datasets::check_target_vertices(t, state.max_vertices)?;
    }
    Ok(Conversion {
        ingest: state.ingest_options(),
        segmentation: query.segmentation()?,
        limits: segmentation::Limits::default(),
        target_vertices: target.map(|t| t as usize),
        laterality: query
            .laterality
            .as_deref()
            .map(parse_laterality)
            .transpose()?,
    })
}

/// A side named in a request.
fn parse_laterality(name: &str) -> Result<Laterality, ApiError> {
    name.parse()
        .map_err(|e| ApiError::invalid_field("laterality", format!("laterality: {e}")))
}

/// Converts every file off the async runtime, then stores them in one transaction.
async fn store_files(
    state: &AppState,
    dataset_id: &str,
    conversion: Conversion,
    files: Vec<UploadedFile>,
) -> Result<Vec<MeshRecord>, ApiError> {
    let meshes = convert_all(conversion, files).await?;
    Ok(state.store.insert_meshes(dataset_id, meshes).await?)
}

/// List a dataset's meshes in upload order.
#[utoipa::path(
    get, path = "/v1/datasets/{id}/meshes", tag = "meshes",
    params(("id" = String, Path, description = "Dataset id"), PageQuery),
    responses(
        (status = 200, description = "A page of meshes", body = Paginated<MeshRecord>),
        (status = 404, description = "No such dataset", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn list_meshes(
    State(state): State<AppState>,
    Path(dataset_id): Path<String>,
    Query(query): Query<PageQuery>,
) -> Result<Json<Paginated<MeshRecord>>, ApiError> {
    let page = query.page()?;
    let (items, total) = state.store.meshes(&dataset_id, page).await?;
    Ok(Json(Paginated::new(items, total, page)))
}

/// Get a mesh's metadata.
#[utoipa::path(
    get, path = "/v1/meshes/{id}", tag = "meshes",
    params(("id" = String, Path, description = "Mesh id")),
    responses(
        (status = 200, description = "The mesh record", body = MeshRecord),
        (status = 404, description = "No such mesh", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<MeshRecord>, ApiError> {
    Ok(Json(state.store.mesh(&id).await?))
}

/// Changes to a mesh's metadata (the geometry never changes).
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MeshUpdate {
    /// The side of a paired organ, `left` or `right`; `null` clears it. Models fitted
    /// before keep the sides they were fitted with.
    #[serde(default, deserialize_with = "present")]
    #[schema(value_type = Option<crate::mesh::Laterality>, nullable)]
    pub laterality: Option<Option<String>>,
}

/// Some(value) for a field present in the body, even when it is `null`.
fn present<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Option<String>>, D::Error> {
    Option::<String>::deserialize(d).map(Some)
}

/// Set or clear a mesh's side.
#[utoipa::path(
    patch, path = "/v1/meshes/{id}", tag = "meshes",
    params(("id" = String, Path, description = "Mesh id")),
    request_body = MeshUpdate,
    responses(
        (status = 200, description = "The updated mesh record", body = MeshRecord),
        (status = 404, description = "No such mesh", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Not a side (`request.invalid_field`) or an unknown field", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn update_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Json(update): Json<MeshUpdate>,
) -> Result<Json<MeshRecord>, ApiError> {
    let Some(laterality) = update.laterality else {
        return Ok(Json(state.store.mesh(&id).await?));
    };
    let laterality = laterality.as_deref().map(parse_laterality).transpose()?;
    Ok(Json(
        state.store.set_mesh_laterality(&id, laterality).await?,
    ))
}

/// Delete a mesh.
#[utoipa::path(
    delete, path = "/v1/meshes/{id}", tag = "meshes",
    params(("id" = String, Path, description = "Mesh id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 404, description = "No such mesh", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn delete_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    state.store.delete_mesh(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// Download a mesh in any supported format.
#[utoipa::path(
    get, path = "/v1/meshes/{id}/file", tag = "meshes",
    params(("id" = String, Path, description = "Mesh id"), DownloadQuery),
    responses(
        (status = 200, description = "The mesh file", content(
            (MeshFile = "model/obj"), (MeshFile = "model/stl"),
            (MeshFile = "application/x-ply"), (MeshFile = "application/vnd.vtk"))),
        (status = 404, description = "No such mesh", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Unknown format", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_mesh(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(query): Query<DownloadQuery>,
) -> Result<Response, ApiError> {
    let format = match &query.format {
        Some(f) => parse_format("format", f)?,
        None => Format::Obj,
    };
    let record = state.store.mesh(&id).await?;
    let geometry = state.store.mesh_geometry(&id).await?;
    let bytes = tokio::task::spawn_blocking(move || mesh::io::write(&geometry, format))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?;
    Ok(mesh_file_response(&record.name, format, bytes))
}

/// A mesh file as an attachment named after the mesh.
pub(crate) fn mesh_file_response(name: &str, format: Format, bytes: Vec<u8>) -> Response {
    file_response(
        bytes,
        format.content_type(),
        "attachment",
        &format!("{name}.{}", format.extension()),
    )
}

/// `bytes` served as `content_type` with a `Content-Disposition` of `disposition`
/// (`attachment` or `inline`) and `file_name`, whose characters outside `[A-Za-z0-9-_.]`
/// become `_`.
pub(crate) fn file_response(
    bytes: Vec<u8>,
    content_type: &'static str,
    disposition: &str,
    file_name: &str,
) -> Response {
    let safe: String = file_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    let disposition = format!("{disposition}; filename=\"{safe}\"");
    let mut response = bytes.into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    if let Ok(value) = HeaderValue::from_str(&disposition) {
        headers.insert(header::CONTENT_DISPOSITION, value);
    }
    response
}
