//! RSMP draws from a smoothed bootstrap of the training shapes' mode coefficients: a random
//! training shape's standard coefficients shrunk by `√(1 − h²)` plus `h` times a standard
//! normal vector, so that the draws keep the coefficients' variance and their joint shape.

use cohortforge::eval::privacy::CorrespondedShapes;
use cohortforge::mesh::Mesh;
use cohortforge::models::ShapeModel;
use cohortforge::models::rsmp::RsmpModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Each training shape's standard coefficients `b / √λ`, from those the model stores (fits
/// of 20 meshes or more with `empirical_coefficients`).
pub fn standard_coefficients(rsmp: &RsmpModel) -> Option<Vec<Vec<f64>>> {
    let by_mode = &rsmp.mode_coefficients.as_ref()?.by_mode;
    let shapes = by_mode.first().map_or(0, Vec::len);
    Some(
        (0..shapes)
            .map(|i| {
                by_mode
                    .iter()
                    .zip(&rsmp.pca.variances)
                    .map(|(values, l)| values[i] / l.sqrt())
                    .collect()
            })
            .collect(),
    )
}

/// `draws` draws with kernel width `h` (share of each mode's sd): a random training shape's
/// standard coefficients shrunk by `√(1 − h²)`, plus `h` times a standard normal value. The
/// first `independent` modes each take their own random training shape, the rest one
/// shape together (0: every mode from one shape, the bootstrap; all: mode-wise).
pub fn bootstrap_draws(
    rsmp: &RsmpModel,
    coefficients: &[Vec<f64>],
    (h, independent): (f64, usize),
    draws: usize,
    seed: u64,
) -> Vec<Mesh> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let shrink = (1.0 - h * h).sqrt();
    let modes = coefficients[0].len();
    let standard: Vec<Vec<f64>> = (0..draws)
        .map(|_| {
            let mut parent = rng.random_range(0..coefficients.len());
            (0..modes)
                .map(|k| {
                    if k > 0 && k <= independent {
                        parent = rng.random_range(0..coefficients.len());
                    }
                    shrink * coefficients[parent][k] + h * rng.sample::<f64, _>(StandardNormal)
                })
                .collect()
        })
        .collect();
    rsmp.decode_standard(0, &standard).unwrap()
}

/// The regenerated training shapes and the 5th percentile of their own nearest-neighbour
/// distances (mm), against which draws are near copies.
pub struct NearCopies {
    shapes: CorrespondedShapes,
    threshold_mm: f64,
}

impl NearCopies {
    pub fn new(rsmp: &RsmpModel, normalised: &[Vec<[f64; 3]>]) -> Self {
        let regenerated = rsmp
            .regenerated_training(&[normalised.to_vec()])
            .unwrap()
            .unwrap()
            .remove(0);
        let shapes = CorrespondedShapes::new(&regenerated).unwrap();
        let threshold_mm = shapes.privacy_threshold(0.05).unwrap().threshold_mm;
        Self {
            shapes,
            threshold_mm,
        }
    }

    /// Share (%) of `drawn` nearer a regenerated training shape than the threshold.
    pub fn percent(&self, drawn: &[Mesh]) -> f64 {
        let near = drawn
            .iter()
            .filter(|m| self.shapes.nearest(&m.vertices).unwrap().distance_mm < self.threshold_mm)
            .count();
        100.0 * near as f64 / drawn.len() as f64
    }
}
