//! RSMP draws from a smoothed bootstrap of the training shapes' mode coefficients: a random
//! training shape's standard coefficients shrunk by `√(1 − h²)` plus `h` times a standard
//! normal vector, so that the draws keep the coefficients' variance and their joint shape.

use cohortforge::eval::privacy::CorrespondedShapes;
use cohortforge::geometry::correspondence::flatten;
use cohortforge::mesh::Mesh;
use cohortforge::models::ShapeModel;
use cohortforge::models::rsmp::RsmpModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Each normalised training shape's standard coefficients `b / √λ`.
pub fn standard_coefficients(rsmp: &RsmpModel, normalised: &[Vec<[f64; 3]>]) -> Vec<Vec<f64>> {
    normalised
        .iter()
        .map(|shape| {
            let x = flatten(
                &shape
                    .iter()
                    .map(|p| rsmp.normalisation.apply(*p))
                    .collect::<Vec<_>>(),
            );
            let b = rsmp.pca.project(&x).unwrap();
            b.iter()
                .zip(&rsmp.pca.variances)
                .map(|(b, l)| b / l.sqrt())
                .collect()
        })
        .collect()
}

/// `draws` draws with kernel width `h` (share of each mode's sd): a random training shape's
/// standard coefficients (with `modewise`, each mode's from its own random training shape)
/// shrunk by `√(1 − h²)`, plus `h` times a standard normal value.
pub fn bootstrap_draws(
    rsmp: &RsmpModel,
    coefficients: &[Vec<f64>],
    (h, modewise): (f64, bool),
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
                    if modewise {
                        parent = rng.random_range(0..coefficients.len());
                    }
                    shrink * coefficients[parent][k] + h * rng.sample::<f64, _>(StandardNormal)
                })
                .collect()
        })
        .collect();
    rsmp.decode_standard(0, &standard).unwrap()
}

/// Share (%) of `drawn` nearer a regenerated training shape than the 5th percentile of the
/// regenerated shapes' own nearest-neighbour distances.
pub fn near_copy_percent(rsmp: &RsmpModel, normalised: &[Vec<[f64; 3]>], drawn: &[Mesh]) -> f64 {
    let regenerated = rsmp
        .regenerated_training(&[normalised.to_vec()])
        .unwrap()
        .unwrap()
        .remove(0);
    let shapes = CorrespondedShapes::new(&regenerated).unwrap();
    let threshold = shapes.privacy_threshold(0.05).unwrap().threshold_mm;
    let near = drawn
        .iter()
        .filter(|m| shapes.nearest(&m.vertices).unwrap().distance_mm < threshold)
        .count();
    100.0 * near as f64 / drawn.len() as f64
}
