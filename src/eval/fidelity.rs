//! Distribution fidelity: how far a synthetic sample of a biomarker (e.g. volumes in ml) is
//! from a reference sample, by the Wasserstein-1 distance (in the values' unit) and the
//! two-sample Kolmogorov–Smirnov statistic (unitless, 0–1).
//!
//! Both compare the empirical distribution functions `F_a` and `F_b`: W1 is the area
//! `∫ |F_a − F_b| dx`, KS is the largest gap `sup |F_a − F_b|`.

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::error::check_values;
use super::stats::{mean, sample_sd, sorted};

/// Terms of the Kolmogorov series summed for the p-value (it converges long before).
const KOLMOGOROV_TERMS: u32 = 100;

/// Both distances between two samples, with the sample sizes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Fidelity {
    /// Values in the first (synthetic) sample.
    pub n_synthetic: usize,
    /// Values in the second (reference) sample.
    pub n_reference: usize,
    /// Wasserstein-1 distance, in the unit of the values.
    pub wasserstein_1: f64,
    /// Two-sample Kolmogorov–Smirnov statistic `D`, 0–1.
    pub ks_statistic: f64,
    /// Asymptotic p-value of `D` under the hypothesis that both samples share one
    /// distribution.
    pub ks_p_value: f64,
}

impl Fidelity {
    /// Compares `synthetic` with `reference` (both non-empty and finite).
    pub fn between(synthetic: &[f64], reference: &[f64]) -> Result<Self, EvalError> {
        let d = ks_statistic(synthetic, reference)?;
        Ok(Self {
            n_synthetic: synthetic.len(),
            n_reference: reference.len(),
            wasserstein_1: wasserstein_1(synthetic, reference)?,
            ks_statistic: d,
            ks_p_value: ks_p_value(d, synthetic.len(), reference.len()),
        })
    }
}

/// How a synthetic sample of a biomarker spreads against the training population's values:
/// the two means and sds, their ratios, and the two-sample KS statistic.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Spread {
    /// Mean of the synthetic values.
    pub synthetic_mean: f64,
    /// Sample sd of the synthetic values.
    pub synthetic_sd: f64,
    /// Mean of the training values.
    pub training_mean: f64,
    /// Sample sd of the training values.
    pub training_sd: f64,
    /// `synthetic_mean / training_mean` (1 is unbiased).
    pub mean_ratio: f64,
    /// `synthetic_sd / training_sd`: below 1 the cohort is narrower than the population,
    /// above 1 wider.
    pub sd_ratio: f64,
    /// Two-sample KS statistic `D` against the training values, 0–1.
    pub ks_statistic: f64,
    /// Its asymptotic p-value (small: the two samples differ).
    pub ks_p_value: f64,
}

impl Spread {
    /// Compares `synthetic` with `training` (both non-empty and finite).
    pub fn between(synthetic: &[f64], training: &[f64]) -> Result<Self, EvalError> {
        let d = ks_statistic(synthetic, training)?;
        let (sm, tm) = (mean(synthetic), mean(training));
        let (ss, ts) = (sample_sd(synthetic), sample_sd(training));
        let ratio = |a: f64, b: f64| if b != 0.0 { a / b } else { f64::NAN };
        Ok(Self {
            synthetic_mean: sm,
            synthetic_sd: ss,
            training_mean: tm,
            training_sd: ts,
            mean_ratio: ratio(sm, tm),
            sd_ratio: ratio(ss, ts),
            ks_statistic: d,
            ks_p_value: ks_p_value(d, synthetic.len(), training.len()),
        })
    }
}

/// Walks the merged sorted values of `a` and `b`, calling `f(x, next_x, F_a, F_b)` on every
/// interval `[x, next_x)` between consecutive distinct values, with the empirical
/// distribution functions at `x` (after every value equal to `x`).
fn walk_cdfs(a: &[f64], b: &[f64], mut f: impl FnMut(f64, f64, f64, f64)) {
    let (a, b) = (sorted(a), sorted(b));
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let x = match (a.get(i), b.get(j)) {
            (Some(&u), Some(&v)) => u.min(v),
            (Some(&u), None) => u,
            (None, Some(&v)) => v,
            (None, None) => break,
        };
        while a.get(i).is_some_and(|&u| u <= x) {
            i += 1;
        }
        while b.get(j).is_some_and(|&v| v <= x) {
            j += 1;
        }
        let next = match (a.get(i), b.get(j)) {
            (Some(&u), Some(&v)) => u.min(v),
            (Some(&u), None) => u,
            (None, Some(&v)) => v,
            (None, None) => x,
        };
        f(x, next, i as f64 / na, j as f64 / nb);
    }
}

fn check_pair(a: &[f64], b: &[f64]) -> Result<(), EvalError> {
    check_values(a, 1, "fidelity synthetic sample")?;
    check_values(b, 1, "fidelity reference sample")
}

/// Two-sample Kolmogorov–Smirnov statistic `sup_x |F_a(x) − F_b(x)|`, 0–1.
pub fn ks_statistic(a: &[f64], b: &[f64]) -> Result<f64, EvalError> {
    check_pair(a, b)?;
    let mut d = 0.0f64;
    walk_cdfs(a, b, |_, _, fa, fb| d = d.max((fa - fb).abs()));
    Ok(d)
}

/// Wasserstein-1 (earth mover's) distance `∫ |F_a(x) − F_b(x)| dx` between the empirical
/// distributions of `a` and `b`, in the unit of the values.
pub fn wasserstein_1(a: &[f64], b: &[f64]) -> Result<f64, EvalError> {
    check_pair(a, b)?;
    let mut area = 0.0;
    walk_cdfs(a, b, |x, next, fa, fb| area += (fa - fb).abs() * (next - x));
    Ok(area)
}

/// Asymptotic p-value of a two-sample KS statistic `d` for sample sizes `n` and `m`
/// (Kolmogorov distribution with the small-sample correction of Stephens, 1970).
pub fn ks_p_value(d: f64, n: usize, m: usize) -> f64 {
    if n == 0 || m == 0 {
        return f64::NAN;
    }
    let effective = (n as f64 * m as f64 / (n + m) as f64).sqrt();
    let lambda = (effective + 0.12 + 0.11 / effective) * d;
    if lambda < 1e-3 {
        return 1.0;
    }
    let sum: f64 = (1..=KOLMOGOROV_TERMS)
        .map(|k| {
            let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
            sign * (-2.0 * f64::from(k * k) * lambda * lambda).exp()
        })
        .sum();
    (2.0 * sum).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ks_of_identical_and_disjoint_samples() {
        let a = [3.0, 1.0, 2.0, 2.0];
        assert_eq!(ks_statistic(&a, &a).unwrap(), 0.0);
        assert_eq!(ks_statistic(&[0.0, 1.0], &[2.0, 3.0]).unwrap(), 1.0);
        assert_eq!(ks_statistic(&[2.0, 3.0], &[0.0, 1.0]).unwrap(), 1.0);
    }

    #[test]
    fn ks_by_hand_with_ties_and_unequal_sizes() {
        // F_a jumps to 1/2 at 1 and to 1 at 3; F_b to 1/4 at 1, 3/4 at 2, 1 at 4.
        // Gaps: at 1 |1/2 − 1/4|, at 2 |1/2 − 3/4|, at 3 |1 − 3/4|: all 1/4.
        let d = ks_statistic(&[1.0, 3.0], &[1.0, 2.0, 2.0, 4.0]).unwrap();
        assert!((d - 0.25).abs() < 1e-12, "{d}");
        // One sample shifted by half its spread: F gap of 1/2 between 2 and 3.
        let d = ks_statistic(&[1.0, 2.0, 3.0, 4.0], &[3.0, 4.0, 5.0, 6.0]).unwrap();
        assert!((d - 0.5).abs() < 1e-12, "{d}");
    }

    #[test]
    fn wasserstein_by_hand() {
        assert_eq!(wasserstein_1(&[0.0, 1.0], &[2.0, 3.0]).unwrap(), 2.0);
        assert_eq!(wasserstein_1(&[2.0, 3.0], &[0.0, 1.0]).unwrap(), 2.0);
        assert_eq!(wasserstein_1(&[5.0, 1.0], &[1.0, 5.0]).unwrap(), 0.0);
        // A point mass at 0 against {0, 4}: half the mass moves 4.
        assert_eq!(wasserstein_1(&[0.0], &[0.0, 4.0]).unwrap(), 2.0);
        // A shift of every value by 1.5 costs 1.5.
        let a = [1.0, 2.0, 7.0];
        let b: Vec<f64> = a.iter().map(|v| v + 1.5).collect();
        assert!((wasserstein_1(&a, &b).unwrap() - 1.5).abs() < 1e-12);
    }

    #[test]
    fn empty_or_non_finite_samples_are_errors() {
        assert!(ks_statistic(&[], &[1.0]).is_err());
        assert!(wasserstein_1(&[1.0], &[]).is_err());
        assert!(wasserstein_1(&[f64::NAN], &[1.0]).is_err());
    }

    #[test]
    fn spread_by_hand() {
        // Synthetic {1, 3} (mean 2, sd √2) against training {0, 2, 4} (mean 2, sd 2).
        let s = Spread::between(&[1.0, 3.0], &[0.0, 2.0, 4.0]).unwrap();
        assert_eq!(
            (s.synthetic_mean, s.training_mean, s.training_sd),
            (2.0, 2.0, 2.0)
        );
        assert!((s.sd_ratio - 2f64.sqrt() / 2.0).abs() < 1e-12);
        assert_eq!(s.mean_ratio, 1.0);
        // F_s − F_t: at 0: 0 − 1/3, at 1: 1/2 − 1/3, at 2: 1/2 − 2/3, at 3: 1 − 2/3.
        assert!((s.ks_statistic - 1.0 / 3.0).abs() < 1e-12);
        assert!(Spread::between(&[], &[1.0]).is_err());
    }

    #[test]
    fn p_values_span_agreement_to_disagreement() {
        assert_eq!(ks_p_value(0.0, 100, 100), 1.0);
        // D = 0.1 with 100 + 100 values is unremarkable; D = 0.5 is not.
        let p = ks_p_value(0.1, 100, 100);
        assert!(p > 0.5 && p < 0.8, "{p}");
        assert!(ks_p_value(0.5, 100, 100) < 1e-9);
        let f = Fidelity::between(&[0.0, 1.0], &[2.0, 3.0]).unwrap();
        assert_eq!((f.wasserstein_1, f.ks_statistic), (2.0, 1.0));
        assert_eq!((f.n_synthetic, f.n_reference), (2, 2));
    }
}
