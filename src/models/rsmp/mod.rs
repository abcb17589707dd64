//! RSMP, the baseline statistical shape model (thesis ch. 3; SPEC §2.2–2.3): every training
//! mesh is registered to a template by rigid CPD, its soft correspondences give a normalised
//! shape with the template's vertices, and PCA of the normalised shapes is the model.

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::alignment::{self, AlignmentParams, Normalisation, simplified};
use super::check_cluster;
use super::progress::{Progress, Stages};
use super::reference::SMALL_POPULATION;
use super::stored::{FittedModel, encode_named};
use super::workers::map_items;
use super::{
    Draw, FitInput, FittedParts, ModelError, ModelFamily, Reconstruction, ShapeModel,
    StandardLatent,
};
use crate::geometry::correspondence::{
    flatten, normalised_shape, refined_correspondences, unflatten,
};
use crate::geometry::cpd::{NonRigidParams, nonrigid_cpd};
use crate::geometry::gpa::generalised_procrustes;
use crate::geometry::pca::{PcaModel, PcaParams, Sampling};
use crate::geometry::procrustes::weighted_procrustes;
use crate::mesh::adjacency::Adjacency;
use crate::mesh::smooth::taubin;
use crate::mesh::{Laterality, Mesh};

mod coefficients;
mod params;

pub use coefficients::ModeCoefficients;

pub use params::{CheckedRsmpParams, DEFAULT_VARIANCE_TARGET, RsmpParams};

/// Fewest training meshes an RSMP fit accepts.
pub const MIN_TRAINING_MESHES: usize = 3;

/// A mesh's normalised shape `[n_template_vertices, 3]` and its vertices in the template
/// frame `[n_vertices, 3]` (mm).
type NormalisedInput = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// A fitted RSMP model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RsmpModel {
    /// The template mesh (mm): the model frame and the connectivity of every output.
    pub template: Mesh,
    /// Global normalisation of the PCA coordinates (undone on output).
    pub normalisation: Normalisation,
    /// PCA of the normalised shapes, `D = 3·n_template_vertices`.
    pub pca: PcaModel,
    /// Registration settings, reused to reconstruct unseen meshes.
    pub alignment: AlignmentParams,
    /// The non-rigid refinement of the correspondences (absent: rigid correspondences only,
    /// as in models stored before it existed).
    #[serde(default)]
    pub nonrigid: Option<NonRigidParams>,
    /// Taubin steps on every drawn shape (0 in models stored before they existed, which
    /// therefore draw the same shapes as before).
    #[serde(default)]
    pub draw_smoothing_steps: usize,
    /// Whether the normalised shapes were aligned to their mean before the PCA (generalised
    /// Procrustes); then a reconstructed mesh's normalised shape is aligned to the PCA mean
    /// first. Models stored before it existed were not.
    #[serde(default)]
    pub procrustes: bool,
    /// Of a mesh with more vertices, about this many are registered (models stored before
    /// the budget existed registered every vertex, and still do).
    #[serde(default = "every_vertex")]
    pub max_vertices: usize,
    /// The training shapes' coefficients, from which Gaussian-sampling draws take each mode's
    /// (absent: `N(0, λᵢ)`, as in models stored before they existed, fits with
    /// `empirical_coefficients` off and fits of fewer than 20 meshes).
    #[serde(default)]
    pub mode_coefficients: Option<ModeCoefficients>,
    /// The template's adjacency, built on the first smoothed draw.
    #[serde(skip)]
    template_adjacency: std::sync::OnceLock<Adjacency>,
}

fn every_vertex() -> usize {
    usize::MAX
}

impl RsmpModel {
    fn to_pca_space(&self, shape: &[[f64; 3]]) -> Vec<f64> {
        flatten(
            &shape
                .iter()
                .map(|p| self.normalisation.apply(*p))
                .collect::<Vec<_>>(),
        )
    }

    fn to_mesh(&self, x: &[f64]) -> Mesh {
        let vertices = unflatten(x)
            .into_iter()
            .map(|p| self.normalisation.undo(p))
            .collect();
        Mesh::new(vertices, self.template.faces.clone())
    }

    /// A drawn shape `[D]` as a mesh, smoothed by the model's Taubin steps.
    fn drawn_mesh(&self, x: &[f64]) -> Mesh {
        let mut mesh = self.to_mesh(x);
        if self.draw_smoothing_steps > 0 {
            let adjacency = self
                .template_adjacency
                .get_or_init(|| Adjacency::from_mesh(&self.template));
            mesh.vertices = taubin(&mesh.vertices, adjacency, self.draw_smoothing_steps);
        }
        mesh
    }

    /// Registers `mesh` to the template: its normalised shape and its vertices in the
    /// template frame (mm).
    ///
    /// Of a mesh above the vertex budget, every k-th vertex is registered and read for the
    /// correspondences (a sample with the mesh's own point density: simplified surfaces
    /// crowd their vertices where the curvature is high, which pulled the correspondences
    /// of LV phantoms' walls outwards, +9–12% wall volume); the returned vertices are all
    /// of the mesh's.
    fn normalise(&self, mesh: &Mesh) -> Result<NormalisedInput, ModelError> {
        // Every vertex when the mesh is within the budget.
        let points = alignment::subsample(&mesh.vertices, self.max_vertices);
        let cpd = alignment::register(&self.template.vertices, &points, &self.alignment)?;
        let aligned: Vec<[f64; 3]> = mesh
            .vertices
            .iter()
            .map(|p| cpd.transform.inverse_apply(*p))
            .collect();
        let h = match &self.nonrigid {
            Some(params) => {
                // σ² of the rigid fit is in the data frame; the template frame is 1/s smaller.
                let sigma2 = cpd.sigma2 / cpd.transform.scale.powi(2);
                // The same stride over the moved vertices gives the moved sample.
                let moved = alignment::subsample(&aligned, self.max_vertices);
                let refined = nonrigid_cpd(&self.template.vertices, &moved, params, sigma2)?;
                refined_correspondences(&refined)
            }
            None => normalised_shape(&self.template.vertices, &points, &cpd)?,
        };
        if !self.procrustes {
            return Ok((h, aligned));
        }
        let mean = unflatten(&self.pca.mean)
            .into_iter()
            .map(|p| self.normalisation.undo(p))
            .collect::<Vec<_>>();
        let pose = weighted_procrustes(&h, &mean, None, false)?;
        Ok((pose.apply_all(&h), pose.apply_all(&aligned)))
    }
}

/// Aligns every normalised shape to their common mean (generalised Procrustes), moving each
/// mesh's vertices in the template frame with it.
fn align_to_mean(
    shapes: &mut [Vec<[f64; 3]>],
    aligned: &mut [Vec<[f64; 3]>],
) -> Result<(), ModelError> {
    let gpa = generalised_procrustes(shapes)?;
    for ((h, vertices), pose) in shapes.iter_mut().zip(aligned).zip(&gpa.transforms) {
        *h = pose.apply_all(h);
        *vertices = pose.apply_all(vertices);
    }
    Ok(())
}

impl ShapeModel for RsmpModel {
    fn atlases(&self) -> &[Mesh] {
        std::slice::from_ref(&self.template)
    }

    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Draw, ModelError> {
        let x = match (&self.mode_coefficients, sampling) {
            (Some(c), Sampling::Gaussian) => self.pca.reconstruct(&c.draw(rng))?,
            _ => self.pca.sample(rng, sampling),
        };
        Ok(Draw {
            mesh: self.drawn_mesh(&x),
            cluster: 0,
        })
    }

    fn reconstruct(
        &self,
        mesh: &Mesh,
        _laterality: Option<Laterality>,
    ) -> Result<Reconstruction, ModelError> {
        let (normalised, aligned_input) = self.normalise(mesh)?;
        let b = self.pca.project(&self.to_pca_space(&normalised))?;
        let x = self.pca.reconstruct(&b)?;
        Ok(Reconstruction {
            mesh: self.to_mesh(&x),
            atlas: 0,
            normalised,
            aligned_input,
        })
    }

    /// Each normalised training shape through the PCA as a draw is made: projected on the
    /// kept modes and smoothed by the draw's Taubin steps. A member lies in the span of the
    /// modes and so, even when it copies no one, nearer a training shape than the training
    /// shapes (each with its own residual off the span) lie to each other: on 100 liver
    /// phantoms the threshold from the raw shapes flagged 8 of 25 held-out patients'
    /// reconstructions as near copies. From [`SMALL_POPULATION`] training meshes on.
    ///
    /// [`SMALL_POPULATION`]: crate::models::reference::SMALL_POPULATION
    fn regenerated_training(
        &self,
        normalised: &[Vec<Vec<[f64; 3]>>],
    ) -> Result<Option<Vec<Vec<Vec<[f64; 3]>>>>, ModelError> {
        let shapes = normalised.first().map(Vec::as_slice).unwrap_or_default();
        // Below this the leave-one-out threshold already compares like with like (the
        // quickstart's 8 meshes: 0 of 100 members flagged with it, 26 with projected shapes).
        if shapes.len() < SMALL_POPULATION {
            return Ok(None);
        }
        let regenerated = shapes
            .iter()
            .map(|shape| {
                let b = self.pca.project(&self.to_pca_space(shape))?;
                Ok(self.drawn_mesh(&self.pca.reconstruct(&b)?).vertices)
            })
            .collect::<Result<Vec<_>, ModelError>>()?;
        Ok(Some(vec![regenerated]))
    }

    /// The PCA runs on coordinates divided by `scale_mm`: λ in mm² is `λ·scale_mm²`.
    fn principal_variances_mm2(&self) -> Option<Vec<f64>> {
        let s2 = self.normalisation.scale_mm.powi(2);
        Some(self.pca.variances.iter().map(|l| l * s2).collect())
    }

    fn standard_latent(&self) -> Option<StandardLatent> {
        Some(StandardLatent {
            priors: vec![1.0],
            dimensions: vec![self.pca.n_modes()],
            principal_modes: true,
        })
    }

    /// `bᵢ = √λᵢ·εᵢ`, then the shape `mean + U·b`.
    fn decode_standard(
        &self,
        cluster: usize,
        standard: &[Vec<f64>],
    ) -> Result<Vec<Mesh>, ModelError> {
        check_cluster(cluster, 1)?;
        standard
            .iter()
            .map(|e| {
                let b: Vec<f64> = e
                    .iter()
                    .zip(&self.pca.variances)
                    .map(|(e, l)| e * l.sqrt())
                    .collect();
                Ok(self.drawn_mesh(&self.pca.reconstruct(&b)?))
            })
            .collect()
    }
}

impl FittedModel for RsmpModel {
    fn encode(&self) -> Result<Vec<u8>, ModelError> {
        encode_named(self)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// The `rsmp` model type.
pub struct Rsmp;

impl ModelFamily for Rsmp {
    const NAME: &'static str = "rsmp";
    const MIN_TRAINING_MESHES: usize = MIN_TRAINING_MESHES;
    const TEMPLATE_FIELD: &'static str = "template";
    const STAGES: &'static [(&'static str, f64)] =
        &[("alignment", 70.0), ("pca", 2.0), ("evaluation", 28.0)];
    type Params = RsmpParams;
    type Checked = CheckedRsmpParams;
    type Model = RsmpModel;

    fn check(params: RsmpParams) -> Result<CheckedRsmpParams, ModelError> {
        params.check()
    }

    fn params(checked: &CheckedRsmpParams) -> &RsmpParams {
        checked.get()
    }

    fn template_mesh_ids(checked: &CheckedRsmpParams) -> Vec<&str> {
        checked.get().template.as_deref().into_iter().collect()
    }

    fn fit(
        params: &CheckedRsmpParams,
        input: &FitInput<'_>,
        stages: &mut Stages,
        progress: &mut dyn Progress,
    ) -> Result<FittedParts<RsmpModel>, ModelError> {
        fit(params.get(), input, stages, progress)
    }
}

/// Registers the training meshes to the template and fits the PCA.
fn fit(
    params: &RsmpParams,
    input: &FitInput<'_>,
    stages: &mut Stages,
    progress: &mut dyn Progress,
) -> Result<FittedParts<RsmpModel>, ModelError> {
    let training = input.training;
    stages.enter("alignment");
    let t = input
        .template_index()
        .unwrap_or_else(|| alignment::median_resolution_index(training));
    let template = training
        .get(t)
        .ok_or_else(|| ModelError::invalid("template", "is not a training mesh"))
        .and_then(|m| simplified(m, params.max_vertices))?;
    let mut model = RsmpModel {
        template,
        normalisation: Normalisation {
            centre: [0.0; 3],
            scale_mm: 1.0,
        },
        pca: PcaModel {
            mean: vec![],
            modes: vec![],
            variances: vec![],
            cumulative_explained: vec![],
        },
        alignment: params.alignment(),
        nonrigid: params.nonrigid(),
        draw_smoothing_steps: params.draw_smoothing_steps,
        procrustes: false,
        max_vertices: params.max_vertices,
        mode_coefficients: None,
        template_adjacency: std::sync::OnceLock::new(),
    };
    let total = training.len() as u64;
    let registered = map_items(
        training,
        |mesh| model.normalise(mesh),
        |done| {
            let message = format!("registered training mesh {done} of {total}");
            Ok(stages.report(progress, done as u64, total, message, None)?)
        },
    )?;
    let (mut shapes, mut aligned): (Vec<_>, Vec<_>) = registered.into_iter().unzip();
    stages.enter("pca");
    if params.procrustes {
        align_to_mean(&mut shapes, &mut aligned)?;
        model.procrustes = true;
    }
    model.normalisation = Normalisation::fit(&aligned);
    let flattened: Vec<Vec<f64>> = shapes.iter().map(|h| model.to_pca_space(h)).collect();
    let pca_params = PcaParams {
        n_modes: params.n_modes,
        variance_target: params.variance_target,
    };
    model.pca = PcaModel::fit_with(&flattened, &pca_params)?;
    if params.empirical_coefficients && training.len() >= SMALL_POPULATION {
        model.mode_coefficients = Some(ModeCoefficients::of_shapes(&model.pca, &flattened)?);
    }
    stages.report(
        progress,
        1,
        1,
        format!("kept {} modes", model.pca.n_modes()),
        None,
    )?;
    Ok(FittedParts {
        explained_variance: Some(model.pca.cumulative_explained.clone()),
        n_modes: Some(model.pca.n_modes()),
        model,
        aligned_training: aligned,
        normalised: vec![shapes],
        losses: Vec::new(),
        clusters: None,
        beta_choices: Vec::new(),
        mirrored_training: Vec::new(),
        laterality: None,
    })
}

#[cfg(test)]
mod tests;
