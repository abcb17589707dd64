//! Parameters of an RSMP fit (`params` of a job with `model_type: "rsmp"`).

use serde::{Deserialize, Serialize};

use crate::geometry::cpd::{NonRigidParams, RigidCpdParams};
use crate::mesh::simplify::MIN_TARGET_VERTICES;
use crate::models::ModelError;
use crate::models::alignment::{AlignmentParams, DEFAULT_MAX_VERTICES, MAX_VERTICES_LIMIT};

/// Default share of variance the kept modes explain.
pub const DEFAULT_VARIANCE_TARGET: f64 = 0.95;

/// Default Taubin steps on drawn shapes.
pub const DEFAULT_DRAW_SMOOTHING_STEPS: usize = 2;
/// Most Taubin steps accepted.
pub const MAX_DRAW_SMOOTHING_STEPS: usize = 50;

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
    /// Refine each rigid registration by a smooth non-rigid CPD before reading the soft
    /// correspondences, so that template points land on the matching part of the surface
    /// (e.g. the same wall of a hollow organ); off gives rigid correspondences only.
    pub nonrigid: bool,
    /// Width of the non-rigid displacement field as a share of the template's rms radius.
    pub nonrigid_beta: f64,
    /// Stiffness λ of the non-rigid displacement field.
    pub nonrigid_lambda: f64,
    /// Taubin λ|μ steps applied to every drawn shape (0: draws as the PCA gives them).
    /// Independent combinations of the modes leave small folds on the surface; on 100 liver
    /// phantoms two steps brought the cohort's sphericity sd from 1.27 to 0.98 of the
    /// training meshes'.
    pub draw_smoothing_steps: usize,
    /// Align the normalised shapes to their mean by rotation and translation (generalised
    /// Procrustes, in correspondence) before the PCA, so that no mode is spent on what the
    /// registration left of each mesh's pose; reconstructions are aligned the same way.
    pub procrustes: bool,
    /// Vertex budget of the registration: a template with more vertices is simplified to
    /// about this many (its simplified surface is then the connectivity of every output),
    /// and of a mesh with more, every k-th vertex is registered so that about this many
    /// remain. CPD's cost grows with the product of the two vertex counts.
    pub max_vertices: usize,
    /// Draw each mode's coefficient from the training shapes' own coefficients of that mode
    /// (one training shape chosen at random per mode) instead of from a Gaussian, from
    /// [`SMALL_POPULATION`] training meshes on (fewer draw Gaussian coefficients). A
    /// request's `sampling: "uniform"` still draws uniform coefficients.
    ///
    /// [`SMALL_POPULATION`]: crate::models::reference::SMALL_POPULATION
    pub empirical_coefficients: bool,
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
            nonrigid: true,
            nonrigid_beta: NonRigidParams::default().beta,
            nonrigid_lambda: NonRigidParams::default().lambda,
            draw_smoothing_steps: DEFAULT_DRAW_SMOOTHING_STEPS,
            procrustes: true,
            max_vertices: DEFAULT_MAX_VERTICES,
            empirical_coefficients: true,
        }
    }
}

impl RsmpParams {
    /// Checks every value (the error names the parameter): what a fit takes.
    pub fn check(self) -> Result<CheckedRsmpParams, ModelError> {
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
        for (name, value) in [
            ("nonrigid_beta", self.nonrigid_beta),
            ("nonrigid_lambda", self.nonrigid_lambda),
        ] {
            if !(value.is_finite() && value > 0.0 && value <= 100.0) {
                return Err(ModelError::invalid(
                    name,
                    format!("must be in (0, 100], got {value}"),
                ));
            }
        }
        if self.draw_smoothing_steps > MAX_DRAW_SMOOTHING_STEPS {
            return Err(ModelError::invalid(
                "draw_smoothing_steps",
                format!("must be at most {MAX_DRAW_SMOOTHING_STEPS}"),
            ));
        }
        if !(MIN_TARGET_VERTICES..=MAX_VERTICES_LIMIT).contains(&self.max_vertices) {
            return Err(ModelError::invalid(
                "max_vertices",
                format!(
                    "must be between {MIN_TARGET_VERTICES} and {MAX_VERTICES_LIMIT}, got {}",
                    self.max_vertices
                ),
            ));
        }
        Ok(CheckedRsmpParams(self))
    }

    pub(super) fn nonrigid(&self) -> Option<NonRigidParams> {
        self.nonrigid.then(|| NonRigidParams {
            beta: self.nonrigid_beta,
            lambda: self.nonrigid_lambda,
            ..NonRigidParams::default()
        })
    }

    pub(super) fn alignment(&self) -> AlignmentParams {
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

/// RSMP parameters that passed [`RsmpParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedRsmpParams(RsmpParams);

impl CheckedRsmpParams {
    /// The parameters.
    pub fn get(&self) -> &RsmpParams {
        &self.0
    }
}
