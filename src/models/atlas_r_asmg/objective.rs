//! The refinement loss of one shape, `L_Ref = w_cd·CD(g_k, h'_k) + w_lap·E(h'_k)` (thesis
//! eqs. 5.8–5.9), as the graph network's refinement asks for it: value and gradient with
//! respect to the unsmoothed normalised shape `h_k`.
//!
//! `h'_k` is the smoothed `h_k` (displacement smoothing by default: `h' = X_μ + A⁻¹(h − X_μ)`,
//! `A = I + γL`; positions: `h' = A⁻¹h`). Both are affine in `h` with the symmetric `A⁻¹`, so
//! `∂L/∂h = A⁻¹ ∂L/∂h'`: one more solve with the factorisation the smoothing already has.
//!
//! Positions enter in Ψ's units (mm divided by the scale Ψ was trained with, the training
//! vertices' RMS radius), so that the terms weigh against `L_Ψ` the same whatever the
//! organ's size; with the thesis's weights of 1 they are of the order of `L_Ψ`.

use super::losses::{chamfer_squared, laplacian_energy};
use crate::geometry::kdtree::PointCloudIndex;
use crate::mesh::adjacency::Adjacency;
use crate::models::ModelError;
use crate::models::asmg::{ScoreMoments, Smoother, Temperature};
use crate::nn::{NnError, RefineObjective, RefineTerms};

/// One training shape's target: its vertices (mm, model frame) and their index.
pub struct Target {
    points: Vec<[f64; 3]>,
    index: PointCloudIndex,
}

impl Target {
    /// The target of a shape with these vertices.
    pub fn new(points: Vec<[f64; 3]>) -> Result<Self, ModelError> {
        let index = PointCloudIndex::new(&points)?;
        Ok(Self { points, index })
    }
}

/// The refinement loss of every training shape on the current atlas.
pub struct Refinement<'a> {
    /// Smoothing on the atlas connectivity (exact solve).
    pub smoother: &'a Smoother,
    /// The atlas connectivity (for the Laplacian term).
    pub adjacency: &'a Adjacency,
    /// The current atlas positions, `[N_μ, 3]` mm.
    pub atlas: &'a [[f64; 3]],
    /// Each training shape's target.
    pub targets: &'a [Target],
    /// The attention temperature.
    pub temperature: Temperature,
    /// Weight of the Chamfer term.
    pub w_cd: f64,
    /// Weight of the Laplacian term.
    pub w_lap: f64,
    /// Ψ's position scale, mm (positions are divided by it).
    pub scale_mm: f64,
}

impl Refinement<'_> {
    /// The weighted terms of shape `k` and `∂L/∂h` (`[N_μ, 3]`, per mm).
    pub fn terms(
        &self,
        k: usize,
        h: &[[f64; 3]],
    ) -> Result<(RefineTerms, Vec<[f64; 3]>), ModelError> {
        let target = self.targets.get(k).ok_or_else(|| {
            ModelError::InvalidInput(format!("no refinement target for shape {k}"))
        })?;
        let smoothed = self.smoother.smooth(h, self.atlas)?;
        let (cd, g_cd) = chamfer_squared(&target.points, &target.index, &smoothed)?;
        let (lap, g_lap) = laplacian_energy(self.adjacency, &smoothed)?;
        // In Ψ's units: values scale by 1/s², gradients per mm by 1/s² as well.
        let unit = 1.0 / (self.scale_mm * self.scale_mm);
        let g_smoothed: Vec<[f64; 3]> = g_cd
            .iter()
            .zip(&g_lap)
            .map(|(a, b)| std::array::from_fn(|d| unit * (self.w_cd * a[d] + self.w_lap * b[d])))
            .collect();
        let gradient = self.smoother.pull_back(&g_smoothed)?;
        Ok((
            RefineTerms {
                chamfer: self.w_cd * cd * unit,
                laplacian: self.w_lap * lap * unit,
            },
            gradient,
        ))
    }
}

impl RefineObjective for Refinement<'_> {
    fn lambda(&self, score_variance: f64) -> f64 {
        let moments = ScoreMoments {
            count: 1,
            mean: 0.0,
            variance: score_variance,
        };
        self.temperature.lambda(&moments).unwrap_or(0.0)
    }

    fn shape(&mut self, k: usize, h: &[[f64; 3]]) -> Result<(RefineTerms, Vec<[f64; 3]>), NnError> {
        self.terms(k, h)
            .map_err(|e| NnError::Objective(e.to_string()))
    }
}
