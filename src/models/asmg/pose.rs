//! The generator's frame: the shapes a generator learns from are aligned to their mean by
//! rigid generalised Procrustes (with `procrustes`), so that no latent direction is spent on
//! the pose the pre-alignment left; a new shape is aligned to that mean before it is encoded
//! and its reconstruction turned back to the shape's pose.

use super::model::{AsmgModel, flatten_f32, nn_error};
use crate::geometry::gpa::generalised_procrustes;
use crate::geometry::procrustes::weighted_procrustes;
use crate::geometry::transform::RigidTransform;
use crate::mesh::Mesh;
use crate::models::ModelError;

/// The shapes a generator learns from.
pub(super) struct GeneratorShapes {
    /// Flattened, mm.
    pub flat: Vec<Vec<f32>>,
    /// The mean they were aligned to, `[N_μ, 3]` mm (with `procrustes`).
    pub procrustes_mean: Option<Vec<[f64; 3]>>,
}

/// The shapes a generator learns from: aligned to their mean by rigid generalised
/// Procrustes first when `procrustes` (and there are two or more).
pub(super) fn generator_shapes(
    shapes: &[Vec<[f64; 3]>],
    procrustes: bool,
) -> Result<GeneratorShapes, ModelError> {
    if !procrustes || shapes.len() < 2 {
        return Ok(GeneratorShapes {
            flat: shapes.iter().map(|h| flatten_f32(h)).collect(),
            procrustes_mean: None,
        });
    }
    let gpa = generalised_procrustes(shapes)?;
    let flat = shapes
        .iter()
        .zip(&gpa.transforms)
        .map(|(h, pose)| flatten_f32(&pose.apply_all(h)))
        .collect();
    Ok(GeneratorShapes {
        flat,
        procrustes_mean: Some(gpa.mean),
    })
}

impl AsmgModel {
    /// The generator's reconstruction (encoder mean, decoder) of a normalised shape
    /// (`[N_μ, 3]`, mm): a mesh with the atlas connectivity, in the shape's pose.
    pub fn regenerate(&self, normalised: &[[f64; 3]]) -> Result<Mesh, ModelError> {
        let vertices = self
            .regenerate_all(&[normalised.to_vec()])?
            .pop()
            .ok_or_else(|| ModelError::Numerical("the generator returned nothing".to_owned()))?;
        Ok(Mesh::new(vertices, self.atlas.faces.clone()))
    }

    /// The generator's reconstructions of many normalised shapes (`[N_μ, 3]` mm each), each
    /// in its shape's pose.
    pub fn regenerate_all(
        &self,
        shapes: &[Vec<[f64; 3]>],
    ) -> Result<Vec<Vec<[f64; 3]>>, ModelError> {
        let nets = self.networks()?;
        let poses = shapes
            .iter()
            .map(|h| self.pose_of(h))
            .collect::<Result<Vec<_>, _>>()?;
        let flat: Vec<Vec<f32>> = shapes
            .iter()
            .zip(&poses)
            .map(|(h, pose)| match pose {
                Some(p) => flatten_f32(&p.apply_all(h)),
                None => flatten_f32(h),
            })
            .collect();
        let out = nets.generator.reconstruct(&flat).map_err(nn_error)?;
        Ok(out
            .iter()
            .zip(&poses)
            .map(|(s, pose)| {
                let vertices = self.to_mesh(s).vertices;
                match pose {
                    Some(p) => p.inverse().apply_all(&vertices),
                    None => vertices,
                }
            })
            .collect())
    }

    /// The rigid pose that takes a normalised shape (`[N_μ, 3]`, mm) onto the mean the
    /// generator learned on (none for models fitted without `procrustes`).
    fn pose_of(&self, normalised: &[[f64; 3]]) -> Result<Option<RigidTransform>, ModelError> {
        self.procrustes_mean
            .as_ref()
            .map(|mean| weighted_procrustes(normalised, mean, None, false))
            .transpose()
            .map_err(ModelError::from)
    }
}
