//! Similarity transforms `y ↦ s·R·y + t` (mm) and the cube rotation group used as starts.

use serde::{Deserialize, Serialize};

use super::points::{self, IDENTITY3, Mat3};

/// A rigid transform with optional isotropic scale: `y ↦ s·R·y + t`.
///
/// `rotation` is row-major and proper (det = +1); `translation` in mm; `scale` unitless.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidTransform {
    /// Rotation matrix `R`, row-major.
    pub rotation: Mat3,
    /// Translation `t` in mm.
    pub translation: [f64; 3],
    /// Isotropic scale `s`.
    pub scale: f64,
}

impl Default for RigidTransform {
    fn default() -> Self {
        Self::identity()
    }
}

impl RigidTransform {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: IDENTITY3,
            translation: [0.0; 3],
            scale: 1.0,
        }
    }

    /// A pure rotation about `centre`: `y ↦ R·(y − c) + c`.
    pub fn rotation_about(rotation: Mat3, centre: [f64; 3]) -> Self {
        let t = points::sub(centre, points::mat_vec(&rotation, centre));
        Self {
            rotation,
            translation: t,
            scale: 1.0,
        }
    }

    /// `s·R·p + t`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        points::add(
            points::scale(points::mat_vec(&self.rotation, p), self.scale),
            self.translation,
        )
    }

    /// The inverse map `Rᵀ·(p − t)/s`. Returns non-finite values if `scale` is zero.
    pub fn inverse_apply(&self, p: [f64; 3]) -> [f64; 3] {
        points::scale(
            points::mat_t_vec(&self.rotation, points::sub(p, self.translation)),
            1.0 / self.scale,
        )
    }

    /// Applies the transform to every point.
    pub fn apply_all(&self, points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points.iter().map(|p| self.apply(*p)).collect()
    }

    /// The inverse transform as a transform.
    pub fn inverse(&self) -> Self {
        let rt = points::transpose(&self.rotation);
        let s = 1.0 / self.scale;
        let t = points::scale(points::mat_vec(&rt, self.translation), -s);
        Self {
            rotation: rt,
            translation: t,
            scale: s,
        }
    }

    /// `self ∘ first`: the transform that applies `first`, then `self`.
    pub fn compose(&self, first: &Self) -> Self {
        let rotation = points::mat_mul(&self.rotation, &first.rotation);
        let moved = points::scale(
            points::mat_vec(&self.rotation, first.translation),
            self.scale,
        );
        Self {
            rotation,
            translation: points::add(moved, self.translation),
            scale: self.scale * first.scale,
        }
    }
}

/// The 24 proper rotations of the cube: signed permutation matrices with det = +1.
///
/// Used as initial rotations for multi-start registration of shapes in random orientations;
/// every rotation lies within 62.8° of one of them. The identity comes first.
pub fn axis_permutation_rotations() -> Vec<Mat3> {
    const PERMUTATIONS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(24);
    for perm in PERMUTATIONS {
        for signs in 0..8u8 {
            let mut m = [[0.0; 3]; 3];
            for (row, &col) in perm.iter().enumerate() {
                m[row][col] = if signs & (1 << row) == 0 { 1.0 } else { -1.0 };
            }
            if points::det(&m) > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::points::{axis_angle, dist2};

    fn sample() -> RigidTransform {
        RigidTransform {
            rotation: axis_angle([1.0, 2.0, 3.0], 0.7),
            translation: [5.0, -2.0, 1.0],
            scale: 1.5,
        }
    }

    #[test]
    fn apply_and_inverse_round_trip() {
        let t = sample();
        let p = [1.0, 2.0, 3.0];
        assert!(dist2(t.inverse_apply(t.apply(p)), p) < 1e-24);
        assert!(dist2(t.inverse().apply(t.apply(p)), p) < 1e-24);
        // s·R·0 + t = t.
        assert_eq!(t.apply([0.0; 3]), [5.0, -2.0, 1.0]);
    }

    #[test]
    fn compose_applies_right_first() {
        let a = sample();
        let b = RigidTransform {
            rotation: axis_angle([0.0, 1.0, 0.0], -1.1),
            translation: [0.0, 3.0, 0.0],
            scale: 0.5,
        };
        let p = [-4.0, 0.5, 2.0];
        assert!(dist2(a.compose(&b).apply(p), a.apply(b.apply(p))) < 1e-24);
        let id = a.compose(&a.inverse());
        assert!(dist2(id.apply(p), p) < 1e-20);
    }

    #[test]
    fn rotation_about_fixes_centre() {
        let c = [3.0, 4.0, 5.0];
        let t = RigidTransform::rotation_about(axis_angle([0.0, 0.0, 1.0], 2.0), c);
        assert!(dist2(t.apply(c), c) < 1e-24);
    }

    #[test]
    fn cube_group_has_24_distinct_proper_rotations() {
        let rs = axis_permutation_rotations();
        assert_eq!(rs.len(), 24);
        assert_eq!(rs[0], IDENTITY3);
        for (i, a) in rs.iter().enumerate() {
            assert_eq!(points::det(a), 1.0);
            for b in &rs[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }
}
