//! From a grid isosurface to a world mesh: the affine, orientation, surface components.

use super::affine::Affine;
use super::marching::GridSurface;
use super::resample::SampleGrid;
use crate::mesh::Mesh;
use crate::mesh::measures::{bounding_box, signed_volume_mm3};
use crate::mesh::topology::connected_components;

/// The surface in world millimetres, outward-facing whatever the handedness of the affine.
pub fn to_world(surface: GridSurface, grid: &SampleGrid, affine: &Affine) -> Mesh {
    let vertices = surface
        .vertices
        .iter()
        .map(|&g| affine.apply(grid.volume_index(g)))
        .collect();
    let mut faces = surface.faces;
    if affine.determinant() < 0.0 {
        // A mirroring affine turns counter-clockwise into clockwise: swap back.
        for f in &mut faces {
            f.swap(1, 2);
        }
    }
    Mesh::new(vertices, faces)
}

/// Keeps the surface component with the most triangles and, with `keep_cavities`, the
/// inward-facing components inside its bounding box (smoothing can also close off a cavity
/// in a filled mask; those go). Returns the mesh and how many components were dropped.
pub fn keep_largest(mesh: Mesh, keep_cavities: bool) -> (Mesh, usize) {
    let (count, label) = connected_components(&mesh);
    if count <= 1 {
        return (mesh, 0);
    }
    let parts: Vec<Mesh> = (0..count as u32).map(|c| part(&mesh, &label, c)).collect();
    let Some(largest) = (0..count).max_by_key(|&c| (parts[c].faces.len(), std::cmp::Reverse(c)))
    else {
        return (mesh, 0);
    };
    let (lo, hi) = bounding_box(&parts[largest]);
    let keep: Vec<bool> = (0..count)
        .map(|c| {
            let (clo, chi) = bounding_box(&parts[c]);
            let inside = (0..3).all(|a| clo[a] >= lo[a] && chi[a] <= hi[a]);
            c == largest || (keep_cavities && inside && signed_volume_mm3(&parts[c]) < 0.0)
        })
        .collect();
    let dropped = keep.iter().filter(|k| !**k).count();
    let kept = (0..count as u32)
        .filter(|&c| keep[c as usize])
        .collect::<Vec<_>>();
    (select(&mesh, &label, &kept), dropped)
}

fn part(mesh: &Mesh, label: &[u32], c: u32) -> Mesh {
    select(mesh, label, &[c])
}

/// The faces whose vertices carry one of `labels`, with vertices renumbered in order.
fn select(mesh: &Mesh, label: &[u32], labels: &[u32]) -> Mesh {
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    for (v, l) in label.iter().enumerate() {
        if labels.contains(l) {
            new_index[v] = vertices.len() as u32;
            vertices.push(mesh.vertices[v]);
        }
    }
    let faces = mesh
        .faces
        .iter()
        .filter(|f| labels.contains(&label[f[0] as usize]))
        .map(|f| f.map(|i| new_index[i as usize]))
        .collect();
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::cube;

    fn shifted(m: &Mesh, by: f64, scale: f64, inward: bool) -> Mesh {
        let mut m = m.clone();
        for v in &mut m.vertices {
            *v = v.map(|c| c * scale + by);
        }
        if inward {
            for f in &mut m.faces {
                f.swap(1, 2);
            }
        }
        m
    }

    fn join(parts: &[Mesh]) -> Mesh {
        let mut out = Mesh::default();
        for p in parts {
            let base = out.vertices.len() as u32;
            out.vertices.extend(&p.vertices);
            out.faces
                .extend(p.faces.iter().map(|f| f.map(|i| i + base)));
        }
        out
    }

    #[test]
    fn keeps_the_largest_part_and_its_cavity() {
        let c = cube();
        let big = shifted(&c, 0.0, 10.0, false);
        let cavity = shifted(&c, 4.0, 1.0, true);
        let mut fine = big.clone();
        // Same shape, more triangles: split every face into three around its centre.
        fine.faces.clear();
        for f in &big.faces {
            let centre = [0, 1, 2]
                .map(|a| f.iter().map(|&i| big.vertices[i as usize][a]).sum::<f64>() / 3.0);
            let m = fine.vertices.len() as u32;
            fine.vertices.push(centre);
            fine.faces
                .extend([[f[0], f[1], m], [f[1], f[2], m], [f[2], f[0], m]]);
        }
        let apart = shifted(&c, 500.0, 1.0, false);
        let all = join(&[apart, fine.clone(), cavity]);
        let (outer, dropped) = keep_largest(all.clone(), false);
        assert_eq!((outer.faces.len(), dropped), (fine.faces.len(), 2));
        let (kept, dropped) = keep_largest(all, true);
        assert_eq!(dropped, 1);
        assert_eq!(kept.faces.len(), fine.faces.len() + c.faces.len());
        let expected = signed_volume_mm3(&fine) - 1000.0;
        assert!((signed_volume_mm3(&kept) - expected).abs() < 1e-9);
    }
}
