//! Several atlases (thesis §5.4, eqs. 5.13–5.15; SPEC §2.8): the soft membership of every
//! shape in every atlas's cluster, and the atlas update weighted by it. Pure building
//! blocks of the multi-atlas model.
//!
//! - `d_km = mean_j ‖h^m_kj − x_μm,j‖²` (mm²) is how far shape `k`'s normalised shape on atlas
//!   `m` lies from that atlas;
//! - `w_km = softmax over m of (−α·d_km)` with `α = 1/std(d)` over the whole `K × M` matrix;
//! - atlas `m` minimises `½ Σ_k w_km ‖h'^m_k − X_μm‖² + (γ_m/2)·Σ_edges‖x_j − x_q‖²`: the
//!   system `(Σ_k w_km · I + γ_m L) X = Σ_k w_km h'^m_k` (positions) or its displacement
//!   form, damped, with `γ_m = N_μm / max deg` by default.

use super::atlas::{AtlasUpdateParams, damp, default_gamma_mu};
use super::laplacian::{LaplacianSolver, checked_adjacency};
use super::smoothing::Smoothing;
use crate::mesh::Mesh;
use crate::models::ModelError;

/// `d_km`: the mean squared distance (mm²) between a normalised shape and its atlas
/// (`[N_μ, 3]` each).
pub fn atlas_distance(normalised: &[[f64; 3]], atlas: &[[f64; 3]]) -> Result<f64, ModelError> {
    if normalised.len() != atlas.len() || atlas.is_empty() {
        return Err(ModelError::InvalidInput(format!(
            "a normalised shape of {} vertices against an atlas of {}",
            normalised.len(),
            atlas.len()
        )));
    }
    let sum: f64 = normalised
        .iter()
        .zip(atlas)
        .map(|(h, x)| (0..3).map(|d| (h[d] - x[d]).powi(2)).sum::<f64>())
        .sum();
    Ok(sum / atlas.len() as f64)
}

/// `w_km` from `d[k][m]` (`K × M`, every row the same length): each row sums to one. With
/// all distances equal (no spread) every shape belongs to every cluster equally.
pub fn soft_weights(d: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, ModelError> {
    let alpha = sharpness(d)?;
    d.iter().map(|row| weights_at(row, alpha)).collect()
}

/// `α = 1/std(d)` over the whole `K × M` matrix (1/mm²; 0 when every distance is equal).
pub fn sharpness(d: &[Vec<f64>]) -> Result<f64, ModelError> {
    let m = d.first().map_or(0, Vec::len);
    if m == 0 || d.iter().any(|row| row.len() != m) {
        return Err(ModelError::InvalidInput(
            "cluster distances need K rows of M ≥ 1 values each".to_owned(),
        ));
    }
    if d.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ModelError::Numerical(
            "a cluster distance is not finite".to_owned(),
        ));
    }
    let n = (d.len() * m) as f64;
    let mean = d.iter().flatten().sum::<f64>() / n;
    let variance = d.iter().flatten().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    Ok(if variance > 0.0 {
        1.0 / variance.sqrt()
    } else {
        0.0
    })
}

/// One shape's weights `softmax_m(−α·d_m)` from its distances to the `M` atlases (mm²),
/// with the sharpness `α` of the training shapes (also how an unseen shape is assigned).
pub fn weights_at(distances: &[f64], alpha: f64) -> Result<Vec<f64>, ModelError> {
    if distances.is_empty() || distances.iter().any(|v| !v.is_finite()) || !alpha.is_finite() {
        return Err(ModelError::Numerical(
            "cluster distances must be finite and at least one".to_owned(),
        ));
    }
    let best = distances.iter().copied().fold(f64::INFINITY, f64::min);
    let e: Vec<f64> = distances
        .iter()
        .map(|v| (-alpha * (v - best)).exp())
        .collect();
    let total: f64 = e.iter().sum();
    Ok(e.iter().map(|v| v / total).collect())
}

/// One damped update of `atlas` from the shapes normalised to it (`smoothed[k]`,
/// `[N_μ, 3]` mm) weighted by `weights[k] ≥ 0` (not all zero).
pub fn weighted_atlas_update(
    atlas: &Mesh,
    smoothed: &[Vec<[f64; 3]>],
    weights: &[f64],
    params: &AtlasUpdateParams,
) -> Result<Mesh, ModelError> {
    let n = atlas.vertex_count();
    if smoothed.len() != weights.len() || smoothed.iter().any(|s| s.len() != n) {
        return Err(ModelError::InvalidInput(format!(
            "{} weights for {} shapes on an atlas of {n} vertices",
            weights.len(),
            smoothed.len()
        )));
    }
    if weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(ModelError::InvalidInput(
            "cluster weights must be finite and >= 0".to_owned(),
        ));
    }
    let total: f64 = weights.iter().sum();
    if total <= 0.0 {
        return Err(ModelError::InvalidInput(
            "the atlas has no shape with a positive weight".to_owned(),
        ));
    }
    let adjacency = checked_adjacency(atlas)?;
    let gamma = params
        .gamma_mu
        .unwrap_or_else(|| default_gamma_mu(&adjacency));
    let solver = LaplacianSolver::new(&adjacency, total, gamma)?;
    let mut rhs = vec![[0.0; 3]; n];
    for (shape, &w) in smoothed.iter().zip(weights) {
        for ((r, h), x) in rhs.iter_mut().zip(shape).zip(&atlas.vertices) {
            for d in 0..3 {
                r[d] += w * match params.target {
                    Smoothing::Positions => h[d],
                    Smoothing::Displacement => h[d] - x[d],
                };
            }
        }
    }
    let solved = solver.solve(&rhs)?;
    let update: Vec<[f64; 3]> = match params.target {
        Smoothing::Positions => solved,
        Smoothing::Displacement => atlas
            .vertices
            .iter()
            .zip(&solved)
            .map(|(x, u)| std::array::from_fn(|d| x[d] + u[d]))
            .collect(),
    };
    Ok(Mesh::new(
        damp(&atlas.vertices, &update, params.damping)?,
        atlas.faces.clone(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::cube;
    use crate::models::asmg::atlas::update_atlas;

    #[test]
    fn soft_weights_of_a_hand_made_matrix() {
        // d = [[0, 2], [2, 0]]: mean 1, std 1, α = 1; row 0: e^0, e^−2 → 1/(1+e^−2).
        let w = soft_weights(&[vec![0.0, 2.0], vec![2.0, 0.0]]).unwrap();
        let expected = 1.0 / (1.0 + (-2.0f64).exp());
        assert!((w[0][0] - expected).abs() < 1e-12, "{w:?}");
        assert!((w[1][1] - expected).abs() < 1e-12, "{w:?}");
        // Three clusters, K = 2: d = [[1, 3, 5], [4, 4, 4]]: mean 3.5, variance
        // (6.25 + 0.25 + 2.25 + 0.25·3)/6 = 1.5833…; row 1 is uniform.
        let d = [vec![1.0, 3.0, 5.0], vec![4.0, 4.0, 4.0]];
        let w = soft_weights(&d).unwrap();
        let alpha = 1.0 / (9.5f64 / 6.0).sqrt();
        let e: Vec<f64> = [0.0, -2.0 * alpha, -4.0 * alpha]
            .iter()
            .map(|v: &f64| v.exp())
            .collect();
        let s: f64 = e.iter().sum();
        for m in 0..3 {
            assert!((w[0][m] - e[m] / s).abs() < 1e-12, "{w:?}");
            assert!((w[1][m] - 1.0 / 3.0).abs() < 1e-12, "{w:?}");
        }
        for row in &w {
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        assert!(soft_weights(&[vec![1.0], vec![1.0, 2.0]]).is_err());
    }

    #[test]
    fn one_hot_weights_give_the_single_atlas_update_of_that_clusters_shapes() {
        let atlas = cube();
        let shape = |k: f64| -> Vec<[f64; 3]> {
            atlas
                .vertices
                .iter()
                .map(|p| [p[0] * k, p[1] + 0.1 * k, p[2] - k])
                .collect()
        };
        let all = vec![shape(1.1), shape(0.8), shape(1.3)];
        for target in [Smoothing::Displacement, Smoothing::Positions] {
            let params = AtlasUpdateParams {
                target,
                ..AtlasUpdateParams::default()
            };
            let weighted = weighted_atlas_update(&atlas, &all, &[1.0, 0.0, 1.0], &params).unwrap();
            let chosen = [all[0].clone(), all[2].clone()];
            let single = update_atlas(&atlas, &chosen, &params).unwrap();
            for (a, b) in weighted.vertices.iter().zip(&single.vertices) {
                for d in 0..3 {
                    assert!((a[d] - b[d]).abs() < 1e-9, "{target:?}: {a:?} vs {b:?}");
                }
            }
        }
        let none = weighted_atlas_update(&atlas, &all, &[0.0; 3], &AtlasUpdateParams::default());
        assert!(none.is_err());
    }

    #[test]
    fn atlas_distance_is_the_mean_squared_vertex_distance() {
        let d = atlas_distance(&[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]], &[[0.0; 3], [0.0; 3]]).unwrap();
        assert!((d - 2.5).abs() < 1e-12);
    }
}
