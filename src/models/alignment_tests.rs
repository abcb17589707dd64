use super::*;
use crate::geometry::points::{axis_angle, mat_vec};
use crate::mesh::phantom::{self, Family};

/// Largest distance (mm) between `T(p)` and the moved point, over all vertices.
fn worst_residual(result: &CpdResult, original: &[[f64; 3]], moved: &[[f64; 3]]) -> f64 {
    original
        .iter()
        .zip(moved)
        .map(|(p, q)| {
            let a = result.transform.apply(*p);
            ((a[0] - q[0]).powi(2) + (a[1] - q[1]).powi(2) + (a[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

fn moved(mesh: &Mesh, scale: f64) -> Vec<[f64; 3]> {
    let rotation = axis_angle([0.3, -0.8, 0.52], 2.6);
    mesh.vertices
        .iter()
        .map(|p| {
            let r = mat_vec(&rotation, *p);
            [
                scale * r[0] + 40.0,
                scale * r[1] - 25.0,
                scale * r[2] + 10.0,
            ]
        })
        .collect()
}

#[test]
fn registration_recovers_a_large_rotation_of_a_phantom() {
    let liver = &phantom::generate(Family::Liver, 1, 4)[0].mesh;
    let target = moved(liver, 1.0);
    let result = register(&liver.vertices, &target, &AlignmentParams::default()).unwrap();
    let worst = worst_residual(&result, &liver.vertices, &target);
    assert!(worst < 1e-3, "largest residual {worst} mm");
}

#[test]
fn registration_of_a_symmetric_cup_matches_the_surface() {
    // The LV cup is nearly symmetric about its long axis: any spin about it fits, so
    // check the surface fit rather than vertex correspondences.
    let lv = &phantom::generate(Family::Lv, 1, 4)[0].mesh;
    let target = moved(lv, 1.0);
    let result = register(&lv.vertices, &target, &AlignmentParams::default()).unwrap();
    // Spins about the axis fit almost equally (about 2 mm apart here); a flipped or
    // tilted cup would be tens of mm off.
    let moved_template = result.transform.apply_all(&lv.vertices);
    let d = crate::geometry::distance::surface_distances(&moved_template, &target).unwrap();
    assert!(d.ed < 2.5 && d.ed_star < 2.5, "{d:?}");
}

#[test]
fn cpd_run_to_convergence_recovers_rotation_translation_and_scale_of_a_phantom() {
    let liver = &phantom::generate(Family::Liver, 1, 6)[0].mesh;
    let template = subsample(&liver.vertices, 400);
    let rotation = axis_angle([0.2, 0.9, -0.4], 0.5);
    let data: Vec<[f64; 3]> = template
        .iter()
        .map(|p| {
            let r = mat_vec(&rotation, *p);
            [1.15 * r[0] + 12.0, 1.15 * r[1] - 7.0, 1.15 * r[2] + 3.0]
        })
        .collect();
    // As in `register`: start at the data's size (a cold start with a free scale can
    // collapse the template) and a variance of 1 mm²; the data has no outliers (w = 0).
    let params = RigidCpdParams {
        scale: true,
        w: 0.0,
        max_iterations: 5000,
        tolerance: 1e-15,
        ..Default::default()
    };
    let s0 = rms_radius(&data) / rms_radius(&template);
    let (cx, cy) = (centroid(&data, None), centroid(&template, None));
    let identity = crate::geometry::points::IDENTITY3;
    let start = RigidTransform {
        rotation: identity,
        translation: sub(cx, cy.map(|c| c * s0)),
        scale: s0,
    };
    let result = rigid_cpd_warm(&template, &data, &params, &start, 1.0).unwrap();
    assert!(
        (result.transform.scale - 1.15).abs() < 1e-3,
        "scale {}",
        result.transform.scale
    );
    for (a, b) in result
        .transform
        .rotation
        .iter()
        .flatten()
        .zip(rotation.iter().flatten())
    {
        assert!(
            (a - b).abs() < 1e-3,
            "rotation {:?}",
            result.transform.rotation
        );
    }
    let expected_t = [12.0, -7.0, 3.0];
    for (a, b) in result.transform.translation.iter().zip(expected_t) {
        assert!(
            (a - b).abs() < 1e-3 * 100.0,
            "translation {:?}",
            result.transform.translation
        );
    }
}

#[test]
fn registration_with_scale_recovers_a_scaled_phantom() {
    let liver = &phantom::generate(Family::Liver, 1, 6)[0].mesh;
    let target = moved(liver, 1.15);
    let mut params = AlignmentParams::default();
    params.cpd.scale = true;
    let result = register(&liver.vertices, &target, &params).unwrap();
    let worst = worst_residual(&result, &liver.vertices, &target);
    assert!(worst < 1e-3, "largest residual {worst} mm");
}

#[test]
fn normalisation_round_trips_and_fits_the_unit_box() {
    let shapes = vec![vec![[0.0, 0.0, 0.0], [100.0, 50.0, 20.0]]];
    let n = Normalisation::fit(&shapes);
    assert_eq!(n.scale_mm, 100.0);
    assert_eq!(n.apply([100.0, 50.0, 20.0]), [0.5, 0.25, 0.1]);
    let p = [12.5, -3.0, 7.0];
    let back = n.undo(n.apply(p));
    assert!((0..3).all(|k| (back[k] - p[k]).abs() < 1e-12));
}

#[test]
fn median_resolution_prefers_the_middle_mesh() {
    let mesh = |n: usize| Mesh::new(vec![[0.0; 3]; n], vec![]);
    let meshes = vec![mesh(10), mesh(300), mesh(100), mesh(2000), mesh(90)];
    assert_eq!(median_resolution_index(&meshes), 2);
}
