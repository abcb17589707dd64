use super::*;
use crate::mesh::fixtures::cube;
use crate::mesh::measures::volume_ml;
use crate::mesh::phantom::{Family, subject};
use crate::models::asmg::laplacian::distance;

fn shifted(points: &[[f64; 3]], by: [f64; 3]) -> Vec<[f64; 3]> {
    points
        .iter()
        .map(|p| [p[0] + by[0], p[1] + by[1], p[2] + by[2]])
        .collect()
}

fn params(gamma_mu: Option<f64>, damping: f64, target: Smoothing) -> AtlasUpdateParams {
    AtlasUpdateParams {
        gamma_mu,
        damping,
        target,
    }
}

#[test]
fn default_gamma_mu_of_a_cube() {
    // 8 vertices; six corners touch two face diagonals (degree 5), two touch none.
    let a = checked_adjacency(&cube()).unwrap();
    assert!((default_gamma_mu(&a) - 8.0 / 5.0).abs() < 1e-15);
}

#[test]
fn without_smoothing_the_update_is_the_mean_shape() {
    let atlas = cube();
    let shapes = vec![
        shifted(&atlas.vertices, [2.0, 0.0, 0.0]),
        shifted(&atlas.vertices, [0.0, -4.0, 0.0]),
    ];
    for target in [Smoothing::Positions, Smoothing::Displacement] {
        let updated = update_atlas(&atlas, &shapes, &params(Some(0.0), 1.0, target)).unwrap();
        let expect = shifted(&atlas.vertices, [1.0, -2.0, 0.0]);
        for (u, e) in updated.vertices.iter().zip(&expect) {
            assert!(distance(*u, *e) < 1e-12);
        }
        assert_eq!(updated.faces, atlas.faces);
        // Damping 1/4 moves a quarter of the way.
        let damped = update_atlas(&atlas, &shapes, &params(Some(0.0), 0.25, target)).unwrap();
        let expect = shifted(&atlas.vertices, [0.25, -0.5, 0.0]);
        for (u, e) in damped.vertices.iter().zip(&expect) {
            assert!(distance(*u, *e) < 1e-12);
        }
    }
}

#[test]
fn a_translation_of_the_shapes_moves_the_update_alike() {
    // L·1 = 0: shifting every shape shifts the update by the same amount, for any γ_μ.
    let atlas = subject(Family::Lv, 4, 0).canonical_mesh();
    let base = vec![atlas.vertices.clone(); 3];
    let moved: Vec<Vec<[f64; 3]>> = base.iter().map(|s| shifted(s, [0.0, 0.0, 7.0])).collect();
    for target in [Smoothing::Positions, Smoothing::Displacement] {
        let updater = AtlasUpdater::new(&atlas, 3, &params(None, 1.0, target)).unwrap();
        let a = updater.update(&atlas.vertices, &base).unwrap();
        let b = updater.update(&atlas.vertices, &moved).unwrap();
        for (p, q) in a.iter().zip(&b) {
            assert!((q[2] - p[2] - 7.0).abs() < 1e-9 && (q[0] - p[0]).abs() < 1e-9);
        }
    }
}

#[test]
fn displacement_updates_keep_the_atlas_and_positions_shrink_it() {
    // Three shapes equal to the atlas, thesis γ_μ: the displacement update returns the
    // atlas exactly; smoothing positions with γ_μ / K ≈ 50 shrinks it.
    let atlas = subject(Family::Lv, 4, 2).canonical_mesh();
    let shapes = vec![atlas.vertices.clone(); 3];
    let d = update_atlas(&atlas, &shapes, &params(None, 1.0, Smoothing::Displacement)).unwrap();
    assert_eq!(d.vertices, atlas.vertices);
    let p = update_atlas(&atlas, &shapes, &params(None, 1.0, Smoothing::Positions)).unwrap();
    assert!(volume_ml(&p) < 0.8 * volume_ml(&atlas));
}

#[test]
fn iterative_and_closed_form_updates_agree() {
    let atlas = subject(Family::Lv, 4, 1).canonical_mesh();
    let shapes: Vec<Vec<[f64; 3]>> = (0..4)
        .map(|k| {
            let s = 1.0 + 0.03 * k as f64;
            atlas.vertices.iter().map(|p| p.map(|c| s * c)).collect()
        })
        .collect();
    let gamma_mu = 3.0;
    let closed = AtlasUpdater::new(
        &atlas,
        4,
        &params(Some(gamma_mu), 1.0, Smoothing::Positions),
    )
    .unwrap()
    .solve(&shapes)
    .unwrap();
    let adjacency = checked_adjacency(&atlas).unwrap();
    let (iterated, sweeps) = iterative_update(
        &adjacency,
        &shapes,
        gamma_mu,
        &atlas.vertices,
        20_000,
        1e-13,
    )
    .unwrap();
    assert!(sweeps < 20_000);
    let worst = closed
        .iter()
        .zip(&iterated)
        .map(|(a, b)| distance(*a, *b))
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "closed form and eq. 4.7 differ by {worst} mm");
}

#[test]
fn bad_inputs_are_errors() {
    let atlas = cube();
    let shapes = vec![atlas.vertices.clone()];
    let t = Smoothing::Displacement;
    assert!(update_atlas(&atlas, &shapes, &params(None, 0.0, t)).is_err());
    assert!(update_atlas(&atlas, &shapes, &params(None, 1.5, t)).is_err());
    assert!(update_atlas(&atlas, &shapes, &params(Some(-1.0), 1.0, t)).is_err());
    assert!(update_atlas(&atlas, &[], &params(None, 1.0, t)).is_err());
    let short = [atlas.vertices[..7].to_vec()];
    assert!(update_atlas(&atlas, &short, &params(None, 1.0, t)).is_err());
}
