//! RSMP, the baseline statistical shape model (thesis ch. 3; SPEC §2.2–2.3): every training
//! mesh is registered to a template by rigid CPD, its soft correspondences give a normalised
//! shape with the template's vertices, and PCA of the normalised shapes is the model.

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::alignment::{self, AlignmentParams, Normalisation};
use super::evaluation::evaluate;
use super::progress::{Progress, Stages};
use super::workers::map_items;
use super::{
    AnyModel, AtlasInfo, FitOutcome, ModelError, ModelSummary, Reconstruction, ReferencePopulation,
    ShapeModel, StageTiming, StoredModel, TrainingShapes,
};
use crate::eval::privacy::DEFAULT_PERCENTILE;
use crate::geometry::correspondence::{flatten, normalised_shape, unflatten};
use crate::geometry::cpd::RigidCpdParams;
use crate::geometry::pca::{PcaModel, PcaParams, Sampling};
use crate::mesh::Mesh;

/// Fewest training meshes an RSMP fit accepts.
pub const MIN_TRAINING_MESHES: usize = 3;
/// Default share of variance the kept modes explain.
pub const DEFAULT_VARIANCE_TARGET: f64 = 0.95;

/// Parameters of an RSMP fit (`params` of a job with `model_type: "rsmp"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RsmpParams {
    /// Mesh id of the template; default: the training mesh whose vertex count is closest
    /// to the median.
    pub template: Option<String>,
    /// Modes to keep (with `variance_target`, the smaller count wins).
    pub n_modes: Option<usize>,
    /// Keep the fewest modes explaining this share of variance, in (0, 1].
    pub variance_target: Option<f64>,
    /// Estimate an isotropic scale in the registration (off keeps size as a shape mode).
    pub scale: bool,
    /// Search 24 initial rotations before registering (for meshes in arbitrary poses).
    pub multistart: bool,
    /// CPD outlier weight w, in [0, 1).
    pub cpd_w: f64,
    /// Most CPD iterations.
    pub cpd_max_iterations: usize,
    /// CPD stopping tolerance (relative change).
    pub cpd_tolerance: f64,
}

impl Default for RsmpParams {
    fn default() -> Self {
        let cpd = RigidCpdParams::default();
        Self {
            template: None,
            n_modes: None,
            variance_target: Some(DEFAULT_VARIANCE_TARGET),
            scale: false,
            multistart: true,
            cpd_w: cpd.w,
            cpd_max_iterations: cpd.max_iterations,
            cpd_tolerance: cpd.tolerance,
        }
    }
}

impl RsmpParams {
    /// Checks every value; the error names the parameter.
    pub fn check(&self) -> Result<(), ModelError> {
        if self.n_modes == Some(0) {
            return Err(ModelError::invalid("n_modes", "must be at least 1"));
        }
        if let Some(t) = self.variance_target
            && !(t > 0.0 && t <= 1.0)
        {
            return Err(ModelError::invalid(
                "variance_target",
                format!("must be in (0, 1], got {t}"),
            ));
        }
        if !(0.0..1.0).contains(&self.cpd_w) {
            return Err(ModelError::invalid(
                "cpd_w",
                format!("must be in [0, 1), got {}", self.cpd_w),
            ));
        }
        if !(1..=10_000).contains(&self.cpd_max_iterations) {
            return Err(ModelError::invalid(
                "cpd_max_iterations",
                "must be between 1 and 10000",
            ));
        }
        if !(self.cpd_tolerance.is_finite() && self.cpd_tolerance > 0.0 && self.cpd_tolerance < 1.0)
        {
            return Err(ModelError::invalid("cpd_tolerance", "must be in (0, 1)"));
        }
        Ok(())
    }

    fn alignment(&self) -> AlignmentParams {
        AlignmentParams {
            cpd: RigidCpdParams {
                w: self.cpd_w,
                max_iterations: self.cpd_max_iterations,
                tolerance: self.cpd_tolerance,
                scale: self.scale,
                min_sigma2: 0.0,
            },
            multistart: self.multistart,
            ..AlignmentParams::default()
        }
    }
}

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

    /// Registers `mesh` to the template: its normalised shape and its vertices in the
    /// template frame (mm).
    fn normalise(&self, mesh: &Mesh) -> Result<NormalisedInput, ModelError> {
        let cpd = alignment::register(&self.template.vertices, &mesh.vertices, &self.alignment)?;
        let h = normalised_shape(&self.template.vertices, &mesh.vertices, &cpd)?;
        let aligned = mesh
            .vertices
            .iter()
            .map(|p| cpd.transform.inverse_apply(*p))
            .collect();
        Ok((h, aligned))
    }
}

impl ShapeModel for RsmpModel {
    fn atlas(&self) -> &Mesh {
        &self.template
    }

    fn sample(&self, rng: &mut ChaCha8Rng, sampling: Sampling) -> Result<Mesh, ModelError> {
        Ok(self.to_mesh(&self.pca.sample(rng, sampling)))
    }

    fn reconstruct(&self, mesh: &Mesh) -> Result<Reconstruction, ModelError> {
        let (normalised, aligned_input) = self.normalise(mesh)?;
        let b = self.pca.project(&self.to_pca_space(&normalised))?;
        let x = self.pca.reconstruct(&b)?;
        Ok(Reconstruction {
            mesh: self.to_mesh(&x),
            normalised,
            aligned_input,
        })
    }
}

/// Fits RSMP to `training` and evaluates it on `holdout`.
///
/// `template_index` picks the template among `training` (default: median resolution).
pub fn fit(
    training: &[Mesh],
    holdout: &[Mesh],
    params: &RsmpParams,
    template_index: Option<usize>,
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    params.check()?;
    if training.len() < MIN_TRAINING_MESHES {
        return Err(ModelError::TooFewMeshes {
            required: MIN_TRAINING_MESHES,
            found: training.len(),
        });
    }
    let mut stages = Stages::new(&[("alignment", 70.0), ("pca", 2.0), ("evaluation", 28.0)]);
    stages.enter("alignment");
    let t = template_index.unwrap_or_else(|| alignment::median_resolution_index(training));
    let template = training
        .get(t)
        .cloned()
        .ok_or_else(|| ModelError::invalid("template", "is not a training mesh"))?;
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
    let (shapes, aligned): (Vec<_>, Vec<_>) = registered.into_iter().unzip();
    stages.enter("pca");
    model.normalisation = Normalisation::fit(&aligned);
    let flattened: Vec<Vec<f64>> = shapes.iter().map(|h| model.to_pca_space(h)).collect();
    let pca_params = PcaParams {
        n_modes: params.n_modes,
        variance_target: params.variance_target,
    };
    model.pca = PcaModel::fit_with(&flattened, &pca_params)?;
    stages.report(
        progress,
        1,
        1,
        format!("kept {} modes", model.pca.n_modes()),
        None,
    )?;
    stages.enter("evaluation");
    let training_faces: Vec<&[[u32; 3]]> = training.iter().map(|m| m.faces.as_slice()).collect();
    let evaluation = evaluate(
        &model,
        &aligned,
        &training_faces,
        holdout,
        training.len(),
        seed,
        &stages,
        progress,
    )?;
    let reference = ReferencePopulation::from_meshes(training)?;
    let training_shapes = TrainingShapes::new(&aligned, &shapes, DEFAULT_PERCENTILE)?;
    stages.close();
    let summary = ModelSummary {
        atlas: AtlasInfo {
            vertex_count: model.template.vertex_count(),
            face_count: model.template.face_count(),
        },
        evaluation,
        explained_variance: Some(model.pca.cumulative_explained.clone()),
        n_modes: Some(model.pca.n_modes()),
        training_count: training.len(),
        holdout_count: holdout.len(),
        timings: StageTiming::all(&stages),
        losses: Vec::new(),
    };
    let model = StoredModel {
        model: AnyModel::Rsmp(model),
        training: training_shapes,
    };
    Ok(FitOutcome {
        model,
        summary,
        reference,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};
    use crate::models::progress::Silent;

    #[test]
    fn fit_samples_and_reconstructs_phantoms() {
        let meshes: Vec<Mesh> = phantom::generate(Family::Lv, 8, 3)
            .into_iter()
            .map(|p| p.mesh)
            .collect();
        let (training, holdout) = meshes.split_at(6);
        let started = std::time::Instant::now();
        let outcome = fit(
            training,
            holdout,
            &RsmpParams::default(),
            None,
            1,
            &mut Silent,
        )
        .unwrap();
        eprintln!(
            "rsmp fit of 6+2 LV phantoms: {:.1} s",
            started.elapsed().as_secs_f64()
        );
        let AnyModel::Rsmp(model) = &outcome.model.model else {
            panic!("an rsmp fit gives an rsmp model")
        };
        let summary = &outcome.summary;
        assert_eq!(summary.training_count, 6);
        assert!(summary.n_modes.unwrap() >= 1 && summary.n_modes.unwrap() <= 5);
        let generalisation = summary.evaluation.generalisation.unwrap();
        eprintln!(
            "generalisation HD {:.2} mm, specificity HD {:.2} mm",
            generalisation.hd.mean, summary.evaluation.specificity.hd.mean
        );
        assert!(generalisation.hd.mean > 0.0 && generalisation.hd.mean < 20.0);
        let sample = model
            .sample(
                &mut crate::models::cohort::draw_rng(5, 0),
                Sampling::Gaussian,
            )
            .unwrap();
        assert_eq!(sample.faces, model.template.faces);
        let volume = crate::mesh::measures::volume_ml(&sample);
        let reference = &outcome.reference.stats[0];
        assert!(
            volume > 0.5 * reference.min && volume < 1.5 * reference.max,
            "{volume} ml"
        );
        let bytes = outcome.model.to_bytes().unwrap();
        let back = StoredModel::from_bytes(&bytes).unwrap();
        let AnyModel::Rsmp(back_model) = &back.model else {
            panic!("the stored model is rsmp")
        };
        assert_eq!(back_model.pca, model.pca);
        assert_eq!(back.training.shapes.len(), 6);
        assert!(back.training.privacy.threshold_mm > 0.0);
    }
}
