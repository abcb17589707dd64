//! Small meshes with known measures, shared by the unit tests of this module.

use super::Mesh;

/// Cube with side 10 mm and corners at 0 and 10 (volume 1 ml, area 6 cm²), faces outward.
/// Vertex `i` has coordinates `10 · (bit 0, bit 1, bit 2)` of `i`.
pub(crate) fn cube() -> Mesh {
    let vertices = (0..8u32)
        .map(|i| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|b| 10.0 * b as f64))
        .collect();
    let faces = vec![
        [0, 2, 1], // z = 0
        [1, 2, 3],
        [4, 5, 6], // z = 10
        [5, 7, 6],
        [0, 1, 4], // y = 0
        [1, 5, 4],
        [2, 6, 3], // y = 10
        [3, 6, 7],
        [0, 4, 2], // x = 0
        [2, 4, 6],
        [1, 3, 5], // x = 10
        [3, 7, 5],
    ];
    Mesh::new(vertices, faces)
}

/// A unit square of two triangles meeting along the diagonal 0–3 whose corner 2 is pulled
/// back across it to `(1, 0.5, 0)`: the triangles face opposite ways, one folded edge.
pub(crate) fn folded_square() -> Mesh {
    Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.5, 0.0],
            [1.0, 1.0, 0.0],
        ],
        vec![[0, 1, 3], [0, 3, 2]],
    )
}

/// Regular tetrahedron with corners at `5 · (±1, ±1, ±1)` (even sign count) plus `offset`.
pub(crate) fn tetrahedron(offset: f64) -> Mesh {
    let p: [[f64; 3]; 4] = [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ];
    Mesh::new(
        p.map(|v| v.map(|x| 5.0 * x + offset)).to_vec(),
        vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
    )
}

/// UV sphere of radius `r` mm centred at `c`: `rings - 1` latitude circles of `segments`
/// vertices plus two poles, faces outward.
pub(crate) fn uv_sphere(r: f64, c: [f64; 3], rings: u32, segments: u32) -> Mesh {
    use std::f64::consts::PI;
    let mut vertices = vec![[c[0], c[1], c[2] + r]];
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = 2.0 * PI * j as f64 / segments as f64;
            vertices.push([
                c[0] + r * theta.sin() * phi.cos(),
                c[1] + r * theta.sin() * phi.sin(),
                c[2] + r * theta.cos(),
            ]);
        }
    }
    let south = vertices.len() as u32;
    vertices.push([c[0], c[1], c[2] - r]);
    let at = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let mut faces = Vec::new();
    for j in 0..segments {
        faces.push([0, at(1, j), at(1, j + 1)]);
        faces.push([south, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Mesh::new(vertices, faces)
}
