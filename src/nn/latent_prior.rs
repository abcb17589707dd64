//! The Gaussian new latent codes are drawn from.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A Gaussian over latent codes, `z = centre + mixing · ε` with `ε ~ N(0, I)`, `[L]`.
///
/// The standard normal is the VAE's own prior. Fitted to the codes of the training shapes
/// ([`TrainedBetaVae::aggregate_prior`]) it draws shapes as varied as the training set: with a
/// small β the codes spread far beyond N(0, I), and draws from it were all close to the mean
/// shape (volume sd 1–3 ml against 14 ml on 40 LV phantoms). The codes of the training
/// shapes are correlated, so the Gaussian keeps their full covariance: drawing every
/// dimension independently loses the covariances, and with them much of the spread along
/// directions such as size that several dimensions share.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentPrior {
    /// Mean code, `[L]`.
    pub centre: Vec<f32>,
    /// Standard deviation per latent dimension, `[L]` (the square roots of the diagonal of
    /// the covariance).
    pub spread: Vec<f32>,
    /// Lower-triangular Cholesky factor of the covariance, `[L, L]` row-major; empty: the
    /// dimensions are independent with standard deviations `spread`.
    pub mixing: Vec<f32>,
}

impl LatentPrior {
    /// N(0, I) in `latent` dimensions.
    pub fn standard(latent: usize) -> Self {
        Self {
            centre: vec![0.0; latent],
            spread: vec![1.0; latent],
            mixing: Vec::new(),
        }
    }

    /// The Gaussian with mean `centre` and covariance `covariance` (`[L, L]`, symmetric
    /// positive semi-definite; a tiny ridge is added when it is singular).
    pub fn with_covariance(centre: Vec<f32>, covariance: &DMatrix<f64>) -> Self {
        let latent = centre.len();
        let spread = (0..latent)
            .map(|d| covariance[(d, d)].max(0.0).sqrt() as f32)
            .collect();
        let ridge = 1e-9 * covariance.trace().abs().max(1e-12) / latent.max(1) as f64;
        let factor = [0.0, ridge, 1e3 * ridge].into_iter().find_map(|r| {
            let regularised = covariance + DMatrix::<f64>::identity(latent, latent) * r;
            regularised.cholesky().map(|c| c.l())
        });
        let mixing = factor.map_or_else(Vec::new, |l| {
            (0..latent)
                .flat_map(|i| (0..latent).map(move |j| (i, j)))
                .map(|(i, j)| l[(i, j)] as f32)
                .collect()
        });
        Self {
            centre,
            spread,
            mixing,
        }
    }

    /// The code of a standard-normal draw `ε` (`[L]`).
    pub fn code(&self, standard: &[f32]) -> Vec<f32> {
        let latent = self.centre.len();
        if self.mixing.len() != latent * latent {
            return standard
                .iter()
                .zip(self.centre.iter().zip(&self.spread))
                .map(|(e, (c, s))| c + s * e)
                .collect();
        }
        (0..latent)
            .map(|i| {
                let row = &self.mixing[i * latent..(i + 1) * latent];
                self.centre[i] + row.iter().zip(standard).map(|(l, e)| l * e).sum::<f32>()
            })
            .collect()
    }
}
