//! Attention correspondences between the atlas and a shape (thesis eqs. 4.2–4.3, SPEC §2.5).
//!
//! With unit-length embeddings `Z_μ` (`[N_μ, d]`) and `Z_k` (`[N_k, d]`), the scores are the
//! cosine similarities `S_k = Z_μ Z_kᵀ` (`[N_μ, N_k]`), the soft correspondences are
//! `Φ_k = softmax over i of λ·S_k` (each row sums to one) and the normalised shape is
//! `h_k = Φ_k X_k` (`[N_μ, 3]`, mm).
//!
//! `Φ_k` is never stored: the scores of a block of 16 atlas rows (`[16, N_k]`) are
//! exponentiated and folded into `h_kj` on the spot, and the blocks are shared over the
//! cores. An inverse-variance temperature needs the variance of all scores first, which
//! costs one more streaming pass over `S_k`. Per shape, as asked here; the thesis pools the
//! variance over all shapes, which [`score_moments`] and [`Temperature::Fixed`] allow.

use std::ops::Range;

use super::embeddings::Embeddings;
use super::parallel::map_blocks;
use super::scores::Scores;
use crate::models::ModelError;

/// Atlas rows per work block (fixed, so results do not depend on the thread count).
const ROW_BLOCK: usize = 16;

/// Thesis setting of the inverse-variance multiplier (λ = 1 / variance of the scores).
pub const THESIS_VARIANCE_MULTIPLIER: f64 = 1.0;

/// Default multiplier: SPEC §2.9 found λ = 1/variance too soft once Ψ is trained and ≈ 30×
/// that sharp enough to keep the shape; 120× (with γ = 0.1) keeps the population's spread:
/// on 100 LV phantoms the normalised shapes match held-out meshes to 0.29 mm (point-to-surface
/// CD, against 0.93 mm at 30×) and the cohort's volume sd rises from 0.61 to 0.88 of the
/// training meshes' with the spread calibration.
pub const DEFAULT_VARIANCE_MULTIPLIER: f64 = 120.0;

/// Score variances at or below this are treated as zero (all scores equal): it is far
/// below any real spread of cosine similarities and above the `f32` rounding noise of equal
/// ones (≈ 1e-14).
pub const SCORE_VARIANCE_FLOOR: f64 = 1e-10;

/// How the inverse temperature λ of the softmax is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Temperature {
    /// `λ = multiplier / variance of all entries of S_k` (thesis: multiplier 1).
    InverseVariance {
        /// Factor on the inverse variance (> 0).
        multiplier: f64,
    },
    /// A fixed `λ ≥ 0` on the cosine similarities.
    Fixed(f64),
}

impl Default for Temperature {
    fn default() -> Self {
        Self::InverseVariance {
            multiplier: DEFAULT_VARIANCE_MULTIPLIER,
        }
    }
}

/// Mean and (population) variance of all entries of a score matrix `S_k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoreMoments {
    /// Number of entries, `N_μ · N_k`.
    pub count: usize,
    /// Mean score.
    pub mean: f64,
    /// Variance of the scores.
    pub variance: f64,
}

impl Temperature {
    /// The inverse temperature λ for scores with these moments. A variance at or below
    /// [`SCORE_VARIANCE_FLOOR`] (all scores equal) gives λ = 0: uniform weights, which any
    /// λ would give for truly equal scores.
    pub fn lambda(&self, moments: &ScoreMoments) -> Result<f64, ModelError> {
        match *self {
            Self::Fixed(lambda) if lambda.is_finite() && lambda >= 0.0 => Ok(lambda),
            Self::Fixed(lambda) => Err(ModelError::invalid(
                "temperature",
                format!("a fixed inverse temperature must be finite and >= 0, got {lambda}"),
            )),
            Self::InverseVariance { multiplier } if multiplier.is_finite() && multiplier > 0.0 => {
                if moments.variance > SCORE_VARIANCE_FLOOR {
                    Ok(multiplier / moments.variance)
                } else {
                    Ok(0.0)
                }
            }
            Self::InverseVariance { multiplier } => Err(ModelError::invalid(
                "temperature",
                format!("the variance multiplier must be finite and > 0, got {multiplier}"),
            )),
        }
    }

    fn needs_moments(&self) -> bool {
        matches!(self, Self::InverseVariance { .. })
    }
}

/// The input vertex an atlas vertex corresponds to most.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Index of the input vertex with the largest weight (argmax of the row of `Φ_k`).
    pub index: u32,
    /// Its weight `Φ_k[j, index]` in `(0, 1]`.
    pub weight: f64,
}

/// The correspondence of one shape to the atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct Correspondence {
    /// The normalised shape `h_k = Φ_k X_k`, `[N_μ, 3]`, mm.
    pub normalised: Vec<[f64; 3]>,
    /// For each atlas vertex, its best-matching input vertex, `[N_μ]` (diagnostics).
    pub matches: Vec<Match>,
    /// The inverse temperature λ used.
    pub lambda: f64,
}

/// Log-weights below this are skipped: with the largest weight 1, even 25,800 such terms
/// add less than `f64` resolution to a row's sum.
const MIN_LOG_WEIGHT: f64 = -50.0;

/// Calls `visit(i, w_i)` with the unnormalised softmax weights
/// `w_i = exp(λ (s_i − max s))` of one row of scores (skipping negligible ones); returns
/// `(Σ w_i, argmax)`.
fn softmax_row(scores: &[f32], lambda: f64, mut visit: impl FnMut(usize, f64)) -> (f64, usize) {
    let mut best = 0;
    for (i, s) in scores.iter().enumerate() {
        if *s > scores[best] {
            best = i;
        }
    }
    let max = scores.get(best).map_or(0.0, |&s| f64::from(s));
    let mut sum = 0.0;
    for (i, s) in scores.iter().enumerate() {
        let log_weight = lambda * (f64::from(*s) - max);
        if log_weight >= MIN_LOG_WEIGHT {
            let w = log_weight.exp();
            sum += w;
            visit(i, w);
        }
    }
    (sum, best)
}

/// Mean and variance of all entries of `S_k = Z_μ Z_kᵀ` (unit-length rows), in one
/// streaming pass. Useful to pool a temperature over several shapes.
pub fn score_moments(atlas: &Embeddings, shape: &Embeddings) -> Result<ScoreMoments, ModelError> {
    let scores = Scores::new(atlas, shape)?;
    Ok(moments_of(&scores))
}

fn moments_of(scores: &Scores<'_>) -> ScoreMoments {
    let partials = map_blocks(
        scores.atlas_rows(),
        ROW_BLOCK,
        scores.cost_per_row(),
        |rows| {
            let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
            for &s in scores.block(rows).values() {
                let s = f64::from(s);
                sum += s;
                sum_sq += s * s;
            }
            (sum, sum_sq)
        },
    );
    let (sum, sum_sq) = partials
        .into_iter()
        .fold((0.0, 0.0), |(a, b), (c, d)| (a + c, b + d));
    let count = scores.atlas_rows() * scores.shape_rows();
    let mean = sum / count as f64;
    ScoreMoments {
        count,
        mean,
        variance: (sum_sq / count as f64 - mean * mean).max(0.0),
    }
}

fn lambda_of(scores: &Scores<'_>, temperature: Temperature) -> Result<f64, ModelError> {
    let moments = if temperature.needs_moments() {
        moments_of(scores)
    } else {
        ScoreMoments {
            count: 0,
            mean: 0.0,
            variance: 0.0,
        }
    };
    temperature.lambda(&moments)
}

/// The inverse temperature λ that `temperature` gives for this atlas and shape.
pub fn inverse_temperature(
    atlas: &Embeddings,
    shape: &Embeddings,
    temperature: Temperature,
) -> Result<f64, ModelError> {
    lambda_of(&Scores::new(atlas, shape)?, temperature)
}

/// Soft correspondences of `shape` (embeddings `[N_k, d]`, vertex positions `[N_k, 3]` mm)
/// to the atlas (embeddings `[N_μ, d]`): the normalised shape and the best match of every
/// atlas vertex. Deterministic; uses the available cores for large inputs.
pub fn correspond(
    atlas: &Embeddings,
    shape: &Embeddings,
    positions: &[[f64; 3]],
    temperature: Temperature,
) -> Result<Correspondence, ModelError> {
    let scores = Scores::new(atlas, shape)?;
    if positions.len() != shape.rows {
        return Err(ModelError::InvalidInput(format!(
            "the shape has {} embeddings but {} vertex positions",
            shape.rows,
            positions.len()
        )));
    }
    let lambda = lambda_of(&scores, temperature)?;
    let blocks = map_blocks(atlas.rows, ROW_BLOCK, scores.cost_per_row(), |rows| {
        normalise_rows(&scores, positions, lambda, rows)
    });
    let mut normalised = Vec::with_capacity(atlas.rows);
    let mut matches = Vec::with_capacity(atlas.rows);
    for (h, m) in blocks.into_iter().flatten() {
        normalised.push(h);
        matches.push(m);
    }
    Ok(Correspondence {
        normalised,
        matches,
        lambda,
    })
}

fn normalise_rows(
    scores: &Scores<'_>,
    positions: &[[f64; 3]],
    lambda: f64,
    rows: Range<usize>,
) -> Vec<([f64; 3], Match)> {
    let block = scores.block(rows.clone());
    (0..rows.len())
        .map(|r| {
            let mut acc = [0.0f64; 3];
            let (sum, best) = softmax_row(block.row(r), lambda, |i, w| {
                let x = positions[i];
                acc[0] += w * x[0];
                acc[1] += w * x[1];
                acc[2] += w * x[2];
            });
            // The argmax term is exp(0) = 1, so sum ≥ 1.
            let h = [acc[0] / sum, acc[1] / sum, acc[2] / sum];
            let m = Match {
                index: best as u32,
                weight: 1.0 / sum,
            };
            (h, m)
        })
        .collect()
}

/// The normalised shape `h_k = Φ_k X_k` (`[N_μ, 3]`, mm); see [`correspond`].
pub fn normalised_shape(
    atlas: &Embeddings,
    shape: &Embeddings,
    positions: &[[f64; 3]],
    temperature: Temperature,
) -> Result<Vec<[f64; 3]>, ModelError> {
    correspond(atlas, shape, positions, temperature).map(|c| c.normalised)
}

/// Rows `rows` of `Φ_k` for a given λ, row-major `[rows.len(), N_k]` (diagnostics and
/// tests; a whole `Φ_k` is large, ask for blocks).
pub fn attention_rows(
    atlas: &Embeddings,
    shape: &Embeddings,
    lambda: f64,
    rows: Range<usize>,
) -> Result<Vec<f64>, ModelError> {
    let scores = Scores::new(atlas, shape)?;
    if rows.start > rows.end || rows.end > atlas.rows {
        return Err(ModelError::InvalidInput(format!(
            "rows {rows:?} are outside the atlas's {} rows",
            atlas.rows
        )));
    }
    if !(lambda.is_finite() && lambda >= 0.0) {
        return Err(ModelError::InvalidInput(format!(
            "the inverse temperature must be finite and >= 0, got {lambda}"
        )));
    }
    let n_k = shape.rows;
    let mut out = vec![0.0; rows.len() * n_k];
    let block = scores.block(rows);
    for (r, row) in out.chunks_exact_mut(n_k).enumerate() {
        let (sum, _) = softmax_row(block.row(r), lambda, |i, w| row[i] = w);
        row.iter_mut().for_each(|w| *w /= sum);
    }
    Ok(out)
}

#[cfg(test)]
#[path = "attention_tests.rs"]
mod tests;
