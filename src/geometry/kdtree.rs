//! Nearest-neighbour index over a point set (a k-d tree), built once and queried often.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::GeometryError;
use super::error::check_points;

/// A k-d tree over a fixed, non-empty, finite point set `[n, 3]` (mm).
pub struct PointCloudIndex {
    tree: ImmutableKdTree<f64, 3>,
    len: usize,
}

impl std::fmt::Debug for PointCloudIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointCloudIndex")
            .field("len", &self.len)
            .finish()
    }
}

impl PointCloudIndex {
    /// Builds the index. Fails on an empty set or a non-finite coordinate.
    pub fn new(points: &[[f64; 3]]) -> Result<Self, GeometryError> {
        check_points(points, "points")?;
        if u32::try_from(points.len()).is_err() {
            return Err(GeometryError::InvalidParams(
                "too many points for the index".into(),
            ));
        }
        let tree = ImmutableKdTree::new_from_slice(points).map_err(|e| {
            GeometryError::DegenerateInput(format!("k-d tree construction failed: {e}"))
        })?;
        Ok(Self {
            tree,
            len: points.len(),
        })
    }

    /// Number of indexed points.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: an index is never empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest indexed point to `p`: `(index, distance in mm)`.
    pub fn nearest(&self, p: [f64; 3]) -> (usize, f64) {
        let hit = self
            .tree
            .query(&p)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        (hit.item as usize, hit.distance.sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_returns_index_and_unsquared_distance() {
        let pts = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        let idx = PointCloudIndex::new(&pts).unwrap();
        assert_eq!(idx.len(), 3);
        let (i, d) = idx.nearest([9.0, 0.0, 0.0]);
        assert_eq!(i, 1);
        assert!((d - 1.0).abs() < 1e-12);
        let (i, d) = idx.nearest([0.0, 7.0, 4.0]);
        assert_eq!(i, 2);
        assert!((d - 5.0).abs() < 1e-12);
    }

    #[test]
    fn matches_brute_force_on_a_cloud() {
        let pts: Vec<[f64; 3]> = (0..500)
            .map(|i| {
                let t = i as f64;
                [
                    (t * 0.37).sin() * 20.0,
                    (t * 0.11).cos() * 15.0,
                    (t * 0.05) % 7.0,
                ]
            })
            .collect();
        let idx = PointCloudIndex::new(&pts).unwrap();
        for q in [[1.0, 2.0, 3.0], [-20.0, 0.0, 1.0], [5.0, -14.0, 6.5]] {
            let brute = pts
                .iter()
                .map(|p| crate::geometry::points::dist2(*p, q).sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!((idx.nearest(q).1 - brute).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_empty_and_nan() {
        assert!(PointCloudIndex::new(&[]).is_err());
        assert!(PointCloudIndex::new(&[[f64::NAN, 0.0, 0.0]]).is_err());
    }
}
