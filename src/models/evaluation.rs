//! Model evaluation (SPEC §3): generalisation and matching on held-out meshes, specificity
//! of generated samples against the training meshes. Distances are vertex-to-vertex, mm.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::progress::{Progress, Stages};
use super::{ModelError, ShapeModel};
use crate::eval::metrics::{self, DistanceSummary, IndexedShapes};
use crate::eval::surface_metrics::{Surface, paired_point_to_surface, point_to_surface_to_nearest};
use crate::geometry::distance::SurfaceDistances;
use crate::geometry::pca::Sampling;
use crate::mesh::{Laterality, Mesh};

/// Added to the fit seed for the specificity samples, so they differ from cohort draws.
const SPECIFICITY_SEED_OFFSET: u64 = 0x5bec_1f1c;

/// How distances between shapes are measured.
pub const VERTEX_TO_VERTEX: &str = "vertex-to-vertex";

/// Quality of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// The same metrics with point-to-surface distances (vertices to the closest point on
    /// the other shape's triangles); specificity pairs as above.
    #[serde(default)]
    pub point_to_surface: Option<SurfaceEvaluation>,
}

/// Metrics with point-to-surface distances, mm.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SurfaceEvaluation {
    /// Reconstruction of each held-out mesh against the original.
    pub generalisation: Option<DistanceSummary>,
    /// Each generated sample against the training mesh closest by vertex ED.
    pub specificity: DistanceSummary,
    /// Each held-out mesh against its normalised shape.
    pub matching: Option<DistanceSummary>,
}

/// Per-item distances, in input order.
#[derive(Debug, Clone, Default, Serialize, Deserialize, utoipa::ToSchema)]
pub struct PerItemDistances {
    /// One per held-out mesh.
    pub generalisation: Vec<SurfaceDistances>,
    /// One per sample.
    pub specificity: Vec<SurfaceDistances>,
    /// One per held-out mesh.
    pub matching: Vec<SurfaceDistances>,
}

/// Evaluates `model`: reconstructs every held-out mesh, and draws `samples` shapes
/// (seeded) to compare with the training shapes aligned into the model frame
/// (`aligned_training[k]` has the faces of `training_faces[k]`).
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    model: &dyn ShapeModel,
    aligned_training: &[Vec<[f64; 3]>],
    training_faces: &[&[[u32; 3]]],
    holdout: &[Mesh],
    holdout_laterality: &[Option<Laterality>],
    samples: usize,
    seed: u64,
    stages: &Stages,
    progress: &mut dyn Progress,
) -> Result<Evaluation, ModelError> {
    let total = (holdout.len() + samples) as u64;
    let mut reconstructions: Vec<Mesh> = Vec::with_capacity(holdout.len());
    let (mut originals, mut normalised, mut atlas_of) = (Vec::new(), Vec::new(), Vec::new());
    for (i, mesh) in holdout.iter().enumerate() {
        let r = model.reconstruct(mesh, holdout_laterality.get(i).copied().flatten())?;
        reconstructions.push(r.mesh);
        atlas_of.push(r.atlas);
        originals.push(r.aligned_input);
        normalised.push(r.normalised);
        let message = format!("reconstructed held-out mesh {} of {}", i + 1, holdout.len());
        stages.report(progress, i as u64 + 1, total, message, None)?;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(SPECIFICITY_SEED_OFFSET));
    let mut generated = Vec::with_capacity(samples);
    for _ in 0..samples {
        generated.push(model.sample(&mut rng, Sampling::Gaussian)?.mesh);
    }
    let training = IndexedShapes::new(aligned_training)?;
    let generated_vertices: Vec<&[[f64; 3]]> =
        generated.iter().map(|m| m.vertices.as_slice()).collect();
    let specificity = metrics::specificity_indexed(&generated_vertices, &training)?;
    let message = format!("compared {samples} samples with the training meshes");
    stages.report(progress, total, total, message, None)?;
    let (generalisation, matching) = if holdout.is_empty() {
        (None, None)
    } else {
        (
            Some(metrics::generalisation(
                &reconstructions
                    .iter()
                    .map(|m| m.vertices.as_slice())
                    .collect::<Vec<_>>(),
                &originals,
            )?),
            Some(metrics::matching(&originals, &normalised)?),
        )
    };
    let atlases = model.atlases();
    let normalised_faces = atlas_of
        .iter()
        .map(|&m| {
            atlases.get(m).map(|a| a.faces.as_slice()).ok_or_else(|| {
                ModelError::InvalidInput(format!("a reconstruction names atlas {m}"))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let surfaces = SurfaceInputs {
        normalised_faces: &normalised_faces,
        reconstructions: &reconstructions,
        originals: &originals,
        normalised: &normalised,
        holdout,
        generated: &generated,
        training: aligned_training,
        training_faces,
        closest_training: &specificity.closest_training,
    };
    let point_to_surface = Some(surfaces.evaluate()?);
    Ok(Evaluation {
        distance: VERTEX_TO_VERTEX.to_owned(),
        point_to_surface,
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

/// What the point-to-surface metrics compare; `reconstructions`, `originals`, `normalised`
/// and `holdout` run in parallel, as do `generated` and `closest_training`.
struct SurfaceInputs<'a> {
    normalised_faces: &'a [&'a [[u32; 3]]],
    reconstructions: &'a [Mesh],
    originals: &'a [Vec<[f64; 3]>],
    normalised: &'a [Vec<[f64; 3]>],
    holdout: &'a [Mesh],
    generated: &'a [Mesh],
    training: &'a [Vec<[f64; 3]>],
    training_faces: &'a [&'a [[u32; 3]]],
    closest_training: &'a [usize],
}

impl SurfaceInputs<'_> {
    fn evaluate(&self) -> Result<SurfaceEvaluation, ModelError> {
        fn of_mesh(m: &Mesh) -> Surface<'_> {
            Surface {
                vertices: m.vertices.as_slice(),
                faces: m.faces.as_slice(),
            }
        }
        let originals: Vec<Surface<'_>> = self
            .originals
            .iter()
            .zip(self.holdout)
            .map(|(v, m)| Surface {
                vertices: v,
                faces: &m.faces,
            })
            .collect();
        let training: Vec<Surface<'_>> = self
            .training
            .iter()
            .zip(self.training_faces)
            .map(|(vertices, faces)| Surface { vertices, faces })
            .collect();
        let samples: Vec<Surface<'_>> = self.generated.iter().map(of_mesh).collect();
        let specificity =
            point_to_surface_to_nearest(&samples, &training, self.closest_training)?.summary;
        if self.holdout.is_empty() {
            return Ok(SurfaceEvaluation {
                generalisation: None,
                specificity,
                matching: None,
            });
        }
        let reconstructions: Vec<Surface<'_>> = self.reconstructions.iter().map(of_mesh).collect();
        let normalised: Vec<Surface<'_>> = self
            .normalised
            .iter()
            .zip(self.normalised_faces)
            .map(|(v, faces)| Surface { vertices: v, faces })
            .collect();
        Ok(SurfaceEvaluation {
            generalisation: Some(paired_point_to_surface(&reconstructions, &originals)?.summary),
            specificity,
            matching: Some(paired_point_to_surface(&originals, &normalised)?.summary),
        })
    }
}
