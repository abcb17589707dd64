//! Icospheres: a regular icosahedron whose triangles are split in four `level` times, with
//! the vertices pushed onto the unit sphere. `10·4^level + 2` vertices, `20·4^level` faces,
//! counter-clockwise seen from outside.

use std::collections::HashMap;

use crate::mesh::Mesh;
use crate::models::ModelError;

/// Highest subdivision level served (163,842 vertices).
pub const MAX_ICOSPHERE_LEVEL: u32 = 7;

/// Vertex count of the icosphere of a subdivision level: `10·4^level + 2`.
pub fn icosphere_vertex_count(level: u32) -> usize {
    10 * 4usize.pow(level) + 2
}

/// The level (≤ [`MAX_ICOSPHERE_LEVEL`]) whose vertex count is closest to `target_vertices`
/// (the lower level on a tie).
pub fn icosphere_level_for(target_vertices: usize) -> u32 {
    (0..=MAX_ICOSPHERE_LEVEL)
        .min_by_key(|&l| icosphere_vertex_count(l).abs_diff(target_vertices))
        .unwrap_or(0)
}

/// The unit icosphere (radius 1, centred at the origin) of a subdivision level.
pub fn icosphere(level: u32) -> Result<Mesh, ModelError> {
    if level > MAX_ICOSPHERE_LEVEL {
        return Err(ModelError::invalid(
            "atlas_vertices",
            format!(
                "an icosphere has at most {} vertices (level {MAX_ICOSPHERE_LEVEL}), \
                 level {level} was asked for",
                icosphere_vertex_count(MAX_ICOSPHERE_LEVEL)
            ),
        ));
    }
    let mut mesh = icosahedron();
    for _ in 0..level {
        mesh = subdivide(&mesh);
    }
    Ok(mesh)
}

fn unit(p: [f64; 3]) -> [f64; 3] {
    let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / n, p[1] / n, p[2] / n]
}

fn icosahedron() -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let vertices = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(unit)
    .to_vec();
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    Mesh::new(vertices, faces)
}

/// Splits every triangle into four at its edge midpoints (shared midpoints are one vertex),
/// projecting the new vertices onto the unit sphere.
fn subdivide(mesh: &Mesh) -> Mesh {
    let mut vertices = mesh.vertices.clone();
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut midpoint = |a: u32, b: u32, vertices: &mut Vec<[f64; 3]>| -> u32 {
        let key = (a.min(b), a.max(b));
        *midpoints.entry(key).or_insert_with(|| {
            let (p, q) = (vertices[a as usize], vertices[b as usize]);
            vertices.push(unit([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
            (vertices.len() - 1) as u32
        })
    };
    let mut faces = Vec::with_capacity(4 * mesh.faces.len());
    for &[a, b, c] in &mesh.faces {
        let ab = midpoint(a, b, &mut vertices);
        let bc = midpoint(b, c, &mut vertices);
        let ca = midpoint(c, a, &mut vertices);
        faces.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
    }
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::measures::{area_mm2, signed_volume_mm3};
    use crate::mesh::topology::euler_characteristic;

    #[test]
    fn counts_and_levels() {
        assert_eq!(icosphere_vertex_count(0), 12);
        assert_eq!(icosphere_vertex_count(3), 642);
        assert_eq!(icosphere_level_for(1000), 3);
        assert_eq!(icosphere_level_for(2000), 4);
        assert_eq!(icosphere_level_for(0), 0);
        assert_eq!(icosphere_level_for(usize::MAX), MAX_ICOSPHERE_LEVEL);
        assert!(icosphere(MAX_ICOSPHERE_LEVEL + 1).is_err());
    }

    #[test]
    fn icospheres_are_closed_outward_unit_spheres() {
        for level in 0..4 {
            let m = icosphere(level).unwrap();
            assert_eq!(m.vertex_count(), icosphere_vertex_count(level));
            assert_eq!(m.face_count(), 20 * 4usize.pow(level));
            assert_eq!(euler_characteristic(&m), 2);
            for p in &m.vertices {
                assert!(((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() < 1e-12);
            }
            // Inscribed polyhedra approach the sphere from below and are outward-oriented.
            let v = signed_volume_mm3(&m);
            assert!(v > 0.0 && v < 4.0 / 3.0 * std::f64::consts::PI);
            assert!(area_mm2(&m) < 4.0 * std::f64::consts::PI);
        }
        let v3 = signed_volume_mm3(&icosphere(3).unwrap());
        assert!((v3 / (4.0 / 3.0 * std::f64::consts::PI) - 1.0).abs() < 0.02);
    }
}
