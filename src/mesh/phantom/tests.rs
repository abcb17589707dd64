//! Whole-phantom tests: topology, volumes, resolution ranges, determinism.

use super::check::assert_closed_surface;
use super::*;
use crate::mesh::measures::volume_ml;

/// Largest accepted relative gap between the mesh volume and the exact volume.
const MAX_VOLUME_ERROR: f64 = 0.02;
const SUBJECTS: usize = 20;

struct Summary {
    volume_ml: (f64, f64),
    vertices: (usize, usize),
    max_error: f64,
}

fn summarise(family: Family, seed: u64) -> Summary {
    let phantoms = generate(family, SUBJECTS, seed);
    let mut s = Summary {
        volume_ml: (f64::MAX, f64::MIN),
        vertices: (usize::MAX, 0),
        max_error: 0.0,
    };
    for p in &phantoms {
        assert_closed_surface(&p.mesh);
        let exact = p.params.volume_ml;
        let err = (volume_ml(&p.mesh) / exact - 1.0).abs();
        s.max_error = s.max_error.max(err);
        s.volume_ml = (s.volume_ml.0.min(exact), s.volume_ml.1.max(exact));
        let n = p.mesh.vertex_count();
        s.vertices = (s.vertices.0.min(n), s.vertices.1.max(n));
    }
    println!(
        "{family}: {SUBJECTS} phantoms, volume {:.1}–{:.1} ml, vertices {}–{}, max relative volume error {:.3e}",
        s.volume_ml.0, s.volume_ml.1, s.vertices.0, s.vertices.1, s.max_error
    );
    s
}

#[test]
fn lv_phantoms_are_closed_cups_of_plausible_size() {
    let s = summarise(Family::Lv, 7);
    assert!(s.max_error < MAX_VOLUME_ERROR);
    assert!(s.volume_ml.0 >= 80.0 && s.volume_ml.1 <= 180.0);
    assert!(s.vertices.0 >= 1000 && s.vertices.1 <= 2000);
    assert!(s.vertices.1 - s.vertices.0 > 200, "resolution should vary");
}

#[test]
fn liver_phantoms_are_closed_lobed_surfaces_of_plausible_size() {
    let s = summarise(Family::Liver, 7);
    assert!(s.max_error < MAX_VOLUME_ERROR);
    assert!(s.volume_ml.0 >= 1000.0 && s.volume_ml.1 <= 1800.0);
    assert!(s.vertices.0 >= 300 && s.vertices.1 <= 3000);
    assert!(s.vertices.1 - s.vertices.0 > 500, "resolution should vary");
}

#[test]
fn same_seed_same_meshes_and_subjects_independent_of_count() {
    for family in Family::ALL {
        let a = generate(family, 5, 42);
        let b = generate(family, 5, 42);
        assert_eq!(a, b);
        let longer = generate(family, 20, 42);
        assert_eq!(a[..], longer[..5]);
        assert_eq!(subject(family, 42, 3), a[3]);
        let other = generate(family, 5, 43);
        assert!(a.iter().zip(&other).all(|(x, y)| x.mesh != y.mesh));
    }
}

#[test]
fn families_under_one_seed_are_independent_streams() {
    let lv = subject(Family::Lv, 1, 0);
    let liver = subject(Family::Liver, 1, 0);
    assert_ne!(lv.params.pose, liver.params.pose);
    assert_eq!(
        (lv.name.as_str(), liver.name.as_str()),
        ("lv_000", "liver_000")
    );
}

#[test]
fn subjects_differ_in_counts_and_connectivity() {
    for family in Family::ALL {
        let phantoms = generate(family, 6, 5);
        for (i, a) in phantoms.iter().enumerate() {
            for b in &phantoms[i + 1..] {
                let same_counts = a.mesh.vertex_count() == b.mesh.vertex_count();
                let shared = a
                    .mesh
                    .faces
                    .iter()
                    .take(50)
                    .filter(|f| b.mesh.faces.contains(f))
                    .count();
                assert!(
                    !same_counts || shared < 50,
                    "{} and {} share a grid",
                    a.name,
                    b.name
                );
            }
        }
        let counts: std::collections::BTreeSet<usize> =
            phantoms.iter().map(|p| p.mesh.vertex_count()).collect();
        assert_eq!(
            counts.len(),
            phantoms.len(),
            "{family}: vertex counts repeat"
        );
    }
}

#[test]
fn pose_is_recorded_and_undoable() {
    let p = subject(Family::Lv, 9, 2);
    let ShapeParams::Lv(lv) = p.params.shape else {
        panic!("not an LV");
    };
    let canonical = p.canonical_mesh();
    // In the canonical frame the apex is at z = -c and the base plane at z = h.
    let zs: Vec<f64> = canonical.vertices.iter().map(|v| v[2]).collect();
    let top = zs.iter().copied().fold(f64::MIN, f64::max);
    let bottom = zs.iter().copied().fold(f64::MAX, f64::min);
    assert!((top - lv.base_height_mm).abs() < 1e-9);
    assert!((bottom + lv.outer_half_length_mm).abs() < 1e-9);
    // The posed mesh is moved: its centroid is off the canonical one by the translation.
    let t = p.params.pose.translation_mm;
    assert!(t.iter().map(|x| x * x).sum::<f64>().sqrt() > 1.0);
    assert!((volume_ml(&canonical) - volume_ml(&p.mesh)).abs() < 1e-9);
}

#[test]
fn family_names_parse_and_print() {
    assert_eq!("lv".parse::<Family>(), Ok(Family::Lv));
    assert_eq!(" Liver ".parse::<Family>(), Ok(Family::Liver));
    assert_eq!(Family::Liver.to_string(), "liver");
    assert_eq!(
        "kidney".parse::<Family>(),
        Err(PhantomError::UnknownFamily("kidney".into()))
    );
}
