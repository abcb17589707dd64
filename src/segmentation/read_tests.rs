//! Malformed and unusual NIfTI files: each gets its stable code, none panics.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::tests::{diagonal, volume_bytes};
use super::*;

fn small(gzip: bool) -> Vec<u8> {
    volume_bytes([6, 5, 4], &diagonal([1.0; 3], [0.0; 3]), gzip, |p| {
        u8::from(p[0] > 1.0 && p[0] < 4.0)
    })
}

fn code(bytes: &[u8]) -> &'static str {
    match read(bytes, &Limits::default()) {
        Ok(_) => "ok",
        Err(e) => e.code(),
    }
}

fn patched(at: usize, with: &[u8]) -> Vec<u8> {
    let mut bytes = small(false);
    bytes[at..at + with.len()].copy_from_slice(with);
    bytes
}

#[test]
fn well_formed_files_read_with_and_without_gzip() {
    for gzip in [false, true] {
        let v = read(&small(gzip), &Limits::default()).unwrap();
        assert_eq!(v.dims, [6, 5, 4]);
        assert_eq!(v.datatype.name(), "uint8");
        let mut ones = 0;
        v.for_each_label(|_, l| ones += usize::from(l == 1))
            .unwrap();
        assert_eq!(ones, 2 * 5 * 4);
    }
}

#[test]
fn malformed_files_get_their_codes() {
    assert_eq!(code(b""), "nifti.parse_error");
    assert_eq!(
        code(b"solid cube\nfacet normal 0 0 1\n"),
        "nifti.parse_error"
    );
    assert_eq!(code(&patched(344, b"n+2\0")), "nifti.parse_error");
    assert_eq!(code(&patched(344, b"ni1\0")), "nifti.unsupported_format");
    assert_eq!(
        code(&patched(0, &540i32.to_le_bytes())),
        "nifti.unsupported_format"
    );
    let full = small(false);
    assert_eq!(
        code(&full[..full.len() - 1]),
        "nifti.parse_error",
        "truncated data"
    );
    assert_eq!(code(&full[..200]), "nifti.parse_error", "truncated header");
    let gz = small(true);
    assert_eq!(
        code(&gz[..gz.len() / 2]),
        "nifti.parse_error",
        "truncated gzip"
    );
    assert_eq!(
        code(&patched(70, &128i16.to_le_bytes())),
        "nifti.unsupported_datatype"
    );
    assert_eq!(
        code(&patched(40, &0i16.to_le_bytes())),
        "nifti.parse_error",
        "dim[0] = 0"
    );
    assert_eq!(
        code(&patched(44, &(-3i16).to_le_bytes())),
        "nifti.parse_error",
        "negative size"
    );
    let four_d = patched(40, &[4, 0, 6, 0, 5, 0, 4, 0, 3, 0]);
    assert_eq!(code(&four_d), "nifti.unsupported_format");
    let limits = Limits {
        max_voxels: 100,
        ..Limits::default()
    };
    assert_eq!(
        read(&small(true), &limits).unwrap_err().code(),
        "nifti.too_large"
    );
    // A header announcing 32767³ voxels is refused before allocating.
    let huge = patched(42, &[0xff, 0x7f, 0xff, 0x7f, 0xff, 0x7f]);
    assert_eq!(code(&huge), "nifti.too_large");
}

#[test]
fn float_labels_must_be_whole_numbers() {
    // float32 data: relabel the header and write 0.0 / 1.0 / 0.25 values.
    let mut bytes = small(false);
    bytes.truncate(352);
    bytes[70..72].copy_from_slice(&16i16.to_le_bytes());
    bytes[72..74].copy_from_slice(&32i16.to_le_bytes());
    for i in 0..120 {
        let v: f32 = if i == 7 { 1.0 } else { 0.0 };
        bytes.extend(v.to_le_bytes());
    }
    let v = read(&bytes, &Limits::default()).unwrap();
    let mut found = Vec::new();
    v.for_each_label(|i, l| {
        if l != 0 {
            found.push((i, l))
        }
    })
    .unwrap();
    assert_eq!(found, vec![(7, 1)]);
    bytes[352 + 4 * 9..352 + 4 * 10].copy_from_slice(&0.25f32.to_le_bytes());
    let v = read(&bytes, &Limits::default()).unwrap();
    let e = v.for_each_label(|_, _| {}).unwrap_err();
    assert_eq!(e.code(), "nifti.not_labels");
    assert!(e.to_string().contains("[3, 1, 0]"), "{e}");
}

#[test]
fn qform_only_gives_the_same_surface_as_the_sform() {
    let affine = diagonal([1.0, 1.2, 2.0], [10.0, -20.0, 30.0]);
    let ball = |p: [f64; 3]| {
        let d = ((p[0] - 20.0).powi(2) + (p[1] + 8.0).powi(2) + (p[2] - 45.0).powi(2)).sqrt();
        u8::from(d < 7.0)
    };
    let sform = volume_bytes([22, 20, 16], &affine, false, ball);
    let mut qform = sform.clone();
    qform[252..254].copy_from_slice(&1i16.to_le_bytes());
    qform[254..256].copy_from_slice(&0i16.to_le_bytes());
    for (k, v) in [10.0f32, -20.0, 30.0].iter().enumerate() {
        qform[268 + 4 * k..272 + 4 * k].copy_from_slice(&v.to_le_bytes());
    }
    let run = |b: &[u8]| {
        volume_to_mesh(
            b,
            &Options::default(),
            &Limits::default(),
            &IngestOptions::default(),
        )
        .unwrap()
    };
    let (s, q) = (run(&sform), run(&qform));
    assert_eq!(q.source.affine, affine::AffineSource::Qform);
    assert_eq!(s.ingested.mesh.faces, q.ingested.mesh.faces);
    let v = (s.ingested.summary.volume_ml, q.ingested.summary.volume_ml);
    assert!((v.0 - v.1).abs() < 1e-9, "{v:?}");
}

/// Random byte changes in the header never panic: every outcome is a mesh or an error.
#[test]
fn damaged_headers_never_panic() {
    let good = small(false);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for _ in 0..400 {
        let mut bytes = good.clone();
        for _ in 0..rng.random_range(1..6) {
            let at = rng.random_range(0..352);
            bytes[at] = rng.random();
        }
        let limits = Limits {
            max_voxels: 1 << 16,
            max_samples: 1 << 18,
        };
        let _ = volume_to_mesh(
            &bytes,
            &Options::default(),
            &limits,
            &IngestOptions::default(),
        );
    }
}
