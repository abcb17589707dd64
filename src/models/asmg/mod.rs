//! ASMG, the atlas-based shape model with a graph network (thesis ch. 4; SPEC §2.4–2.6 and
//! §2.9). The correspondence and atlas part works on per-vertex embeddings and needs no
//! network; [`fit`] and [`model`] tie it to the graph VAE Ψ and the beta-VAE generator.
//!
//! - [`embeddings`]: the `[n_vertices, d_z]` matrices the graph network Ψ hands over;
//! - [`attention`]: soft correspondences `Φ_k` and normalised shapes `h_k = Φ_k X_k`;
//! - [`laplacian`]: the factored `(c·I + γL)` of the atlas connectivity, Jacobi sweeps;
//! - [`smoothing`]: Laplacian smoothing of normalised shapes (positions or displacement);
//! - [`atlas`]: the atlas update from the smoothed shapes, damped;
//! - [`init`], [`icosphere`]: the initial atlas;
//! - [`learn`]: Algorithm 1, the loop over all of the above until the atlas settles;
//! - [`soft_clusters`]: soft memberships of shapes in several atlases and the weighted
//!   atlas update (the multi-atlas building blocks);
//! - [`beta_selection`]: the generator's KL weight chosen on held-out folds of few shapes;
//! - [`params`]: the job parameters of `model_type: "asmg"`;
//! - [`fit`]: the whole fit (pre-alignment, Ψ, atlas, generator, evaluation);
//! - `generator`: one atlas's beta-VAE and the model built around it;
//! - [`model`]: the fitted model (sampling, reconstruction, stored weights).

pub mod atlas;
pub mod attention;
mod beta_selection;
pub mod biomarker_calibration;
pub mod calibration;
pub mod embeddings;
pub mod fit;
mod generator;
pub mod icosphere;
pub mod init;
pub mod laplacian;
pub mod learn;
pub mod marginal_map;
pub mod model;
mod monitor;
pub mod multi_atlas;
pub mod nonrigid;
mod parallel;
pub mod params;
mod pose;
pub mod registration;
mod scores;
pub mod smoothing;
pub mod soft_clusters;

pub use atlas::{AtlasUpdateParams, AtlasUpdater, update_atlas};
pub use attention::{
    Correspondence, Match, ScoreMoments, Temperature, attention_rows, correspond,
    inverse_temperature, normalised_shape, score_moments,
};
pub use embeddings::Embeddings;
pub use init::{AtlasInit, initial_atlas};
pub use laplacian::LaplacianSolver;
pub use learn::{
    AtlasLoopParams, AtlasStep, LearnedAtlas, NormalisedShapes, ShapeInput, learn_atlas,
    normalise_shapes,
};
pub use model::AsmgModel;
pub use params::{AsmgParams, CalibrationKind, CheckedAsmgParams, FeatureKind, SmoothingTarget};
pub use smoothing::{Smoother, Smoothing, SmoothingMethod, SmoothingParams, smooth};

use crate::models::progress::{Progress, Stages};
use crate::models::{FitInput, FittedParts, ModelError, ModelFamily};

/// The `asmg` model type.
pub struct Asmg;

impl ModelFamily for Asmg {
    const NAME: &'static str = "asmg";
    const MIN_TRAINING_MESHES: usize = fit::MIN_TRAINING_MESHES;
    const TEMPLATE_FIELD: &'static str = "atlas";
    const STAGES: &'static [(&'static str, f64)] = &fit::STAGES;
    type Params = AsmgParams;
    type Checked = CheckedAsmgParams;
    type Model = AsmgModel;

    fn check(params: AsmgParams) -> Result<CheckedAsmgParams, ModelError> {
        params.check()
    }

    fn params(checked: &CheckedAsmgParams) -> &AsmgParams {
        checked.get()
    }

    fn template_mesh_ids(checked: &CheckedAsmgParams) -> Vec<&str> {
        checked.get().atlas_mesh_id().into_iter().collect()
    }

    fn fit(
        params: &CheckedAsmgParams,
        input: &FitInput<'_>,
        stages: &mut Stages,
        progress: &mut dyn Progress,
    ) -> Result<FittedParts<AsmgModel>, ModelError> {
        fit::fit(params.get(), input, stages, progress)
    }
}
