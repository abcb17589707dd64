//! A generator (beta-VAE) on the normalised shapes of one atlas, its KL weight chosen on
//! held-out folds when the shapes are few, and the model of that atlas built around it.

use super::beta_selection::{SelectionData, choose_beta, epochs_with_choice};
use super::model::{AsmgModel, NetworkSizes, nn_error};
use super::monitor::StageMonitor;
use super::params::AsmgParams;
use crate::mesh::Mesh;
use crate::models::beta_choice::BetaChoice;
use crate::models::progress::{Progress, Stages};
use crate::models::{LossCurve, ModelError};
use crate::nn::{BetaVaeConfig, BetaVaeTraining, TrainedGraphVae, train_weighted_beta_vae};

/// One generator's training data: shapes on one atlas and, for a soft cluster, a weight
/// per shape.
pub(crate) struct GeneratorData<'a> {
    /// Ψ (shared by every atlas).
    pub(crate) graph: &'a TrainedGraphVae,
    /// The atlas (mm, model frame).
    pub(crate) atlas: Mesh,
    /// The mesh inputs are registered to.
    pub(crate) reference: &'a Mesh,
    /// The smoothed normalised shapes on `atlas`, `[N_μ, 3]` mm each.
    pub(crate) shapes: &'a [Vec<[f64; 3]>],
    /// Weight per shape (`None`: all equal).
    pub(crate) weights: Option<&'a [f32]>,
    /// (volume ml, area cm²) of each shape's training mesh (simplified), in `shapes`' order:
    /// the spread the calibration gives the draws.
    pub(crate) measured: &'a [[f64; 2]],
    /// `(m, M)` for the generator of cluster `m` of `M`; `None` for a model of one atlas.
    pub(crate) cluster: Option<(usize, usize)>,
}

/// A generator's model, its loss curve (`beta_vae`, or `beta_vae_{m}` for cluster `m`) and
/// how its KL weight was chosen (`None`: as given).
pub(crate) struct TrainedGenerator {
    pub(crate) model: AsmgModel,
    pub(crate) curve: LossCurve,
    pub(crate) beta_choice: Option<BetaChoice>,
}

/// Trains a generator (beta-VAE) on one atlas's shapes and builds the model of that atlas.
pub(crate) fn train_generator(
    data: GeneratorData<'_>,
    params: &AsmgParams,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<TrainedGenerator, ModelError> {
    let (curve_name, stage_name) = match data.cluster {
        None => ("beta_vae".to_owned(), "generator".to_owned()),
        Some((m, count)) => (
            format!("beta_vae_{m}"),
            format!("generator {} of {count}", m + 1),
        ),
    };
    let super::pose::GeneratorShapes {
        flat: shapes,
        procrustes_mean,
    } = super::pose::generator_shapes(data.shapes, params.procrustes)?;
    let atlas = data.atlas;
    let vae_config = BetaVaeConfig::new(3 * atlas.vertex_count()).with_latent(params.latent_dim);
    let mut vae_training = BetaVaeTraining {
        epochs: params.epochs_vae,
        batch_size: params.batch_size_vae,
        lr: params.lr,
        beta: params.beta,
        seed,
        ..BetaVaeTraining::default()
    };
    let beta_choice = if params.choose_beta {
        let selection = SelectionData {
            shapes: &shapes,
            weights: data.weights,
            cluster: data.cluster.map(|(m, _)| m),
            measured: data.measured,
            faces: &atlas.faces,
            calibration: params.calibrate_spread.then_some(params.calibration),
        };
        choose_beta(&selection, &vae_config, &vae_training, stages, progress)?
    } else {
        None
    };
    if let Some(choice) = &beta_choice {
        vae_training.beta = choice.chosen;
    }
    let epochs = params.epochs_vae;
    let span = if beta_choice.is_some() {
        let all = epochs_with_choice(epochs);
        (all - epochs, all)
    } else {
        (0, epochs)
    };
    let mut monitor = StageMonitor::spanning(stages, progress, &stage_name, epochs, span);
    let generator = train_weighted_beta_vae(
        &shapes,
        data.weights,
        &vae_config,
        &vae_training,
        &mut monitor,
    )
    .map_err(nn_error)?;
    let curve = LossCurve {
        network: curve_name,
        per_epoch: monitor.losses,
    };
    let weights = (
        data.graph.to_bytes().map_err(nn_error)?,
        generator.to_bytes().map_err(nn_error)?,
    );
    let sizes = NetworkSizes::of(&data.graph.config, &generator.config);
    let latent_prior = generator
        .weighted_aggregate_prior(&shapes, data.weights)
        .map_err(nn_error)?;
    let networks = AsmgModel::derive(data.graph.clone(), generator, &atlas, params)?;
    let mut model = AsmgModel::new(
        atlas,
        data.reference.clone(),
        params.clone(),
        sizes,
        weights,
        Some(networks),
    );
    model.latent_prior = Some(latent_prior);
    model.procrustes_mean = procrustes_mean;
    model.nonrigid = params.nonrigid_refinement();
    if params.calibrate_spread {
        model.calibrate_spread(&shapes, data.weights, data.measured, seed)?;
    }
    Ok(TrainedGenerator {
        model,
        curve,
        beta_choice,
    })
}
