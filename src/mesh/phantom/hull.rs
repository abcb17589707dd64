//! Convex hull of points on the unit sphere, i.e. their spherical Delaunay triangulation.
//!
//! Incremental Quickhull with outside sets: each face keeps the points in front of it; the
//! farthest one is added, the faces it sees are replaced by a fan to their horizon.

use crate::mesh::measures::{cross, dot, norm, sub};

/// A point sees a face when it lies farther than this in front of the face plane
/// (unit-sphere units).
const VISIBLE_EPS: f64 = 1e-12;
/// Smallest accepted norm of a face's edge cross product (twice its area).
const MIN_FACE_CROSS: f64 = 1e-14;
const NONE: usize = usize::MAX;

/// Why no hull could be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub(super) enum HullError {
    /// All points are (nearly) coplanar, or fewer than four.
    #[error("fewer than four points in general position")]
    Degenerate,
    /// Rounding gave a visible region that is not a disk.
    #[error("inconsistent horizon while adding point {0}")]
    Horizon(u32),
}

struct Face {
    v: [u32; 3],
    /// `adj[k]` is the face across edge `v[k] → v[(k + 1) % 3]`.
    adj: [usize; 3],
    normal: [f64; 3],
    offset: f64,
    alive: bool,
    outside: Vec<u32>,
}

struct Hull<'a> {
    points: &'a [[f64; 3]],
    faces: Vec<Face>,
    /// Visit stamp and visibility per face for the current insertion.
    mark: Vec<(u32, bool)>,
    stamp: u32,
}

/// Triangles of the convex hull, counter-clockwise from outside, as indices into `points`.
///
/// Points that are not hull vertices are not referenced.
pub(super) fn convex_hull(points: &[[f64; 3]]) -> Result<Vec<[u32; 3]>, HullError> {
    let mut hull = Hull::new(points)?;
    let mut pending: Vec<usize> = (0..hull.faces.len()).collect();
    while let Some(f) = pending.pop() {
        if !hull.faces[f].alive || hull.faces[f].outside.is_empty() {
            continue;
        }
        let face = &hull.faces[f];
        let p = face
            .outside
            .iter()
            .copied()
            .max_by(|&a, &b| {
                face.distance(points[a as usize])
                    .total_cmp(&face.distance(points[b as usize]))
            })
            .ok_or(HullError::Degenerate)?;
        hull.add_point(f, p, &mut pending)?;
    }
    Ok(hull.faces.iter().filter(|f| f.alive).map(|f| f.v).collect())
}

impl Face {
    fn new(points: &[[f64; 3]], v: [u32; 3]) -> Option<Self> {
        let [a, b, c] = v.map(|i| points[i as usize]);
        let n = cross(sub(b, a), sub(c, a));
        let len = norm(n);
        if len < MIN_FACE_CROSS {
            return None;
        }
        let normal = n.map(|x| x / len);
        Some(Self {
            v,
            adj: [NONE; 3],
            normal,
            offset: dot(normal, a),
            alive: true,
            outside: Vec::new(),
        })
    }

    fn distance(&self, p: [f64; 3]) -> f64 {
        dot(self.normal, p) - self.offset
    }
}

impl<'a> Hull<'a> {
    /// The starting tetrahedron with every other point in the outside set of a face.
    fn new(points: &'a [[f64; 3]]) -> Result<Self, HullError> {
        let [a, b, c, d] = initial_simplex(points).ok_or(HullError::Degenerate)?;
        let vs = [[a, b, c], [a, d, b], [b, d, c], [c, d, a]];
        let mut faces = Vec::with_capacity(2 * points.len());
        for v in vs {
            faces.push(Face::new(points, v).ok_or(HullError::Degenerate)?);
        }
        for f in 0..4 {
            for k in 0..3 {
                let (u, w) = (faces[f].v[k], faces[f].v[(k + 1) % 3]);
                let g = (0..4)
                    .find(|&g| (0..3).any(|j| faces[g].v[j] == w && faces[g].v[(j + 1) % 3] == u));
                faces[f].adj[k] = g.ok_or(HullError::Degenerate)?;
            }
        }
        let mut hull = Self {
            points,
            faces,
            mark: vec![(0, false); 4],
            stamp: 0,
        };
        for q in 0..points.len() as u32 {
            if ![a, b, c, d].contains(&q) {
                hull.assign(q, 0..4);
            }
        }
        Ok(hull)
    }

    /// Puts `q` in the outside set of the candidate face it is farthest in front of;
    /// returns that face, or `None` when `q` is in no candidate's front.
    fn assign(&mut self, q: u32, candidates: impl Iterator<Item = usize>) -> Option<usize> {
        let p = self.points[q as usize];
        let mut best = None;
        let mut best_d = VISIBLE_EPS;
        for f in candidates {
            let face = &self.faces[f];
            if face.alive {
                let d = face.distance(p);
                if d > best_d {
                    best_d = d;
                    best = Some(f);
                }
            }
        }
        if let Some(f) = best {
            self.faces[f].outside.push(q);
        }
        best
    }

    /// Adds point `p`, seen from face `f0`: replaces the visible faces by a fan to the horizon.
    fn add_point(&mut self, f0: usize, p: u32, pending: &mut Vec<usize>) -> Result<(), HullError> {
        let point = self.points[p as usize];
        self.stamp += 1;
        let stamp = self.stamp;
        self.mark[f0] = (stamp, true);
        let mut visible = vec![f0];
        let mut horizon: Vec<(u32, u32, usize)> = Vec::new();
        let mut stack = vec![f0];
        while let Some(f) = stack.pop() {
            for k in 0..3 {
                let g = self.faces[f].adj[k];
                if self.mark[g].0 != stamp {
                    let seen = self.faces[g].distance(point) > VISIBLE_EPS;
                    self.mark[g] = (stamp, seen);
                    if seen {
                        visible.push(g);
                        stack.push(g);
                    }
                }
                if !self.mark[g].1 {
                    horizon.push((self.faces[f].v[k], self.faces[f].v[(k + 1) % 3], g));
                }
            }
        }
        if horizon.is_empty() {
            return Err(HullError::Horizon(p));
        }
        let first_new = self.faces.len();
        for &(u, w, g) in &horizon {
            let id = self.faces.len();
            let mut face = Face::new(self.points, [u, w, p]).ok_or(HullError::Horizon(p))?;
            face.adj[0] = g;
            let kg = (0..3)
                .find(|&k| self.faces[g].v[k] == w && self.faces[g].v[(k + 1) % 3] == u)
                .ok_or(HullError::Horizon(p))?;
            self.faces[g].adj[kg] = id;
            self.faces.push(face);
            self.mark.push((0, false));
        }
        self.link_fan(first_new, p)?;
        let mut orphans = Vec::new();
        for &f in &visible {
            self.faces[f].alive = false;
            orphans.append(&mut self.faces[f].outside);
        }
        let end = self.faces.len();
        for q in orphans.into_iter().filter(|&q| q != p) {
            // Points still outside the hull see a new face, or rarely only an old one.
            let home = self
                .assign(q, first_new..end)
                .or_else(|| self.assign(q, 0..first_new));
            pending.extend(home);
        }
        pending.extend(first_new..end);
        Ok(())
    }

    /// Links the new faces `(u, w, p)` around `p` and checks that they form one cycle.
    fn link_fan(&mut self, first_new: usize, p: u32) -> Result<(), HullError> {
        let end = self.faces.len();
        for a in first_new..end {
            let w = self.faces[a].v[1];
            let mut next = (first_new..end).filter(|&b| self.faces[b].v[0] == w);
            let b = next.next().ok_or(HullError::Horizon(p))?;
            if next.next().is_some() {
                return Err(HullError::Horizon(p));
            }
            self.faces[a].adj[1] = b;
            self.faces[b].adj[2] = a;
        }
        let (mut f, mut steps) = (first_new, 0);
        loop {
            f = self.faces[f].adj[1];
            steps += 1;
            if f == first_new || steps > end - first_new {
                break;
            }
        }
        if steps == end - first_new {
            Ok(())
        } else {
            Err(HullError::Horizon(p))
        }
    }
}

/// Four points spanning a tetrahedron of large volume, or `None` if all are coplanar.
fn initial_simplex(points: &[[f64; 3]]) -> Option<[u32; 4]> {
    let p0 = *points.first()?;
    let argmax = |score: &dyn Fn([f64; 3]) -> f64| -> (u32, f64) {
        points
            .iter()
            .enumerate()
            .map(|(i, &p)| (i as u32, score(p)))
            .fold(
                (0, f64::NEG_INFINITY),
                |best, x| if x.1 > best.1 { x } else { best },
            )
    };
    let (i1, d1) = argmax(&|p| norm(sub(p, p0)));
    let p1 = points[i1 as usize];
    let axis = sub(p1, p0);
    let (i2, d2) = argmax(&|p| norm(cross(sub(p, p0), axis)));
    let n = cross(axis, sub(points[i2 as usize], p0));
    let (i3, d3) = argmax(&|p| dot(n, sub(p, p0)).abs());
    if d1 < MIN_FACE_CROSS || d2 < MIN_FACE_CROSS || d3 < MIN_FACE_CROSS {
        return None;
    }
    // Order the base so that the fourth point lies behind it.
    if dot(n, sub(points[i3 as usize], p0)) > 0.0 {
        Some([0, i2, i1, i3])
    } else {
        Some([0, i1, i2, i3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::mesh::phantom::check::assert_closed_surface;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_sphere_points(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                loop {
                    let p: [f64; 3] = [0; 3].map(|_| rng.random_range(-1.0..1.0));
                    let r = norm(p);
                    if r > 0.1 && r <= 1.0 {
                        break p.map(|x| x / r);
                    }
                }
            })
            .collect()
    }

    #[test]
    fn octahedron_has_eight_outward_faces() {
        let pts = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        // Each face plane holds exactly three vertices, so the hull is unique.
        let faces = convex_hull(&pts).unwrap();
        assert_eq!(faces.len(), 8);
        let mesh = Mesh::new(pts, faces);
        assert_closed_surface(&mesh);
        let v = crate::mesh::measures::signed_volume_mm3(&mesh);
        assert!((v - 4.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn random_sphere_points_give_a_closed_delaunay_surface() {
        for seed in 0..5 {
            let pts = random_sphere_points(600, seed);
            let faces = convex_hull(&pts).unwrap();
            assert_eq!(faces.len(), 2 * pts.len() - 4);
            // Convexity: no point in front of any face plane.
            for f in &faces {
                let face = Face::new(&pts, *f).unwrap();
                let worst = pts
                    .iter()
                    .map(|&p| face.distance(p))
                    .fold(f64::MIN, f64::max);
                assert!(worst < 1e-9, "point {worst} in front of a hull face");
            }
            assert_closed_surface(&Mesh::new(pts, faces));
        }
    }

    #[test]
    fn interior_points_are_left_out() {
        let mut pts = random_sphere_points(100, 7);
        pts.push([0.1, 0.0, 0.0]);
        pts.push([0.0, -0.2, 0.3]);
        let faces = convex_hull(&pts).unwrap();
        assert_eq!(faces.len(), 2 * 100 - 4);
        assert!(faces.iter().flatten().all(|&i| i < 100));
    }

    #[test]
    fn coplanar_points_are_rejected() {
        let pts = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        assert_eq!(convex_hull(&pts), Err(HullError::Degenerate));
    }
}
