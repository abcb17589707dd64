//! Evaluation of shape models: surface distances, biomarkers, clinical acceptance.
//! Pure: no async, SQL or HTTP.

pub mod acceptance;
pub mod biomarkers;
pub mod clustering;
mod error;
pub mod fidelity;
pub mod gaussian_reference;
pub mod hull;
pub mod kde;
pub mod metrics;
pub mod normal;
pub mod privacy;
pub mod shape_columns;
pub mod stats;
pub mod surface_metrics;

pub use biomarkers::Biomarkers;
pub use error::EvalError;
pub use stats::{MeanStd, SummaryStats};
