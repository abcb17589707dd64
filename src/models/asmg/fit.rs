//! Fitting ASMG (thesis ch. 4; SPEC §2.4–2.6): simplify and pre-align the training meshes,
//! train the graph VAE Ψ on them, learn the atlas and the correspondences (Algorithm 1),
//! train the beta-VAE generator on the smoothed normalised shapes, and evaluate.

use super::init::{AtlasInit, initial_atlas};
use super::learn::{LearnedAtlas, ShapeInput, learn_atlas};
use super::model::{
    AsmgModel, NetworkSizes, align, embed_mesh, embeddings_of, flatten_f32, nn_error, simplified,
};
use super::monitor::StageMonitor;
use super::params::{AsmgParams, AtlasChoice};
use crate::eval::privacy::DEFAULT_PERCENTILE;
use crate::mesh::Mesh;
use crate::models::alignment::median_resolution_index;
use crate::models::evaluation::evaluate;
use crate::models::progress::{Progress, Stages};
use crate::models::workers::map_items;
use crate::models::{
    AnyModel, AtlasInfo, FitOutcome, LossCurve, ModelError, ModelSummary, ReferencePopulation,
    StageTiming, StoredModel, TrainingShapes,
};
use crate::nn::{
    BetaVaeConfig, BetaVaeTraining, GraphSample, GraphVaeConfig, GraphVaeTraining, TrainedGraphVae,
    train_beta_vae, train_graph_vae,
};

/// Fewest training meshes an ASMG fit accepts.
pub const MIN_TRAINING_MESHES: usize = 3;
/// Meshes embedded per forward pass of Ψ after training.
const EMBED_CHUNK: usize = 8;
/// Stages of a fit and their rough share of the time.
const STAGES: [(&str, f64); 5] = [
    ("alignment", 15.0),
    ("graph_vae", 45.0),
    ("atlas", 10.0),
    ("generator", 20.0),
    ("evaluation", 10.0),
];

/// The training meshes simplified and registered to the reference.
struct Aligned {
    /// The reference (simplified, mm): the model frame.
    reference: Mesh,
    /// Each training mesh simplified and in the model frame.
    meshes: Vec<Mesh>,
    /// All original vertices of each training mesh in the model frame.
    vertices: Vec<Vec<[f64; 3]>>,
}

fn align_training(
    training: &[Mesh],
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
        |mesh| align(&reference, mesh, &alignment, params.max_vertices),
        |done| {
            let message = format!("registered training mesh {done} of {total}");
            Ok(stages.report(progress, done as u64, total, message, None)?)
        },
    )?;
    let (meshes, vertices) = registered.into_iter().unzip();
    Ok(Aligned {
        reference,
        meshes,
        vertices,
    })
}

/// Ψ for the fit's feature set and the default sizes of thesis table 4.3.
fn graph_config(params: &AsmgParams) -> GraphVaeConfig {
    GraphVaeConfig::new().with_d_x(params.features.features().width())
}

fn train_graph(
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
fn starting_atlas(
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
            AtlasInit::Given(simplified(&nearest, params.atlas_vertices)?)
        }
    };
    initial_atlas(&choice, aligned)
}

fn learn(
    graph: &TrainedGraphVae,
    aligned: &Aligned,
    initial: Mesh,
    params: &AsmgParams,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<LearnedAtlas, ModelError> {
    let samples: Vec<GraphSample> = aligned
        .meshes
        .iter()
        .map(|m| GraphSample::from_mesh(m, params.features.features()))
        .collect();
    let embeddings = embeddings_of(graph, &samples, EMBED_CHUNK)?;
    let inputs: Vec<ShapeInput<'_>> = embeddings
        .iter()
        .zip(&aligned.meshes)
        .map(|(e, m)| ShapeInput {
            embeddings: e,
            positions: &m.vertices,
        })
        .collect();
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

/// Fits ASMG to `training` and evaluates it on `holdout`. `atlas_index` is the position in
/// `training` of the mesh given as `atlas` (if one was).
pub fn fit(
    training: &[Mesh],
    holdout: &[Mesh],
    params: &AsmgParams,
    atlas_index: Option<usize>,
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    params.check()?;
    if let (Some(id), None) = (params.atlas_mesh_id(), atlas_index) {
        return Err(ModelError::invalid(
            "atlas",
            format!("mesh {id} is not among the training meshes"),
        ));
    }
    if training.len() < MIN_TRAINING_MESHES {
        return Err(ModelError::TooFewMeshes {
            required: MIN_TRAINING_MESHES,
            found: training.len(),
        });
    }
    let mut stages = Stages::new(&STAGES);
    stages.enter("alignment");
    let reference_index = atlas_index.unwrap_or_else(|| median_resolution_index(training));
    let aligned = align_training(training, params, reference_index, &stages, progress)?;

    stages.enter("graph_vae");
    let samples: Vec<GraphSample> = aligned
        .meshes
        .iter()
        .map(|m| GraphSample::from_mesh(m, params.features.features()))
        .collect();
    let (graph, graph_losses) = train_graph(&samples, params, seed, &stages, progress)?;
    drop(samples);

    stages.enter("atlas");
    let initial = starting_atlas(params, &aligned.meshes, atlas_index)?;
    let learned = learn(&graph, &aligned, initial, params, &stages, progress)?;

    stages.enter("generator");
    let shapes: Vec<Vec<f32>> = learned.smoothed.iter().map(|h| flatten_f32(h)).collect();
    let vae_config =
        BetaVaeConfig::new(3 * learned.atlas.vertex_count()).with_latent(params.latent_dim);
    let vae_training = BetaVaeTraining {
        epochs: params.epochs_vae,
        batch_size: params.batch_size_vae,
        lr: params.lr,
        beta: params.beta,
        seed,
        ..BetaVaeTraining::default()
    };
    let mut monitor = StageMonitor::new(&stages, progress, "generator", params.epochs_vae);
    let generator =
        train_beta_vae(&shapes, &vae_config, &vae_training, &mut monitor).map_err(nn_error)?;
    let losses = vec![
        LossCurve {
            network: "graph_vae".to_owned(),
            per_epoch: graph_losses,
        },
        LossCurve {
            network: "beta_vae".to_owned(),
            per_epoch: monitor.losses,
        },
    ];
    // The members are compared with these (same atlas vertices, model frame, mm).
    let normalised = learned.smoothed.clone();

    let weights = (
        graph.to_bytes().map_err(nn_error)?,
        generator.to_bytes().map_err(nn_error)?,
    );
    let sizes = NetworkSizes::of(&graph.config, &generator.config);
    let latent_prior = generator.aggregate_prior(&shapes).map_err(nn_error)?;
    let networks = AsmgModel::derive(graph, generator, &learned.atlas, params)?;
    let mut model = AsmgModel::new(
        learned.atlas,
        aligned.reference,
        params.clone(),
        sizes,
        weights,
        Some(networks),
    );
    model.latent_prior = Some(latent_prior);

    stages.enter("evaluation");
    let training_faces: Vec<&[[u32; 3]]> = training.iter().map(|m| m.faces.as_slice()).collect();
    let evaluation = evaluate(
        &model,
        &aligned.vertices,
        &training_faces,
        holdout,
        training.len(),
        seed,
        &stages,
        progress,
    )?;
    let reference = ReferencePopulation::from_meshes(training)?;
    let training_shapes = TrainingShapes::new(&aligned.vertices, &normalised, DEFAULT_PERCENTILE)?;
    stages.close();
    let summary = ModelSummary {
        atlas: AtlasInfo {
            vertex_count: model.atlas.vertex_count(),
            face_count: model.atlas.face_count(),
        },
        evaluation,
        explained_variance: None,
        n_modes: None,
        training_count: training.len(),
        holdout_count: holdout.len(),
        timings: StageTiming::all(&stages),
        losses,
    };
    Ok(FitOutcome {
        model: StoredModel {
            model: AnyModel::Asmg(model),
            training: training_shapes,
        },
        summary,
        reference,
    })
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
