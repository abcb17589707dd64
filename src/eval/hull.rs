//! Leave-one-out projections of shapes in correspondence onto the affine hull of the others.
//!
//! A linear shape model of `n` training shapes draws shapes in (or near) their affine hull; a
//! new patient lies off it. With few training shapes that matters for the near-copy
//! threshold: a drawn shape near the middle of the hull is closer to some training shape than
//! the training shapes are to each other, without copying any. Projecting each training shape
//! on the hull of the others gives what such a model makes of a patient it has not seen,
//! whose distance to the nearest other training shape is the like-with-like reference.

use nalgebra::{DMatrix, DVector};

use super::EvalError;

/// Relative cut-off of singular values in the least-squares solve (collinear shapes).
const RANK_TOLERANCE: f64 = 1e-10;

/// For each shape `i` (each `[n_vertices, 3]`, mm, in correspondence; at least 3), its
/// closest point in the affine hull of the other shapes, `[n_vertices, 3]` mm.
pub fn leave_one_out_projections<S: AsRef<[[f64; 3]]>>(
    shapes: &[S],
) -> Result<Vec<Vec<[f64; 3]>>, EvalError> {
    let n = shapes.len();
    if n < 3 {
        return Err(EvalError::TooFewValues {
            what: "shapes for leave-one-out projections",
            required: 3,
            found: n,
        });
    }
    let m = shapes[0].as_ref().len();
    if let Some(other) = shapes.iter().find(|s| s.as_ref().len() != m) {
        return Err(EvalError::DimensionMismatch {
            what: "vertices of corresponding shapes",
            expected: m,
            found: other.as_ref().len(),
        });
    }
    // Centred coordinates keep the Gram matrix well conditioned.
    let flat: Vec<Vec<f64>> = shapes
        .iter()
        .map(|s| s.as_ref().iter().flatten().copied().collect())
        .collect();
    let mean: Vec<f64> = (0..3 * m)
        .map(|k| flat.iter().map(|f| f[k]).sum::<f64>() / n as f64)
        .collect();
    let centred: Vec<Vec<f64>> = flat
        .iter()
        .map(|f| f.iter().zip(&mean).map(|(v, c)| v - c).collect())
        .collect();
    if centred.iter().flatten().any(|v| !v.is_finite()) {
        return Err(EvalError::NonFinite { what: "shapes" });
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let gram = DMatrix::from_fn(n, n, |j, k| dot(&centred[j], &centred[k]));
    (0..n)
        .map(|i| Ok(project(i, &gram, &centred, &mean)))
        .collect()
}

/// Shape `i` projected on the affine hull of the others, from the Gram matrix of the
/// centred shapes: with an anchor `a ≠ i` and directions `d_j = x_j − x_a`, solves
/// `(DᵀD)·c = Dᵀ(x_i − x_a)` in the least-squares sense and returns `x_a + D·c`.
fn project(i: usize, gram: &DMatrix<f64>, centred: &[Vec<f64>], mean: &[f64]) -> Vec<[f64; 3]> {
    let n = centred.len();
    let others: Vec<usize> = (0..n).filter(|&j| j != i).collect();
    let (a, directions) = (others[0], &others[1..]);
    let g = |j: usize, k: usize| gram[(j, k)];
    let d = directions.len();
    let dtd = DMatrix::from_fn(d, d, |r, c| {
        let (j, k) = (directions[r], directions[c]);
        g(j, k) - g(j, a) - g(a, k) + g(a, a)
    });
    let rhs = DVector::from_fn(d, |r, _| {
        let j = directions[r];
        g(j, i) - g(j, a) - g(a, i) + g(a, a)
    });
    let scale = dtd.diagonal().max().max(f64::MIN_POSITIVE);
    let c = dtd
        .svd(true, true)
        .solve(&rhs, RANK_TOLERANCE * scale)
        .unwrap_or_else(|_| DVector::zeros(d));
    let mut x: Vec<f64> = centred[a].clone();
    for (r, &j) in directions.iter().enumerate() {
        for ((v, xj), xa) in x.iter_mut().zip(&centred[j]).zip(&centred[a]) {
            *v += c[r] * (xj - xa);
        }
    }
    x.chunks_exact(3)
        .zip(mean.chunks_exact(3))
        .map(|(p, c)| [p[0] + c[0], p[1] + c[1], p[2] + c[2]])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points.to_vec()
    }

    #[test]
    fn a_shape_on_the_line_of_two_others_projects_onto_itself() {
        // One-vertex shapes at x = 0, 1, 3: each lies on the line through the other two.
        let shapes = vec![
            shape(&[[0.0, 0.0, 0.0]]),
            shape(&[[1.0, 0.0, 0.0]]),
            shape(&[[3.0, 0.0, 0.0]]),
        ];
        let projected = leave_one_out_projections(&shapes).unwrap();
        for (p, s) in projected.iter().zip(&shapes) {
            assert!((p[0][0] - s[0][0]).abs() < 1e-9, "{p:?} vs {s:?}");
        }
    }

    #[test]
    fn a_shape_off_the_hull_drops_onto_it() {
        // Two-vertex shapes; the third is the first two's midpoint lifted by 2 mm in z at
        // both vertices: its projection is the midpoint.
        let shapes = vec![
            shape(&[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]),
            shape(&[[2.0, 0.0, 0.0], [12.0, 4.0, 0.0]]),
            shape(&[[1.0, 0.0, 2.0], [11.0, 2.0, 2.0]]),
        ];
        let projected = leave_one_out_projections(&shapes).unwrap();
        let expected = [[1.0, 0.0, 0.0], [11.0, 2.0, 0.0]];
        for (p, e) in projected[2].iter().zip(expected) {
            for k in 0..3 {
                assert!((p[k] - e[k]).abs() < 1e-9, "{:?}", projected[2]);
            }
        }
    }

    #[test]
    fn needs_three_shapes_of_one_size() {
        let two = vec![shape(&[[0.0; 3]]), shape(&[[1.0, 0.0, 0.0]])];
        assert!(leave_one_out_projections(&two).is_err());
        let ragged = vec![
            shape(&[[0.0; 3]]),
            shape(&[[1.0, 0.0, 0.0]]),
            shape(&[[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]),
        ];
        assert!(leave_one_out_projections(&ragged).is_err());
    }
}
