//! `/v1/models`: fitted models with provenance and evaluation; atlases listed and
//! downloaded.

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::Response;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Json, PageQuery, Paginated, Path, Query};
use super::meshes::{MeshFile, mesh_file_response, parse_format};
use crate::mesh::{self, Format};
use crate::models::clusters::winning_cluster;
use crate::models::{ClusterSummary, StoredModel};
use crate::store::models::{ModelRecord, Provenance};

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(list_models))
        .routes(routes!(get_model, delete_model))
        .routes(routes!(download_atlas))
        .routes(routes!(list_atlases))
        .routes(routes!(download_atlas_at))
}

/// A fitted model.
#[derive(Debug, Serialize, ToSchema)]
pub struct ModelView {
    /// Identifier.
    pub id: String,
    /// Model type, e.g. `rsmp`.
    pub model_type: String,
    /// Parameters with defaults filled in.
    #[schema(value_type = Object)]
    pub params: serde_json::Value,
    /// Seed of the fit.
    pub seed: u64,
    /// Dataset it was fitted to.
    pub dataset_id: String,
    /// Job that fitted it.
    pub job_id: String,
    /// Training and held-out meshes with their checksums.
    pub provenance: Provenance,
    /// The first atlas (template).
    #[schema(value_type = crate::models::AtlasInfo)]
    pub atlas: serde_json::Value,
    /// Every atlas (one for single-atlas models), each with its own connectivity.
    pub atlases: Vec<AtlasView>,
    /// The clusters: each atlas with its prior, and every training and held-out mesh with
    /// its soft weights over the atlases and its winning cluster (single-atlas models: one
    /// atlas of prior 1, every mesh in cluster 0).
    pub clusters: ClustersView,
    /// Quality in mm: `generalisation`, `specificity`, `matching`, each `{hd, ed, ed_star, cd}`
    /// of `{mean, std}`; generalisation and matching on the held-out meshes.
    #[schema(value_type = crate::models::Evaluation)]
    pub evaluation: serde_json::Value,
    /// Cumulative explained variance per mode (PCA models).
    #[schema(value_type = Option<Vec<f64>>)]
    pub explained_variance: serde_json::Value,
    /// Modes kept (PCA models).
    #[schema(value_type = Option<u64>)]
    pub n_modes: serde_json::Value,
    /// Training meshes used.
    #[schema(value_type = u64)]
    pub training_count: serde_json::Value,
    /// Held-out meshes evaluated.
    #[schema(value_type = u64)]
    pub holdout_count: serde_json::Value,
    /// Seconds per stage of the fit.
    #[schema(value_type = Vec<crate::models::StageTiming>)]
    pub timings: serde_json::Value,
    /// How a seeded cohort of 1,000 drawn at the end of the fit spreads against the training
    /// meshes: per biomarker the means, sds, their ratios and the KS statistic, the near
    /// copies, the joint A^μ beside what a Gaussian with the training biomarkers' mean and
    /// covariance reaches, and a note when the population is too small. Absent for models
    /// fitted before it was measured.
    #[schema(value_type = Option<crate::models::spread::FidelitySummary>)]
    #[serde(skip_serializing_if = "serde_json::Value::is_null")]
    pub fidelity: serde_json::Value,
    /// How each generator's KL weight β was chosen on held-out folds of its training shapes
    /// (models of the ASMG family fitted on fewer than 50 shapes); absent when β was used as
    /// given.
    #[schema(value_type = Option<Vec<crate::models::beta_choice::BetaChoice>>)]
    #[serde(skip_serializing_if = "serde_json::Value::is_null")]
    pub beta_choices: serde_json::Value,
    /// The training meshes registered as their mirror images (`mirror`: left and right
    /// organs all learned on the side of the alignment reference, which every member takes);
    /// absent when none was.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub mirrored_mesh_ids: Vec<String>,
    /// With `mirror`, the side every shape of the model and every cohort member has (the
    /// alignment reference's), when the training meshes' sides were given (`laterality` of a
    /// mesh); absent otherwise.
    #[schema(value_type = Option<crate::mesh::Laterality>)]
    #[serde(skip_serializing_if = "serde_json::Value::is_null")]
    pub laterality: serde_json::Value,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
}

/// One atlas of a model.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct AtlasView {
    /// Position among the model's atlases, from 0 (the cluster index of its members).
    pub index: usize,
    /// Vertices.
    pub vertex_count: usize,
    /// Triangles.
    pub face_count: usize,
    /// V − E + F: 2 for a closed genus-0 surface, 0 for genus 1; absent for models stored
    /// before it was recorded.
    pub euler_characteristic: Option<i64>,
    /// Where to download it (`?format=obj|stl|ply|vtk`).
    pub href: String,
}

/// An atlas as a cluster.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ClusterAtlasView {
    /// Atlas index.
    pub index: usize,
    /// Vertices.
    pub vertex_count: usize,
    /// V − E + F.
    pub euler_characteristic: Option<i64>,
    /// Probability that a draw comes from this cluster.
    pub prior: f64,
    /// Effective number of training meshes its generator learned from (Kish's effective
    /// sample size of its weights, `(Σ_k w_km)² / Σ_k w_km²`; its member count when every
    /// weight is 0 or 1). A mesh weighted into several clusters counts in each, so the
    /// clusters' figures can add up to more than the training meshes. Below 10 the generator
    /// mostly reproduces its meshes.
    pub effective_meshes: f64,
}

/// One mesh's membership.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct AssignmentView {
    /// The training or held-out mesh.
    pub mesh_id: String,
    /// Soft weight of each atlas (sum 1).
    pub weights: Vec<f64>,
    /// The atlas of largest weight.
    pub cluster: usize,
}

/// The model's clusters.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ClustersView {
    /// Each atlas with its prior.
    pub atlases: Vec<ClusterAtlasView>,
    /// Every training and held-out mesh.
    pub assignments: Vec<AssignmentView>,
    /// Said when a cluster's generator learns from fewer than 10 training meshes' worth of
    /// weight, with what to do about it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// The clusters recorded in the summary, or, for models with one atlas (which record
/// none), that atlas with prior 1 and every mesh in it.
fn clusters_of(
    summary: &serde_json::Value,
    atlases: &[AtlasView],
    provenance: &Provenance,
) -> ClustersView {
    let recorded = summary
        .get("clusters")
        .and_then(|c| serde_json::from_value::<ClusterSummary>(c.clone()).ok())
        .unwrap_or_else(|| {
            let all_in_first = |n: usize| vec![vec![1.0]; n];
            ClusterSummary {
                priors: vec![1.0],
                training: all_in_first(provenance.training_mesh_ids.len()),
                holdout: all_in_first(provenance.holdout_mesh_ids.len()),
            }
        });
    let ids = provenance
        .training_mesh_ids
        .iter()
        .zip(&recorded.training)
        .chain(provenance.holdout_mesh_ids.iter().zip(&recorded.holdout));
    let effective = recorded.effective_meshes();
    ClustersView {
        atlases: atlases
            .iter()
            .map(|a| ClusterAtlasView {
                index: a.index,
                vertex_count: a.vertex_count,
                euler_characteristic: a.euler_characteristic,
                prior: recorded.priors.get(a.index).copied().unwrap_or(0.0),
                effective_meshes: effective.get(a.index).copied().unwrap_or(0.0),
            })
            .collect(),
        note: recorded.thin_cluster_note(),
        assignments: ids
            .map(|(id, weights)| AssignmentView {
                mesh_id: id.clone(),
                weights: weights.clone(),
                cluster: winning_cluster(weights),
            })
            .collect(),
    }
}

/// The atlases recorded in a model's summary (models stored before several atlases existed
/// record only `atlas`).
fn atlases_of(id: &str, summary: &serde_json::Value) -> Vec<AtlasView> {
    let listed = summary
        .get("atlases")
        .and_then(serde_json::Value::as_array)
        .filter(|a| !a.is_empty())
        .cloned()
        .or_else(|| summary.get("atlas").map(|a| vec![a.clone()]))
        .unwrap_or_default();
    listed
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let count =
                |k: &str| a.get(k).and_then(serde_json::Value::as_u64).unwrap_or(0) as usize;
            AtlasView {
                index: i,
                vertex_count: count("vertex_count"),
                face_count: count("face_count"),
                euler_characteristic: a
                    .get("euler_characteristic")
                    .and_then(serde_json::Value::as_i64),
                href: format!("/v1/models/{id}/atlases/{i}"),
            }
        })
        .collect()
}

/// The ids of the training meshes the summary lists as mirrored (by training position).
fn mirrored_of(summary: &serde_json::Value, provenance: &Provenance) -> Vec<String> {
    summary
        .get("mirrored_training")
        .and_then(serde_json::Value::as_array)
        .map(|positions| {
            positions
                .iter()
                .filter_map(serde_json::Value::as_u64)
                .filter_map(|k| provenance.training_mesh_ids.get(k as usize).cloned())
                .collect()
        })
        .unwrap_or_default()
}

impl From<ModelRecord> for ModelView {
    fn from(r: ModelRecord) -> Self {
        let field = |name: &str| {
            r.summary
                .get(name)
                .cloned()
                .unwrap_or(serde_json::Value::Null)
        };
        let atlases = atlases_of(&r.id, &r.summary);
        Self {
            clusters: clusters_of(&r.summary, &atlases, &r.provenance),
            atlases,
            atlas: field("atlas"),
            evaluation: field("evaluation"),
            explained_variance: field("explained_variance"),
            n_modes: field("n_modes"),
            training_count: field("training_count"),
            holdout_count: field("holdout_count"),
            timings: field("timings"),
            fidelity: field("fidelity"),
            beta_choices: field("beta_choices"),
            mirrored_mesh_ids: mirrored_of(&r.summary, &r.provenance),
            laterality: field("laterality"),
            id: r.id,
            model_type: r.model_type,
            params: r.params,
            seed: r.seed,
            dataset_id: r.dataset_id,
            job_id: r.job_id,
            provenance: r.provenance,
            created_at: r.created_at,
        }
    }
}

/// List models, newest first.
#[utoipa::path(
    get, path = "/v1/models", tag = "models", params(PageQuery),
    responses((status = 200, description = "A page of models", body = Paginated<ModelView>))
)]
async fn list_models(
    State(state): State<AppState>,
    Query(q): Query<PageQuery>,
) -> Result<Json<Paginated<ModelView>>, ApiError> {
    let page = q.page()?;
    let (items, total) = state.store.models(page).await?;
    Ok(Json(Paginated::new(
        items.into_iter().map(ModelView::from).collect(),
        total,
        page,
    )))
}

/// Get a model with its provenance and evaluation.
#[utoipa::path(
    get, path = "/v1/models/{id}", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 200, description = "The model", body = ModelView),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn get_model(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<ModelView>, ApiError> {
    Ok(Json(state.store.model(&id).await?.into()))
}

/// Delete a model and its cohorts.
#[utoipa::path(
    delete, path = "/v1/models/{id}", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn delete_model(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    state.store.delete_model(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// Query of a mesh download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct FormatQuery {
    /// Output format: `obj` (default), `stl`, `ply` or `vtk`.
    #[param(value_type = Option<super::vocabulary::MeshFormatName>, inline)]
    pub format: Option<String>,
}

impl FormatQuery {
    /// The requested format, OBJ by default.
    pub fn format(&self) -> Result<Format, ApiError> {
        self.format
            .as_deref()
            .map_or(Ok(Format::Obj), |f| parse_format("format", f))
    }
}

/// Loads and decodes a stored model off the async runtime.
pub(super) async fn load_model(
    state: &AppState,
    id: &str,
) -> Result<(StoredModel, serde_json::Value), ApiError> {
    let (payload, reference) = state.store.model_payload(id).await?;
    let model = tokio::task::spawn_blocking(move || StoredModel::from_bytes(&payload))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
        .map_err(|e| ApiError::unreadable_model(id, e))?;
    Ok((model, reference))
}

/// Download the model's first atlas (template) mesh: the same as `/atlases/0`.
#[utoipa::path(
    get, path = "/v1/models/{id}/atlas", tag = "models",
    params(("id" = String, Path, description = "Model id"), FormatQuery),
    responses(
        (status = 200, description = "The atlas mesh", content(
            (MeshFile = "model/obj"), (MeshFile = "model/stl"),
            (MeshFile = "application/x-ply"), (MeshFile = "application/vnd.vtk"))),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The model was stored in a format this release does not read", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_atlas(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    atlas_response(&state, &id, 0, &q).await
}

/// The model's atlases: one per cluster, each with its own connectivity.
#[utoipa::path(
    get, path = "/v1/models/{id}/atlases", tag = "models",
    params(("id" = String, Path, description = "Model id")),
    responses(
        (status = 200, description = "The atlases, in cluster order", body = Vec<AtlasView>),
        (status = 404, description = "No such model", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn list_atlases(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Vec<AtlasView>>, ApiError> {
    let record = state.store.model(&id).await?;
    Ok(Json(atlases_of(&record.id, &record.summary)))
}

/// Download atlas `m` of the model.
#[utoipa::path(
    get, path = "/v1/models/{id}/atlases/{m}", tag = "models",
    params(("id" = String, Path, description = "Model id"), ("m" = u32, Path, description = "Atlas index, from 0"), FormatQuery),
    responses(
        (status = 200, description = "The atlas mesh", content(
            (MeshFile = "model/obj"), (MeshFile = "model/stl"),
            (MeshFile = "application/x-ply"), (MeshFile = "application/vnd.vtk"))),
        (status = 404, description = "No such model or atlas", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The model was stored in a format this release does not read", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn download_atlas_at(
    State(state): State<AppState>,
    Path((id, m)): Path<(String, u32)>,
    Query(q): Query<FormatQuery>,
) -> Result<Response, ApiError> {
    atlas_response(&state, &id, m as usize, &q).await
}

async fn atlas_response(
    state: &AppState,
    id: &str,
    m: usize,
    q: &FormatQuery,
) -> Result<Response, ApiError> {
    let format = q.format()?;
    let (model, _) = load_model(state, id).await?;
    let atlases = model.model.atlases();
    let atlas = atlases.get(m).ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "atlas.not_found",
            format!(
                "model {id} has {} atlas(es), numbered from 0; atlas {m} does not exist",
                atlases.len()
            ),
        )
    })?;
    let bytes = mesh::io::write(atlas, format);
    let name = if m == 0 {
        format!("atlas_{id}")
    } else {
        format!("atlas_{m}_{id}")
    };
    Ok(mesh_file_response(&name, format, bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirrored_training_positions_become_mesh_ids() {
        let provenance = Provenance {
            training_mesh_ids: vec!["a".into(), "b".into(), "c".into()],
            holdout_mesh_ids: vec!["d".into()],
            training_sha256: Vec::new(),
            holdout_sha256: Vec::new(),
            training_laterality: Vec::new(),
            holdout_laterality: Vec::new(),
        };
        let summary = serde_json::json!({"mirrored_training": [0, 2]});
        assert_eq!(mirrored_of(&summary, &provenance), ["a", "c"]);
        // Models fitted without `mirror` (or before it) list none.
        assert!(mirrored_of(&serde_json::json!({}), &provenance).is_empty());
    }
}
