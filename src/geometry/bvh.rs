//! Closest points on a triangle surface through a bounding-volume hierarchy (axis-aligned
//! boxes, median split of the triangle centroids along the widest axis).

use super::GeometryError;
use super::error::check_points;
use super::points::dist2;
use super::triangle::closest_point_on_triangle;

/// Most triangles in a leaf.
const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Aabb {
    const EMPTY: Self = Self {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    fn grow(&mut self, p: [f64; 3]) {
        for (k, c) in p.into_iter().enumerate() {
            self.lo[k] = self.lo[k].min(c);
            self.hi[k] = self.hi[k].max(c);
        }
    }

    /// Squared distance (mm²) from `p` to the box; 0 inside.
    fn distance2(&self, p: [f64; 3]) -> f64 {
        (0..3)
            .map(|k| {
                let d = (self.lo[k] - p[k]).max(p[k] - self.hi[k]).max(0.0);
                d * d
            })
            .sum()
    }

    fn widest_axis(&self) -> usize {
        let extent = |k: usize| self.hi[k] - self.lo[k];
        (0..3)
            .max_by(|a, b| extent(*a).total_cmp(&extent(*b)))
            .unwrap_or(0)
    }
}

/// A node: a leaf holds `count` triangles from `first` in the ordered list; an inner node's
/// children are at `first` and `first + 1` in the node list.
#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb,
    first: usize,
    count: usize,
}

/// The closest point of a surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Index of the triangle it lies on.
    pub face: usize,
    /// The point, mm.
    pub point: [f64; 3],
    /// Distance from the query, mm.
    pub distance: f64,
}

/// A triangle surface `[n_vertices, 3]` (mm) with faces `[n_faces, 3]`, indexed for
/// closest-point queries.
#[derive(Debug, Clone)]
pub struct TriangleBvh {
    corners: Vec<[[f64; 3]; 3]>,
    order: Vec<usize>,
    nodes: Vec<Node>,
}

impl TriangleBvh {
    /// Builds the hierarchy. Fails without faces, on a non-finite vertex or a face index
    /// out of range.
    pub fn new(vertices: &[[f64; 3]], faces: &[[u32; 3]]) -> Result<Self, GeometryError> {
        check_points(vertices, "vertices")?;
        if faces.is_empty() {
            return Err(GeometryError::DegenerateInput(
                "the surface has no faces".into(),
            ));
        }
        let corners = faces
            .iter()
            .map(|f| {
                let corner = |i: u32| vertices.get(i as usize).copied();
                match (corner(f[0]), corner(f[1]), corner(f[2])) {
                    (Some(a), Some(b), Some(c)) => Ok([a, b, c]),
                    _ => Err(GeometryError::InvalidParams(format!(
                        "face {f:?} refers to a vertex beyond the {} given",
                        vertices.len()
                    ))),
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let centroids: Vec<[f64; 3]> = corners
            .iter()
            .map(|[a, b, c]| std::array::from_fn(|k| (a[k] + b[k] + c[k]) / 3.0))
            .collect();
        let mut bvh = Self {
            order: (0..corners.len()).collect(),
            corners,
            nodes: Vec::new(),
        };
        bvh.nodes.push(Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: bvh.order.len(),
        });
        bvh.split(0, &centroids);
        Ok(bvh)
    }

    fn bounds_of(&self, first: usize, count: usize) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &t in &self.order[first..first + count] {
            self.corners[t].iter().for_each(|p| b.grow(*p));
        }
        b
    }

    /// Sets the bounds of node `at` and splits it while it holds more than a leaf's worth
    /// (iteratively, so deep trees cannot overflow the stack).
    fn split(&mut self, root: usize, centroids: &[[f64; 3]]) {
        let mut pending = vec![root];
        while let Some(at) = pending.pop() {
            let Node { first, count, .. } = self.nodes[at];
            self.nodes[at].bounds = self.bounds_of(first, count);
            if count <= LEAF_SIZE {
                continue;
            }
            let mut spread = Aabb::EMPTY;
            for &t in &self.order[first..first + count] {
                spread.grow(centroids[t]);
            }
            let axis = spread.widest_axis();
            let half = count / 2;
            self.order[first..first + count].select_nth_unstable_by(half, |a, b| {
                centroids[*a][axis].total_cmp(&centroids[*b][axis])
            });
            let left = self.nodes.len();
            self.nodes.push(Node {
                bounds: Aabb::EMPTY,
                first,
                count: half,
            });
            self.nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: first + half,
                count: count - half,
            });
            self.nodes[at] = Node {
                bounds: self.nodes[at].bounds,
                first: left,
                count: 0,
            };
            pending.push(left);
            pending.push(left + 1);
        }
    }

    /// Number of triangles.
    pub fn face_count(&self) -> usize {
        self.corners.len()
    }

    /// The closest point of the surface to `p` (mm).
    pub fn closest(&self, p: [f64; 3]) -> SurfacePoint {
        let mut best = SurfacePoint {
            face: 0,
            point: self.corners[0][0],
            distance: f64::INFINITY,
        };
        let mut best2 = f64::INFINITY;
        let mut stack = vec![(0usize, self.nodes[0].bounds.distance2(p))];
        while let Some((at, bound2)) = stack.pop() {
            if bound2 >= best2 {
                continue;
            }
            let node = self.nodes[at];
            if node.count > 0 {
                for &t in &self.order[node.first..node.first + node.count] {
                    let [a, b, c] = self.corners[t];
                    let q = closest_point_on_triangle(p, a, b, c);
                    let d2 = dist2(p, q);
                    if d2 < best2 {
                        best2 = d2;
                        best = SurfacePoint {
                            face: t,
                            point: q,
                            distance: 0.0,
                        };
                    }
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let (dl, dr) = (
                self.nodes[l].bounds.distance2(p),
                self.nodes[r].bounds.distance2(p),
            );
            // The nearer child is popped first.
            if dl <= dr {
                stack.push((r, dr));
                stack.push((l, dl));
            } else {
                stack.push((l, dl));
                stack.push((r, dr));
            }
        }
        best.distance = best2.sqrt();
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};

    fn brute_force(mesh: &crate::mesh::Mesh, p: [f64; 3]) -> f64 {
        mesh.faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
                dist2(p, closest_point_on_triangle(p, a, b, c)).sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn cube_distances() {
        // The 10 mm cube with corners at 0 and 10.
        let cube = crate::mesh::fixtures::cube();
        let bvh = TriangleBvh::new(&cube.vertices, &cube.faces).unwrap();
        // Outside a face, beyond an edge, beyond a corner, and inside.
        assert!((bvh.closest([5.0, 5.0, 30.0]).distance - 20.0).abs() < 1e-12);
        assert!((bvh.closest([20.0, 20.0, 5.0]).distance - 200f64.sqrt()).abs() < 1e-12);
        assert!((bvh.closest([20.0, 20.0, 20.0]).distance - 300f64.sqrt()).abs() < 1e-12);
        assert!((bvh.closest([5.0, 5.0, 6.0]).distance - 4.0).abs() < 1e-12);
    }

    #[test]
    fn matches_brute_force_on_a_phantom() {
        let liver = &phantom::generate(Family::Liver, 1, 3)[0].mesh;
        let bvh = TriangleBvh::new(&liver.vertices, &liver.faces).unwrap();
        assert_eq!(bvh.face_count(), liver.faces.len());
        let centre = crate::geometry::points::centroid(&liver.vertices, None);
        for i in 0..60 {
            let t = i as f64 * 0.37;
            let r = 20.0 + 3.0 * i as f64;
            let p = [
                centre[0] + r * t.cos(),
                centre[1] + r * t.sin(),
                centre[2] + 40.0 * (0.5 * t).sin(),
            ];
            let hit = bvh.closest(p);
            let expected = brute_force(liver, p);
            assert!(
                (hit.distance - expected).abs() < 1e-9,
                "{} vs {expected}",
                hit.distance
            );
            assert!((dist2(hit.point, p).sqrt() - hit.distance).abs() < 1e-9);
        }
    }

    #[test]
    fn rejects_bad_surfaces() {
        assert!(TriangleBvh::new(&[[0.0; 3]], &[]).is_err());
        assert!(TriangleBvh::new(&[[0.0; 3], [1.0, 0.0, 0.0]], &[[0, 1, 2]]).is_err());
    }
}
