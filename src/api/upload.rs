//! Turning uploaded files into meshes to store: surface meshes are validated, NIfTI label
//! volumes become surfaces, and either may be simplified. Runs off the async runtime.

use axum::body::Bytes;
use axum::extract::{FromRequest, Multipart, Request};
use axum::http::StatusCode;
use serde_json::{Map, Value, json};

use super::AppState;
use super::error::ApiError;
use super::meshes::UploadQuery;
use crate::mesh::simplify::simplify;
use crate::mesh::validate::{IngestOptions, Ingested, validate};
use crate::mesh::{self, Format, Laterality};
use crate::segmentation::{self, NiftiError, Options};
use crate::store::meshes::{NewMesh, format_name};

/// Media type of NIfTI-1 uploads (`.nii` or `.nii.gz`).
pub const NIFTI_CONTENT_TYPE: &str = "application/x-nifti";
/// `source_format` of meshes made from label volumes.
pub const NIFTI_SOURCE_FORMAT: &str = "nifti";

/// What an uploaded file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A surface mesh file.
    Mesh(Format),
    /// A NIfTI-1 label volume, gzip-compressed or not.
    Nifti,
}

impl InputKind {
    /// From a `?format=` value: a mesh format or `nifti`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "nifti" | "nii" | "nii.gz" => Some(InputKind::Nifti),
            other => Format::from_name(other).map(InputKind::Mesh),
        }
    }

    /// From a Content-Type (`application/x-nifti`, or a mesh type).
    pub fn from_content_type(content_type: &str) -> Option<Self> {
        let essence = content_type.split(';').next().unwrap_or_default().trim();
        if essence.eq_ignore_ascii_case(NIFTI_CONTENT_TYPE) {
            return Some(InputKind::Nifti);
        }
        Format::from_content_type(content_type).map(InputKind::Mesh)
    }

    /// From a file name: `*.nii`, `*.nii.gz`, or a mesh extension.
    pub fn from_file_name(name: &str) -> Option<Self> {
        let lower = name.to_ascii_lowercase();
        if lower.ends_with(".nii") || lower.ends_with(".nii.gz") {
            return Some(InputKind::Nifti);
        }
        Format::from_file_name(name).map(InputKind::Mesh)
    }
}

/// A file of the request before parsing.
pub struct UploadedFile {
    /// Mesh name (empty: named after its checksum).
    pub name: String,
    /// What the bytes hold.
    pub kind: InputKind,
    /// The file.
    pub bytes: Bytes,
}

/// How the files of one upload are turned into meshes.
#[derive(Debug, Clone)]
pub struct Conversion {
    /// Validation of the surfaces.
    pub ingest: IngestOptions,
    /// Label volume parameters (NIfTI files).
    pub segmentation: Options,
    /// Label volume size limits.
    pub limits: segmentation::Limits,
    /// Simplify every mesh to about this many vertices.
    pub target_vertices: Option<usize>,
    /// The side of every mesh of the upload, when the user gave it.
    pub laterality: Option<Laterality>,
}

impl From<NiftiError> for ApiError {
    fn from(err: NiftiError) -> Self {
        let status = match err.code() {
            "nifti.too_large" => StatusCode::PAYLOAD_TOO_LARGE,
            "nifti.unsupported_format" => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            _ => StatusCode::UNPROCESSABLE_ENTITY,
        };
        match err {
            NiftiError::Mesh(e) => ApiError::from(e),
            NiftiError::InvalidOption(e) => ApiError::invalid_field(e.field, e.message),
            other => ApiError::new(status, other.code(), other.to_string()),
        }
    }
}

pub(super) fn parse_input_kind(name: &str) -> Result<InputKind, ApiError> {
    InputKind::from_name(name).ok_or_else(|| {
        ApiError::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "mesh.unsupported_format",
            format!(
                "format '{name}' is not a supported upload format; use obj, stl, ply, vtk or nifti"
            ),
        )
        .with("field", "format")
    })
}

pub(super) fn unsupported_content_type(found: Option<&str>) -> ApiError {
    ApiError::new(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "mesh.unsupported_format",
        format!(
            "cannot tell the file format from Content-Type {}; send model/obj, model/stl, \
             application/x-ply, application/vnd.vtk or application/x-nifti, add \
             ?format=obj|stl|ply|vtk|nifti, or upload multipart/form-data",
            found.map_or("(none)".to_owned(), |c| format!("'{c}'"))
        ),
    )
}

/// The `file` parts of a multipart upload, each with its kind and name.
pub(super) async fn read_multipart(
    state: &AppState,
    query: &UploadQuery,
    request: Request,
) -> Result<Vec<UploadedFile>, ApiError> {
    let default_kind = query.format.as_deref().map(parse_input_kind).transpose()?;
    let mut multipart = Multipart::from_request(request, state).await.map_err(|r| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            "request.unreadable_body",
            r.body_text(),
        )
    })?;
    let mut files = Vec::new();
    while let Some(field) = multipart.next_field().await? {
        let part = files.len();
        let field_name = field.name().unwrap_or_default().to_owned();
        if !matches!(field_name.as_str(), "file" | "files" | "file[]" | "files[]") {
            return Err(ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "request.unexpected_part",
                format!(
                    "multipart part '{field_name}' is not expected; send each file as a part named 'file'"
                ),
            ));
        }
        let file_name = field.file_name().unwrap_or_default().to_owned();
        let kind = InputKind::from_file_name(&file_name)
            .or_else(|| field.content_type().and_then(InputKind::from_content_type))
            .or(default_kind)
            .ok_or_else(|| {
                unsupported_content_type(field.content_type())
                    .with("part", part)
                    .with("filename", file_name.clone())
            })?;
        let name = file_stem(&file_name);
        if !name.is_empty() {
            super::meshes::check_name(&name)?;
        }
        let bytes = field.bytes().await?;
        files.push(UploadedFile { name, kind, bytes });
    }
    if files.is_empty() {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.no_files",
            "the multipart body holds no 'file' part; attach at least one mesh or NIfTI file",
        ));
    }
    Ok(files)
}

/// The file name without directories and extension (`.nii.gz` counts as one).
fn file_stem(file_name: &str) -> String {
    let base = file_name.rsplit(['/', '\\']).next().unwrap_or_default();
    let base = match base.len().checked_sub(".gz".len()) {
        Some(cut) if base.to_ascii_lowercase().ends_with(".nii.gz") => &base[..cut],
        _ => base,
    };
    match base.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_owned(),
        _ => base.to_owned(),
    }
}

/// Converts every file off the async runtime; the first failure fails the batch.
pub async fn convert_all(
    conversion: Conversion,
    files: Vec<UploadedFile>,
) -> Result<Vec<NewMesh>, ApiError> {
    let count = files.len();
    tokio::task::spawn_blocking(move || {
        files
            .into_iter()
            .enumerate()
            .map(|(part, file)| {
                let name = file.name.clone();
                convert(&conversion, file).map_err(|err| {
                    if count > 1 {
                        err.with("part", part).with("filename", name)
                    } else {
                        err
                    }
                })
            })
            .collect()
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?
}

/// One file to a mesh ready to store.
fn convert(conversion: &Conversion, file: UploadedFile) -> Result<NewMesh, ApiError> {
    let (ingested, source_format, mut source) = match file.kind {
        InputKind::Mesh(format) => {
            let ingested = mesh::validate::ingest(&file.bytes, format, &conversion.ingest)?;
            (ingested, format_name(format), Map::new())
        }
        InputKind::Nifti => {
            let made = segmentation::volume_to_mesh(
                &file.bytes,
                &conversion.segmentation,
                &conversion.limits,
                &conversion.ingest,
            )?;
            let source = match serde_json::to_value(&made.source) {
                Ok(Value::Object(map)) => map,
                _ => return Err(ApiError::internal("the NIfTI source did not serialise")),
            };
            (made.ingested, NIFTI_SOURCE_FORMAT.to_owned(), source)
        }
    };
    let ingested = match conversion.target_vertices {
        Some(target) if target < ingested.summary.vertex_count => {
            let (simplified, record) = simplified(ingested, target, &conversion.ingest)?;
            source.insert("simplification".into(), record);
            simplified
        }
        _ => ingested,
    };
    let name = if file.name.is_empty() {
        format!("mesh_{}", &mesh::codec::sha256_hex(&ingested.mesh)[..12])
    } else {
        file.name
    };
    Ok(NewMesh {
        name,
        source_format,
        ingested,
        source: (!source.is_empty()).then_some(Value::Object(source)),
        laterality: conversion.laterality,
    })
}

/// Simplifies and validates again; the record keeps the vertex count of the upload.
fn simplified(
    ingested: Ingested,
    target: usize,
    ingest: &IngestOptions,
) -> Result<(Ingested, Value), ApiError> {
    let before = &ingested.summary;
    let result = simplify(&ingested.mesh, target)?;
    let mut after = validate(result.mesh, ingest)?;
    let record = json!({
        "method": "quadric_edge_collapse",
        "target_vertices": target,
        "vertex_count_before": before.vertex_count,
        "face_count_before": before.face_count,
        "volume_ml_before": before.volume_ml,
        "area_cm2_before": before.area_cm2,
    });
    after.summary.original_vertex_count = before.original_vertex_count;
    Ok((after, record))
}
