//! cohortforge: generative models of anatomical shape served as virtual cohorts.
//!
//! Layers, each using only the ones listed below it (checked by `tests/it/architecture.rs`):

/// HTTP routes, handlers, auth, problem+json errors and the OpenAPI document.
pub mod api;
/// Command-line interface: the server and the offline commands.
pub mod cli;
/// Service configuration from flags and `COHORTFORGE_*` environment variables.
pub mod config;
/// Distances, biomarkers and clinical acceptance (pure).
pub mod eval;
/// Rigid registration, k-d tree queries, PCA and other shape geometry (pure).
pub mod geometry;
/// Durable fit jobs and the worker pool that runs them.
pub mod jobs;
/// Triangle meshes: formats, validation, measures and phantoms (pure).
pub mod mesh;
/// Shape models (rsmp, ...) behind one interface, and virtual cohorts (pure).
pub mod models;
/// Neural networks on burn: FeaStConv, the graph VAE and the beta-VAE (pure).
pub mod nn;
/// Report pages: self-contained HTML with inline SVG plots of cohorts and models (pure).
pub mod report;
/// NIfTI label volumes to closed surface meshes: labels, components, marching cubes (pure).
pub mod segmentation;
/// SQLite repositories for datasets, meshes (and later jobs, models, cohorts).
pub mod store;
/// Prometheus metrics of the process, scraped at `/metrics`.
pub mod telemetry;
