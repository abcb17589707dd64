//! The real KiTS19 label volumes and kidney meshes in `../shared/data/kits19/` (skipped with a
//! note when the directory is missing): label volumes to meshes, and simplification.

use std::path::PathBuf;
use std::time::Instant;

use cohortforge::geometry::bvh::TriangleBvh;
use cohortforge::mesh::Mesh;
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

/// Symmetric vertex-to-vertex Hausdorff distance (mm) between two point sets.
fn hausdorff_mm(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    let one_way = |from: &[[f64; 3]], to: &[[f64; 3]]| {
        let tree = ImmutableKdTree::<f64, 3>::new_from_slice(to).expect("k-d tree");
        from.iter()
            .map(|p| {
                tree.query(p)
                    .nearest_one::<SquaredEuclidean<f64>>()
                    .execute()
                    .distance
            })
            .fold(0.0f64, f64::max)
            .sqrt()
    };
    one_way(a, b).max(one_way(b, a))
}

/// Largest distance (mm) from a vertex of `dense` to the surface `coarse` (exact closest
/// points on its triangles).
fn surface_deviation_mm(dense: &Mesh, coarse: &Mesh) -> f64 {
    let surface = TriangleBvh::new(&coarse.vertices, &coarse.faces).expect("surface");
    dense
        .vertices
        .iter()
        .map(|p| surface.closest(*p).distance)
        .fold(0.0, f64::max)
}

#[test]
fn kidney_meshes_simplify_to_2000_vertices_closed_with_their_volume() {
    use cohortforge::mesh::Format;
    use cohortforge::mesh::simplify::simplify;
    use cohortforge::mesh::validate::{ingest, validate};
    const TARGET: usize = 2000;
    let Some(dir) = kits19_dir("kidney-meshes") else {
        return;
    };
    let opts = IngestOptions::default();
    let mut failures = Vec::new();
    for path in files(&dir, ".obj") {
        let original = ingest(
            &std::fs::read(&path).expect("readable mesh"),
            Format::Obj,
            &opts,
        )
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let started = Instant::now();
        let s = simplify(&original.mesh, TARGET).expect("simplifies");
        let seconds = started.elapsed().as_secs_f64();
        let checked = validate(s.mesh.clone(), &opts).expect("valid");
        let before = original.summary.volume_ml;
        let after = checked.summary.volume_ml;
        let change = (after - before) / before;
        let hausdorff = hausdorff_mm(&original.mesh.vertices, &s.mesh.vertices);
        let deviation = surface_deviation_mm(&original.mesh, &s.mesh);
        println!(
            "{}: {} → {} vertices, volume {:.2} → {:.2} ml ({:+.3}%), Hausdorff vertex-to-vertex \
             {:.2} mm, largest vertex-to-surface {:.2} mm, {:.3} s",
            path.file_name().unwrap_or_default().to_string_lossy(),
            original.summary.vertex_count,
            checked.summary.vertex_count,
            before,
            after,
            100.0 * change,
            hausdorff,
            deviation,
            seconds
        );
        let closed = checked.summary.watertight
            && checked.summary.components == 1
            && checked.summary.euler_characteristic == original.summary.euler_characteristic
            && checked.warnings.is_empty();
        let reduced = checked.summary.vertex_count <= TARGET + TARGET / 20;
        if !closed || !reduced || change.abs() >= 0.01 {
            failures.push(path.display().to_string());
        }
    }
    assert!(failures.is_empty(), "failed: {failures:?}");
}
