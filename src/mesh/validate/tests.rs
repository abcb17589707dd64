//! Pipeline tests: measures of accepted meshes, repairs with warnings, and rejections.

use super::*;
use crate::mesh::fixtures::{cube, tetrahedron, uv_sphere};

fn ok(mesh: Mesh) -> Ingested {
    validate(mesh, &IngestOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn codes(i: &Ingested) -> Vec<&'static str> {
    i.warnings.iter().map(|w| w.code).collect()
}

fn rejected(mesh: Mesh) -> MeshError {
    validate(mesh, &IngestOptions::default()).expect_err("must be rejected")
}

#[test]
fn unit_cube_summary() {
    let i = ok(cube());
    assert!(i.warnings.is_empty(), "{:?}", i.warnings);
    let s = &i.summary;
    assert_eq!(s.volume_ml, 1.0);
    assert!((s.area_cm2 - 6.0).abs() < 1e-12);
    assert!(s.watertight);
    assert_eq!((s.components, s.euler_characteristic), (1, 2));
    assert_eq!(
        (s.vertex_count, s.face_count, s.original_vertex_count),
        (8, 12, 8)
    );
    assert_eq!((s.bbox_min, s.bbox_max), ([0.0; 3], [10.0; 3]));
    assert_eq!(i.mesh, cube());
}

#[test]
fn open_cube_is_accepted_with_a_warning() {
    let mut c = cube();
    c.faces.pop();
    let i = ok(c);
    assert!(!i.summary.watertight);
    assert_eq!(codes(&i), ["mesh.not_watertight"]);
    assert!(
        i.warnings[0].message.contains("3 boundary edges"),
        "{}",
        i.warnings[0].message
    );
    assert_eq!(i.summary.euler_characteristic, 8 - 18 + 11);
}

#[test]
fn reversed_cube_is_reoriented() {
    let mut c = cube();
    for f in &mut c.faces {
        f.swap(1, 2);
    }
    let i = ok(c);
    assert_eq!(codes(&i), ["mesh.faces_reoriented"]);
    assert!(i.warnings[0].message.starts_with("flipped 12 of 12"));
    assert_eq!(i.summary.volume_ml, 1.0);
    assert_eq!(i.mesh, cube());
}

#[test]
fn partly_inverted_sphere_is_made_consistent() {
    let good = uv_sphere(10.0, [0.0; 3], 8, 12);
    let mut s = good.clone();
    for f in [1, 2, 30] {
        s.faces[f].swap(0, 1);
    }
    let i = ok(s);
    assert_eq!(codes(&i), ["mesh.faces_reoriented"]);
    assert!(i.warnings[0].message.starts_with("flipped 3 of"));
    assert!((i.summary.volume_ml - crate::mesh::measures::volume_ml(&good)).abs() < 1e-12);
}

#[test]
fn stl_cube_is_welded_back_to_eight_vertices() {
    let bytes = io::write(&cube(), Format::Stl);
    let i = ingest(&bytes, Format::Stl, &IngestOptions::default()).unwrap();
    assert_eq!(codes(&i), ["mesh.duplicate_vertices_welded"]);
    assert!(i.warnings[0].message.starts_with("merged 28 vertices"));
    assert_eq!(
        (i.summary.vertex_count, i.summary.original_vertex_count),
        (8, 36)
    );
    assert_eq!(i.summary.volume_ml, 1.0);
    assert_eq!(i.mesh.faces.len(), 12);
}

#[test]
fn weld_tolerance_closes_cracks() {
    let mut c = cube();
    // Split corner 7 into a copy 1 µm away used by two of its faces.
    c.vertices.push([10.0, 10.0, 10.0 + 1e-3]);
    c.faces[3] = [5, 8, 6];
    c.faces[11] = [3, 8, 5];
    let exact = ok(c.clone());
    assert!(!exact.summary.watertight);
    let opts = IngestOptions {
        weld_tolerance_mm: 0.01,
        ..IngestOptions::default()
    };
    let welded = validate(c, &opts).unwrap();
    assert!(welded.summary.watertight);
    assert_eq!(codes(&welded), ["mesh.duplicate_vertices_welded"]);
    assert_eq!(welded.mesh, cube());
}

#[test]
fn degenerate_faces_and_their_vertices_are_removed() {
    let mut c = cube();
    c.vertices.push([5.0, 0.0, 0.0]);
    c.faces.push([0, 8, 1]);
    c.faces.push([2, 2, 3]);
    let i = ok(c);
    assert_eq!(
        codes(&i),
        [
            "mesh.degenerate_faces_removed",
            "mesh.unreferenced_vertices_removed"
        ]
    );
    assert!(i.warnings[0].message.starts_with("removed 2 degenerate"));
    assert!(i.summary.watertight);
    assert_eq!(i.mesh, cube());
    assert_eq!(i.summary.original_vertex_count, 9);
}

#[test]
fn empty_meshes() {
    let e = rejected(Mesh::default());
    assert_eq!(e.code(), "mesh.empty");
    let one = Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    );
    let e = rejected(one);
    assert!(e.to_string().contains("only 3 vertices"), "{e}");
    let flat = Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]],
        vec![[0, 1, 2], [1, 2, 3]],
    );
    let e = rejected(flat);
    assert_eq!(e.code(), "mesh.empty");
    assert!(
        e.to_string().starts_with("all 2 triangles are degenerate"),
        "{e}"
    );
}

#[test]
fn rejections_of_meshes_made_in_code() {
    let mut t = tetrahedron(0.0);
    t.vertices[2][1] = f64::INFINITY;
    let e = rejected(t);
    assert_eq!(e.code(), "mesh.non_finite");
    assert!(e.to_string().starts_with("the 3rd vertex"), "{e}");
    let mut t = tetrahedron(0.0);
    t.faces[1][2] = 4;
    let e = rejected(t);
    assert_eq!(e.code(), "mesh.index_out_of_range");
    assert!(
        e.to_string()
            .starts_with("the 2nd triangle refers to vertex 4"),
        "{e}"
    );
    let tight = IngestOptions {
        limits: Limits {
            max_vertices: 100,
            max_faces: 100,
        },
        ..IngestOptions::default()
    };
    let e = validate(uv_sphere(5.0, [0.0; 3], 10, 12), &tight).unwrap_err();
    assert_eq!(e.code(), "mesh.too_large");
}

#[test]
fn fan_of_three_triangles_is_non_manifold() {
    let mut t = tetrahedron(0.0);
    t.vertices.push([0.0, 0.0, 20.0]);
    t.faces.push([0, 1, 4]);
    let e = rejected(t);
    assert_eq!(e.code(), "mesh.non_manifold");
    assert!(
        e.to_string()
            .contains("from (5, 5, 5) to (5, -5, -5) mm is shared by 3"),
        "{e}"
    );
}

#[test]
fn duplicate_face_is_non_manifold() {
    let mut c = cube();
    c.faces.push([3, 5, 7]);
    let e = rejected(c);
    assert_eq!(e.code(), "mesh.non_manifold");
    assert!(e.to_string().contains("the 12th and 13th triangles"), "{e}");
}

#[test]
fn two_parts_and_a_bowtie_are_accepted_with_warnings() {
    let mut m = tetrahedron(0.0);
    let far = tetrahedron(50.0);
    m.vertices.extend(&far.vertices);
    m.faces.extend(far.faces.iter().map(|f| f.map(|i| i + 4)));
    let i = ok(m);
    assert_eq!(codes(&i), ["mesh.multiple_components"]);
    assert_eq!(
        (i.summary.components, i.summary.euler_characteristic),
        (2, 4)
    );

    let mut b = cube();
    let shift = |v: &[f64; 3]| [v[0] + 10.0, v[1] + 10.0, v[2] + 10.0];
    let second: Vec<[f64; 3]> = cube().vertices[1..].iter().map(shift).collect();
    b.vertices.extend(second);
    // The second cube's corner 0 is the first cube's corner 7.
    b.faces.extend(
        cube()
            .faces
            .iter()
            .map(|f| f.map(|i| if i == 0 { 7 } else { i + 7 })),
    );
    let i = ok(b);
    assert_eq!(codes(&i), ["mesh.non_manifold_vertices"]);
    assert_eq!(i.summary.volume_ml, 2.0);
    assert_eq!(i.summary.components, 1);
}

#[test]
fn sphere_survives_every_format() {
    let s = uv_sphere(25.0, [10.0, -3.0, 7.5], 12, 20);
    let want = ok(s.clone()).summary;
    for format in Format::ALL {
        let got = ingest(&io::write(&s, format), format, &IngestOptions::default()).unwrap();
        let g = &got.summary;
        assert_eq!(
            (g.vertex_count, g.face_count),
            (want.vertex_count, want.face_count),
            "{format}"
        );
        assert!(
            (g.volume_ml - want.volume_ml).abs() < 1e-5 * want.volume_ml,
            "{format}"
        );
        assert!(g.watertight && g.euler_characteristic == 2, "{format}");
    }
}

#[test]
fn summary_and_warning_serialise_with_stable_names() {
    let i = ok(cube());
    let json = serde_json::to_value(&i.summary).unwrap();
    for key in [
        "vertex_count",
        "face_count",
        "volume_ml",
        "area_cm2",
        "watertight",
        "components",
        "euler_characteristic",
        "bbox_min",
        "bbox_max",
        "original_vertex_count",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    let w = Warning {
        code: "mesh.not_watertight",
        message: "m".into(),
    };
    assert_eq!(
        serde_json::to_string(&w).unwrap(),
        r#"{"code":"mesh.not_watertight","message":"m"}"#
    );
}
