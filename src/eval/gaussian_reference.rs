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

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::EvalError;
use super::acceptance::{Flags, Intervals, Rates, joint_acceptance_rates, rates};
use super::error::check_values;

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
