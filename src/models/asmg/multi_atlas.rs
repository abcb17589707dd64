//! Several atlases learnt together (thesis §5.4): every shape normalised to every atlas,
//! its soft weights from how far each normalised shape lies from its atlas (eq. 5.13), and
//! each atlas moved by the update weighted by them (eqs. 5.14–5.15). With one atlas every
//! weight is 1 and a step is ASMG's damped atlas update.

use super::atlas::AtlasUpdateParams;
use super::laplacian::mean_distance;
use super::learn::{ShapeInput, normalise_shapes};
use super::model::embed_mesh;
use super::params::AsmgParams;
use super::smoothing::Smoother;
use super::soft_clusters::{atlas_distance, sharpness, weighted_atlas_update, weights_at};
use crate::mesh::Mesh;
use crate::models::ModelError;
use crate::nn::TrainedGraphVae;

/// A cluster whose weights sum to less than this keeps its atlas in a step.
const MIN_CLUSTER_WEIGHT: f64 = 1e-9;

/// The atlases (fixed connectivity each, mm, model frame) and their smoothers.
pub struct AtlasSet {
    /// The atlases, in order.
    pub atlases: Vec<Mesh>,
    /// Smoothing on each atlas's connectivity.
    pub smoothers: Vec<Smoother>,
}

/// The training shapes on every atlas and their soft memberships.
#[derive(Debug, Clone, PartialEq)]
pub struct Memberships {
    /// `smoothed[m][k]`: shape `k`'s smoothed normalised shape on atlas `m`, `[N_μm, 3]` mm.
    pub smoothed: Vec<Vec<Vec<[f64; 3]>>>,
    /// `d[k][m]`, mm².
    pub distances: Vec<Vec<f64>>,
    /// `w[k][m]`, each row summing to one.
    pub weights: Vec<Vec<f64>>,
    /// `α = 1/std(d)`, 1/mm².
    pub alpha: f64,
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClusterStep {
    /// Mean movement of the atlas vertices over every atlas, mm.
    pub movement_mm: f64,
    /// Mean over atlases of the largest attention weight.
    pub mean_match_weight: f64,
}

impl AtlasSet {
    /// The set of `atlases` with the fit's smoothing.
    pub fn new(atlases: Vec<Mesh>, params: &AsmgParams) -> Result<Self, ModelError> {
        if atlases.is_empty() {
            return Err(ModelError::invalid(
                "atlases",
                "must name at least one atlas",
            ));
        }
        let smoothers = atlases
            .iter()
            .map(|a| Smoother::new(a, params.smoothing()))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { atlases, smoothers })
    }

    /// Shapes normalised to every atlas with Ψ = `graph`, their distances and weights;
    /// the mean largest attention weight beside.
    pub fn memberships(
        &self,
        graph: &TrainedGraphVae,
        inputs: &[ShapeInput<'_>],
        params: &AsmgParams,
    ) -> Result<(Memberships, f64), ModelError> {
        let mut smoothed = Vec::with_capacity(self.atlases.len());
        let mut match_weight = 0.0;
        for (atlas, smoother) in self.atlases.iter().zip(&self.smoothers) {
            let z = embed_mesh(graph, atlas, params)?;
            let n = normalise_shapes(atlas, &z, inputs, params.temperature(), smoother)?;
            match_weight += n.mean_match_weight / self.atlases.len() as f64;
            smoothed.push(n.smoothed);
        }
        let distances = (0..inputs.len())
            .map(|k| {
                self.atlases
                    .iter()
                    .zip(&smoothed)
                    .map(|(a, s)| atlas_distance(&s[k], &a.vertices))
                    .collect::<Result<Vec<f64>, _>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        let alpha = sharpness(&distances)?;
        let weights = distances
            .iter()
            .map(|row| weights_at(row, alpha))
            .collect::<Result<Vec<_>, _>>()?;
        let memberships = Memberships {
            smoothed,
            distances,
            weights,
            alpha,
        };
        Ok((memberships, match_weight))
    }

    /// One damped step: memberships on the current atlases, then each atlas updated from
    /// its weighted shapes (an atlas of no weight stays).
    pub fn step(
        &mut self,
        graph: &TrainedGraphVae,
        inputs: &[ShapeInput<'_>],
        params: &AsmgParams,
    ) -> Result<ClusterStep, ModelError> {
        let (members, mean_match_weight) = self.memberships(graph, inputs, params)?;
        Ok(ClusterStep {
            movement_mm: self.update(&members, params)?,
            mean_match_weight,
        })
    }

    /// Moves each atlas by the damped update from its shapes in `members` (taken on these
    /// atlases) weighted by their weights; an atlas of no weight stays. Returns the mean
    /// movement over atlases, mm.
    pub fn update(
        &mut self,
        members: &Memberships,
        params: &AsmgParams,
    ) -> Result<f64, ModelError> {
        let update: AtlasUpdateParams = params.atlas_loop().atlas_update;
        let mut movement = 0.0;
        for (m, atlas) in self.atlases.iter_mut().enumerate() {
            let w: Vec<f64> = members.weights.iter().map(|row| row[m]).collect();
            if w.iter().sum::<f64>() < MIN_CLUSTER_WEIGHT {
                continue;
            }
            let moved = weighted_atlas_update(atlas, &members.smoothed[m], &w, &update)?;
            movement += mean_distance(&atlas.vertices, &moved.vertices);
            *atlas = moved;
        }
        Ok(movement / self.atlases.len() as f64)
    }
}

/// Algorithm 1 for several atlases: steps until the atlases move less than the tolerance
/// on average or `max_em_steps`; `on_step` sees each step (and may stop the loop).
pub fn learn_atlases(
    graph: &TrainedGraphVae,
    inputs: &[ShapeInput<'_>],
    set: &mut AtlasSet,
    params: &AsmgParams,
    mut on_step: impl FnMut(usize, &ClusterStep) -> Result<(), ModelError>,
) -> Result<Vec<ClusterStep>, ModelError> {
    let mut steps = Vec::new();
    for step in 1..=params.max_em_steps.max(1) {
        let record = set.step(graph, inputs, params)?;
        steps.push(record);
        on_step(step, &record)?;
        if record.movement_mm < params.tolerance {
            break;
        }
    }
    Ok(steps)
}
