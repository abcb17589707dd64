//! Rigid pre-alignment (SPEC §2.1): every mesh is registered to a reference by rigid CPD,
//! keeping millimetres. Phantoms and patients come in arbitrary orientations, so the
//! registration first searches the 24 axis-permutation rotations on subsampled point
//! clouds, registers the best start on larger subsamples, and finishes on all points
//! warm-started with the subsample's variance (a few iterations instead of a hundred).

use serde::{Deserialize, Serialize};

use crate::geometry::cpd::{
    CpdResult, RigidCpdParams, rigid_cpd_from, rigid_cpd_multistart, rigid_cpd_warm,
};
use crate::geometry::{GeometryError, axis_permutation_rotations};
use crate::mesh::Mesh;

/// Settings of the registration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AlignmentParams {
    /// CPD settings of the final registration on all points.
    pub cpd: RigidCpdParams,
    /// Search the 24 axis-permutation rotations before refining.
    pub multistart: bool,
    /// Points per cloud during the rotation search.
    pub search_points: usize,
    /// CPD iterations per start during the rotation search.
    pub search_iterations: usize,
    /// Points per cloud of the intermediate registration.
    pub refine_points: usize,
    /// Most CPD iterations on all points after the intermediate registration.
    pub finish_iterations: usize,
}

impl Default for AlignmentParams {
    fn default() -> Self {
        Self {
            cpd: RigidCpdParams::default(),
            multistart: true,
            search_points: 300,
            search_iterations: 30,
            refine_points: 600,
            finish_iterations: 20,
        }
    }
}

/// Every `k`-th point so that at most `n` remain (deterministic).
pub fn subsample(points: &[[f64; 3]], n: usize) -> Vec<[f64; 3]> {
    let stride = points.len().div_ceil(n.max(1)).max(1);
    points.iter().step_by(stride).copied().collect()
}

/// Index of the mesh whose vertex count is closest to the median (ties: the first).
pub fn median_resolution_index(meshes: &[Mesh]) -> usize {
    let mut counts: Vec<usize> = meshes.iter().map(Mesh::vertex_count).collect();
    counts.sort_unstable();
    let median = counts.get(counts.len() / 2).copied().unwrap_or(0);
    meshes
        .iter()
        .enumerate()
        .min_by_key(|(_, m)| m.vertex_count().abs_diff(median))
        .map_or(0, |(i, _)| i)
}

/// Registers `template` onto `data`: the result maps template points into the data frame.
pub fn register(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &AlignmentParams,
) -> Result<CpdResult, GeometryError> {
    if !params.multistart {
        return crate::geometry::rigid_cpd(template, data, &params.cpd);
    }
    let search = RigidCpdParams {
        max_iterations: params.search_iterations.max(1),
        ..params.cpd
    };
    let coarse = rigid_cpd_multistart(
        &subsample(template, params.search_points),
        &subsample(data, params.search_points),
        &search,
        &axis_permutation_rotations(),
    )?;
    let middle = rigid_cpd_from(
        &subsample(template, params.refine_points),
        &subsample(data, params.refine_points),
        &params.cpd,
        &coarse.transform,
    )?;
    let finish = RigidCpdParams {
        max_iterations: params.finish_iterations.max(1),
        ..params.cpd
    };
    rigid_cpd_warm(template, data, &finish, &middle.transform, middle.sigma2)
}

/// One global affine normalisation of a dataset, `x' = (x − centre) / scale`, kept with the
/// model and undone on every output so that outputs are in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// Centre in mm.
    pub centre: [f64; 3],
    /// Scale in mm: the largest bounding-box side of the aligned training shapes.
    pub scale_mm: f64,
}

impl Normalisation {
    /// From aligned shapes (each `[n_vertices, 3]`, mm): their common bounding box maps
    /// into roughly `[-0.5, 0.5]³`.
    pub fn fit<S: AsRef<[[f64; 3]]>>(shapes: &[S]) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in shapes.iter().flat_map(|s| s.as_ref().iter()) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let centre = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
        let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        Self {
            centre: if centre.iter().all(|c: &f64| c.is_finite()) {
                centre
            } else {
                [0.0; 3]
            },
            scale_mm: if side.is_finite() && side > 0.0 {
                side
            } else {
                1.0
            },
        }
    }

    /// Into normalised coordinates.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| (p[k] - self.centre[k]) / self.scale_mm)
    }

    /// Back to mm.
    pub fn undo(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| p[k] * self.scale_mm + self.centre[k])
    }
}

#[cfg(test)]
mod tests {
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
        let lv = &phantom::generate(Family::Lv, 1, 4)[0].mesh;
        let target = moved(lv, 1.0);
        let result = register(&lv.vertices, &target, &AlignmentParams::default()).unwrap();
        let worst = worst_residual(&result, &lv.vertices, &target);
        assert!(worst < 1e-3, "largest residual {worst} mm");
    }

    #[test]
    fn registration_with_scale_recovers_a_scaled_phantom() {
        let liver = &phantom::generate(Family::Liver, 1, 6)[0].mesh;
        let target = moved(liver, 1.15);
        let mut params = AlignmentParams::default();
        params.cpd.scale = true;
        let result = register(&liver.vertices, &target, &params).unwrap();
        assert!(
            (result.transform.scale - 1.15).abs() < 1e-3,
            "scale {}",
            result.transform.scale
        );
        let worst = worst_residual(&result, &liver.vertices, &target);
        assert!(worst < 1e-3 * 100.0, "largest residual {worst} mm");
    }

    #[test]
    fn normalisation_round_trips_and_fits_the_unit_box() {
        let shapes = vec![vec![[0.0, 0.0, 0.0], [100.0, 50.0, 20.0]]];
        let n = Normalisation::fit(&shapes);
        assert_eq!(n.scale_mm, 100.0);
        assert_eq!(n.apply([100.0, 50.0, 20.0]), [0.5, 0.5, 0.5]);
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
}
