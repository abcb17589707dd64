//! Privacy guard: a virtual cohort must not hand out a patient's shape. Every member gets
//! the distance to its nearest training shape; members closer than the training set's own
//! nearest-neighbour distances usually are (a low percentile) are flagged as near copies.
//!
//! Shapes are compared in correspondence: members and the training shapes' normalised
//! shapes share the atlas's vertices, and the distance is the mean distance between
//! corresponding vertices in mm. A member that reproduces a patient's normalised shape is at
//! distance 0. (It costs O(n_vertices) per pair, so checking 1,000 members against hundreds
//! of patients stays cheap.)

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::metrics::parallel_map;
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
    /// Mean distance between corresponding vertices, mm.
    pub distance_mm: f64,
}

/// Mean distance (mm) between corresponding vertices of `a` and `b` (equal lengths).
pub fn correspondence_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .sum();
    sum / a.len().max(1) as f64
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

/// Training shapes in correspondence (all with the same vertex count), `[n_vertices, 3]`
/// each, mm.
#[derive(Debug, Clone)]
pub struct CorrespondedShapes<'a> {
    shapes: Vec<&'a [[f64; 3]]>,
}

impl<'a> CorrespondedShapes<'a> {
    /// Fails without shapes or when vertex counts differ.
    pub fn new<S: AsRef<[[f64; 3]]>>(shapes: &'a [S]) -> Result<Self, EvalError> {
        let shapes: Vec<&[[f64; 3]]> = shapes.iter().map(AsRef::as_ref).collect();
        let n = shapes.first().map_or(0, |s| s.len());
        if shapes.is_empty() || n == 0 {
            return Err(EvalError::TooFewValues {
                what: "training shapes",
                required: 1,
                found: 0,
            });
        }
        if let Some(other) = shapes.iter().find(|s| s.len() != n) {
            return Err(EvalError::DimensionMismatch {
                what: "vertices of corresponding shapes",
                expected: n,
                found: other.len(),
            });
        }
        Ok(Self { shapes })
    }

    /// Number of shapes.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// Never true: construction needs a shape.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// The training shape nearest to `shape` (same vertex count), ties to the lower index.
    pub fn nearest(&self, shape: &[[f64; 3]]) -> Result<NearestTraining, EvalError> {
        let n = self.shapes[0].len();
        if shape.len() != n {
            return Err(EvalError::DimensionMismatch {
                what: "vertices of the shape to compare",
                expected: n,
                found: shape.len(),
            });
        }
        let mut best = NearestTraining {
            index: 0,
            distance_mm: f64::INFINITY,
        };
        for (k, s) in self.shapes.iter().enumerate() {
            let d = correspondence_distance(shape, s);
            if d < best.distance_mm {
                best = NearestTraining {
                    index: k,
                    distance_mm: d,
                };
            }
        }
        Ok(best)
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
                .map(|j| correspondence_distance(self.shapes[k], self.shapes[j]))
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
        let shapes = CorrespondedShapes::new(&training).unwrap();
        let copy = shapes.nearest(&training[2]).unwrap();
        assert_eq!(
            copy,
            NearestTraining {
                index: 2,
                distance_mm: 0.0
            }
        );
        let threshold = shapes.privacy_threshold(0.05).unwrap();
        // Nearest-neighbour distances are 1, 1, 2, 3 (planes at z = 0, 1, 3, 6).
        assert_eq!(threshold.training_nn_mm, vec![1.0, 1.0, 2.0, 3.0]);
        assert!((threshold.threshold_mm - 1.0).abs() < 1e-12);
        let shifted = shapes.nearest(&cloud(2.6, 20)).unwrap();
        assert_eq!(shifted.index, 2);
        assert!((shifted.distance_mm - 0.4).abs() < 1e-12);
    }

    #[test]
    fn shapes_out_of_correspondence_are_refused() {
        let training = vec![cloud(0.0, 20), cloud(1.0, 19)];
        assert!(CorrespondedShapes::new(&training).is_err());
        let ok = vec![cloud(0.0, 20), cloud(1.0, 20)];
        let shapes = CorrespondedShapes::new(&ok).unwrap();
        assert!(shapes.nearest(&cloud(0.0, 21)).is_err());
        // One vertex moved by 2 mm out of 4: a mean of 0.5 mm.
        let a = [[0.0; 3]; 4];
        let mut b = a;
        b[1] = [0.0, 2.0, 0.0];
        assert_eq!(correspondence_distance(&a, &b), 0.5);
    }
}
