//! Parameters of an ASMG fit (`params` of a job with `model_type: "asmg"`, issue 4 item 4):
//! what the graph network sees, how the atlas is learned, and how both networks train.

use serde::{Deserialize, Serialize};

use super::atlas::AtlasUpdateParams;
use super::attention::{DEFAULT_VARIANCE_MULTIPLIER, Temperature};
use super::init::DEFAULT_ATLAS_VERTICES;
use super::learn::{AtlasLoopParams, DEFAULT_MAX_STEPS, DEFAULT_TOLERANCE_MM};
use super::smoothing::{DEFAULT_GAMMA, Smoothing, SmoothingMethod, SmoothingParams};
use crate::geometry::cpd::NonRigidParams;
use crate::mesh::simplify::MIN_TARGET_VERTICES;
use crate::models::ModelError;
use crate::models::alignment::AlignmentParams;
use crate::nn::Features;

pub use crate::models::alignment::{DEFAULT_MAX_VERTICES, MAX_VERTICES_LIMIT};
/// Default latent width `L` of the generator (thesis fig. 4.13).
pub const DEFAULT_LATENT_DIM: usize = 16;
/// Default epochs of the graph VAE Ψ. Chosen by matching quality within the time budget (a
/// fit of 100 LV phantoms in 10 minutes on 2 cores): on 40 LV phantoms (`asmg_stages`), 3
/// epochs matched as well as 5 (CD h'–mesh 3.58 vs 3.60 mm, HD 5.19 vs 5.31 mm, the same
/// volumes and coverage) at 60% of the time.
pub const DEFAULT_EPOCHS_GRAPH: usize = 3;
/// Default epochs of the beta-VAE generator.
pub const DEFAULT_EPOCHS_VAE: usize = 100;
/// Default mini-batch size of Ψ (SPEC §2.9: small batches, 4).
pub const DEFAULT_BATCH_SIZE: usize = 4;
/// Default mini-batch size of the generator. Its steps cost the optimiser's update of ≈ 4
/// million weights whatever the batch, so larger batches buy time: on 40 LV phantoms,
/// batch 16 trained in 13 s against 47 s for batch 4, reconstructing to 1.13 vs 1.19 mm RMS
/// with draws as varied (volume sd 10.0 vs 9.9 ml; the normalised shapes 13.9 ml).
pub const DEFAULT_BATCH_SIZE_VAE: usize = 16;
/// Default Adam learning rate of both networks.
pub const DEFAULT_LR: f64 = 1e-3;
/// Default KL weight of the generator on standardised shapes. On 40 LV phantoms
/// (`asmg_stages`, 100 epochs, Ψ of 5 epochs, latent dimensions drawn independently): β 0.1
/// reconstructed to 1.49 mm RMS with draws of volume sd 4.2 ml, β 1 to 1.83 mm with draws of
/// sd 6.0 ml (training 13.9 ml).
pub const DEFAULT_BETA: f64 = 1.0;
/// Default KL weight of Ψ (SPEC §2.4).
pub const DEFAULT_W_KL: f64 = 1e-3;
/// Default weight of Ψ's normal term (hybrid features, SPEC §2.4).
pub const DEFAULT_W_NORM: f64 = 1e-2;
/// Default CPD iterations of the pre-alignment's refinement (the 24-rotation search has its
/// own budget); fewer than RSMP's 100 because the attention absorbs small residual
/// misalignment, and the pre-alignment took 29% of a 100-phantom fit.
pub const DEFAULT_CPD_MAX_ITERATIONS: usize = 40;
/// Largest epoch count accepted for either network.
pub const MAX_EPOCHS: usize = 10_000;
/// Largest latent width accepted.
pub const MAX_LATENT_DIM: usize = 512;
/// Largest number of atlas steps accepted.
pub const MAX_EM_STEPS: usize = 1000;

/// Per-vertex features of the graph network (sGCN or hGCN).
///
/// Hybrid is the default: on 40 LV phantoms (`cargo run --release --example asmg_stages`),
/// spatial embeddings matched the inner wall of the atlas to the outer wall of smaller
/// shapes, so the normalised shapes kept 46 ml of the meshes' 102 ml and the fit collapsed;
/// with normals the normalised shapes kept 100 ml.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FeatureKind {
    /// Positions (sGCN).
    Spatial,
    /// Positions and angle-weighted vertex normals (hGCN, eq. 4.13).
    #[default]
    Hybrid,
}

impl FeatureKind {
    /// The network's feature set.
    pub fn features(self) -> Features {
        match self {
            Self::Spatial => Features::Spatial,
            Self::Hybrid => Features::Hybrid,
        }
    }
}

/// What the normalised shapes' smoothing acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SmoothingTarget {
    /// The positions (thesis eq. 4.5; shrinks shapes, SPEC §2.9).
    Positions,
    /// The displacement from the atlas.
    #[default]
    Displacement,
}

impl SmoothingTarget {
    fn smoothing(self) -> Smoothing {
        match self {
            Self::Positions => Smoothing::Positions,
            Self::Displacement => Smoothing::Displacement,
        }
    }
}

/// How drawn shapes get the training shapes' spread (with `calibrate_spread` on).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationKind {
    /// Each draw moved along the training shapes' regression on volume and area until the
    /// draws' volume and area have the training meshes' mean and covariance, and volume and
    /// shape index (area / volume^(2/3)) each its smoothed distribution (see
    /// [`super::biomarker_calibration`]); what else the draws do stays as decoded.
    #[default]
    Biomarkers,
    /// One linear map of the draws' coordinates on the training shapes' principal modes
    /// giving them the training mean and covariance there (see [`super::calibration`]).
    Modes,
}

/// Parameters of an ASMG fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AsmgParams {
    /// Features of Ψ: `spatial` (sGCN) or `hybrid` (hGCN).
    pub features: FeatureKind,
    /// Initial atlas: `auto` (the training mesh closest to `atlas_vertices`, simplified to
    /// it), `icosphere`, or the id of a mesh of the dataset.
    pub atlas: String,
    /// Requested atlas resolution `N_μ` (vertices).
    pub atlas_vertices: usize,
    /// Meshes with more vertices are simplified to this before Ψ sees them.
    pub max_vertices: usize,
    /// Latent width `L` of the generator.
    pub latent_dim: usize,
    /// Epochs of Ψ.
    pub epochs_graph: usize,
    /// Epochs of the generator.
    pub epochs_vae: usize,
    /// Meshes per mini-batch of Ψ.
    pub batch_size: usize,
    /// Shapes per mini-batch of the generator.
    pub batch_size_vae: usize,
    /// Adam learning rate of both networks.
    pub lr: f64,
    /// KL weight of the generator on standardised shapes (mean shape, spread); with
    /// `choose_beta`, the smallest candidate.
    pub beta: f64,
    /// Below 50 training shapes (from 6), choose the generator's KL weight among `beta`
    /// times 1, 3, 10 and 30 on held-out folds of the training shapes: the smallest held-out
    /// reconstruction error among the weights whose draws are near copies of their training
    /// shapes at most 8% of the time. With β 1 on 16 KiTS19 kidneys half the cohort were
    /// near copies. Models stored before it existed were trained with `beta` as given.
    pub choose_beta: bool,
    /// KL weight of Ψ.
    pub w_kl: f64,
    /// Weight of Ψ's normal term (hybrid only).
    pub w_norm: f64,
    /// Smoothing weight γ of the normalised shapes.
    pub gamma: f64,
    /// What is smoothed: `displacement` (default) or `positions` (thesis).
    pub smoothing: SmoothingTarget,
    /// Fixed inverse temperature λ on cosine similarities; `null`: λ = `variance_multiplier`
    /// / variance of the scores.
    pub temperature: Option<f64>,
    /// Factor on 1/variance of the scores when `temperature` is null (thesis: 1).
    pub variance_multiplier: f64,
    /// Largest number of atlas steps (Algorithm 1).
    pub max_em_steps: usize,
    /// Stop the atlas loop once a step moves the atlas less than this on average, mm.
    pub tolerance: f64,
    /// Search 24 initial rotations in the pre-alignment.
    pub multistart: bool,
    /// Most CPD iterations of the pre-alignment.
    pub cpd_max_iterations: usize,
    /// Give drawn shapes the training shapes' mean and covariance on the principal modes of
    /// the training population's normalised shapes (a generator's draws vary less than its
    /// training shapes: without it, and with `variance_multiplier` 30 and `gamma` 1, cohorts
    /// of 100 LV phantoms had half the training meshes' volume sd).
    pub calibrate_spread: bool,
    /// Which calibration: `biomarkers` (draws moved along the training shapes' regression on
    /// volume and area) or `modes` (a linear map on the principal modes, the only one before
    /// `calibration` existed; models stored then were calibrated on the modes whatever their
    /// stored parameters read).
    pub calibration: CalibrationKind,
    /// Align the shapes a generator learns from to their mean (rigid generalised Procrustes)
    /// first, so that no latent direction is spent on the pose the pre-alignment left; a new
    /// mesh's normalised shape is aligned to that mean before it is encoded, and its
    /// reconstruction moved back to the mesh's pose. Off by default: on 100 LV phantoms
    /// (seed 1) it raised joint A^μ from 83.3% to 88.2% and cut generalisation ED from 2.17
    /// to 1.92 mm, but narrowed the cohort's volume sd from 0.875 to 0.840 of the training
    /// meshes'.
    pub procrustes: bool,
    /// Deform each normalised shape onto its mesh with non-rigid CPD after the attention
    /// (see [`super::nonrigid`]); a new mesh's normalised shape is refined the same way before
    /// it is encoded. Off by default: on 100 LV phantoms (seed 1) it cut matching HD from 6.85
    /// to 4.06 mm and specificity HD from 8.18 to 6.70 mm, but the cohort's volume sd fell from
    /// 0.875 to 0.762 of the training meshes' (seed 3: 0.685 to 0.791).
    pub nonrigid: bool,
    /// Register every mesh as its mirror image too and let the training population choose
    /// which of the two each mesh takes (see [`crate::models::sides`]), so that left and
    /// right organs (KiTS19 kidneys) are all learned on the reference's side; a new mesh
    /// takes the side nearer the atlas. The model summary lists the mirrored meshes. Off by
    /// default: it doubles the registrations, and meshes of one side gain nothing from it.
    pub mirror: bool,
}

impl Default for AsmgParams {
    fn default() -> Self {
        Self {
            features: FeatureKind::Hybrid,
            atlas: "auto".to_owned(),
            atlas_vertices: DEFAULT_ATLAS_VERTICES,
            max_vertices: DEFAULT_MAX_VERTICES,
            latent_dim: DEFAULT_LATENT_DIM,
            epochs_graph: DEFAULT_EPOCHS_GRAPH,
            epochs_vae: DEFAULT_EPOCHS_VAE,
            batch_size: DEFAULT_BATCH_SIZE,
            batch_size_vae: DEFAULT_BATCH_SIZE_VAE,
            lr: DEFAULT_LR,
            beta: DEFAULT_BETA,
            choose_beta: true,
            w_kl: DEFAULT_W_KL,
            w_norm: DEFAULT_W_NORM,
            gamma: DEFAULT_GAMMA,
            smoothing: SmoothingTarget::Displacement,
            temperature: None,
            variance_multiplier: DEFAULT_VARIANCE_MULTIPLIER,
            max_em_steps: DEFAULT_MAX_STEPS,
            tolerance: DEFAULT_TOLERANCE_MM,
            multistart: true,
            cpd_max_iterations: DEFAULT_CPD_MAX_ITERATIONS,
            calibrate_spread: true,
            calibration: CalibrationKind::Biomarkers,
            procrustes: false,
            nonrigid: false,
            mirror: false,
        }
    }
}

/// ASMG parameters that passed [`AsmgParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedAsmgParams(AsmgParams);

impl CheckedAsmgParams {
    /// The parameters.
    pub fn get(&self) -> &AsmgParams {
        &self.0
    }
}

/// How the initial atlas is chosen, as parsed from `atlas`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AtlasChoice<'a> {
    /// The training mesh closest to `atlas_vertices`.
    Auto,
    /// An icosphere of the shapes' mean size.
    Icosphere,
    /// A mesh of the dataset, by id.
    Mesh(&'a str),
}

fn positive_finite(field: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ModelError::invalid(
            field,
            format!("must be a positive number, got {v}"),
        ))
    }
}

fn non_negative_finite(field: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::invalid(
            field,
            format!("must be a number >= 0, got {v}"),
        ))
    }
}

fn within(field: &str, v: usize, lo: usize, hi: usize) -> Result<(), ModelError> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(ModelError::invalid(
            field,
            format!("must be between {lo} and {hi}, got {v}"),
        ))
    }
}

impl AsmgParams {
    /// Checks every value (the error names the parameter): what a fit takes.
    pub fn check(self) -> Result<CheckedAsmgParams, ModelError> {
        self.validate()?;
        Ok(CheckedAsmgParams(self))
    }

    /// Checks every value; the error names the parameter.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.atlas.trim().is_empty() {
            return Err(ModelError::invalid(
                "atlas",
                "must be \"auto\", \"icosphere\" or a mesh id",
            ));
        }
        within(
            "max_vertices",
            self.max_vertices,
            MIN_TARGET_VERTICES,
            MAX_VERTICES_LIMIT,
        )?;
        within(
            "atlas_vertices",
            self.atlas_vertices,
            MIN_TARGET_VERTICES,
            self.max_vertices,
        )?;
        within("latent_dim", self.latent_dim, 1, MAX_LATENT_DIM)?;
        within("epochs_graph", self.epochs_graph, 1, MAX_EPOCHS)?;
        within("epochs_vae", self.epochs_vae, 1, MAX_EPOCHS)?;
        within("batch_size", self.batch_size, 1, 1024)?;
        within("batch_size_vae", self.batch_size_vae, 1, 1024)?;
        within("max_em_steps", self.max_em_steps, 1, MAX_EM_STEPS)?;
        within("cpd_max_iterations", self.cpd_max_iterations, 1, 10_000)?;
        positive_finite("lr", self.lr)?;
        non_negative_finite("beta", self.beta)?;
        non_negative_finite("w_kl", self.w_kl)?;
        non_negative_finite("w_norm", self.w_norm)?;
        non_negative_finite("gamma", self.gamma)?;
        non_negative_finite("tolerance", self.tolerance)?;
        positive_finite("variance_multiplier", self.variance_multiplier)?;
        if let Some(t) = self.temperature {
            non_negative_finite("temperature", t)?;
        }
        Ok(())
    }

    /// The initial-atlas choice.
    pub fn atlas_choice(&self) -> AtlasChoice<'_> {
        match self.atlas.as_str() {
            "auto" => AtlasChoice::Auto,
            "icosphere" => AtlasChoice::Icosphere,
            id => AtlasChoice::Mesh(id),
        }
    }

    /// The mesh id given as atlas, if any.
    pub fn atlas_mesh_id(&self) -> Option<&str> {
        match self.atlas_choice() {
            AtlasChoice::Mesh(id) => Some(id),
            _ => None,
        }
    }

    /// The attention temperature.
    pub fn temperature(&self) -> Temperature {
        match self.temperature {
            Some(lambda) => Temperature::Fixed(lambda),
            None => Temperature::InverseVariance {
                multiplier: self.variance_multiplier,
            },
        }
    }

    /// Smoothing of the normalised shapes (exact solve).
    pub fn smoothing(&self) -> SmoothingParams {
        SmoothingParams {
            gamma: self.gamma,
            target: self.smoothing.smoothing(),
            method: SmoothingMethod::Exact,
        }
    }

    /// Settings of Algorithm 1.
    pub fn atlas_loop(&self) -> AtlasLoopParams {
        AtlasLoopParams {
            temperature: self.temperature(),
            smoothing: self.smoothing(),
            atlas_update: AtlasUpdateParams {
                target: self.smoothing.smoothing(),
                ..AtlasUpdateParams::default()
            },
            tolerance_mm: self.tolerance,
            max_steps: self.max_em_steps,
        }
    }

    /// The non-rigid refinement of normalised shapes this fit asks for (`None`: off).
    pub fn nonrigid_refinement(&self) -> Option<NonRigidParams> {
        self.nonrigid.then(NonRigidParams::default)
    }

    /// Settings of the rigid pre-alignment.
    pub fn alignment(&self) -> AlignmentParams {
        let mut a = AlignmentParams {
            multistart: self.multistart,
            mirror: self.mirror,
            ..AlignmentParams::default()
        };
        a.cpd.max_iterations = self.cpd_max_iterations;
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(p: AsmgParams) -> String {
        match p.validate() {
            Err(ModelError::InvalidParams { field, .. }) => field,
            other => panic!("expected invalid params, got {other:?}"),
        }
    }

    #[test]
    fn defaults_are_valid_and_bad_values_name_their_field() {
        let d = AsmgParams::default();
        assert!(d.clone().check().is_ok());
        assert_eq!(d.atlas_choice(), AtlasChoice::Auto);
        assert_eq!(
            d.temperature(),
            Temperature::InverseVariance {
                multiplier: DEFAULT_VARIANCE_MULTIPLIER
            }
        );
        let with = |f: fn(&mut AsmgParams)| {
            let mut p = AsmgParams::default();
            f(&mut p);
            p
        };
        assert_eq!(field(with(|p| p.latent_dim = 0)), "latent_dim");
        assert_eq!(field(with(|p| p.lr = -1.0)), "lr");
        assert_eq!(field(with(|p| p.beta = f64::NAN)), "beta");
        assert_eq!(field(with(|p| p.atlas_vertices = 5000)), "atlas_vertices");
        assert_eq!(field(with(|p| p.temperature = Some(-3.0))), "temperature");
        assert_eq!(field(with(|p| p.max_em_steps = 0)), "max_em_steps");
        assert_eq!(field(with(|p| p.atlas = " ".into())), "atlas");
    }

    #[test]
    fn atlas_choices_and_derived_settings() {
        let mut p = AsmgParams {
            atlas: "icosphere".into(),
            temperature: Some(1e4),
            smoothing: SmoothingTarget::Positions,
            ..AsmgParams::default()
        };
        assert_eq!(p.atlas_choice(), AtlasChoice::Icosphere);
        assert_eq!(p.temperature(), Temperature::Fixed(1e4));
        assert_eq!(p.atlas_loop().smoothing.target, Smoothing::Positions);
        assert_eq!(p.atlas_loop().atlas_update.target, Smoothing::Positions);
        p.atlas = "m-42".into();
        assert_eq!(p.atlas_mesh_id(), Some("m-42"));
        assert_eq!(p.alignment().cpd.max_iterations, DEFAULT_CPD_MAX_ITERATIONS);
    }
}
