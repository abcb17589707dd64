//! The checked-in fixture corpus: every malformed file in `tests/fixtures/bad/` is
//! rejected with the code its manifest names, and every file in `tests/fixtures/good/` is
//! accepted with the expected measures.

use super::*;
use std::path::PathBuf;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn read_fixture(rel: &str) -> Vec<u8> {
    let path = fixtures().join(rel);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_bad_fixture_gives_its_code() {
    let manifest = String::from_utf8(read_fixture("bad/manifest.csv")).unwrap();
    let mut lines = manifest.lines();
    assert_eq!(lines.next(), Some("file,format,expected_code"));
    let mut checked = 0;
    let mut failures = Vec::new();
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let [file, format, expected] = line.split(',').collect::<Vec<_>>()[..] else {
            panic!("bad manifest line {line:?}");
        };
        let format = Format::from_name(format).unwrap_or_else(|| panic!("format in {line:?}"));
        let bytes = read_fixture(&format!("bad/{file}"));
        match ingest(&bytes, format, &IngestOptions::default()) {
            Ok(_) => failures.push(format!("{file}: accepted, expected {expected}")),
            Err(e) if e.code() != expected => {
                failures.push(format!("{file}: {} ({e}), expected {expected}", e.code()))
            }
            Err(e) => {
                // Messages are sentences with a remedy, never a bare code.
                let msg = e.to_string();
                assert!(msg.contains(';') && msg.len() > 40, "{file}: {msg}");
            }
        }
        checked += 1;
    }
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(checked >= 22, "only {checked} bad fixtures");
}

#[test]
fn good_fixtures_are_accepted() {
    let tetra_ml = 1000.0 / 6.0 / 1000.0;
    for (file, volume_ml, vertices, faces) in [
        ("cube.obj", 1.0, 8, 12),
        ("cube_ascii.stl", 1.0, 8, 12),
        ("cube_binary.stl", 1.0, 8, 12),
        ("tetra.ply", tetra_ml, 4, 4),
        ("tetra.vtk", tetra_ml, 4, 4),
    ] {
        let format = Format::from_file_name(file).unwrap();
        let got = ingest(
            &read_fixture(&format!("good/{file}")),
            format,
            &IngestOptions::default(),
        )
        .unwrap_or_else(|e| panic!("{file}: {e}"));
        let s = &got.summary;
        assert!(
            (s.volume_ml - volume_ml).abs() < 1e-9,
            "{file}: {}",
            s.volume_ml
        );
        assert_eq!((s.vertex_count, s.face_count), (vertices, faces), "{file}");
        assert!(s.watertight && s.euler_characteristic == 2, "{file}");
        let reoriented = got
            .warnings
            .iter()
            .any(|w| w.code == "mesh.faces_reoriented");
        assert!(!reoriented, "{file} should already face outward");
    }
}
