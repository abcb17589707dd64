//! Rigid Coherent Point Drift (Myronenko & Song 2010; thesis eqs. 3.2–3.9, SPEC §2.2).
//!
//! The template `Y` (`[M, 3]`, the GMM centroids) is moved onto the data `X` (`[N, 3]`) by
//! `T(y) = s·R·y + t`. Both clouds are centred internally for numerical accuracy; results
//! are reported in the original coordinates (mm).

mod estep;
mod nonrigid;

use serde::{Deserialize, Serialize};

pub use estep::PosteriorSums;
pub use nonrigid::{NonRigidParams, NonRigidResult, nonrigid_cpd};

use super::GeometryError;
use super::error::check_points;
use super::points::{self, Mat3};
use super::procrustes::rotation_from_cross_covariance;
use super::transform::RigidTransform;

/// σ² is never allowed below this fraction of its initial value.
const SIGMA2_FLOOR_RELATIVE: f64 = 1e-12;
/// Total responsibility below which the template is considered to explain nothing.
const MIN_TOTAL_RESPONSIBILITY: f64 = 1e-12;

/// Parameters of rigid CPD.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidCpdParams {
    /// Weight `w` of the uniform outlier component, in `[0, 1)`.
    pub w: f64,
    /// Maximum number of EM iterations.
    pub max_iterations: usize,
    /// Stop when the relative change of the negative log-likelihood or of σ² is below this.
    pub tolerance: f64,
    /// Estimate the isotropic scale `s` (otherwise `s = 1`).
    pub scale: bool,
    /// Smallest variance σ² (mm²) the EM may reach; 0 lets it shrink freely. A floor at
    /// about the squared point spacing keeps a coarse registration from snapping onto
    /// individual points.
    #[serde(default)]
    pub min_sigma2: f64,
}

impl Default for RigidCpdParams {
    fn default() -> Self {
        Self {
            w: 0.1,
            max_iterations: 100,
            tolerance: 1e-6,
            scale: false,
            min_sigma2: 0.0,
        }
    }
}

impl RigidCpdParams {
    /// Checks the ranges of the parameters.
    pub fn check(&self) -> Result<(), GeometryError> {
        if !(0.0..1.0).contains(&self.w) {
            return Err(GeometryError::InvalidParams(format!(
                "cpd w must be in [0, 1), got {}",
                self.w
            )));
        }
        if self.max_iterations == 0 {
            return Err(GeometryError::InvalidParams(
                "cpd max_iterations must be >= 1".into(),
            ));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(GeometryError::InvalidParams(
                "cpd tolerance must be finite and >= 0".into(),
            ));
        }
        if !(self.min_sigma2.is_finite() && self.min_sigma2 >= 0.0) {
            return Err(GeometryError::InvalidParams(
                "cpd min_sigma2 must be finite and >= 0".into(),
            ));
        }
        Ok(())
    }
}

/// Outcome of a rigid CPD registration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CpdResult {
    /// Template-to-data transform `T(y) = s·R·y + t`.
    pub transform: RigidTransform,
    /// Final isotropic variance σ² in mm².
    pub sigma2: f64,
    /// Number of M-steps taken.
    pub iterations: usize,
    /// Whether a tolerance was met before `max_iterations`.
    pub converged: bool,
    /// The outlier weight `w` used (needed to recompute the posterior).
    pub outlier_weight: f64,
    /// Negative log-likelihood of the data at the final transform and σ².
    pub negative_log_likelihood: f64,
}

fn check_inputs(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &RigidCpdParams,
) -> Result<(), GeometryError> {
    params.check()?;
    check_points(template, "template")?;
    check_points(data, "data")
}

/// Rigid CPD from `R = I`, `s = 1` (SPEC §2.2), with both clouds centred first.
///
/// The start is `T(y) = y + (cx − cy)`, which is `t = 0` in centred coordinates, as in the
/// reference implementation (which normalises both clouds to zero mean before registering).
/// Use [`rigid_cpd_from`] for another initial transform.
pub fn rigid_cpd(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &RigidCpdParams,
) -> Result<CpdResult, GeometryError> {
    rigid_cpd_multistart(template, data, params, &[points::IDENTITY3])
}

/// State of the EM loop in centred coordinates (`x' = x − cx`, `y' = y − cy`).
struct Centred {
    x: Vec<[f64; 3]>,
    y: Vec<[f64; 3]>,
    cx: [f64; 3],
    cy: [f64; 3],
}

impl Centred {
    fn new(template: &[[f64; 3]], data: &[[f64; 3]]) -> Self {
        let cx = points::centroid(data, None);
        let cy = points::centroid(template, None);
        let x = data.iter().map(|p| points::sub(*p, cx)).collect();
        let y = template.iter().map(|p| points::sub(*p, cy)).collect();
        Self { x, y, cx, cy }
    }

    /// `T'(y') = T(y' + cy) − cx` for a transform given in original coordinates.
    fn to_centred(&self, t: &RigidTransform) -> RigidTransform {
        RigidTransform {
            translation: points::sub(t.apply(self.cy), self.cx),
            ..*t
        }
    }

    fn to_original(&self, t: &RigidTransform) -> RigidTransform {
        let moved_cy = points::scale(points::mat_vec(&t.rotation, self.cy), t.scale);
        let translation = points::sub(points::add(t.translation, self.cx), moved_cy);
        RigidTransform { translation, ..*t }
    }

    /// Initial σ² = Σₙₘ‖xₙ − T(yₘ)‖² / (3NM), using Σₙ x'ₙ = 0.
    fn initial_sigma2(&self, moved: &[[f64; 3]]) -> f64 {
        let (m, n) = (moved.len() as f64, self.x.len() as f64);
        let sx: f64 = self.x.iter().map(|p| points::norm2(*p)).sum();
        let sz: f64 = moved.iter().map(|p| points::norm2(*p)).sum();
        (m * sx + n * sz) / (3.0 * n * m)
    }
}

/// One closed-form M-step (SPEC §2.2). Returns the new transform (centred frame) and σ².
fn m_step(
    c: &Centred,
    sums: &PosteriorSums,
    with_scale: bool,
) -> Result<Option<(RigidTransform, f64)>, GeometryError> {
    let np: f64 = sums.p1.iter().sum();
    if np <= MIN_TOTAL_RESPONSIBILITY {
        return Ok(None);
    }
    let mu_x = points::scale(
        c.x.iter()
            .zip(&sums.pt1)
            .fold([0.0; 3], |a, (x, w)| points::add(a, points::scale(*x, *w))),
        1.0 / np,
    );
    let mu_y = points::scale(
        c.y.iter()
            .zip(&sums.p1)
            .fold([0.0; 3], |a, (y, w)| points::add(a, points::scale(*y, *w))),
        1.0 / np,
    );
    // A = X̂ᵀ·Pᵀ·Ŷ = Σₘ (P·X)ₘ·y'ₘᵀ − N_P·μx·μyᵀ.
    let mut a: Mat3 = [[0.0; 3]; 3];
    for (px, y) in sums.px.iter().zip(&c.y) {
        for (r, row) in a.iter_mut().enumerate() {
            for (col, cell) in row.iter_mut().enumerate() {
                *cell += px[r] * y[col];
            }
        }
    }
    for (r, row) in a.iter_mut().enumerate() {
        for (col, cell) in row.iter_mut().enumerate() {
            *cell -= np * mu_x[r] * mu_y[col];
        }
    }
    let (rotation, tr_ar) = rotation_from_cross_covariance(&a)?;
    let yy =
        c.y.iter()
            .zip(&sums.p1)
            .map(|(y, w)| w * points::norm2(*y))
            .sum::<f64>()
            - np * points::norm2(mu_y);
    let xx =
        c.x.iter()
            .zip(&sums.pt1)
            .map(|(x, w)| w * points::norm2(*x))
            .sum::<f64>()
            - np * points::norm2(mu_x);
    let scale = if with_scale {
        if yy <= 0.0 {
            return Err(GeometryError::DegenerateInput(
                "template points coincide".into(),
            ));
        }
        tr_ar / yy
    } else {
        1.0
    };
    let translation = points::sub(mu_x, points::scale(points::mat_vec(&rotation, mu_y), scale));
    // Expected residual Σ P‖x − T(y)‖² / (3 N_P); equals (xx − s·tr(AᵀR)) / (3 N_P) when s is
    // estimated (SPEC §2.2) and stays correct when s is held at 1.
    let sigma2 = (xx - 2.0 * scale * tr_ar + scale * scale * yy) / (3.0 * np);
    Ok(Some((
        RigidTransform {
            rotation,
            translation,
            scale,
        },
        sigma2,
    )))
}

fn relative_change(old: f64, new: f64) -> f64 {
    (new - old).abs() / new.abs().max(f64::MIN_POSITIVE)
}

/// Rigid CPD starting from `initial` (a template-to-data transform in original coordinates).
pub fn rigid_cpd_from(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &RigidCpdParams,
    initial: &RigidTransform,
) -> Result<CpdResult, GeometryError> {
    check_inputs(template, data, params)?;
    let c = Centred::new(template, data);
    let transform = c.to_centred(initial);
    let sigma2 = c.initial_sigma2(&transform.apply_all(&c.y));
    em_loop(&c, transform, sigma2, params)
}

/// Rigid CPD warm-started from `initial` with the variance `sigma2` (mm²) of an earlier
/// registration (e.g. of subsampled clouds), so that it needs only a few iterations.
pub fn rigid_cpd_warm(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &RigidCpdParams,
    initial: &RigidTransform,
    sigma2: f64,
) -> Result<CpdResult, GeometryError> {
    check_inputs(template, data, params)?;
    let c = Centred::new(template, data);
    em_loop(&c, c.to_centred(initial), sigma2, params)
}

fn em_loop(
    c: &Centred,
    mut transform: RigidTransform,
    mut sigma2: f64,
    params: &RigidCpdParams,
) -> Result<CpdResult, GeometryError> {
    if !(sigma2.is_finite() && sigma2 > 0.0) {
        return Err(GeometryError::DegenerateInput("all points coincide".into()));
    }
    let floor = (sigma2 * SIGMA2_FLOOR_RELATIVE).max(params.min_sigma2);
    sigma2 = sigma2.max(floor);
    let (mut iterations, mut converged, mut previous_nll) = (0, false, f64::NAN);
    while iterations < params.max_iterations {
        let sums = estep::posterior_sums_moved(&transform.apply_all(&c.y), &c.x, sigma2, params.w);
        let nll = sums.negative_log_likelihood;
        if relative_change(previous_nll, nll) <= params.tolerance {
            converged = true;
            break;
        }
        previous_nll = nll;
        let Some((next, next_sigma2)) = m_step(c, &sums, params.scale)? else {
            break;
        };
        iterations += 1;
        let sigma2_change = relative_change(sigma2, next_sigma2.max(floor));
        transform = next;
        sigma2 = next_sigma2.max(floor);
        if sigma2_change <= params.tolerance || sigma2 <= floor {
            converged = true;
            break;
        }
    }
    let final_sums =
        estep::posterior_sums_moved(&transform.apply_all(&c.y), &c.x, sigma2, params.w);
    Ok(CpdResult {
        transform: c.to_original(&transform),
        sigma2,
        iterations,
        converged,
        outlier_weight: params.w,
        negative_log_likelihood: final_sums.negative_log_likelihood,
    })
}

/// Rigid CPD from several initial rotations; keeps the run with the lowest final negative
/// log-likelihood (the first one on ties).
///
/// Each start rotates the template about its centroid and moves that centroid onto the
/// data centroid. Pass [`axis_permutation_rotations`](super::axis_permutation_rotations)
/// for shapes in arbitrary orientations.
pub fn rigid_cpd_multistart(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &RigidCpdParams,
    starts: &[Mat3],
) -> Result<CpdResult, GeometryError> {
    check_inputs(template, data, params)?;
    if starts.is_empty() {
        return Err(GeometryError::InvalidParams(
            "multistart needs at least one rotation".into(),
        ));
    }
    let cx = points::centroid(data, None);
    let cy = points::centroid(template, None);
    let mut best: Option<CpdResult> = None;
    for rotation in starts {
        let moved_cy = points::mat_vec(rotation, cy);
        let initial = RigidTransform {
            rotation: *rotation,
            translation: points::sub(cx, moved_cy),
            scale: 1.0,
        };
        let run = rigid_cpd_from(template, data, params, &initial)?;
        if best.is_none_or(|b| run.negative_log_likelihood < b.negative_log_likelihood) {
            best = Some(run);
        }
    }
    best.ok_or(GeometryError::InvalidParams(
        "multistart needs at least one rotation".into(),
    ))
}

fn check_posterior_args(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    sigma2: f64,
    w: f64,
) -> Result<(), GeometryError> {
    check_points(template, "template")?;
    check_points(data, "data")?;
    if !(sigma2.is_finite() && sigma2 > 0.0) {
        return Err(GeometryError::InvalidParams(format!(
            "sigma2 must be > 0, got {sigma2}"
        )));
    }
    if !(0.0..1.0).contains(&w) {
        return Err(GeometryError::InvalidParams(format!(
            "w must be in [0, 1), got {w}"
        )));
    }
    Ok(())
}

/// Sums `P·1`, `Pᵀ·1`, `P·X` of the posterior for `transform` and `sigma2` (mm²), with
/// `P·X` in the data's coordinates. Memory `O(M + N)`.
pub fn posterior_sums(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    transform: &RigidTransform,
    sigma2: f64,
    w: f64,
) -> Result<PosteriorSums, GeometryError> {
    check_posterior_args(template, data, sigma2, w)?;
    Ok(estep::posterior_sums_moved(
        &transform.apply_all(template),
        data,
        sigma2,
        w,
    ))
}

/// The dense posterior `P` (eq. 3.7), `[M, N]` row-major: `P[m·N + n] = p(yₘ | xₙ)`.
///
/// Needs `8·M·N` bytes; prefer [`posterior_sums`] when only the sums are needed.
pub fn posterior(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    transform: &RigidTransform,
    sigma2: f64,
    w: f64,
) -> Result<Vec<f64>, GeometryError> {
    check_posterior_args(template, data, sigma2, w)?;
    Ok(estep::dense_posterior_moved(
        &transform.apply_all(template),
        data,
        sigma2,
        w,
    ))
}

#[cfg(test)]
mod tests;
