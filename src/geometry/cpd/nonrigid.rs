//! Smooth non-rigid CPD (Myronenko & Song 2010, coherent point drift) on a low-rank
//! displacement field, used to refine a rigid registration before soft correspondences are
//! read.
//!
//! The template `Y` (`[M, 3]`) moves to `Y + Φ·C`, where `Φ` (`[M, K]`) holds Gaussian
//! kernels `exp(−‖yₘ − z_k‖²/2β²)` at `K` control points `Z` taken from the template, and
//! `C` (`[K, 3]`, mm) are the coefficients. The prior is the field's kernel norm
//! `λ/2·tr(Cᵀ·G_ZZ·C)`, so the M-step solves the `K × K` system
//! `(Φᵀ·d(P1)·Φ + λσ²·G_ZZ)·C = Φᵀ·(P·X − d(P1)·Y)`: linear in `M` and `N` per iteration,
//! with the same E-step as rigid CPD. Both clouds must already be in one frame (the rigid
//! result undone), in mm.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::estep::{PosteriorSums, posterior_sums_moved};
use crate::geometry::GeometryError;
use crate::geometry::error::check_points;
use crate::geometry::points::{dist2, dot, norm2, rms_radius};

/// σ² never falls below this fraction of its starting value.
const SIGMA2_FLOOR_RELATIVE: f64 = 1e-6;

/// Settings of the non-rigid refinement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NonRigidParams {
    /// Kernel width β as a share of the template's rms radius (its root-mean-square
    /// distance from its centroid): larger is smoother.
    pub beta: f64,
    /// Weight λ of the smoothness prior (unitless); larger keeps the template stiffer.
    pub lambda: f64,
    /// Weight of the uniform outlier component, in `[0, 1)`. Default 0: with outliers
    /// allowed, a free field can let σ² collapse by pinning template points onto a few data
    /// points and calling the rest outliers.
    pub w: f64,
    /// Most EM iterations.
    pub max_iterations: usize,
    /// Stop when the relative change of σ² falls below this.
    pub tolerance: f64,
    /// Control points `K` (the template is subsampled evenly to at most this many).
    pub control_points: usize,
}

impl Default for NonRigidParams {
    fn default() -> Self {
        Self {
            beta: 0.3,
            lambda: 0.2,
            w: 0.0,
            max_iterations: 100,
            tolerance: 1e-4,
            control_points: 150,
        }
    }
}

impl NonRigidParams {
    /// Checks the ranges (the message names the parameter).
    pub fn check(&self) -> Result<(), GeometryError> {
        let bad = |what: &str| Err(GeometryError::InvalidParams(what.to_owned()));
        if !(self.beta.is_finite() && self.beta > 0.0) {
            return bad("non-rigid beta must be > 0");
        }
        if !(self.lambda.is_finite() && self.lambda > 0.0) {
            return bad("non-rigid lambda must be > 0");
        }
        if !(0.0..1.0).contains(&self.w) {
            return bad("non-rigid w must be in [0, 1)");
        }
        if self.max_iterations == 0 || self.control_points == 0 {
            return bad("non-rigid iterations and control points must be >= 1");
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad("non-rigid tolerance must be finite and >= 0");
        }
        Ok(())
    }
}

/// Outcome of a non-rigid refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct NonRigidResult {
    /// The deformed template `Y + Φ·C`, `[M, 3]` (mm).
    pub moved: Vec<[f64; 3]>,
    /// Final σ² (mm²).
    pub sigma2: f64,
    /// Posterior sums at the deformed template and the final σ².
    pub sums: PosteriorSums,
    /// M-steps taken.
    pub iterations: usize,
}

/// The low-rank field: kernels at the control points and their Gram matrix.
struct Field {
    /// `Φ`, `[M, K]` row-major.
    phi: DMatrix<f64>,
    /// `G_ZZ`, `[K, K]`.
    gram: DMatrix<f64>,
}

impl Field {
    fn new(template: &[[f64; 3]], params: &NonRigidParams) -> Self {
        let stride = template.len().div_ceil(params.control_points).max(1);
        let control: Vec<[f64; 3]> = template.iter().step_by(stride).copied().collect();
        let beta = params.beta * rms_radius(template);
        let kernel = |a: [f64; 3], b: [f64; 3]| (-dist2(a, b) / (2.0 * beta * beta)).exp();
        let phi = DMatrix::from_fn(template.len(), control.len(), |m, k| {
            kernel(template[m], control[k])
        });
        let gram = DMatrix::from_fn(control.len(), control.len(), |i, j| {
            kernel(control[i], control[j])
        });
        Self { phi, gram }
    }

    /// Solves the M-step for `C` (`[K, 3]`).
    fn solve(
        &self,
        template: &[[f64; 3]],
        sums: &PosteriorSums,
        lambda_sigma2: f64,
    ) -> Option<DMatrix<f64>> {
        let (m, k) = self.phi.shape();
        let mut weighted = self.phi.clone();
        for (row, p1) in sums.p1.iter().enumerate().take(m) {
            weighted.row_mut(row).scale_mut(*p1);
        }
        let mut a = self.phi.transpose() * &weighted + &self.gram * lambda_sigma2;
        // A small ridge keeps the Gram matrix of close control points positive definite.
        let ridge = 1e-10 * a.trace() / k as f64;
        for i in 0..k {
            a[(i, i)] += ridge;
        }
        let rhs = DMatrix::from_fn(m, 3, |row, c| {
            sums.px[row][c] - sums.p1[row] * template[row][c]
        });
        let b = self.phi.transpose() * rhs;
        a.cholesky().map(|ch| ch.solve(&b))
    }

    fn deform(&self, template: &[[f64; 3]], c: &DMatrix<f64>) -> Vec<[f64; 3]> {
        let v = &self.phi * c;
        template
            .iter()
            .enumerate()
            .map(|(m, y)| [y[0] + v[(m, 0)], y[1] + v[(m, 1)], y[2] + v[(m, 2)]])
            .collect()
    }
}

/// `σ² = (Σₙ Pt1ₙ‖xₙ‖² − 2 Σₘ (PX)ₘ·y'ₘ + Σₘ P1ₘ‖y'ₘ‖²) / (3 N_P)`.
fn variance(data: &[[f64; 3]], moved: &[[f64; 3]], sums: &PosteriorSums) -> Option<f64> {
    let np: f64 = sums.p1.iter().sum();
    if np <= 1e-12 {
        return None;
    }
    let xx: f64 = data.iter().zip(&sums.pt1).map(|(x, w)| w * norm2(*x)).sum();
    let xy: f64 = sums.px.iter().zip(moved).map(|(px, y)| dot(*px, *y)).sum();
    let yy: f64 = moved.iter().zip(&sums.p1).map(|(y, w)| w * norm2(*y)).sum();
    Some(((xx - 2.0 * xy + yy) / (3.0 * np)).max(0.0))
}

/// Deforms `template` onto `data` (both `[·, 3]`, mm, one frame), starting at variance
/// `sigma2` (mm², e.g. the rigid registration's final σ²).
pub fn nonrigid_cpd(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &NonRigidParams,
    sigma2: f64,
) -> Result<NonRigidResult, GeometryError> {
    params.check()?;
    check_points(template, "template")?;
    check_points(data, "data")?;
    if !(sigma2.is_finite() && sigma2 > 0.0) {
        return Err(GeometryError::InvalidParams(format!(
            "the starting sigma2 must be > 0, got {sigma2}"
        )));
    }
    let field = Field::new(template, params);
    let floor = sigma2 * SIGMA2_FLOOR_RELATIVE;
    let (mut moved, mut sigma2, mut iterations) = (template.to_vec(), sigma2, 0);
    while iterations < params.max_iterations {
        let sums = posterior_sums_moved(&moved, data, sigma2, params.w);
        let Some(c) = field.solve(template, &sums, params.lambda * sigma2) else {
            break;
        };
        let next = field.deform(template, &c);
        let next_sigma2 = variance(data, &next, &sums).unwrap_or(sigma2).max(floor);
        iterations += 1;
        let change = (next_sigma2 - sigma2).abs() / sigma2;
        moved = next;
        sigma2 = next_sigma2;
        if change <= params.tolerance || sigma2 <= floor {
            break;
        }
    }
    let sums = posterior_sums_moved(&moved, data, sigma2, params.w);
    Ok(NonRigidResult {
        moved,
        sigma2,
        sums,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(n: usize, radius: f64) -> Vec<[f64; 3]> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let t = golden * i as f64;
                [radius * r * t.cos(), radius * r * t.sin(), radius * z]
            })
            .collect()
    }

    /// Mean distance (mm, to first order) of `points` from the ellipsoid with semi-axes
    /// 26, 20, 20 mm.
    fn off_ellipsoid(points: &[[f64; 3]]) -> f64 {
        let r = |p: &[f64; 3]| {
            ((p[0] / 26.0).powi(2) + (p[1] / 20.0).powi(2) + (p[2] / 20.0).powi(2)).sqrt()
        };
        points
            .iter()
            .map(|p| 20.0 * (r(p) - 1.0).abs())
            .sum::<f64>()
            / points.len() as f64
    }

    #[test]
    fn a_stretched_sphere_is_reached_and_a_rigid_fit_is_not_disturbed() {
        let template = sphere(300, 20.0);
        // Data: a denser sphere stretched by 30% along x (no rigid motion explains it).
        let data: Vec<[f64; 3]> = sphere(500, 20.0)
            .into_iter()
            .map(|p| [1.3 * p[0], p[1], p[2]])
            .collect();
        let before = off_ellipsoid(&template);
        let r = nonrigid_cpd(&template, &data, &NonRigidParams::default(), 10.0).unwrap();
        let after = off_ellipsoid(&r.moved);
        assert!(
            after < 0.2 * before,
            "{before:.2} → {after:.2} mm, σ² {} after {}",
            r.sigma2,
            r.iterations
        );
        assert!(r.iterations >= 2);
        // Identical clouds: the template hardly moves.
        let same = nonrigid_cpd(&template, &template, &NonRigidParams::default(), 4.0).unwrap();
        let moved = same
            .moved
            .iter()
            .zip(&template)
            .map(|(a, b)| dist2(*a, *b).sqrt())
            .fold(0.0, f64::max);
        assert!(moved < 0.5, "moved {moved:.3} mm");
    }

    #[test]
    fn bad_settings_are_refused() {
        let p = sphere(10, 1.0);
        let params = NonRigidParams {
            beta: 0.0,
            ..NonRigidParams::default()
        };
        assert!(nonrigid_cpd(&p, &p, &params, 1.0).is_err());
        assert!(nonrigid_cpd(&p, &p, &NonRigidParams::default(), 0.0).is_err());
    }
}
