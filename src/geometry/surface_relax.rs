//! Tangential relaxation of a correspondence on the surface it was read from.
//!
//! A soft correspondence (an average of surface points) can slide neighbouring vertices of
//! a template past each other along the surface: the shape is right, but its triangles fold
//! over. Laplacian smoothing of the displacement removes such folds only by also flattening
//! the shape. Relaxation keeps the shape by construction: each step moves every vertex
//! within the surface's tangent plane towards the place its neighbours' displacements from
//! the template put it, then back onto the surface (its closest point). Only the sliding is
//! smoothed; the surface the vertices lie on is the patient's own.

use super::bvh::TriangleBvh;
use super::error::GeometryError;
use super::points::{add, dot, scale, sub};
use crate::mesh::Mesh;
use crate::mesh::adjacency::Adjacency;
use crate::mesh::measures::face_normals;

/// Share of the way to the neighbours' mean displacement a step goes: below 1 so that the
/// finest ripples (neighbours alternating) die out instead of swapping sides every step.
const STEP: f64 = 0.5;

/// A surface indexed for closest points, with the unit normal of each triangle.
#[derive(Debug, Clone)]
pub struct RelaxSurface {
    bvh: TriangleBvh,
    normals: Vec<[f64; 3]>,
}

impl RelaxSurface {
    /// The surface of `mesh` (mm; triangles wound outwards).
    pub fn new(mesh: &Mesh) -> Result<Self, GeometryError> {
        let bvh = TriangleBvh::new(&mesh.vertices, &mesh.faces)?;
        Ok(Self {
            bvh,
            normals: face_normals(mesh),
        })
    }

    /// The closest surface point to `p` and the normal of its triangle.
    fn closest(&self, p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let hit = self.bvh.closest(p);
        (hit.point, self.normals[hit.face])
    }

    /// The closest point to `p` on the triangles that face the way of `normal` (not the
    /// other wall of a thin part); `None` when no triangle does.
    fn closest_facing(&self, p: [f64; 3], normal: [f64; 3]) -> Option<[f64; 3]> {
        let hit = self
            .bvh
            .closest_where(p, |t| dot(self.normals[t], normal) > 0.0);
        hit.distance.is_finite().then_some(hit.point)
    }
}

/// `shape` (`[N, 3]`, mm), a correspondence of the template `template` (`[N, 3]`, mm, with
/// unit vertex normals `template_normals` and connectivity `adjacency`) on `surface`, after
/// `steps` relaxation steps; every vertex ends on the surface, at the closest point that
/// faces the way of its template normal (so not on the other wall of a thin part).
pub fn relax_on_surface(
    shape: &[[f64; 3]],
    template: &[[f64; 3]],
    template_normals: &[[f64; 3]],
    adjacency: &Adjacency,
    surface: &RelaxSurface,
    steps: usize,
) -> Result<Vec<[f64; 3]>, GeometryError> {
    let n = shape.len();
    if template.len() != n || template_normals.len() != n || adjacency.vertex_count() != n {
        return Err(GeometryError::InvalidParams(format!(
            "relaxation of {n} vertices on a template of {} vertices, {} normals and {} \
             neighbour lists",
            template.len(),
            template_normals.len(),
            adjacency.vertex_count()
        )));
    }
    let mut current: Vec<[f64; 3]> = (0..n)
        .map(|i| onto(surface, shape[i], template_normals[i]))
        .collect();
    for _ in 0..steps {
        let displacement: Vec<[f64; 3]> = (0..n).map(|i| sub(current[i], template[i])).collect();
        current = (0..n)
            .map(|i| {
                let neighbours = adjacency.neighbours(i);
                if neighbours.is_empty() {
                    return current[i];
                }
                let mut mean = [0.0; 3];
                for &j in neighbours {
                    mean = add(mean, displacement[j as usize]);
                }
                let mean = scale(mean, 1.0 / neighbours.len() as f64);
                let (_, normal) = surface.closest(current[i]);
                let step = scale(sub(mean, displacement[i]), STEP);
                let tangential = sub(step, scale(normal, dot(step, normal)));
                let moved = add(current[i], tangential);
                onto(surface, moved, template_normals[i])
            })
            .collect();
    }
    Ok(current)
}

/// The closest point to `p` of the surface that faces the way of `normal`; `p` itself
/// when none does.
fn onto(surface: &RelaxSurface, p: [f64; 3], normal: [f64; 3]) -> [f64; 3] {
    surface.closest_facing(p, normal).unwrap_or(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::uv_sphere;
    use crate::mesh::measures::{folded_edges, vertex_normals};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A template sphere, and the same sphere with every vertex slid along the surface by up
    /// to `slide` radians in a random direction: the form kept, the triangles folded.
    fn slid_sphere(slide: f64) -> (Mesh, Vec<[f64; 3]>) {
        let template = uv_sphere(20.0, [0.0; 3], 16, 24);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let slid = template
            .vertices
            .iter()
            .map(|p| {
                let q = [0, 1, 2].map(|_| rng.random_range(-slide..slide) * 20.0);
                let moved = add(*p, q);
                scale(moved, 20.0 / dot(moved, moved).sqrt())
            })
            .collect();
        (template, slid)
    }

    #[test]
    fn sliding_is_undone_and_every_vertex_stays_on_the_surface() {
        let (template, slid) = slid_sphere(0.12);
        let folded = Mesh::new(slid.clone(), template.faces.clone());
        assert!(
            folded_edges(&folded) > 20,
            "{} folds",
            folded_edges(&folded)
        );
        let surface = RelaxSurface::new(&uv_sphere(20.0, [0.0; 3], 48, 96)).unwrap();
        let adjacency = Adjacency::from_mesh(&template);
        let normals = vertex_normals(&template);
        let relaxed = relax_on_surface(
            &slid,
            &template.vertices,
            &normals,
            &adjacency,
            &surface,
            30,
        )
        .unwrap();
        let relaxed_mesh = Mesh::new(relaxed.clone(), template.faces.clone());
        assert_eq!(folded_edges(&relaxed_mesh), 0);
        for p in &relaxed {
            let r = dot(*p, *p).sqrt();
            assert!((r - 20.0).abs() < 0.1, "radius {r}");
        }
    }
}
