//! Clinical acceptance of synthetic biomarkers against a reference population
//! (thesis §3.2.2 and table 3.1, SPEC §3).
//!
//! Three intervals are derived from the reference sample: its range `[min, max]` (A^r), the
//! Chebyshev-style interval `M ± 3B` around the KDE mode with `B = √(σ² + (M − μ)²)` (A^M),
//! and `μ ± 2σ` (A^μ). Bounds are inclusive.

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::error::check_values;
use super::kde::kde_mode;
use super::stats::{mean, sample_sd};

pub use super::stats::SummaryStats;

/// Half-width of the mode interval in units of `B`.
pub const MODE_INTERVAL_B: f64 = 3.0;
/// Half-width of the mean interval in units of σ.
pub const MEAN_INTERVAL_SD: f64 = 2.0;

/// Statistics of a biomarker in the reference (training) population.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ReferenceStats {
    /// Number of reference values.
    pub n: usize,
    /// Mean μ.
    pub mean: f64,
    /// Sample standard deviation σ (`n − 1`).
    pub sd: f64,
    /// Mode M: argmax of a Gaussian KDE with Silverman's bandwidth.
    pub mode: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

impl ReferenceStats {
    /// From at least two finite reference values.
    pub fn from_values(values: &[f64]) -> Result<Self, EvalError> {
        check_values(values, 2, "reference")?;
        let (min, max) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
        Ok(Self {
            n: values.len(),
            mean: mean(values),
            sd: sample_sd(values),
            mode: kde_mode(values)?,
            min,
            max,
        })
    }

    /// `B = √(σ² + (M − μ)²)`.
    pub fn b(&self) -> f64 {
        (self.sd * self.sd + (self.mode - self.mean).powi(2)).sqrt()
    }

    /// The three acceptance intervals.
    pub fn intervals(&self) -> Intervals {
        let b = self.b();
        Intervals {
            range: [self.min, self.max],
            mode: [
                self.mode - MODE_INTERVAL_B * b,
                self.mode + MODE_INTERVAL_B * b,
            ],
            mean: [
                self.mean - MEAN_INTERVAL_SD * self.sd,
                self.mean + MEAN_INTERVAL_SD * self.sd,
            ],
        }
    }
}

/// Acceptance intervals `[low, high]` (inclusive) of one biomarker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Intervals {
    /// `[min, max]` of the reference (A^r).
    pub range: [f64; 2],
    /// `[M − 3B, M + 3B]` (A^M).
    pub mode: [f64; 2],
    /// `[μ − 2σ, μ + 2σ]` (A^μ).
    pub mean: [f64; 2],
}

/// Whether one value lies in each interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Flags {
    /// Inside `[min, max]`.
    pub range: bool,
    /// Inside `M ± 3B`.
    pub mode: bool,
    /// Inside `μ ± 2σ`.
    pub mean: bool,
}

impl Flags {
    /// Accepted under every criterion: the start of a joint judgement.
    pub const ALL: Self = Self {
        range: true,
        mode: true,
        mean: true,
    };

    /// Accepted under each criterion by both.
    pub fn and(self, other: Self) -> Self {
        Self {
            range: self.range && other.range,
            mode: self.mode && other.mode,
            mean: self.mean && other.mean,
        }
    }
}

/// Acceptance rates A^r, A^M, A^μ as fractions in `[0, 1]` over `n` members (all 0 when
/// `n = 0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Rates {
    /// Members assessed.
    pub n: usize,
    /// A^r.
    pub range: f64,
    /// A^M.
    pub mode: f64,
    /// A^μ.
    pub mean: f64,
}

fn inside(interval: [f64; 2], v: f64) -> bool {
    v >= interval[0] && v <= interval[1]
}

impl Intervals {
    /// Flags for one value (a non-finite value is never accepted).
    pub fn accepted(&self, value: f64) -> Flags {
        Flags {
            range: inside(self.range, value),
            mode: inside(self.mode, value),
            mean: inside(self.mean, value),
        }
    }

    /// Shares of `values` accepted under each criterion.
    pub fn acceptance_rates(&self, values: &[f64]) -> Rates {
        rates(values.iter().map(|v| self.accepted(*v)))
    }
}

/// Shares of `flags` accepted under each criterion.
pub(crate) fn rates(flags: impl Iterator<Item = Flags>) -> Rates {
    let (mut n, mut r, mut m, mut u) = (0usize, 0usize, 0usize, 0usize);
    for f in flags {
        n += 1;
        r += usize::from(f.range);
        m += usize::from(f.mode);
        u += usize::from(f.mean);
    }
    let share = |k: usize| if n == 0 { 0.0 } else { k as f64 / n as f64 };
    Rates {
        n,
        range: share(r),
        mode: share(m),
        mean: share(u),
    }
}

/// Joint acceptance over several biomarkers: a member is accepted under a criterion when it
/// is accepted for every biomarker. `columns[k][i]` is biomarker `k` of member `i`, judged
/// by `intervals[k]`; all columns must have the same length.
pub fn joint_acceptance_rates<C: AsRef<[f64]>>(
    intervals: &[Intervals],
    columns: &[C],
) -> Result<Rates, EvalError> {
    if columns.len() != intervals.len() {
        return Err(EvalError::DimensionMismatch {
            what: "biomarker columns",
            expected: intervals.len(),
            found: columns.len(),
        });
    }
    let n = columns.first().map_or(0, |c| c.as_ref().len());
    if let Some(bad) = columns.iter().find(|c| c.as_ref().len() != n) {
        return Err(EvalError::DimensionMismatch {
            what: "biomarker column",
            expected: n,
            found: bad.as_ref().len(),
        });
    }
    Ok(rates((0..n).map(|i| {
        intervals
            .iter()
            .zip(columns)
            .fold(Flags::ALL, |acc, (iv, col)| {
                acc.and(iv.accepted(col.as_ref()[i]))
            })
    })))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> ReferenceStats {
        ReferenceStats::from_values(&[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap()
    }

    #[test]
    fn reference_stats_by_hand() {
        let r = reference();
        assert_eq!((r.n, r.mean, r.min, r.max), (5, 3.0, 1.0, 5.0));
        assert!((r.sd - 2.5f64.sqrt()).abs() < 1e-12);
        // Symmetric sample: M = μ = 3, so B = σ.
        assert!((r.mode - 3.0).abs() < 1e-8);
        assert!((r.b() - 2.5f64.sqrt()).abs() < 1e-8);
        let iv = r.intervals();
        let s = 2.5f64.sqrt();
        assert_eq!(iv.range, [1.0, 5.0]);
        assert!(
            (iv.mean[0] - (3.0 - 2.0 * s)).abs() < 1e-12
                && (iv.mean[1] - (3.0 + 2.0 * s)).abs() < 1e-12
        );
        assert!(
            (iv.mode[0] - (3.0 - 3.0 * s)).abs() < 1e-7
                && (iv.mode[1] - (3.0 + 3.0 * s)).abs() < 1e-7
        );
    }

    #[test]
    fn rates_by_hand() {
        // Intervals: range [1, 5], mean 3 ± 3.162 = [−0.162, 6.162], mode 3 ± 4.743 = [−1.743, 7.743].
        let iv = reference().intervals();
        let sample = [0.0, 1.0, 3.0, 5.0, 5.5, 6.5, 7.0, 8.0];
        // range: 1, 3, 5 → 3/8; mean: 0, 1, 3, 5, 5.5 → 5/8; mode: all but 8 → 7/8.
        let r = iv.acceptance_rates(&sample);
        assert_eq!(
            r,
            Rates {
                n: 8,
                range: 3.0 / 8.0,
                mode: 7.0 / 8.0,
                mean: 5.0 / 8.0
            }
        );
        assert_eq!(
            iv.accepted(1.0),
            Flags {
                range: true,
                mode: true,
                mean: true
            }
        );
        assert_eq!(
            iv.accepted(f64::NAN),
            Flags {
                range: false,
                mode: false,
                mean: false
            }
        );
        assert_eq!(iv.acceptance_rates(&[]).n, 0);
    }

    #[test]
    fn mode_shift_widens_b() {
        // A skewed sample: the mode sits left of the mean, so B > σ.
        let r = ReferenceStats::from_values(&[1.0, 1.1, 1.2, 1.3, 1.4, 5.0, 9.0]).unwrap();
        assert!(r.mode < r.mean);
        assert!(r.b() > r.sd);
    }

    #[test]
    fn joint_rates_require_every_biomarker() {
        let a = reference().intervals();
        let b = ReferenceStats::from_values(&[10.0, 20.0, 30.0])
            .unwrap()
            .intervals();
        // Member 0 in both ranges; member 1 out of range for b; member 2 out for a.
        let joint = joint_acceptance_rates(&[a, b], &[vec![2.0, 3.0, 0.5], vec![15.0, 35.0, 20.0]])
            .unwrap();
        assert_eq!(joint.n, 3);
        assert_eq!(joint.range, 1.0 / 3.0);
        assert!(joint_acceptance_rates(&[a, b], &[vec![1.0]]).is_err());
        assert!(joint_acceptance_rates(&[a, b], &[vec![1.0], vec![1.0, 2.0]]).is_err());
    }

    #[test]
    fn too_few_reference_values() {
        assert_eq!(
            ReferenceStats::from_values(&[1.0]).unwrap_err().code(),
            "eval.too_few_values"
        );
    }
}
