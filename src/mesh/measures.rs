//! Whole-mesh measures: enclosed volume (ml), surface area (cm²), bounding box (mm), and
//! face and vertex normals.

use super::Mesh;
use super::topology::{by_edge, edge_uses};

/// Cubic millimetres per millilitre.
pub const MM3_PER_ML: f64 = 1000.0;
/// Square millimetres per square centimetre.
pub const MM2_PER_CM2: f64 = 100.0;

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Signed enclosed volume in mm³ by the divergence theorem.
///
/// Positive for a closed mesh whose faces are oriented outward. The sum is taken relative
/// to the vertex centroid to keep rounding small for meshes far from the origin.
pub fn signed_volume_mm3(mesh: &Mesh) -> f64 {
    let n = mesh.vertices.len().max(1) as f64;
    let mut c = [0.0; 3];
    for v in &mesh.vertices {
        for k in 0..3 {
            c[k] += v[k] / n;
        }
    }
    let mut six_v = 0.0;
    for f in 0..mesh.faces.len() {
        let [a, b, d] = mesh.triangle(f);
        six_v += dot(sub(a, c), cross(sub(b, c), sub(d, c)));
    }
    six_v / 6.0
}

/// Enclosed volume in ml (signed; see [`signed_volume_mm3`]).
pub fn volume_ml(mesh: &Mesh) -> f64 {
    signed_volume_mm3(mesh) / MM3_PER_ML
}

/// Total surface area in mm².
pub fn area_mm2(mesh: &Mesh) -> f64 {
    (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            0.5 * norm(cross(sub(b, a), sub(c, a)))
        })
        .sum()
}

/// Total surface area in cm².
pub fn area_cm2(mesh: &Mesh) -> f64 {
    area_mm2(mesh) / MM2_PER_CM2
}

/// `a` scaled to unit length, or the zero vector if `a` has no length.
pub(crate) fn normalized(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    if n > 0.0 { a.map(|x| x / n) } else { [0.0; 3] }
}

/// Axis-aligned bounding box `(min, max)` in mm; both zero for a mesh without vertices.
pub fn bounding_box(mesh: &Mesh) -> ([f64; 3], [f64; 3]) {
    let Some(first) = mesh.vertices.first() else {
        return ([0.0; 3], [0.0; 3]);
    };
    let (mut lo, mut hi) = (*first, *first);
    for v in &mesh.vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    (lo, hi)
}

/// Unit normal of each face, `[n_faces]`, by the right-hand rule (outward for faces
/// counter-clockwise seen from outside); the zero vector for zero-area faces.
pub fn face_normals(mesh: &Mesh) -> Vec<[f64; 3]> {
    (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            normalized(cross(sub(b, a), sub(c, a)))
        })
        .collect()
}

/// Edges whose two triangles turn by more than 90° against each other (their normals'
/// dot product is negative): creases and folded-over triangles. A smooth organ surface has
/// few (the 20 KiTS19 kidney meshes 0–21 of 30,000–55,000 edges); a correspondence that
/// slides neighbouring vertices past each other leaves many.
pub fn folded_edges(mesh: &Mesh) -> usize {
    let normals = face_normals(mesh);
    let uses = edge_uses(mesh);
    by_edge(&uses)
        .filter(|run| {
            let [a, b] = run else { return false };
            dot(normals[a.face as usize], normals[b.face as usize]) < 0.0
        })
        .count()
}

/// Angle-weighted vertex normals (mean weighted by angle, thesis eq. 4.13), `[n_vertices]`.
///
/// Each face adds its unit normal times its interior angle (radians) at the vertex; the sum
/// is scaled to unit length. This depends only on the local geometry, not on how the
/// surface is triangulated. Zero-area faces add nothing; a vertex with no face of
/// positive area gets the zero vector.
pub fn vertex_normals(mesh: &Mesh) -> Vec<[f64; 3]> {
    let mut sum = vec![[0.0; 3]; mesh.vertices.len()];
    for (f, face) in mesh.faces.iter().enumerate() {
        let p = mesh.triangle(f);
        let n = normalized(cross(sub(p[1], p[0]), sub(p[2], p[0])));
        if n == [0.0; 3] {
            continue;
        }
        for k in 0..3 {
            let e1 = sub(p[(k + 1) % 3], p[k]);
            let e2 = sub(p[(k + 2) % 3], p[k]);
            let angle = norm(cross(e1, e2)).atan2(dot(e1, e2));
            let s = &mut sum[face[k] as usize];
            for d in 0..3 {
                s[d] += angle * n[d];
            }
        }
    }
    sum.into_iter().map(normalized).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, folded_square};

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < tol)
    }

    #[test]
    fn cube_measures() {
        let c = cube();
        assert_eq!(volume_ml(&c), 1.0);
        assert!((area_cm2(&c) - 6.0).abs() < 1e-12);
        assert_eq!(bounding_box(&c), ([0.0; 3], [10.0; 3]));
        let n = face_normals(&c);
        assert_eq!(n[0], [0.0, 0.0, -1.0]);
        assert_eq!(n[11], [1.0, 0.0, 0.0]);
    }

    #[test]
    fn a_cube_has_no_folded_edge_and_a_vertex_pushed_through_a_face_folds_it() {
        // The cube's edges turn by exactly 90°: creases, not folds.
        assert_eq!(folded_edges(&cube()), 0);
        // A square of two triangles, flat: no fold; its corner 2 pulled back across the
        // diagonal 0–3 turns triangle 1 over: one fold.
        let mut square = folded_square();
        assert_eq!(folded_edges(&square), 1);
        square.vertices[2] = [0.0, 1.0, 0.0];
        assert_eq!(folded_edges(&square), 0);
    }

    #[test]
    fn cube_vertex_normals_are_diagonals_whatever_the_triangulation() {
        // Corners 0 and 1 touch different numbers of triangles; angle weighting still gives
        // the exact diagonal (an unweighted mean would not).
        let c = cube();
        let n = vertex_normals(&c);
        let s = 1.0 / 3.0f64.sqrt();
        for (v, p) in c.vertices.iter().enumerate() {
            let expected = p.map(|x| if x > 0.0 { s } else { -s });
            assert!(close(n[v], expected, 1e-12), "vertex {v}: {:?}", n[v]);
        }
    }

    #[test]
    fn regular_tetrahedron_normals_point_away_from_the_centroid() {
        let p = [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ];
        let t = Mesh::new(
            p.map(|v| v.map(|x| 5.0 * x + 2.0)).to_vec(),
            vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        );
        assert!(signed_volume_mm3(&t) > 0.0);
        let n = vertex_normals(&t);
        for v in 0..4 {
            assert!(
                close(n[v], normalized(p[v]), 1e-12),
                "vertex {v}: {:?}",
                n[v]
            );
        }
    }

    #[test]
    fn zero_area_faces_and_isolated_vertices() {
        let m = Mesh::new(
            vec![
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [9.0; 3],
            ],
            vec![[0, 1, 2], [0, 1, 3]],
        );
        assert_eq!(face_normals(&m)[0], [0.0; 3]);
        let n = vertex_normals(&m);
        assert_eq!(n[2], [0.0; 3]);
        assert_eq!(n[4], [0.0; 3]);
        assert_eq!(n[0], [0.0, 0.0, 1.0]);
        assert_eq!(bounding_box(&m), ([0.0; 3], [9.0; 3]));
    }

    fn tetrahedron() -> Mesh {
        // Corner tetrahedron with legs of 10 mm: volume 1000/6 mm³.
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [10.0, 0.0, 0.0],
                [0.0, 10.0, 0.0],
                [0.0, 0.0, 10.0],
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn tetrahedron_volume_and_area() {
        let t = tetrahedron();
        assert!((signed_volume_mm3(&t) - 1000.0 / 6.0).abs() < 1e-9);
        // Three right triangles of 50 mm² and one equilateral with side 10√2: (√3/4)·200.
        let equilateral = 3.0f64.sqrt() / 4.0 * 200.0;
        assert!((area_mm2(&t) - (150.0 + equilateral)).abs() < 1e-9);
    }

    #[test]
    fn flipped_faces_give_negative_volume() {
        let mut t = tetrahedron();
        for f in &mut t.faces {
            f.swap(1, 2);
        }
        assert!(signed_volume_mm3(&t) < 0.0);
    }
}
