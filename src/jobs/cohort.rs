//! Cohort requests and the drawing of one cohort, shared by the request path (small cohorts
//! answered at once) and the worker pool (large or asynchronous ones).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use tokio::runtime::Handle;
use utoipa::ToSchema;

use super::run::RunError;
use crate::eval::acceptance::Flags;
use crate::eval::metrics::parallel_map;
use crate::geometry::pca::Sampling;
use crate::mesh::laterality::mirror_image;
use crate::mesh::{Laterality, Mesh, codec};
use crate::models::cohort::{
    CohortSpec, Criterion, Member, TrainingIndex, draw_shape, sample_cohort_given,
};
use crate::models::conditional::{Conditional, Target};
use crate::models::progress::Progress;
use crate::models::{ModelError, ReferencePopulation, ShapeModel, StoredModel};
use crate::store::Store;
use crate::store::cohorts::{MemberGeometry, NewMember};
use crate::store::jobs::Job;

/// Largest cohort.
pub const MAX_COHORT_SIZE: usize = 10_000;
/// Draws allowed per wanted member with `only_accepted`.
pub const DRAWS_PER_MEMBER: usize = 20;

/// Acceptance settings of a cohort request.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AcceptanceRequest {
    /// Criterion used by `only_accepted`: `range`, `mode` or `mean` (default).
    #[serde(default)]
    pub criterion: Criterion,
}

/// Body of `POST /v1/models/{id}/cohorts`.
#[derive(Debug, Clone, Deserialize, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CohortRequest {
    /// Members wanted (1–10,000).
    #[schema(minimum = 1, maximum = 10_000)]
    pub size: usize,
    /// Seed (default 0): the same model, seed and request give identical members.
    #[serde(default)]
    #[schema(minimum = 0)]
    pub seed: u64,
    /// `gaussian` (default: the model's own distribution, Gaussian coefficients clipped at
    /// 3 sd; an `rsmp` model fitted on 20 meshes or more takes each mode's coefficient from a
    /// training shape's) or `uniform` (coefficients uniform within ±3 sd).
    #[serde(default)]
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
    #[schema(example = json!({"volume_ml": {"min": 120, "max": 160}}))]
    pub targets: BTreeMap<String, Target>,
    /// The side of a paired organ every member should be, `left` or `right`: the members of
    /// a model of the other side (its `laterality`) are served as their mirror images
    /// (biomarkers unchanged). A model that does not know its side refuses it (422
    /// `cohort.laterality_unknown`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub laterality: Option<Laterality>,
}

impl CohortRequest {
    /// The sampling settings of this request.
    pub fn spec(&self) -> CohortSpec {
        CohortSpec {
            size: self.size,
            seed: self.seed,
            sampling: self.sampling,
            criterion: self.acceptance.criterion,
            only_accepted: self.only_accepted,
            exclude_near_copies: self.exclude_near_copies,
            max_draws: self.size.saturating_mul(DRAWS_PER_MEMBER),
        }
    }

    /// Whether the members are served as their mirror images: the request asks for a side
    /// and the model's shapes (`model_side`, from its summary) are of the other.
    pub fn mirrors_members(&self, model_side: Option<Laterality>) -> bool {
        matches!((self.laterality, model_side), (Some(asked), Some(side)) if asked != side)
    }
}

/// The side of a model's shapes, from its stored summary (`None`: unknown).
pub fn model_side(summary: &serde_json::Value) -> Option<Laterality> {
    summary
        .get("laterality")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
}

/// One member of a cohort: where it was drawn, its biomarkers, and how it compares with the
/// training population.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct MemberSummary {
    /// Position in the cohort, from 0.
    pub index: usize,
    /// Draw number it came from (draws rejected by `only_accepted`, targets or the privacy
    /// guard leave gaps).
    pub draw: u64,
    /// Cluster (atlas) it was drawn from; 0 for single-atlas models.
    #[serde(default)]
    pub cluster: usize,
    /// Biomarkers by name: `volume_ml` (ml), `area_cm2` (cm²), `sphericity`, `extent_*_mm`
    /// (mm), ….
    #[schema(example = json!({"volume_ml": 104.2, "area_cm2": 121.5}))]
    pub biomarkers: BTreeMap<String, f64>,
    /// Whether every biomarker lies in the training range (`range`), in `M ± 3B` around the
    /// mode (`mode`), and in `μ ± 2σ` (`mean`).
    pub accepted: Flags,
    /// Mean distance between corresponding vertices to the nearest training shape (mm).
    pub nearest_training_mm: f64,
    /// The nearest training mesh.
    pub nearest_training_mesh_id: Option<String>,
    /// Nearer to a training shape than the model's privacy threshold.
    pub near_copy: bool,
}

impl MemberSummary {
    fn of(m: &Member, training_ids: &[String]) -> Self {
        Self {
            index: m.index,
            draw: m.draw,
            cluster: m.cluster,
            biomarkers: m
                .biomarkers
                .iter()
                .map(|(name, value)| (name.to_owned(), value))
                .collect(),
            accepted: m.accepted,
            nearest_training_mm: m.nearest_training.distance_mm,
            nearest_training_mesh_id: training_ids.get(m.nearest_training.index).cloned(),
            near_copy: m.near_copy,
        }
    }
}

/// A cohort drawn and ready to store.
#[derive(Debug)]
pub struct DrawnCohort {
    /// The acceptance report (JSON).
    pub report: serde_json::Value,
    /// The members in order.
    pub members: Vec<NewMember>,
}

/// What a cohort is drawn from.
pub struct CohortSource {
    /// The decoded model.
    pub stored: StoredModel,
    /// Biomarkers of its training population.
    pub reference: ReferencePopulation,
    /// Its training meshes, in the order of the model's training shapes.
    pub training_ids: Vec<String>,
}

/// Draws the cohort `request` asks of `source`; blocking (call it off the async runtime).
pub fn draw_cohort(
    source: &CohortSource,
    request: &CohortRequest,
    progress: &mut dyn Progress,
) -> Result<DrawnCohort, ModelError> {
    let spec = request.spec();
    let shapes = source.stored.training.normalised_f64();
    let training = TrainingIndex::new(&shapes, &source.stored.training.privacy)?;
    let model = source.stored.model.as_ref();
    let conditional = conditional_of(model, request)?;
    let (members, report) = sample_cohort_given(
        model,
        &source.reference,
        &training,
        &spec,
        conditional.as_ref(),
        progress,
    )?;
    let report = serde_json::to_value(&report)
        .map_err(|e| ModelError::InvalidInput(format!("cohort report: {e}")))?;
    let members = parallel_map(&members, |m| {
        let summary = serde_json::to_value(MemberSummary::of(m, &source.training_ids))
            .map_err(|e| ModelError::InvalidInput(format!("cohort member: {e}")))?;
        Ok(NewMember {
            index: m.index,
            summary,
            mesh_sha256: codec::sha256_hex(&m.mesh),
        })
    })
    .into_iter()
    .collect::<Result<_, ModelError>>()?;
    Ok(DrawnCohort { report, members })
}

/// The shapes of a cohort's members: stored ones as they are, the others drawn again from
/// `source` (the cohort's model) by their draw numbers, each checked against the checksum
/// taken when it was first drawn; all as mirror images when the request asks for the other
/// side than the model's (`model_side`). Blocking (call it off the async runtime).
pub fn member_shapes(
    source: Option<&CohortSource>,
    request: &CohortRequest,
    model_side: Option<Laterality>,
    geometries: Vec<MemberGeometry>,
) -> Result<Vec<Mesh>, RunError> {
    let shapes = drawn_shapes(source, request, geometries)?;
    Ok(match request.mirrors_members(model_side) {
        true => shapes.iter().map(mirror_image).collect(),
        false => shapes,
    })
}

/// [`member_shapes`] as drawn.
fn drawn_shapes(
    source: Option<&CohortSource>,
    request: &CohortRequest,
    geometries: Vec<MemberGeometry>,
) -> Result<Vec<Mesh>, RunError> {
    let redraws: Vec<(u64, &str)> = geometries
        .iter()
        .filter_map(|g| match g {
            MemberGeometry::Redraw { draw, mesh_sha256 } => Some((*draw, mesh_sha256.as_str())),
            MemberGeometry::Stored(_) => None,
        })
        .collect();
    let mut drawn = match (source, redraws.is_empty()) {
        (_, true) => Vec::new(),
        (Some(source), false) => redraw(source, request, &redraws)?,
        (None, false) => {
            return Err(RunError::Invalid(
                "members to draw again but no model to draw them from".into(),
            ));
        }
    }
    .into_iter();
    geometries
        .into_iter()
        .map(|g| match g {
            MemberGeometry::Stored(mesh) => Ok(mesh),
            MemberGeometry::Redraw { .. } => drawn
                .next()
                .ok_or_else(|| RunError::Invalid("a member was not drawn again".into())),
        })
        .collect()
}

/// The conditional sampler of a request with targets (fitted from seeded pilot draws).
fn conditional_of(
    model: &(dyn ShapeModel + Sync),
    request: &CohortRequest,
) -> Result<Option<Conditional>, ModelError> {
    if request.targets.is_empty() {
        return Ok(None);
    }
    let targets: Vec<(String, Target)> = request.targets.clone().into_iter().collect();
    Conditional::new(model, &targets, request.seed).map(Some)
}

/// Draws `draws` (draw number, SHA-256) again as [`draw_cohort`] drew them.
fn redraw(
    source: &CohortSource,
    request: &CohortRequest,
    draws: &[(u64, &str)],
) -> Result<Vec<Mesh>, RunError> {
    let spec = request.spec();
    let model = source.stored.model.as_ref();
    let conditional = conditional_of(model, request)?;
    parallel_map(draws, |&(draw, sha256)| {
        let mesh = draw_shape(model, &spec, conditional.as_ref(), draw)?.mesh;
        if codec::sha256_hex(&mesh) != sha256 {
            return Err(RunError::NotReproducible { draw });
        }
        Ok(mesh)
    })
    .into_iter()
    .collect()
}

/// Reads the model, its reference population and its training mesh ids.
pub async fn load_source(store: &Store, model_id: &str) -> Result<CohortSource, RunError> {
    let (payload, reference) = store.model_payload(model_id).await?;
    let training_ids = store.model(model_id).await?.provenance.training_mesh_ids;
    let reference: ReferencePopulation = serde_json::from_value(reference)
        .map_err(|e| RunError::Invalid(format!("model {model_id} reference: {e}")))?;
    let stored = tokio::task::spawn_blocking(move || StoredModel::from_bytes(&payload))
        .await
        .map_err(|e| RunError::Invalid(e.to_string()))??;
    Ok(CohortSource {
        stored,
        reference,
        training_ids,
    })
}

/// Draws the cohort of a cohort job; blocking, to be called on a worker thread.
pub fn run_cohort_job(
    handle: &Handle,
    store: &Store,
    job: &Job,
    progress: &mut dyn Progress,
) -> Result<DrawnCohort, RunError> {
    let model_id = job
        .model_id
        .as_deref()
        .ok_or_else(|| RunError::Invalid(format!("cohort job {} names no model", job.id)))?;
    let request: CohortRequest = serde_json::from_value(job.params.clone())
        .map_err(|e| RunError::Invalid(format!("cohort job {}: {e}", job.id)))?;
    let source = handle.block_on(load_source(store, model_id))?;
    let drawn = draw_cohort(&source, &request, progress)?;
    crate::telemetry::record_members_drawn("job", drawn.members.len());
    Ok(drawn)
}
