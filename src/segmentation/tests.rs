//! The whole pipeline on hand-made volumes with known answers.

use std::f64::consts::PI;

use super::affine::{Affine, AffineSource};
use super::write::encode_labels;
use super::*;
use crate::mesh::measures::{area_mm2, bounding_box, volume_ml};

/// A volume of `dims` voxels whose label at each voxel centre is `label(world position)`.
pub(crate) fn volume_bytes(
    dims: [usize; 3],
    affine: &Affine,
    gzip: bool,
    label: impl Fn([f64; 3]) -> u8,
) -> Vec<u8> {
    let mut labels = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                labels.push(label(affine.apply([i as f64, j as f64, k as f64])));
            }
        }
    }
    encode_labels(dims, &labels, affine, gzip)
}

pub(crate) fn diagonal(spacing: [f64; 3], offset: [f64; 3]) -> Affine {
    Affine {
        linear: [
            [spacing[0], 0.0, 0.0],
            [0.0, spacing[1], 0.0],
            [0.0, 0.0, spacing[2]],
        ],
        offset,
        source: AffineSource::Sform,
    }
}

fn mesh_of(bytes: &[u8], options: &Options) -> Segmented {
    volume_to_mesh(
        bytes,
        options,
        &Limits::default(),
        &IngestOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{}: {e}", e.code()))
}

fn assert_closed_genus_0(s: &Segmented) {
    let summary = &s.ingested.summary;
    assert!(summary.watertight, "{summary:?}");
    assert_eq!(summary.components, 1, "{summary:?}");
    assert_eq!(summary.euler_characteristic, 2, "{summary:?}");
    assert!(s.ingested.warnings.is_empty(), "{:?}", s.ingested.warnings);
}

#[test]
fn voxelised_sphere_converges_to_the_analytic_sphere() {
    let r: f64 = 12.0;
    let centre = [3.3, -2.2, 1.1];
    let exact_volume = 4.0 / 3.0 * PI * r.powi(3) / 1000.0;
    let exact_area = 4.0 * PI * r * r;
    let mut errors = Vec::new();
    for (n, h) in [2.0, 1.0, 0.5, 0.25].into_iter().enumerate() {
        let size = (2.0 * r / h).ceil() as usize + 6;
        let half = (size - 1) as f64 / 2.0 * h;
        let affine = diagonal([h; 3], centre.map(|c| c - half + 0.17 * h));
        let bytes = volume_bytes([size; 3], &affine, n % 2 == 0, |p| {
            let d = (0..3)
                .map(|a| (p[a] - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            u8::from(d <= r)
        });
        // Smoothing scales with the voxels: its shrinkage (about sigma² / r) vanishes too.
        let options = Options {
            voxel_mm: h,
            smooth_sigma_mm: h,
            ..Options::default()
        };
        let s = mesh_of(&bytes, &options);
        assert_closed_genus_0(&s);
        let volume_error = (s.ingested.summary.volume_ml - exact_volume) / exact_volume;
        let area_error = (area_mm2(&s.ingested.mesh) - exact_area) / exact_area;
        let (lo, hi) = bounding_box(&s.ingested.mesh);
        for a in 0..3 {
            assert!(
                ((lo[a] + hi[a]) / 2.0 - centre[a]).abs() < h / 2.0,
                "centre {lo:?} {hi:?}"
            );
        }
        errors.push((h, volume_error.abs(), area_error.abs()));
    }
    println!("sphere r = {r} mm: (voxel mm, volume error, area error) {errors:?}");
    for w in errors.windows(2) {
        assert!(w[1].1 < w[0].1, "volume error must shrink: {errors:?}");
        assert!(w[1].2 < w[0].2, "area error must shrink: {errors:?}");
    }
    let (_, volume_error, area_error) = errors[3];
    assert!(volume_error < 0.005, "{errors:?}");
    assert!(area_error < 0.005, "{errors:?}");
}

/// A box `[lo, hi)` in world mm.
fn in_box(p: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> bool {
    (0..3).all(|a| p[a] >= lo[a] && p[a] < hi[a])
}

#[test]
fn only_the_asked_label_becomes_the_surface() {
    let affine = diagonal([1.0, 1.0, 2.0], [0.0; 3]);
    let bytes = volume_bytes([40, 30, 20], &affine, false, |p| {
        if in_box(p, [2.0, 2.0, 2.0], [12.0, 12.0, 12.0]) {
            1
        } else if in_box(p, [20.0, 5.0, 4.0], [36.0, 25.0, 30.0]) {
            2
        } else {
            0
        }
    });
    let two = mesh_of(
        &bytes,
        &Options {
            labels: vec![2],
            ..Options::default()
        },
    );
    assert_closed_genus_0(&two);
    let (lo, hi) = bounding_box(&two.ingested.mesh);
    assert!(lo[0] > 18.0 && hi[0] < 37.0, "{lo:?} {hi:?}");
    assert_eq!(two.source.selected_voxels, 16 * 20 * 13);
    let both = mesh_of(
        &bytes,
        &Options {
            labels: vec![1, 2],
            component: Component::All,
            ..Options::default()
        },
    );
    assert_eq!(both.ingested.summary.components, 2);
    assert_eq!(both.source.label_components, 2);
    let absent = volume_to_mesh(
        &bytes,
        &Options {
            labels: vec![3],
            ..Options::default()
        },
        &Limits::default(),
        &IngestOptions::default(),
    )
    .unwrap_err();
    assert_eq!(absent.code(), "nifti.empty_label");
    assert!(
        absent
            .to_string()
            .contains("labels present: 1 (500 voxels), 2 (4160 voxels)"),
        "{absent}"
    );
}

#[test]
fn an_l_shaped_object_stays_closed_with_genus_0() {
    let affine = diagonal([0.9, 0.9, 2.5], [-10.0, 5.0, 100.0]);
    let bytes = volume_bytes([50, 40, 20], &affine, true, |p| {
        let leg = in_box(p, [-6.0, 8.0, 104.0], [2.0, 40.0, 130.0]);
        let foot = in_box(p, [-6.0, 8.0, 104.0], [30.0, 16.0, 130.0]);
        u8::from(leg || foot)
    });
    assert_closed_genus_0(&mesh_of(&bytes, &Options::default()));
    // Without smoothing (which rounds the box edges off) and on a fine grid (so that
    // crossings are not placed between saturated samples) the voxel volume is kept.
    let fine = Options {
        smooth_sigma_mm: 0.0,
        voxel_mm: 0.3,
        ..Options::default()
    };
    let s = mesh_of(&bytes, &fine);
    assert_closed_genus_0(&s);
    let (v, voxels) = (s.ingested.summary.volume_ml, s.source.voxel_volume_ml);
    assert!((v - voxels).abs() < 0.01 * voxels, "{v} vs {voxels} ml");
}

/// An asymmetric blob (ellipsoid with a bump) in world mm.
fn blob(p: [f64; 3]) -> u8 {
    let e = ((p[0] - 5.0) / 14.0).powi(2)
        + ((p[1] + 3.0) / 9.0).powi(2)
        + ((p[2] - 40.0) / 20.0).powi(2);
    let bump = (p[0] - 17.0).powi(2) + (p[1] - 3.0).powi(2) + (p[2] - 48.0).powi(2);
    u8::from(e <= 1.0 || bump <= 36.0)
}

/// The affine of the same voxel centres indexed as `index_a = M index_b + m0`.
fn reindexed(a: &Affine, m: [[f64; 3]; 3], m0: [f64; 3]) -> Affine {
    let mut linear = [[0.0; 3]; 3];
    for (r, row) in linear.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a.linear[r][k] * m[k][c]).sum();
        }
    }
    Affine {
        linear,
        offset: a.apply(m0),
        source: AffineSource::Sform,
    }
}

#[test]
fn permuted_and_flipped_axes_give_the_same_world_surface() {
    let dims = [40, 36, 24];
    let a = diagonal([0.9, 0.8, 2.5], [-15.0, -15.0, 5.0]);
    let reference = mesh_of(&volume_bytes(dims, &a, false, blob), &Options::default());
    assert_closed_genus_0(&reference);
    assert!(!reference.source.mirrored);
    // i ↔ k with j flipped (a rotation), and i ↔ k alone (a mirror).
    let variants = [
        (
            [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]],
            [0.0, 35.0, 0.0],
            false,
        ),
        (
            [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
            [0.0, 0.0, 0.0],
            true,
        ),
    ];
    let (rlo, rhi) = bounding_box(&reference.ingested.mesh);
    for (m, m0, mirrored) in variants {
        let b = reindexed(&a, m, m0);
        let b_dims = [dims[2], dims[1], dims[0]];
        let s = mesh_of(&volume_bytes(b_dims, &b, true, blob), &Options::default());
        assert_closed_genus_0(&s);
        assert_eq!(s.source.mirrored, mirrored);
        assert_eq!(s.source.selected_voxels, reference.source.selected_voxels);
        let (v, rv) = (
            s.ingested.summary.volume_ml,
            reference.ingested.summary.volume_ml,
        );
        assert!((v - rv).abs() < 1e-3 * rv, "{v} vs {rv}");
        let (lo, hi) = bounding_box(&s.ingested.mesh);
        for k in 0..3 {
            assert!(
                (lo[k] - rlo[k]).abs() < 0.05 && (hi[k] - rhi[k]).abs() < 0.05,
                "{lo:?} {hi:?} vs {rlo:?} {rhi:?}"
            );
        }
    }
}

#[test]
fn cavities_are_filled_or_kept_as_inner_surfaces() {
    let affine = diagonal([1.0; 3], [0.0; 3]);
    let shell = |p: [f64; 3]| {
        let d = p.iter().map(|c| (c - 20.0).powi(2)).sum::<f64>().sqrt();
        u8::from((8.0..=15.0).contains(&d))
    };
    let bytes = volume_bytes([41; 3], &affine, false, shell);
    let filled = mesh_of(&bytes, &Options::default());
    assert_closed_genus_0(&filled);
    assert!(filled.source.filled_voxels > 2000);
    let hollow = mesh_of(
        &bytes,
        &Options {
            fill_holes: false,
            ..Options::default()
        },
    );
    assert_eq!(hollow.ingested.summary.components, 2);
    assert_eq!(hollow.ingested.summary.euler_characteristic, 4);
    let shell_ml = 4.0 / 3.0 * PI * (15.0f64.powi(3) - 8.0f64.powi(3)) / 1000.0;
    let v = volume_ml(&hollow.ingested.mesh);
    assert!((v - shell_ml).abs() < 0.05 * shell_ml, "{v} vs {shell_ml}");
}
