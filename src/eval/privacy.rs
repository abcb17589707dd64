//! Privacy guard: a virtual cohort must not hand out a patient's shape. Every member gets
//! the distance to its nearest training shape; members closer than the training set's own
//! nearest-neighbour distances usually are (a low percentile) are flagged as near copies.
//!
//! Shapes are compared in correspondence: members and the training shapes' normalised
//! shapes share the atlas's vertices, and the distance is the mean distance between
//! corresponding vertices in mm. A member that reproduces a patient's normalised shape is at
//! distance 0. The search for the nearest training shape visits the shapes nearest-first
//! by a coarse probe and drops a shape as soon as its running mean exceeds the best one, so
//! it finds exactly what comparing every shape in full finds, at a fraction of the cost.

use serde::{Deserialize, Serialize};

use super::EvalError;
use super::metrics::parallel_map;
use super::shape_columns::ShapeColumns;

/// Default percentile of the training nearest-neighbour distances used as the threshold.
pub const DEFAULT_PERCENTILE: f64 = 0.05;

/// The near-copy threshold of a training set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PrivacyThreshold {
    /// Percentile (0–1) of `training_nn_mm` taken as the threshold.
    pub percentile: f64,
    /// Members nearer than this to a training shape are near copies, mm.
    pub threshold_mm: f64,
    /// Each training shape's distance to its nearest other training shape, mm (with
    /// `leave_one_out`: from its projection on the hull of the others).
    pub training_nn_mm: Vec<f64>,
    /// Whether the distances are measured from each training shape's projection on the
    /// affine hull of the others (few training shapes) instead of from the shape itself.
    /// Thresholds stored before it existed are not.
    #[serde(default)]
    pub leave_one_out: bool,
}

/// A shape's nearest training shape.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NearestTraining {
    /// Index of the training shape.
    pub index: usize,
    /// Mean distance between corresponding vertices, mm.
    pub distance_mm: f64,
}

/// Vertices in a coarse probe of a shape (about; the stride is rounded).
const PROBE_VERTICES: usize = 64;
/// Vertices summed between two checks of the running sum against the best distance.
const PRUNE_CHUNK: usize = 128;

/// Mean distance (mm) between corresponding vertices of `a` and `b` (equal lengths).
pub fn correspondence_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    mean_distance_below(&ShapeColumns::new(a), &ShapeColumns::new(b), f64::INFINITY)
        .unwrap_or(f64::INFINITY)
}

/// The mean distance between corresponding vertices of `a` and `b`, summed chunk by chunk
/// in vertex order (always the same value for the same shapes), or `None` as soon as the
/// running mean exceeds `bound`: the full mean would too, as the running sum never falls.
fn mean_distance_below(a: &ShapeColumns, b: &ShapeColumns, bound: f64) -> Option<f64> {
    let n = a.len();
    let count = n.max(1) as f64;
    let mut sum = 0.0;
    for start in (0..n).step_by(PRUNE_CHUNK) {
        sum += a.distance_sum(b, start..(start + PRUNE_CHUNK).min(n));
        if sum / count > bound {
            return None;
        }
    }
    Some(sum / count)
}

/// Every `stride`-th vertex of `shape`.
fn probe(shape: &[[f64; 3]], stride: usize) -> ShapeColumns {
    let picked: Vec<[f64; 3]> = shape.iter().step_by(stride).copied().collect();
    ShapeColumns::new(&picked)
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
/// each, mm, kept as coordinate columns for the distance kernel.
#[derive(Debug, Clone)]
pub struct CorrespondedShapes {
    shapes: Vec<ShapeColumns>,
    /// Every shape's vertices at `probe_stride` steps.
    probes: Vec<ShapeColumns>,
    probe_stride: usize,
}

impl CorrespondedShapes {
    /// Fails without shapes or when vertex counts differ.
    pub fn new<S: AsRef<[[f64; 3]]>>(shapes: &[S]) -> Result<Self, EvalError> {
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
        let probe_stride = (n / PROBE_VERTICES).max(1);
        Ok(Self {
            probes: shapes.iter().map(|s| probe(s, probe_stride)).collect(),
            shapes: shapes.iter().map(|s| ShapeColumns::new(s)).collect(),
            probe_stride,
        })
    }

    /// Number of shapes.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// Never true: construction needs a shape.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// The training shape nearest to `shape` (same vertex count), ties to the lower index:
    /// exactly what comparing every training shape in full gives.
    pub fn nearest(&self, shape: &[[f64; 3]]) -> Result<NearestTraining, EvalError> {
        let n = self.shapes[0].len();
        if shape.len() != n {
            return Err(EvalError::DimensionMismatch {
                what: "vertices of the shape to compare",
                expected: n,
                found: shape.len(),
            });
        }
        let columns = ShapeColumns::new(shape);
        let coarse = probe(shape, self.probe_stride);
        let mut order: Vec<(f64, usize)> = self
            .probes
            .iter()
            .enumerate()
            .map(|(k, p)| (coarse.distance_sum(p, 0..p.len()), k))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut best = NearestTraining {
            index: 0,
            distance_mm: f64::INFINITY,
        };
        for (_, k) in order {
            if let Some(d) = mean_distance_below(&columns, &self.shapes[k], best.distance_mm)
                && (d < best.distance_mm || (d == best.distance_mm && k < best.index))
            {
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
        let training_nn_mm = parallel_map(&ks, |&k| self.nearest_other(&self.shapes[k], k));
        Ok(PrivacyThreshold::from_distances(
            percentile_p,
            training_nn_mm,
            false,
        ))
    }

    /// The near-copy threshold for a few training shapes: the `percentile` of the distance
    /// from each shape's projection on the affine hull of the others
    /// ([`super::hull::leave_one_out_projections`]) to its nearest other training shape.
    /// `shapes` are the same shapes as `self`'s (at least 3).
    pub fn leave_one_out_threshold<S: AsRef<[[f64; 3]]>>(
        &self,
        shapes: &[S],
        percentile_p: f64,
    ) -> Result<PrivacyThreshold, EvalError> {
        if shapes.len() != self.shapes.len() {
            return Err(EvalError::DimensionMismatch {
                what: "training shapes",
                expected: self.shapes.len(),
                found: shapes.len(),
            });
        }
        let projected = super::hull::leave_one_out_projections(shapes)?;
        let ks: Vec<usize> = (0..projected.len()).collect();
        let distances = parallel_map(&ks, |&k| {
            self.nearest_other(&ShapeColumns::new(&projected[k]), k)
        });
        Ok(PrivacyThreshold::from_distances(
            percentile_p,
            distances,
            true,
        ))
    }

    /// Mean corresponding-vertex distance from `shape` to the nearest training shape other
    /// than `skip`, mm.
    fn nearest_other(&self, shape: &ShapeColumns, skip: usize) -> f64 {
        (0..self.shapes.len())
            .filter(|&j| j != skip)
            .filter_map(|j| mean_distance_below(shape, &self.shapes[j], f64::INFINITY))
            .fold(f64::INFINITY, f64::min)
    }
}

impl PrivacyThreshold {
    fn from_distances(percentile_p: f64, training_nn_mm: Vec<f64>, leave_one_out: bool) -> Self {
        Self {
            percentile: percentile_p,
            threshold_mm: percentile(&training_nn_mm, percentile_p).unwrap_or(0.0),
            training_nn_mm,
            leave_one_out,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(offset: f64, n: usize) -> Vec<[f64; 3]> {
        (0..n).map(|i| [i as f64, (i % 3) as f64, offset]).collect()
    }

    #[test]
    fn leave_one_out_distances_by_hand() {
        // One-vertex shapes A (0,0), B (10,0), C (5,5): A and B project onto C (the line BC
        // and AC meet their perpendicular from A and B at C), C onto (5,0), 5 mm from A.
        let shapes = vec![
            vec![[0.0, 0.0, 0.0]],
            vec![[10.0, 0.0, 0.0]],
            vec![[5.0, 5.0, 0.0]],
        ];
        let corresponded = CorrespondedShapes::new(&shapes).unwrap();
        let plain = corresponded.privacy_threshold(0.5).unwrap();
        let loo = corresponded.leave_one_out_threshold(&shapes, 0.5).unwrap();
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-4);
        let d = 50f64.sqrt();
        assert!(
            close(&plain.training_nn_mm, &[d, d, d]),
            "{:?}",
            plain.training_nn_mm
        );
        assert!(!plain.leave_one_out);
        assert!(
            close(&loo.training_nn_mm, &[0.0, 0.0, 5.0]),
            "{:?}",
            loo.training_nn_mm
        );
        assert!(loo.leave_one_out);
        assert!(
            corresponded
                .leave_one_out_threshold(&shapes[..2], 0.5)
                .is_err()
        );
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
        // Coordinates are compared in single precision: well below a micrometre here.
        assert!((shifted.distance_mm - 0.4).abs() < 1e-6);
    }

    /// The plain search: every shape in full, in index order.
    fn brute_force(training: &[Vec<[f64; 3]>], shape: &[[f64; 3]]) -> NearestTraining {
        let mut best = NearestTraining {
            index: 0,
            distance_mm: f64::INFINITY,
        };
        for (k, s) in training.iter().enumerate() {
            let d = correspondence_distance(shape, s);
            if d < best.distance_mm {
                best = NearestTraining {
                    index: k,
                    distance_mm: d,
                };
            }
        }
        best
    }

    #[test]
    fn the_pruned_search_finds_exactly_what_the_full_search_finds() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut jitter = |base: &[[f64; 3]], sd: f64| -> Vec<[f64; 3]> {
            base.iter()
                .map(|p| p.map(|c| c + sd * (rng.random::<f64>() - 0.5)))
                .collect()
        };
        let base: Vec<[f64; 3]> = (0..500)
            .map(|i| {
                let t = i as f64 * 0.1;
                [40.0 * t.cos(), 30.0 * t.sin(), i as f64 * 0.2]
            })
            .collect();
        let mut training: Vec<Vec<[f64; 3]>> = (0..40).map(|_| jitter(&base, 8.0)).collect();
        // Two identical training shapes: a copy of either is nearest to the lower index.
        training[31] = training[12].clone();
        let shapes = CorrespondedShapes::new(&training).unwrap();
        let mut queries: Vec<Vec<[f64; 3]>> = (0..30).map(|_| jitter(&base, 8.0)).collect();
        queries.push(training[31].clone());
        queries.push(jitter(&training[7], 0.5));
        for q in &queries {
            assert_eq!(shapes.nearest(q).unwrap(), brute_force(&training, q));
        }
        assert_eq!(shapes.nearest(&training[31]).unwrap().index, 12);
        assert_eq!(shapes.nearest(&queries[31]).unwrap().index, 7);
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
