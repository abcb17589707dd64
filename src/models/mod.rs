//! Shape models behind one interface: fit on training meshes, sample new shapes,
//! reconstruct unseen ones. Pure: no async, SQL or HTTP.
//!
//! Model types (listed once, in [`registry`]): `rsmp` (rigid CPD + soft correspondences +
//! PCA, thesis ch. 3), `asmg` (graph VAE + attention correspondences + learned atlas +
//! beta-VAE, thesis ch. 4), `atlas-r-asmg` (the same trained end to end with a refinement
//! loss, thesis §5.2) and `matlas-r-asmg` (several atlases, soft clusters, a generator per
//! cluster, thesis §5.4). A model has one or more atlases, each with its own connectivity; a
//! draw says which atlas (cluster) it came from.

pub mod alignment;
pub mod asmg;
pub mod atlas_r_asmg;
pub mod beta_choice;
pub mod clusters;
pub mod cohort;
pub mod conditional;
mod error;
pub mod evaluation;
pub mod fitting;
pub mod folding;
pub mod latent_effects;
pub mod matlas_r_asmg;
pub mod progress;
pub mod reference;
pub mod registry;
pub mod rsmp;
pub mod shape_modes;
pub mod sides;
pub mod spread;
pub mod stored;
mod targets_report;
#[cfg(test)]
pub(crate) mod test_fits;
pub mod workers;

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use error::ModelError;
pub use evaluation::Evaluation;
pub use fitting::{FitInput, FittedParts};
pub use reference::ReferencePopulation;
pub use registry::{ModelFamily, ModelParams, ModelType};
pub use stored::{FittedModel, StoredModel};

use crate::eval::privacy::CorrespondedShapes;
use crate::eval::privacy::PrivacyThreshold;
use crate::geometry::pca::Sampling;
use crate::mesh::{Laterality, Mesh};

/// A model's reconstruction of a mesh.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// The reconstructed shape: the connectivity of atlas `atlas`, mm, model frame.
    pub mesh: Mesh,
    /// Which of the model's atlases the reconstruction used.
    pub atlas: usize,
    /// The input's normalised shape on that atlas (before projection), `[N_μ, 3]`, mm.
    pub normalised: Vec<[f64; 3]>,
    /// The input's vertices moved into the model frame, `[n_vertices, 3]`, mm.
    pub aligned_input: Vec<[f64; 3]>,
}

/// One generated shape and the cluster (atlas) it was drawn from.
#[derive(Debug, Clone, PartialEq)]
pub struct Draw {
    /// The shape: mm, model frame, the connectivity of atlas `cluster`.
    pub mesh: Mesh,
    /// Index of the atlas (0 for single-atlas models).
    pub cluster: usize,
}

/// How a model's draws arise when each is a standard-normal vector `ε` mapped to a shape by
/// the generator of one cluster (PCA coefficients `bᵢ = √λᵢ·εᵢ`, or the latent Gaussian's
/// `z = centre + mixing·ε`).
#[derive(Debug, Clone, PartialEq)]
pub struct StandardLatent {
    /// `π_m`: the probability that a draw comes from cluster `m` (summing to one).
    pub priors: Vec<f64>,
    /// Length `L_m` of the standard-normal vector of each cluster.
    pub dimensions: Vec<usize>,
    /// The coordinates are PCA modes in decreasing variance (otherwise latent codes).
    pub principal_modes: bool,
}

/// What every fitted model can do.
pub trait ShapeModel {
    /// The atlases (templates) in the model frame, mm: one or more, each with its own
    /// connectivity.
    fn atlases(&self) -> &[Mesh];
    /// Draws one new shape.
    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Draw, ModelError>;
    /// Reconstructs an unseen mesh through the model; `laterality` is its side when the user
    /// gave it (a model that learns both sides on one takes it without comparison).
    fn reconstruct(
        &self,
        mesh: &Mesh,
        laterality: Option<Laterality>,
    ) -> Result<Reconstruction, ModelError>;
    /// The training shapes as the model's generator reproduces them, `[atlas][shape]`
    /// (`[N_μm, 3]` mm each), given the normalised shapes `[atlas][shape]`: what the privacy
    /// guard compares members with, so that a member (a decoder output) is measured against
    /// decoder outputs, like with like. `None`: the normalised shapes themselves.
    #[allow(clippy::type_complexity)]
    fn regenerated_training(
        &self,
        normalised: &[Vec<Vec<[f64; 3]>>],
    ) -> Result<Option<Vec<Vec<Vec<[f64; 3]>>>>, ModelError> {
        let _ = normalised;
        Ok(None)
    }
    /// Variances `λᵢ` of the kept PCA modes in mm², largest first (PCA models only).
    fn principal_variances_mm2(&self) -> Option<Vec<f64>> {
        None
    }
    /// The standard-normal draws behind [`sample`](Self::sample), when draws are made so.
    fn standard_latent(&self) -> Option<StandardLatent> {
        None
    }
    /// The shapes of standard-normal vectors `[L_m]` through cluster `cluster`'s generator
    /// (mm, that atlas's connectivity); unclipped.
    fn decode_standard(
        &self,
        cluster: usize,
        standard: &[Vec<f64>],
    ) -> Result<Vec<Mesh>, ModelError> {
        let _ = (cluster, standard);
        Err(ModelError::InvalidInput(
            "this model does not draw from a standard normal".to_owned(),
        ))
    }
}

/// The training shapes in the model frame, kept with a model for the privacy guard and for
/// offline specificity.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainingShapes {
    /// Vertices of each training mesh after pre-alignment, mm, `[n_vertices, 3]` each.
    pub shapes: Vec<Vec<[f32; 3]>>,
    /// `normalised[m][k]`: training mesh `k` normalised to atlas `m` (in correspondence with
    /// it), mm, `[N_μm, 3]`, as the model's generator reproduces it where it has one (see
    /// [`ShapeModel::regenerated_training`]): what cohort members of cluster `m` are
    /// compared with.
    pub normalised: Vec<Vec<Vec<[f32; 3]>>>,
    /// Near-copy threshold of each atlas, from the nearest-neighbour distances of the
    /// training shapes normalised to it.
    pub privacy: Vec<PrivacyThreshold>,
}

/// `Ok` when `cluster` is one of `count` clusters.
pub(crate) fn check_cluster(cluster: usize, count: usize) -> Result<(), ModelError> {
    if cluster < count {
        Ok(())
    } else {
        Err(ModelError::InvalidInput(format!(
            "cluster {cluster} of a model with {count} clusters"
        )))
    }
}

fn to_f32(shapes: &[Vec<[f64; 3]>]) -> Vec<Vec<[f32; 3]>> {
    shapes
        .iter()
        .map(|s| s.iter().map(|p| p.map(|c| c as f32)).collect())
        .collect()
}

fn to_f64(shapes: &[Vec<[f32; 3]>]) -> Vec<Vec<[f64; 3]>> {
    shapes
        .iter()
        .map(|s| s.iter().map(|p| p.map(f64::from)).collect())
        .collect()
}

/// The near-copy threshold of shapes in correspondence (`[N, 3]` mm each) at the default
/// percentile, as a cohort's privacy guard takes it (see [`TrainingShapes::new`]).
pub(crate) fn near_copy_threshold<S: AsRef<[[f64; 3]]>>(
    shapes: &[S],
) -> Result<PrivacyThreshold, ModelError> {
    threshold_at(shapes, crate::eval::privacy::DEFAULT_PERCENTILE)
}

fn threshold_at<S: AsRef<[[f64; 3]]>>(
    shapes: &[S],
    percentile: f64,
) -> Result<PrivacyThreshold, ModelError> {
    let corresponded = CorrespondedShapes::new(shapes)?;
    // With few shapes every draw lies near their hull, which a new patient does not:
    // compare like with like (each shape as the others' hull makes it).
    Ok(
        if (3..reference::SMALL_POPULATION).contains(&shapes.len()) {
            corresponded.leave_one_out_threshold(shapes, percentile)?
        } else {
            corresponded.privacy_threshold(percentile)?
        },
    )
}

impl TrainingShapes {
    /// From aligned training vertices and their normalised shapes per atlas (model frame,
    /// mm); each atlas's threshold is the `percentile` of its normalised shapes'
    /// nearest-neighbour distances, below [`reference::SMALL_POPULATION`] shapes measured
    /// from each shape's projection on the hull of the others.
    pub fn new(
        aligned: &[Vec<[f64; 3]>],
        normalised: &[Vec<Vec<[f64; 3]>>],
        percentile: f64,
    ) -> Result<Self, ModelError> {
        let privacy = normalised
            .iter()
            .map(|shapes| threshold_at(shapes, percentile))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            shapes: to_f32(aligned),
            normalised: normalised.iter().map(|s| to_f32(s)).collect(),
            privacy,
        })
    }

    /// The aligned training vertices in f64.
    pub fn to_f64(&self) -> Vec<Vec<[f64; 3]>> {
        to_f64(&self.shapes)
    }

    /// The normalised shapes in f64, `[atlas][shape]`.
    pub fn normalised_f64(&self) -> Vec<Vec<Vec<[f64; 3]>>> {
        self.normalised.iter().map(|s| to_f64(s)).collect()
    }
}

/// Atlas facts reported with a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct AtlasInfo {
    /// Position among the model's atlases.
    #[serde(default)]
    pub index: usize,
    /// Vertices of the atlas.
    pub vertex_count: usize,
    /// Triangles of the atlas.
    pub face_count: usize,
    /// V − E + F (2 for a sphere, 0 for a torus); absent in models stored before it was kept.
    #[serde(default)]
    pub euler_characteristic: Option<i64>,
}

impl AtlasInfo {
    /// The facts of atlas `index`.
    pub fn of(index: usize, atlas: &Mesh) -> Self {
        Self {
            index,
            vertex_count: atlas.vertex_count(),
            face_count: atlas.face_count(),
            euler_characteristic: Some(crate::mesh::topology::euler_characteristic(atlas)),
        }
    }
}

/// Time spent in one stage of the fit.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct StageTiming {
    /// Stage name.
    pub stage: String,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl StageTiming {
    /// The wall-clock time of every stage entered so far, in order.
    pub fn all(stages: &progress::Stages) -> Vec<Self> {
        stages
            .seconds
            .iter()
            .map(|(stage, seconds)| Self {
                stage: (*stage).to_owned(),
                seconds: *seconds,
            })
            .collect()
    }
}

/// Everything reported about a fitted model besides its parameters.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelSummary {
    /// The first atlas (the only one of single-atlas models).
    pub atlas: AtlasInfo,
    /// Every atlas, in order.
    #[serde(default)]
    pub atlases: Vec<AtlasInfo>,
    /// Quality on held-out and generated shapes.
    pub evaluation: Evaluation,
    /// Cumulative explained variance per mode (PCA models).
    pub explained_variance: Option<Vec<f64>>,
    /// Modes kept (PCA models).
    pub n_modes: Option<usize>,
    /// Training meshes used.
    pub training_count: usize,
    /// Held-out meshes evaluated.
    pub holdout_count: usize,
    /// Time per stage.
    pub timings: Vec<StageTiming>,
    /// Mean training loss per epoch of each trained network (none for closed-form fits).
    #[serde(default)]
    pub losses: Vec<LossCurve>,
    /// Soft clusters of models with several atlases (absent: one atlas, every mesh in it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clusters: Option<ClusterSummary>,
    /// How a seeded cohort of the model spreads against the training population (absent in
    /// summaries stored before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fidelity: Option<spread::FidelitySummary>,
    /// How each generator's KL weight was chosen on held-out folds (empty: as given).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beta_choices: Vec<beta_choice::BetaChoice>,
    /// Positions (in the training order) of the training meshes registered as their mirror
    /// images, so that every shape takes the side of the alignment reference (`mirror`);
    /// empty for models fitted without it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mirrored_training: Vec<usize>,
    /// With `mirror`, the side (`left` or `right`) every shape of the model, and so every
    /// cohort member, has: the alignment reference's, known when the user gave the side of
    /// training meshes; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub laterality: Option<Laterality>,
}

/// The soft clusters of a multi-atlas fit (thesis eq. 5.13), in mesh order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterSummary {
    /// `π_m`: the probability that a draw comes from cluster `m`.
    pub priors: Vec<f64>,
    /// `w_km` of every training mesh (rows in training order, each summing to one).
    pub training: Vec<Vec<f64>>,
    /// The weights of every held-out mesh, computed as for an unseen mesh.
    pub holdout: Vec<Vec<f64>>,
}

/// The mean training loss per epoch of one network.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LossCurve {
    /// Which network, e.g. `graph_vae`.
    pub network: String,
    /// Mean loss of each epoch, in order.
    pub per_epoch: Vec<f64>,
}

/// A fit's result: the model, its summary and the reference population.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    /// The fitted model and its training shapes.
    pub model: StoredModel,
    /// Atlas, evaluation, timings.
    pub summary: ModelSummary,
    /// Biomarkers of the training population.
    pub reference: ReferencePopulation,
}
