//! The refinement stage: Ψ trained further on `L_Ψ + L_Ref` (thesis eq. 5.6 without the
//! generator's term), the atlas rebuilt after every epoch with eq. 5.12 (the same damped
//! closed form as ASMG's), and the training shapes normalised on the final atlas.

use super::objective::{RefineAtlas, Refinement, Target};
use super::params::AtlasRAsmgParams;
use crate::mesh::Mesh;
use crate::models::asmg::fit::Aligned;
use crate::models::asmg::model::nn_error;
use crate::models::asmg::multi_atlas::{AtlasSet, Memberships};
use crate::models::progress::{Progress, Stages};
use crate::models::{LossCurve, ModelError};
use crate::nn::{
    Flow, GraphRefiner, GraphSample, Monitor, RefineEpoch, RefineTraining, TrainedGraphVae,
};

/// What the refinement leaves for the generators.
pub(crate) struct Refined {
    /// Ψ after refinement.
    pub(crate) graph: TrainedGraphVae,
    /// The atlases after the last update (mm, model frame).
    pub(crate) atlases: Vec<Mesh>,
    /// The training shapes on those atlases and their soft weights.
    pub(crate) memberships: Memberships,
    /// Loss curves: the total and each term per epoch.
    pub(crate) losses: Vec<LossCurve>,
}

/// Cancellation between batches, through the fit's progress.
struct BatchCheck<'a> {
    stages: &'a Stages,
    progress: &'a mut dyn Progress,
    epoch: u64,
    epochs: u64,
    /// The previous epoch's losses, repeated while this one runs.
    last: Option<RefineEpoch>,
}

/// `L_Ψ …, Chamfer …, Laplacian …` of an epoch.
fn terms(e: &RefineEpoch) -> String {
    format!(
        "L_Ψ {:.4}, Chamfer {:.4}, Laplacian {:.4}",
        e.graph, e.chamfer, e.laplacian
    )
}

impl Monitor for BatchCheck<'_> {
    fn batch(&mut self) -> Flow {
        let mut message = format!("refinement epoch {} of {}", self.epoch + 1, self.epochs);
        if let Some(last) = &self.last {
            message.push_str(&format!(" (epoch {}: {})", self.epoch, terms(last)));
        }
        let loss = self.last.map(|l| l.total());
        match self
            .stages
            .report(self.progress, self.epoch, self.epochs, message, loss)
        {
            Ok(()) => Flow::Continue,
            Err(_) => Flow::Cancel,
        }
    }

    fn epoch(&mut self, _epoch: usize, _epochs: usize, _mean_loss: f64) -> Flow {
        Flow::Continue
    }
}

fn curves(epochs: &[RefineEpoch]) -> Vec<LossCurve> {
    let curve = |network: &str, f: fn(&RefineEpoch) -> f64| LossCurve {
        network: network.to_owned(),
        per_epoch: epochs.iter().map(f).collect(),
    };
    vec![
        curve("refinement", RefineEpoch::total),
        curve("refinement_graph_vae", |e| e.graph),
        curve("refinement_chamfer", |e| e.chamfer),
        curve("refinement_laplacian", |e| e.laplacian),
    ]
}

/// Refines Ψ and the atlases for `epochs_refine` epochs from `graph` and `atlases`; each
/// shape's terms on atlas `m` count by its soft weight `w_km` (all 1 with one atlas), and the
/// weights are recomputed with every atlas update. `weights[k][m]` are the soft weights
/// of the training shapes on the starting atlases.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine(
    graph: TrainedGraphVae,
    atlases: Vec<Mesh>,
    weights: Vec<Vec<f64>>,
    aligned: &Aligned,
    params: &AtlasRAsmgParams,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Refined, ModelError> {
    let asmg = &params.asmg;
    let r = &params.refinement;
    let samples: Vec<GraphSample> = aligned.samples(asmg);
    let targets = aligned
        .meshes
        .iter()
        .map(|m| Target::new(m.vertices.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut set = AtlasSet::new(atlases, asmg)?;
    let training = RefineTraining {
        batch_size: asmg.batch_size,
        lr: asmg.lr,
        w_kl: asmg.w_kl,
        w_norm: asmg.w_norm,
        seed,
    };
    let mut refiner = GraphRefiner::new(&graph, training).map_err(nn_error)?;
    let mut weights = weights;
    let mut embeddings = Vec::new();
    let epochs = r.epochs_refine as u64;
    let mut done = Vec::with_capacity(r.epochs_refine);
    for epoch in 0..epochs {
        let atlas_samples: Vec<GraphSample> = set
            .atlases
            .iter()
            .map(|a| GraphSample::from_mesh(a, asmg.features.features()))
            .collect();
        let mut objective = Refinement {
            atlases: set
                .atlases
                .iter()
                .zip(&set.smoothers)
                .map(|(a, smoother)| RefineAtlas {
                    smoother,
                    positions: &a.vertices,
                })
                .collect(),
            targets: &targets,
            temperature: asmg.temperature(),
            w_cd: r.w_cd,
            w_lap: r.w_lap,
        };
        let mut check = BatchCheck {
            stages,
            progress: &mut *progress,
            epoch,
            epochs,
            last: done.last().copied(),
        };
        let Some(losses) = refiner
            .epoch(
                &samples,
                &atlas_samples,
                &weights,
                &mut objective,
                &mut check,
            )
            .map_err(nn_error)?
        else {
            break;
        };
        // One damped update of every atlas per epoch (eq. 5.12; 5.14–5.15 with several).
        // The next epoch weighs the shapes as the refined Ψ places them on these atlases
        // (before their move: one damped step stale).
        let current = refiner.trained();
        embeddings = aligned.embeddings(&current, asmg)?;
        let memberships = set
            .memberships(&current, &aligned.inputs(&embeddings), asmg)?
            .0;
        let moved = set.update(&memberships, asmg)?;
        weights = memberships.weights;
        done.push(losses);
        let message = format!(
            "refinement epoch {} of {epochs}: {}; atlas moved {moved:.3} mm",
            epoch + 1,
            terms(&losses),
        );
        stages.report(progress, epoch + 1, epochs, message, Some(losses.total()))?;
    }
    let graph = refiner.trained();
    if embeddings.is_empty() || done.len() < r.epochs_refine {
        // Finished early: Ψ moved since the last embeddings were taken.
        embeddings = aligned.embeddings(&graph, asmg)?;
    }
    // The final shapes and weights, on the final atlases.
    let memberships = set
        .memberships(&graph, &aligned.inputs(&embeddings), asmg)?
        .0;
    Ok(Refined {
        graph,
        atlases: set.atlases,
        memberships,
        losses: curves(&done),
    })
}

#[cfg(test)]
#[path = "refine_tests.rs"]
mod tests;
