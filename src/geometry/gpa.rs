//! Rigid generalised Procrustes alignment (GPA) of shapes already in correspondence.
//!
//! Each shape `[M, 3]` (mm) is rotated and translated (never scaled) onto the mean of all of
//! them, the mean recomputed, and so on until it settles. The mean is kept in the frame of
//! the shapes' plain average, so the aligned shapes stay where they were on the whole.
//!
//! PCA of shapes that still differ by small rotations spends modes on those rotations, and a
//! rotation taken linearly (`x + θ·K·x`) also stretches the shape by `√(1 + θ²)`; a drawn
//! shape then combines such stretches with real shape modes. Aligning in correspondence first
//! leaves only shape in the PCA.

use super::GeometryError;
use super::procrustes::weighted_procrustes;
use super::transform::RigidTransform;

/// Most alternations of aligning and averaging.
pub const MAX_ITERATIONS: usize = 20;
/// Stop when the mean moves less than this share of its rms radius between alternations.
const TOLERANCE: f64 = 1e-9;

/// The aligned frame of a set of shapes.
#[derive(Debug, Clone, PartialEq)]
pub struct Gpa {
    /// For each input shape, the transform onto the mean (`aligned = T(shape)`).
    pub transforms: Vec<RigidTransform>,
    /// The mean of the aligned shapes `[M, 3]`, mm.
    pub mean: Vec<[f64; 3]>,
}

/// Pointwise mean of shapes with equal vertex counts.
fn average<S: AsRef<[[f64; 3]]>>(shapes: &[S]) -> Vec<[f64; 3]> {
    let n = shapes.len().max(1) as f64;
    let m = shapes.first().map_or(0, |s| s.as_ref().len());
    let mut mean = vec![[0.0; 3]; m];
    for shape in shapes {
        for (acc, p) in mean.iter_mut().zip(shape.as_ref()) {
            for k in 0..3 {
                acc[k] += p[k] / n;
            }
        }
    }
    mean
}

fn mean_square_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = a.len().max(1) as f64;
    a.iter()
        .zip(b)
        .map(|(p, q)| super::points::dist2(*p, *q))
        .sum::<f64>()
        / n
}

/// Aligns `shapes` (each `[M, 3]`, mm, the same `M`, at least one) rigidly onto their mean.
pub fn generalised_procrustes<S: AsRef<[[f64; 3]]>>(shapes: &[S]) -> Result<Gpa, GeometryError> {
    let first = shapes
        .first()
        .ok_or_else(|| GeometryError::DegenerateInput("no shapes to align".into()))?;
    let m = first.as_ref().len();
    if let Some(other) = shapes.iter().find(|s| s.as_ref().len() != m) {
        return Err(GeometryError::DimensionMismatch {
            what: "shape",
            expected: m,
            found: other.as_ref().len(),
        });
    }
    let anchor = average(shapes);
    let spread = super::points::rms_radius(&anchor)
        .powi(2)
        .max(f64::MIN_POSITIVE);
    let mut mean = anchor.clone();
    for _ in 0..MAX_ITERATIONS {
        let aligned = shapes
            .iter()
            .map(|s| Ok(weighted_procrustes(s.as_ref(), &mean, None, false)?.apply_all(s.as_ref())))
            .collect::<Result<Vec<_>, GeometryError>>()?;
        // Keep the new mean in the anchor's frame, so the alternation cannot drift.
        let next = average(&aligned);
        let back = weighted_procrustes(&next, &anchor, None, false)?;
        let next = back.apply_all(&next);
        let moved = mean_square_distance(&next, &mean);
        mean = next;
        if moved < TOLERANCE * TOLERANCE * spread {
            break;
        }
    }
    let transforms = shapes
        .iter()
        .map(|s| weighted_procrustes(s.as_ref(), &mean, None, false))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Gpa { transforms, mean })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::points::{axis_angle, dist2, rotation_angle};

    fn shape() -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, 0.0],
            [40.0, 0.0, 0.0],
            [0.0, 20.0, 0.0],
            [0.0, 0.0, 10.0],
            [10.0, 15.0, 5.0],
        ]
    }

    fn moved(rotation_axis: [f64; 3], angle: f64, shift: [f64; 3]) -> Vec<[f64; 3]> {
        let r = axis_angle(rotation_axis, angle);
        RigidTransform {
            rotation: r,
            translation: shift,
            scale: 1.0,
        }
        .apply_all(&shape())
    }

    #[test]
    fn posed_copies_of_one_shape_align_exactly() {
        let copies = vec![
            moved([0.0, 0.0, 1.0], 0.2, [1.0, 0.0, 0.0]),
            moved([0.0, 1.0, 0.0], -0.15, [0.0, 3.0, 0.0]),
            moved([1.0, 1.0, 0.0], 0.1, [0.0, 0.0, -2.0]),
        ];
        let gpa = generalised_procrustes(&copies).unwrap();
        let aligned: Vec<Vec<[f64; 3]>> = copies
            .iter()
            .zip(&gpa.transforms)
            .map(|(s, t)| t.apply_all(s))
            .collect();
        for a in &aligned {
            for (p, q) in a.iter().zip(&gpa.mean) {
                assert!(dist2(*p, *q) < 1e-16, "{p:?} vs {q:?}");
            }
        }
        // Rotations are rigid: no scale, proper.
        assert!(gpa.transforms.iter().all(|t| t.scale == 1.0));
        // The mean stays where the plain average was on the whole (same centroid).
        let (c_mean, c_avg) = (
            crate::geometry::points::centroid(&gpa.mean, None),
            crate::geometry::points::centroid(&average(&copies), None),
        );
        assert!(dist2(c_mean, c_avg) < 1e-16);
    }

    #[test]
    fn aligned_shapes_keep_their_differences_in_shape() {
        // Two shapes that differ in one vertex and by a pose: the pose goes, the vertex stays.
        let mut other = shape();
        other[4][2] += 6.0;
        let posed = RigidTransform {
            rotation: axis_angle([0.0, 0.0, 1.0], 0.3),
            translation: [5.0, -2.0, 1.0],
            scale: 1.0,
        }
        .apply_all(&other);
        let gpa = generalised_procrustes(&[shape(), posed.clone()]).unwrap();
        let a = gpa.transforms[0].apply_all(&shape());
        let b = gpa.transforms[1].apply_all(&posed);
        let gap: f64 = a.iter().zip(&b).map(|(p, q)| dist2(*p, *q)).sum();
        // Rigid alignment cannot remove the 6 mm change; it only spreads it.
        assert!(gap > 20.0 && gap < 36.0 + 1e-9, "{gap}");
        let relative = crate::geometry::points::mat_mul(
            &gpa.transforms[1].rotation,
            &crate::geometry::points::transpose(&gpa.transforms[0].rotation),
        );
        assert!((rotation_angle(&relative) - 0.3).abs() < 0.05);
    }

    #[test]
    fn rejects_empty_and_ragged_input() {
        let none: Vec<Vec<[f64; 3]>> = vec![];
        assert!(generalised_procrustes(&none).is_err());
        let ragged = vec![shape(), shape()[..4].to_vec()];
        assert!(generalised_procrustes(&ragged).is_err());
    }
}
