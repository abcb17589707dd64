//! Cosine scores `S = Z_μ Z_kᵀ` between atlas and shape embeddings, a block of atlas rows
//! at a time.
//!
//! The kernel is plain Rust that the compiler vectorises: the shape rows are regrouped once
//! into panels of 16 rows stored dimension-major, and a pair of atlas rows is multiplied
//! into a panel as 2 × 16 running sums, one broadcast product per dimension. Every score is
//! summed over the dimensions in order, so it does not depend on blocks or threads. (A BLAS-style
//! `f32` product from faer was faster on its own but left the vector unit in a state that
//! made the `exp` calls that follow it about 20× slower on this machine.)

use std::ops::Range;

use super::embeddings::Embeddings;
use crate::models::ModelError;

/// Shape rows per panel (the width of the running sums).
const PANEL: usize = 16;
/// Atlas rows multiplied into a panel together.
const PAIR: usize = 2;

/// Cosine similarities of a block of atlas rows with every shape row, row-major
/// `[rows, N_k]`.
pub(crate) struct ScoreBlock {
    n_k: usize,
    data: Vec<f32>,
}

impl ScoreBlock {
    /// The scores of the block's `r`-th atlas row against every shape row, `[N_k]`.
    pub(crate) fn row(&self, r: usize) -> &[f32] {
        &self.data[r * self.n_k..(r + 1) * self.n_k]
    }

    /// Every score of the block.
    pub(crate) fn values(&self) -> &[f32] {
        &self.data
    }
}

/// Atlas and shape embeddings checked against each other, with their inverse row norms.
pub(crate) struct Scores<'a> {
    atlas: &'a Embeddings,
    shape: &'a Embeddings,
    atlas_inverse_norms: Vec<f32>,
    shape_inverse_norms: Vec<f32>,
    /// The shape rows in panels of [`PANEL`]: panel `p` holds, for every dimension `k`, the
    /// values `z_k[16p + t][k]` for `t < 16` (zero past the last row), `[panels, d, 16]`.
    panels: Vec<[f32; PANEL]>,
}

impl<'a> Scores<'a> {
    /// Checks both embeddings and that their dimensions agree.
    pub(crate) fn new(atlas: &'a Embeddings, shape: &'a Embeddings) -> Result<Self, ModelError> {
        atlas.check()?;
        shape.check()?;
        if atlas.dim != shape.dim {
            return Err(ModelError::InvalidInput(format!(
                "atlas embeddings have dimension {} but the shape's have {}",
                atlas.dim, shape.dim
            )));
        }
        Ok(Self {
            atlas,
            shape,
            atlas_inverse_norms: atlas.inverse_norms(),
            shape_inverse_norms: shape.inverse_norms(),
            panels: panels_of(shape),
        })
    }

    /// `N_μ`.
    pub(crate) fn atlas_rows(&self) -> usize {
        self.atlas.rows
    }

    /// `N_k`.
    pub(crate) fn shape_rows(&self) -> usize {
        self.shape.rows
    }

    /// Work per atlas row, for deciding whether to use threads.
    pub(crate) fn cost_per_row(&self) -> usize {
        self.shape.rows.saturating_mul(self.shape.dim)
    }

    /// The scores `cos(z_μj, z_ki)` of the atlas rows `rows` (within `0..N_μ`).
    pub(crate) fn block(&self, rows: Range<usize>) -> ScoreBlock {
        let (n_k, dim) = (self.shape.rows, self.shape.dim);
        let atlas_row = |j: usize| &self.atlas.data[j * dim..(j + 1) * dim];
        let b = rows.len();
        let mut data = vec![0.0f32; b * n_k];
        for r0 in (0..b).step_by(PAIR) {
            // A lone last row is paired with itself; the copy is not stored.
            let rs = [r0, (r0 + 1).min(b - 1)];
            let a = rs.map(|r| atlas_row(rows.start + r));
            let a_inv = rs.map(|r| self.atlas_inverse_norms[rows.start + r]);
            for (p, panel) in self.panels.chunks_exact(dim.max(1)).enumerate() {
                let sums = pair_times_panel(a, panel);
                let i0 = p * PANEL;
                let width = PANEL.min(n_k - i0);
                for (t, r) in rs.iter().enumerate().take(b - r0) {
                    let out = &mut data[r * n_k + i0..r * n_k + i0 + width];
                    let inv = &self.shape_inverse_norms[i0..i0 + width];
                    for ((o, s), b_inv) in out.iter_mut().zip(&sums[t]).zip(inv) {
                        *o = s * a_inv[t] * b_inv;
                    }
                }
            }
        }
        ScoreBlock { n_k, data }
    }
}

/// Regroups the shape rows into dimension-major panels of [`PANEL`] rows.
fn panels_of(shape: &Embeddings) -> Vec<[f32; PANEL]> {
    let (n, dim) = (shape.rows, shape.dim);
    let mut panels = vec![[0.0f32; PANEL]; n.div_ceil(PANEL) * dim];
    for (i, row) in shape.row_iter().enumerate() {
        let (p, t) = (i / PANEL, i % PANEL);
        for (k, v) in row.iter().enumerate() {
            panels[p * dim + k][t] = *v;
        }
    }
    panels
}

/// `Σ_k a_r[k] · panel[k][t]` for both atlas rows `r` and the 16 panel rows `t`.
fn pair_times_panel(a: [&[f32]; PAIR], panel: &[[f32; PANEL]]) -> [[f32; PANEL]; PAIR] {
    let mut acc = [[0.0f32; PANEL]; PAIR];
    for ((column, x0), x1) in panel.iter().zip(a[0]).zip(a[1]) {
        for t in 0..PANEL {
            acc[0][t] += x0 * column[t];
            acc[1][t] += x1 * column[t];
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    fn emb(rows: usize, dim: usize, seed: u32) -> Embeddings {
        // Deterministic values in [-1, 1] without a random generator.
        let data = (0..rows * dim)
            .map(|k| {
                let x = (k as u32).wrapping_mul(2_654_435_761).wrapping_add(seed);
                (x >> 8) as f32 / (1u32 << 23) as f32 - 1.0
            })
            .collect();
        Embeddings::new(rows, dim, data).unwrap()
    }

    #[test]
    fn scores_match_plain_cosines_for_odd_sizes() {
        // 7 atlas rows (a short tile), 5 shape rows (a short pair), dimension 11 (a tail).
        let (atlas, shape) = (emb(7, 11, 1), emb(5, 11, 2));
        let scores = Scores::new(&atlas, &shape).unwrap();
        let block = scores.block(2..7);
        for r in 0..5 {
            for i in 0..5 {
                let a = &atlas.data[(r + 2) * 11..(r + 3) * 11];
                let b = &shape.data[i * 11..(i + 1) * 11];
                let dot: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x * y)).sum();
                let na: f64 = a.iter().map(|x| f64::from(x * x)).sum::<f64>().sqrt();
                let nb: f64 = b.iter().map(|x| f64::from(x * x)).sum::<f64>().sqrt();
                let got = f64::from(block.row(r)[i]);
                assert!(
                    (got - dot / (na * nb)).abs() < 1e-6,
                    "{got} vs {}",
                    dot / (na * nb)
                );
            }
        }
        assert_eq!(block.values().len(), 25);
    }

    #[test]
    fn a_row_scores_the_same_in_any_block() {
        let (atlas, shape) = (emb(9, 16, 3), emb(300, 16, 4));
        let scores = Scores::new(&atlas, &shape).unwrap();
        let whole = scores.block(0..9);
        let part = scores.block(5..6);
        assert_eq!(whole.row(5), part.row(0));
    }
}
