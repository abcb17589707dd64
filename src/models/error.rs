//! Errors of model fitting and sampling.

use super::progress::Cancelled;
use crate::eval::EvalError;
use crate::geometry::GeometryError;

/// What can stop a fit or a cohort.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A parameter has an invalid value.
    #[error("params.{field}: {message}")]
    InvalidParams {
        /// The parameter.
        field: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// The training split is too small.
    #[error(
        "the model needs at least {required} training meshes but the split leaves {found}; \
         upload more meshes or lower holdout_fraction"
    )]
    TooFewMeshes {
        /// Least number of training meshes.
        required: usize,
        /// Training meshes available.
        found: usize,
    },
    /// Acceptance sampling could not find enough accepted members.
    #[error(
        "only {accepted} of {draws} draws passed every filter asked for (the {criterion} \
         criterion, the privacy guard, the targets and the plausible range, as requested), short \
         of the {size} asked for; lower size, widen the criterion or the targets, or turn off \
         only_accepted or exclude_near_copies"
    )]
    AcceptanceUnreachable {
        /// Members asked for.
        size: usize,
        /// Accepted members found.
        accepted: usize,
        /// Draws made (the bound).
        draws: usize,
        /// The criterion.
        criterion: &'static str,
    },
    /// A cohort target lies outside what the model's draws reach, or too few draws met it.
    #[error(
        "targets.{biomarker}: {detail}; this model's draws reach {low:.2}–{high:.2} {unit} \
         (seen in its own pilot draws): ask for a target inside that range"
    )]
    TargetUnreachable {
        /// The biomarker's JSON name.
        biomarker: String,
        /// What failed.
        detail: String,
        /// Lowest value the model reaches.
        low: f64,
        /// Highest value the model reaches.
        high: f64,
        /// Unit of the biomarker.
        unit: &'static str,
    },
    /// Geometry failed (registration, PCA, distances).
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// Evaluation failed (biomarkers, statistics).
    #[error(transparent)]
    Eval(#[from] EvalError),
    /// The job was cancelled.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    /// A stored model was written in a format this release does not read.
    #[error(
        "the stored model is in {}, but this release reads format {}; \
         fit the model again with this release",
        .found.map_or("a format without a format version (written before format 2)".to_owned(), |v| format!("format {v}")),
        .supported.iter().map(u16::to_string).collect::<Vec<_>>().join(", ")
    )]
    UnsupportedVersion {
        /// The version found, `None` without a header.
        found: Option<u16>,
        /// The versions this release reads.
        supported: Vec<u16>,
    },
    /// No model type has this name.
    #[error("model_type '{name}' is not known; use one of: {known}")]
    UnknownModelType {
        /// The name given.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// A stored model could not be decoded.
    #[error("stored model is corrupt: {0}")]
    Corrupt(String),
    /// Inputs of a numerical step do not fit together (sizes, non-finite values).
    #[error("invalid model input: {0}")]
    InvalidInput(String),
    /// A numerical step failed (e.g. a factorisation).
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl ModelError {
    /// Stable code.
    pub fn code(&self) -> &'static str {
        match self {
            Self::InvalidParams { .. } => "model.invalid_params",
            Self::TooFewMeshes { .. } => "model.too_few_meshes",
            Self::AcceptanceUnreachable { .. } => "cohort.acceptance_unreachable",
            Self::TargetUnreachable { .. } => "cohort.target_unreachable",
            Self::Geometry(e) => e.code(),
            Self::Eval(e) => e.code(),
            Self::Cancelled(_) => "job.cancelled",
            Self::Corrupt(_) => "model.corrupt",
            Self::UnsupportedVersion { .. } => "model.unsupported_version",
            Self::UnknownModelType { .. } => "model.unknown_type",
            Self::InvalidInput(_) => "model.invalid_input",
            Self::Numerical(_) => "model.numerical",
        }
    }

    /// An invalid parameter.
    pub fn invalid(field: &str, message: impl Into<String>) -> Self {
        Self::InvalidParams {
            field: field.to_owned(),
            message: message.into(),
        }
    }
}
