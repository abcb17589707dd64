//! Choosing the generator's KL weight β on held-out folds of its training shapes.
//!
//! With few training shapes a beta-VAE with a small β learns each shape as its own corner
//! of the latent space, and its draws hand the patients back (on 16 KiTS19 kidneys, β 1:
//! 489 of 1,000 draws were near copies). A larger β stops that but also smooths away what
//! the shapes have in common. The shapes are split into folds; for each candidate β a
//! generator is trained on all folds but one, and
//! - its draws (from its training codes' Gaussian and calibrated, as cohorts draw) are
//!   compared with its own training shapes passed through it, against the near-copy
//!   threshold those shapes give (what a cohort's privacy guard does);
//! - the held-out fold is reconstructed by it (encoder mean, decoder): the error of a
//!   generator on shapes it has not seen.
//!
//! Kept is the candidate with the smallest held-out error among those whose draws are near
//! copies at most [`NEAR_COPY_BOUND`] of the time ([`BetaChoice::pick`]).

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::biomarker_calibration::BiomarkerCalibration;
use super::calibration::SpreadCalibration;
use super::model::{latent_coordinate, nn_error};
use super::monitor::StageMonitor;
use super::params::CalibrationKind;
use crate::eval::privacy::{CorrespondedShapes, correspondence_distance};
use crate::geometry::pca::Sampling;
use crate::models::beta_choice::{BetaCandidate, BetaChoice, NEAR_COPY_BOUND};
use crate::models::progress::{Progress, Stages};
use crate::models::{ModelError, near_copy_threshold};
use crate::nn::{BetaVaeConfig, BetaVaeTraining, TrainedBetaVae, train_weighted_beta_vae};

/// From this many training shapes on, β is used as given (near copies were rare there:
/// 0–1.3% of 1,000 draws on 100 LV or liver phantoms with β 1).
pub const CHOOSE_BELOW: usize = 50;
/// Fewest shapes β is chosen on (every fold's generator learns from at least four).
const CHOOSE_FROM: usize = 6;
/// Folds the shapes are split into.
const FOLDS: usize = 4;
/// Shapes drawn from each fold's generator.
const DRAWS_PER_FOLD: usize = 100;
/// The candidates, as multiples of the β asked for.
const BETA_FACTORS: [f64; 4] = [1.0, 3.0, 10.0, 30.0];

/// The shapes one generator learns from, as in [`super::generator::train_generator`].
pub(crate) struct SelectionData<'a> {
    /// Flattened shapes `[3·N_μ]`, mm.
    pub(crate) shapes: &'a [Vec<f32>],
    /// Weight per shape (`None`: all equal).
    pub(crate) weights: Option<&'a [f32]>,
    /// Cluster of the generator (`None`: the only one).
    pub(crate) cluster: Option<usize>,
    /// (volume ml, area cm²) of each shape's mesh, in `shapes`' order.
    pub(crate) measured: &'a [[f64; 2]],
    /// The atlas faces the shapes share.
    pub(crate) faces: &'a [[u32; 3]],
    /// How the model's draws are calibrated (`None`: not at all).
    pub(crate) calibration: Option<CalibrationKind>,
}

impl SelectionData<'_> {
    /// Draws calibrated as the model calibrates its draws, on a fold's training shapes.
    fn calibrated(&self, split: &Split, mut drawn: Vec<Vec<f32>>) -> Vec<Vec<f32>> {
        let training = split.pick(self.shapes);
        let weights = split.weights(self.weights);
        let weights = weights.as_deref();
        match self.calibration {
            Some(CalibrationKind::Biomarkers) => {
                // Without a row per shape the calibration measures the shapes themselves.
                let measured: Vec<[f64; 2]> = split
                    .training
                    .iter()
                    .filter_map(|&k| self.measured.get(k).copied())
                    .collect();
                let fitted =
                    BiomarkerCalibration::fit(&training, weights, &measured, &drawn, self.faces);
                if let Some(c) = fitted {
                    drawn.iter_mut().for_each(|s| c.apply(s, self.faces));
                }
            }
            Some(CalibrationKind::Modes) => {
                if let Some(c) = SpreadCalibration::fit(&training, weights, &drawn) {
                    drawn.iter_mut().for_each(|s| c.apply(s));
                }
            }
            None => {}
        }
        drawn
    }
}

/// Chooses β for a generator of `config` trained as `training` (whose `beta` is the smallest
/// candidate); `None` when there are too few or enough shapes, or β is 0: β stays as given.
pub(crate) fn choose_beta(
    data: &SelectionData<'_>,
    config: &BetaVaeConfig,
    training: &BetaVaeTraining,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Option<BetaChoice>, ModelError> {
    let n = data.shapes.len();
    if !(CHOOSE_FROM..CHOOSE_BELOW).contains(&n) || training.beta <= 0.0 {
        return Ok(None);
    }
    let folds = fold_of_each_shape(n, training.seed);
    let mut candidates = Vec::with_capacity(BETA_FACTORS.len());
    for (c, factor) in BETA_FACTORS.into_iter().enumerate() {
        let beta = training.beta * factor;
        let mut tally = Tally::default();
        for fold in 0..FOLDS {
            let before = (c * FOLDS + fold) * training.epochs;
            let split = Split::of(&folds, fold);
            let trial = BetaVaeTraining {
                beta,
                ..training.clone()
            };
            let name = format!("generator (β {beta} on fold {} of {FOLDS})", fold + 1);
            let mut monitor = StageMonitor::spanning(
                stages,
                progress,
                &name,
                training.epochs,
                (before, epochs_with_choice(training.epochs)),
            );
            let generator = train_weighted_beta_vae(
                &split.pick(data.shapes),
                split.weights(data.weights).as_deref(),
                config,
                &trial,
                &mut monitor,
            )
            .map_err(nn_error)?;
            tally.add_fold(&generator, data, &split, training.seed ^ fold as u64)?;
        }
        candidates.push(tally.candidate(beta));
        // Larger β only smooths more: stop at the first that keeps near copies in bound and
        // generalises no better than the one before.
        if stop_after(&candidates) {
            break;
        }
    }
    Ok(BetaChoice::pick(
        data.cluster,
        FOLDS,
        DRAWS_PER_FOLD,
        candidates,
    ))
}

/// Epochs of a generator stage that chooses β: every fold of every candidate and the
/// generator itself (the search may stop early; progress then jumps ahead).
pub(crate) fn epochs_with_choice(epochs: usize) -> usize {
    (BETA_FACTORS.len() * FOLDS + 1) * epochs
}

/// Whether the last candidate ends the search: within the near-copy bound and with a
/// held-out error no smaller than the candidate's before it.
fn stop_after(candidates: &[BetaCandidate]) -> bool {
    match candidates {
        [.., before, last] => {
            last.near_copy_fraction <= NEAR_COPY_BOUND
                && before.near_copy_fraction <= NEAR_COPY_BOUND
                && last.holdout_error_mm >= before.holdout_error_mm
        }
        _ => false,
    }
}

/// A seeded assignment of `n` shapes to [`FOLDS`] folds of nearly equal size.
fn fold_of_each_shape(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let mut fold = vec![0; n];
    for (position, &shape) in order.iter().enumerate() {
        fold[shape] = position % FOLDS;
    }
    fold
}

/// The shapes a fold's generator learns from and the ones it is tested on.
struct Split {
    training: Vec<usize>,
    held_out: Vec<usize>,
}

impl Split {
    fn of(folds: &[usize], fold: usize) -> Self {
        let (held_out, training) = (0..folds.len()).partition(|&k| folds[k] == fold);
        Self { training, held_out }
    }

    fn pick(&self, shapes: &[Vec<f32>]) -> Vec<Vec<f32>> {
        self.training.iter().map(|&k| shapes[k].clone()).collect()
    }

    fn weights(&self, weights: Option<&[f32]>) -> Option<Vec<f32>> {
        weights.map(|w| self.training.iter().map(|&k| w[k]).collect())
    }
}

/// Sums over the folds of one candidate.
#[derive(Default)]
struct Tally {
    near_copies: usize,
    draws: usize,
    /// Σ weight · held-out error (mm) and Σ weight.
    error_sum: f64,
    weight_sum: f64,
}

impl Tally {
    fn add_fold(
        &mut self,
        generator: &TrainedBetaVae,
        data: &SelectionData<'_>,
        split: &Split,
        seed: u64,
    ) -> Result<(), ModelError> {
        let training = split.pick(data.shapes);
        let weights = split.weights(data.weights);
        let compared = points(&generator.reconstruct(&training).map_err(nn_error)?);
        let threshold = near_copy_threshold(&compared)?.threshold_mm;
        let corresponded = CorrespondedShapes::new(&compared)?;
        let drawn = draws(generator, &training, weights.as_deref(), seed)?;
        for draw in points(&data.calibrated(split, drawn)) {
            if corresponded.nearest(&draw)?.distance_mm < threshold {
                self.near_copies += 1;
            }
            self.draws += 1;
        }
        let held_out: Vec<Vec<f32>> = split
            .held_out
            .iter()
            .map(|&k| data.shapes[k].clone())
            .collect();
        let reconstructed = points(&generator.reconstruct(&held_out).map_err(nn_error)?);
        for ((shape, again), &k) in points(&held_out)
            .iter()
            .zip(&reconstructed)
            .zip(&split.held_out)
        {
            let w = data.weights.map_or(1.0, |w| f64::from(w[k]));
            self.error_sum += w * correspondence_distance(shape, again);
            self.weight_sum += w;
        }
        Ok(())
    }

    fn candidate(&self, beta: f64) -> BetaCandidate {
        BetaCandidate {
            beta,
            near_copy_fraction: self.near_copies as f64 / self.draws.max(1) as f64,
            holdout_error_mm: if self.weight_sum > 0.0 {
                self.error_sum / self.weight_sum
            } else {
                f64::INFINITY
            },
        }
    }
}

/// [`DRAWS_PER_FOLD`] shapes drawn as cohorts draw them: clipped standard coordinates
/// through the Gaussian of the training shapes' codes.
fn draws(
    generator: &TrainedBetaVae,
    training: &[Vec<f32>],
    weights: Option<&[f32]>,
    seed: u64,
) -> Result<Vec<Vec<f32>>, ModelError> {
    let prior = generator
        .weighted_aggregate_prior(training, weights)
        .map_err(nn_error)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let codes: Vec<Vec<f32>> = (0..DRAWS_PER_FOLD)
        .map(|_| {
            let standard: Vec<f32> = (0..generator.config.latent)
                .map(|_| latent_coordinate(&mut rng, Sampling::Gaussian))
                .collect();
            prior.code(&standard)
        })
        .collect();
    generator.decode(&codes).map_err(nn_error)
}

/// Flattened shapes as points `[N_μ, 3]`, mm.
fn points(flat: &[Vec<f32>]) -> Vec<Vec<[f64; 3]>> {
    flat.iter()
        .map(|s| {
            s.chunks_exact(3)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                .collect()
        })
        .collect()
}

#[cfg(test)]
#[path = "beta_selection_tests.rs"]
mod tests;
