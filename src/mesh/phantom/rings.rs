//! Closed surfaces from a sequence of vertex rings around an axis.
//!
//! A ring is a closed loop of `count` vertices at angles `offset + 2π j / count` (radians,
//! counter-clockwise seen from the side the sequence heads to); a ring of one vertex is a pole.
//! Consecutive rings are stitched by the two-pointer merge on angle, so rings with different
//! counts and offsets give a valid strip of `count_a + count_b` triangles. A sequence that
//! starts and ends with a pole is a closed genus-0 surface.

use std::f64::consts::TAU;

/// A ring of consecutive vertices `first .. first + count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Ring {
    /// Index of the ring's first vertex.
    pub first: u32,
    /// Number of vertices (1 for a pole).
    pub count: u32,
    /// Angle of vertex `first` in radians.
    pub offset: f64,
}

impl Ring {
    pub(super) fn angle(&self, j: u32) -> f64 {
        self.offset + TAU * f64::from(j) / f64::from(self.count)
    }

    fn vertex(&self, j: u32) -> u32 {
        self.first + j % self.count
    }
}

/// Triangles of the closed strip sequence `rings[0] → rings[1] → …`.
///
/// Seen from outside, the sequence runs upward and angles grow to the right, which makes
/// the faces counter-clockwise from outside.
pub(super) fn stitch_sequence(rings: &[Ring]) -> Vec<[u32; 3]> {
    let mut faces = Vec::new();
    for pair in rings.windows(2) {
        stitch(&pair[0], &pair[1], &mut faces);
    }
    faces
}

/// Appends the triangles between a lower ring `a` and an upper ring `b`.
pub(super) fn stitch(a: &Ring, b: &Ring, faces: &mut Vec<[u32; 3]>) {
    if a.count == 1 {
        for j in 0..b.count {
            faces.push([a.first, b.vertex(j + 1), b.vertex(j)]);
        }
        return;
    }
    if b.count == 1 {
        for i in 0..a.count {
            faces.push([a.vertex(i), a.vertex(i + 1), b.first]);
        }
        return;
    }
    // Start b at its last vertex at or before a's first vertex (in angle), unwrapped so
    // that b_angle(0) <= a_angle(0) < b_angle(1).
    let step_b = TAU / f64::from(b.count);
    let lag = (a.offset - b.offset).rem_euclid(TAU);
    let j0 = ((lag / step_b).floor() as u32).min(b.count - 1);
    let b_start = a.offset - (lag - f64::from(j0) * step_b);
    let b_angle = |j: u32| b_start + step_b * f64::from(j);
    let (mut i, mut j) = (0u32, 0u32);
    while i < a.count || j < b.count {
        let advance_a = if i == a.count {
            false
        } else if j == b.count {
            true
        } else {
            a.angle(i + 1) <= b_angle(j + 1)
        };
        if advance_a {
            faces.push([a.vertex(i), a.vertex(i + 1), b.vertex(j0 + j)]);
            i += 1;
        } else {
            faces.push([a.vertex(i), b.vertex(j0 + j + 1), b.vertex(j0 + j)]);
            j += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::mesh::measures::signed_volume_mm3;
    use crate::mesh::phantom::check::assert_closed_surface;

    /// A sphere of radius 10 mm from rings with the given counts and offsets.
    fn ring_sphere(counts: &[u32], offsets: &[f64]) -> Mesh {
        let n = counts.len() + 1;
        let mut vertices = vec![[0.0, 0.0, -10.0]];
        let mut rings = vec![Ring {
            first: 0,
            count: 1,
            offset: 0.0,
        }];
        for (k, (&count, &offset)) in counts.iter().zip(offsets).enumerate() {
            let theta = std::f64::consts::PI * (k + 1) as f64 / n as f64;
            let ring = Ring {
                first: vertices.len() as u32,
                count,
                offset,
            };
            for j in 0..count {
                let phi = ring.angle(j);
                let (s, c) = (theta.sin() * 10.0, -theta.cos() * 10.0);
                vertices.push([s * phi.cos(), s * phi.sin(), c]);
            }
            rings.push(ring);
        }
        rings.push(Ring {
            first: vertices.len() as u32,
            count: 1,
            offset: 0.0,
        });
        vertices.push([0.0, 0.0, 10.0]);
        Mesh::new(vertices, stitch_sequence(&rings))
    }

    #[test]
    fn strip_has_one_triangle_per_ring_vertex() {
        let a = Ring {
            first: 0,
            count: 5,
            offset: 0.3,
        };
        let b = Ring {
            first: 5,
            count: 8,
            offset: 4.0,
        };
        let mut faces = Vec::new();
        stitch(&a, &b, &mut faces);
        assert_eq!(faces.len(), 13);
    }

    #[test]
    fn uneven_rings_close_an_outward_sphere() {
        let mesh = ring_sphere(&[5, 9, 14, 13, 7, 3], &[0.0, 2.0, 6.1, 3.3, 0.01, 5.9]);
        assert_closed_surface(&mesh);
        let v = signed_volume_mm3(&mesh);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
        assert!(v > 0.3 * exact && v < exact, "volume {v}");
    }

    #[test]
    fn equal_offsets_and_counts_give_the_usual_grid() {
        let mesh = ring_sphere(&[6, 6], &[0.0, 0.0]);
        assert_closed_surface(&mesh);
        assert_eq!(mesh.faces.len(), 6 + 12 + 6);
    }
}
