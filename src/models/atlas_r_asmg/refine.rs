//! The refinement stage: Ψ trained further on `L_Ψ + L_Ref` (thesis eq. 5.6 without the
//! generator's term), the atlas rebuilt after every epoch with eq. 5.12 (the same damped
//! closed form as ASMG's), and the training shapes normalised on the final atlas.

use super::objective::{Refinement, Target};
use super::params::AtlasRAsmgParams;
use crate::mesh::Mesh;
use crate::models::asmg::Embeddings;
use crate::models::asmg::fit::{Aligned, learn_from};
use crate::models::asmg::model::{embed_mesh, nn_error};
use crate::models::asmg::{Smoother, normalise_shapes};
use crate::models::progress::{Progress, Silent, Stages};
use crate::models::{LossCurve, ModelError};
use crate::nn::{
    Flow, GraphRefiner, GraphSample, Monitor, RefineEpoch, RefineTraining, TrainedGraphVae,
};

/// What the refinement leaves for the generator.
pub(crate) struct Refined {
    /// Ψ after refinement.
    pub(crate) graph: TrainedGraphVae,
    /// The atlas after the last update (mm, model frame).
    pub(crate) atlas: Mesh,
    /// The training shapes' smoothed normalised shapes on that atlas, `K` of `[N_μ, 3]` mm.
    pub(crate) smoothed: Vec<Vec<[f64; 3]>>,
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

/// The smoothed normalised shapes of every training mesh (embedded by `graph` as
/// `embeddings`) on `atlas`.
fn normalise_on(
    graph: &TrainedGraphVae,
    aligned: &Aligned,
    embeddings: &[Embeddings],
    atlas: &Mesh,
    params: &AtlasRAsmgParams,
    smoother: &Smoother,
) -> Result<Vec<Vec<[f64; 3]>>, ModelError> {
    let inputs = aligned.inputs(embeddings);
    let atlas_embeddings = embed_mesh(graph, atlas, &params.asmg)?;
    let normalised = normalise_shapes(
        atlas,
        &atlas_embeddings,
        &inputs,
        params.asmg.temperature(),
        smoother,
    )?;
    Ok(normalised.smoothed)
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

/// Refines Ψ and the atlas for `epochs_refine` epochs from `graph` and `atlas`.
pub(crate) fn refine(
    graph: TrainedGraphVae,
    mut atlas: Mesh,
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
    let smoother = Smoother::new(&atlas, asmg.smoothing())?;
    let training = RefineTraining {
        batch_size: asmg.batch_size,
        lr: asmg.lr,
        w_kl: asmg.w_kl,
        w_norm: asmg.w_norm,
        seed,
    };
    let mut refiner = GraphRefiner::new(&graph, training).map_err(nn_error)?;
    // One damped atlas step per epoch (eq. 5.12).
    let mut one_step = asmg.clone();
    one_step.max_em_steps = 1;
    let epochs = r.epochs_refine as u64;
    let mut done = Vec::with_capacity(r.epochs_refine);
    let mut embeddings: Vec<Embeddings> = Vec::new();
    for epoch in 0..epochs {
        let atlas_sample = GraphSample::from_mesh(&atlas, asmg.features.features());
        let mut objective = Refinement {
            smoother: &smoother,
            adjacency: smoother.adjacency(),
            atlas: &atlas.vertices,
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
            .epoch(&samples, &atlas_sample, &mut objective, &mut check)
            .map_err(nn_error)?
        else {
            // Ψ moved since the last embeddings were taken.
            embeddings.clear();
            break;
        };
        let current = refiner.trained();
        embeddings = aligned.embeddings(&current, asmg)?;
        let learned = learn_from(
            &current,
            aligned,
            &embeddings,
            atlas,
            &one_step,
            stages,
            &mut Silent,
        )?;
        let moved = learned.steps.last().map_or(0.0, |s| s.movement_mm);
        atlas = learned.atlas;
        done.push(losses);
        let message = format!(
            "refinement epoch {} of {epochs}: {}; atlas moved {moved:.3} mm",
            epoch + 1,
            terms(&losses)
        );
        stages.report(progress, epoch + 1, epochs, message, Some(losses.total()))?;
    }
    let graph = refiner.trained();
    // The last finished epoch's embeddings are the refined Ψ's.
    if embeddings.is_empty() {
        embeddings = aligned.embeddings(&graph, asmg)?;
    }
    let smoothed = normalise_on(&graph, aligned, &embeddings, &atlas, params, &smoother)?;
    Ok(Refined {
        graph,
        atlas,
        smoothed,
        losses: curves(&done),
    })
}

#[cfg(test)]
#[path = "refine_tests.rs"]
mod tests;
