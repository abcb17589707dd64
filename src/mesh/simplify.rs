//! Simplification by quadric edge collapse (meshoptimizer), keeping the surface closed.
//!
//! Vertices are moved to the quadric-optimal positions while collapsing, which keeps the
//! enclosed volume close to the original. The result is checked: a collapse sequence that
//! would open, pinch or split the surface is refused, and a milder target is tried.

use super::manifold::{bowtie_vertices, check_edges};
use super::topology::{connected_components, euler_characteristic};
use super::{Mesh, MeshError};
use std::collections::HashMap;

/// Error bound handed to the simplifier, relative to the mesh extent: large enough that the
/// vertex target, not the error, decides where it stops.
const MAX_RELATIVE_ERROR: f32 = 1.0;
/// Triangle targets tried in turn, as multiples of the asked one, until a result is closed
/// and manifold with the input's topology (a different stopping point avoids the collapse
/// that pinched the surface).
const TARGET_FACTORS: [f64; 6] = [1.0, 0.98, 1.02, 1.05, 1.1, 1.25];
/// Fewest vertices a simplified surface may have.
pub const MIN_TARGET_VERTICES: usize = 8;

/// A simplified mesh and what it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Simplified {
    /// The simplified surface, same units and orientation as the input.
    pub mesh: Mesh,
    /// Vertices of the input.
    pub original_vertex_count: usize,
    /// Triangles of the input.
    pub original_face_count: usize,
}

/// Reduces `mesh` to about `target_vertices` vertices (never more than it has), keeping a
/// closed, manifold input closed and manifold with the same Euler characteristic.
///
/// The input should be welded (one vertex per position), as from
/// [`crate::mesh::validate::validate`].
pub fn simplify(mesh: &Mesh, target_vertices: usize) -> Result<Simplified, MeshError> {
    if target_vertices < MIN_TARGET_VERTICES {
        return Err(MeshError::Unsupported {
            what: format!("simplifying to {target_vertices} vertices"),
            fix: format!("ask for at least {MIN_TARGET_VERTICES} vertices"),
        });
    }
    let original = Simplified {
        mesh: mesh.clone(),
        original_vertex_count: mesh.vertices.len(),
        original_face_count: mesh.faces.len(),
    };
    if mesh.vertices.len() <= target_vertices || mesh.faces.is_empty() {
        return Ok(original);
    }
    let euler = euler_characteristic(mesh);
    let components = connected_components(mesh).0;
    let ratio = target_vertices as f64 / mesh.vertices.len() as f64;
    for factor in TARGET_FACTORS {
        let keep = (ratio * factor).min(1.0);
        let target_faces = ((mesh.faces.len() as f64 * keep).round() as usize).max(4);
        let candidate = drop_pillows(collapse(mesh, target_faces));
        let unchanged_topology = euler_characteristic(&candidate) == euler
            && connected_components(&candidate).0 == components;
        if unchanged_topology && closed_manifold(&candidate) {
            return Ok(Simplified {
                mesh: candidate,
                ..original
            });
        }
    }
    Ok(original)
}

/// Every edge shared by exactly two triangles, no duplicate triangle, no bow-tie vertex.
fn closed_manifold(mesh: &Mesh) -> bool {
    let origin: Vec<u32> = (0..mesh.faces.len() as u32).collect();
    check_edges(mesh, &origin)
        .is_ok_and(|e| e.boundary_edges == 0 && bowtie_vertices(mesh, &e.uses) == 0)
}

/// Removes pairs of triangles on the same three vertices (a flattened pocket the
/// simplifier can leave where a thin part collapsed), and the vertices only they used.
fn drop_pillows(mesh: Mesh) -> Mesh {
    let mut seen: HashMap<[u32; 3], usize> = HashMap::new();
    let mut drop = vec![false; mesh.faces.len()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let mut key = *face;
        key.sort_unstable();
        if let Some(&g) = seen.get(&key).filter(|&&g| !drop[g]) {
            drop[g] = true;
            drop[f] = true;
        } else {
            seen.insert(key, f);
        }
    }
    if !drop.contains(&true) {
        return mesh;
    }
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .zip(&drop)
        .filter(|(_, d)| !**d)
        .map(|(f, _)| *f)
        .collect();
    compact(&mesh.vertices, faces)
}

/// Keeps the vertices `faces` use, renumbered in order of first use.
fn compact(vertices: &[[f64; 3]], mut faces: Vec<[u32; 3]>) -> Mesh {
    let mut new_index = vec![u32::MAX; vertices.len()];
    let mut kept = Vec::new();
    for i in faces.iter_mut().flatten() {
        let slot = &mut new_index[*i as usize];
        if *slot == u32::MAX {
            *slot = kept.len() as u32;
            kept.push(vertices[*i as usize]);
        }
        *i = *slot;
    }
    Mesh::new(kept, faces)
}

/// One run of the simplifier to at most `target_faces` triangles, unused vertices dropped.
fn collapse(mesh: &Mesh, target_faces: usize) -> Mesh {
    let n = mesh.vertices.len().max(1) as f64;
    let centre = [0, 1, 2].map(|a| mesh.vertices.iter().map(|v| v[a]).sum::<f64>() / n);
    // Single precision relative to the centroid: micrometres for organs of decimetres.
    let mut positions: Vec<[f32; 3]> = mesh
        .vertices
        .iter()
        .map(|v| [0, 1, 2].map(|a| (v[a] - centre[a]) as f32))
        .collect();
    let mut indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let target_index_count = (3 * target_faces).min(indices.len());
    let kept = meshopt::simplify_with_update(
        &mut indices,
        &mut positions,
        &mut [],
        &[],
        0,
        None,
        target_index_count,
        MAX_RELATIVE_ERROR,
        meshopt::SimplifyOptions::None,
        None,
    );
    indices.truncate(kept - kept % 3);
    let vertices: Vec<[f64; 3]> = positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| f64::from(p[a]) + centre[a]))
        .collect();
    let faces = indices
        .chunks_exact(3)
        .map(|f| [f[0], f[1], f[2]])
        .collect();
    compact(&vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::measures::volume_ml;
    use crate::mesh::phantom::{self, Family};

    #[test]
    fn a_phantom_halves_and_stays_closed_with_its_volume() {
        let p = phantom::subject(Family::Lv, 3, 0);
        let n = p.mesh.vertex_count();
        let s = simplify(&p.mesh, n / 2).unwrap();
        assert_eq!(s.original_vertex_count, n);
        assert!(
            s.mesh.vertex_count() <= n / 2 + n / 20,
            "{} of {n}",
            s.mesh.vertex_count()
        );
        assert_eq!(euler_characteristic(&s.mesh), euler_characteristic(&p.mesh));
        let (before, after) = (volume_ml(&p.mesh), volume_ml(&s.mesh));
        assert!(
            (after - before).abs() < 0.01 * before,
            "{before} → {after} ml"
        );
    }

    #[test]
    fn back_to_back_triangles_are_dropped() {
        let mut m = crate::mesh::fixtures::cube();
        let n = m.vertices.len() as u32;
        m.vertices
            .extend([[20.0, 0.0, 0.0], [21.0, 0.0, 0.0], [20.0, 1.0, 0.0]]);
        m.faces.extend([[n, n + 1, n + 2], [n, n + 2, n + 1]]);
        let cleaned = drop_pillows(m);
        assert_eq!((cleaned.vertex_count(), cleaned.face_count()), (8, 12));
        assert!((volume_ml(&cleaned) - 1.0).abs() < 1e-12);
        assert!(closed_manifold(&cleaned));
    }

    #[test]
    fn small_targets_and_small_meshes() {
        let cube = crate::mesh::fixtures::cube();
        assert_eq!(simplify(&cube, 100).unwrap().mesh, cube);
        assert_eq!(
            simplify(&cube, 3).unwrap_err().code(),
            "mesh.unsupported_format"
        );
    }
}
