//! End-to-end tests: one binary, a real server on an ephemeral port, a temporary database.

mod architecture;
mod asmg;
mod atlas_r_asmg;
mod auth;
mod bad_uploads;
mod cli;
mod cohorts;
mod datasets;
mod jobs;
mod kits19;
mod matlas_r_asmg;
mod meshes;
mod nifti;
mod openapi;
mod pictures_exports;
mod processes;
mod queue;
mod reports;
mod support;
