use super::*;
use crate::mesh::measures::volume_ml;
use crate::mesh::phantom::check::assert_closed_surface;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn flat_lobe() -> Lobe {
    Lobe {
        direction: [1.0, 0.0, 0.0],
        amplitude: 0.0,
        concentration: 1.0,
    }
}

/// An ellipsoid 100 × 70 × 80 mm (semi-axes) written as a liver without lobes.
fn ellipsoid_liver() -> LiverParams {
    LiverParams {
        axes: [1.0, 0.7, 0.8],
        lobes: [flat_lobe(); LOBE_COUNT],
        scale_mm: 100.0,
        sphere_points: 500,
        jitter: 0.3,
    }
}

#[test]
fn lobeless_liver_is_an_ellipsoid() {
    let p = ellipsoid_liver();
    assert!((p.radius_mm([1.0, 0.0, 0.0]) - 100.0).abs() < 1e-12);
    assert!((p.radius_mm([0.0, 0.0, -1.0]) - 80.0).abs() < 1e-12);
    let exact = 4.0 / 3.0 * PI * 100.0 * 70.0 * 80.0 / 1000.0;
    assert!(
        (p.volume_ml() / exact - 1.0).abs() < 1e-12,
        "{}",
        p.volume_ml()
    );
}

#[test]
fn a_lobe_adds_its_amplitude_at_its_peak() {
    let mut p = ellipsoid_liver();
    p.lobes[0] = Lobe {
        direction: [0.0, 0.0, 1.0],
        amplitude: 0.25,
        concentration: 3.0,
    };
    assert!((p.radius_mm([0.0, 0.0, 1.0]) - 100.0).abs() < 1e-12);
    // Opposite the peak the bump has decayed to 0.25·e⁻⁶.
    let far = 80.0 * (1.0 + 0.25 * (-6.0f64).exp());
    assert!((p.radius_mm([0.0, 0.0, -1.0]) - far).abs() < 1e-12);
}

#[test]
fn volume_quadrature_converges() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let mut worst: f64 = 0.0;
    for _ in 0..20 {
        let p = LiverParams::sample(&mut rng);
        let reference = p.volume_ml_with(2 * VOLUME_NODES_THETA, 2 * VOLUME_STEPS_PHI);
        worst = worst.max((p.volume_ml() / reference - 1.0).abs());
        // A 4 × 8 grid is still off, so the comparison is not vacuous.
        let coarse = p.volume_ml_with(4, 8);
        assert!((coarse / reference - 1.0).abs() > 1e-7);
    }
    println!("liver volume quadrature: max relative change on doubling {worst:.1e}");
    assert!(worst < 1e-12, "{worst}");
}

#[test]
fn fine_meshes_converge_to_the_exact_volume() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let mut p = LiverParams::sample(&mut rng);
    let exact = p.volume_ml();
    // Hull triangulation of many points, and an independent, finer ring triangulation.
    p.sphere_points = 40_000;
    let hull_mesh = p.mesh(&mut rng);
    let (points, faces) = ring_sphere(160_000);
    let ring_mesh = p.radial_mesh(points, faces);
    for (what, mesh, tolerance) in [("hull", &hull_mesh, 3e-4), ("rings", &ring_mesh, 1e-4)] {
        let err = (volume_ml(mesh) / exact - 1.0).abs();
        println!(
            "liver {exact:.3} ml, {what} mesh of {} vertices: error {err:.2e}",
            mesh.vertex_count()
        );
        assert!(err < tolerance, "{what}: {err}");
    }
}

#[test]
fn sampled_livers_stay_in_range_with_positive_radius() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let r = LiverRanges::default();
    for _ in 0..50 {
        let p = LiverParams::sample(&mut rng);
        let v = p.volume_ml();
        assert!(
            v >= r.volume_ml.0 - 1e-9 && v <= r.volume_ml.1 + 1e-9,
            "{v}"
        );
        // The lobes never pinch the surface: the factor over the ellipsoid stays positive.
        let grid = 24;
        for i in 0..=grid {
            for j in 0..2 * grid {
                let (t, f) = (PI * i as f64 / grid as f64, PI * j as f64 / grid as f64);
                let u = [t.sin() * f.cos(), t.sin() * f.sin(), t.cos()];
                let factor = p.radius_mm(u) / (p.scale_mm * ellipsoid_radius(p.axes, u));
                assert!(factor > 0.3, "lobe factor {factor}");
            }
        }
        assert!((r.sphere_points.0..=r.sphere_points.1).contains(&p.sphere_points));
    }
}

#[test]
fn liver_mesh_is_closed_with_one_vertex_per_point() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let p = LiverParams::sample(&mut rng);
    let mesh = p.mesh(&mut rng);
    assert_closed_surface(&mesh);
    assert_eq!(mesh.vertex_count(), p.sphere_points);
    for v in &mesh.vertices {
        let r = norm(*v);
        assert!((r - p.radius_mm(v.map(|x| x / r))).abs() < 1e-9);
    }
}

#[test]
fn ring_fallback_is_closed() {
    let (points, faces) = ring_sphere(400);
    let mesh = ellipsoid_liver().radial_mesh(points, faces);
    assert_closed_surface(&mesh);
    assert!(
        (300..500).contains(&mesh.vertex_count()),
        "{}",
        mesh.vertex_count()
    );
}
