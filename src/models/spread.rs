//! How faithfully a fitted model's cohorts vary like the training population: a seeded
//! cohort drawn at the end of every fit, each biomarker's spread against the training
//! values, the share of near copies, and a note when the population is too small.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::cohort::{CohortSpec, Criterion, TrainingIndex, sample_cohort};
use super::{ModelError, ReferencePopulation, ShapeModel, TrainingShapes};
use crate::eval::fidelity::Spread;
use crate::eval::gaussian_reference::{GAUSSIAN_REFERENCE_DRAWS, gaussian_joint_acceptance};
use crate::geometry::pca::Sampling;

/// Members of the cohort drawn to judge a fit's spread.
pub const FIDELITY_MEMBERS: usize = 1000;

/// Added to the fit seed for the fidelity cohort, so that it differs from other draws.
const FIDELITY_SEED_OFFSET: u64 = 0xf1de_1175;

/// The spread of a fitted model's cohort against its training population.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct FidelitySummary {
    /// Members drawn (Gaussian sampling, every draw kept).
    pub members: usize,
    /// Seed of the draws.
    pub seed: u64,
    /// Per biomarker: means, sds, their ratios and the KS statistic against the training
    /// values.
    pub biomarkers: BTreeMap<String, Spread>,
    /// Members nearer to a training shape than the privacy threshold.
    pub near_copies: usize,
    /// Members drawn again because a biomarker fell outside a small population's plausible
    /// range.
    pub implausible_replaced: usize,
    /// Joint A^μ of the cohort: the share of members inside `μ ± 2σ` of every biomarker
    /// (absent in summaries stored before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_acceptance: Option<f64>,
    /// The joint A^μ of draws from the Gaussian with the training biomarkers' mean and
    /// covariance: what a generator with a Gaussian latent space can be expected to reach
    /// (populations with lighter tails than a Gaussian score higher themselves).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaussian_joint_acceptance: Option<f64>,
    /// Said when the training population is too small for its estimates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub population_note: Option<String>,
}

impl FidelitySummary {
    /// The cohort's joint A^μ beside the Gaussian yardstick, in words (absent in summaries
    /// stored before both were kept).
    pub fn acceptance_sentence(&self) -> Option<String> {
        let (cohort, gaussian) = (self.joint_acceptance?, self.gaussian_joint_acceptance?);
        Some(format!(
            "{:.1}% of the members lie inside μ ± 2σ of every biomarker (joint A^μ); draws from \
             a Gaussian with the training biomarkers' mean and covariance do {:.1}% of the \
             time, which is what a model with a Gaussian latent space can be expected to reach",
            100.0 * cohort,
            100.0 * gaussian
        ))
    }
}

/// Draws [`FIDELITY_MEMBERS`] members (seeded from `seed`) and compares them with the
/// training population.
pub fn fidelity_summary<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    training: &TrainingShapes,
    seed: u64,
) -> Result<FidelitySummary, ModelError> {
    let normalised = training.normalised_f64();
    let index = TrainingIndex::new(&normalised, &training.privacy)?;
    let spec = CohortSpec {
        size: FIDELITY_MEMBERS,
        seed: seed.wrapping_add(FIDELITY_SEED_OFFSET),
        sampling: Sampling::Gaussian,
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: 20 * FIDELITY_MEMBERS,
    };
    let (_, report) = sample_cohort(model, reference, &index, &spec)?;
    Ok(FidelitySummary {
        members: FIDELITY_MEMBERS,
        seed: spec.seed,
        biomarkers: report
            .biomarkers
            .iter()
            .filter_map(|(name, b)| b.spread.map(|s| (name.clone(), s)))
            .collect(),
        near_copies: report.privacy.near_copies,
        joint_acceptance: Some(report.acceptance.mean),
        gaussian_joint_acceptance: gaussian_joint_acceptance(
            &reference.intervals(),
            &reference.values,
            GAUSSIAN_REFERENCE_DRAWS,
            spec.seed,
        )
        .ok()
        .map(|r| r.mean),
        implausible_replaced: report.implausible_replaced,
        population_note: report.population_note,
    })
}
