//! Test helper: checks that a mesh is a closed, consistently oriented, edge-manifold,
//! connected genus-0 surface without degenerate triangles and with positive volume.

use std::collections::HashMap;

use crate::mesh::Mesh;
use crate::mesh::measures::{cross, norm, signed_volume_mm3, sub};

/// Smallest triangle area accepted, as a fraction of the mean triangle area.
const MIN_RELATIVE_AREA: f64 = 1e-4;

/// Panics with a message unless `mesh` is a closed, outward-oriented genus-0 surface.
pub(super) fn assert_closed_surface(mesh: &Mesh) {
    let n = mesh.vertices.len();
    let mut used = vec![false; n];
    // Every directed edge exactly once; its reverse present: edge-manifold and oriented.
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            assert!((a as usize) < n, "face {f} has vertex {a} out of range");
            assert_ne!(a, b, "face {f} repeats a vertex");
            used[a as usize] = true;
            assert!(
                directed.insert((a, b), f).is_none(),
                "directed edge {a}->{b} used twice (face {f})"
            );
        }
    }
    for &(a, b) in directed.keys() {
        assert!(directed.contains_key(&(b, a)), "edge {a}-{b} has one face");
    }
    assert!(used.iter().all(|&u| u), "unreferenced vertex");
    let edges = directed.len() / 2;
    let euler = n as i64 - edges as i64 + mesh.faces.len() as i64;
    assert_eq!(
        euler, 2,
        "Euler characteristic {euler}, expected 2 (genus 0)"
    );
    assert_eq!(components(mesh), 1, "mesh is not connected");
    let areas: Vec<f64> = (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            0.5 * norm(cross(sub(b, a), sub(c, a)))
        })
        .collect();
    let mean = areas.iter().sum::<f64>() / areas.len() as f64;
    let min = areas.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        min > MIN_RELATIVE_AREA * mean,
        "degenerate triangle: area {min} mm² vs mean {mean} mm²"
    );
    assert!(signed_volume_mm3(mesh) > 0.0, "not outward oriented");
}

/// Number of connected components over shared vertices.
fn components(mesh: &Mesh) -> usize {
    let mut parent: Vec<usize> = (0..mesh.vertices.len()).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for face in &mesh.faces {
        for k in 1..3 {
            let (a, b) = (
                find(&mut parent, face[0] as usize),
                find(&mut parent, face[k] as usize),
            );
            parent[a] = b;
        }
    }
    (0..parent.len())
        .filter(|&x| find(&mut parent, x) == x)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::panic::catch_unwind;

    fn tetrahedron() -> Mesh {
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
    fn accepts_a_tetrahedron() {
        assert_closed_surface(&tetrahedron());
    }

    #[test]
    fn rejects_a_flipped_face_an_open_mesh_and_inside_out() {
        let mut flipped = tetrahedron();
        flipped.faces[3].swap(1, 2);
        assert!(catch_unwind(|| assert_closed_surface(&flipped)).is_err());
        let mut open = tetrahedron();
        open.faces.pop();
        assert!(catch_unwind(|| assert_closed_surface(&open)).is_err());
        let mut inside_out = tetrahedron();
        inside_out.faces.iter_mut().for_each(|f| f.swap(1, 2));
        assert!(catch_unwind(|| assert_closed_surface(&inside_out)).is_err());
    }

    #[test]
    fn rejects_two_components() {
        let mut two = tetrahedron();
        let shifted: Vec<[f64; 3]> = two
            .vertices
            .iter()
            .map(|v| [v[0] + 50.0, v[1], v[2]])
            .collect();
        two.vertices.extend(shifted);
        let more: Vec<[u32; 3]> = two.faces.iter().map(|f| f.map(|i| i + 4)).collect();
        two.faces.extend(more);
        assert!(catch_unwind(|| assert_closed_surface(&two)).is_err());
    }
}
