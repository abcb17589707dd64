//! Reader and writer tests: round trips for every format and the error codes of bad input.

mod obj_stl;
mod ply_vtk;

use super::*;
use crate::mesh::fixtures::{cube, tetrahedron, uv_sphere};

pub(super) fn limits() -> Limits {
    Limits::default()
}

pub(super) fn parse(bytes: &[u8], format: Format) -> Mesh {
    read(bytes, format, &limits()).unwrap_or_else(|e| panic!("{format}: {e}"))
}

pub(super) fn fail(bytes: &[u8], format: Format) -> MeshError {
    match read(bytes, format, &limits()) {
        Ok(m) => panic!(
            "{format}: accepted {} vertices {} faces",
            m.vertices.len(),
            m.faces.len()
        ),
        Err(e) => e,
    }
}

fn close(a: [f64; 3], b: [f64; 3], rel: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= rel * a[k].abs().max(b[k].abs()).max(1.0))
}

pub(super) fn assert_same_triangles(got: &Mesh, want: &Mesh, rel: f64) {
    assert_eq!(got.faces.len(), want.faces.len());
    for f in 0..want.faces.len() {
        let (g, w) = (got.triangle(f), want.triangle(f));
        for k in 0..3 {
            assert!(
                close(g[k], w[k], rel),
                "face {f} corner {k}: {:?} vs {:?}",
                g[k],
                w[k]
            );
        }
    }
}

fn test_meshes() -> Vec<Mesh> {
    let mut odd = uv_sphere(37.3, [-120.25, 4.0e3, 1.0 / 3.0], 16, 24);
    odd.vertices[5][0] = 1.0e-7;
    assert!(odd.vertices.len() > 300);
    vec![tetrahedron(0.25), cube(), odd]
}

#[test]
fn round_trip_exact_formats() {
    for format in [Format::Obj, Format::Ply, Format::Vtk] {
        for m in test_meshes() {
            let back = parse(&write(&m, format), format);
            assert_eq!(back.faces, m.faces, "{format}");
            assert_eq!(
                back.vertices, m.vertices,
                "{format}: coordinates must survive exactly"
            );
        }
    }
}

#[test]
fn round_trip_stl_to_f32_precision() {
    for m in test_meshes() {
        let bytes = write(&m, Format::Stl);
        assert_eq!(bytes.len(), 84 + 50 * m.faces.len());
        assert!(!bytes.starts_with(b"solid"));
        let back = parse(&bytes, Format::Stl);
        assert_eq!(back.vertices.len(), 3 * m.faces.len());
        assert_same_triangles(&back, &m, 1e-5);
    }
}

/// Deterministic bytes that look like nothing (a 64-bit LCG).
pub(crate) fn garbage(n: usize) -> Vec<u8> {
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 33) as u8
        })
        .collect()
}

// ---------- robustness ----------

/// Every prefix and many single-byte corruptions of valid files either parse or fail with
/// an error; none panics.
#[test]
fn truncated_and_corrupted_files_never_panic() {
    let t = tetrahedron(1.0);
    let mut samples: Vec<(Format, Vec<u8>)> =
        Format::ALL.iter().map(|&f| (f, write(&t, f))).collect();
    samples.push((Format::Stl, obj_stl::ASCII_TETRA.as_bytes().to_vec()));
    samples.push((Format::Vtk, ply_vtk::VTK_51.as_bytes().to_vec()));
    samples.push((Format::Ply, ply_vtk::binary_ply(2, None)));
    let noise = garbage(4096);
    for (format, bytes) in &samples {
        for cut in 0..bytes.len() {
            let _ = read(&bytes[..cut], *format, &limits());
        }
        for (k, pair) in noise.chunks_exact(2).take(300).enumerate() {
            let mut m = bytes.clone();
            let at = (k * 7919 + pair[0] as usize) % m.len();
            m[at] = pair[1];
            let _ = crate::mesh::validate::ingest(&m, *format, &Default::default());
        }
    }
}
