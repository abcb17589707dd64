//! Rigid pre-alignment (SPEC §2.1): every mesh is registered to a reference by rigid CPD,
//! keeping millimetres. Phantoms and patients come in arbitrary orientations, so the
//! registration first searches the 24 axis-permutation rotations on subsampled point
//! clouds, registers the best start on larger subsamples, and finishes on all points
//! warm-started with the subsample's variance (a few iterations instead of a hundred).

use serde::{Deserialize, Serialize};

use crate::geometry::cpd::{CpdResult, RigidCpdParams, rigid_cpd_from, rigid_cpd_warm};
use crate::geometry::distance::directed;
use crate::geometry::kdtree::PointCloudIndex;
use crate::geometry::points::{centroid, mat_vec, rms_radius, sub};
use crate::geometry::{GeometryError, RigidTransform, axis_permutation_rotations};
use crate::mesh::simplify::simplify;
use crate::mesh::{Laterality, Mesh};
use crate::models::ModelError;

/// Default vertex budget of a mesh before it is registered (and, for the ASMG family, before
/// the graph network sees it): larger meshes are simplified first.
pub const DEFAULT_MAX_VERTICES: usize = 3000;
/// Largest vertex budget accepted (the kidneys of KiTS19 have up to 25,800 vertices).
pub const MAX_VERTICES_LIMIT: usize = 30_000;

/// A mesh simplified to at most `max_vertices` vertices (unchanged when it has fewer).
pub fn simplified(mesh: &Mesh, max_vertices: usize) -> Result<Mesh, ModelError> {
    simplify(mesh, max_vertices)
        .map(|s| s.mesh)
        .map_err(|e| ModelError::InvalidInput(format!("simplification failed: {e}")))
}

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
    /// Register each mesh as its mirror image too and let the population choose between
    /// the two (see [`crate::models::sides`]). Absent from models stored before it existed:
    /// false.
    #[serde(default)]
    pub mirror: bool,
    /// With `mirror`, the side of the reference, which every shape of the model has: known
    /// when the user gave the side of training meshes, and then a new mesh of a given side
    /// takes it without comparison. Absent from models stored before it existed: unknown.
    #[serde(default)]
    pub laterality: Option<Laterality>,
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
            mirror: false,
            laterality: None,
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

/// Starts kept from the rotation search for the intermediate registration.
const SEARCH_CANDIDATES: usize = 6;

/// Area per point (mm²) of `points` spread over a sphere of their rms radius: about the
/// squared point spacing, the variance floor of the coarse registration stages.
fn spacing2(points: &[[f64; 3]]) -> f64 {
    let r = rms_radius(points);
    4.0 * std::f64::consts::PI * r * r / points.len().max(1) as f64
}

/// How well `transform` lays `template` onto `data`: the symmetric mean closest-point
/// distance in mm. (The likelihood is no good judge across starts: with the outlier term, a
/// tight fit of part of the shape can beat a looser fit of all of it.)
fn fit_distance(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    data_index: &PointCloudIndex,
    transform: &RigidTransform,
) -> Result<f64, GeometryError> {
    let moved = transform.apply_all(template);
    let moved_index = PointCloudIndex::new(&moved)?;
    Ok(0.5 * (directed(&moved, data_index).mean + directed(data, &moved_index).mean))
}

/// The rotation search: every axis-permutation start on subsampled clouds with the scale
/// fixed (a free scale can collapse the template from a poor start); the best few by
/// surface fit.
fn search_rotations(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &AlignmentParams,
) -> Result<Vec<CpdResult>, GeometryError> {
    let search = RigidCpdParams {
        max_iterations: params.search_iterations.max(1),
        scale: false,
        min_sigma2: spacing2(data),
        ..params.cpd
    };
    let (cx, cy) = (centroid(data, None), centroid(template, None));
    let runs = axis_permutation_rotations()
        .iter()
        .map(|r| {
            let initial = RigidTransform {
                rotation: *r,
                translation: sub(cx, mat_vec(r, cy)),
                scale: 1.0,
            };
            rigid_cpd_from(template, data, &search, &initial)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let index = PointCloudIndex::new(data)?;
    let mut ranked = runs
        .into_iter()
        .map(|run| Ok((fit_distance(template, data, &index, &run.transform)?, run)))
        .collect::<Result<Vec<_>, GeometryError>>()?;
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(ranked
        .into_iter()
        .take(SEARCH_CANDIDATES)
        .map(|(_, run)| run)
        .collect())
}

/// Registers `template` onto `data`: the result maps template points into the data frame.
///
/// With `multistart`: a rotation search on subsamples (the template pre-scaled to the
/// data's size when the scale is estimated), the best starts registered on larger
/// subsamples, and the best of those finished on all points, each stage warm-started with
/// the previous variance.
pub fn register(
    template: &[[f64; 3]],
    data: &[[f64; 3]],
    params: &AlignmentParams,
) -> Result<CpdResult, GeometryError> {
    if !params.multistart {
        return crate::geometry::rigid_cpd(template, data, &params.cpd);
    }
    let s0 = if params.cpd.scale {
        rms_radius(data) / rms_radius(template)
    } else {
        1.0
    };
    // The rotation is found with the scale held at the size ratio s0 (a free scale
    // shrinks the template while the rotation is still poor); only the last stage frees it.
    let scaled: Vec<[f64; 3]> = template.iter().map(|p| p.map(|c| c * s0)).collect();
    let candidates = search_rotations(
        &subsample(&scaled, params.search_points),
        &subsample(data, params.search_points),
        params,
    )?;
    let (middle_template, middle_data) = (
        subsample(&scaled, params.refine_points),
        subsample(data, params.refine_points),
    );
    let middle_index = PointCloudIndex::new(&middle_data)?;
    let middle_params = RigidCpdParams {
        scale: false,
        ..params.cpd
    };
    let mut best: Option<(f64, CpdResult)> = None;
    for c in candidates {
        let run = rigid_cpd_warm(
            &middle_template,
            &middle_data,
            &middle_params,
            &c.transform,
            c.sigma2,
        )?;
        let fit = fit_distance(
            &middle_template,
            &middle_data,
            &middle_index,
            &run.transform,
        )?;
        if best.as_ref().is_none_or(|(b, _)| fit < *b) {
            best = Some((fit, run));
        }
    }
    let (_, middle) =
        best.ok_or_else(|| GeometryError::InvalidParams("no rotation candidates".into()))?;
    let finish = RigidCpdParams {
        max_iterations: params.finish_iterations.max(1),
        ..params.cpd
    };
    let mut result = rigid_cpd_warm(&scaled, data, &finish, &middle.transform, middle.sigma2)?;
    // T(y) = s·R·(s0·y) + t for the original template.
    result.transform.scale *= s0;
    Ok(result)
}

/// A registration of the template onto a mesh or onto the mesh's mirror image.
#[derive(Debug, Clone)]
pub struct Registration {
    /// Maps template points onto the registered points: the mesh's vertices, or their
    /// mirror images when `mirrored`.
    pub cpd: CpdResult,
    /// The mesh was mirrored (x → −x) before it was registered: a left kidney laid onto a
    /// right one (which side each mesh takes: [`crate::models::sides`]).
    pub mirrored: bool,
}

impl Registration {
    /// A point of the mesh (mm) as it was registered: mirrored when the mesh was.
    pub fn registered(&self, p: [f64; 3]) -> [f64; 3] {
        if self.mirrored { mirror(p) } else { p }
    }

    /// A point of the mesh (mm) in the template frame.
    pub fn to_template_frame(&self, p: [f64; 3]) -> [f64; 3] {
        self.cpd.transform.inverse_apply(self.registered(p))
    }

    /// The mesh's faces for its vertices in the template frame: a mirror image turns a
    /// surface inside out, so each mirrored triangle's winding is reversed to keep its
    /// normal pointing outwards.
    pub fn faces(&self, faces: &[[u32; 3]]) -> Vec<[u32; 3]> {
        if self.mirrored {
            faces.iter().map(|&[a, b, c]| [a, c, b]).collect()
        } else {
            faces.to_vec()
        }
    }
}

/// The mirror image of a point in the plane x = 0: the reflection every mirrored mesh and
/// member takes.
pub use crate::mesh::laterality::mirror_point as mirror;

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
#[path = "alignment_tests.rs"]
mod tests;
