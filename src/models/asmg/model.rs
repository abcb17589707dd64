//! A fitted ASMG model: the learned atlas, the graph VAE Ψ that embeds vertices, and the
//! beta-VAE generator of atlas-domain shapes, with the settings that tie them together.
//!
//! The networks are stored as burn records (bytes) and rebuilt once, on first use, after a
//! model is read back. Sampling draws a standard normal ε (clipped), maps it through the
//! Gaussian fitted to the training shapes' codes and decodes it to a mesh with the atlas
//! connectivity (mm). Reconstruction of an unseen mesh: simplify, register rigidly to the
//! alignment reference, Ψ → attention Φ → h → smoothed h' → encoder mean → decoder.

use std::sync::OnceLock;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use super::biomarker_calibration::BiomarkerCalibration;
use super::calibration::SpreadCalibration;
use super::embeddings::Embeddings;
use super::learn::{ShapeInput, normalise_shapes};
use super::nonrigid::refine_normalised;
use super::params::AsmgParams;
use super::registration::align;
use super::smoothing::Smoother;
use crate::geometry::cpd::NonRigidParams;
use crate::geometry::pca::Sampling;
use crate::mesh::{Laterality, Mesh};
use crate::models::alignment::AlignmentParams;
use crate::models::stored::{FittedModel, encode_named};
use crate::models::{Draw, ModelError, Reconstruction, ShapeModel, StandardLatent, check_cluster};
use crate::nn::{
    BetaVaeConfig, GraphSample, GraphVaeConfig, LatentPrior, NnError, TrainedBetaVae,
    TrainedGraphVae,
};

/// Latent coordinates are kept within ±this (in standard deviations), as RSMP clips its
/// mode weights at 3√λ.
pub const LATENT_CLIP: f64 = 3.0;

/// Sizes of the two networks, enough to rebuild them from their weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NetworkSizes {
    /// Ψ: node feature width (3 or 6).
    pub graph_d_x: usize,
    /// Ψ: hidden widths.
    pub graph_hidden: Vec<usize>,
    /// Ψ: embedding width `d_z`.
    pub graph_d_z: usize,
    /// Ψ: FeaStConv heads.
    pub graph_heads: usize,
    /// Generator: input width `3·N_μ`.
    pub vae_d_in: usize,
    /// Generator: hidden widths.
    pub vae_hidden: Vec<usize>,
    /// Generator: latent width `L`.
    pub vae_latent: usize,
}

impl NetworkSizes {
    /// The sizes of the given configurations.
    pub fn of(graph: &GraphVaeConfig, vae: &BetaVaeConfig) -> Self {
        Self {
            graph_d_x: graph.d_x,
            graph_hidden: graph.hidden.clone(),
            graph_d_z: graph.d_z,
            graph_heads: graph.heads,
            vae_d_in: vae.d_in,
            vae_hidden: vae.hidden.clone(),
            vae_latent: vae.latent,
        }
    }

    fn graph(&self) -> GraphVaeConfig {
        GraphVaeConfig::new()
            .with_d_x(self.graph_d_x)
            .with_hidden(self.graph_hidden.clone())
            .with_d_z(self.graph_d_z)
            .with_heads(self.graph_heads)
    }

    fn vae(&self) -> BetaVaeConfig {
        BetaVaeConfig::new(self.vae_d_in)
            .with_hidden(self.vae_hidden.clone())
            .with_latent(self.vae_latent)
    }
}

/// The networks and what is derived from them, ready to use.
#[derive(Debug, Clone)]
pub struct Networks {
    /// Ψ.
    pub graph: TrainedGraphVae,
    /// The generator.
    pub generator: TrainedBetaVae,
    /// `Z_μ = Ψ(X_μ)` of the final atlas, `[N_μ, d_z]`.
    pub atlas_embeddings: Embeddings,
    /// Smoothing on the atlas connectivity (factored once).
    pub smoother: Smoother,
}

/// A fitted ASMG model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AsmgModel {
    /// The learned atlas (mm, model frame): the connectivity of every output.
    pub atlas: Mesh,
    /// The mesh every input is rigidly registered to (simplified, mm, model frame).
    pub reference: Mesh,
    /// Registration settings, reused for unseen meshes.
    pub alignment: AlignmentParams,
    /// The fit's parameters (features, vertex budget, attention and smoothing settings).
    pub params: AsmgParams,
    /// Sizes of Ψ and of the generator.
    pub sizes: NetworkSizes,
    /// Ψ's weights (burn record).
    #[serde(with = "serde_bytes")]
    pub graph_weights: Vec<u8>,
    /// The generator's weights (burn record).
    #[serde(with = "serde_bytes")]
    pub generator_weights: Vec<u8>,
    /// The Gaussian that new codes are drawn from, fitted to the training shapes' codes
    /// (absent in models stored before it existed: N(0, I)).
    #[serde(default)]
    pub latent_prior: Option<LatentPrior>,
    /// Corrections that give drawn shapes the training shapes' spread (absent in models
    /// stored before it existed, or fitted with `calibrate_spread` off: draws as decoded).
    #[serde(default)]
    pub spread_calibration: Option<SpreadCalibration>,
    /// Moves of drawn shapes along the training shapes' regression on volume and area that
    /// give the draws their volume and area spread (fitted with `calibration: "biomarkers"`;
    /// it replaces `spread_calibration`; absent in models stored before it existed).
    #[serde(default)]
    pub biomarker_calibration: Option<BiomarkerCalibration>,
    /// The mean the generator's shapes were aligned to, `[N_μ, 3]` mm (fitted with
    /// `procrustes`; absent in models stored before it: shapes enter as normalised).
    #[serde(default)]
    pub procrustes_mean: Option<Vec<[f64; 3]>>,
    /// The non-rigid refinement every normalised shape gets (fitted with `nonrigid`; absent
    /// in models stored before it: shapes as the attention gives them).
    #[serde(default)]
    pub nonrigid: Option<NonRigidParams>,
    /// The networks once built (boxed: they are large and most copies of a model never
    /// build them).
    #[serde(skip)]
    networks: OnceLock<Box<Networks>>,
}

/// A network error as a model error.
pub(crate) fn nn_error(e: NnError) -> ModelError {
    match e {
        NnError::Cancelled => ModelError::Cancelled(crate::models::progress::Cancelled),
        NnError::Diverged { .. } => ModelError::Numerical(e.to_string()),
        NnError::Weights(_) => ModelError::Corrupt(e.to_string()),
        other => ModelError::InvalidInput(other.to_string()),
    }
}

/// Flattened `[x0, y0, z0, x1, …]` in `f32`.
pub fn flatten_f32(shape: &[[f64; 3]]) -> Vec<f32> {
    shape.iter().flat_map(|p| p.map(|c| c as f32)).collect()
}

/// Ψ's embeddings of one (aligned) mesh.
pub fn embed_mesh(
    graph: &TrainedGraphVae,
    mesh: &Mesh,
    params: &AsmgParams,
) -> Result<Embeddings, ModelError> {
    let sample = GraphSample::from_mesh(mesh, params.features.features());
    let z = graph.embed(&sample).map_err(nn_error)?;
    Embeddings::new(mesh.vertex_count(), graph.config.d_z, z)
}

/// Ψ's embeddings of many graphs, `chunk` graphs per forward pass.
pub fn embeddings_of(
    graph: &TrainedGraphVae,
    samples: &[GraphSample],
    chunk: usize,
) -> Result<Vec<Embeddings>, ModelError> {
    let mut out = Vec::with_capacity(samples.len());
    for part in samples.chunks(chunk.max(1)) {
        let blocks = graph.embed_many(part).map_err(nn_error)?;
        for (sample, z) in part.iter().zip(blocks) {
            out.push(Embeddings::new(sample.vertex_count(), graph.config.d_z, z)?);
        }
    }
    Ok(out)
}

impl AsmgModel {
    /// A model from its parts; `networks`, when given, are the trained networks the weights
    /// came from (saves rebuilding them).
    pub fn new(
        atlas: Mesh,
        reference: Mesh,
        params: AsmgParams,
        sizes: NetworkSizes,
        weights: (Vec<u8>, Vec<u8>),
        networks: Option<Networks>,
    ) -> Self {
        let model = Self {
            atlas,
            reference,
            alignment: params.alignment(),
            params,
            sizes,
            graph_weights: weights.0,
            generator_weights: weights.1,
            latent_prior: None,
            spread_calibration: None,
            biomarker_calibration: None,
            procrustes_mean: None,
            nonrigid: None,
            networks: OnceLock::new(),
        };
        if let Some(n) = networks {
            let _ = model.networks.set(Box::new(n));
        }
        model
    }

    /// The networks, rebuilt from the stored weights on first use.
    pub fn networks(&self) -> Result<&Networks, ModelError> {
        if let Some(n) = self.networks.get() {
            return Ok(n.as_ref());
        }
        let graph = TrainedGraphVae::from_bytes(&self.sizes.graph(), &self.graph_weights)
            .map_err(nn_error)?;
        let generator = TrainedBetaVae::from_bytes(&self.sizes.vae(), &self.generator_weights)
            .map_err(nn_error)?;
        let built = Self::derive(graph, generator, &self.atlas, &self.params)?;
        // Another thread may have won the race; either value is the same.
        let _ = self.networks.set(Box::new(built));
        self.networks
            .get()
            .map(Box::as_ref)
            .ok_or_else(|| ModelError::Numerical("the networks could not be kept".to_owned()))
    }

    /// The networks with the atlas embeddings and the smoother of `atlas`.
    pub fn derive(
        graph: TrainedGraphVae,
        generator: TrainedBetaVae,
        atlas: &Mesh,
        params: &AsmgParams,
    ) -> Result<Networks, ModelError> {
        let atlas_embeddings = embed_mesh(&graph, atlas, params)?;
        let smoother = Smoother::new(atlas, params.smoothing())?;
        Ok(Networks {
            graph,
            generator,
            atlas_embeddings,
            smoother,
        })
    }

    /// The smoothed normalised shape `h'` (`[N_μ, 3]`, mm) of a mesh already in the model
    /// frame and within the vertex budget.
    pub fn normalise_aligned(&self, aligned: &Mesh) -> Result<Vec<[f64; 3]>, ModelError> {
        let nets = self.networks()?;
        let embeddings = embed_mesh(&nets.graph, aligned, &self.params)?;
        let input = ShapeInput {
            embeddings: &embeddings,
            positions: &aligned.vertices,
        };
        let mut out = normalise_shapes(
            &self.atlas,
            &nets.atlas_embeddings,
            &[input],
            self.params.temperature(),
            &nets.smoother,
        )?;
        let smoothed = out
            .smoothed
            .pop()
            .ok_or_else(|| ModelError::Numerical("no normalised shape".to_owned()))?;
        match &self.nonrigid {
            Some(params) => refine_normalised(&smoothed, &aligned.vertices, params),
            None => Ok(smoothed),
        }
    }

    /// A mesh with the atlas connectivity from flattened coordinates (mm).
    pub(super) fn to_mesh(&self, flat: &[f32]) -> Mesh {
        let vertices = flat
            .chunks_exact(3)
            .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            .collect();
        Mesh::new(vertices, self.atlas.faces.clone())
    }

    /// A latent code `[L]` drawn as cohorts draw them: clipped standard coordinates mapped
    /// through the latent prior.
    pub(crate) fn draw_code(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Vec<f32> {
        let standard: Vec<f32> = (0..self.sizes.vae_latent)
            .map(|_| latent_coordinate(rng, sampling))
            .collect();
        self.code_of(standard)
    }

    /// The latent code of a standard-normal vector `ε` (`[L]`): through the latent
    /// Gaussian fitted to the training codes, or `ε` itself for models without one.
    pub(super) fn code_of(&self, standard: Vec<f32>) -> Vec<f32> {
        match &self.latent_prior {
            Some(prior) if prior.centre.len() == standard.len() => prior.code(&standard),
            _ => standard,
        }
    }

    /// Decodes latent codes `[L]` to meshes, with the spread calibration when the model
    /// has one.
    pub fn decode(&self, latents: &[Vec<f32>]) -> Result<Vec<Mesh>, ModelError> {
        let mut shapes = self.decode_uncalibrated(latents)?;
        if let Some(calibration) = &self.biomarker_calibration {
            let faces = &self.atlas.faces;
            shapes.iter_mut().for_each(|s| calibration.apply(s, faces));
        } else if let Some(calibration) = &self.spread_calibration {
            shapes.iter_mut().for_each(|s| calibration.apply(s));
        }
        Ok(shapes.iter().map(|s| self.to_mesh(s)).collect())
    }

    /// The generator's shapes (flattened, mm) of latent codes `[L]`, as decoded.
    pub(crate) fn decode_uncalibrated(
        &self,
        latents: &[Vec<f32>],
    ) -> Result<Vec<Vec<f32>>, ModelError> {
        let nets = self.networks()?;
        nets.generator.decode(latents).map_err(nn_error)
    }
}

/// One latent coordinate: standard normal clipped to ±[`LATENT_CLIP`], or uniform on it.
pub(super) fn latent_coordinate(rng: &mut ChaCha8Rng, sampling: Sampling) -> f32 {
    let v: f64 = match sampling {
        Sampling::Gaussian => rng.sample::<f64, _>(StandardNormal),
        Sampling::Uniform => rng.random_range(-LATENT_CLIP..=LATENT_CLIP),
    };
    v.clamp(-LATENT_CLIP, LATENT_CLIP) as f32
}

impl FittedModel for AsmgModel {
    fn encode(&self) -> Result<Vec<u8>, ModelError> {
        encode_named(self)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

impl ShapeModel for AsmgModel {
    fn atlases(&self) -> &[Mesh] {
        std::slice::from_ref(&self.atlas)
    }

    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Draw, ModelError> {
        let mesh = self
            .decode(&[self.draw_code(rng, sampling)])?
            .pop()
            .ok_or_else(|| ModelError::Numerical("the generator returned nothing".to_owned()))?;
        Ok(Draw { mesh, cluster: 0 })
    }

    fn regenerated_training(
        &self,
        normalised: &[Vec<Vec<[f64; 3]>>],
    ) -> Result<Option<Vec<Vec<Vec<[f64; 3]>>>>, ModelError> {
        let shapes = normalised.first().map(Vec::as_slice).unwrap_or_default();
        Ok(Some(vec![self.regenerate_all(shapes)?]))
    }

    fn standard_latent(&self) -> Option<StandardLatent> {
        Some(StandardLatent {
            priors: vec![1.0],
            dimensions: vec![self.sizes.vae_latent],
            principal_modes: false,
        })
    }

    fn decode_standard(
        &self,
        cluster: usize,
        standard: &[Vec<f64>],
    ) -> Result<Vec<Mesh>, ModelError> {
        check_cluster(cluster, 1)?;
        let codes: Vec<Vec<f32>> = standard
            .iter()
            .map(|e| self.code_of(e.iter().map(|v| *v as f32).collect()))
            .collect();
        self.decode(&codes)
    }

    fn reconstruct(
        &self,
        mesh: &Mesh,
        laterality: Option<Laterality>,
    ) -> Result<Reconstruction, ModelError> {
        let (aligned, aligned_input) = align(
            &self.reference,
            mesh,
            laterality,
            &self.alignment,
            self.params.max_vertices,
            &[&self.atlas.vertices],
        )?;
        let normalised = self.normalise_aligned(&aligned)?;
        let mesh = self.regenerate(&normalised)?;
        Ok(Reconstruction {
            mesh,
            atlas: 0,
            normalised,
            aligned_input,
        })
    }
}
