//! The real KiTS19 label volumes and kidney meshes in `../shared/data/kits19/` (skipped with a
//! note when the directory is missing): label volumes to meshes, and simplification.

use std::path::PathBuf;
use std::time::Instant;

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

/// Largest distance (mm) from a vertex of `dense` to the surface `coarse`, each vertex
/// measured against the triangles around its 8 nearest coarse vertices.
fn surface_deviation_mm(dense: &Mesh, coarse: &Mesh) -> f64 {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    use std::num::NonZero;
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&coarse.vertices).expect("k-d tree");
    let mut around = vec![Vec::new(); coarse.vertices.len()];
    for (f, face) in coarse.faces.iter().enumerate() {
        for &v in face {
            around[v as usize].push(f);
        }
    }
    let k = NonZero::new(8).expect("non-zero");
    dense
        .vertices
        .iter()
        .map(|p| {
            let near = tree
                .query(p)
                .nearest_n::<SquaredEuclidean<f64>>(k)
                .execute();
            near.iter()
                .flat_map(|n| around[n.item as usize].iter())
                .map(|&f| point_triangle_mm(*p, coarse.triangle(f)))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// Distance (mm) from `p` to the triangle `[a, b, c]` (Ericson, Real-Time Collision Detection).
fn point_triangle_mm(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> f64 {
    let sub = |u: [f64; 3], v: [f64; 3]| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
    let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let at = |s: f64, t: f64| [0, 1, 2].map(|i| a[i] + s * (b[i] - a[i]) + t * (c[i] - a[i]));
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    let (va, vb, vc) = (d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2);
    let q = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else if d3 >= 0.0 && d4 <= d3 {
        b
    } else if d6 >= 0.0 && d5 <= d6 {
        c
    } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        at(d1 / (d1 - d3), 0.0)
    } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        at(0.0, d2 / (d2 - d6))
    } else if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        [0, 1, 2].map(|i| b[i] + w * (c[i] - b[i]))
    } else {
        let denom = 1.0 / (va + vb + vc);
        at(vb * denom, vc * denom)
    };
    dot(sub(p, q), sub(p, q)).sqrt()
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
