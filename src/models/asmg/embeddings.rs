//! Per-vertex embeddings produced by the graph network Ψ, as a plain row-major matrix.

use crate::models::ModelError;

/// Embeddings of the vertices of one mesh: `[rows, dim]`, row-major, `f32`.
///
/// Row `i` is the embedding `z_i` of vertex `i`. The fields are public so that a network can
/// hand over its output without copying; [`Embeddings::check`] validates them.
#[derive(Debug, Clone, PartialEq)]
pub struct Embeddings {
    /// Number of vertices (rows).
    pub rows: usize,
    /// Embedding dimension `d_z` (columns).
    pub dim: usize,
    /// Row-major values, `rows · dim` of them.
    pub data: Vec<f32>,
}

impl Embeddings {
    /// Embeddings from row-major `f32` values (`[rows, dim]`), validated.
    pub fn new(rows: usize, dim: usize, data: Vec<f32>) -> Result<Self, ModelError> {
        let e = Self { rows, dim, data };
        e.check()?;
        Ok(e)
    }

    /// Embeddings from row-major `f64` values (`[rows, dim]`), rounded to `f32`, validated.
    pub fn from_f64(rows: usize, dim: usize, data: &[f64]) -> Result<Self, ModelError> {
        Self::new(rows, dim, data.iter().map(|&v| v as f32).collect())
    }

    /// Checks that there is at least one row and column, that `data` holds `rows · dim`
    /// values and that all of them are finite.
    pub fn check(&self) -> Result<(), ModelError> {
        if self.rows == 0 || self.dim == 0 {
            return Err(ModelError::InvalidInput(format!(
                "embeddings must have at least one row and column, got [{}, {}]",
                self.rows, self.dim
            )));
        }
        if self.rows.checked_mul(self.dim) != Some(self.data.len()) {
            return Err(ModelError::InvalidInput(format!(
                "embeddings [{}, {}] need {} values, got {}",
                self.rows,
                self.dim,
                self.rows.saturating_mul(self.dim),
                self.data.len()
            )));
        }
        if let Some(i) = self.data.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::InvalidInput(format!(
                "embedding value {} of row {} is not finite",
                i % self.dim,
                i / self.dim
            )));
        }
        Ok(())
    }

    /// The rows, each of length `dim` (call [`Embeddings::check`] first).
    pub fn row_iter(&self) -> std::slice::ChunksExact<'_, f32> {
        self.data.chunks_exact(self.dim.max(1))
    }

    /// `1 / ‖z_i‖` for every row; 0 for a zero row (whose scores are then all 0).
    pub fn inverse_norms(&self) -> Vec<f32> {
        self.row_iter()
            .map(|row| {
                let norm = f64::from(dot(row, row)).sqrt();
                if norm > 0.0 { (1.0 / norm) as f32 } else { 0.0 }
            })
            .collect()
    }
}

/// Lanes of the unrolled dot product (lets the compiler use SIMD registers).
const DOT_LANES: usize = 8;

/// `Σ a_l b_l` over the common length, with a fixed summation order (deterministic).
pub(crate) fn dot(a: &[f32], b: &[f32]) -> f32 {
    let ca = a.chunks_exact(DOT_LANES);
    let cb = b.chunks_exact(DOT_LANES);
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0f32; DOT_LANES];
    for (x, y) in ca.zip(cb) {
        for l in 0..DOT_LANES {
            acc[l] += x[l] * y[l];
        }
    }
    let half = [
        acc[0] + acc[4],
        acc[1] + acc[5],
        acc[2] + acc[6],
        acc[3] + acc[7],
    ];
    ((half[0] + half[2]) + (half[1] + half[3])) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_values_are_checked() {
        assert!(Embeddings::new(2, 3, vec![0.0; 6]).is_ok());
        assert!(matches!(
            Embeddings::new(2, 3, vec![0.0; 5]),
            Err(ModelError::InvalidInput(_))
        ));
        assert!(Embeddings::new(0, 3, vec![]).is_err());
        let err = Embeddings::new(2, 2, vec![0.0, 1.0, f32::NAN, 0.0]).unwrap_err();
        assert!(err.to_string().contains("row 1"), "{err}");
    }

    #[test]
    fn inverse_norms_of_rows() {
        let e = Embeddings::from_f64(3, 2, &[3.0, 4.0, 0.0, 0.0, 0.0, 0.5]).unwrap();
        let inv = e.inverse_norms();
        assert!((inv[0] - 0.2).abs() < 1e-7);
        assert_eq!(inv[1], 0.0);
        assert!((inv[2] - 2.0).abs() < 1e-7);
    }

    #[test]
    fn dot_matches_a_plain_sum_with_a_tail() {
        let a: Vec<f32> = (0..19).map(|i| i as f32 * 0.5).collect();
        let b: Vec<f32> = (0..19).map(|i| 1.0 - i as f32 * 0.1).collect();
        let plain: f64 = a.iter().zip(&b).map(|(x, y)| f64::from(x * y)).sum();
        assert!((f64::from(dot(&a, &b)) - plain).abs() < 1e-4);
        assert_eq!(dot(&[2.0], &[3.0]), 6.0);
    }
}
