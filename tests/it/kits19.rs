//! The real KiTS19 label volumes and kidney meshes in `../shared/data/kits19/` (skipped with a
//! note when the directory is missing): label volumes to meshes, and simplification.

use std::path::PathBuf;
use std::time::Instant;

use cohortforge::mesh::validate::IngestOptions;
use cohortforge::segmentation::{self, Limits, Options};

use crate::support::crate_dir;

/// Largest relative difference between the mesh volume and the voxel volume of the selection.
const VOLUME_TOLERANCE: f64 = 0.02;

fn kits19_dir(sub: &str) -> Option<PathBuf> {
    let dir = crate_dir().join("../shared/data/kits19").join(sub);
    if dir.is_dir() {
        Some(dir)
    } else {
        println!("skipped: {} is missing", dir.display());
        None
    }
}

fn files(dir: &PathBuf, suffix: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("readable directory")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.to_string_lossy().ends_with(suffix))
        .collect();
    files.sort();
    files
}

#[test]
fn kidney_label_volumes_become_closed_meshes_with_the_voxel_volume() {
    let Some(dir) = kits19_dir("segmentations") else {
        return;
    };
    let options = Options::default();
    let mut failures = Vec::new();
    for path in files(&dir, ".nii.gz") {
        let bytes = std::fs::read(&path).expect("readable volume");
        let started = Instant::now();
        let s = segmentation::volume_to_mesh(
            &bytes,
            &options,
            &Limits::default(),
            &IngestOptions::default(),
        )
        .unwrap_or_else(|e| panic!("{}: {} {e}", path.display(), e.code()));
        let seconds = started.elapsed().as_secs_f64();
        let summary = &s.ingested.summary;
        let (mesh_ml, voxel_ml) = (summary.volume_ml, s.source.voxel_volume_ml);
        let error = (mesh_ml - voxel_ml) / voxel_ml;
        println!(
            "{}: spacing {:?} mm, {} label components, mesh {:.2} ml, voxels {:.2} ml, \
             difference {:+.2}%, {} vertices, euler {}, {:.2} s",
            path.file_name().unwrap_or_default().to_string_lossy(),
            s.source
                .voxel_spacing_mm
                .map(|v| (v * 1000.0).round() / 1000.0),
            s.source.label_components,
            mesh_ml,
            voxel_ml,
            100.0 * error,
            summary.vertex_count,
            summary.euler_characteristic,
            seconds
        );
        for w in &s.ingested.warnings {
            println!("  warning {}: {}", w.code, w.message);
        }
        let closed = summary.watertight && summary.components == 1;
        let manifold = !s
            .ingested
            .warnings
            .iter()
            .any(|w| w.code == "mesh.non_manifold_vertices");
        if error.abs() > VOLUME_TOLERANCE || !closed || !manifold {
            failures.push(path.display().to_string());
        }
    }
    assert!(failures.is_empty(), "failed: {failures:?}");
}
