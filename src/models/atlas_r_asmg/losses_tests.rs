//! The loss terms against hand-computed values and finite differences.

use super::*;
use crate::mesh::fixtures::tetrahedron;

#[test]
fn chamfer_of_hand_made_points_is_the_hand_computed_sum() {
    // a: (0,0,0) and (4,0,0); b: (1,0,0) and (0,2,0).
    // a→b: (0,0,0)→(1,0,0) is 1; (4,0,0)→(1,0,0) is 9. b→a: (1,0,0)→(0,0,0) is 1;
    // (0,2,0)→(0,0,0) is 4. CD = 1 + 9 + 1 + 4 = 15.
    let a = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]];
    let b = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
    let index = PointCloudIndex::new(&a).unwrap();
    let (value, gradient) = chamfer_squared(&a, &index, &b).unwrap();
    assert!((value - 15.0).abs() < 1e-12, "{value}");
    // b0 gets 2(b0 − a0) + 2(b0 − a1) from a→b and 2(b0 − a0) from b→a:
    // (2,0,0) + (−6,0,0) + (2,0,0) = (−2,0,0); b1 gets 2(b1 − a0) = (0,4,0).
    assert_eq!(gradient, vec![[-2.0, 0.0, 0.0], [0.0, 4.0, 0.0]]);
}

/// Central differences of `f` at `b`, coordinate by coordinate.
fn finite_differences(f: impl Fn(&[[f64; 3]]) -> f64, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let eps = 1e-6;
    (0..b.len())
        .map(|j| {
            std::array::from_fn(|d| {
                let mut plus = b.to_vec();
                let mut minus = b.to_vec();
                plus[j][d] += eps;
                minus[j][d] -= eps;
                (f(&plus) - f(&minus)) / (2.0 * eps)
            })
        })
        .collect()
}

fn assert_close(analytic: &[[f64; 3]], numeric: &[[f64; 3]]) {
    for (a, n) in analytic.iter().zip(numeric) {
        for d in 0..3 {
            assert!((a[d] - n[d]).abs() < 1e-5, "{a:?} vs {n:?}");
        }
    }
}

#[test]
fn chamfer_gradient_matches_finite_differences() {
    // Points in general position, so no nearest neighbour changes within ±1e-6.
    let a = [
        [0.1, 0.3, -0.2],
        [2.0, 0.5, 0.7],
        [-1.3, 1.1, 0.4],
        [0.6, -1.8, 1.9],
        [1.4, 2.2, -0.9],
    ];
    let b = [[0.4, 0.1, 0.2], [1.7, 1.2, 0.1], [-0.8, 0.9, 1.3]];
    let index = PointCloudIndex::new(&a).unwrap();
    let (_, gradient) = chamfer_squared(&a, &index, &b).unwrap();
    let numeric = finite_differences(|b| chamfer_squared(&a, &index, b).unwrap().0, &b);
    assert_close(&gradient, &numeric);
}

#[test]
fn laplacian_energy_is_zero_for_a_uniform_shape_and_its_gradient_matches() {
    let mesh = tetrahedron(0.0);
    let adjacency = Adjacency::from_mesh(&mesh);
    // Every vertex of a tetrahedron neighbours the other three: all at one point, r = 0.
    let same = vec![[1.0, 2.0, 3.0]; 4];
    assert_eq!(laplacian_energy(&adjacency, &same).unwrap().0, 0.0);
    // Vertex 0 at (3,0,0), the rest at the origin: r_0 = (3,0,0) and r_j = (−1,0,0) for
    // the others (the mean of their neighbours is (1,0,0)); E = 9 + 3·1 = 12.
    let mut b = vec![[0.0; 3]; 4];
    b[0] = [3.0, 0.0, 0.0];
    let (value, _) = laplacian_energy(&adjacency, &b).unwrap();
    assert!((value - 12.0).abs() < 1e-12, "{value}");
    let b: Vec<[f64; 3]> = mesh
        .vertices
        .iter()
        .enumerate()
        .map(|(i, p)| {
            [
                p[0] + 0.1 * i as f64,
                p[1] - 0.05,
                p[2] + 0.02 * (i * i) as f64,
            ]
        })
        .collect();
    let (_, gradient) = laplacian_energy(&adjacency, &b).unwrap();
    let numeric = finite_differences(|b| laplacian_energy(&adjacency, b).unwrap().0, &b);
    assert_close(&gradient, &numeric);
}
