//! Spread calibration of a generator: a VAE's decoded samples vary less than the shapes it
//! was trained on (the decoder averages what the latent code does not pin down), so its
//! cohorts would be too narrow. After training, a seeded batch of drawn shapes is compared
//! with the training shapes along the training population's principal modes; every drawn
//! shape is then moved by one linear map of its coordinates on those modes so that the draws
//! have the training shapes' mean and covariance there (the optimal-transport map between
//! the two Gaussians). Matching each mode's sd alone is not enough: a generator's draws are
//! correlated across the modes, and a biomarker such as volume, which moves along several of
//! them, then varies less than in the training shapes even when every mode's sd is right.
//! What lies outside the modes is left as drawn, or pulled in when it varies more there than
//! the training shapes do. This is `calibration: "modes"`; the default moves draws along the
//! training shapes' regression on volume and area instead (see [`super::biomarker_calibration`]),
//! which keeps the draws' combinations of lengths and widths.
//!
//! Shapes are flattened atlas-domain vertex positions `[3·N_μ]` in mm.

use nalgebra::{DMatrix, SymmetricEigen};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::biomarker_calibration::{BiomarkerCalibration, biomarkers};
use super::model::{AsmgModel, latent_coordinate};
use super::params::CalibrationKind;
use crate::geometry::pca::Sampling;
use crate::models::ModelError;

/// Uncalibrated draws the corrections are estimated from, in antithetic pairs (a standard
/// latent vector and its negative, which cancel what is linear in the code). On 100 LV
/// phantoms the volume mean of 1,000 independent draws has an sd of 0.3 ml from one draw set
/// to another (0.2 ml in pairs); the biomarker calibration multiplies an error in it by
/// about 1.6 and hands it to every cohort, so 1,000 draws left cohorts up to 1.1% too large.
pub const CALIBRATION_DRAWS: usize = 8000;
/// Of those, the first ones the modes calibration (`calibration: "modes"`) is fitted to.
const MODES_CALIBRATION_DRAWS: usize = 2000;
/// Draws decoded at a time (even, so that pairs stay together).
const DECODE_BATCH: usize = 500;
/// Added to the fit seed for the calibration draws.
const CALIBRATION_SEED_OFFSET: u64 = 0x5bea_dca1;

/// Share of the training shapes' variance the calibrated modes explain.
pub const CALIBRATED_VARIANCE: f64 = 0.95;
/// Bounds of a mode's gain (and of the transform's eigenvalues): a direction the generator
/// barely varies is widened at most this much, one it over-varies narrowed at most to its
/// inverse. Generators of 100 LV phantoms vary some directions of the leading modes 8× less
/// than their training shapes; a bound of 4 kept their cohorts' volume sd at 0.78 of the
/// training meshes'.
pub const MAX_GAIN: f64 = 10.0;

/// Weights and weighted mean of training shapes, shared by both calibrations.
pub(super) struct WeightedShapes {
    /// One non-negative weight a shape (all 1 when none were given).
    pub w: Vec<f64>,
    /// Sum of the weights.
    pub total: f64,
    /// Weighted mean shape, `[3·N_μ]` mm.
    pub mean: Vec<f64>,
}

impl WeightedShapes {
    /// `None` when there are fewer than three shapes or the weights sum to zero.
    pub(super) fn of(training: &[Vec<f32>], weights: Option<&[f32]>) -> Option<Self> {
        let dim = training.first()?.len();
        if training.len() < 3 {
            return None;
        }
        let w: Vec<f64> = match weights {
            Some(w) if w.len() == training.len() => {
                w.iter().map(|&v| f64::from(v.max(0.0))).collect()
            }
            _ => vec![1.0; training.len()],
        };
        let total: f64 = w.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let mean = (0..dim)
            .map(|j| {
                training
                    .iter()
                    .zip(&w)
                    .map(|(x, w)| w * f64::from(x[j]))
                    .sum::<f64>()
                    / total
            })
            .collect();
        Some(Self { w, total, mean })
    }
}

/// Per-mode corrections of drawn shapes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpreadCalibration {
    /// The training shapes' (weighted) mean, `[3·N_μ]` mm.
    pub mean: Vec<f32>,
    /// Unit principal directions of the training shapes, `[K][3·N_μ]`.
    pub modes: Vec<Vec<f32>>,
    /// Mean coordinate of the uncalibrated draws along each mode, `[K]` mm.
    pub drawn_mean: Vec<f32>,
    /// Training sd over drawn sd along each mode, `[K]`.
    pub gain: Vec<f32>,
    /// Factor (≤ 1) on what a drawn shape has off the modes, so that the draws vary there
    /// no more than the training shapes do (1 in models stored before it existed).
    #[serde(default = "unit_gain")]
    pub residual_gain: f32,
    /// Map `[K][K]` (row-major rows) from a drawn shape's coordinates on the modes, less
    /// `drawn_mean`, to its calibrated coordinates: the draws then have the training shapes'
    /// covariance on the modes. Symmetric, eigenvalues within `[1/MAX_GAIN, MAX_GAIN]`.
    /// `None` in models stored before it existed, which scale each mode by `gain`.
    #[serde(default)]
    pub transform: Option<Vec<Vec<f32>>>,
}

fn unit_gain() -> f32 {
    1.0
}

impl SpreadCalibration {
    /// Fits the corrections from the training shapes (each with a weight, `None`: equal) and
    /// uncalibrated draws of the generator. `None` when there are too few shapes or draws
    /// to estimate a spread.
    pub fn fit(training: &[Vec<f32>], weights: Option<&[f32]>, drawn: &[Vec<f32>]) -> Option<Self> {
        let dim = training.first()?.len();
        if drawn.len() < 3 || drawn.iter().any(|d| d.len() != dim) {
            return None;
        }
        let WeightedShapes { w, total, mean } = WeightedShapes::of(training, weights)?;
        let (modes, variances, residual_variance) = principal_modes(training, &w, total, &mean)?;
        let mut calibration = Self {
            mean: mean.iter().map(|&v| v as f32).collect(),
            modes: modes
                .iter()
                .map(|m| m.iter().map(|&v| v as f32).collect())
                .collect(),
            drawn_mean: Vec::with_capacity(modes.len()),
            gain: Vec::with_capacity(modes.len()),
            residual_gain: 1.0,
            transform: None,
        };
        // Centred coordinates of the draws on the modes, `[draws][K]`.
        let mut coords: Vec<Vec<f64>> = drawn
            .iter()
            .map(|d| {
                (0..modes.len())
                    .map(|k| calibration.coordinate(d, k))
                    .collect()
            })
            .collect();
        let n = coords.len() as f64;
        for (k, variance) in variances.iter().enumerate() {
            let centre = coords.iter().map(|c| c[k]).sum::<f64>() / n;
            coords.iter_mut().for_each(|c| c[k] -= centre);
            let sd = (coords.iter().map(|c| c[k] * c[k]).sum::<f64>() / (n - 1.0)).sqrt();
            let gain = if sd > 0.0 {
                variance.sqrt() / sd
            } else {
                MAX_GAIN
            };
            calibration.drawn_mean.push(centre as f32);
            calibration
                .gain
                .push(gain.clamp(1.0 / MAX_GAIN, MAX_GAIN) as f32);
        }
        let transform = covariance_map(&coords, &variances);
        calibration.transform = Some(
            (0..transform.nrows())
                .map(|r| transform.row(r).iter().map(|&v| v as f32).collect())
                .collect(),
        );
        let drawn_residual = drawn
            .iter()
            .map(|d| calibration.residual(d).iter().map(|r| r * r).sum::<f64>())
            .sum::<f64>()
            / (drawn.len() as f64 - 1.0);
        if drawn_residual > residual_variance {
            calibration.residual_gain = (residual_variance / drawn_residual).sqrt() as f32;
        }
        Some(calibration)
    }

    /// Coordinate of `shape` along mode `k`, relative to the training mean (mm).
    fn coordinate(&self, shape: &[f32], k: usize) -> f64 {
        self.modes[k]
            .iter()
            .zip(shape.iter().zip(&self.mean))
            .map(|(u, (x, m))| f64::from(*u) * f64::from(x - m))
            .sum()
    }

    /// What `shape` has off the modes, relative to the training mean, `[3·N_μ]` mm.
    fn residual(&self, shape: &[f32]) -> Vec<f64> {
        let mut r: Vec<f64> = shape
            .iter()
            .zip(&self.mean)
            .map(|(x, m)| f64::from(x - m))
            .collect();
        for (k, mode) in self.modes.iter().enumerate() {
            let c = self.coordinate(shape, k);
            r.iter_mut()
                .zip(mode)
                .for_each(|(r, u)| *r -= c * f64::from(*u));
        }
        r
    }

    /// Moves a drawn shape so that its coordinates `c` on the modes become
    /// `transform · (c − drawn mean)` (`gain` per mode in models without a transform) and
    /// what it has off the modes is scaled by the residual gain; a shape of another width is
    /// left alone.
    pub fn apply(&self, shape: &mut [f32]) {
        if shape.len() != self.mean.len() {
            return;
        }
        let residual = self.residual(shape);
        let centred: Vec<f64> = (0..self.modes.len())
            .map(|k| self.coordinate(shape, k) - f64::from(self.drawn_mean[k]))
            .collect();
        let coords: Vec<f64> = match &self.transform {
            Some(map) => map
                .iter()
                .map(|row| {
                    row.iter()
                        .zip(&centred)
                        .map(|(a, c)| f64::from(*a) * c)
                        .sum()
                })
                .collect(),
            None => centred
                .iter()
                .zip(&self.gain)
                .map(|(c, g)| c * f64::from(*g))
                .collect(),
        };
        let residual_gain = f64::from(self.residual_gain);
        for (j, x) in shape.iter_mut().enumerate() {
            let on_modes: f64 = coords
                .iter()
                .zip(&self.modes)
                .map(|(c, u)| c * f64::from(u[j]))
                .sum();
            *x = (f64::from(self.mean[j]) + on_modes + residual_gain * residual[j]) as f32;
        }
    }

    /// Number of calibrated modes.
    pub fn mode_count(&self) -> usize {
        self.modes.len()
    }
}

impl AsmgModel {
    /// Fits and keeps the spread calibration that `params.calibration` names from the
    /// training shapes (flattened, mm; each with a weight, `None`: equal), the (volume ml,
    /// area cm²) of their meshes (used by the biomarker-directed one) and
    /// [`CALIBRATION_DRAWS`] draws (antithetic pairs) seeded from `seed`. The biomarker-directed one falls back
    /// to the modes when volume and area cannot be regressed on (fewer than three shapes, or
    /// the two do not vary independently).
    pub fn calibrate_spread(
        &mut self,
        training: &[Vec<f32>],
        weights: Option<&[f32]>,
        measured: &[[f64; 2]],
        seed: u64,
    ) -> Result<(), ModelError> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(CALIBRATION_SEED_OFFSET));
        let faces = &self.atlas.faces;
        // The modes calibration keeps the first draws; the biomarker one needs only each
        // draw's volume and area, so the draws are decoded a batch at a time.
        let mut kept = Vec::with_capacity(MODES_CALIBRATION_DRAWS);
        let mut rows = Vec::with_capacity(CALIBRATION_DRAWS);
        while rows.len() < CALIBRATION_DRAWS {
            let codes = self.antithetic_codes(&mut rng, DECODE_BATCH);
            let drawn = self.decode_uncalibrated(&codes)?;
            rows.extend(drawn.iter().map(|x| biomarkers(x, faces)));
            let room = MODES_CALIBRATION_DRAWS.saturating_sub(kept.len());
            kept.extend(drawn.into_iter().take(room));
        }
        self.biomarker_calibration = match self.params.calibration {
            CalibrationKind::Biomarkers => BiomarkerCalibration::fit_to_drawn_biomarkers(
                training, weights, measured, &rows, faces,
            ),
            CalibrationKind::Modes => None,
        };
        self.spread_calibration = match self.biomarker_calibration {
            Some(_) => None,
            None => SpreadCalibration::fit(training, weights, &kept),
        };
        Ok(())
    }

    /// `count` latent codes (even) drawn as cohorts draw them, in antithetic pairs: a
    /// standard latent vector and its negative.
    pub(super) fn antithetic_codes(&self, rng: &mut ChaCha8Rng, count: usize) -> Vec<Vec<f32>> {
        (0..count / 2)
            .flat_map(|_| {
                let standard: Vec<f32> = (0..self.sizes.vae_latent)
                    .map(|_| latent_coordinate(rng, Sampling::Gaussian))
                    .collect();
                let opposite = standard.iter().map(|v| -v).collect();
                [self.code_of(standard), self.code_of(opposite)]
            })
            .collect()
    }
}

/// The symmetric map `A` `[K][K]` that gives centred draw coordinates `[draws][K]` the
/// covariance `diag(variances)` (see [`transport_map`]).
fn covariance_map(coords: &[Vec<f64>], variances: &[f64]) -> DMatrix<f64> {
    let k = variances.len();
    let n = coords.len() as f64;
    let drawn = DMatrix::from_fn(k, k, |a, b| {
        coords.iter().map(|c| c[a] * c[b]).sum::<f64>() / (n - 1.0)
    });
    let target = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(variances));
    transport_map(drawn, &target)
}

/// The symmetric map `A = S^-½ (S^½ T S^½)^½ S^-½` that takes centred values of covariance
/// `S` to covariance `T` moving them least (the optimal-transport map between the two
/// Gaussians), its eigenvalues bounded by [`MAX_GAIN`] like the per-mode gains.
pub(super) fn transport_map(drawn: DMatrix<f64>, target: &DMatrix<f64>) -> DMatrix<f64> {
    // A direction the draws do not vary in at all gets the largest gain.
    let floor = target.diagonal().iter().copied().fold(0.0, f64::max) * 1e-12;
    let root = |m: DMatrix<f64>, power: f64| -> DMatrix<f64> {
        let e = SymmetricEigen::new(m);
        let d = e.eigenvalues.map(|v| v.max(floor).powf(power));
        &e.eigenvectors * DMatrix::from_diagonal(&d) * e.eigenvectors.transpose()
    };
    let drawn_root = root(drawn.clone(), 0.5);
    let drawn_inverse_root = root(drawn, -0.5);
    let middle = root(&drawn_root * target * &drawn_root, 0.5);
    let map = &drawn_inverse_root * middle * &drawn_inverse_root;
    let map = (&map + map.transpose()) * 0.5;
    let e = SymmetricEigen::new(map);
    let bounded = e.eigenvalues.map(|v| v.clamp(1.0 / MAX_GAIN, MAX_GAIN));
    &e.eigenvectors * DMatrix::from_diagonal(&bounded) * e.eigenvectors.transpose()
}

/// Unit principal directions `[K][dim]` of the weighted training shapes, their variances,
/// up to [`CALIBRATED_VARIANCE`] of the total, and the variance left off them (mm²), from
/// the `n × n` Gram matrix.
fn principal_modes(
    training: &[Vec<f32>],
    w: &[f64],
    total: f64,
    mean: &[f64],
) -> Option<(Vec<Vec<f64>>, Vec<f64>, f64)> {
    let n = training.len();
    let centred: Vec<Vec<f64>> = training
        .iter()
        .zip(w)
        .map(|(x, w)| {
            let s = (w / total).sqrt();
            x.iter()
                .zip(mean)
                .map(|(v, m)| s * (f64::from(*v) - m))
                .collect()
        })
        .collect();
    let gram = DMatrix::from_fn(n, n, |i, j| {
        centred[i]
            .iter()
            .zip(&centred[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    let eigen = SymmetricEigen::new(gram);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let sum: f64 = eigen.eigenvalues.iter().filter(|v| **v > 0.0).sum();
    if sum <= 0.0 {
        return None;
    }
    // Weighted variances are biased by the effective sample size; n/(n−1) for equal weights.
    let unbias = n as f64 / (n as f64 - 1.0);
    let (mut modes, mut variances, mut explained) = (Vec::new(), Vec::new(), 0.0);
    for &k in &order {
        let lambda = eigen.eigenvalues[k];
        if lambda <= sum * 1e-9 || explained >= CALIBRATED_VARIANCE * sum {
            break;
        }
        let v = eigen.eigenvectors.column(k);
        let dim = centred[0].len();
        let scale = lambda.sqrt();
        let mode: Vec<f64> = (0..dim)
            .map(|j| (0..n).map(|i| v[i] * centred[i][j]).sum::<f64>() / scale)
            .collect();
        modes.push(mode);
        variances.push(lambda * unbias);
        explained += lambda;
    }
    Some((modes, variances, (sum - explained).max(0.0) * unbias))
}

#[cfg(test)]
#[path = "calibration_tests.rs"]
mod tests;
