//! Marching cubes on a regular grid with one vertex per crossed grid edge.
//!
//! Written here rather than taken from a crate: the crates at hand emit a triangle soup with
//! single-precision positions computed separately in each cube (so neighbours disagree in the
//! last bits and welding by position can leave cracks). Here every grid edge owns one vertex,
//! created once, so the surface is welded by construction and, with a table that resolves
//! ambiguous faces the same way from both sides, closed and manifold whenever the field is
//! below the level on the grid's border.

use super::field::{Field, linear};
use super::tables::{CORNERS, EDGES, TRIANGLES};

/// Crossing points are kept at least this fraction of an edge away from its ends, so that a
/// sample exactly at the level cannot make two vertices coincide.
pub const EDGE_MARGIN: f64 = 1e-4;

/// No vertex on this edge yet.
const NONE: u32 = u32::MAX;

/// An isosurface in grid coordinates (sample units, x fastest).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GridSurface {
    /// Vertex positions in sample units, `[n_vertices]` of `[x, y, z]`.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise seen from the outside (values at or below the level).
    pub faces: Vec<[u32; 3]>,
}

/// The surface between samples above `level` (inside) and the others (outside).
pub fn march(field: &Field, level: f32) -> GridSurface {
    let dims = field.dims;
    let mut surface = GridSurface::default();
    if dims.iter().any(|&n| n < 2) || field.values.len() != dims.iter().product::<usize>() {
        return surface;
    }
    let mut on_edge = [
        vec![NONE; field.values.len()],
        vec![NONE; field.values.len()],
        vec![NONE; field.values.len()],
    ];
    for z in 0..dims[2] - 1 {
        for y in 0..dims[1] - 1 {
            for x in 0..dims[0] - 1 {
                let pattern = cube_pattern(field, [x, y, z], level);
                if pattern == 0 || pattern == 0xff {
                    continue;
                }
                for tri in TRIANGLES[pattern].chunks_exact(3) {
                    if tri[0] < 0 {
                        break;
                    }
                    let mut ids = [0u32; 3];
                    for (id, &edge) in ids.iter_mut().zip(tri) {
                        *id = edge_vertex(
                            field,
                            level,
                            [x, y, z],
                            edge as usize,
                            &mut on_edge,
                            &mut surface,
                        );
                    }
                    // With bits set for outside corners, the table's triangles are
                    // counter-clockwise seen from the outside.
                    surface.faces.push(ids);
                }
            }
        }
    }
    surface
}

/// Bit `c` set when corner `c` of the cube at `p` is outside (at or below the level).
fn cube_pattern(field: &Field, p: [usize; 3], level: f32) -> usize {
    let mut pattern = 0;
    for (c, offset) in CORNERS.iter().enumerate() {
        let q = [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]];
        if field.at(q) <= level {
            pattern |= 1 << c;
        }
    }
    pattern
}

/// The vertex on cube edge `edge` of the cube at `p`, created on first use.
fn edge_vertex(
    field: &Field,
    level: f32,
    p: [usize; 3],
    edge: usize,
    on_edge: &mut [Vec<u32>; 3],
    surface: &mut GridSurface,
) -> u32 {
    let [a, b] = EDGES[edge];
    let (ca, cb) = (CORNERS[a], CORNERS[b]);
    let axis = (0..3).find(|&k| ca[k] != cb[k]).unwrap_or(0);
    let mut lower = [p[0] + ca[0], p[1] + ca[1], p[2] + ca[2]];
    lower[axis] = p[axis] + ca[axis].min(cb[axis]);
    let key = linear(field.dims, lower);
    if on_edge[axis][key] != NONE {
        return on_edge[axis][key];
    }
    let mut upper = lower;
    upper[axis] += 1;
    let (v0, v1) = (f64::from(field.at(lower)), f64::from(field.at(upper)));
    let t = ((f64::from(level) - v0) / (v1 - v0)).clamp(EDGE_MARGIN, 1.0 - EDGE_MARGIN);
    let mut position = lower.map(|c| c as f64);
    position[axis] += t;
    let id = surface.vertices.len() as u32;
    surface.vertices.push(position);
    on_edge[axis][key] = id;
    id
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::mesh::measures::{area_mm2, signed_volume_mm3};
    use crate::mesh::topology::euler_characteristic;
    use std::collections::HashMap;

    fn field(dims: [usize; 3], f: impl Fn([f64; 3]) -> f32) -> Field {
        let mut values = Vec::new();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    values.push(f([x as f64, y as f64, z as f64]));
                }
            }
        }
        Field { dims, values }
    }

    /// Every directed edge once and its reverse once: closed, manifold, consistently oriented.
    fn assert_closed_oriented(s: &GridSurface, what: &str) {
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for f in &s.faces {
            for k in 0..3 {
                *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1, "{what}: directed edge {a}->{b} used {n} times");
            assert_eq!(
                directed.get(&(b, a)),
                Some(&1),
                "{what}: edge {a}-{b} is open"
            );
        }
    }

    #[test]
    fn sphere_is_closed_outward_and_close_to_analytic() {
        let r = 6.3;
        let s = march(
            &field([17, 17, 17], |p| {
                let d = ((p[0] - 8.0).powi(2) + (p[1] - 8.0).powi(2) + (p[2] - 8.0).powi(2)).sqrt();
                (r - d) as f32
            }),
            0.0,
        );
        assert_closed_oriented(&s, "sphere");
        let mesh = Mesh::new(s.vertices.clone(), s.faces.clone());
        assert_eq!(euler_characteristic(&mesh), 2);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let volume = signed_volume_mm3(&mesh);
        assert!(volume > 0.0, "outward faces give a positive volume");
        assert!((volume - exact).abs() < 0.02 * exact, "{volume} vs {exact}");
        let area = area_mm2(&mesh);
        let exact_area = 4.0 * std::f64::consts::PI * r * r;
        assert!(
            (area - exact_area).abs() < 0.03 * exact_area,
            "{area} vs {exact_area}"
        );
    }

    #[test]
    fn a_single_inside_sample_gives_an_octahedron() {
        let s = march(
            &field([3, 3, 3], |p| if p == [1.0; 3] { 1.0 } else { 0.0 }),
            0.5,
        );
        assert_eq!(s.vertices.len(), 6);
        assert_eq!(s.faces.len(), 8);
        assert_closed_oriented(&s, "octahedron");
        let mesh = Mesh::new(s.vertices, s.faces);
        // Crossings at the edge midpoints: an octahedron of half-diagonal 0.5.
        assert!((signed_volume_mm3(&mesh) - 4.0 / 3.0 * 0.125).abs() < 1e-9);
    }

    #[test]
    fn samples_at_the_level_do_not_collapse_vertices() {
        // Values exactly at the level on the plane x = 2: outside, but crossings stay distinct.
        let s = march(
            &field([6, 4, 4], |p| {
                let interior = (1.0..=2.0).contains(&p[0])
                    && (1.0..=2.0).contains(&p[1])
                    && (1.0..=2.0).contains(&p[2]);
                if !interior {
                    0.0
                } else if p[0] == 2.0 {
                    0.5
                } else {
                    1.0
                }
            }),
            0.5,
        );
        assert_closed_oriented(&s, "level plane");
        let mesh = Mesh::new(s.vertices, s.faces);
        assert!(signed_volume_mm3(&mesh) > 0.0);
    }

    /// Every pattern of two neighbouring cubes (12 corners, 4,096 patterns) along each axis,
    /// inside a border of outside samples: the surface must always be closed and manifold.
    /// This checks that the table resolves ambiguous faces alike from both sides.
    #[test]
    fn every_pair_of_neighbouring_cubes_gives_a_closed_surface() {
        for axis in 0..3 {
            let mut dims = [4, 4, 4];
            dims[axis] = 5;
            for bits in 0u32..4096 {
                let f = field(dims, |p| {
                    let q = p.map(|c| c as usize);
                    if q.iter().zip(dims).any(|(&c, n)| c == 0 || c == n - 1) {
                        return 0.0;
                    }
                    let mut local = [q[0] - 1, q[1] - 1, q[2] - 1];
                    local.swap(0, axis);
                    let bit = local[0] + 3 * (local[1] + 2 * local[2]);
                    if bits >> bit & 1 == 1 { 1.0 } else { 0.0 }
                });
                let s = march(&f, 0.5);
                assert_closed_oriented(&s, &format!("axis {axis}, pattern {bits:#x}"));
            }
        }
    }
}
