//! The main ways a model's shapes vary, as shapes: for PCA models the mean ± 3√λᵢ along the
//! first modes, for latent models the mean code ± 2 sd along the latent directions of
//! largest biomarker effect (from [`latent_effects`](super::latent_effects)).

use super::latent_effects::latent_effects;
use super::{ModelError, ShapeModel};
use crate::eval::Biomarkers;
use crate::mesh::Mesh;

/// Steps along a PCA mode, in sd.
pub const PCA_STEP_SD: f64 = 3.0;
/// Steps along a latent direction, in sd.
pub const LATENT_STEP_SD: f64 = 2.0;

/// One direction of variation drawn as three shapes.
#[derive(Debug, Clone)]
pub struct ShapeMode {
    /// What the direction is, e.g. `mode 1` or `cluster 0, direction 1`.
    pub label: String,
    /// The cluster (atlas) whose generator made the shapes.
    pub cluster: usize,
    /// Step from the mean, in sd of the standard-normal coordinates.
    pub step_sd: f64,
    /// Predicted change of volume (ml) and area (cm²) from mean to `plus`.
    pub effect: (f64, f64),
    /// The shapes at `−step`, `0` and `+step` (mm).
    pub shapes: [Mesh; 3],
}

/// Up to `count` modes per cluster (the draws of `seed` fit the latent directions); empty
/// for models that do not draw from a standard normal.
pub fn shape_modes<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    count: usize,
    seed: u64,
) -> Result<Vec<ShapeMode>, ModelError> {
    let Some(latent) = model.standard_latent() else {
        return Ok(Vec::new());
    };
    let mut modes = Vec::new();
    for (cluster, &dimension) in latent.dimensions.iter().enumerate() {
        let (directions, step_sd) = if latent.principal_modes {
            let axes = (0..count.min(dimension))
                .map(|i| {
                    (0..dimension)
                        .map(|j| f64::from(u8::from(i == j)))
                        .collect()
                })
                .collect::<Vec<Vec<f64>>>();
            (axes, PCA_STEP_SD)
        } else {
            let effects = latent_effects(model, cluster, dimension, seed)?;
            (effects.strongest_directions(count), LATENT_STEP_SD)
        };
        for (k, d) in directions.iter().enumerate() {
            let at = |t: f64| d.iter().map(|c| t * c).collect::<Vec<f64>>();
            let shapes = model.decode_standard(cluster, &[at(-step_sd), at(0.0), at(step_sd)])?;
            let [minus, mean, plus]: [Mesh; 3] = shapes
                .try_into()
                .map_err(|_| ModelError::Numerical("a mode needs three shapes".into()))?;
            let (b0, b1) = (Biomarkers::from_mesh(&mean)?, Biomarkers::from_mesh(&plus)?);
            let label = match (latent.principal_modes, latent.dimensions.len()) {
                (true, _) => format!("mode {}", k + 1),
                (false, 1) => format!("direction {}", k + 1),
                (false, _) => format!("cluster {cluster}, direction {}", k + 1),
            };
            modes.push(ShapeMode {
                label,
                cluster,
                step_sd,
                effect: (b1.volume_ml - b0.volume_ml, b1.area_cm2 - b0.area_cm2),
                shapes: [minus, mean, plus],
            });
        }
    }
    Ok(modes)
}
