//! mAtlas-R-ASMG (thesis §5.4, eqs. 5.13–5.17; SPEC §2.8): several atlases, each with its
//! own connectivity and topology, soft clusters of the training shapes around them, and a
//! generator per cluster. Built from the steps of `atlas-r-asmg`:
//!
//! 1. pre-alignment and Ψ as in ASMG, one Ψ for every atlas;
//! 2. the initial atlases: the meshes named in `atlases`, or the medoids of a k-medoids
//!    clustering of the pre-aligned meshes (`"auto"`: three, fewer below 30 meshes, so that
//!    each generator has about ten meshes to learn from; [`medoids`]; our choice, the thesis
//!    starts from expert shapes), each simplified to `atlas_vertices`. With one atlas the
//!    initial atlas is chosen as `atlas-r-asmg` chooses it, so that M = 1 is `atlas-r-asmg`;
//! 3. Algorithm 1 for several atlases: every shape normalised to every atlas (`h^m_k`),
//!    `d_km = mean_j‖h'^m_kj − x_μm,j‖²`, `w_km = softmax_m(−α·d_km)` with `α = 1/std(d)`,
//!    and every atlas moved by the update weighted by its `w_km` with its own `γ_m`;
//! 4. refinement as in `atlas-r-asmg`, each shape's terms on atlas `m` weighted by `w_km`
//!    (every atlas rides in every batch, pairs of weight below 10⁻³ are skipped; the weights
//!    are recomputed after each epoch, with the atlas update). The thesis does not say how
//!    refinement works with several atlases; this is what we chose;
//! 5. a beta-VAE per atlas, sized for that atlas, its loss and standardisation weighted by
//!    `w_km` over the shapes of weight ≥ [`MIN_GENERATOR_WEIGHT`] (no hidden layers
//!    shared), with the Gaussian of its weighted codes;
//! 6. priors `π_m = mean_k w_km` (the thesis leaves them open); ancestral sampling draws a
//!    cluster by `π`, then a shape from its generator (atlas `m`'s connectivity). An unseen
//!    mesh is normalised to every atlas, weighted with the training `α` and reconstructed by
//!    the generator of its largest weight.

mod medoids;
pub mod model;
pub mod params;

pub use model::MatlasModel;
pub use params::{AtlasesChoice, CheckedMatlasParams, MatlasParams};

use crate::mesh::Mesh;
use crate::models::asmg::biomarker_calibration::mesh_biomarkers;
use crate::models::asmg::fit::{
    Aligned, GeneratorData, align_input, learn, simplified_atlas, starting_atlas, train_generator,
    train_graph,
};
use crate::models::asmg::multi_atlas::{AtlasSet, Memberships, learn_atlases};
use crate::models::asmg::{self, AsmgParams, initial_atlas};
use crate::models::atlas_r_asmg::refine_atlases;
use crate::models::beta_choice::BetaChoice;
use crate::models::progress::{Progress, Stages};
use crate::models::{ClusterSummary, FitInput, FittedParts, LossCurve, ModelError, ModelFamily};

/// Shapes of smaller weight do not enter a cluster's generator.
pub const MIN_GENERATOR_WEIGHT: f64 = 0.01;
/// Mixed into the seed of generator `m > 0`.
const GENERATOR_SEED_SALT: u64 = 0x6e4e_c1a5;

/// Stages of a fit and their rough share of the time.
const STAGES: [(&str, f64); 6] = [
    ("alignment", 10.0),
    ("graph_vae", 25.0),
    ("atlas", 10.0),
    ("refinement", 35.0),
    ("generator", 12.0),
    ("evaluation", 8.0),
];

/// The `matlas-r-asmg` model type.
pub struct MatlasRAsmg;

impl ModelFamily for MatlasRAsmg {
    const NAME: &'static str = "matlas-r-asmg";
    const MIN_TRAINING_MESHES: usize = asmg::fit::MIN_TRAINING_MESHES;
    const TEMPLATE_FIELD: &'static str = "atlases";
    const STAGES: &'static [(&'static str, f64)] = &STAGES;
    type Params = MatlasParams;
    type Checked = CheckedMatlasParams;
    type Model = MatlasModel;

    fn parse(params: &serde_json::Value) -> Result<MatlasParams, ModelError> {
        MatlasParams::from_json(params)
    }

    fn check(params: MatlasParams) -> Result<CheckedMatlasParams, ModelError> {
        params.check()
    }

    fn params(checked: &CheckedMatlasParams) -> &MatlasParams {
        checked.get()
    }

    fn template_mesh_ids(checked: &CheckedMatlasParams) -> Vec<&str> {
        checked.get().mesh_ids()
    }

    fn label_params(label: &str) -> Option<serde_json::Value> {
        MatlasParams::from_label(label)
    }

    fn fit(
        params: &CheckedMatlasParams,
        input: &FitInput<'_>,
        stages: &mut Stages,
        progress: &mut dyn Progress,
    ) -> Result<FittedParts<MatlasModel>, ModelError> {
        fit(params.get(), input, stages, progress)
    }
}

/// The initial atlases (mm, model frame).
fn initial_atlases(
    params: &MatlasParams,
    aligned: &Aligned,
    input: &FitInput<'_>,
) -> Result<Vec<Mesh>, ModelError> {
    let asmg = &params.refined.asmg;
    let ids = match &params.atlases {
        AtlasesChoice::Meshes(ids) => ids,
        counted => {
            return counted_atlases(counted.count(aligned.meshes.len()), asmg, aligned, input);
        }
    };
    if input.template_indices.len() != ids.len() {
        return Err(ModelError::invalid(
            "atlases",
            "every mesh named in atlases must be a training mesh",
        ));
    }
    input
        .template_indices
        .iter()
        .map(|&i| {
            let mesh = aligned.meshes.get(i).cloned().ok_or_else(|| {
                ModelError::invalid("atlases", "names a mesh that is not a training mesh")
            })?;
            initial_atlas(&asmg::AtlasInit::Given(mesh), &aligned.meshes)
        })
        .collect()
}

/// `m` initial atlases: ASMG's starting atlas for one, else the medoids of the meshes.
fn counted_atlases(
    m: usize,
    asmg: &AsmgParams,
    aligned: &Aligned,
    input: &FitInput<'_>,
) -> Result<Vec<Mesh>, ModelError> {
    if m == 1 {
        return Ok(vec![starting_atlas(
            asmg,
            &aligned.meshes,
            input.template_index(),
        )?]);
    }
    if m > aligned.meshes.len() {
        return Err(ModelError::invalid(
            "atlases",
            format!(
                "{m} atlases need at least {m} training meshes, got {}",
                aligned.meshes.len()
            ),
        ));
    }
    let d = medoids::distance_matrix(&aligned.meshes)?;
    let (chosen, _) = medoids::k_medoids(&d, m)?;
    chosen
        .iter()
        .map(|&i| simplified_atlas(&aligned.meshes[i], asmg))
        .collect()
}

/// Learns the atlases from `initial` with Ψ = `graph` (Algorithm 1; ASMG's loop for one).
fn learn_clusters(
    graph: &crate::nn::TrainedGraphVae,
    aligned: &Aligned,
    initial: Vec<Mesh>,
    asmg: &AsmgParams,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<(Vec<Mesh>, Vec<Vec<f64>>), ModelError> {
    if initial.len() == 1 {
        let atlas = initial.into_iter().next().unwrap_or_default();
        let learned = learn(graph, aligned, atlas, asmg, stages, progress)?;
        return Ok((vec![learned.atlas], vec![vec![1.0]; aligned.meshes.len()]));
    }
    let embeddings = aligned.embeddings(graph, asmg)?;
    let inputs = aligned.inputs(&embeddings);
    let mut set = AtlasSet::new(initial, asmg)?;
    let total = asmg.max_em_steps as u64;
    let count = set.atlases.len();
    learn_atlases(graph, &inputs, &mut set, asmg, |step, s| {
        let message = format!(
            "atlas step {step} ({count} atlases): moved {:.3} mm on average, mean match weight {:.3}",
            s.movement_mm, s.mean_match_weight
        );
        stages.report(progress, step as u64, total, message, None)?;
        Ok(())
    })?;
    let (memberships, _) = set.memberships(graph, &inputs, asmg)?;
    Ok((set.atlases, memberships.weights))
}

/// `π_m = mean_k w_km`.
fn priors(weights: &[Vec<f64>], count: usize) -> Vec<f64> {
    let k = weights.len().max(1) as f64;
    (0..count)
        .map(|m| weights.iter().map(|row| row[m]).sum::<f64>() / k)
        .collect()
}

/// The generators of every cluster, in cluster order.
#[derive(Default)]
struct Generators {
    models: Vec<asmg::AsmgModel>,
    curves: Vec<LossCurve>,
    beta_choices: Vec<BetaChoice>,
}

/// A generator per atlas on the shapes of that cluster, weighted.
#[allow(clippy::too_many_arguments)]
fn train_generators(
    graph: &crate::nn::TrainedGraphVae,
    aligned: &Aligned,
    atlases: Vec<Mesh>,
    memberships: &Memberships,
    params: &MatlasParams,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Generators, ModelError> {
    let count = atlases.len();
    let mut generators = Generators::default();
    for (m, atlas) in atlases.into_iter().enumerate() {
        let column: Vec<f64> = memberships.weights.iter().map(|row| row[m]).collect();
        let mut members: Vec<usize> = (0..column.len())
            .filter(|&k| column[k] >= MIN_GENERATOR_WEIGHT)
            .collect();
        if members.is_empty() {
            // A cluster nobody belongs to still gets a generator (its prior is ~0): its
            // likeliest shape.
            members.push(crate::models::clusters::winning_cluster(&column));
        }
        let shapes: Vec<Vec<[f64; 3]>> = members
            .iter()
            .map(|&k| memberships.smoothed[m][k].clone())
            .collect();
        let weights: Vec<f32> = members.iter().map(|&k| column[k] as f32).collect();
        let measured: Vec<[f64; 2]> = members
            .iter()
            .map(|&k| mesh_biomarkers(&aligned.meshes[k]))
            .collect();
        let uniform = weights.iter().all(|w| *w == 1.0);
        let data = GeneratorData {
            graph,
            atlas,
            reference: &aligned.reference,
            shapes: &shapes,
            weights: (!uniform).then_some(weights.as_slice()),
            measured: &measured,
            cluster: (count > 1).then_some((m, count)),
        };
        let part_seed = if m == 0 {
            seed
        } else {
            seed ^ GENERATOR_SEED_SALT.wrapping_mul(m as u64)
        };
        let trained = train_generator(data, &params.refined.asmg, part_seed, stages, progress)?;
        generators.models.push(trained.model);
        generators.curves.push(trained.curve);
        generators.beta_choices.extend(trained.beta_choice);
    }
    Ok(generators)
}

fn fit(
    params: &MatlasParams,
    input: &FitInput<'_>,
    stages: &mut Stages,
    progress: &mut dyn Progress,
) -> Result<FittedParts<MatlasModel>, ModelError> {
    let asmg = &params.refined.asmg;
    let aligned = align_input(asmg, input, stages, progress)?;

    stages.enter("graph_vae");
    let samples = aligned.samples(asmg);
    let (graph, graph_losses) = train_graph(&samples, asmg, input.seed, stages, progress)?;
    drop(samples);

    stages.enter("atlas");
    let initial = initial_atlases(params, &aligned, input)?;
    let (atlases, weights) = learn_clusters(&graph, &aligned, initial, asmg, stages, progress)?;

    stages.enter("refinement");
    let refined = refine_atlases(
        graph,
        atlases,
        weights,
        &aligned,
        &params.refined,
        input.seed,
        stages,
        progress,
    )?;
    let mut losses = vec![LossCurve {
        network: "graph_vae".to_owned(),
        per_epoch: graph_losses,
    }];
    losses.extend(refined.losses);

    stages.enter("generator");
    let count = refined.atlases.len();
    let mut memberships = refined.memberships;
    memberships.smoothed = memberships
        .smoothed
        .into_iter()
        .map(|shapes| asmg::fit::refined(asmg, shapes, &aligned))
        .collect::<Result<_, _>>()?;
    let generators = train_generators(
        &refined.graph,
        &aligned,
        refined.atlases,
        &memberships,
        params,
        input.seed,
        stages,
        progress,
    )?;
    losses.extend(generators.curves);
    let mut parts = generators.models;
    for part in &mut parts {
        part.alignment.laterality = aligned.laterality;
    }
    let model = MatlasModel::new(
        parts,
        priors(&memberships.weights, count),
        memberships.alpha,
    )?;
    let holdout = input
        .holdout
        .iter()
        .enumerate()
        .map(|(i, mesh)| model.cluster_weights(mesh, input.holdout_side(i)))
        .collect::<Result<Vec<_>, _>>()?;
    let clusters = ClusterSummary {
        priors: model.priors.clone(),
        training: memberships.weights,
        holdout,
    };
    Ok(FittedParts {
        model,
        mirrored_training: aligned.mirrored_positions(),
        laterality: aligned.laterality,
        aligned_training: aligned.vertices,
        // Members of cluster m are compared with every training shape on atlas m.
        normalised: memberships.smoothed,
        explained_variance: None,
        n_modes: None,
        losses,
        clusters: Some(clusters),
        beta_choices: generators.beta_choices,
    })
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
