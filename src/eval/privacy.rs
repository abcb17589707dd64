//! Privacy guard: a virtual cohort must not hand out a patient's shape. Every member gets
//! the distance to its nearest training shape; members closer than the training set's own
//! nearest-neighbour distances usually are (a low percentile) are flagged as near copies.
//!
//! The distance between two shapes is the symmetric mean closest-point distance
//! `(ED(a, b) + ED(b, a)) / 2` in mm (half the Chamfer distance of SPEC §3).

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::metrics::{IndexedShapes, parallel_map};
use crate::geometry::distance::directed;
use crate::geometry::kdtree::PointCloudIndex;

/// Default percentile of the training nearest-neighbour distances used as the threshold.
pub const DEFAULT_PERCENTILE: f64 = 0.05;

/// The near-copy threshold of a training set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrivacyThreshold {
    /// Percentile (0–1) of `training_nn_mm` taken as the threshold.
    pub percentile: f64,
    /// Members nearer than this to a training shape are near copies, mm.
    pub threshold_mm: f64,
    /// Each training shape's distance to its nearest other training shape, mm.
    pub training_nn_mm: Vec<f64>,
}

/// A shape's nearest training shape.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NearestTraining {
    /// Index of the training shape.
    pub index: usize,
    /// Symmetric mean closest-point distance to it, mm.
    pub distance_mm: f64,
}

fn symmetric_mean(
    a: &[[f64; 3]],
    ia: &PointCloudIndex,
    b: &[[f64; 3]],
    ib: &PointCloudIndex,
) -> f64 {
    0.5 * (directed(a, ib).mean + directed(b, ia).mean)
}

/// Value at `p` (0–1) of `values` by linear interpolation between order statistics.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if sorted.is_empty() {
        return None;
    }
    sorted.sort_by(f64::total_cmp);
    let position = p.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (lo, hi) = (position.floor() as usize, position.ceil() as usize);
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * (position - lo as f64))
}

impl IndexedShapes<'_> {
    /// The training shape nearest to `shape` (symmetric mean distance), ties to the lower index.
    pub fn nearest(&self, shape: &[[f64; 3]]) -> Result<NearestTraining, EvalError> {
        let own = PointCloudIndex::new(shape)?;
        let mut best = NearestTraining {
            index: 0,
            distance_mm: f64::INFINITY,
        };
        for (k, (s, index)) in self.shapes.iter().zip(&self.indices).enumerate() {
            let d = symmetric_mean(shape, &own, s, index);
            if d < best.distance_mm {
                best = NearestTraining {
                    index: k,
                    distance_mm: d,
                };
            }
        }
        if best.distance_mm.is_finite() {
            Ok(best)
        } else {
            Err(EvalError::TooFewValues {
                what: "training shapes",
                required: 1,
                found: 0,
            })
        }
    }

    /// [`IndexedShapes::nearest`] in two stages for speed: every training shape is ranked by
    /// the distance estimated on every `stride`-th vertex of both shapes, and the exact
    /// distance is computed for the best `candidates` only.
    pub fn nearest_pruned(
        &self,
        shape: &[[f64; 3]],
        stride: usize,
        candidates: usize,
    ) -> Result<NearestTraining, EvalError> {
        let own = PointCloudIndex::new(shape)?;
        let stride = stride.max(1);
        let coarse: Vec<[f64; 3]> = shape.iter().step_by(stride).copied().collect();
        let mut estimates: Vec<(f64, usize)> = self
            .shapes
            .iter()
            .zip(&self.indices)
            .enumerate()
            .map(|(k, (s, index))| {
                let theirs: Vec<[f64; 3]> = s.iter().step_by(stride).copied().collect();
                (
                    0.5 * (directed(&coarse, index).mean + directed(&theirs, &own).mean),
                    k,
                )
            })
            .collect();
        estimates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut best = NearestTraining {
            index: 0,
            distance_mm: f64::INFINITY,
        };
        for &(_, k) in estimates.iter().take(candidates.max(1)) {
            let d = symmetric_mean(shape, &own, self.shapes[k], &self.indices[k]);
            if d < best.distance_mm || (d == best.distance_mm && k < best.index) {
                best = NearestTraining {
                    index: k,
                    distance_mm: d,
                };
            }
        }
        if best.distance_mm.is_finite() {
            Ok(best)
        } else {
            Err(EvalError::TooFewValues {
                what: "training shapes",
                required: 1,
                found: 0,
            })
        }
    }

    /// The near-copy threshold: the `percentile` of each training shape's distance to its
    /// nearest other training shape (needs at least two shapes).
    pub fn privacy_threshold(&self, percentile_p: f64) -> Result<PrivacyThreshold, EvalError> {
        if self.shapes.len() < 2 {
            return Err(EvalError::TooFewValues {
                what: "training shapes",
                required: 2,
                found: self.shapes.len(),
            });
        }
        let ks: Vec<usize> = (0..self.shapes.len()).collect();
        let training_nn_mm = parallel_map(&ks, |&k| {
            (0..self.shapes.len())
                .filter(|&j| j != k)
                .map(|j| {
                    symmetric_mean(
                        self.shapes[k],
                        &self.indices[k],
                        self.shapes[j],
                        &self.indices[j],
                    )
                })
                .fold(f64::INFINITY, f64::min)
        });
        let threshold_mm = percentile(&training_nn_mm, percentile_p).unwrap_or(0.0);
        Ok(PrivacyThreshold {
            percentile: percentile_p,
            threshold_mm,
            training_nn_mm,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(offset: f64, n: usize) -> Vec<[f64; 3]> {
        (0..n).map(|i| [i as f64, (i % 3) as f64, offset]).collect()
    }

    #[test]
    fn percentile_interpolates() {
        assert_eq!(percentile(&[4.0, 1.0, 3.0, 2.0, 5.0], 0.5), Some(3.0));
        assert_eq!(percentile(&[1.0, 2.0], 0.25), Some(1.25));
        assert_eq!(percentile(&[], 0.5), None);
    }

    #[test]
    fn an_exact_training_shape_is_at_distance_zero_and_below_the_threshold() {
        let training = vec![
            cloud(0.0, 20),
            cloud(1.0, 20),
            cloud(3.0, 20),
            cloud(6.0, 20),
        ];
        let indexed = IndexedShapes::new(&training).unwrap();
        let copy = indexed.nearest(&training[2]).unwrap();
        assert_eq!(
            copy,
            NearestTraining {
                index: 2,
                distance_mm: 0.0
            }
        );
        let threshold = indexed.privacy_threshold(0.05).unwrap();
        // Nearest-neighbour distances are 1, 1, 2, 3 (planes at z = 0, 1, 3, 6).
        assert_eq!(threshold.training_nn_mm, vec![1.0, 1.0, 2.0, 3.0]);
        assert!((threshold.threshold_mm - 1.0).abs() < 1e-12);
        assert_eq!(indexed.nearest_pruned(&training[2], 3, 2).unwrap(), copy);
        let shifted = indexed.nearest(&cloud(2.6, 20)).unwrap();
        assert_eq!(
            indexed.nearest_pruned(&cloud(2.6, 20), 4, 1).unwrap(),
            shifted
        );
        assert_eq!(shifted.index, 2);
        assert!((shifted.distance_mm - 0.4).abs() < 1e-12);
    }
}
