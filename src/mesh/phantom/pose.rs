//! Rigid poses: a rotation and a translation in mm.

use std::f64::consts::TAU;

use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion};
use rand::Rng;

/// A rigid motion `x ↦ R x + t` (t in mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidPose {
    /// Rotation matrix `R`, rows first: `rotation[row][col]`.
    pub rotation: [[f64; 3]; 3],
    /// Translation `t` in mm.
    pub translation_mm: [f64; 3],
}

impl RigidPose {
    /// The identity pose.
    pub const IDENTITY: RigidPose = RigidPose {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_mm: [0.0; 3],
    };

    /// A uniformly random rotation (Shoemake's unit quaternion) and a translation uniform
    /// in `[-max_translation_mm, max_translation_mm]` per axis.
    pub(super) fn random<R: Rng + ?Sized>(rng: &mut R, max_translation_mm: f64) -> Self {
        let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
        let (s1, s2) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = [
            s2 * (TAU * u3).cos(),
            s1 * (TAU * u2).sin(),
            s1 * (TAU * u2).cos(),
            s2 * (TAU * u3).sin(),
        ];
        let mut translation_mm = [0.0; 3];
        for t in &mut translation_mm {
            *t = rng.random_range(-max_translation_mm..=max_translation_mm);
        }
        Self {
            rotation: rotation_from_quaternion(q),
            translation_mm,
        }
    }

    /// Maps a canonical point to the posed frame: `R p + t` (mm).
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let mut out = self.translation_mm;
        for (row, o) in r.iter().zip(out.iter_mut()) {
            *o += row[0] * p[0] + row[1] * p[1] + row[2] * p[2];
        }
        out
    }

    /// Maps a posed point back to the canonical frame: `Rᵀ (p − t)` (mm).
    pub fn apply_inverse(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [
            p[0] - self.translation_mm[0],
            p[1] - self.translation_mm[1],
            p[2] - self.translation_mm[2],
        ];
        let r = &self.rotation;
        [0, 1, 2].map(|c| r[0][c] * d[0] + r[1][c] * d[1] + r[2][c] * d[2])
    }

    /// The rotation as a unit quaternion `[w, x, y, z]` with `w ≥ 0`.
    pub fn quaternion(&self) -> [f64; 4] {
        let r = &self.rotation;
        let m = Matrix3::from_fn(|i, j| r[i][j]);
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
        let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
        [q.w, q.i, q.j, q.k].map(|c| sign * c)
    }
}

/// Rotation matrix of the unit quaternion `[w, x, y, z]`.
fn rotation_from_quaternion(q: [f64; 4]) -> [[f64; 3]; 3] {
    let uq = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let m = uq.to_rotation_matrix();
    let m = m.matrix();
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < tol)
    }

    #[test]
    fn quarter_turn_about_z() {
        // q = (cos 45°, 0, 0, sin 45°) turns x onto y.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let pose = RigidPose {
            rotation: rotation_from_quaternion([h, 0.0, 0.0, h]),
            translation_mm: [10.0, 0.0, -5.0],
        };
        assert!(close(pose.apply([1.0, 0.0, 0.0]), [10.0, 1.0, -5.0], 1e-12));
        let q = pose.quaternion();
        assert!((q[0] - h).abs() < 1e-12 && (q[3] - h).abs() < 1e-12);
    }

    #[test]
    fn random_pose_is_rigid_and_invertible() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let pose = RigidPose::random(&mut rng, 60.0);
            let r = pose.rotation;
            for i in 0..3 {
                for j in 0..3 {
                    let d: f64 = (0..3).map(|k| r[i][k] * r[j][k]).sum();
                    assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
            let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
            assert!((det - 1.0).abs() < 1e-12);
            assert!(pose.translation_mm.iter().all(|t| t.abs() <= 60.0));
            let p = [3.0, -7.0, 11.0];
            assert!(close(pose.apply_inverse(pose.apply(p)), p, 1e-12));
            let back = RigidPose {
                rotation: rotation_from_quaternion(pose.quaternion()),
                ..pose
            };
            assert!(close(back.apply(p), pose.apply(p), 1e-10));
        }
    }

    #[test]
    fn random_rotations_cover_directions() {
        // The image of the z axis should average to about zero for a uniform rotation.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let n = 4000;
        let mut mean = [0.0; 3];
        for _ in 0..n {
            let r = RigidPose::random(&mut rng, 0.0).rotation;
            for k in 0..3 {
                mean[k] += r[k][2] / n as f64;
            }
        }
        // Standard error per component is 1/sqrt(3n) ≈ 0.009.
        assert!(mean.iter().all(|m| m.abs() < 0.04), "{mean:?}");
    }
}
