//! How a model's biomarkers move with its standard-normal draws: seeded pilot draws of each
//! cluster's generator and a least-squares linear fit `b ≈ a + G·ε` of their biomarkers.
//! With `ε ~ N(0, I)` this is the joint Gaussian of (code, biomarkers) that conditional
//! cohorts condition and the latent "modes" follow.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::{ModelError, ShapeModel};
use crate::eval::Biomarkers;
use crate::eval::metrics::parallel_map;

/// Standard-normal coordinates are clipped here, as the model's own draws are.
pub const STANDARD_CLIP: f64 = 3.0;
/// Salt of the pilot draws' seed, so that they never coincide with cohort draws.
const PILOT_SALT: u64 = 0x9170_7e55;

/// The pilot draws of one cluster and the linear fit of their biomarkers.
#[derive(Debug, Clone)]
pub struct LatentEffects {
    /// The cluster (atlas).
    pub cluster: usize,
    /// `a`: the fitted biomarkers at `ε = 0`, `[B]` in [`Biomarkers::NAMES`] order.
    pub intercept: DVector<f64>,
    /// `G`: the change of each biomarker per unit of each coordinate, `[B, L]`.
    pub gradient: DMatrix<f64>,
    /// Covariance of what the linear fit leaves unexplained, `[B, B]`.
    pub residual: DMatrix<f64>,
    /// Biomarkers of every pilot draw, `[n][B]`.
    pub pilot: Vec<[f64; 6]>,
}

/// Pilot draws per cluster: enough for a stable fit of `L + 1` coefficients.
pub fn pilot_size(dimension: usize) -> usize {
    (10 * (dimension + 1)).clamp(300, 2_000)
}

/// Clipped standard-normal vectors `[n][L]`, reproducible from `(seed, cluster)`.
fn standard_draws(seed: u64, cluster: usize, n: usize, dimension: usize) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ PILOT_SALT);
    rng.set_stream(cluster as u64);
    (0..n)
        .map(|_| {
            (0..dimension)
                .map(|_| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    z.clamp(-STANDARD_CLIP, STANDARD_CLIP)
                })
                .collect()
        })
        .collect()
}

/// The effects of cluster `cluster` of `model`, whose draws are `dimension`-long.
pub fn latent_effects<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    cluster: usize,
    dimension: usize,
    seed: u64,
) -> Result<LatentEffects, ModelError> {
    let n = pilot_size(dimension);
    let standard = standard_draws(seed, cluster, n, dimension);
    let meshes = model.decode_standard(cluster, &standard)?;
    let pilot = parallel_map(&meshes, |m| Biomarkers::from_mesh(m).map(|b| b.values()))
        .into_iter()
        .collect::<Result<Vec<_>, _>>()?;
    fit(cluster, &standard, pilot)
}

/// Least squares of `pilot` (`[n][B]`) on `[1, ε]` with a tiny ridge.
fn fit(
    cluster: usize,
    standard: &[Vec<f64>],
    pilot: Vec<[f64; 6]>,
) -> Result<LatentEffects, ModelError> {
    let (n, l) = (standard.len(), standard.first().map_or(0, Vec::len));
    let x = DMatrix::from_fn(
        n,
        l + 1,
        |i, j| if j == 0 { 1.0 } else { standard[i][j - 1] },
    );
    let y = DMatrix::from_fn(n, 6, |i, b| pilot[i][b]);
    let mut normal = x.transpose() * &x;
    for j in 1..=l {
        normal[(j, j)] += 1e-9 * n as f64;
    }
    let coefficients = normal
        .cholesky()
        .ok_or_else(|| ModelError::Numerical("pilot draws too few for a linear fit".into()))?
        .solve(&(x.transpose() * &y));
    let residuals = &y - &x * &coefficients;
    let dof = (n.saturating_sub(l + 1)).max(1) as f64;
    let residual = residuals.transpose() * &residuals / dof;
    Ok(LatentEffects {
        cluster,
        intercept: coefficients.row(0).transpose(),
        gradient: coefficients.rows(1, l).transpose(),
        residual,
        pilot,
    })
}

impl LatentEffects {
    /// The coordinate directions (unit vectors `[L]`) along which the biomarkers change
    /// most, each biomarker's change counted in units of its spread in the pilot draws:
    /// the right singular vectors of the standardised gradient, strongest first, each
    /// signed so that volume grows along it.
    pub fn strongest_directions(&self, count: usize) -> Vec<Vec<f64>> {
        let spread: Vec<f64> = (0..6)
            .map(|b| {
                let v: Vec<f64> = self.pilot.iter().map(|p| p[b]).collect();
                crate::eval::stats::sample_sd(&v).max(1e-12)
            })
            .collect();
        let scaled = DMatrix::from_fn(self.gradient.nrows(), self.gradient.ncols(), |b, j| {
            self.gradient[(b, j)] / spread[b]
        });
        let svd = scaled.svd(false, true);
        let Some(v_t) = svd.v_t else {
            return Vec::new();
        };
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
        order
            .into_iter()
            .take(count)
            .map(|k| {
                let d: Vec<f64> = v_t.row(k).iter().copied().collect();
                let volume_change: f64 = d
                    .iter()
                    .zip(self.gradient.row(0).iter())
                    .map(|(a, g)| a * g)
                    .sum();
                let sign = if volume_change < 0.0 { -1.0 } else { 1.0 };
                d.into_iter().map(|c| sign * c).collect()
            })
            .collect()
    }

    /// `[min, max]` of biomarker `b` over the pilot draws.
    pub fn pilot_range(&self, b: usize) -> (f64, f64) {
        self.pilot
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[b]), hi.max(p[b]))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_relation_is_recovered() {
        let standard = standard_draws(4, 0, 400, 3);
        let pilot: Vec<[f64; 6]> = standard
            .iter()
            .map(|e| {
                let v = 100.0 + 15.0 * e[0] - 2.0 * e[2];
                [v, 50.0 + 3.0 * e[1], 0.5, 1.0, 2.0, 3.0]
            })
            .collect();
        let fitted = fit(0, &standard, pilot).unwrap();
        assert!((fitted.intercept[0] - 100.0).abs() < 1e-6);
        assert!((fitted.gradient[(0, 0)] - 15.0).abs() < 1e-6);
        assert!((fitted.gradient[(0, 2)] + 2.0).abs() < 1e-6);
        assert!((fitted.gradient[(1, 1)] - 3.0).abs() < 1e-6);
        assert!(fitted.residual[(0, 0)].abs() < 1e-12);
        // Volume and area vary most along ε₀ and ε₁ (in units of their spread).
        let d = fitted.strongest_directions(2);
        assert_eq!(d.len(), 2);
        assert!(d[0][0] > 0.9 || d[1][0] > 0.9, "{d:?}");
        assert!(standard.iter().flatten().all(|z| z.abs() <= STANDARD_CLIP));
        assert_eq!(standard, standard_draws(4, 0, 400, 3));
        assert_ne!(standard, standard_draws(4, 1, 400, 3));
    }
}
