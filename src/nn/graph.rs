//! Graph samples and batches of disjoint graphs for the graph networks.
//!
//! A mini-batch of meshes of different sizes is one graph: node features are stacked
//! (`[N, d_x]`, `N` the total vertex count) and the edge index of each mesh is shifted by the
//! number of nodes before it, so one forward pass handles the whole batch.

use std::ops::Range;

use burn::tensor::{Device, Tensor, TensorData};

use super::error::{NnError, check_finite};
use super::slots::{GraphTensors, SlotLayout};
use crate::mesh::Mesh;
use crate::mesh::measures::vertex_normals;
use crate::mesh::topology::edges;

/// Which per-vertex features a graph carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Features {
    /// Positions only (sGCN): `d_x = 3`.
    Spatial,
    /// Positions and angle-weighted vertex normals (hGCN): `d_x = 6`.
    Hybrid,
}

impl Features {
    /// Feature width `d_x`.
    pub fn width(self) -> usize {
        match self {
            Self::Spatial => 3,
            Self::Hybrid => 6,
        }
    }
}

/// One shape as a graph: positions (mm), optional unit normals and undirected edges.
#[derive(Debug, Clone, PartialEq)]
pub struct GraphSample {
    /// Vertex positions in mm, `[n, 3]`.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, `[n, 3]`, for hybrid features.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Undirected edges `[a, b]`; self-loops are added by the batch, not stored here.
    pub edges: Vec<[u32; 2]>,
}

impl GraphSample {
    /// The graph of a mesh: its vertices, its unique edges and, for hybrid features, its
    /// angle-weighted vertex normals.
    pub fn from_mesh(mesh: &Mesh, features: Features) -> Self {
        let to_f32 = |p: &[f64; 3]| p.map(|x| x as f32);
        Self {
            positions: mesh.vertices.iter().map(to_f32).collect(),
            normals: (features == Features::Hybrid)
                .then(|| vertex_normals(mesh).iter().map(to_f32).collect()),
            edges: edges(mesh),
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The features this sample carries.
    pub fn features(&self) -> Features {
        if self.normals.is_some() {
            Features::Hybrid
        } else {
            Features::Spatial
        }
    }

    /// Checks sizes, finiteness and edge indices; `index` names the sample in errors.
    pub fn validate(&self, index: usize) -> Result<(), NnError> {
        let n = self.positions.len();
        if n == 0 {
            return Err(NnError::EmptySample { sample: index });
        }
        check_finite(self.positions.as_flattened(), "positions")?;
        if let Some(normals) = &self.normals {
            if normals.len() != n {
                return Err(NnError::DimensionMismatch {
                    what: "normals",
                    expected: n,
                    found: normals.len(),
                });
            }
            check_finite(normals.as_flattened(), "normals")?;
        }
        for (e, edge) in self.edges.iter().enumerate() {
            if let Some(&vertex) = edge.iter().find(|&&v| v as usize >= n) {
                return Err(NnError::EdgeOutOfRange {
                    sample: index,
                    edge: e,
                    vertex,
                    vertex_count: n,
                });
            }
        }
        Ok(())
    }

    /// Node features `[n, d_x]` row-major, positions mapped by `scaling`.
    fn features_into(&self, scaling: &PositionScaling, out: &mut Vec<f32>) {
        for (i, p) in self.positions.iter().enumerate() {
            out.extend(scaling.apply(*p));
            if let Some(normals) = &self.normals {
                out.extend(normals[i]);
            }
        }
    }
}

/// Maps positions (mm) to network units: `(p − shift) / scale`. Normals are left as they are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionScaling {
    /// Subtracted from every position, mm.
    pub shift: [f32; 3],
    /// Divides the shifted positions, mm.
    pub scale: f32,
}

impl PositionScaling {
    /// The identity map.
    pub const IDENTITY: Self = Self {
        shift: [0.0; 3],
        scale: 1.0,
    };

    /// Centre of all vertices and their root-mean-square distance from it, so that the
    /// training positions have zero mean and unit RMS radius.
    pub fn fit(samples: &[GraphSample]) -> Self {
        let n: usize = samples.iter().map(GraphSample::vertex_count).sum();
        if n == 0 {
            return Self::IDENTITY;
        }
        let points = || samples.iter().flat_map(|s| s.positions.iter());
        let mut mean = [0.0f64; 3];
        for p in points() {
            for d in 0..3 {
                mean[d] += f64::from(p[d]) / n as f64;
            }
        }
        let ms: f64 = points()
            .map(|p| {
                (0..3)
                    .map(|d| (f64::from(p[d]) - mean[d]).powi(2))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / n as f64;
        let scale = if ms > 0.0 { ms.sqrt() as f32 } else { 1.0 };
        Self {
            shift: mean.map(|m| m as f32),
            scale,
        }
    }

    /// `(p − shift) / scale`.
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|d| (p[d] - self.shift[d]) / self.scale)
    }
}

/// Several graphs stacked into one disjoint graph.
#[derive(Debug, Clone, PartialEq)]
pub struct GraphBatch {
    /// Node features `[N, d_x]`, row-major.
    pub features: Vec<f32>,
    /// Feature width `d_x`.
    pub d_x: usize,
    /// Edge index `[2, E]`: row 0, the source node `j` of each message.
    pub sources: Vec<u32>,
    /// Edge index `[2, E]`: row 1, the target node `i`; every node has its self-loop.
    pub targets: Vec<u32>,
    /// Node range of each graph in the stacked features.
    pub node_ranges: Vec<Range<usize>>,
}

impl GraphBatch {
    /// Stacks `samples` (already validated, all with the same features) into one graph.
    /// Edges run both ways, duplicates and given self-loops are dropped, and one self-loop
    /// per node is added; edges are ordered by target, then source.
    pub fn new(samples: &[&GraphSample], scaling: &PositionScaling) -> Self {
        let d_x = samples.first().map_or(3, |s| s.features().width());
        let mut batch = Self {
            features: Vec::new(),
            d_x,
            sources: Vec::new(),
            targets: Vec::new(),
            node_ranges: Vec::with_capacity(samples.len()),
        };
        for sample in samples {
            let offset = batch.node_count();
            let n = sample.vertex_count();
            sample.features_into(scaling, &mut batch.features);
            for (i, neighbours) in neighbour_lists(sample).iter().enumerate() {
                for &j in neighbours {
                    batch.sources.push((offset + j as usize) as u32);
                    batch.targets.push((offset + i) as u32);
                }
            }
            batch.node_ranges.push(offset..offset + n);
        }
        batch
    }

    /// Total number of nodes `N`.
    pub fn node_count(&self) -> usize {
        self.features.len() / self.d_x.max(1)
    }

    /// Number of directed edges `E`, self-loops included.
    pub fn edge_count(&self) -> usize {
        self.sources.len()
    }

    /// Number of graphs.
    pub fn graph_count(&self) -> usize {
        self.node_ranges.len()
    }

    /// The node features as a tensor `[N, d_x]`.
    pub fn feature_tensor(&self, device: &Device) -> Tensor<2> {
        let data = TensorData::new(self.features.clone(), [self.node_count(), self.d_x]);
        Tensor::from_data(data, device)
    }

    /// The edges grouped by source (see [`SlotLayout`]) and the degrees, on `device`.
    pub fn tensors(&self, device: &Device) -> GraphTensors {
        let n = self.node_count();
        let mut degree = vec![0usize; n];
        for &t in &self.targets {
            degree[t as usize] += 1;
        }
        let layout = SlotLayout::new(n, &self.sources, &self.targets);
        GraphTensors::new(&layout, &degree, device)
    }
}

/// For each vertex, itself followed by its neighbours in increasing order.
fn neighbour_lists(sample: &GraphSample) -> Vec<Vec<u32>> {
    let n = sample.vertex_count();
    let mut lists: Vec<Vec<u32>> = (0..n as u32).map(|i| vec![i]).collect();
    for &[a, b] in &sample.edges {
        if a != b {
            lists[a as usize].push(b);
            lists[b as usize].push(a);
        }
    }
    for list in &mut lists {
        list[1..].sort_unstable();
        list.dedup();
    }
    lists
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::tetrahedron;

    fn path(n: u32) -> GraphSample {
        GraphSample {
            positions: (0..n).map(|i| [i as f32, 0.0, 0.0]).collect(),
            normals: None,
            edges: (1..n).map(|i| [i - 1, i]).collect(),
        }
    }

    #[test]
    fn batch_offsets_edges_and_adds_self_loops() {
        let (a, b) = (path(3), path(2));
        let batch = GraphBatch::new(&[&a, &b], &PositionScaling::IDENTITY);
        assert_eq!(batch.node_count(), 5);
        assert_eq!(batch.node_ranges, vec![0..3, 3..5]);
        // path 0-1-2: 3 self-loops + 4 directed; path 3-4: 2 + 2.
        assert_eq!(batch.edge_count(), 11);
        let pairs: Vec<(u32, u32)> = batch
            .sources
            .iter()
            .copied()
            .zip(batch.targets.iter().copied())
            .collect();
        assert_eq!(
            pairs,
            vec![
                (0, 0),
                (1, 0),
                (1, 1),
                (0, 1),
                (2, 1),
                (2, 2),
                (1, 2),
                (3, 3),
                (4, 3),
                (4, 4),
                (3, 4)
            ]
        );
        assert_eq!(&batch.features[9..12], &[0.0, 0.0, 0.0]); // first node of graph b
    }

    #[test]
    fn duplicate_edges_and_self_loops_are_dropped() {
        let mut g = path(3);
        g.edges.extend([[1, 0], [2, 2]]);
        let batch = GraphBatch::new(&[&g], &PositionScaling::IDENTITY);
        assert_eq!(batch.edge_count(), 7);
        let t = batch.tensors(&crate::nn::device::inference_device());
        let inv: Vec<f32> = t.inv_degree.into_data().iter::<f32>().collect();
        assert_eq!(inv, vec![0.5, 1.0 / 3.0, 0.5]);
    }

    #[test]
    fn hybrid_mesh_sample_has_unit_normals_and_six_features() {
        let mesh = tetrahedron(0.0);
        let s = GraphSample::from_mesh(&mesh, Features::Hybrid);
        assert_eq!(s.edges.len(), 6);
        let normals = s.normals.as_ref().unwrap();
        // Corner (1,1,1)·5 points outward along (1,1,1)/√3.
        let k = 1.0 / 3f32.sqrt();
        for c in normals[0] {
            assert!((c - k).abs() < 1e-6);
        }
        let batch = GraphBatch::new(&[&s], &PositionScaling::IDENTITY);
        assert_eq!(batch.d_x, 6);
        assert_eq!(batch.features.len(), 24);
        assert_eq!(batch.edge_count(), 4 + 12);
    }

    #[test]
    fn scaling_centres_and_normalises() {
        let s = GraphSample {
            positions: vec![[1.0, 2.0, 3.0], [3.0, 2.0, 3.0]],
            normals: None,
            edges: vec![],
        };
        let sc = PositionScaling::fit(&[s]);
        assert_eq!(sc.shift, [2.0, 2.0, 3.0]);
        assert!((sc.scale - 1.0).abs() < 1e-6);
        assert_eq!(sc.apply([4.0, 2.0, 3.0]), [2.0, 0.0, 0.0]);
    }

    #[test]
    fn validation_rejects_bad_samples() {
        let mut g = path(3);
        g.edges.push([0, 3]);
        assert_eq!(g.validate(4).unwrap_err().code(), "nn.edge_out_of_range");
        let empty = GraphSample {
            positions: vec![],
            normals: None,
            edges: vec![],
        };
        assert_eq!(empty.validate(0).unwrap_err().code(), "nn.empty_sample");
        let mut nan = path(2);
        nan.positions[1][2] = f32::NAN;
        assert_eq!(nan.validate(0).unwrap_err().code(), "nn.non_finite");
        let mut short = path(2);
        short.normals = Some(vec![[0.0, 0.0, 1.0]]);
        assert_eq!(
            short.validate(0).unwrap_err().code(),
            "nn.dimension_mismatch"
        );
        assert!(path(2).validate(0).is_ok());
    }
}
