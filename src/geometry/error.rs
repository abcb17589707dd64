//! Errors of the geometry layer, each with a stable machine-readable code.

use thiserror::Error;

/// What went wrong in a geometric computation.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GeometryError {
    /// A statistical model needs more shapes than it was given.
    #[error("need at least {required} shapes, got {found}")]
    TooFewShapes {
        /// Shapes required.
        required: usize,
        /// Shapes given.
        found: usize,
    },
    /// A point set is empty.
    #[error("point set `{what}` is empty")]
    EmptyPointSet {
        /// Which input was empty.
        what: &'static str,
    },
    /// A coordinate or value is NaN or infinite.
    #[error("input `{what}` contains a non-finite value")]
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
    /// The input is valid but carries no information to work with (e.g. identical shapes).
    #[error("degenerate input: {0}")]
    DegenerateInput(String),
    /// A parameter is outside its allowed range.
    #[error("invalid parameter: {0}")]
    InvalidParams(String),
    /// A matrix decomposition failed to converge.
    #[error("singular value decomposition did not converge")]
    SvdFailed,
}

impl GeometryError {
    /// Stable error code, e.g. `geometry.too_few_shapes`.
    pub fn code(&self) -> &'static str {
        match self {
            Self::TooFewShapes { .. } => "geometry.too_few_shapes",
            Self::EmptyPointSet { .. } => "geometry.empty_point_set",
            Self::NonFinite { .. } => "geometry.non_finite",
            Self::DimensionMismatch { .. } => "geometry.dimension_mismatch",
            Self::DegenerateInput(_) => "geometry.degenerate_input",
            Self::InvalidParams(_) => "geometry.invalid_params",
            Self::SvdFailed => "geometry.svd_failed",
        }
    }
}

/// Checks that a point set is non-empty and finite.
pub(crate) fn check_points(points: &[[f64; 3]], what: &'static str) -> Result<(), GeometryError> {
    if points.is_empty() {
        return Err(GeometryError::EmptyPointSet { what });
    }
    if points.iter().flatten().any(|c| !c.is_finite()) {
        return Err(GeometryError::NonFinite { what });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_stable() {
        let e = GeometryError::TooFewShapes {
            required: 2,
            found: 1,
        };
        assert_eq!(e.code(), "geometry.too_few_shapes");
        assert_eq!(e.to_string(), "need at least 2 shapes, got 1");
        assert_eq!(
            GeometryError::DegenerateInput("x".into()).code(),
            "geometry.degenerate_input"
        );
        assert!(check_points(&[], "a").is_err());
        assert_eq!(
            check_points(&[[0.0, f64::NAN, 0.0]], "a")
                .unwrap_err()
                .code(),
            "geometry.non_finite"
        );
    }
}
