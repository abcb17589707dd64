//! Weighted orthogonal Procrustes (Kabsch with the reflection fix).
//!
//! Used by the CPD M-step and to align shapes that are already in correspondence.

use nalgebra::Matrix3;

use super::GeometryError;
use super::error::check_points;
use super::points::{self, Mat3};
use super::transform::RigidTransform;

/// Convergence threshold of the 3×3 SVD.
const SVD_EPSILON: f64 = f64::EPSILON;
/// Iteration cap of the 3×3 SVD (it needs a handful in practice).
const SVD_MAX_ITERATIONS: usize = 1000;

/// The proper rotation `R` maximising `tr(AᵀR)` for a 3×3 cross-covariance
/// `A = Σ w·(x − μx)(y − μy)ᵀ` (targets `x` as rows, sources `y` as columns).
///
/// With `A = U·S·Vᵀ` (singular values descending), `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ`, so a
/// reflection is never returned. Also returns `tr(AᵀR)`.
pub fn rotation_from_cross_covariance(a: &Mat3) -> Result<(Mat3, f64), GeometryError> {
    if a.iter().flatten().any(|v| !v.is_finite()) {
        return Err(GeometryError::NonFinite {
            what: "cross_covariance",
        });
    }
    let m = Matrix3::from_fn(|i, j| a[i][j]);
    let svd = m
        .try_svd(true, true, SVD_EPSILON, SVD_MAX_ITERATIONS)
        .ok_or(GeometryError::SvdFailed)?;
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(GeometryError::SvdFailed);
    };
    let d = (u * v_t).determinant().signum();
    let correction = Matrix3::from_diagonal(&nalgebra::Vector3::new(
        1.0,
        1.0,
        if d < 0.0 { -1.0 } else { 1.0 },
    ));
    let r = u * correction * v_t;
    let rotation: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]));
    let trace = (m.transpose() * r).trace();
    Ok((rotation, trace))
}

/// The similarity transform `T(y) = s·R·y + t` minimising `Σ wᵢ‖targetᵢ − T(sourceᵢ)‖²`.
///
/// `source` and `target` are corresponding points `[n, 3]` in mm; `weights` (length `n`,
/// non-negative) default to 1. With `with_scale == false`, `s = 1`.
pub fn weighted_procrustes(
    source: &[[f64; 3]],
    target: &[[f64; 3]],
    weights: Option<&[f64]>,
    with_scale: bool,
) -> Result<RigidTransform, GeometryError> {
    check_points(source, "source")?;
    check_points(target, "target")?;
    if target.len() != source.len() {
        return Err(GeometryError::DimensionMismatch {
            what: "target",
            expected: source.len(),
            found: target.len(),
        });
    }
    if let Some(w) = weights {
        if w.len() != source.len() {
            return Err(GeometryError::DimensionMismatch {
                what: "weights",
                expected: source.len(),
                found: w.len(),
            });
        }
        if w.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(GeometryError::InvalidParams(
                "weights must be finite and >= 0".into(),
            ));
        }
        if w.iter().sum::<f64>() <= 0.0 {
            return Err(GeometryError::DegenerateInput(
                "all weights are zero".into(),
            ));
        }
    }
    let weight = |i: usize| weights.map_or(1.0, |w| w[i]);
    let mu_s = points::centroid(source, weights);
    let mu_t = points::centroid(target, weights);
    let mut a = [[0.0; 3]; 3];
    let mut source_spread = 0.0;
    for (i, (s, t)) in source.iter().zip(target).enumerate() {
        let (ds, dt) = (points::sub(*s, mu_s), points::sub(*t, mu_t));
        let w = weight(i);
        for (r, row) in a.iter_mut().enumerate() {
            for (c, cell) in row.iter_mut().enumerate() {
                *cell += w * dt[r] * ds[c];
            }
        }
        source_spread += w * points::norm2(ds);
    }
    let (rotation, trace) = rotation_from_cross_covariance(&a)?;
    let scale = if with_scale {
        if source_spread <= 0.0 {
            return Err(GeometryError::DegenerateInput(
                "source points coincide".into(),
            ));
        }
        trace / source_spread
    } else {
        1.0
    };
    let moved = points::scale(points::mat_vec(&rotation, mu_s), scale);
    Ok(RigidTransform {
        rotation,
        translation: points::sub(mu_t, moved),
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::points::{axis_angle, det, dist2};

    fn cloud() -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [0.0, 5.0, 0.0],
            [0.0, 0.0, 3.0],
            [2.0, 7.0, 1.0],
            [-4.0, 1.0, 6.0],
        ]
    }

    #[test]
    fn exact_on_noiseless_data() {
        let truth = RigidTransform {
            rotation: axis_angle([0.3, -1.0, 0.5], 2.4),
            translation: [12.0, -7.0, 3.5],
            scale: 1.3,
        };
        let src = cloud();
        let dst = truth.apply_all(&src);
        let est = weighted_procrustes(&src, &dst, None, true).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((est.rotation[i][j] - truth.rotation[i][j]).abs() < 1e-12);
            }
        }
        assert!(dist2(est.translation, truth.translation) < 1e-20);
        assert!((est.scale - 1.3).abs() < 1e-12);
        let rigid = weighted_procrustes(&src, &dst, Some(&[1.0; 6]), false).unwrap();
        assert_eq!(rigid.scale, 1.0);
        assert!((rigid.rotation[1][2] - truth.rotation[1][2]).abs() < 1e-12);
    }

    #[test]
    fn mirror_image_gives_a_rotation_not_a_reflection() {
        let src = cloud();
        let mirrored: Vec<_> = src.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let est = weighted_procrustes(&src, &mirrored, None, false).unwrap();
        assert!((det(&est.rotation) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn zero_weight_points_are_ignored() {
        let src = cloud();
        let truth = RigidTransform {
            rotation: axis_angle([0.0, 0.0, 1.0], 0.5),
            translation: [1.0, 2.0, 3.0],
            scale: 1.0,
        };
        let mut dst = truth.apply_all(&src);
        dst[5] = [100.0, 100.0, 100.0];
        let w = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
        let est = weighted_procrustes(&src, &dst, Some(&w), false).unwrap();
        assert!(dist2(est.translation, truth.translation) < 1e-20);
    }

    #[test]
    fn rejects_bad_input() {
        let src = cloud();
        assert_eq!(
            weighted_procrustes(&src, &src[..3], None, false)
                .unwrap_err()
                .code(),
            "geometry.dimension_mismatch"
        );
        assert_eq!(
            weighted_procrustes(&src, &src, Some(&[0.0; 6]), false)
                .unwrap_err()
                .code(),
            "geometry.degenerate_input"
        );
    }
}
