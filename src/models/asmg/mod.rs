//! ASMG correspondence and atlas (thesis §4.2.1, app. A; SPEC §2.5 and §2.9): the numerical
//! part of the model that works on per-vertex embeddings and needs no network.
//!
//! - [`embeddings`]: the `[n_vertices, d_z]` matrices the graph network Ψ hands over;
//! - [`attention`]: soft correspondences `Φ_k` and normalised shapes `h_k = Φ_k X_k`;
//! - [`laplacian`]: the factored `(c·I + γL)` of the atlas connectivity, Jacobi sweeps;
//! - [`smoothing`]: Laplacian smoothing of normalised shapes (positions or displacement);
//! - [`atlas`]: the atlas update from the smoothed shapes, damped;
//! - [`init`], [`icosphere`]: the initial atlas;
//! - [`learn`]: Algorithm 1, the loop over all of the above until the atlas settles.

pub mod atlas;
pub mod attention;
pub mod embeddings;
pub mod icosphere;
pub mod init;
pub mod laplacian;
pub mod learn;
mod parallel;
mod scores;
pub mod smoothing;

pub use atlas::{AtlasUpdateParams, AtlasUpdater, update_atlas};
pub use attention::{
    Correspondence, Match, ScoreMoments, Temperature, attention_rows, correspond,
    inverse_temperature, normalised_shape, score_moments,
};
pub use embeddings::Embeddings;
pub use init::{AtlasInit, initial_atlas};
pub use laplacian::LaplacianSolver;
pub use learn::{
    AtlasLoopParams, AtlasStep, LearnedAtlas, NormalisedShapes, ShapeInput, learn_atlas,
    normalise_shapes,
};
pub use smoothing::{Smoother, Smoothing, SmoothingMethod, SmoothingParams, smooth};
