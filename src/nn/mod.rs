//! Neural networks on burn: the FeaStConv graph convolution, the graph VAE Ψ that embeds
//! mesh vertices, and the beta-VAE generator of atlas-domain shapes (thesis ch. 4,
//! SPEC §2.4 and §2.6). Pure: no async, SQL, HTTP or file system.
//!
//! The device is chosen at run time ([`device`]); weights, batch order and sampling noise come
//! from seeded streams, so the same seed gives the same network. Trained networks store their
//! weights as burn records (bytes) and are rebuilt from their config and those bytes.

pub mod beta_vae;
mod beta_vae_train;
pub mod dense;
pub mod device;
mod error;
pub mod feast;
pub mod graph;
pub mod graph_vae;
mod graph_vae_train;
mod init;
mod latent_prior;
pub mod refine;
pub mod slots;
pub mod train;

pub use beta_vae::{BetaVaeConfig, ShapeScaling};
pub use beta_vae_train::{
    BetaVaeTraining, TrainedBetaVae, train_beta_vae, train_weighted_beta_vae,
};
pub use error::NnError;
pub use feast::{FeaStConfig, FeaStConv};
pub use graph::{Features, GraphBatch, GraphSample, PositionScaling};
pub use graph_vae::GraphVaeConfig;
pub use graph_vae_train::{GraphVaeTraining, TrainedGraphVae, train_graph_vae};
pub use latent_prior::LatentPrior;
pub use refine::{GraphRefiner, RefineEpoch, RefineObjective, RefineTerms, RefineTraining};
pub use slots::{GraphTensors, SlotLayout};
pub use train::{Flow, Monitor, Unmonitored};
