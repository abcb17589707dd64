//! Running one fit job: load its meshes, split them, fit, and describe the model to store.

use tokio::runtime::Handle;

use super::cohort::{DrawnCohort, run_cohort_job};
use super::fit::fit_model;
use super::split::holdout_split;
use crate::mesh::{Laterality, Mesh};
use crate::models::progress::Progress;
use crate::models::{FitInput, FitOutcome, ModelError, ModelType};
use crate::store::jobs::{Job, JobKind};
use crate::store::models::{NewModel, Provenance};
use crate::store::{Store, StoreError};

/// Why a job did not produce a model.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The fit failed or was cancelled.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The job's data could not be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The job record is unusable (e.g. a model type this version does not know).
    #[error("{0}")]
    Invalid(String),
    /// A cohort member drawn again from its model is not the shape first drawn.
    #[error(
        "member of draw {draw} no longer comes out of its model as it was first drawn (this \
         release computes it differently); ask for the cohort again with the same request"
    )]
    NotReproducible {
        /// The member's draw number.
        draw: u64,
    },
}

struct Split {
    training: Vec<Mesh>,
    holdout: Vec<Mesh>,
    provenance: Provenance,
    template_indices: Vec<usize>,
}

fn load_split(
    handle: &Handle,
    store: &Store,
    job: &Job,
    templates: &[&str],
) -> Result<Split, RunError> {
    let meshes = handle.block_on(store.dataset_mesh_keys(&job.dataset_id))?;
    let ids: Vec<String> = meshes.iter().map(|m| m.id.clone()).collect();
    let (training_ids, holdout_ids) =
        holdout_split(&ids, job.holdout_fraction, job.seed, templates);
    let key = |wanted: &String| meshes.iter().find(|m| &m.id == wanted);
    let sha = |wanted: &[String]| -> Vec<String> {
        wanted
            .iter()
            .filter_map(|w| key(w).map(|m| m.sha256.clone()))
            .collect()
    };
    let sides = |wanted: &[String]| -> Vec<Option<Laterality>> {
        wanted
            .iter()
            .map(|w| key(w).and_then(|m| m.laterality))
            .collect()
    };
    let load = |wanted: &[String]| -> Result<Vec<Mesh>, StoreError> {
        wanted
            .iter()
            .map(|id| handle.block_on(store.mesh_geometry(id)))
            .collect()
    };
    let template_indices = templates
        .iter()
        .map(|t| {
            training_ids.iter().position(|id| id == t).ok_or_else(|| {
                RunError::Invalid(format!(
                    "template mesh {t} is no longer in dataset {}",
                    job.dataset_id
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Split {
        training: load(&training_ids)?,
        holdout: load(&holdout_ids)?,
        provenance: Provenance {
            training_sha256: sha(&training_ids),
            holdout_sha256: sha(&holdout_ids),
            training_laterality: sides(&training_ids),
            holdout_laterality: sides(&holdout_ids),
            training_mesh_ids: training_ids,
            holdout_mesh_ids: holdout_ids,
        },
        template_indices,
    })
}

/// What a job produced, to be stored with its completion.
#[derive(Debug)]
pub enum JobOutput {
    /// A fitted model.
    Model(Box<NewModel>),
    /// A drawn cohort.
    Cohort(DrawnCohort),
}

/// Runs `job` (a fit or a cohort); blocking, to be called on a worker thread.
pub fn run_job(
    handle: &Handle,
    store: &Store,
    job: &Job,
    progress: &mut dyn Progress,
) -> Result<JobOutput, RunError> {
    match job.kind {
        JobKind::Fit => {
            run_fit_job(handle, store, job, progress).map(|m| JobOutput::Model(Box::new(m)))
        }
        JobKind::Cohort => run_cohort_job(handle, store, job, progress).map(JobOutput::Cohort),
    }
}

/// Fits the model of `job`.
fn run_fit_job(
    handle: &Handle,
    store: &Store,
    job: &Job,
    progress: &mut dyn Progress,
) -> Result<NewModel, RunError> {
    let model_type = ModelType::from_name(&job.model_type)
        .ok_or_else(|| RunError::Invalid(format!("unknown model type {}", job.model_type)))?;
    let params = model_type.parse_params(&job.params)?;
    let split = load_split(handle, store, job, &params.template_mesh_ids())?;
    let input = FitInput {
        training: &split.training,
        holdout: &split.holdout,
        training_laterality: &split.provenance.training_laterality,
        holdout_laterality: &split.provenance.holdout_laterality,
        template_indices: &split.template_indices,
        seed: job.seed,
    };
    let outcome: FitOutcome = fit_model(&params, &input, progress)?;
    crate::telemetry::record_fit_stages(
        &job.model_type,
        outcome
            .summary
            .timings
            .iter()
            .map(|t| (t.stage.as_str(), t.seconds)),
    );
    let json = |v: Result<serde_json::Value, serde_json::Error>| {
        v.map_err(|e| RunError::Invalid(e.to_string()))
    };
    Ok(NewModel {
        model_type: job.model_type.clone(),
        params: params.to_json(),
        seed: job.seed,
        dataset_id: job.dataset_id.clone(),
        provenance: split.provenance,
        summary: json(serde_json::to_value(&outcome.summary))?,
        reference: json(serde_json::to_value(&outcome.reference))?,
        payload: outcome.model.to_bytes()?,
    })
}
