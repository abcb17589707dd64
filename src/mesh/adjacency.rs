//! Vertex adjacency of a mesh in compressed sparse row form (for graph convolutions,
//! Laplacians and smoothing).

use super::Mesh;
use super::topology::edges;

/// Neighbours of every vertex through mesh edges, in CSR form.
///
/// The neighbours of vertex `v` are `neighbours[offsets[v]..offsets[v + 1]]`, sorted
/// ascending; `offsets` has `n_vertices + 1` entries.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Adjacency {
    /// Start of each vertex's neighbour list, `[n_vertices + 1]`.
    pub offsets: Vec<u32>,
    /// Concatenated neighbour lists, `[2 · n_edges]`.
    pub neighbours: Vec<u32>,
}

impl Adjacency {
    /// The adjacency of the unique undirected edges of `mesh`.
    pub fn from_mesh(mesh: &Mesh) -> Self {
        let n = mesh.vertices.len();
        let edges = edges(mesh);
        let mut degree = vec![0u32; n];
        for &[a, b] in &edges {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        for d in &degree {
            offsets.push(offsets[offsets.len() - 1] + d);
        }
        let mut fill: Vec<u32> = offsets[..n].to_vec();
        let mut neighbours = vec![0u32; 2 * edges.len()];
        for &[a, b] in &edges {
            neighbours[fill[a as usize] as usize] = b;
            fill[a as usize] += 1;
            neighbours[fill[b as usize] as usize] = a;
            fill[b as usize] += 1;
        }
        for v in 0..n {
            neighbours[offsets[v] as usize..offsets[v + 1] as usize].sort_unstable();
        }
        Self {
            offsets,
            neighbours,
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// The sorted neighbours of vertex `v` (panics if `v` is not a vertex).
    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Number of neighbours of vertex `v`.
    pub fn degree(&self, v: usize) -> usize {
        (self.offsets[v + 1] - self.offsets[v]) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, tetrahedron};

    #[test]
    fn tetrahedron_is_complete() {
        let a = Adjacency::from_mesh(&tetrahedron(0.0));
        assert_eq!(a.vertex_count(), 4);
        assert_eq!(a.neighbours(0), &[1, 2, 3]);
        assert_eq!(a.neighbours(2), &[0, 1, 3]);
        assert_eq!(a.degree(3), 3);
    }

    #[test]
    fn cube_degrees_follow_the_diagonals() {
        // Corner 0 touches no face diagonal; corner 1 touches two (1-2 and 1-4).
        let a = Adjacency::from_mesh(&cube());
        assert_eq!(a.neighbours(0), &[1, 2, 4]);
        assert_eq!(a.neighbours(1), &[0, 2, 3, 4, 5]);
        let degrees: Vec<usize> = (0..8).map(|v| a.degree(v)).collect();
        assert_eq!(degrees.iter().sum::<usize>(), 36);
        assert_eq!(a.offsets.len(), 9);
    }

    #[test]
    fn isolated_vertex_has_no_neighbours() {
        let mut m = tetrahedron(0.0);
        m.vertices.push([9.0; 3]);
        let a = Adjacency::from_mesh(&m);
        assert_eq!(a.neighbours(4), &[] as &[u32]);
        assert_eq!(a.degree(4), 0);
    }
}
