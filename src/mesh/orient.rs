//! Consistent, outward triangle orientation: neighbours across an edge must run it in
//! opposite directions, and a closed surface must enclose a positive volume.

use super::Mesh;
use super::measures::signed_volume_mm3;
use super::topology::{EdgeUse, by_edge};
use std::collections::VecDeque;

/// What orientation repair did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Reorientation {
    /// Triangles whose winding was reversed.
    pub(crate) flipped: usize,
    /// Connected parts that cannot be oriented consistently (left as they were).
    pub(crate) non_orientable_parts: usize,
}

/// Makes the winding consistent within each edge-connected part (flipping the minority),
/// then, if the surface is `closed` and encloses a negative volume, flips every triangle.
pub(crate) fn orient(mesh: &mut Mesh, uses: &[EdgeUse], closed: bool) -> Reorientation {
    let (offsets, links) = face_links(mesh.faces.len(), uses);
    let mut flip = vec![false; mesh.faces.len()];
    let mut report = Reorientation::default();
    if links.iter().any(|&(_, same)| same) {
        let mut visited = vec![false; mesh.faces.len()];
        for seed in 0..mesh.faces.len() {
            if !visited[seed] {
                let part = propagate(seed, &offsets, &links, &mut visited, &mut flip);
                settle(&part, &mut flip, &mut report);
            }
        }
    }
    for (face, &f) in mesh.faces.iter_mut().zip(&flip) {
        if f {
            face.swap(1, 2);
            report.flipped += 1;
        }
    }
    if closed && report.non_orientable_parts == 0 && signed_volume_mm3(mesh) < 0.0 {
        for face in &mut mesh.faces {
            face.swap(1, 2);
        }
        report.flipped = mesh.faces.len() - report.flipped;
    }
    report
}

/// Face neighbours across two-face edges in CSR form: `(neighbour, same direction)`.
fn face_links(n_faces: usize, uses: &[EdgeUse]) -> (Vec<usize>, Vec<(u32, bool)>) {
    let pairs: Vec<(u32, u32, bool)> = by_edge(uses)
        .filter_map(|run| match run {
            [u, w] => Some((u.face, w.face, u.forward == w.forward)),
            _ => None,
        })
        .collect();
    let mut offsets = vec![0usize; n_faces + 1];
    for &(a, b, _) in &pairs {
        offsets[a as usize + 1] += 1;
        offsets[b as usize + 1] += 1;
    }
    for i in 0..n_faces {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut links = vec![(0u32, false); offsets[n_faces]];
    for &(a, b, same) in &pairs {
        links[fill[a as usize]] = (b, same);
        fill[a as usize] += 1;
        links[fill[b as usize]] = (a, same);
        fill[b as usize] += 1;
    }
    (offsets, links)
}

/// One edge-connected part found by breadth-first search, and whether its triangles can
/// be given one consistent winding.
struct Part {
    faces: Vec<usize>,
    orientable: bool,
}

/// Visits the part of `seed`, setting each face's flip relative to the seed.
fn propagate(
    seed: usize,
    offsets: &[usize],
    links: &[(u32, bool)],
    visited: &mut [bool],
    flip: &mut [bool],
) -> Part {
    let mut part = Part {
        faces: vec![seed],
        orientable: true,
    };
    visited[seed] = true;
    let mut queue = VecDeque::from([seed]);
    while let Some(f) = queue.pop_front() {
        for &(g, same) in &links[offsets[f]..offsets[f + 1]] {
            let g = g as usize;
            let wanted = flip[f] ^ same;
            if !visited[g] {
                visited[g] = true;
                flip[g] = wanted;
                part.faces.push(g);
                queue.push_back(g);
            } else if flip[g] != wanted {
                part.orientable = false;
            }
        }
    }
    part
}

/// Keeps the smaller set of flips in an orientable part; undoes all flips otherwise.
fn settle(part: &Part, flip: &mut [bool], report: &mut Reorientation) {
    if !part.orientable {
        report.non_orientable_parts += 1;
        for &f in &part.faces {
            flip[f] = false;
        }
        return;
    }
    let flipped = part.faces.iter().filter(|&&f| flip[f]).count();
    if 2 * flipped > part.faces.len() {
        for &f in &part.faces {
            flip[f] = !flip[f];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, uv_sphere};
    use crate::mesh::topology::edge_uses;

    fn orient_all(m: &mut Mesh, closed: bool) -> Reorientation {
        let uses = edge_uses(m);
        orient(m, &uses, closed)
    }

    #[test]
    fn outward_cube_is_untouched() {
        let mut c = cube();
        assert_eq!(orient_all(&mut c, true), Reorientation::default());
        assert_eq!(c, cube());
    }

    #[test]
    fn reversed_cube_is_flipped_back() {
        let mut c = cube();
        for f in &mut c.faces {
            f.swap(0, 1);
        }
        let r = orient_all(&mut c, true);
        assert_eq!(r.flipped, 12);
        assert_eq!(signed_volume_mm3(&c), 1000.0);
    }

    #[test]
    fn a_few_wrong_faces_are_repaired() {
        let mut s = uv_sphere(10.0, [1.0, 2.0, 3.0], 6, 8);
        let good = s.clone();
        for f in [0, 5, 17] {
            s.faces[f].swap(0, 2);
        }
        let r = orient_all(&mut s, true);
        assert_eq!(r.flipped, 3);
        assert_eq!(r.non_orientable_parts, 0);
        for (a, b) in s.faces.iter().zip(&good.faces) {
            let mut a = *a;
            // Same cyclic order as the original.
            while a[0] != b[0] {
                a.rotate_left(1);
            }
            assert_eq!(&a, b);
        }
    }

    #[test]
    fn mobius_strip_is_reported_not_changed() {
        // A strip of 6 quads (12 triangles) closed with a half twist.
        let n = 6u32;
        let mut vertices = Vec::new();
        for i in 0..n {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let (c, s) = ((t / 2.0).cos(), (t / 2.0).sin());
            for w in [-1.0, 1.0] {
                let r = 10.0 + 2.0 * w * c;
                vertices.push([r * t.cos(), r * t.sin(), 2.0 * w * s]);
            }
        }
        let mut faces = Vec::new();
        for i in 0..n {
            let (a, b) = (2 * i, 2 * i + 1);
            let (c, d) = if i + 1 < n {
                (2 * i + 2, 2 * i + 3)
            } else {
                (1, 0)
            };
            faces.push([a, c, b]);
            faces.push([b, c, d]);
        }
        let mut m = Mesh::new(vertices, faces);
        let before = m.clone();
        let r = orient_all(&mut m, false);
        assert_eq!(r.non_orientable_parts, 1);
        assert_eq!(r.flipped, 0);
        assert_eq!(m, before);
    }
}
