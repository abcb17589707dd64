//! What every fit shares: its input, the parts a model type hands back, and the closing
//! steps written once (evaluation, reference population, training shapes, summary).

use std::sync::Arc;

use super::evaluation::evaluate;
use super::progress::{Progress, Stages};
use super::registry::ModelType;
use super::spread::fidelity_summary;
use super::stored::{FittedModel, StoredModel};
use super::{
    AtlasInfo, ClusterSummary, FitOutcome, LossCurve, ModelError, ModelSummary,
    ReferencePopulation, StageTiming, TrainingShapes,
};
use crate::eval::privacy::DEFAULT_PERCENTILE;
use crate::mesh::{Laterality, Mesh};

/// The meshes and settings of one fit.
#[derive(Debug, Clone, Copy)]
pub struct FitInput<'a> {
    /// Training meshes (mm), in fit order.
    pub training: &'a [Mesh],
    /// Held-out meshes for generalisation and matching.
    pub holdout: &'a [Mesh],
    /// The side of each training mesh where the user gave it (empty, or one per mesh).
    pub training_laterality: &'a [Option<Laterality>],
    /// The side of each held-out mesh where the user gave it (empty, or one per mesh).
    pub holdout_laterality: &'a [Option<Laterality>],
    /// Positions in `training` of the meshes the user named as template or atlases, in the
    /// order named (empty: the model chooses).
    pub template_indices: &'a [usize],
    /// Seed: the same inputs and seed give the same model.
    pub seed: u64,
}

impl<'a> FitInput<'a> {
    /// The meshes alone: no side given, the model chooses its template or atlases.
    pub fn new(training: &'a [Mesh], holdout: &'a [Mesh], seed: u64) -> Self {
        Self {
            training,
            holdout,
            training_laterality: &[],
            holdout_laterality: &[],
            template_indices: &[],
            seed,
        }
    }

    /// Position in `training` of the first mesh the user named as template or atlas.
    pub fn template_index(&self) -> Option<usize> {
        self.template_indices.first().copied()
    }

    /// The side the user gave held-out mesh `i`, if any.
    pub fn holdout_side(&self, i: usize) -> Option<Laterality> {
        self.holdout_laterality.get(i).copied().flatten()
    }
}

/// What a model type's fit hands to [`finish`].
#[derive(Debug)]
pub struct FittedParts<M> {
    /// The fitted model.
    pub model: M,
    /// All vertices of each training mesh in the model frame, `[n_vertices, 3]` mm each.
    pub aligned_training: Vec<Vec<[f64; 3]>>,
    /// `normalised[m][k]`: training shape `k` normalised to atlas `m`, `[N_μm, 3]` mm.
    pub normalised: Vec<Vec<Vec<[f64; 3]>>>,
    /// Cumulative explained variance per mode (PCA models).
    pub explained_variance: Option<Vec<f64>>,
    /// Modes kept (PCA models).
    pub n_modes: Option<usize>,
    /// Loss per epoch of each trained network.
    pub losses: Vec<LossCurve>,
    /// Soft clusters (multi-atlas models).
    pub clusters: Option<ClusterSummary>,
    /// KL weights chosen on held-out folds, one per generator that chose (see
    /// [`super::beta_choice`]).
    pub beta_choices: Vec<super::beta_choice::BetaChoice>,
    /// Positions (in the training order) of the training meshes registered as their
    /// mirror images (see [`super::sides`]).
    pub mirrored_training: Vec<usize>,
    /// The side every shape of the model has, when known (see [`super::sides`]).
    pub laterality: Option<Laterality>,
}

/// Evaluates the fitted model on the held-out meshes and samples, and assembles the
/// outcome: the stored model, its summary and the reference population.
pub fn finish<M: FittedModel + 'static>(
    model_type: ModelType,
    parts: FittedParts<M>,
    input: &FitInput<'_>,
    mut stages: Stages,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    stages.enter("evaluation");
    let training_faces: Vec<&[[u32; 3]]> =
        input.training.iter().map(|m| m.faces.as_slice()).collect();
    let evaluation = evaluate(
        &parts.model,
        &parts.aligned_training,
        &training_faces,
        input.holdout,
        input.holdout_laterality,
        input.training.len(),
        input.seed,
        &stages,
        progress,
    )?;
    let reference = ReferencePopulation::from_meshes(input.training)?;
    let compared = parts.model.regenerated_training(&parts.normalised)?;
    let training = TrainingShapes::new(
        &parts.aligned_training,
        compared.as_ref().unwrap_or(&parts.normalised),
        DEFAULT_PERCENTILE,
    )?;
    let fidelity = fidelity_summary(
        &parts.model,
        &reference,
        &training,
        input.training,
        input.seed,
    )?;
    stages.close();
    let atlases: Vec<AtlasInfo> = parts
        .model
        .atlases()
        .iter()
        .enumerate()
        .map(|(i, a)| AtlasInfo::of(i, a))
        .collect();
    let summary = ModelSummary {
        atlas: atlases
            .first()
            .cloned()
            .ok_or_else(|| ModelError::InvalidInput("the model has no atlas".to_owned()))?,
        atlases,
        evaluation,
        explained_variance: parts.explained_variance,
        n_modes: parts.n_modes,
        training_count: input.training.len(),
        holdout_count: input.holdout.len(),
        timings: StageTiming::all(&stages),
        losses: parts.losses,
        clusters: parts.clusters,
        fidelity: Some(fidelity),
        beta_choices: parts.beta_choices,
        mirrored_training: parts.mirrored_training,
        laterality: parts.laterality,
    };
    Ok(FitOutcome {
        model: StoredModel {
            model_type,
            model: Arc::new(parts.model),
            training,
        },
        summary,
        reference,
    })
}
