//! Fitting ASMG (thesis ch. 4; SPEC §2.4–2.6): simplify and pre-align the training meshes,
//! train the graph VAE Ψ on them, learn the atlas and the correspondences (Algorithm 1),
//! train the beta-VAE generator on the smoothed normalised shapes. The steps are shared
//! with `atlas-r-asmg`, which refines Ψ and the atlas between the atlas and the generator.

use super::biomarker_calibration::mesh_biomarkers;
use super::embeddings::Embeddings;
pub(crate) use super::generator::{GeneratorData, train_generator};
use super::init::{AtlasInit, initial_atlas};
use super::learn::{LearnedAtlas, ShapeInput, learn_atlas};
use super::model::{AsmgModel, embed_mesh, embeddings_of, nn_error};
use super::monitor::StageMonitor;
use super::params::{AsmgParams, AtlasChoice};
use super::registration::{align_sides, side_candidates};
use crate::mesh::{Laterality, Mesh};
use crate::models::alignment::{median_resolution_index, simplified};
use crate::models::progress::{Progress, Stages};
use crate::models::sides::{SideChoice, choose_sides};
use crate::models::workers::map_items;
use crate::models::{FitInput, FittedParts, LossCurve, ModelError};
use crate::nn::{GraphSample, GraphVaeConfig, GraphVaeTraining, TrainedGraphVae, train_graph_vae};

/// Fewest training meshes an ASMG fit accepts.
pub const MIN_TRAINING_MESHES: usize = 3;
/// Meshes embedded per forward pass of Ψ after training.
pub(crate) const EMBED_CHUNK: usize = 8;
/// Stages of a fit and their rough share of the time.
pub(crate) const STAGES: [(&str, f64); 5] = [
    ("alignment", 15.0),
    ("graph_vae", 45.0),
    ("atlas", 10.0),
    ("generator", 20.0),
    ("evaluation", 10.0),
];

/// The training meshes simplified and registered to the reference.
pub(crate) struct Aligned {
    /// The reference (simplified, mm): the model frame.
    pub(crate) reference: Mesh,
    /// Each training mesh simplified and in the model frame.
    pub(crate) meshes: Vec<Mesh>,
    /// All original vertices of each training mesh in the model frame.
    pub(crate) vertices: Vec<Vec<[f64; 3]>>,
    /// Which training meshes were registered as their mirror images.
    pub(crate) mirrored: Vec<bool>,
    /// The side of the reference, which every shape takes, when the user gave sides.
    pub(crate) laterality: Option<Laterality>,
}

impl Aligned {
    /// Positions of the meshes registered as their mirror images.
    pub(crate) fn mirrored_positions(&self) -> Vec<usize> {
        (0..self.mirrored.len())
            .filter(|k| self.mirrored[*k])
            .collect()
    }

    /// The graphs of the simplified meshes, with the fit's features.
    pub(crate) fn samples(&self, params: &AsmgParams) -> Vec<GraphSample> {
        self.meshes
            .iter()
            .map(|m| GraphSample::from_mesh(m, params.features.features()))
            .collect()
    }

    /// Ψ's embeddings of every simplified mesh, `[N_k, d_z]` each.
    pub(crate) fn embeddings(
        &self,
        graph: &TrainedGraphVae,
        params: &AsmgParams,
    ) -> Result<Vec<Embeddings>, ModelError> {
        embeddings_of(graph, &self.samples(params), EMBED_CHUNK)
    }

    /// The shapes as the atlas loop sees them: embeddings beside positions.
    pub(crate) fn inputs<'a>(&'a self, embeddings: &'a [Embeddings]) -> Vec<ShapeInput<'a>> {
        embeddings
            .iter()
            .zip(&self.meshes)
            .map(|(e, m)| ShapeInput {
                embeddings: e,
                positions: &m.vertices,
            })
            .collect()
    }
}

pub(crate) fn align_training(
    training: &[Mesh],
    given: &[Option<Laterality>],
    params: &AsmgParams,
    reference_index: usize,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Aligned, ModelError> {
    let reference = training
        .get(reference_index)
        .ok_or_else(|| ModelError::invalid("atlas", "is not a training mesh"))
        .and_then(|m| simplified(m, params.max_vertices))?;
    let alignment = params.alignment();
    let total = training.len() as u64;
    let registered = map_items(
        training,
        |mesh| align_sides(&reference, mesh, &alignment, params.max_vertices),
        |done| {
            let message = format!("registered training mesh {done} of {total}");
            Ok(stages.report(progress, done as u64, total, message, None)?)
        },
    )?;
    let candidates: Option<Vec<_>> = registered.iter().map(|s| side_candidates(s)).collect();
    let choice = match candidates {
        Some(c) => choose_sides(&c, reference_index, given)?,
        None => SideChoice {
            mirrored: vec![false; registered.len()],
            laterality: None,
        },
    };
    let mirrored = choice.mirrored;
    let (mut meshes, mut vertices) = (Vec::new(), Vec::new());
    for (mut sides, take_mirrored) in registered.into_iter().zip(&mirrored) {
        let chosen = sides.swap_remove(usize::from(*take_mirrored));
        meshes.push(chosen.mesh);
        vertices.push(chosen.vertices);
    }
    Ok(Aligned {
        reference,
        meshes,
        vertices,
        mirrored,
        laterality: choice.laterality,
    })
}

/// Ψ for the fit's feature set and the default sizes of thesis table 4.3.
fn graph_config(params: &AsmgParams) -> GraphVaeConfig {
    GraphVaeConfig::new().with_d_x(params.features.features().width())
}

pub(crate) fn train_graph(
    samples: &[GraphSample],
    params: &AsmgParams,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<(TrainedGraphVae, Vec<f64>), ModelError> {
    let training = GraphVaeTraining {
        epochs: params.epochs_graph,
        batch_size: params.batch_size,
        lr: params.lr,
        w_kl: params.w_kl,
        w_norm: params.w_norm,
        seed,
    };
    let mut monitor = StageMonitor::new(stages, progress, "graph VAE", params.epochs_graph);
    let trained = train_graph_vae(samples, &graph_config(params), &training, &mut monitor)
        .map_err(nn_error)?;
    Ok((trained, monitor.losses))
}

/// The initial atlas for the parameters (`given`: the user's atlas mesh among the aligned
/// training meshes).
pub(crate) fn starting_atlas(
    params: &AsmgParams,
    aligned: &[Mesh],
    given: Option<usize>,
) -> Result<Mesh, ModelError> {
    let choice = match (params.atlas_choice(), given) {
        (AtlasChoice::Icosphere, _) => AtlasInit::Icosphere {
            target_vertices: params.atlas_vertices,
        },
        (AtlasChoice::Mesh(_), Some(i)) => AtlasInit::Given(
            aligned
                .get(i)
                .cloned()
                .ok_or_else(|| ModelError::invalid("atlas", "is not a training mesh"))?,
        ),
        (AtlasChoice::Mesh(id), None) => {
            return Err(ModelError::invalid(
                "atlas",
                format!("mesh {id} is not among the training meshes"),
            ));
        }
        (AtlasChoice::Auto, _) => {
            let nearest = initial_atlas(
                &AtlasInit::Auto {
                    target_vertices: params.atlas_vertices,
                },
                aligned,
            )?;
            return simplified_atlas(&nearest, params);
        }
    };
    initial_atlas(&choice, aligned)
}

/// A training mesh simplified to `atlas_vertices`, checked as an initial atlas.
pub(crate) fn simplified_atlas(mesh: &Mesh, params: &AsmgParams) -> Result<Mesh, ModelError> {
    let atlas = simplified(mesh, params.atlas_vertices)?;
    initial_atlas(&AtlasInit::Given(atlas), std::slice::from_ref(mesh))
}

pub(crate) fn learn(
    graph: &TrainedGraphVae,
    aligned: &Aligned,
    initial: Mesh,
    params: &AsmgParams,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<LearnedAtlas, ModelError> {
    let embeddings = aligned.embeddings(graph, params)?;
    learn_from(
        graph,
        aligned,
        &embeddings,
        initial,
        params,
        stages,
        progress,
    )
}

/// [`learn`] with the training meshes' embeddings by `graph` already computed.
pub(crate) fn learn_from(
    graph: &TrainedGraphVae,
    aligned: &Aligned,
    embeddings: &[Embeddings],
    initial: Mesh,
    params: &AsmgParams,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<LearnedAtlas, ModelError> {
    let inputs = aligned.inputs(embeddings);
    let total = params.max_em_steps as u64;
    learn_atlas(
        initial,
        &inputs,
        &params.atlas_loop(),
        |atlas| embed_mesh(graph, atlas, params),
        |step| {
            let message = format!(
                "atlas step {}: moved {:.3} mm (largest {:.3} mm), mean match weight {:.3}",
                step.step, step.movement_mm, step.max_movement_mm, step.mean_match_weight
            );
            stages.report(progress, step.step as u64, total, message, None)?;
            Ok(())
        },
    )
}

/// Checks that a mesh named as atlas is among the training meshes.
pub(crate) fn check_atlas_choice(
    params: &AsmgParams,
    input: &FitInput<'_>,
) -> Result<(), ModelError> {
    if let (Some(id), None) = (params.atlas_mesh_id(), input.template_index()) {
        return Err(ModelError::invalid(
            "atlas",
            format!("mesh {id} is not among the training meshes"),
        ));
    }
    Ok(())
}

/// Pre-aligns the training meshes to the atlas mesh or the median-resolution one.
pub(crate) fn align_input(
    params: &AsmgParams,
    input: &FitInput<'_>,
    stages: &mut Stages,
    progress: &mut dyn Progress,
) -> Result<Aligned, ModelError> {
    check_atlas_choice(params, input)?;
    stages.enter("alignment");
    let reference_index = input
        .template_index()
        .unwrap_or_else(|| median_resolution_index(input.training));
    align_training(
        input.training,
        input.training_laterality,
        params,
        reference_index,
        stages,
        progress,
    )
}

/// What the generator is trained on: Ψ, the learned atlas and the training shapes on it.
pub(crate) struct Correspondences {
    /// The trained (and possibly refined) Ψ.
    pub(crate) graph: TrainedGraphVae,
    /// The learned atlas (mm, model frame).
    pub(crate) atlas: Mesh,
    /// The training shapes' smoothed normalised shapes on it, `K` of `[N_μ, 3]` mm.
    pub(crate) smoothed: Vec<Vec<[f64; 3]>>,
    /// The pre-aligned training meshes.
    pub(crate) aligned: Aligned,
    /// Loss curves so far (Ψ, refinement).
    pub(crate) losses: Vec<LossCurve>,
}

/// Trains the generator on the smoothed normalised shapes and builds the model.
pub(crate) fn train_generator_and_build(
    learned: Correspondences,
    params: &AsmgParams,
    seed: u64,
    stages: &mut Stages,
    progress: &mut dyn Progress,
) -> Result<FittedParts<AsmgModel>, ModelError> {
    let Correspondences {
        graph,
        atlas,
        smoothed,
        aligned,
        mut losses,
    } = learned;
    stages.enter("generator");
    let measured: Vec<[f64; 2]> = aligned.meshes.iter().map(mesh_biomarkers).collect();
    let data = GeneratorData {
        graph: &graph,
        atlas,
        reference: &aligned.reference,
        shapes: &smoothed,
        weights: None,
        measured: &measured,
        cluster: None,
    };
    let mut trained = train_generator(data, params, seed, stages, progress)?;
    trained.model.alignment.laterality = aligned.laterality;
    losses.push(trained.curve);
    Ok(FittedParts {
        model: trained.model,
        mirrored_training: aligned.mirrored_positions(),
        laterality: aligned.laterality,
        aligned_training: aligned.vertices,
        // The members are compared with these (same atlas vertices, model frame, mm).
        normalised: vec![smoothed],
        explained_variance: None,
        n_modes: None,
        losses,
        clusters: None,
        beta_choices: trained.beta_choice.into_iter().collect(),
    })
}

/// The normalised shapes deformed onto their meshes when `nonrigid` is on (else as given).
pub(crate) fn refined(
    params: &AsmgParams,
    shapes: Vec<Vec<[f64; 3]>>,
    aligned: &Aligned,
) -> Result<Vec<Vec<[f64; 3]>>, ModelError> {
    let Some(refinement) = params.nonrigid_refinement() else {
        return Ok(shapes);
    };
    let meshes: Vec<&[[f64; 3]]> = aligned
        .meshes
        .iter()
        .map(|m| m.vertices.as_slice())
        .collect();
    super::nonrigid::refine_all(&shapes, &meshes, &refinement)
}

/// Fits ASMG up to its evaluation.
pub(crate) fn fit(
    params: &AsmgParams,
    input: &FitInput<'_>,
    stages: &mut Stages,
    progress: &mut dyn Progress,
) -> Result<FittedParts<AsmgModel>, ModelError> {
    let aligned = align_input(params, input, stages, progress)?;

    stages.enter("graph_vae");
    let samples = aligned.samples(params);
    let (graph, graph_losses) = train_graph(&samples, params, input.seed, stages, progress)?;
    drop(samples);

    stages.enter("atlas");
    let initial = starting_atlas(params, &aligned.meshes, input.template_index())?;
    let learned = learn(&graph, &aligned, initial, params, stages, progress)?;
    let losses = vec![LossCurve {
        network: "graph_vae".to_owned(),
        per_epoch: graph_losses,
    }];
    let smoothed = refined(params, learned.smoothed, &aligned)?;
    let learned = Correspondences {
        graph,
        atlas: learned.atlas,
        smoothed,
        aligned,
        losses,
    };
    train_generator_and_build(learned, params, input.seed, stages, progress)
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
