//! The one dispatch from validated parameters to a model type's fit, shared by fit jobs and
//! the offline `fit` and `bench` commands.

use super::params::ModelParams;
use crate::mesh::Mesh;
use crate::models::progress::Progress;
use crate::models::{FitOutcome, ModelError, asmg, rsmp};

/// Fits the model that `params` describe to `training` and evaluates it on `holdout`.
///
/// `template_index` picks the template (or atlas) among `training`; `None` lets the model
/// choose. The same inputs and `seed` give the same model.
pub fn fit_model(
    params: &ModelParams,
    training: &[Mesh],
    holdout: &[Mesh],
    template_index: Option<usize>,
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    match params {
        ModelParams::Rsmp(p) => rsmp::fit(training, holdout, p, template_index, seed, progress),
        ModelParams::Asmg(p) => asmg::fit(training, holdout, p, template_index, seed, progress),
    }
}
