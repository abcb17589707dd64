//! Model evaluation (SPEC §3): generalisation and matching on held-out meshes, specificity
//! of generated samples against the training meshes. Distances are vertex-to-vertex, mm.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::progress::{Progress, Stages};
use super::{ModelError, ShapeModel};
use crate::eval::metrics::{self, DistanceSummary, IndexedShapes};
use crate::geometry::distance::SurfaceDistances;
use crate::geometry::pca::Sampling;
use crate::mesh::Mesh;

/// Added to the fit seed for the specificity samples, so they differ from cohort draws.
const SPECIFICITY_SEED_OFFSET: u64 = 0x5bec_1f1c;

/// How distances between shapes are measured.
pub const VERTEX_TO_VERTEX: &str = "vertex-to-vertex";

/// Quality of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Evaluation {
    /// How distances are measured.
    pub distance: String,
    /// Reconstruction of each held-out mesh against the original (none without holdout).
    pub generalisation: Option<DistanceSummary>,
    /// Each generated sample against its closest training mesh.
    pub specificity: DistanceSummary,
    /// Each held-out mesh against its normalised shape (none without holdout).
    pub matching: Option<DistanceSummary>,
    /// Samples generated for specificity.
    pub specificity_samples: usize,
    /// Per-item distances behind the summaries.
    pub per_item: PerItemDistances,
}

/// Per-item distances, in input order.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PerItemDistances {
    /// One per held-out mesh.
    pub generalisation: Vec<SurfaceDistances>,
    /// One per sample.
    pub specificity: Vec<SurfaceDistances>,
    /// One per held-out mesh.
    pub matching: Vec<SurfaceDistances>,
}

/// Evaluates `model`: reconstructs every held-out mesh, and draws `samples` shapes
/// (seeded) to compare with the training shapes aligned into the model frame.
pub fn evaluate(
    model: &dyn ShapeModel,
    aligned_training: &[Vec<[f64; 3]>],
    holdout: &[Mesh],
    samples: usize,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Evaluation, ModelError> {
    let total = (holdout.len() + samples) as u64;
    let mut reconstructions = Vec::with_capacity(holdout.len());
    let (mut originals, mut normalised) = (Vec::new(), Vec::new());
    for (i, mesh) in holdout.iter().enumerate() {
        let r = model.reconstruct(mesh)?;
        reconstructions.push(r.mesh.vertices);
        originals.push(r.aligned_input);
        normalised.push(r.normalised);
        let message = format!("reconstructed held-out mesh {} of {}", i + 1, holdout.len());
        stages.report(progress, i as u64 + 1, total, message, None)?;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(SPECIFICITY_SEED_OFFSET));
    let mut generated = Vec::with_capacity(samples);
    for _ in 0..samples {
        generated.push(model.sample(&mut rng, Sampling::Gaussian)?.vertices);
    }
    let training = IndexedShapes::new(aligned_training)?;
    let specificity = metrics::specificity_indexed(&generated, &training)?;
    let message = format!("compared {samples} samples with the training meshes");
    stages.report(progress, total, total, message, None)?;
    let (generalisation, matching) = if holdout.is_empty() {
        (None, None)
    } else {
        (
            Some(metrics::generalisation(&reconstructions, &originals)?),
            Some(metrics::matching(&originals, &normalised)?),
        )
    };
    Ok(Evaluation {
        distance: VERTEX_TO_VERTEX.to_owned(),
        generalisation: generalisation.as_ref().map(|g| g.summary),
        specificity: specificity.summary,
        matching: matching.as_ref().map(|m| m.summary),
        specificity_samples: samples,
        per_item: PerItemDistances {
            generalisation: generalisation.map(|g| g.per_pair).unwrap_or_default(),
            specificity: specificity.per_sample,
            matching: matching.map(|m| m.per_pair).unwrap_or_default(),
        },
    })
}
