//! Fits for unit tests: a model type by name on a few meshes.

use super::progress::Silent;
use super::{FitInput, FitOutcome, ModelType};
use crate::mesh::Mesh;

/// A model of type `name` fitted on `training` (seed 1, no held-out meshes) with `params`
/// (JSON as a fit request's).
pub(crate) fn fitted(name: &str, training: &[Mesh], params: serde_json::Value) -> FitOutcome {
    let input = FitInput {
        training,
        holdout: &[],
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &[],
        seed: 1,
    };
    ModelType::parse_name(name)
        .unwrap()
        .parse_params(&params)
        .unwrap()
        .fit(&input, &mut Silent)
        .unwrap()
}
