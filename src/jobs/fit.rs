//! The one entry from validated parameters to a fit, shared by fit jobs and the offline
//! `fit` and `bench` commands.

use crate::mesh::Mesh;
use crate::models::progress::Progress;
use crate::models::{FitInput, FitOutcome, ModelError, ModelParams};

/// Fits the model that `params` describe to `training` and evaluates it on `holdout`.
///
/// `template_indices` pick the template or the atlases among `training` (positions);
/// empty lets the model choose. The same inputs and `seed` give the same model.
pub fn fit_model(
    params: &ModelParams,
    training: &[Mesh],
    holdout: &[Mesh],
    template_indices: &[usize],
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    let input = FitInput {
        training,
        holdout,
        template_indices,
        seed,
    };
    params.fit(&input, progress)
}
