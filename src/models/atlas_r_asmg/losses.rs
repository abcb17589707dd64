//! The refinement's loss terms (thesis eqs. 5.8–5.9) with their gradients, computed
//! outside the network: nearest neighbours come from k-d trees, so memory stays linear in
//! the vertex counts.
//!
//! - Chamfer: `CD(a, b) = Σ_i min_j ‖a_i − b_j‖² + Σ_j min_i ‖b_j − a_i‖²` (the thesis's
//!   sum of squared distances, both ways; units², not a mean);
//! - Laplacian (umbrella) energy: `E(b) = Σ_j ‖b_j − mean_{q∈N(j)} b_q‖²`.
//!
//! Both gradients are with respect to `b` (`[n_b, 3]`), with the nearest-neighbour
//! assignment held fixed (it is piecewise constant).

use crate::geometry::kdtree::PointCloudIndex;
use crate::mesh::adjacency::Adjacency;
use crate::models::ModelError;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add_scaled(acc: &mut [f64; 3], v: [f64; 3], k: f64) {
    for d in 0..3 {
        acc[d] += k * v[d];
    }
}

/// `CD(a, b)` and `∂CD/∂b`. `a_index` indexes `a` (built once per target shape).
pub fn chamfer_squared(
    a: &[[f64; 3]],
    a_index: &PointCloudIndex,
    b: &[[f64; 3]],
) -> Result<(f64, Vec<[f64; 3]>), ModelError> {
    if a.len() != a_index.len() {
        return Err(ModelError::InvalidInput(format!(
            "the index holds {} points but the target has {}",
            a_index.len(),
            a.len()
        )));
    }
    let b_index = PointCloudIndex::new(b)?;
    let mut value = 0.0;
    let mut gradient = vec![[0.0; 3]; b.len()];
    for p in a {
        let (j, d) = b_index.nearest(*p);
        value += d * d;
        add_scaled(&mut gradient[j], sub(b[j], *p), 2.0);
    }
    for (j, q) in b.iter().enumerate() {
        let (i, d) = a_index.nearest(*q);
        value += d * d;
        add_scaled(&mut gradient[j], sub(*q, a[i]), 2.0);
    }
    Ok((value, gradient))
}

/// The umbrella residuals `r_j = b_j − mean_{q∈N(j)} b_q` (0 for isolated vertices).
fn umbrella_residuals(adjacency: &Adjacency, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    (0..b.len())
        .map(|j| {
            let neighbours = adjacency.neighbours(j);
            if neighbours.is_empty() {
                return [0.0; 3];
            }
            let mut mean = [0.0; 3];
            for &q in neighbours {
                add_scaled(&mut mean, b[q as usize], 1.0 / neighbours.len() as f64);
            }
            sub(b[j], mean)
        })
        .collect()
}

/// `E(b) = Σ_j ‖r_j‖²` and `∂E/∂b`: `2 r_m − 2 Σ_{j∈N(m)} r_j / deg_j` (the adjacency is
/// symmetric).
pub fn laplacian_energy(
    adjacency: &Adjacency,
    b: &[[f64; 3]],
) -> Result<(f64, Vec<[f64; 3]>), ModelError> {
    if adjacency.vertex_count() != b.len() {
        return Err(ModelError::InvalidInput(format!(
            "the atlas has {} vertices but the shape {}",
            adjacency.vertex_count(),
            b.len()
        )));
    }
    let r = umbrella_residuals(adjacency, b);
    let value = r
        .iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .sum();
    let gradient = (0..b.len())
        .map(|m| {
            let mut g = [0.0; 3];
            add_scaled(&mut g, r[m], 2.0);
            for &j in adjacency.neighbours(m) {
                let j = j as usize;
                add_scaled(&mut g, r[j], -2.0 / adjacency.degree(j) as f64);
            }
            g
        })
        .collect();
    Ok((value, gradient))
}

#[cfg(test)]
#[path = "losses_tests.rs"]
mod tests;
