//! Evaluation of shape models: surface distances, biomarkers, clinical acceptance.
//! Pure: no async, SQL or HTTP.

pub mod acceptance;
pub mod biomarkers;
mod error;
pub mod kde;
pub mod metrics;
pub mod privacy;
pub mod stats;

pub use biomarkers::Biomarkers;
pub use error::EvalError;
pub use stats::{MeanStd, SummaryStats};
