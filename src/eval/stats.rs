//! Descriptive statistics of samples: mean ± sd, five-number-style summaries, quantiles.

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::error::check_values;

/// Mean and sample standard deviation (`n − 1`; 0 for a single value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct MeanStd {
    /// Arithmetic mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub std: f64,
}

impl MeanStd {
    /// Of a non-empty, finite sample.
    pub fn from_values(values: &[f64]) -> Result<Self, EvalError> {
        check_values(values, 1, "mean_std")?;
        Ok(Self {
            mean: mean(values),
            std: sample_sd(values),
        })
    }
}

/// Summary of a synthetic (or any) sample of a biomarker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SummaryStats {
    /// Number of values.
    pub n: usize,
    /// Arithmetic mean.
    pub mean: f64,
    /// Sample standard deviation (`n − 1`; 0 for a single value).
    pub sd: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Median (mean of the two middle values for even `n`).
    pub median: f64,
}

impl SummaryStats {
    /// Of a non-empty, finite sample.
    pub fn from_values(values: &[f64]) -> Result<Self, EvalError> {
        check_values(values, 1, "summary")?;
        let sorted = sorted(values);
        Ok(Self {
            n: values.len(),
            mean: mean(values),
            sd: sample_sd(values),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            median: quantile_sorted(&sorted, 0.5),
        })
    }
}

/// Arithmetic mean (NaN for an empty slice).
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// Sample standard deviation with `n − 1`; 0 for fewer than two values.
pub fn sample_sd(values: &[f64]) -> f64 {
    if values.len() < 2 {
        return 0.0;
    }
    let m = mean(values);
    (values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (values.len() - 1) as f64).sqrt()
}

/// A sorted copy (finite values assumed).
pub fn sorted(values: &[f64]) -> Vec<f64> {
    let mut s = values.to_vec();
    s.sort_by(f64::total_cmp);
    s
}

/// Quantile `q ∈ [0, 1]` of a sorted, non-empty slice by linear interpolation between
/// order statistics (position `q·(n − 1)`).
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    let Some(last) = sorted.len().checked_sub(1) else {
        return f64::NAN;
    };
    let pos = q.clamp(0.0, 1.0) * last as f64;
    let lo = pos.floor() as usize;
    let hi = (lo + 1).min(last);
    let frac = pos - lo as f64;
    sorted[lo] + frac * (sorted[hi] - sorted[lo])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_summary() {
        let s = SummaryStats::from_values(&[5.0, 1.0, 4.0, 2.0, 3.0]).unwrap();
        assert_eq!(
            (s.n, s.mean, s.min, s.max, s.median),
            (5, 3.0, 1.0, 5.0, 3.0)
        );
        assert!((s.sd - 2.5f64.sqrt()).abs() < 1e-12);
        let even = SummaryStats::from_values(&[4.0, 1.0, 2.0, 10.0]).unwrap();
        assert_eq!(even.median, 3.0);
        assert!(SummaryStats::from_values(&[]).is_err());
    }

    #[test]
    fn mean_std_of_one_value_has_zero_std() {
        assert_eq!(
            MeanStd::from_values(&[7.0]).unwrap(),
            MeanStd {
                mean: 7.0,
                std: 0.0
            }
        );
        let m = MeanStd::from_values(&[1.0, 3.0]).unwrap();
        assert!((m.std - 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn quantiles_interpolate() {
        let s = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile_sorted(&s, 0.25), 1.75);
        assert_eq!(quantile_sorted(&s, 0.75), 3.25);
        assert_eq!(quantile_sorted(&s, 1.0), 4.0);
    }
}
