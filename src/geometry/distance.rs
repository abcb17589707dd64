//! Surface distances between vertex sets (SPEC §3): Hausdorff, mean closest-point (ED),
//! its reverse (ED*) and their sum (CD), all in mm.

use serde::{Deserialize, Serialize};

use super::GeometryError;
use super::bvh::TriangleBvh;
use super::kdtree::PointCloudIndex;

/// Distances between a shape `g` and a shape `g'`, in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SurfaceDistances {
    /// Symmetric Hausdorff distance `HD(g, g')`.
    pub hd: f64,
    /// `ED(g, g')`: mean over the vertices of `g` of the distance to the closest vertex of `g'`.
    pub ed: f64,
    /// `ED*(g, g') = ED(g', g)`.
    pub ed_star: f64,
    /// Chamfer distance `CD = ED + ED*`.
    pub cd: f64,
}

impl SurfaceDistances {
    /// From the one-sided distances `g → g'` (`ab`) and `g' → g` (`ba`).
    pub fn from_directed(ab: DirectedDistance, ba: DirectedDistance) -> Self {
        Self {
            hd: ab.max.max(ba.max),
            ed: ab.mean,
            ed_star: ba.mean,
            cd: ab.mean + ba.mean,
        }
    }
}

/// One-sided closest-point distances from `points` to an indexed set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectedDistance {
    /// Largest closest-point distance (directed Hausdorff), mm.
    pub max: f64,
    /// Mean closest-point distance, mm.
    pub mean: f64,
}

/// Closest-point distances from every point of `points` to the set behind `target`.
/// `points` must be non-empty; returns zeros otherwise.
pub fn directed(points: &[[f64; 3]], target: &PointCloudIndex) -> DirectedDistance {
    if points.is_empty() {
        return DirectedDistance {
            max: 0.0,
            mean: 0.0,
        };
    }
    let (mut max, mut sum) = (0.0f64, 0.0);
    for p in points {
        let d = target.nearest(*p).1;
        max = max.max(d);
        sum += d;
    }
    DirectedDistance {
        max,
        mean: sum / points.len() as f64,
    }
}

/// Distances between `a` and `b` using prebuilt indices of both (`a_index` over `a`,
/// `b_index` over `b`); use this when one set is compared with many others.
pub fn surface_distances_indexed(
    a: &[[f64; 3]],
    a_index: &PointCloudIndex,
    b: &[[f64; 3]],
    b_index: &PointCloudIndex,
) -> SurfaceDistances {
    SurfaceDistances::from_directed(directed(a, b_index), directed(b, a_index))
}

/// Distances between vertex sets `a` (`g`) and `b` (`g'`), `[n, 3]` in mm.
/// Fails if either set is empty or holds a non-finite coordinate.
pub fn surface_distances(
    a: &[[f64; 3]],
    b: &[[f64; 3]],
) -> Result<SurfaceDistances, GeometryError> {
    let a_index = PointCloudIndex::new(a)?;
    let b_index = PointCloudIndex::new(b)?;
    Ok(surface_distances_indexed(a, &a_index, b, &b_index))
}

/// Distances from every point of `points` to the closest point of a triangle surface.
pub fn directed_to_surface(points: &[[f64; 3]], surface: &TriangleBvh) -> DirectedDistance {
    let (mut max, mut sum) = (0.0f64, 0.0);
    for p in points {
        let d = surface.closest(*p).distance;
        max = max.max(d);
        sum += d;
    }
    DirectedDistance {
        max,
        mean: if points.is_empty() {
            0.0
        } else {
            sum / points.len() as f64
        },
    }
}

/// Point-to-surface distances between meshes `a` (`g`) and `b` (`g'`), mm: `ED` averages
/// the distance from `a`'s vertices to `b`'s triangles, `ED*` the reverse, `HD` is the
/// larger maximum. Unlike vertex-to-vertex distances they do not grow with coarse sampling.
pub fn point_to_surface_distances(
    a: &[[f64; 3]],
    a_surface: &TriangleBvh,
    b: &[[f64; 3]],
    b_surface: &TriangleBvh,
) -> SurfaceDistances {
    SurfaceDistances::from_directed(
        directed_to_surface(a, b_surface),
        directed_to_surface(b, a_surface),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_to_surface_between_nested_cubes() {
        // The 10 mm cube and the same cube grown by 2 mm about its centre: every vertex of
        // the big cube is 2·√3 mm from the small one's corner, every small-cube vertex 2 mm
        // from the big cube's faces.
        let small = crate::mesh::fixtures::cube();
        let big: Vec<[f64; 3]> = small
            .vertices
            .iter()
            .map(|p| p.map(|c| (c - 5.0) * 1.4 + 5.0))
            .collect();
        let small_bvh = TriangleBvh::new(&small.vertices, &small.faces).unwrap();
        let big_bvh = TriangleBvh::new(&big, &small.faces).unwrap();
        let d = point_to_surface_distances(&small.vertices, &small_bvh, &big, &big_bvh);
        assert!((d.ed - 2.0).abs() < 1e-12, "{d:?}");
        assert!((d.ed_star - 12f64.sqrt()).abs() < 1e-12, "{d:?}");
        assert!((d.hd - 12f64.sqrt()).abs() < 1e-12);
        // Vertex-to-vertex distances agree here (corners face corners).
        let v = surface_distances(&small.vertices, &big).unwrap();
        assert!((v.ed - 12f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn hand_computed_example() {
        // g = {(0,0,0), (1,0,0)}, g' = {(0,0,2)}.
        // From g: distances 2 and √5 → ED = (2 + √5)/2; from g': min(2, √5) = 2 → ED* = 2.
        let g = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let h = [[0.0, 0.0, 2.0]];
        let d = surface_distances(&g, &h).unwrap();
        let s5 = 5f64.sqrt();
        assert!((d.ed - (2.0 + s5) / 2.0).abs() < 1e-12);
        assert!((d.ed_star - 2.0).abs() < 1e-12);
        assert!((d.hd - s5).abs() < 1e-12);
        assert!((d.cd - (d.ed + d.ed_star)).abs() < 1e-15);
        // Swapping the sets swaps ED and ED* and keeps HD.
        let r = surface_distances(&h, &g).unwrap();
        assert_eq!((r.ed, r.ed_star, r.hd), (d.ed_star, d.ed, d.hd));
    }

    #[test]
    fn asymmetric_subset_example() {
        // b ⊂ a: every b point lies on a (ED* = 0) but a has a far point.
        let a = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        let b = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let d = surface_distances(&a, &b).unwrap();
        assert_eq!(d.ed_star, 0.0);
        assert!((d.ed - 4.0 / 3.0).abs() < 1e-12);
        assert!((d.hd - 4.0).abs() < 1e-12);
    }

    #[test]
    fn identical_sets_have_zero_distance() {
        let a = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        let d = surface_distances(&a, &a).unwrap();
        assert_eq!(
            d,
            SurfaceDistances {
                hd: 0.0,
                ed: 0.0,
                ed_star: 0.0,
                cd: 0.0
            }
        );
        assert!(surface_distances(&a, &[]).is_err());
    }
}
