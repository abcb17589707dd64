//! Pictures of shapes (PNG): `GET /v1/models/{id}/renders/{name}`,
//! `GET /v1/cohorts/{id}/renders/members` and `GET /v1/cohorts/{id}/members/{index}/render`.

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::Response;
use serde::Deserialize;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Path, Query};
use super::meshes::file_response;
use super::models::load_model;
use super::plots::PlotImage;
use crate::geometry::bvh::TriangleBvh;
use crate::mesh::{Laterality, Mesh};
use crate::models::StoredModel;
use crate::models::shape_modes::shape_modes;
use crate::report::render::pictures::{self, DEFAULT_PANEL_PX};
use crate::report::render::{PANEL_PX, RenderError, View};

/// Modes drawn per cluster.
const MODES_SHOWN: usize = 3;
/// Members drawn when no indices are given.
const DEFAULT_MEMBERS: usize = 8;
/// Most members on one picture.
pub const MAX_MEMBERS: usize = 32;

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(model_render))
        .routes(routes!(members_render))
        .routes(routes!(member_render))
}

/// View and size of a picture.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct RenderQuery {
    /// `anterior` (from −y), `lateral` (from +x) or `superior` (from +z); default: all
    /// three side by side (one view, anterior, for grids of modes and members).
    #[param(value_type = Option<super::vocabulary::ViewName>, inline)]
    pub view: Option<String>,
    /// Side of each panel in px, 48–1024 (default 240).
    #[param(minimum = 48, maximum = 1024)]
    pub size: Option<u32>,
    /// Members of a grid: comma-separated indices (default the first 8; at most 32).
    #[param(pattern = r"^[0-9]+(,[0-9]+)*$")]
    pub indices: Option<String>,
}

impl RenderQuery {
    fn view(&self) -> Result<Option<View>, ApiError> {
        self.view
            .as_deref()
            .map(|name| {
                View::parse(name).ok_or_else(|| {
                    ApiError::invalid_field(
                        "view",
                        format!("view '{name}' is not one of anterior, lateral, superior"),
                    )
                })
            })
            .transpose()
    }

    fn size(&self) -> Result<u32, ApiError> {
        let size = self.size.unwrap_or(DEFAULT_PANEL_PX);
        let (lo, hi) = PANEL_PX;
        if (lo..=hi).contains(&size) {
            Ok(size)
        } else {
            Err(ApiError::invalid_field(
                "size",
                format!("size must be between {lo} and {hi} px, got {size}"),
            ))
        }
    }

    fn indices(&self, size: usize) -> Result<Vec<usize>, ApiError> {
        let Some(list) = self.indices.as_deref() else {
            return Ok((0..size.min(DEFAULT_MEMBERS)).collect());
        };
        let indices = list
            .split(',')
            .map(|s| s.trim().parse::<usize>().ok().filter(|i| *i < size))
            .collect::<Option<Vec<_>>>()
            .filter(|v| !v.is_empty() && v.len() <= MAX_MEMBERS)
            .ok_or_else(|| {
                ApiError::invalid_field(
                    "indices",
                    format!(
                        "indices must be 1–{MAX_MEMBERS} comma-separated member indices below {size}, got '{list}'"
                    ),
                )
            })?;
        Ok(indices)
    }
}

fn png_response(stem: &str, bytes: Vec<u8>) -> Response {
    file_response(bytes, "image/png", "inline", &format!("{stem}.png"))
}

fn render_failed(e: RenderError) -> ApiError {
    match e {
        RenderError::Layout(detail) => ApiError::invalid_field("size", detail),
        RenderError::Png(e) => ApiError::internal(e.to_string()),
    }
}

/// Runs a picture off the async runtime.
async fn off_runtime(
    f: impl FnOnce() -> Result<Vec<u8>, ApiError> + Send + 'static,
) -> Result<Vec<u8>, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
}

/// The render names a model offers.
pub(super) fn render_names(stored: &StoredModel, holdout: usize) -> Vec<String> {
    let atlases = stored.model.atlases().len();
    let mut names = vec!["atlas".to_owned()];
    if atlases > 1 {
        names.extend((0..atlases).map(|m| format!("atlas_{m}")));
    }
    if stored.model.standard_latent().is_some() {
        names.push("modes".to_owned());
    }
    names.extend((0..holdout).map(|k| format!("reconstruction_{k}")));
    names
}

/// A model's picture `name` as PNG (see [`model_render`]).
pub(super) async fn model_picture(
    state: &AppState,
    id: &str,
    name: &str,
    view: Option<View>,
    size: u32,
) -> Result<Vec<u8>, ApiError> {
    let (stored, _) = load_model(state, id).await?;
    let holdout_ids = state.store.model(id).await?.provenance.holdout_mesh_ids;
    let names = render_names(&stored, holdout_ids.len());
    if !names.iter().any(|n| n == name) {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "render.not_found",
            format!(
                "model {id} has no picture '{name}'; available: {}",
                names.join(", ")
            ),
        )
        .with("available", names));
    }
    let title = format!("{} · model {id}", name.replace('_', " "));
    if let Some(k) = name.strip_prefix("reconstruction_") {
        let k: usize = k.parse().map_err(|_| ApiError::internal("render name"))?;
        let mesh = state.store.mesh_geometry(&holdout_ids[k]).await?;
        let laterality = state.store.mesh(&holdout_ids[k]).await?.laterality;
        let mesh_id = holdout_ids[k].clone();
        return off_runtime(move || {
            let title = format!("held-out mesh {mesh_id} and its reconstruction");
            reconstruction_picture(&stored, &mesh, laterality, &title, view, size)
        })
        .await;
    }
    let name = name.to_owned();
    off_runtime(move || {
        let model = stored.model.as_ref();
        let atlases: Vec<(usize, &Mesh)> = model.atlases().iter().enumerate().collect();
        let chosen = match name.strip_prefix("atlas_") {
            Some(m) => m.parse::<usize>().ok().and_then(|m| atlases.get(m..=m)),
            None => Some(&atlases[..]),
        };
        if name == "modes" {
            let modes = shape_modes(model, MODES_SHOWN, 0)
                .map_err(|e| ApiError::internal(e.to_string()))?;
            return pictures::modes(&title, &modes, view.unwrap_or_default(), size)
                .map_err(render_failed);
        }
        let chosen = chosen.ok_or_else(|| ApiError::internal("render name"))?;
        pictures::atlases(&title, chosen, view, size).map_err(render_failed)
    })
    .await
}

/// The held-out `mesh` (of the side the user gave, if any) in the model frame beside its
/// reconstruction coloured by the distance of each reconstruction vertex to the held-out
/// surface.
fn reconstruction_picture(
    stored: &StoredModel,
    mesh: &Mesh,
    laterality: Option<Laterality>,
    title: &str,
    view: Option<View>,
    size: u32,
) -> Result<Vec<u8>, ApiError> {
    let unreadable = |e: crate::models::ModelError| {
        ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, e.code(), e.to_string())
    };
    let r = stored
        .model
        .reconstruct(mesh, laterality)
        .map_err(unreadable)?;
    let held_out = Mesh::new(r.aligned_input, mesh.faces.clone());
    let surface = TriangleBvh::new(&held_out.vertices, &held_out.faces)
        .map_err(|e| ApiError::internal(e.to_string()))?;
    let errors: Vec<f64> = r
        .mesh
        .vertices
        .iter()
        .map(|p| surface.closest(*p).distance)
        .collect();
    pictures::reconstruction(title, &held_out, &r.mesh, &errors, view, size).map_err(render_failed)
}

/// A picture of a model: its atlases, its modes or a reconstruction.
///
/// Names: `atlas` (every atlas), `atlas_{m}` (one atlas of a multi-atlas model), `modes`
/// (PCA models: the mean ± 3√λ along the first three modes; latent models: the mean code
/// ± 2 sd along the three latent directions of largest biomarker effect, per cluster) and
/// `reconstruction_{k}` (held-out mesh `k` beside its reconstruction, coloured by the
/// distance of each vertex to the held-out surface in mm). An unknown name is a 404
/// `render.not_found` whose `available` lists the names. Deterministic: the same request
/// gives the same bytes.
#[utoipa::path(
    get, path = "/v1/models/{id}/renders/{name}", tag = "models",
    params(
        ("id" = String, Path, description = "Model id"),
        ("name" = String, Path, description = "Picture name, e.g. `atlas`"),
        RenderQuery,
    ),
    responses(
        (status = 200, description = "The picture", content((PlotImage = "image/png"))),
        (status = 404, description = "No such model (`model.not_found`) or picture (`render.not_found`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid view or size (`request.invalid_field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn model_render(
    State(state): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    Query(query): Query<RenderQuery>,
) -> Result<Response, ApiError> {
    let (view, size) = (query.view()?, query.size()?);
    let png = model_picture(&state, &id, &name, view, size).await?;
    Ok(png_response(&format!("model-{id}-{name}"), png))
}

/// Members `indices` of a cohort in one view (anterior unless asked otherwise), as PNG.
pub(super) async fn members_picture(
    state: &AppState,
    id: &str,
    indices: &[usize],
    view: Option<View>,
    size: u32,
) -> Result<Vec<u8>, ApiError> {
    let cohort = state.store.cohort_head(id).await?;
    let wanted: Vec<i64> = indices.iter().map(|&i| i as i64).collect();
    let meshes: Vec<(usize, Mesh)> = indices
        .iter()
        .copied()
        .zip(super::cohort_files::member_shapes_of(state, &cohort, &wanted).await?)
        .collect();
    let title = format!("cohort {id}");
    off_runtime(move || {
        let members: Vec<(usize, &Mesh)> = meshes.iter().map(|(i, m)| (*i, m)).collect();
        pictures::members(&title, &members, view, size).map_err(render_failed)
    })
    .await
}

/// A grid of cohort members.
///
/// The first 8 members, or those of `indices`, in one view, at one scale.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/renders/members", tag = "cohorts",
    params(("id" = String, Path, description = "Cohort id"), RenderQuery),
    responses(
        (status = 200, description = "The picture", content((PlotImage = "image/png"))),
        (status = 404, description = "No such cohort (`cohort.not_found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The cohort is not drawn (`cohort.not_ready`), or a member no longer comes out of its model as first drawn (`cohort.not_reproducible`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid view, size or indices (`request.invalid_field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn members_render(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(query): Query<RenderQuery>,
) -> Result<Response, ApiError> {
    let (view, size) = (query.view()?, query.size()?);
    let count = state.store.cohort(&id).await?.members.len();
    let indices = query.indices(count)?;
    let png = members_picture(&state, &id, &indices, view, size).await?;
    Ok(png_response(&format!("cohort-{id}-members"), png))
}

/// A picture of one cohort member: the three views, or the one asked for.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/members/{index}/render", tag = "cohorts",
    params(
        ("id" = String, Path, description = "Cohort id"),
        ("index" = i64, Path, description = "Member index, from 0"),
        RenderQuery,
    ),
    responses(
        (status = 200, description = "The picture", content((PlotImage = "image/png"))),
        (status = 404, description = "No such cohort or member", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The cohort is not drawn (`cohort.not_ready`), or a member no longer comes out of its model as first drawn (`cohort.not_reproducible`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid view or size (`request.invalid_field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn member_render(
    State(state): State<AppState>,
    Path((id, index)): Path<(String, i64)>,
    Query(query): Query<RenderQuery>,
) -> Result<Response, ApiError> {
    let (view, size) = (query.view()?, query.size()?);
    let Ok(index) = usize::try_from(index) else {
        // The store's own "no such member" answer.
        state.store.cohort_member_geometry(&id, index).await?;
        return Err(ApiError::internal("a negative member index was found"));
    };
    let png = members_picture(&state, &id, &[index], view, size).await?;
    Ok(png_response(&format!("cohort-{id}-member-{index:05}"), png))
}
