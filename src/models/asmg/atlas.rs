//! Atlas update from the smoothed shapes (thesis eqs. 4.6–4.7, app. A.2; SPEC §2.5, §2.9).
//!
//! The atlas positions `X_μ` (`[N_μ, 3]`, mm; its connectivity is fixed) minimise
//! `½ Σ_k ‖h'_k − X_μ‖² + (γ_μ/2)·Σ_edges ‖x_μj − x_μq‖²`, i.e. solve
//! `(K·I + γ_μ L) X_μ = Σ_k h'_k`, with `γ_μ = N_μ / max_j deg_j` by default. Eq. 4.7 is the
//! Jacobi iteration of the same system. As with the shapes, smoothing the positions shrinks
//! the atlas (the effective weight is `γ_μ / K`, large for few shapes), so the update can
//! smooth the displacement instead: `X_μ + (K·I + γ_μ L)⁻¹ Σ_k (h'_k − X_μ)`. The new atlas
//! is damped, `X_μ ← (1 − α)·X_μ + α·update`, because the undamped loop oscillates
//! (SPEC §2.9).

use super::laplacian::{LaplacianSolver, checked_adjacency, jacobi};
use super::smoothing::Smoothing;
use crate::mesh::Mesh;
use crate::mesh::adjacency::Adjacency;
use crate::models::ModelError;

/// Default damping α of the atlas update (1: no damping).
pub const DEFAULT_DAMPING: f64 = 0.5;

/// Settings of the atlas update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AtlasUpdateParams {
    /// Weight `γ_μ ≥ 0` of the atlas Laplacian (default [`default_gamma_mu`]).
    pub gamma_mu: Option<f64>,
    /// Damping α in (0, 1] (1: take the update as it is).
    pub damping: f64,
    /// Smooth the atlas positions (thesis eq. 4.7) or the displacement towards the shapes.
    pub target: Smoothing,
}

impl Default for AtlasUpdateParams {
    fn default() -> Self {
        Self {
            gamma_mu: None,
            damping: DEFAULT_DAMPING,
            target: Smoothing::Displacement,
        }
    }
}

/// The thesis's atlas smoothing weight, `γ_μ = N_μ / max_j deg_j` (1 for a graph without
/// edges, where the weight does not matter).
pub fn default_gamma_mu(adjacency: &Adjacency) -> f64 {
    let n = adjacency.vertex_count();
    let max_degree = (0..n).map(|v| adjacency.degree(v)).max().unwrap_or(0);
    if max_degree == 0 {
        1.0
    } else {
        n as f64 / max_degree as f64
    }
}

/// Closed-form atlas updates for `K` shapes on one atlas connectivity; `(K·I + γ_μ L)` is
/// factored once here.
#[derive(Debug, Clone)]
pub struct AtlasUpdater {
    adjacency: Adjacency,
    shape_count: usize,
    params: AtlasUpdateParams,
    solver: LaplacianSolver,
}

impl AtlasUpdater {
    /// Prepares updates of the connectivity of `atlas` from `shape_count ≥ 1` smoothed
    /// shapes.
    pub fn new(
        atlas: &Mesh,
        shape_count: usize,
        params: &AtlasUpdateParams,
    ) -> Result<Self, ModelError> {
        check_damping(params.damping)?;
        if shape_count == 0 {
            return Err(ModelError::TooFewMeshes {
                required: 1,
                found: 0,
            });
        }
        let adjacency = checked_adjacency(atlas)?;
        let gamma_mu = params
            .gamma_mu
            .unwrap_or_else(|| default_gamma_mu(&adjacency));
        let gamma_mu = check_gamma_mu(gamma_mu)?;
        let solver = LaplacianSolver::new(&adjacency, shape_count as f64, gamma_mu)?;
        Ok(Self {
            adjacency,
            shape_count,
            params: *params,
            solver,
        })
    }

    /// The weight `γ_μ` in use.
    pub fn gamma_mu(&self) -> f64 {
        self.solver.gamma()
    }

    /// The number of shapes `K` the system was built for.
    pub fn shape_count(&self) -> usize {
        self.shape_count
    }

    /// The atlas connectivity.
    pub fn adjacency(&self) -> &Adjacency {
        &self.adjacency
    }

    /// The closed-form positions `(K·I + γ_μ L)⁻¹ Σ_k h'_k` (`[N_μ, 3]`, mm; eq. A.7) from
    /// the `K` smoothed shapes (each `[N_μ, 3]`, mm), whatever the configured target.
    pub fn solve(&self, smoothed: &[Vec<[f64; 3]>]) -> Result<Vec<[f64; 3]>, ModelError> {
        self.check_count(smoothed)?;
        self.solver
            .solve(&sum_shapes(smoothed, self.adjacency.vertex_count())?)
    }

    /// The undamped update of the atlas at `current` (`[N_μ, 3]`, mm) for the configured
    /// target: [`AtlasUpdater::solve`] for positions, or
    /// `X_μ + (K·I + γ_μ L)⁻¹ Σ_k (h'_k − X_μ)` for the displacement.
    pub fn update(
        &self,
        current: &[[f64; 3]],
        smoothed: &[Vec<[f64; 3]>],
    ) -> Result<Vec<[f64; 3]>, ModelError> {
        self.check_count(smoothed)?;
        let n = self.adjacency.vertex_count();
        if current.len() != n {
            return Err(ModelError::InvalidInput(format!(
                "the atlas update was prepared for {n} vertices but the atlas has {}",
                current.len()
            )));
        }
        match self.params.target {
            Smoothing::Positions => self.solve(smoothed),
            Smoothing::Displacement => {
                let k = smoothed.len() as f64;
                let rhs: Vec<[f64; 3]> = sum_shapes(smoothed, n)?
                    .iter()
                    .zip(current)
                    .map(|(s, x)| std::array::from_fn(|d| s[d] - k * x[d]))
                    .collect();
                let displacement = self.solver.solve(&rhs)?;
                Ok(current
                    .iter()
                    .zip(&displacement)
                    .map(|(x, u)| std::array::from_fn(|d| x[d] + u[d]))
                    .collect())
            }
        }
    }

    /// The damped new atlas positions, `(1 − α)·current + α·update`.
    pub fn step(
        &self,
        current: &[[f64; 3]],
        smoothed: &[Vec<[f64; 3]>],
    ) -> Result<Vec<[f64; 3]>, ModelError> {
        damp(
            current,
            &self.update(current, smoothed)?,
            self.params.damping,
        )
    }

    fn check_count(&self, smoothed: &[Vec<[f64; 3]>]) -> Result<(), ModelError> {
        if smoothed.len() == self.shape_count {
            Ok(())
        } else {
            Err(ModelError::InvalidInput(format!(
                "the atlas update was prepared for {} shapes but got {}",
                self.shape_count,
                smoothed.len()
            )))
        }
    }
}

/// `Σ_k h'_k` (`[n_vertices, 3]`, mm); every shape must have `n_vertices` rows.
pub fn sum_shapes(
    smoothed: &[Vec<[f64; 3]>],
    n_vertices: usize,
) -> Result<Vec<[f64; 3]>, ModelError> {
    let mut sum = vec![[0.0; 3]; n_vertices];
    for (k, shape) in smoothed.iter().enumerate() {
        if shape.len() != n_vertices {
            return Err(ModelError::InvalidInput(format!(
                "smoothed shape {k} has {} vertices, the atlas {n_vertices}",
                shape.len()
            )));
        }
        for (s, p) in sum.iter_mut().zip(shape) {
            *s = [s[0] + p[0], s[1] + p[1], s[2] + p[2]];
        }
    }
    Ok(sum)
}

/// Eq. 4.7 by Jacobi sweeps from the current atlas `start` (`[N_μ, 3]`, mm):
/// `x_μj ← (Σ_k h'_kj + γ_μ Σ_{q∈N(j)} x_μq) / (K + γ_μ·deg_j)`, at most `steps` sweeps or
/// until a sweep moves the vertices by less than `tolerance_mm` on average.
pub fn iterative_update(
    adjacency: &Adjacency,
    smoothed: &[Vec<[f64; 3]>],
    gamma_mu: f64,
    start: &[[f64; 3]],
    steps: usize,
    tolerance_mm: f64,
) -> Result<(Vec<[f64; 3]>, usize), ModelError> {
    if smoothed.is_empty() {
        return Err(ModelError::TooFewMeshes {
            required: 1,
            found: 0,
        });
    }
    let gamma_mu = check_gamma_mu(gamma_mu)?;
    let sum = sum_shapes(smoothed, adjacency.vertex_count())?;
    let system = (smoothed.len() as f64, gamma_mu);
    jacobi(adjacency, system, &sum, start, steps, tolerance_mm)
}

/// `(1 − α)·old + α·update` for `0 < α ≤ 1` (mm).
pub fn damp(
    old: &[[f64; 3]],
    update: &[[f64; 3]],
    damping: f64,
) -> Result<Vec<[f64; 3]>, ModelError> {
    check_damping(damping)?;
    if old.len() != update.len() {
        return Err(ModelError::InvalidInput(format!(
            "damping {} atlas vertices towards {} updated ones",
            old.len(),
            update.len()
        )));
    }
    Ok(old
        .iter()
        .zip(update)
        .map(|(o, u)| std::array::from_fn(|d| (1.0 - damping) * o[d] + damping * u[d]))
        .collect())
}

/// One damped closed-form update of `atlas` from its `K` smoothed shapes: the atlas with new
/// positions and the same faces. Prefer an [`AtlasUpdater`] when updating repeatedly.
pub fn update_atlas(
    atlas: &Mesh,
    smoothed: &[Vec<[f64; 3]>],
    params: &AtlasUpdateParams,
) -> Result<Mesh, ModelError> {
    let updater = AtlasUpdater::new(atlas, smoothed.len(), params)?;
    Ok(Mesh::new(
        updater.step(&atlas.vertices, smoothed)?,
        atlas.faces.clone(),
    ))
}

pub(crate) fn check_damping(damping: f64) -> Result<f64, ModelError> {
    if damping.is_finite() && damping > 0.0 && damping <= 1.0 {
        Ok(damping)
    } else {
        Err(ModelError::invalid(
            "damping",
            format!("must be in (0, 1], got {damping}"),
        ))
    }
}

fn check_gamma_mu(gamma_mu: f64) -> Result<f64, ModelError> {
    if gamma_mu.is_finite() && gamma_mu >= 0.0 {
        Ok(gamma_mu)
    } else {
        Err(ModelError::invalid(
            "gamma_mu",
            format!("must be finite and >= 0, got {gamma_mu}"),
        ))
    }
}

#[cfg(test)]
#[path = "atlas_tests.rs"]
mod tests;
