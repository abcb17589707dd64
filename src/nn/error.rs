//! Errors of the neural-network layer, each with a stable machine-readable code.

use thiserror::Error;

/// What went wrong while building, training, running or (de)serialising a network.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NnError {
    /// There is nothing to train on.
    #[error("training needs at least one sample, got none")]
    EmptyDataset,
    /// A sample has no vertices (graph) or no values (flat shape).
    #[error("sample {sample} is empty")]
    EmptySample {
        /// Index of the sample.
        sample: usize,
    },
    /// An edge refers to a vertex that does not exist.
    #[error(
        "sample {sample}: edge {edge} refers to vertex {vertex}, but there are {vertex_count} vertices"
    )]
    EdgeOutOfRange {
        /// Index of the sample.
        sample: usize,
        /// Index of the edge.
        edge: usize,
        /// Offending vertex index.
        vertex: u32,
        /// Number of vertices.
        vertex_count: usize,
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
    /// An input value is NaN or infinite.
    #[error("`{what}` contains a non-finite value")]
    NonFinite {
        /// Which input held the value.
        what: &'static str,
    },
    /// A configuration or training setting is out of range.
    #[error("invalid setting `{name}`: {reason}")]
    InvalidConfig {
        /// Which setting.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// The loss became NaN or infinite during training.
    #[error("training diverged at epoch {epoch}: the loss is not finite")]
    Diverged {
        /// Epoch (0-based) in which it happened.
        epoch: usize,
    },
    /// The monitor asked to stop between batches.
    #[error("training was cancelled")]
    Cancelled,
    /// Stored weights could not be read or do not fit the configuration.
    #[error("stored weights are unusable: {0}")]
    Weights(String),
    /// A loss computed outside the network (the refinement objective) failed.
    #[error("the refinement loss could not be computed: {0}")]
    Objective(String),
}

impl NnError {
    /// Stable error code, e.g. `nn.empty_dataset`.
    pub fn code(&self) -> &'static str {
        match self {
            Self::EmptyDataset => "nn.empty_dataset",
            Self::EmptySample { .. } => "nn.empty_sample",
            Self::EdgeOutOfRange { .. } => "nn.edge_out_of_range",
            Self::DimensionMismatch { .. } => "nn.dimension_mismatch",
            Self::NonFinite { .. } => "nn.non_finite",
            Self::InvalidConfig { .. } => "nn.invalid_config",
            Self::Diverged { .. } => "nn.diverged",
            Self::Cancelled => "nn.cancelled",
            Self::Objective(_) => "nn.objective",
            Self::Weights(_) => "nn.weights",
        }
    }
}

/// Checks that every value is finite.
pub(crate) fn check_finite(values: &[f32], what: &'static str) -> Result<(), NnError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(NnError::NonFinite { what })
    }
}

/// Rejects a setting unless `ok` holds.
pub(crate) fn require(ok: bool, name: &'static str, reason: &str) -> Result<(), NnError> {
    if ok {
        Ok(())
    } else {
        Err(NnError::InvalidConfig {
            name,
            reason: reason.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_stable() {
        assert_eq!(NnError::EmptyDataset.code(), "nn.empty_dataset");
        assert_eq!(
            check_finite(&[1.0, f32::NAN], "x").unwrap_err().code(),
            "nn.non_finite"
        );
        assert!(check_finite(&[1.0, -2.0], "x").is_ok());
        assert_eq!(
            require(false, "lr", "must be positive").unwrap_err().code(),
            "nn.invalid_config"
        );
        assert_eq!(NnError::Cancelled.code(), "nn.cancelled");
    }
}
