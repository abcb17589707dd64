//! Shape models behind one interface: fit on training meshes, sample new shapes,
//! reconstruct unseen ones. Pure: no async, SQL or HTTP.
//!
//! Model types: `rsmp` (rigid CPD + soft correspondences + PCA, thesis ch. 3) and `asmg`
//! (graph VAE + attention correspondences + learned atlas + beta-VAE, thesis ch. 4).

pub mod alignment;
pub mod asmg;
pub mod cohort;
mod error;
pub mod evaluation;
pub mod progress;
pub mod reference;
pub mod rsmp;
pub mod workers;

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use error::ModelError;
pub use evaluation::Evaluation;
pub use reference::ReferencePopulation;

use crate::eval::privacy::CorrespondedShapes;
use crate::eval::privacy::PrivacyThreshold;
use crate::geometry::pca::Sampling;
use crate::mesh::Mesh;

/// Kinds of shape model a job can fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelType {
    /// Rigid CPD to a template, soft-correspondence normalisation, PCA.
    Rsmp,
    /// Graph VAE embeddings, attention correspondences, learned atlas, beta-VAE.
    Asmg,
}

impl ModelType {
    /// Every model type.
    pub const ALL: [ModelType; 2] = [ModelType::Rsmp, ModelType::Asmg];

    /// The name used in the API.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Rsmp => "rsmp",
            Self::Asmg => "asmg",
        }
    }

    /// From its API name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.as_str() == name)
    }
}

/// A model's reconstruction of a mesh.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// The reconstructed shape: the model's connectivity, mm, model frame.
    pub mesh: Mesh,
    /// The input's normalised shape (before projection), `[n_atlas_vertices, 3]`, mm.
    pub normalised: Vec<[f64; 3]>,
    /// The input's vertices moved into the model frame, `[n_vertices, 3]`, mm.
    pub aligned_input: Vec<[f64; 3]>,
}

/// What every fitted model can do.
pub trait ShapeModel {
    /// The atlas (template) mesh in the model frame, mm.
    fn atlas(&self) -> &Mesh;
    /// Draws one new shape (mm, atlas connectivity).
    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Mesh, ModelError>;
    /// Reconstructs an unseen mesh through the model.
    fn reconstruct(&self, mesh: &Mesh) -> Result<Reconstruction, ModelError>;
}

/// A fitted model of any type, as stored.
// One value per loaded model, never kept in bulk: the size difference does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum AnyModel {
    /// See [`rsmp::RsmpModel`].
    Rsmp(rsmp::RsmpModel),
    /// See [`asmg::AsmgModel`].
    Asmg(asmg::AsmgModel),
}

impl AnyModel {
    /// The model behind the common interface.
    pub fn shape_model(&self) -> &(dyn ShapeModel + Sync) {
        match self {
            Self::Rsmp(m) => m,
            Self::Asmg(m) => m,
        }
    }
}

/// The training shapes in the model frame, kept with a model for the privacy guard and for
/// offline specificity.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainingShapes {
    /// Vertices of each training mesh after pre-alignment, mm, `[n_vertices, 3]` each.
    pub shapes: Vec<Vec<[f32; 3]>>,
    /// Each training mesh's normalised shape (in correspondence with the atlas), mm,
    /// `[n_atlas_vertices, 3]` each: what cohort members are compared with.
    pub normalised: Vec<Vec<[f32; 3]>>,
    /// Near-copy threshold derived from the normalised shapes' nearest-neighbour distances.
    pub privacy: PrivacyThreshold,
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

impl TrainingShapes {
    /// From aligned training vertices and their normalised shapes (model frame, mm); the
    /// threshold is the `percentile` of the normalised shapes' nearest-neighbour distances.
    pub fn new(
        aligned: &[Vec<[f64; 3]>],
        normalised: &[Vec<[f64; 3]>],
        percentile: f64,
    ) -> Result<Self, ModelError> {
        let privacy = CorrespondedShapes::new(normalised)?.privacy_threshold(percentile)?;
        Ok(Self {
            shapes: to_f32(aligned),
            normalised: to_f32(normalised),
            privacy,
        })
    }

    /// The aligned training vertices in f64.
    pub fn to_f64(&self) -> Vec<Vec<[f64; 3]>> {
        to_f64(&self.shapes)
    }

    /// The normalised shapes in f64.
    pub fn normalised_f64(&self) -> Vec<Vec<[f64; 3]>> {
        to_f64(&self.normalised)
    }
}

/// What is stored for a model: the fitted model and its training shapes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StoredModel {
    /// The fitted model.
    pub model: AnyModel,
    /// Training shapes and privacy threshold.
    pub training: TrainingShapes,
}

impl StoredModel {
    /// Compact binary form for storage.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ModelError> {
        postcard::to_stdvec(self).map_err(|e| ModelError::Corrupt(e.to_string()))
    }

    /// From [`StoredModel::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ModelError> {
        postcard::from_bytes(bytes).map_err(|e| ModelError::Corrupt(e.to_string()))
    }
}

/// Atlas facts reported with a model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AtlasInfo {
    /// Vertices of the atlas.
    pub vertex_count: usize,
    /// Triangles of the atlas.
    pub face_count: usize,
}

/// Time spent in one stage of the fit.
#[derive(Debug, Clone, Serialize, Deserialize)]
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
    /// The atlas.
    pub atlas: AtlasInfo,
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
