//! The initial atlas of Algorithm 1 (SPEC §2.5): a training mesh near the requested
//! resolution, a mesh given by the user, or an icosphere of the shapes' mean size.

use super::icosphere::{icosphere, icosphere_level_for};
use super::laplacian::checked_adjacency;
use crate::mesh::Mesh;
use crate::models::ModelError;

/// Default atlas resolution `N_μ` (thesis fig. 4.11: about 1,000 vertices was best).
pub const DEFAULT_ATLAS_VERTICES: usize = 1000;

/// How the atlas starts.
#[derive(Debug, Clone, PartialEq)]
pub enum AtlasInit {
    /// The training mesh whose vertex count is closest to `target_vertices` (the first one
    /// on a tie).
    Auto {
        /// Requested `N_μ`.
        target_vertices: usize,
    },
    /// This mesh (mm, in the frame of the aligned training meshes).
    Given(Mesh),
    /// The icosphere whose vertex count is closest to `target_vertices`, centred at the
    /// mean centroid of the training meshes and scaled to their mean RMS radius.
    Icosphere {
        /// Requested `N_μ`.
        target_vertices: usize,
    },
}

impl Default for AtlasInit {
    fn default() -> Self {
        Self::Auto {
            target_vertices: DEFAULT_ATLAS_VERTICES,
        }
    }
}

/// The initial atlas for `choice` and the (aligned) training meshes.
pub fn initial_atlas(choice: &AtlasInit, training: &[Mesh]) -> Result<Mesh, ModelError> {
    let atlas = match choice {
        AtlasInit::Auto { target_vertices } => training
            .iter()
            .min_by_key(|m| m.vertex_count().abs_diff(*target_vertices))
            .cloned()
            .ok_or(ModelError::TooFewMeshes {
                required: 1,
                found: 0,
            })?,
        AtlasInit::Given(mesh) => mesh.clone(),
        AtlasInit::Icosphere { target_vertices } => {
            let (centre, radius) = mean_centre_and_radius(training)?;
            let mut sphere = icosphere(icosphere_level_for(*target_vertices))?;
            for p in &mut sphere.vertices {
                *p = std::array::from_fn(|d| centre[d] + radius * p[d]);
            }
            sphere
        }
    };
    check_atlas(&atlas)?;
    Ok(atlas)
}

/// Centroid of a mesh's vertices and their RMS distance to it (mm).
pub fn centroid_and_rms_radius(mesh: &Mesh) -> Option<([f64; 3], f64)> {
    let n = mesh.vertex_count();
    if n == 0 {
        return None;
    }
    let mut c = [0.0; 3];
    for p in &mesh.vertices {
        for d in 0..3 {
            c[d] += p[d] / n as f64;
        }
    }
    let sq: f64 = mesh
        .vertices
        .iter()
        .map(|p| (0..3).map(|d| (p[d] - c[d]).powi(2)).sum::<f64>())
        .sum();
    Some((c, (sq / n as f64).sqrt()))
}

fn mean_centre_and_radius(training: &[Mesh]) -> Result<([f64; 3], f64), ModelError> {
    let stats: Vec<([f64; 3], f64)> = training
        .iter()
        .filter_map(centroid_and_rms_radius)
        .collect();
    if stats.is_empty() {
        return Err(ModelError::TooFewMeshes {
            required: 1,
            found: 0,
        });
    }
    let k = stats.len() as f64;
    let mut centre = [0.0; 3];
    let mut radius = 0.0;
    for (c, r) in &stats {
        for d in 0..3 {
            centre[d] += c[d] / k;
        }
        radius += r / k;
    }
    Ok((centre, radius))
}

fn check_atlas(atlas: &Mesh) -> Result<(), ModelError> {
    if atlas.vertex_count() < 4 || atlas.face_count() == 0 {
        return Err(ModelError::invalid(
            "atlas",
            format!(
                "the atlas needs at least 4 vertices and a face, got {} and {}",
                atlas.vertex_count(),
                atlas.face_count()
            ),
        ));
    }
    if atlas.vertices.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ModelError::invalid(
            "atlas",
            "vertex positions must be finite",
        ));
    }
    checked_adjacency(atlas).map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::cube;
    use crate::mesh::phantom::{Family, generate};

    #[test]
    fn auto_takes_the_mesh_nearest_the_target() {
        let meshes: Vec<Mesh> = generate(Family::Lv, 4, 9)
            .into_iter()
            .map(|p| p.mesh)
            .collect();
        let counts: Vec<usize> = meshes.iter().map(Mesh::vertex_count).collect();
        let target = counts[2] + 1;
        let atlas = initial_atlas(
            &AtlasInit::Auto {
                target_vertices: target,
            },
            &meshes,
        )
        .unwrap();
        let best = counts.iter().map(|c| c.abs_diff(target)).min().unwrap();
        assert_eq!(atlas.vertex_count().abs_diff(target), best);
        assert!(meshes.contains(&atlas));
        assert!(initial_atlas(&AtlasInit::default(), &[]).is_err());
    }

    #[test]
    fn icosphere_takes_the_mean_size_and_centre() {
        // A 10 mm cube (RMS radius 5√3 mm) and a copy doubled and shifted: the icosphere
        // sits at the mean centre with the mean radius, 1.5 × 5√3 mm.
        let a = cube();
        let mut b = cube();
        for p in &mut b.vertices {
            *p = [2.0 * p[0] + 10.0, 2.0 * p[1], 2.0 * p[2]];
        }
        let (ca, ra) = centroid_and_rms_radius(&a).unwrap();
        let (cb, rb) = centroid_and_rms_radius(&b).unwrap();
        assert!((ra - 5.0 * 3f64.sqrt()).abs() < 1e-12);
        assert!((rb - 2.0 * ra).abs() < 1e-12);
        let choice = AtlasInit::Icosphere {
            target_vertices: 150,
        };
        let sphere = initial_atlas(&choice, &[a, b]).unwrap();
        assert_eq!(sphere.vertex_count(), 162);
        let (c, r) = centroid_and_rms_radius(&sphere).unwrap();
        for d in 0..3 {
            assert!((c[d] - (ca[d] + cb[d]) / 2.0).abs() < 1e-9);
        }
        assert!((r - 1.5 * ra).abs() < 1e-9);
    }

    #[test]
    fn a_given_atlas_is_checked() {
        let good = initial_atlas(&AtlasInit::Given(cube()), &[]).unwrap();
        assert_eq!(good, cube());
        let broken = Mesh::new(vec![[0.0; 3]; 4], vec![[0, 1, 9]]);
        assert!(initial_atlas(&AtlasInit::Given(broken), &[]).is_err());
        let empty = Mesh::default();
        assert!(initial_atlas(&AtlasInit::Given(empty), &[]).is_err());
    }
}
