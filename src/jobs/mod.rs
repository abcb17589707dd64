//! Durable fit jobs: validation at submission, the worker pool, and the run of one job.

pub mod fit;
pub mod run;
pub mod split;
pub mod worker;

pub use crate::models::ModelParams;
pub use worker::{WorkerPool, WorkerSettings};
