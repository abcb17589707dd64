use super::*;
use crate::mesh::measures::volume_ml;
use crate::mesh::phantom::check::assert_closed_surface;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A hand-made cup: 30 × 27 × 70 mm outside, 9 mm walls, 8 mm apex, base 10 mm above centre.
fn cup() -> LvParams {
    LvParams {
        outer_radius_x_mm: 30.0,
        outer_radius_y_mm: 27.0,
        outer_half_length_mm: 70.0,
        inner_radius_x_mm: 21.0,
        inner_radius_y_mm: 18.0,
        inner_half_length_mm: 62.0,
        base_height_mm: 10.0,
        edge_length_mm: 3.5,
    }
}

#[test]
fn segment_volume_matches_known_cases() {
    let (a, b, c) = (3.0, 2.0, 5.0);
    let full = 4.0 / 3.0 * PI * a * b * c;
    assert!((ellipsoid_segment_volume_mm3(a, b, c, c) - full).abs() < 1e-12);
    assert!((ellipsoid_segment_volume_mm3(a, b, c, 0.0) - full / 2.0).abs() < 1e-12);
    assert!(ellipsoid_segment_volume_mm3(a, b, c, -c).abs() < 1e-12);
    // Unit sphere cap below z = -1/2: π h² (3 − h)/3 with cap height h = 1/2.
    let cap = PI * 0.25 * 2.5 / 3.0;
    assert!((ellipsoid_segment_volume_mm3(1.0, 1.0, 1.0, -0.5) - cap).abs() < 1e-12);
}

#[test]
fn cup_volume_by_hand() {
    let p = cup();
    // Outer: π·30·27·(80 − (1000 + 343000)/(3·4900)); inner: π·21·18·(72 − (1000 + 238328)/(3·3844)).
    let outer = PI * 30.0 * 27.0 * (80.0 - 344_000.0 / 14_700.0);
    let inner = PI * 21.0 * 18.0 * (72.0 - 239_328.0 / 11_532.0);
    assert!((p.volume_ml() - (outer - inner) / 1000.0).abs() < 1e-12);
    assert!(
        (p.volume_ml() - 83.169_507).abs() < 1e-6,
        "{}",
        p.volume_ml()
    );
    assert_eq!(p.long_axis_mm(), 80.0);
    assert_eq!(p.wall_thickness_mm(), 9.0);
    assert_eq!(p.apex_thickness_mm(), 8.0);
}

#[test]
fn fine_mesh_converges_to_the_exact_volume() {
    let p = cup();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let exact = p.volume_ml();
    let coarse = volume_ml(&p.mesh_with_edge(4.0, &mut rng));
    let fine_mesh = p.mesh_with_edge(0.5, &mut rng);
    assert!(fine_mesh.vertex_count() > 50_000);
    let fine = volume_ml(&fine_mesh);
    let (e_coarse, e_fine) = ((coarse / exact - 1.0).abs(), (fine / exact - 1.0).abs());
    println!(
        "LV cup {exact:.4} ml: edge 4 mm error {e_coarse:.2e}, edge 0.5 mm error {e_fine:.2e}"
    );
    assert!(e_fine < 2e-4, "fine mesh error {e_fine}");
    assert!(e_fine < e_coarse / 10.0);
}

#[test]
fn cup_mesh_is_a_closed_surface_with_a_flat_rim() {
    let p = cup();
    let mesh = p.mesh(&mut ChaCha8Rng::seed_from_u64(5));
    assert_closed_surface(&mesh);
    let top = mesh.vertices.iter().map(|v| v[2]).fold(f64::MIN, f64::max);
    let bottom = mesh.vertices.iter().map(|v| v[2]).fold(f64::MAX, f64::min);
    assert!((top - 10.0).abs() < 1e-12 && (bottom + 70.0).abs() < 1e-12);
    // Every vertex lies on the outer ellipsoid, the inner one or the base plane.
    for v in &mesh.vertices {
        let on = |a: f64, b: f64, c: f64| {
            ((v[0] / a).powi(2) + (v[1] / b).powi(2) + (v[2] / c).powi(2) - 1.0).abs() < 1e-9
        };
        assert!(on(30.0, 27.0, 70.0) || on(21.0, 18.0, 62.0) || (v[2] - 10.0).abs() < 1e-12);
    }
}

#[test]
fn sampled_cups_stay_in_range() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let r = LvRanges::default();
    for _ in 0..200 {
        let p = LvParams::sample(&mut rng);
        let v = p.volume_ml();
        assert!(
            (r.wall_volume_ml.0..=r.wall_volume_ml.1).contains(&v),
            "{v}"
        );
        assert!(p.inner_radius_y_mm > 5.0 && p.inner_half_length_mm > p.base_height_mm);
        assert!(p.edge_length_mm > 1.0 && p.edge_length_mm < 10.0);
    }
}

#[test]
fn scaling_a_cup_scales_its_volume_by_the_cube() {
    let p = cup();
    let big = p.scaled(2.0);
    assert!((big.volume_ml() - 8.0 * p.volume_ml()).abs() < 1e-9);
    assert_eq!(big.wall_thickness_mm(), 18.0);
    assert_eq!(big.edge_length_mm, 7.0);
}
