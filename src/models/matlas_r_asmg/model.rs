//! A fitted mAtlas-R-ASMG model: one ASMG part per atlas (its atlas, its generator and the
//! Gaussian of its codes; Ψ and the registration reference are shared), the priors `π_m`
//! of the clusters and the sharpness `α` that assigns a new shape to them.

use std::sync::OnceLock;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::geometry::pca::Sampling;
use crate::mesh::{Laterality, Mesh};
use crate::models::asmg::AsmgModel;
use crate::models::asmg::registration::align;
use crate::models::asmg::soft_clusters::{atlas_distance, weights_at};
use crate::models::clusters::winning_cluster;
use crate::models::stored::{FittedModel, encode_named};
use crate::models::{Draw, ModelError, Reconstruction, ShapeModel, StandardLatent, check_cluster};

/// A fitted multi-atlas model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MatlasModel {
    /// One part per atlas, in atlas order.
    pub parts: Vec<AsmgModel>,
    /// `π_m`, summing to one: the probability that a draw comes from cluster `m`.
    pub priors: Vec<f64>,
    /// `α = 1/std(d)` of the training shapes' distances (1/mm²).
    pub alpha: f64,
    #[serde(skip)]
    atlases: OnceLock<Vec<Mesh>>,
}

/// An unseen mesh as the clusters see it.
struct Placed {
    /// The input in the model frame (all vertices, mm).
    aligned_input: Vec<[f64; 3]>,
    /// Its smoothed normalised shape on every atlas.
    normalised: Vec<Vec<[f64; 3]>>,
    /// Its soft weights.
    weights: Vec<f64>,
}

impl MatlasModel {
    /// A model from its parts (at least one, sharing reference and Ψ) and priors.
    pub fn new(parts: Vec<AsmgModel>, priors: Vec<f64>, alpha: f64) -> Result<Self, ModelError> {
        if parts.is_empty() || parts.len() != priors.len() {
            return Err(ModelError::InvalidInput(format!(
                "{} atlases with {} priors",
                parts.len(),
                priors.len()
            )));
        }
        let total: f64 = priors.iter().sum();
        if priors.iter().any(|p| !(p.is_finite() && *p >= 0.0)) || total <= 0.0 {
            return Err(ModelError::InvalidInput(
                "cluster priors must be >= 0 and not all zero".to_owned(),
            ));
        }
        Ok(Self {
            priors: priors.iter().map(|p| p / total).collect(),
            parts,
            alpha,
            atlases: OnceLock::new(),
        })
    }

    /// The cluster of a uniform number `u` in [0, 1): the first `m` whose cumulative prior
    /// exceeds `u` (a cluster of prior 0 is never drawn).
    pub fn cluster_of(&self, u: f64) -> usize {
        let mut cumulative = 0.0;
        for (m, p) in self.priors.iter().enumerate() {
            cumulative += p;
            if *p > 0.0 && u < cumulative {
                return m;
            }
        }
        // Rounding left `u` past the last sum: the last cluster with a prior.
        self.priors.iter().rposition(|p| *p > 0.0).unwrap_or(0)
    }

    fn place(&self, mesh: &Mesh, laterality: Option<Laterality>) -> Result<Placed, ModelError> {
        let first = &self.parts[0];
        let atlases: Vec<&[[f64; 3]]> = self
            .parts
            .iter()
            .map(|p| p.atlas.vertices.as_slice())
            .collect();
        let (aligned, aligned_input) = align(
            &first.reference,
            mesh,
            laterality,
            &first.alignment,
            first.params.max_vertices,
            &atlases,
        )?;
        let normalised = self
            .parts
            .iter()
            .map(|part| part.normalise_aligned(&aligned))
            .collect::<Result<Vec<_>, _>>()?;
        let distances = self
            .parts
            .iter()
            .zip(&normalised)
            .map(|(part, h)| atlas_distance(h, &part.atlas.vertices))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Placed {
            aligned_input,
            normalised,
            weights: weights_at(&distances, self.alpha)?,
        })
    }

    /// The soft weights of an unseen mesh (as for the training shapes, eq. 5.13).
    pub fn cluster_weights(
        &self,
        mesh: &Mesh,
        laterality: Option<Laterality>,
    ) -> Result<Vec<f64>, ModelError> {
        Ok(self.place(mesh, laterality)?.weights)
    }
}

impl FittedModel for MatlasModel {
    fn encode(&self) -> Result<Vec<u8>, ModelError> {
        encode_named(self)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

impl ShapeModel for MatlasModel {
    fn atlases(&self) -> &[Mesh] {
        self.atlases
            .get_or_init(|| self.parts.iter().map(|p| p.atlas.clone()).collect())
    }

    /// Ancestral sampling: a cluster by the priors, then a draw of its generator.
    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Draw, ModelError> {
        // One cluster draws as its part alone (M = 1 is `atlas-r-asmg`, draw for draw).
        let cluster = if self.parts.len() > 1 {
            self.cluster_of(rng.random::<f64>())
        } else {
            0
        };
        let draw = self.parts[cluster].sample(rng, sampling)?;
        Ok(Draw {
            mesh: draw.mesh,
            cluster,
        })
    }

    /// Shapes normalised to atlas `m` through generator `m`.
    fn regenerated_training(
        &self,
        normalised: &[Vec<Vec<[f64; 3]>>],
    ) -> Result<Option<Vec<Vec<Vec<[f64; 3]>>>>, ModelError> {
        self.parts
            .iter()
            .zip(normalised)
            .map(|(part, shapes)| part.regenerate_all(shapes))
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    fn standard_latent(&self) -> Option<StandardLatent> {
        let parts: Vec<StandardLatent> = self
            .parts
            .iter()
            .map(ShapeModel::standard_latent)
            .collect::<Option<_>>()?;
        Some(StandardLatent {
            priors: self.priors.clone(),
            dimensions: parts.iter().flat_map(|p| p.dimensions.clone()).collect(),
            principal_modes: false,
        })
    }

    fn decode_standard(
        &self,
        cluster: usize,
        standard: &[Vec<f64>],
    ) -> Result<Vec<Mesh>, ModelError> {
        check_cluster(cluster, self.parts.len())?;
        self.parts[cluster].decode_standard(0, standard)
    }

    /// Through the generator of the cluster of largest weight.
    fn reconstruct(
        &self,
        mesh: &Mesh,
        laterality: Option<Laterality>,
    ) -> Result<Reconstruction, ModelError> {
        let placed = self.place(mesh, laterality)?;
        let atlas = winning_cluster(&placed.weights);
        let normalised = placed.normalised.into_iter().nth(atlas).unwrap_or_default();
        Ok(Reconstruction {
            mesh: self.parts[atlas].regenerate(&normalised)?,
            atlas,
            normalised,
            aligned_input: placed.aligned_input,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn priors_only(priors: Vec<f64>) -> MatlasModel {
        MatlasModel {
            parts: Vec::new(),
            priors,
            alpha: 1.0,
            atlases: OnceLock::new(),
        }
    }

    #[test]
    fn a_cluster_of_prior_one_is_the_only_one_drawn() {
        let model = priors_only(vec![1.0, 0.0, 0.0]);
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(4);
        for _ in 0..1000 {
            assert_eq!(model.cluster_of(rng.random::<f64>()), 0);
        }
        let model = priors_only(vec![0.0, 0.0, 1.0]);
        assert_eq!(model.cluster_of(0.0), 2);
        assert_eq!(model.cluster_of(1.0), 2);
    }

    #[test]
    fn clusters_are_drawn_in_proportion_to_their_priors() {
        let model = priors_only(vec![0.5, 0.3, 0.2]);
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(9);
        let mut counts = [0usize; 3];
        for _ in 0..10_000 {
            counts[model.cluster_of(rng.random::<f64>())] += 1;
        }
        for (c, p) in counts.iter().zip([0.5, 0.3, 0.2]) {
            let share = *c as f64 / 10_000.0;
            assert!((share - p).abs() < 0.02, "{counts:?}");
        }
    }
}
