//! ASMG correspondence and atlas (thesis §4.2.1, app. A; SPEC §2.5 and §2.9): the numerical
//! part of the model that works on per-vertex embeddings and needs no network.
//!
//! - [`embeddings`]: the `[n_vertices, d_z]` matrices the graph network Ψ hands over;
//! - [`attention`]: soft correspondences `Φ_k` and normalised shapes `h_k = Φ_k X_k`;
//! - [`laplacian`]: the factored `(c·I + γL)` of the atlas connectivity, Jacobi sweeps;
//! - [`smoothing`]: Laplacian smoothing of normalised shapes (positions or displacement).

pub mod attention;
pub mod embeddings;
pub mod laplacian;
mod parallel;
mod scores;
pub mod smoothing;

pub use attention::{
    Correspondence, Match, ScoreMoments, Temperature, attention_rows, correspond,
    inverse_temperature, normalised_shape, score_moments,
};
pub use embeddings::Embeddings;
pub use laplacian::LaplacianSolver;
pub use smoothing::{Smoother, Smoothing, SmoothingMethod, SmoothingParams, smooth};
