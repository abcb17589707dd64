//! Messages grouped by their source node, the layout FeaStConv computes in.
//!
//! Every edge `j → i` is a slot in a row that belongs to its source `j`; a row has `D` slots
//! (unused ones masked out) and a node with more than `D` out-edges gets several rows. All
//! slots of a row share `x_j·W_m`, so the messages of a row are one small matrix product
//! `q_row [D, H] · (x_j W) [H, d_out]`, and no `[E, H, d_out]` tensor is ever formed.

use burn::tensor::{Device, Int, Tensor, TensorData};

/// Largest number of slots per row considered.
const MAX_SLOTS: usize = 32;
/// Fixed cost of a row, in slots, when choosing the row width (one small product per row).
const ROW_COST_SLOTS: usize = 4;

/// Rows of slots on the host: which node each row belongs to and where each slot's message
/// goes.
#[derive(Debug, Clone, PartialEq)]
pub struct SlotLayout {
    /// Slots per row `D`.
    pub slots: usize,
    /// Source node of each row, `[R]`.
    pub row_sources: Vec<u32>,
    /// Target node of each slot, `[R·D]` (an unused slot points at its row's source).
    pub slot_targets: Vec<u32>,
    /// 1 for a used slot, 0 for padding, `[R·D]`.
    pub slot_mask: Vec<f32>,
}

impl SlotLayout {
    /// The layout of the directed edges `sources[e] → targets[e]` on `n` nodes, with the row
    /// width that minimises the padded work.
    pub fn new(n: usize, sources: &[u32], targets: &[u32]) -> Self {
        let mut out: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (&s, &t) in sources.iter().zip(targets) {
            out[s as usize].push(t);
        }
        let max_degree = out.iter().map(Vec::len).max().unwrap_or(1).max(1);
        let cost = |d: usize| -> usize {
            out.iter()
                .map(|l| l.len().div_ceil(d) * (d + ROW_COST_SLOTS))
                .sum()
        };
        let slots = (1..=max_degree.min(MAX_SLOTS))
            .min_by_key(|&d| (cost(d), usize::MAX - d))
            .unwrap_or(1);
        let mut layout = Self {
            slots,
            row_sources: Vec::new(),
            slot_targets: Vec::new(),
            slot_mask: Vec::new(),
        };
        for (j, targets) in out.iter().enumerate() {
            for chunk in targets.chunks(slots) {
                layout.row_sources.push(j as u32);
                for s in 0..slots {
                    layout
                        .slot_targets
                        .push(chunk.get(s).copied().unwrap_or(j as u32));
                    layout
                        .slot_mask
                        .push(if s < chunk.len() { 1.0 } else { 0.0 });
                }
            }
        }
        layout
    }

    /// Number of rows `R`.
    pub fn row_count(&self) -> usize {
        self.row_sources.len()
    }

    /// Whether row `r` is node `r` for every node, so no gather of node rows is needed.
    fn rows_are_nodes(&self, n: usize) -> bool {
        self.row_count() == n
            && self
                .row_sources
                .iter()
                .enumerate()
                .all(|(r, &j)| r == j as usize)
    }
}

/// A batch's edges on a device, ready for graph convolutions.
#[derive(Debug, Clone)]
pub struct GraphTensors {
    /// Source node of each row, `[R]`; `None` when row `r` is node `r`.
    pub row_sources: Option<Tensor<1, Int>>,
    /// Target node of each slot, `[R·D]`.
    pub slot_targets: Tensor<1, Int>,
    /// 1 for a used slot, 0 for padding, `[R, D, 1]`.
    pub slot_mask: Tensor<3>,
    /// `1 / |N(i)|` (self-loop included), `[N, 1]`.
    pub inv_degree: Tensor<2>,
    /// `N`.
    pub node_count: usize,
    /// `R`.
    pub row_count: usize,
    /// `D`.
    pub slots: usize,
}

impl GraphTensors {
    /// Uploads `layout` and the in-degrees `degree` (`[N]`, self-loops included) to `device`.
    pub fn new(layout: &SlotLayout, degree: &[usize], device: &Device) -> Self {
        let n = degree.len();
        let index = |v: &[u32]| {
            let data: Vec<i64> = v.iter().map(|&i| i64::from(i)).collect();
            Tensor::<1, Int>::from_data(TensorData::new(data, [v.len()]), device)
        };
        let r = layout.row_count();
        let inv: Vec<f32> = degree.iter().map(|&d| 1.0 / d.max(1) as f32).collect();
        Self {
            row_sources: (!layout.rows_are_nodes(n)).then(|| index(&layout.row_sources)),
            slot_targets: index(&layout.slot_targets),
            slot_mask: Tensor::from_data(
                TensorData::new(layout.slot_mask.clone(), [r, layout.slots, 1]),
                device,
            ),
            inv_degree: Tensor::from_data(TensorData::new(inv, [n, 1]), device),
            node_count: n,
            row_count: r,
            slots: layout.slots,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_hold_the_out_edges_of_their_source() {
        // Node 0 → 0, 1, 2; node 1 → 0, 1; node 2 → 0, 2.
        let sources = [0, 1, 2, 0, 1, 0, 2];
        let targets = [0, 0, 0, 1, 1, 2, 2];
        let layout = SlotLayout::new(3, &sources, &targets);
        // Width 3 costs 3 rows · (3 + 4) = 21 against 4 · (2 + 4) = 24 for width 2.
        assert_eq!(layout.slots, 3);
        assert_eq!(layout.row_sources, vec![0, 1, 2]);
        assert_eq!(layout.slot_targets, vec![0, 1, 2, 0, 1, 1, 0, 2, 2]);
        assert_eq!(
            layout.slot_mask,
            vec![1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0]
        );
        assert!(layout.rows_are_nodes(3));
    }

    #[test]
    fn a_node_of_high_degree_gets_several_rows() {
        // A star: node 0 joined to 1..=12, every node with its self-loop.
        let mut sources = Vec::new();
        let mut targets = Vec::new();
        for j in 0..13u32 {
            sources.push(j);
            targets.push(j);
        }
        for j in 1..13u32 {
            sources.extend([0, j]);
            targets.extend([j, 0]);
        }
        let layout = SlotLayout::new(13, &sources, &targets);
        assert_eq!(layout.slots, 2);
        assert_eq!(layout.row_count(), 7 + 12);
        assert_eq!(&layout.row_sources[..8], &[0, 0, 0, 0, 0, 0, 0, 1]);
        assert!(!layout.rows_are_nodes(13));
        let used: f32 = layout.slot_mask.iter().sum();
        assert_eq!(used as usize, sources.len());
        let g = GraphTensors::new(&layout, &[13; 13], &crate::nn::device::inference_device());
        assert!(g.row_sources.is_some());
        assert_eq!(g.slot_mask.dims(), [19, 2, 1]);
    }
}
