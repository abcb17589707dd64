//! Biomarker-directed spread calibration: the generator's draws combine a shape's dimensions
//! as the training shapes do, but vary less in volume and area (a decoder averages away what
//! the latent code does not pin down, here mostly wall thickness). Instead of remapping the
//! draws on the principal modes (see [`super::calibration`], which restores the spread but
//! mixes the modes, so that draws combine lengths and widths no patient has), every draw is
//! moved along the direction in which the training shapes change with volume and area (their
//! regression on the two) until the draws' volume and area have the mean and covariance of the
//! training meshes' (the patients', not those of their normalised shapes, which the atlas
//! smoothing shrinks a little) and then the meshes' distribution of volume and of the shape
//! index `area / volume^(2/3)` (quantile maps, see [`super::marginal_map`]: an organ's volume
//! is skewed, an affine map's draws are not). What the draws do in every other direction
//! stays as decoded.
//!
//! Shapes are flattened atlas-domain vertex positions `[3·N_μ]` in mm; biomarkers are the
//! enclosed volume (ml, unsigned) and the surface area (cm²) of a shape with the atlas faces.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use serde::{Deserialize, Serialize};

use super::calibration::{WeightedShapes, transport_map};
use super::marginal_map::{MarginalMap, ShapeMaps};
use crate::mesh::Mesh;
use crate::mesh::measures::{area_cm2, volume_ml};

/// Number of calibrated biomarkers (volume, area).
pub const BIOMARKERS: usize = 2;

/// Moves drawn shapes along the training shapes' regression on volume and area.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BiomarkerCalibration {
    /// Change of the shape per unit of each biomarker, `[2][3·N_μ]` (mm per ml, mm per cm²):
    /// the training shapes' regression coefficients on (volume, area).
    pub directions: Vec<Vec<f32>>,
    /// Mean (volume ml, area cm²) of the uncalibrated draws.
    pub drawn_mean: [f64; BIOMARKERS],
    /// Mean (volume ml, area cm²) of the training shapes, which the draws are given.
    pub target_mean: [f64; BIOMARKERS],
    /// Map `[2][2]` (row-major rows) from a draw's biomarkers less `drawn_mean` to their
    /// calibrated deviation from `target_mean`: symmetric, the least movement that gives the
    /// draws the training shapes' biomarker covariance.
    pub map: [[f64; BIOMARKERS]; BIOMARKERS],
    /// Most moves along the directions per draw: a regression step lands near its target,
    /// not on it (1 in models stored before this field, which keep drawing as they did).
    #[serde(default = "first_order")]
    pub steps: u32,
    /// Per biomarker, the quantile map applied after `map` that gives the draws the
    /// training meshes' distribution, skew included (see [`super::marginal_map`]); `None` in
    /// models stored before it existed, whose targets stay affine.
    #[serde(default)]
    pub marginals: Option<Vec<MarginalMap>>,
    /// Quantile maps applied after `map` to the volume and to the shape index
    /// `area / volume^(2/3)`, the area target following from the two (see [`ShapeMaps`]);
    /// new calibrations have these instead of `marginals`, which mapped volume and area each
    /// on its own and bent their combination in the tails. `None` in models stored before.
    #[serde(default)]
    pub shape_maps: Option<ShapeMaps>,
}

/// Most moves per draw for new calibrations: on LV phantoms a few reach the targets to well
/// under 0.1 ml, where one move left the draws' volume sd up to 8% above the patients'.
pub const CALIBRATION_STEPS: u32 = 6;

/// A move stops once both biomarkers are this close to their targets (relative).
const TOLERANCE: f64 = 1e-5;

/// Times a step that would leave a shape farther from its targets is halved before the
/// moves stop.
const HALVINGS: i32 = 5;

fn first_order() -> u32 {
    1
}

/// The larger relative difference of a shape's biomarkers `b` from their targets.
fn miss(b: &[f64; BIOMARKERS], target: &[f64; BIOMARKERS]) -> f64 {
    (0..BIOMARKERS)
        .map(|k| ((target[k] - b[k]) / target[k].abs().max(f64::MIN_POSITIVE)).abs())
        .fold(0.0, f64::max)
}

/// (volume ml, area cm²) of a flattened shape `[3·N_μ]` with the atlas faces.
pub fn biomarkers(shape: &[f32], faces: &[[u32; 3]]) -> [f64; BIOMARKERS] {
    let vertices = shape
        .chunks_exact(3)
        .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
        .collect();
    mesh_biomarkers(&Mesh::new(vertices, faces.to_vec()))
}

/// (volume ml, unsigned, area cm²) of a mesh.
pub fn mesh_biomarkers(mesh: &Mesh) -> [f64; BIOMARKERS] {
    [volume_ml(mesh).abs(), area_cm2(mesh)]
}

/// Weighted mean and covariance of biomarker rows, the covariance divided by the total
/// weight, with the factor that unbiases it (n/(n−1) for equal weights).
fn moments(rows: &[[f64; BIOMARKERS]], w: &[f64]) -> (DVector<f64>, DMatrix<f64>, f64) {
    let total: f64 = w.iter().sum();
    let mean = rows
        .iter()
        .zip(w)
        .fold(DVector::zeros(BIOMARKERS), |s, (r, w)| {
            s + DVector::from_column_slice(r) * *w
        })
        / total;
    let square: f64 = w.iter().map(|w| w * w).sum();
    let unbias = total / (total - square / total);
    let cov = rows
        .iter()
        .zip(w)
        .fold(DMatrix::zeros(BIOMARKERS, BIOMARKERS), |s, (r, w)| {
            let d = DVector::from_column_slice(r) - &mean;
            s + &d * d.transpose() * *w
        })
        / total;
    (mean, cov, unbias)
}

impl BiomarkerCalibration {
    /// Fits the calibration from the training shapes (each with a weight, `None`: equal),
    /// the biomarkers of their meshes (the targets; the shapes' own when `measured` is not
    /// one row per shape), uncalibrated draws and the atlas faces. `None` when there are too
    /// few shapes or draws, a draw has another width than the shapes, or volume and area do
    /// not vary independently in the training shapes (their covariance is singular).
    pub fn fit(
        training: &[Vec<f32>],
        weights: Option<&[f32]>,
        measured: &[[f64; BIOMARKERS]],
        drawn: &[Vec<f32>],
        faces: &[[u32; 3]],
    ) -> Option<Self> {
        let dim = training.first()?.len();
        if drawn.iter().any(|d| d.len() != dim) {
            return None;
        }
        let drawn_rows: Vec<_> = drawn.iter().map(|x| biomarkers(x, faces)).collect();
        Self::fit_to_drawn_biomarkers(training, weights, measured, &drawn_rows, faces)
    }

    /// [`Self::fit`] from the (volume ml, area cm²) of the uncalibrated draws instead of the
    /// draws themselves.
    pub fn fit_to_drawn_biomarkers(
        training: &[Vec<f32>],
        weights: Option<&[f32]>,
        measured: &[[f64; BIOMARKERS]],
        drawn_rows: &[[f64; BIOMARKERS]],
        faces: &[[u32; 3]],
    ) -> Option<Self> {
        if drawn_rows.len() < 3 {
            return None;
        }
        let WeightedShapes {
            w,
            total,
            mean: x_mean,
        } = WeightedShapes::of(training, weights)?;
        let dim = x_mean.len();
        let trained: Vec<_> = training.iter().map(|x| biomarkers(x, faces)).collect();
        let (shape_mean, biased_cov, unbias) = moments(&trained, &w);
        if !unbias.is_finite() {
            return None;
        }
        let inverse = biased_cov.clone().try_inverse()?;
        let targets = if measured.len() == training.len() {
            measured
        } else {
            &trained
        };
        let (target_mean, target_cov, _) = moments(targets, &w);
        // Regression coefficients: the cross-covariance of coordinates and biomarkers
        // `[3·N_μ][2]` times the inverse biomarker covariance (both divided by the total weight).
        let directions: Vec<Vec<f32>> = (0..BIOMARKERS)
            .map(|b| {
                (0..dim)
                    .map(|j| {
                        let cross = |k: usize| {
                            training
                                .iter()
                                .zip(&trained)
                                .zip(&w)
                                .map(|((x, r), w)| {
                                    w * (f64::from(x[j]) - x_mean[j]) * (r[k] - shape_mean[k])
                                })
                                .sum::<f64>()
                                / total
                        };
                        let row = (0..BIOMARKERS).map(|k| cross(k) * inverse[(k, b)]);
                        row.sum::<f64>() as f32
                    })
                    .collect()
            })
            .collect();
        let (drawn_mean, drawn_cov, drawn_unbias) =
            moments(drawn_rows, &vec![1.0; drawn_rows.len()]);
        let map = transport_map(drawn_cov * drawn_unbias, &(target_cov * unbias));
        let mut calibration = Self {
            directions,
            drawn_mean: [drawn_mean[0], drawn_mean[1]],
            target_mean: [target_mean[0], target_mean[1]],
            map: [[map[(0, 0)], map[(0, 1)]], [map[(1, 0)], map[(1, 1)]]],
            steps: CALIBRATION_STEPS,
            marginals: None,
            shape_maps: None,
        };
        let affine: Vec<_> = drawn_rows.iter().map(|b| calibration.target(b)).collect();
        calibration.shape_maps = ShapeMaps::fit(&affine, targets, &w);
        Some(calibration)
    }

    /// Moves a drawn shape along the directions so that its biomarkers `b` become
    /// `target_mean + map · (b − drawn_mean)`. The first move is by the difference (what
    /// models stored before `steps` did, once); the directions are a regression, not an exact
    /// inverse, so up to `steps − 1` Newton moves follow. A shape of another width is left
    /// alone.
    pub fn apply(&self, shape: &mut [f32], faces: &[[u32; 3]]) {
        if self.directions.iter().any(|d| d.len() != shape.len()) {
            return;
        }
        let drawn = biomarkers(shape, faces);
        let target = self.target(&drawn);
        self.move_by(shape, [target[0] - drawn[0], target[1] - drawn[1]]);
        if self.steps <= 1 {
            return;
        }
        let mut b = biomarkers(shape, faces);
        for _ in 1..self.steps {
            match self.newton_move(shape, faces, &target, &b) {
                Some(moved) => b = moved,
                None => break,
            }
        }
    }

    /// The calibrated biomarkers of a draw whose uncalibrated ones are `b`:
    /// `target_mean + map · (b − drawn_mean)` (ml, cm²), then through each biomarker's
    /// quantile map when the calibration has them.
    pub fn target(&self, b: &[f64; BIOMARKERS]) -> [f64; BIOMARKERS] {
        let deviation = [b[0] - self.drawn_mean[0], b[1] - self.drawn_mean[1]];
        let affine: [f64; BIOMARKERS] = std::array::from_fn(|k| {
            self.target_mean[k] + self.map[k][0] * deviation[0] + self.map[k][1] * deviation[1]
        });
        if let Some(maps) = &self.shape_maps {
            return maps.apply(affine).unwrap_or(affine);
        }
        match &self.marginals {
            Some(maps) if maps.len() == BIOMARKERS => {
                std::array::from_fn(|k| maps[k].apply(affine[k]))
            }
            _ => affine,
        }
    }

    /// Moves a shape whose biomarkers are `b` by the change along the directions that their
    /// measured effect on its volume and area says meets `target`, halved while that would
    /// leave it farther away; its new biomarkers. None when the shape is already on target
    /// or no move brings it nearer.
    fn newton_move(
        &self,
        shape: &mut [f32],
        faces: &[[u32; 3]],
        target: &[f64; BIOMARKERS],
        b: &[f64; BIOMARKERS],
    ) -> Option<[f64; BIOMARKERS]> {
        let before = miss(b, target);
        if before <= TOLERANCE {
            return None;
        }
        let inverse = self.effect(shape, faces, b, target).try_inverse()?;
        let change = inverse * Vector2::new(target[0] - b[0], target[1] - b[1]);
        let previous = shape.to_vec();
        let nearer = (0..HALVINGS).find_map(|halving| {
            let factor = 0.5_f64.powi(halving);
            shape.copy_from_slice(&previous);
            self.move_by(shape, [factor * change[0], factor * change[1]]);
            let moved = biomarkers(shape, faces);
            (miss(&moved, target) < before).then_some(moved)
        });
        if nearer.is_none() {
            shape.copy_from_slice(&previous);
        }
        nearer
    }

    /// The change of (volume, area) per unit moved along each direction at `shape`, whose
    /// biomarkers are `b` (finite differences, a thousandth of each target's size).
    fn effect(
        &self,
        shape: &[f32],
        faces: &[[u32; 3]],
        b: &[f64; BIOMARKERS],
        target: &[f64; BIOMARKERS],
    ) -> Matrix2<f64> {
        let mut effect = Matrix2::zeros();
        for m in 0..BIOMARKERS {
            let h = 1e-3 * target[m].abs().max(f64::MIN_POSITIVE);
            let mut trial = shape.to_vec();
            let mut change = [0.0; BIOMARKERS];
            change[m] = h;
            self.move_by(&mut trial, change);
            let moved = biomarkers(&trial, faces);
            for k in 0..BIOMARKERS {
                effect[(k, m)] = (moved[k] - b[k]) / h;
            }
        }
        effect
    }

    /// Adds `change[k]` units of each biomarker's direction to a shape.
    fn move_by(&self, shape: &mut [f32], change: [f64; BIOMARKERS]) {
        for (j, x) in shape.iter_mut().enumerate() {
            let moved: f64 = (0..BIOMARKERS)
                .map(|k| change[k] * f64::from(self.directions[k][j]))
                .sum();
            *x = (f64::from(*x) + moved) as f32;
        }
    }
}

#[cfg(test)]
#[path = "biomarker_calibration_tests.rs"]
mod tests;
