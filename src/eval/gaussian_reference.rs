//! The acceptance a Gaussian generator can be expected to reach: draws from the multivariate
//! normal with the reference biomarkers' mean and covariance, judged by the reference's own
//! intervals.
//!
//! A model that draws shapes from a Gaussian latent space (PCA scores, a VAE's codes) gives
//! biomarkers that are close to jointly Gaussian. A population whose biomarkers have lighter
//! tails than a Gaussian (sizes bounded on both sides, say) falls inside `μ ± 2σ` more often
//! than the 95.4% of a normal variable, and its joint acceptance over several biomarkers is
//! then out of reach of such a model however faithful it is. This yardstick, computed on the
//! same reference in the same run, tells the two apart.
//!
//! The same Gaussian measures how far a shape's biomarkers lie from the reference jointly:
//! the Mahalanobis distance, which sees a combination no reference member has (a long axis
//! too long for the volume) where every biomarker alone is inside its interval.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::EvalError;
use super::acceptance::{Flags, Intervals, Rates, joint_acceptance_rates, rates};
use super::error::check_values;
use super::stats::{quantile_sorted, sorted};

/// Draws judged by [`gaussian_joint_acceptance`] in the benchmark: the rate's standard error
/// is below 0.1 percentage point.
pub const GAUSSIAN_REFERENCE_DRAWS: usize = 100_000;

/// Joint acceptance rates of `draws` members drawn (seeded by `seed`) from the multivariate
/// normal with the mean and sample covariance of `columns` (`columns[k][i]`: biomarker `k`
/// of reference member `i`), judged by `intervals[k]`. A singular covariance (a biomarker
/// that is a linear function of others) gets a tiny ridge. Fails when the columns are ragged,
/// hold fewer than two or non-finite values, or do not match the intervals.
pub fn gaussian_joint_acceptance<C: AsRef<[f64]>>(
    intervals: &[Intervals],
    columns: &[C],
    draws: usize,
    seed: u64,
) -> Result<Rates, EvalError> {
    // Checks the shapes (one column per interval, equal lengths) before any arithmetic.
    joint_acceptance_rates(intervals, columns)?;
    for c in columns {
        check_values(c.as_ref(), 2, "reference")?;
    }
    let (mean, factor) = mean_and_factor(columns);
    let dims = mean.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Ok(rates((0..draws).map(|_| {
        let noise = DVector::from_fn(dims, |_, _| StandardNormal.sample(&mut rng));
        let member = &mean + &factor * noise;
        intervals
            .iter()
            .zip(member.iter())
            .fold(Flags::ALL, |acc, (iv, v)| acc.and(iv.accepted(*v)))
    })))
}

/// Mahalanobis distance of each member of `samples` from the mean of `reference`, under the
/// reference's sample covariance (`columns[k][i]`: biomarker `k` of member `i`; unitless, in
/// reference standard deviations along each principal direction). Fails when either set of
/// columns is ragged, holds non-finite values, or the two differ in their biomarkers; the
/// reference needs two members more than it has biomarkers, for a covariance of full rank.
pub fn biomarker_distances<C: AsRef<[f64]>, S: AsRef<[f64]>>(
    reference: &[C],
    samples: &[S],
) -> Result<Vec<f64>, EvalError> {
    if reference.is_empty() || reference.len() != samples.len() {
        return Err(EvalError::DimensionMismatch {
            what: "sample biomarkers",
            expected: reference.len(),
            found: samples.len(),
        });
    }
    for c in reference {
        check_values(c.as_ref(), reference.len() + 2, "reference")?;
    }
    same_lengths(reference, "reference")?;
    same_lengths(samples, "sample")?;
    for c in samples {
        check_values(c.as_ref(), 0, "sample")?;
    }
    let n = samples[0].as_ref().len();
    let (mean, factor) = mean_and_factor(reference);
    let dims = mean.len();
    Ok((0..n)
        .map(|i| {
            let offset = DVector::from_fn(dims, |k, _| samples[k].as_ref()[i] - mean[k]);
            factor
                .solve_lower_triangular(&offset)
                .map_or(f64::INFINITY, |standard| standard.norm())
        })
        .collect())
}

/// The `q` quantile (0–1) of [`biomarker_distances`] of `samples` from `reference`.
pub fn distance_quantile<C: AsRef<[f64]>, S: AsRef<[f64]>>(
    reference: &[C],
    samples: &[S],
    q: f64,
) -> Result<f64, EvalError> {
    let distances = sorted(&biomarker_distances(reference, samples)?);
    check_values(&distances, 1, "sample")?;
    Ok(quantile_sorted(&distances, q))
}

/// Fails when the columns differ in length.
fn same_lengths<C: AsRef<[f64]>>(columns: &[C], what: &'static str) -> Result<(), EvalError> {
    let expected = columns.first().map_or(0, |c| c.as_ref().len());
    match columns.iter().find(|c| c.as_ref().len() != expected) {
        Some(c) => Err(EvalError::DimensionMismatch {
            what,
            expected,
            found: c.as_ref().len(),
        }),
        None => Ok(()),
    }
}

/// Mean `[K]` and lower Cholesky factor `[K, K]` of the sample covariance (`n − 1`) of the
/// columns (finite, at least two rows); the diagonal of standard deviations if even the
/// ridged covariance has no factor.
fn mean_and_factor<C: AsRef<[f64]>>(columns: &[C]) -> (DVector<f64>, DMatrix<f64>) {
    let dims = columns.len();
    let n = columns.first().map_or(0, |c| c.as_ref().len());
    let data = DMatrix::from_fn(n, dims, |i, k| columns[k].as_ref()[i]);
    let mean = DVector::from_fn(dims, |k, _| data.column(k).mean());
    let centred = DMatrix::from_fn(n, dims, |i, k| data[(i, k)] - mean[k]);
    let covariance = centred.transpose() * &centred / (n as f64 - 1.0);
    let ridge = 1e-9 * covariance.trace().abs().max(1e-12) / dims.max(1) as f64;
    let factor = [0.0, ridge, 1e3 * ridge]
        .into_iter()
        .find_map(|r| {
            let regularised = &covariance + DMatrix::<f64>::identity(dims, dims) * r;
            regularised.cholesky().map(|c| c.l())
        })
        .unwrap_or_else(|| {
            DMatrix::from_diagonal(&covariance.diagonal().map(|v| v.max(0.0).sqrt()))
        });
    (mean, factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::acceptance::ReferenceStats;

    /// `[-1, 1, -1, 1]` and `[-1, -1, 1, 1]`: means 0, sds 2/√3, uncorrelated.
    fn uncorrelated() -> Vec<Vec<f64>> {
        vec![vec![-1.0, 1.0, -1.0, 1.0], vec![-1.0, -1.0, 1.0, 1.0]]
    }

    fn intervals_of(columns: &[Vec<f64>]) -> Vec<Intervals> {
        columns
            .iter()
            .map(|c| ReferenceStats::from_values(c).unwrap().intervals())
            .collect()
    }

    /// P(|Z| ≤ 2) for a standard normal Z.
    const INSIDE_TWO_SD: f64 = 0.954_499_736;

    #[test]
    fn one_gaussian_biomarker_falls_inside_two_sd_as_a_normal_variable_does() {
        let columns = vec![vec![1.0, 2.0, 3.0, 4.0, 5.0]];
        let rates =
            gaussian_joint_acceptance(&intervals_of(&columns), &columns, 100_000, 1).unwrap();
        assert_eq!(rates.n, 100_000);
        assert!((rates.mean - INSIDE_TWO_SD).abs() < 0.004, "{rates:?}");
    }

    #[test]
    fn independent_biomarkers_multiply_and_tied_ones_do_not() {
        let free = uncorrelated();
        let joint = gaussian_joint_acceptance(&intervals_of(&free), &free, 100_000, 2).unwrap();
        let expected = INSIDE_TWO_SD * INSIDE_TWO_SD;
        assert!((joint.mean - expected).abs() < 0.004, "{joint:?}");
        // The second biomarker is 2·first + 1: every draw in one interval is in the other.
        let first = vec![1.0, 2.0, 4.0, 7.0];
        let tied = vec![first.clone(), first.iter().map(|v| 2.0 * v + 1.0).collect()];
        let joint = gaussian_joint_acceptance(&intervals_of(&tied), &tied, 100_000, 2).unwrap();
        assert!((joint.mean - INSIDE_TWO_SD).abs() < 0.004, "{joint:?}");
    }

    #[test]
    fn same_seed_same_rates() {
        let columns = uncorrelated();
        let intervals = intervals_of(&columns);
        let a = gaussian_joint_acceptance(&intervals, &columns, 1000, 9).unwrap();
        let b = gaussian_joint_acceptance(&intervals, &columns, 1000, 9).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn distances_are_in_reference_sds_and_see_broken_ties() {
        // Uncorrelated, sd 2/√3 each: (2/√3, 0) is one sd out, (2/√3, 2/√3) is √2.
        let free = uncorrelated();
        let sd = 2.0 / 3f64.sqrt();
        let samples = vec![vec![0.0, sd, sd], vec![0.0, 0.0, sd]];
        let d = biomarker_distances(&free, &samples).unwrap();
        assert!(d[0].abs() < 1e-12, "{d:?}");
        assert!((d[1] - 1.0).abs() < 1e-9, "{d:?}");
        assert!((d[2] - 2f64.sqrt()).abs() < 1e-9, "{d:?}");
        // The second biomarker is 2·first + 1 with a little noise: a member that keeps each
        // value inside its range but breaks the tie lies far out; one on the line does not.
        let first = [1.0, 2.0, 4.0, 7.0, 5.0];
        let second: Vec<f64> = first
            .iter()
            .zip([0.01, -0.01, 0.02, -0.02, 0.0])
            .map(|(v, e)| 2.0 * v + 1.0 + e)
            .collect();
        let tied = vec![first.to_vec(), second];
        let d = biomarker_distances(&tied, &[vec![2.0, 2.0], vec![5.0, 13.0]]).unwrap();
        assert!(d[0] < 2.0, "on the line: {d:?}");
        assert!(d[1] > 100.0, "off the line: {d:?}");
    }

    #[test]
    fn distances_refuse_mismatched_or_ragged_biomarkers() {
        let free = uncorrelated();
        assert!(biomarker_distances(&free, &[vec![0.0]]).is_err());
        assert!(biomarker_distances(&free, &[vec![0.0], vec![0.0, 1.0]]).is_err());
        assert!(biomarker_distances(&free, &[vec![f64::NAN], vec![0.0]]).is_err());
        // Two biomarkers need four reference members for a covariance of full rank.
        let short = vec![vec![1.0, 2.0, 4.0], vec![2.0, 1.0, 3.0]];
        assert!(biomarker_distances(&short, &[vec![0.0], vec![0.0]]).is_err());
        let enough = vec![vec![1.0, 2.0, 4.0, 3.0], vec![2.0, 1.0, 3.0, 5.0]];
        assert!(biomarker_distances(&enough, &[vec![0.0], vec![0.0]]).is_ok());
        assert!(distance_quantile(&enough, &[Vec::<f64>::new(), Vec::new()], 0.95).is_err());
    }

    #[test]
    fn refuses_ragged_short_or_mismatched_columns() {
        let columns = uncorrelated();
        let intervals = intervals_of(&columns);
        let ragged = vec![vec![1.0, 2.0, 3.0], vec![1.0, 2.0]];
        assert!(gaussian_joint_acceptance(&intervals, &ragged, 10, 1).is_err());
        let short = vec![vec![1.0], vec![2.0]];
        assert!(gaussian_joint_acceptance(&intervals, &short, 10, 1).is_err());
        assert!(gaussian_joint_acceptance(&intervals[..1], &columns, 10, 1).is_err());
    }
}
