//! Durable jobs (fits and large cohorts): the worker pool and the run of one job.

pub mod cohort;
pub mod fit;
pub mod run;
pub mod split;
pub mod worker;

pub use crate::models::ModelParams;
pub use worker::{WorkerPool, WorkerSettings};
