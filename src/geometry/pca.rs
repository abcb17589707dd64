//! PCA shape model (thesis eqs. 3.11–3.15, SPEC §2.3): mean shape, orthonormal modes and
//! their variances from a thin SVD of the centred training matrix.
//!
//! Shapes are flattened point lists of length `D = 3M` (see
//! [`flatten`](super::correspondence::flatten)), in mm.

use faer::Mat;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::GeometryError;

/// Coefficients are limited to `±COEFFICIENT_LIMIT_SD·√λᵢ` (β = 3 in the thesis).
pub const COEFFICIENT_LIMIT_SD: f64 = 3.0;
/// Modes with `λᵢ ≤ RELATIVE_VARIANCE_FLOOR·λ₁` are numerical noise and dropped.
pub const RELATIVE_VARIANCE_FLOOR: f64 = 1e-12;
/// Slack when comparing the cumulative explained variance with a target.
const VARIANCE_TARGET_SLACK: f64 = 1e-12;

/// How many modes to keep. With both set, the smaller of the two counts is kept; with
/// neither, all modes are kept.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PcaParams {
    /// Keep at most this many modes (≥ 1).
    pub n_modes: Option<usize>,
    /// Keep the fewest modes whose cumulative explained variance (eq. 3.15) reaches this
    /// fraction, in `(0, 1]`.
    pub variance_target: Option<f64>,
}

impl PcaParams {
    /// Checks the ranges of the parameters.
    pub fn check(&self) -> Result<(), GeometryError> {
        if self.n_modes == Some(0) {
            return Err(GeometryError::InvalidParams(
                "pca n_modes must be >= 1".into(),
            ));
        }
        if let Some(t) = self.variance_target
            && !(t > 0.0 && t <= 1.0)
        {
            return Err(GeometryError::InvalidParams(format!(
                "pca variance_target must be in (0, 1], got {t}"
            )));
        }
        Ok(())
    }

    /// Number of modes to keep given the cumulative explained variance of all modes.
    pub fn select(&self, cumulative_explained: &[f64]) -> usize {
        let all = cumulative_explained.len();
        let by_target = self.variance_target.map_or(all, |t| {
            cumulative_explained
                .iter()
                .position(|c| *c >= t - VARIANCE_TARGET_SLACK)
                .map_or(all, |i| i + 1)
        });
        self.n_modes
            .map_or(by_target, |n| n.min(by_target))
            .min(all)
    }
}

/// How shape coefficients `bᵢ` are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// `bᵢ ~ N(0, λᵢ)`, clipped to `±3√λᵢ`.
    #[default]
    Gaussian,
    /// `bᵢ` uniform in `[−3√λᵢ, 3√λᵢ]`.
    Uniform,
}

/// A linear shape model `x ≈ mean + Σᵢ bᵢ·modeᵢ`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PcaModel {
    /// Mean shape, `[D]` (mm).
    pub mean: Vec<f64>,
    /// Kept modes, `[L][D]`, orthonormal, ordered by decreasing variance; each mode's
    /// largest-magnitude component is positive.
    pub modes: Vec<Vec<f64>>,
    /// Variances `λᵢ = sᵢ²/(K − 1)` of the kept modes, `[L]` (mm²).
    pub variances: Vec<f64>,
    /// Cumulative explained variance (eq. 3.15) of every non-degenerate mode found at fit
    /// time (not only the kept ones); increasing, ending at 1.
    pub cumulative_explained: Vec<f64>,
}

fn check_samples(samples: &[Vec<f64>]) -> Result<usize, GeometryError> {
    if samples.len() < 2 {
        return Err(GeometryError::TooFewShapes {
            required: 2,
            found: samples.len(),
        });
    }
    let d = samples[0].len();
    if d == 0 {
        return Err(GeometryError::DegenerateInput(
            "shapes have no coordinates".into(),
        ));
    }
    for s in samples {
        if s.len() != d {
            return Err(GeometryError::DimensionMismatch {
                what: "shape",
                expected: d,
                found: s.len(),
            });
        }
        if s.iter().any(|v| !v.is_finite()) {
            return Err(GeometryError::NonFinite { what: "shape" });
        }
    }
    Ok(d)
}

/// Singular values and right singular vectors (one `Vec` of length `D` per value) of the
/// centred `[K, D]` sample matrix. faer's vectorised kernels run on a thread of their own:
/// they can leave the calling thread's vector unit in a state that slows later scalar
/// floating-point code (registration, distances) many times over.
fn thin_svd_on_own_thread(
    samples: &[Vec<f64>],
    mean: &[f64],
) -> Result<(Vec<f64>, Vec<Vec<f64>>), GeometryError> {
    let decompose = || {
        let centred =
            Mat::<f64>::from_fn(samples.len(), mean.len(), |i, j| samples[i][j] - mean[j]);
        let svd = centred.thin_svd().map_err(|_| GeometryError::SvdFailed)?;
        let (s, v) = (svd.S().column_vector(), svd.V());
        let singular: Vec<f64> = (0..s.nrows()).map(|i| s[i]).collect();
        let vectors = (0..s.nrows())
            .map(|i| (0..mean.len()).map(|j| v[(j, i)]).collect())
            .collect();
        Ok((singular, vectors))
    };
    std::thread::scope(|scope| scope.spawn(decompose).join())
        .unwrap_or(Err(GeometryError::SvdFailed))
}

impl PcaModel {
    /// Fits all non-degenerate modes to `K ≥ 2` flattened shapes of equal length `D`.
    pub fn fit(samples: &[Vec<f64>]) -> Result<Self, GeometryError> {
        let d = check_samples(samples)?;
        let k = samples.len();
        let mean: Vec<f64> = (0..d)
            .map(|j| samples.iter().map(|s| s[j]).sum::<f64>() / k as f64)
            .collect();
        let (singular, v) = thin_svd_on_own_thread(samples, &mean)?;
        let rank = singular.len().min(k - 1);
        let all: Vec<f64> = (0..rank)
            .map(|i| singular[i] * singular[i] / (k - 1) as f64)
            .collect();
        let top = all.first().copied().unwrap_or(0.0);
        if top <= 0.0 {
            return Err(GeometryError::DegenerateInput(
                "all shapes are identical".into(),
            ));
        }
        let kept = all
            .iter()
            .take_while(|l| **l > RELATIVE_VARIANCE_FLOOR * top)
            .count();
        let variances = all[..kept].to_vec();
        let modes = (0..kept).map(|i| oriented(v[i].clone())).collect();
        let total: f64 = variances.iter().sum();
        let cumulative_explained = variances
            .iter()
            .scan(0.0, |acc, l| {
                *acc += l;
                Some(*acc / total)
            })
            .collect();
        Ok(Self {
            mean,
            modes,
            variances,
            cumulative_explained,
        })
    }

    /// Fits and keeps the number of modes chosen by `params`.
    pub fn fit_with(samples: &[Vec<f64>], params: &PcaParams) -> Result<Self, GeometryError> {
        params.check()?;
        let mut model = Self::fit(samples)?;
        model.truncate(params.select(&model.cumulative_explained));
        Ok(model)
    }

    /// Keeps only the first `n_modes` modes (the cumulative curve is left whole).
    pub fn truncate(&mut self, n_modes: usize) {
        self.modes.truncate(n_modes);
        self.variances.truncate(n_modes);
    }

    /// Length `D` of a flattened shape.
    pub fn dimension(&self) -> usize {
        self.mean.len()
    }

    /// Number of kept modes `L`.
    pub fn n_modes(&self) -> usize {
        self.modes.len()
    }

    /// Shape coefficients `b = Uᵀ(x − mean)` (eq. 3.14), `[L]`.
    pub fn project(&self, x: &[f64]) -> Result<Vec<f64>, GeometryError> {
        if x.len() != self.dimension() {
            return Err(GeometryError::DimensionMismatch {
                what: "shape",
                expected: self.dimension(),
                found: x.len(),
            });
        }
        Ok(self
            .modes
            .iter()
            .map(|m| {
                m.iter()
                    .zip(x)
                    .zip(&self.mean)
                    .map(|((u, xi), mu)| u * (xi - mu))
                    .sum()
            })
            .collect())
    }

    /// The shape `mean + U·b` (eq. 3.13), `[D]`. `b` may be shorter than `L` (the rest
    /// count as zero) but not longer.
    pub fn reconstruct(&self, b: &[f64]) -> Result<Vec<f64>, GeometryError> {
        if b.len() > self.n_modes() {
            return Err(GeometryError::DimensionMismatch {
                what: "coefficients",
                expected: self.n_modes(),
                found: b.len(),
            });
        }
        Ok(self.combine(b))
    }

    /// `mean + U·b` for `b` no longer than `L`.
    fn combine(&self, b: &[f64]) -> Vec<f64> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { combine_avx2(&self.mean, &self.modes, b) };
        }
        combine_baseline(&self.mean, &self.modes, b)
    }

    /// Random coefficients `[L]` limited to `±3√λᵢ`.
    pub fn sample_coefficients<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        sampling: Sampling,
    ) -> Vec<f64> {
        self.variances
            .iter()
            .map(|l| {
                let limit = COEFFICIENT_LIMIT_SD * l.sqrt();
                match sampling {
                    Sampling::Gaussian => {
                        let z: f64 = StandardNormal.sample(rng);
                        (z * l.sqrt()).clamp(-limit, limit)
                    }
                    Sampling::Uniform => limit * (2.0 * rng.random::<f64>() - 1.0),
                }
            })
            .collect()
    }

    /// A random shape `[D]` from [`sample_coefficients`](Self::sample_coefficients).
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R, sampling: Sampling) -> Vec<f64> {
        let b = self.sample_coefficients(rng, sampling);
        self.combine(&b)
    }
}

/// [`combine_baseline`] compiled for AVX2: four coordinates at a time, the same multiplies
/// and adds in the same order (no fused multiply-add), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn combine_avx2(mean: &[f64], modes: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    combine_baseline(mean, modes, b)
}

/// `mean + Σᵢ bᵢ·modes[i]`, mode by mode.
#[inline(always)]
fn combine_baseline(mean: &[f64], modes: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let mut x = mean.to_vec();
    for (bi, m) in b.iter().zip(modes) {
        for (xj, uj) in x.iter_mut().zip(m) {
            *xj += bi * uj;
        }
    }
    x
}

/// Flips a mode so that its largest-magnitude component is positive (a stable sign).
fn oriented(mut mode: Vec<f64>) -> Vec<f64> {
    let largest = mode
        .iter()
        .copied()
        .fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a });
    if largest < 0.0 {
        mode.iter_mut().for_each(|v| *v = -*v);
    }
    mode
}

#[cfg(test)]
mod tests;
