//! Surface topology checks of validation: duplicate triangles and edges shared by more
//! than two triangles (rejected), boundary edges and bow-tie vertices (counted).

use super::io::text::ordinal;
use super::topology::{EdgeUse, UnionFind, by_edge, edge_uses};
use super::{Mesh, MeshError};

/// What the edge-manifold check found on an accepted mesh.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct EdgeReport {
    /// Every edge use, sorted by edge (see [`edge_uses`]).
    pub(crate) uses: Vec<EdgeUse>,
    /// Edges used by exactly one triangle.
    pub(crate) boundary_edges: usize,
}

/// Rejects duplicate triangles and edges with more than two triangles.
///
/// `origin` gives each face's triangle index in the file, for messages.
pub(crate) fn check_edges(mesh: &Mesh, origin: &[u32]) -> Result<EdgeReport, MeshError> {
    reject_duplicate_faces(mesh, origin)?;
    let uses = edge_uses(mesh);
    let mut boundary_edges = 0;
    for run in by_edge(&uses) {
        match run.len() {
            1 => boundary_edges += 1,
            2 => {}
            n => {
                let [a, b] = run[0].edge;
                let faces: Vec<String> = run
                    .iter()
                    .take(4)
                    .map(|u| ordinal(origin[u.face as usize] as usize))
                    .collect();
                return Err(MeshError::NonManifold {
                    detail: format!(
                        "the edge from {} to {} mm is shared by {n} triangles (the {} \
                         triangles of the file), but a surface edge can border at most two",
                        point(mesh, a),
                        point(mesh, b),
                        faces.join(", ")
                    ),
                });
            }
        }
    }
    Ok(EdgeReport {
        uses,
        boundary_edges,
    })
}

fn reject_duplicate_faces(mesh: &Mesh, origin: &[u32]) -> Result<(), MeshError> {
    let mut keyed: Vec<([u32; 3], u32)> = mesh
        .faces
        .iter()
        .enumerate()
        .map(|(f, face)| {
            let mut k = *face;
            k.sort_unstable();
            (k, f as u32)
        })
        .collect();
    keyed.sort_unstable();
    for pair in keyed.windows(2) {
        if pair[0].0 == pair[1].0 {
            let [a, b, c] = pair[0].0;
            return Err(MeshError::NonManifold {
                detail: format!(
                    "the {} and {} triangles of the file use the same three vertices {}, {} \
                     and {} mm",
                    ordinal(origin[pair[0].1 as usize] as usize),
                    ordinal(origin[pair[1].1 as usize] as usize),
                    point(mesh, a),
                    point(mesh, b),
                    point(mesh, c)
                ),
            });
        }
    }
    Ok(())
}

/// A vertex position for messages: `(x, y, z)` with up to 4 decimals.
fn point(mesh: &Mesh, v: u32) -> String {
    let p = mesh.vertices[v as usize];
    let c = p.map(|x| {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" {
            "0".to_string()
        } else {
            s.to_string()
        }
    });
    format!("({}, {}, {})", c[0], c[1], c[2])
}

/// Vertices where the triangles around them form more than one fan (bow-ties): the
/// surface touches itself at a point there.
pub(crate) fn bowtie_vertices(mesh: &Mesh, uses: &[EdgeUse]) -> usize {
    let corner = |f: u32, v: u32| -> usize {
        let k = mesh.faces[f as usize]
            .iter()
            .position(|&x| x == v)
            .unwrap_or(0);
        3 * f as usize + k
    };
    let mut fans = UnionFind::new(3 * mesh.faces.len());
    for run in by_edge(uses) {
        if let [u, w] = run {
            for v in u.edge {
                fans.union(corner(u.face, v), corner(w.face, v));
            }
        }
    }
    let mut first_fan = vec![usize::MAX; mesh.vertices.len()];
    let mut bowtie = vec![false; mesh.vertices.len()];
    for (f, face) in mesh.faces.iter().enumerate() {
        for (k, &v) in face.iter().enumerate() {
            let fan = fans.find(3 * f + k);
            let seen = &mut first_fan[v as usize];
            if *seen == usize::MAX {
                *seen = fan;
            } else if *seen != fan {
                bowtie[v as usize] = true;
            }
        }
    }
    bowtie.iter().filter(|&&b| b).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, tetrahedron};

    #[test]
    fn closed_cube_has_no_boundary() {
        let c = cube();
        let origin: Vec<u32> = (0..12).collect();
        let r = check_edges(&c, &origin).unwrap();
        assert_eq!(r.boundary_edges, 0);
        assert_eq!(bowtie_vertices(&c, &r.uses), 0);
    }

    #[test]
    fn fin_edge_is_named() {
        // Three triangles on the edge (0,0,0)-(10,0,0).
        let m = Mesh::new(
            vec![
                [0.0; 3],
                [10.0, 0.0, 0.0],
                [0.0, 10.0, 0.0],
                [0.0, -10.0, 0.0],
                [0.0, 0.0, 10.0],
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let e = check_edges(&m, &[0, 1, 2]).unwrap_err();
        assert_eq!(e.code(), "mesh.non_manifold");
        let msg = e.to_string();
        assert!(
            msg.contains("from (0, 0, 0) to (10, 0, 0) mm is shared by 3 triangles"),
            "{msg}"
        );
        assert!(msg.contains("the 1st, 2nd, 3rd triangles"), "{msg}");
    }

    #[test]
    fn duplicate_face_in_any_rotation() {
        let mut t = tetrahedron(0.0);
        t.faces.push([2, 0, 1]);
        let e = check_edges(&t, &[0, 1, 2, 3, 4]).unwrap_err();
        assert_eq!(e.code(), "mesh.non_manifold");
        assert!(e.to_string().contains("the 1st and 5th triangles"), "{e}");
    }

    #[test]
    fn two_tetrahedra_touching_at_a_vertex_make_a_bowtie() {
        let mut m = tetrahedron(0.0);
        let other = tetrahedron(0.0);
        // Reflect the second through vertex 0 so they share only that vertex.
        let p0 = m.vertices[0];
        m.vertices.extend(
            other.vertices[1..]
                .iter()
                .map(|v| [0, 1, 2].map(|k| 2.0 * p0[k] - v[k])),
        );
        m.faces.extend(
            other
                .faces
                .iter()
                .map(|f| f.map(|i| if i == 0 { 0 } else { i + 3 })),
        );
        let origin: Vec<u32> = (0..8).collect();
        let r = check_edges(&m, &origin).unwrap();
        assert_eq!(r.boundary_edges, 0);
        assert_eq!(bowtie_vertices(&m, &r.uses), 1);
    }
}
