//! Errors of the evaluation layer, each with a stable machine-readable code.

use thiserror::Error;

use crate::geometry::GeometryError;

/// What went wrong while evaluating shapes or cohorts.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EvalError {
    /// A statistic needs more values than it was given.
    #[error("`{what}` needs at least {required} values, got {found}")]
    TooFewValues {
        /// Which statistic.
        what: &'static str,
        /// Values required.
        required: usize,
        /// Values given.
        found: usize,
    },
    /// A value is NaN or infinite.
    #[error("`{what}` contains a non-finite value")]
    NonFinite {
        /// Which input held the value.
        what: &'static str,
    },
    /// Lengths that must agree do not.
    #[error("dimension mismatch in `{what}`: expected {expected}, found {found}")]
    DimensionMismatch {
        /// Which input had the wrong length.
        what: &'static str,
        /// Length expected.
        expected: usize,
        /// Length found.
        found: usize,
    },
    /// A mesh refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {vertex}, but the mesh has {vertex_count} vertices")]
    InvalidMesh {
        /// Offending face.
        face: usize,
        /// Offending vertex index.
        vertex: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A geometric computation failed.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
}

impl EvalError {
    /// Stable error code, e.g. `eval.too_few_values` (geometry errors keep their own code).
    pub fn code(&self) -> &'static str {
        match self {
            Self::TooFewValues { .. } => "eval.too_few_values",
            Self::NonFinite { .. } => "eval.non_finite",
            Self::DimensionMismatch { .. } => "eval.dimension_mismatch",
            Self::InvalidMesh { .. } => "eval.invalid_mesh",
            Self::Geometry(e) => e.code(),
        }
    }
}

/// Checks that `values` has at least `required` entries, all finite.
pub(crate) fn check_values(
    values: &[f64],
    required: usize,
    what: &'static str,
) -> Result<(), EvalError> {
    if values.len() < required {
        return Err(EvalError::TooFewValues {
            what,
            required,
            found: values.len(),
        });
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(EvalError::NonFinite { what });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_stable() {
        assert_eq!(
            check_values(&[1.0], 2, "x").unwrap_err().code(),
            "eval.too_few_values"
        );
        assert_eq!(
            check_values(&[f64::NAN], 1, "x").unwrap_err().code(),
            "eval.non_finite"
        );
        let g: EvalError = GeometryError::SvdFailed.into();
        assert_eq!(g.code(), "geometry.svd_failed");
    }
}
