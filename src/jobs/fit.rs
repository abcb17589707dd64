//! The one entry from validated parameters to a fit, shared by fit jobs and the offline
//! `fit` and `bench` commands.

use crate::models::progress::Progress;
use crate::models::{FitInput, FitOutcome, ModelError, ModelParams};

/// Fits the model that `params` describe to `input`'s training meshes and evaluates it on
/// its held-out ones. The same input (meshes, sides, template positions, seed) gives the
/// same model.
pub fn fit_model(
    params: &ModelParams,
    input: &FitInput<'_>,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    params.fit(input, progress)
}
