//! Point-to-surface versions of the quality metrics: distances from vertices to the closest
//! point on the other shape's triangles (through a BVH), which many users of the field quote
//! because they do not depend on how finely the shapes are sampled.

use super::EvalError;
use std::collections::{BTreeMap, BTreeSet};

use super::metrics::{PairedDistances, paired_with, parallel_map};
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::distance::point_to_surface_distances;

/// A triangle surface: vertices `[n_vertices, 3]` in mm and faces `[n_faces, 3]`.
#[derive(Debug, Clone, Copy)]
pub struct Surface<'a> {
    /// Vertices, mm.
    pub vertices: &'a [[f64; 3]],
    /// Triangles as vertex indices.
    pub faces: &'a [[u32; 3]],
}

/// Point-to-surface distances of pairs `(a[i], b[i])` (`g`, `g'`); the lists must be equally
/// long and non-empty.
pub fn paired_point_to_surface(
    a: &[Surface<'_>],
    b: &[Surface<'_>],
) -> Result<PairedDistances, EvalError> {
    paired_with(a, b, |g, h| {
        let g_bvh = TriangleBvh::new(g.vertices, g.faces)?;
        let h_bvh = TriangleBvh::new(h.vertices, h.faces)?;
        Ok(point_to_surface_distances(
            g.vertices, &g_bvh, h.vertices, &h_bvh,
        ))
    })
}

/// Point-to-surface distances of each sample (`g`) to the training surface
/// `training[nearest[i]]` (`g'`): every training surface used is indexed once, however many
/// samples it is nearest to.
pub fn point_to_surface_to_nearest(
    samples: &[Surface<'_>],
    training: &[Surface<'_>],
    nearest: &[usize],
) -> Result<PairedDistances, EvalError> {
    let used: Vec<usize> = nearest
        .iter()
        .copied()
        .collect::<BTreeSet<usize>>()
        .into_iter()
        .collect();
    let built = parallel_map(&used, |&k| match training.get(k) {
        Some(t) => TriangleBvh::new(t.vertices, t.faces).map_err(EvalError::from),
        None => Err(EvalError::DimensionMismatch {
            what: "training surfaces",
            expected: k + 1,
            found: training.len(),
        }),
    });
    let mut surfaces = BTreeMap::new();
    for (k, bvh) in used.into_iter().zip(built) {
        surfaces.insert(k, bvh?);
    }
    paired_with(samples, nearest, |g, k| {
        let (Some(h), Some(h_bvh)) = (training.get(*k), surfaces.get(k)) else {
            return Err(EvalError::DimensionMismatch {
                what: "training surfaces",
                expected: k + 1,
                found: training.len(),
            });
        };
        let g_bvh = TriangleBvh::new(g.vertices, g.faces)?;
        Ok(point_to_surface_distances(
            g.vertices, &g_bvh, h.vertices, h_bvh,
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_surface_against_a_finer_sampling_of_itself_is_at_zero() {
        // A square as two triangles against the same square as eight: vertex-to-vertex
        // distances see the extra vertices, point-to-surface ones do not.
        let coarse_v = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        let coarse_f = [[0, 1, 2], [0, 2, 3]];
        let mut fine_v = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                fine_v.push([i as f64, j as f64, 0.0]);
            }
        }
        let mut fine_f = Vec::new();
        for j in 0..2u32 {
            for i in 0..2u32 {
                let v = j * 3 + i;
                fine_f.push([v, v + 1, v + 4]);
                fine_f.push([v, v + 4, v + 3]);
            }
        }
        let coarse = Surface {
            vertices: &coarse_v,
            faces: &coarse_f,
        };
        let fine = Surface {
            vertices: &fine_v,
            faces: &fine_f,
        };
        let d = paired_point_to_surface(&[coarse], &[fine]).unwrap();
        assert!(
            d.per_pair[0].hd < 1e-12 && d.summary.cd.mean < 1e-12,
            "{d:?}"
        );
        let v = crate::geometry::distance::surface_distances(&coarse_v, &fine_v).unwrap();
        assert!(v.ed_star > 0.5, "{v:?}");
    }

    #[test]
    fn nearest_surfaces_match_the_paired_distances() {
        let v0 = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let v1 = [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]];
        let f = [[0, 1, 2]];
        let (a, b) = (
            Surface {
                vertices: &v0,
                faces: &f,
            },
            Surface {
                vertices: &v1,
                faces: &f,
            },
        );
        let by_index = point_to_surface_to_nearest(&[a, a, b], &[b, a], &[0, 1, 0]).unwrap();
        let paired = paired_point_to_surface(&[a, a, b], &[b, a, b]).unwrap();
        assert_eq!(by_index, paired);
        assert!((by_index.per_pair[0].ed - 2.0).abs() < 1e-12);
        assert!(point_to_surface_to_nearest(&[a], &[b], &[3]).is_err());
    }

    #[test]
    fn mismatched_lists_are_refused() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let f = [[0, 1, 2]];
        let s = Surface {
            vertices: &v,
            faces: &f,
        };
        assert!(paired_point_to_surface(&[s, s], &[s]).is_err());
    }
}
