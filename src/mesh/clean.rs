//! Clean-up steps of validation: weld duplicate vertices, drop degenerate triangles and
//! unreferenced vertices. Each step keeps first-occurrence order, so results are
//! deterministic.

use super::Mesh;
use super::measures::{cross, dot, norm, sub};
use std::collections::HashMap;

/// A triangle is degenerate when twice its area is at most this times its longest edge
/// squared (the sine of its largest angle is at rounding level).
pub const DEGENERATE_RELATIVE_AREA: f64 = 1e-12;

/// Merges vertices at the same position, or within `tolerance_mm` if it is positive.
///
/// Each group keeps the position of its first vertex; faces are remapped. Returns how many
/// vertices were merged away.
pub(crate) fn weld(mesh: &mut Mesh, tolerance_mm: f64) -> usize {
    let remap = if tolerance_mm > 0.0 {
        weld_within(&mesh.vertices, tolerance_mm)
    } else {
        weld_exact(&mesh.vertices)
    };
    let (remap, kept) = remap;
    let merged = mesh.vertices.len() - kept.len();
    if merged > 0 {
        mesh.vertices = kept.iter().map(|&v| mesh.vertices[v as usize]).collect();
        for f in &mut mesh.faces {
            *f = f.map(|i| remap[i as usize]);
        }
    }
    merged
}

/// Exact welding by bit pattern (with −0 taken as +0): `(new index per vertex, kept)`.
fn weld_exact(vertices: &[[f64; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(vertices.len());
    let mut kept = Vec::with_capacity(vertices.len());
    let remap = vertices
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let key = v.map(|c| (c + 0.0).to_bits());
            *first.entry(key).or_insert_with(|| {
                kept.push(i as u32);
                kept.len() as u32 - 1
            })
        })
        .collect();
    (remap, kept)
}

/// Welding within a distance on a hash grid of cell size `tol`: each vertex joins the
/// earliest kept vertex within `tol`, else it is kept.
fn weld_within(vertices: &[[f64; 3]], tol: f64) -> (Vec<u32>, Vec<u32>) {
    let cell = |v: &[f64; 3]| v.map(|c| (c / tol).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut kept: Vec<u32> = Vec::new();
    let mut remap = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let c = cell(v);
        let mut best: Option<u32> = None;
        for d in 0..27i64 {
            let key = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
            for &k in grid.get(&key).map_or(&[][..], Vec::as_slice) {
                let p = vertices[kept[k as usize] as usize];
                if norm(sub(p, *v)) <= tol && best.is_none_or(|b| k < b) {
                    best = Some(k);
                }
            }
        }
        let id = best.unwrap_or_else(|| {
            kept.push(i as u32);
            let id = kept.len() as u32 - 1;
            grid.entry(c).or_default().push(id);
            id
        });
        remap.push(id);
    }
    (remap, kept)
}

/// Whether a triangle repeats a vertex or has (numerically) zero area.
pub(crate) fn is_degenerate(mesh: &Mesh, f: usize) -> bool {
    let [a, b, c] = mesh.faces[f];
    if a == b || b == c || a == c {
        return true;
    }
    let [p, q, r] = mesh.triangle(f);
    let longest = [sub(q, p), sub(r, q), sub(p, r)]
        .iter()
        .map(|e| dot(*e, *e))
        .fold(0.0, f64::max);
    norm(cross(sub(q, p), sub(r, p))) <= DEGENERATE_RELATIVE_AREA * longest
}

/// Removes degenerate triangles; `origin` (the file's triangle index per face) follows.
/// Returns how many were removed.
pub(crate) fn drop_degenerate(mesh: &mut Mesh, origin: &mut Vec<u32>) -> usize {
    let keep: Vec<bool> = (0..mesh.faces.len())
        .map(|f| !is_degenerate(mesh, f))
        .collect();
    let before = mesh.faces.len();
    let mut k = keep.iter();
    mesh.faces.retain(|_| *k.next().unwrap_or(&true));
    let mut k = keep.iter();
    origin.retain(|_| *k.next().unwrap_or(&true));
    before - mesh.faces.len()
}

/// Removes vertices no face uses, keeping order. Returns how many were removed.
pub(crate) fn drop_unreferenced(mesh: &mut Mesh) -> usize {
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    for &i in mesh.faces.iter().flatten() {
        new_index[i as usize] = 0;
    }
    let mut next = 0u32;
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    for (v, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = next;
            next += 1;
            vertices.push(mesh.vertices[v]);
        }
    }
    let removed = mesh.vertices.len() - vertices.len();
    if removed > 0 {
        mesh.vertices = vertices;
        for f in &mut mesh.faces {
            *f = f.map(|i| new_index[i as usize]);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_weld_keeps_first_occurrence_and_merges_signed_zero() {
        let mut m = Mesh::new(
            vec![
                [1.0, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [-0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 4], [2, 3, 4]],
        );
        assert_eq!(weld(&mut m, 0.0), 2);
        assert_eq!(
            m.vertices,
            vec![[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        );
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 1, 2]]);
    }

    #[test]
    fn tolerance_weld_joins_near_points_only() {
        let mut m = Mesh::new(
            vec![
                [0.0; 3],
                [0.05, 0.0, 0.0],
                [0.3, 0.0, 0.0],
                [0.0, 0.0, 0.09],
                [5.0; 3],
            ],
            vec![[0, 2, 4], [1, 3, 4]],
        );
        assert_eq!(weld(&mut m, 0.1), 2);
        assert_eq!(m.vertices, vec![[0.0; 3], [0.3, 0.0, 0.0], [5.0; 3]]);
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 0, 2]]);
    }

    #[test]
    fn degenerate_and_unreferenced() {
        let mut m = Mesh::new(
            vec![
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [7.0; 3],
            ],
            vec![[0, 1, 3], [0, 1, 2], [1, 1, 3], [3, 1, 0]],
        );
        let mut origin = vec![0, 1, 2, 3];
        assert!(!is_degenerate(&m, 0));
        assert!(is_degenerate(&m, 1));
        assert_eq!(drop_degenerate(&mut m, &mut origin), 2);
        assert_eq!(origin, vec![0, 3]);
        assert_eq!(drop_unreferenced(&mut m), 2);
        assert_eq!(m.vertices, vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(m.faces, vec![[0, 1, 2], [2, 1, 0]]);
    }

    #[test]
    fn thin_but_valid_triangles_are_kept() {
        let m = Mesh::new(
            vec![[0.0; 3], [100.0, 0.0, 0.0], [50.0, 1e-6, 0.0]],
            vec![[0, 1, 2]],
        );
        assert!(!is_degenerate(&m, 0));
    }
}
