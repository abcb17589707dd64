//! Soft-correspondence normalisation (thesis eq. 3.10, SPEC §2.3).
//!
//! After rigid CPD of the template `Y` (`[M, 3]`) onto a shape's vertices `X` (`[N, 3]`),
//! each template point `j` gets the posterior-weighted mean of the data points, mapped back
//! into the template frame: `h_j = Σᵢ P_jᵢ·T⁻¹(xᵢ) / Σᵢ P_jᵢ`. The result has the template's
//! point count and order, so shapes of different sizes become comparable vectors for PCA.

use super::GeometryError;
use super::cpd::{CpdResult, NonRigidResult, posterior_sums};
use super::kdtree::PointCloudIndex;
use super::points;

/// Rows whose total responsibility `Σᵢ P_jᵢ` is below this take the nearest data point.
pub const ROW_MASS_FLOOR: f64 = 1e-12;

/// The normalised shape `h` (`[M, 3]`, mm, template frame, pose removed) of `data` given the
/// CPD `result` of `template` onto `data`.
///
/// Because `T⁻¹` is affine and the weights of a row sum to one,
/// `h_j = T⁻¹(Σᵢ P_jᵢ xᵢ / Σᵢ P_jᵢ)`, so only `P·1` and `P·X` are needed. A template point
/// that claims (almost) no data falls back to `T⁻¹` of the data point nearest to `T(y_j)`.
pub fn normalised_shape(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    result: &CpdResult,
) -> Result<Vec<[f64; 3]>, GeometryError> {
    let transform = &result.transform;
    if !(transform.scale.is_finite() && transform.scale > 0.0) {
        return Err(GeometryError::InvalidParams(format!(
            "transform scale must be > 0, got {}",
            transform.scale
        )));
    }
    let sums = posterior_sums(
        template,
        data,
        transform,
        result.sigma2,
        result.outlier_weight,
    )?;
    let mut index: Option<PointCloudIndex> = None;
    let mut h = Vec::with_capacity(template.len());
    for ((y, p1), px) in template.iter().zip(&sums.p1).zip(&sums.px) {
        let in_data_frame = if *p1 > ROW_MASS_FLOOR {
            points::scale(*px, 1.0 / p1)
        } else {
            let idx = match index.take() {
                Some(idx) => idx,
                None => PointCloudIndex::new(data)?,
            };
            let (nearest, _) = idx.nearest(transform.apply(*y));
            index = Some(idx);
            data.get(nearest).copied().unwrap_or(*y)
        };
        h.push(transform.inverse_apply(in_data_frame));
    }
    Ok(h)
}

/// Soft correspondences after a non-rigid refinement (eq. 3.10 with the refined posterior):
/// `h_j = Σᵢ P_jᵢ·xᵢ / Σᵢ P_jᵢ` for `data` in the template frame (`[M, 3]`, mm). Template
/// points that claim (almost) no data keep their deformed position.
pub fn refined_correspondences(refined: &NonRigidResult) -> Vec<[f64; 3]> {
    let sums = &refined.sums;
    sums.p1
        .iter()
        .zip(&sums.px)
        .zip(&refined.moved)
        .map(|((p1, px), moved)| {
            if *p1 > ROW_MASS_FLOOR {
                points::scale(*px, 1.0 / p1)
            } else {
                *moved
            }
        })
        .collect()
}

/// Flattens a point list `[M, 3]` to `[x₀, y₀, z₀, x₁, …]` (`3M` values), as used by PCA.
pub fn flatten(points: &[[f64; 3]]) -> Vec<f64> {
    points.iter().flatten().copied().collect()
}

/// Inverse of [`flatten`]; trailing values that do not form a full point are dropped.
pub fn unflatten(values: &[f64]) -> Vec<[f64; 3]> {
    values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::cpd::{RigidCpdParams, rigid_cpd};
    use crate::geometry::points::{axis_angle, dist2};
    use crate::geometry::transform::RigidTransform;

    fn grid() -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        for i in 0..6 {
            for j in 0..4 {
                for k in 0..3 {
                    v.push([
                        i as f64 * 4.0,
                        j as f64 * 3.0 + 0.5 * i as f64,
                        k as f64 * 2.5,
                    ]);
                }
            }
        }
        v
    }

    #[test]
    fn pose_is_removed_for_a_moved_copy() {
        let template = grid();
        let pose = RigidTransform {
            rotation: axis_angle([1.0, 1.0, 0.0], 0.4),
            translation: [20.0, -5.0, 3.0],
            scale: 1.0,
        };
        let data = pose.apply_all(&template);
        let result = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
        let h = normalised_shape(&template, &data, &result).unwrap();
        assert_eq!(h.len(), template.len());
        for (a, b) in h.iter().zip(&template) {
            assert!(dist2(*a, *b) < 1e-12, "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn soft_average_by_hand() {
        // Identity pose, σ² = 1, w = 0: template point at the origin sees data at ±1 on x
        // with equal weight, so h₀ = 0; the far template point claims nothing and falls back
        // to its nearest data point (1, 0, 0).
        let template = [[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0]];
        let data = [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let result = CpdResult {
            transform: RigidTransform::identity(),
            sigma2: 1.0,
            iterations: 0,
            converged: true,
            outlier_weight: 0.0,
            negative_log_likelihood: 0.0,
        };
        let h = normalised_shape(&template, &data, &result).unwrap();
        assert!(dist2(h[0], [0.0, 0.0, 0.0]) < 1e-24);
        assert_eq!(h[1], [1.0, 0.0, 0.0]);
    }

    #[test]
    fn flatten_round_trip() {
        let p = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        assert_eq!(flatten(&p), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(unflatten(&flatten(&p)), p.to_vec());
    }
}
