//! Combinatorial structure of a triangle mesh: edges, Euler characteristic, connected
//! components, and the sorted edge-use list the validation works on.

use super::Mesh;

/// One side of an edge as used by a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct EdgeUse {
    /// The edge's vertices, smaller first.
    pub(crate) edge: [u32; 2],
    /// The face using it.
    pub(crate) face: u32,
    /// Whether the face runs from `edge[0]` to `edge[1]`.
    pub(crate) forward: bool,
}

/// Every edge use of every face (`3 · n_faces`), sorted by edge, then face.
pub(crate) fn edge_uses(mesh: &Mesh) -> Vec<EdgeUse> {
    let mut uses = Vec::with_capacity(3 * mesh.faces.len());
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            uses.push(EdgeUse {
                edge: [a.min(b), a.max(b)],
                face: f as u32,
                forward: a < b,
            });
        }
    }
    uses.sort_unstable();
    uses
}

/// Runs of uses of the same edge in a sorted edge-use list.
pub(crate) fn by_edge(uses: &[EdgeUse]) -> impl Iterator<Item = &[EdgeUse]> {
    uses.chunk_by(|a, b| a.edge == b.edge)
}

/// Unique undirected edges `[a, b]` with `a < b`, sorted.
pub fn edges(mesh: &Mesh) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = mesh
        .faces
        .iter()
        .flat_map(|f| [[f[0], f[1]], [f[1], f[2]], [f[2], f[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Euler characteristic V − E + F (2 for a closed surface of genus 0).
pub fn euler_characteristic(mesh: &Mesh) -> i64 {
    mesh.vertices.len() as i64 - edges(mesh).len() as i64 + mesh.faces.len() as i64
}

/// Connected components through faces: the count and a label per vertex, `[n_vertices]`.
///
/// Labels are numbered in order of each component's smallest vertex; a vertex in no face
/// is a component of its own.
pub fn connected_components(mesh: &Mesh) -> (usize, Vec<u32>) {
    let mut sets = UnionFind::new(mesh.vertices.len());
    for &[a, b, c] in &mesh.faces {
        sets.union(a as usize, b as usize);
        sets.union(a as usize, c as usize);
    }
    let mut label_of_root = vec![u32::MAX; mesh.vertices.len()];
    let mut labels = Vec::with_capacity(mesh.vertices.len());
    let mut count = 0;
    for v in 0..mesh.vertices.len() {
        let root = sets.find(v);
        if label_of_root[root] == u32::MAX {
            label_of_root[root] = count;
            count += 1;
        }
        labels.push(label_of_root[root]);
    }
    (count as usize, labels)
}

/// Disjoint sets over `0..n` with path halving and union by size.
pub(crate) struct UnionFind {
    parent: Vec<usize>,
    size: Vec<usize>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
            size: vec![1; n],
        }
    }

    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a;
        self.size[a] += self.size[b];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, tetrahedron, uv_sphere};

    #[test]
    fn cube_and_tetrahedron_counts() {
        let c = cube();
        assert_eq!(edges(&c).len(), 18);
        assert_eq!(euler_characteristic(&c), 2);
        let t = tetrahedron(0.0);
        assert_eq!(
            edges(&t),
            vec![[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
        );
        assert_eq!(euler_characteristic(&t), 2);
        assert_eq!(euler_characteristic(&uv_sphere(3.0, [0.0; 3], 8, 12)), 2);
    }

    #[test]
    fn components_label_by_smallest_vertex() {
        // Vertices 0..4 tetrahedron B (offset), 4..8 tetrahedron A, vertex 8 isolated.
        let a = tetrahedron(0.0);
        let mut m = tetrahedron(20.0);
        m.vertices.extend(&a.vertices);
        m.faces.extend(a.faces.iter().map(|f| f.map(|i| i + 4)));
        m.vertices.push([99.0; 3]);
        let (n, labels) = connected_components(&m);
        assert_eq!(n, 3);
        assert_eq!(labels, vec![0, 0, 0, 0, 1, 1, 1, 1, 2]);
        assert_eq!(euler_characteristic(&m), 9 - 12 + 8);
    }

    #[test]
    fn edge_uses_pair_up_on_a_closed_surface() {
        let uses = edge_uses(&cube());
        assert_eq!(uses.len(), 36);
        for run in by_edge(&uses) {
            assert_eq!(run.len(), 2);
            assert_ne!(run[0].forward, run[1].forward, "{run:?}");
        }
    }
}
