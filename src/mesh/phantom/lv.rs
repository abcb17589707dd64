//! Left-ventricle myocardium phantom: a thick-walled truncated ellipsoidal cup.
//!
//! Canonical frame (mm): the long axis is `z`, both ellipsoids are centred at the origin,
//! the apex points to `-z` and the base plane is `z = base_height_mm`. The myocardium is the
//! outer ellipsoid below the base plane minus the inner (cavity) ellipsoid below it; the two
//! walls are joined at the base by a flat annular rim.

use std::f64::consts::{PI, TAU};

use rand::Rng;

use super::rings::{Ring, stitch_sequence};
use crate::mesh::Mesh;
use crate::mesh::measures::MM3_PER_ML;

/// Ranges the LV parameters are drawn from (uniformly), in mm unless stated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LvRanges {
    /// Outer short-axis radius along `x`.
    pub outer_radius_mm: (f64, f64),
    /// Short-axis eccentricity: `outer_radius_y = outer_radius_x · (1 − e)`.
    pub eccentricity: (f64, f64),
    /// Apex-to-base length of the outer wall.
    pub long_axis_mm: (f64, f64),
    /// Base height as a fraction of the outer half length (negative: below the equator).
    pub base_fraction: (f64, f64),
    /// Lateral wall thickness.
    pub wall_thickness_mm: (f64, f64),
    /// Apical wall thickness as a fraction of the lateral one.
    pub apex_fraction: (f64, f64),
    /// Accepted myocardial volume in ml (draws outside are redrawn).
    pub wall_volume_ml: (f64, f64),
    /// Target vertex count of the mesh.
    pub vertices: (f64, f64),
}

impl Default for LvRanges {
    fn default() -> Self {
        Self {
            outer_radius_mm: (27.0, 36.0),
            eccentricity: (0.0, 0.12),
            long_axis_mm: (65.0, 95.0),
            base_fraction: (-0.1, 0.3),
            wall_thickness_mm: (8.0, 13.0),
            apex_fraction: (0.6, 1.0),
            wall_volume_ml: (80.0, 180.0),
            vertices: (1100.0, 1900.0),
        }
    }
}

/// Redraws allowed before a draw is scaled into the volume range instead.
const MAX_DRAWS: usize = 1000;
/// Fewest vertices on a ring that is not a pole.
const MIN_RING_VERTICES: u32 = 5;
/// Relative random spread of the vertex count of each ring.
const RING_COUNT_SPREAD: f64 = 0.12;
/// Random shift of each interior ring along the profile, in ring spacings.
const RING_POSITION_JITTER: f64 = 0.3;
/// Samples of the meridian arc-length table.
const MERIDIAN_SAMPLES: usize = 2048;

/// Parameters of an LV cup in its canonical frame (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LvParams {
    /// Outer ellipsoid semi-axis along `x`.
    pub outer_radius_x_mm: f64,
    /// Outer ellipsoid semi-axis along `y`.
    pub outer_radius_y_mm: f64,
    /// Outer ellipsoid semi-axis along `z` (the apex is at `z = -outer_half_length_mm`).
    pub outer_half_length_mm: f64,
    /// Inner (cavity) ellipsoid semi-axis along `x`.
    pub inner_radius_x_mm: f64,
    /// Inner ellipsoid semi-axis along `y`.
    pub inner_radius_y_mm: f64,
    /// Inner ellipsoid semi-axis along `z`.
    pub inner_half_length_mm: f64,
    /// Height of the base plane above the ellipsoids' centre.
    pub base_height_mm: f64,
    /// Target edge length of the mesh.
    pub edge_length_mm: f64,
}

/// Volume in mm³ of the ellipsoid `x²/a² + y²/b² + z²/c² ≤ 1` below the plane `z = h`,
/// `π a b ∫_{-c}^{h} (1 − z²/c²) dz`, for `-c ≤ h ≤ c`.
pub fn ellipsoid_segment_volume_mm3(a: f64, b: f64, c: f64, h: f64) -> f64 {
    PI * a * b * ((h + c) - (h.powi(3) + c.powi(3)) / (3.0 * c * c))
}

impl LvParams {
    /// Apex-to-base length of the outer wall in mm.
    pub fn long_axis_mm(&self) -> f64 {
        self.outer_half_length_mm + self.base_height_mm
    }

    /// Lateral wall thickness (along `x`) in mm.
    pub fn wall_thickness_mm(&self) -> f64 {
        self.outer_radius_x_mm - self.inner_radius_x_mm
    }

    /// Wall thickness at the apex in mm.
    pub fn apex_thickness_mm(&self) -> f64 {
        self.outer_half_length_mm - self.inner_half_length_mm
    }

    /// Exact volume of the cavity (inside the inner wall, below the base) in ml.
    pub fn cavity_volume_ml(&self) -> f64 {
        ellipsoid_segment_volume_mm3(
            self.inner_radius_x_mm,
            self.inner_radius_y_mm,
            self.inner_half_length_mm,
            self.base_height_mm,
        ) / MM3_PER_ML
    }

    /// Exact myocardial (wall) volume in ml.
    pub fn volume_ml(&self) -> f64 {
        let outer = ellipsoid_segment_volume_mm3(
            self.outer_radius_x_mm,
            self.outer_radius_y_mm,
            self.outer_half_length_mm,
            self.base_height_mm,
        );
        outer / MM3_PER_ML - self.cavity_volume_ml()
    }

    /// Draws a cup from the default ranges, redrawing until its wall volume is in range.
    pub(super) fn sample<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let ranges = LvRanges::default();
        let (lo, hi) = ranges.wall_volume_ml;
        let mut p = Self::draw_shape(rng, &ranges);
        for _ in 1..MAX_DRAWS {
            if (lo..=hi).contains(&p.volume_ml()) {
                break;
            }
            p = Self::draw_shape(rng, &ranges);
        }
        let v = p.volume_ml();
        if !(lo..=hi).contains(&v) {
            p = p.scaled((v.clamp(lo, hi) / v).cbrt());
        }
        let target_vertices = rng.random_range(ranges.vertices.0..=ranges.vertices.1);
        // Rings spaced √3/2 edge apart with edge-long segments: one vertex per √3/2 edge².
        p.edge_length_mm = (2.0 * p.approx_area_mm2() / (3f64.sqrt() * target_vertices)).sqrt();
        p
    }

    fn draw_shape<R: Rng + ?Sized>(rng: &mut R, r: &LvRanges) -> Self {
        let mut draw = |range: (f64, f64)| rng.random_range(range.0..=range.1);
        let a = draw(r.outer_radius_mm);
        let b = a * (1.0 - draw(r.eccentricity));
        let long_axis = draw(r.long_axis_mm);
        let beta = draw(r.base_fraction);
        let c = long_axis / (1.0 + beta);
        let t = draw(r.wall_thickness_mm);
        let t_apex = t * draw(r.apex_fraction);
        Self {
            outer_radius_x_mm: a,
            outer_radius_y_mm: b,
            outer_half_length_mm: c,
            inner_radius_x_mm: a - t,
            inner_radius_y_mm: b - t,
            inner_half_length_mm: c - t_apex,
            base_height_mm: beta * c,
            edge_length_mm: 0.0,
        }
    }

    fn scaled(&self, s: f64) -> Self {
        Self {
            outer_radius_x_mm: s * self.outer_radius_x_mm,
            outer_radius_y_mm: s * self.outer_radius_y_mm,
            outer_half_length_mm: s * self.outer_half_length_mm,
            inner_radius_x_mm: s * self.inner_radius_x_mm,
            inner_radius_y_mm: s * self.inner_radius_y_mm,
            inner_half_length_mm: s * self.inner_half_length_mm,
            base_height_mm: s * self.base_height_mm,
            edge_length_mm: s * self.edge_length_mm,
        }
    }

    fn outer(&self) -> Meridian {
        Meridian::new(
            self.outer_radius_x_mm,
            self.outer_radius_y_mm,
            self.outer_half_length_mm,
            self.base_height_mm,
        )
    }

    fn inner(&self) -> Meridian {
        Meridian::new(
            self.inner_radius_x_mm,
            self.inner_radius_y_mm,
            self.inner_half_length_mm,
            self.base_height_mm,
        )
    }

    /// Surface area in mm², approximating each wall as a surface of revolution of its
    /// mean radius.
    fn approx_area_mm2(&self) -> f64 {
        let (outer, inner) = (self.outer(), self.inner());
        let (ro, ri) = (outer.mean_radius_at_base(), inner.mean_radius_at_base());
        outer.area_mm2() + inner.area_mm2() + PI * (ro * ro - ri * ri)
    }

    /// The cup's mesh with this subject's own ring layout and connectivity.
    pub(super) fn mesh<R: Rng + ?Sized>(&self, rng: &mut R) -> Mesh {
        self.mesh_with_edge(self.edge_length_mm, rng)
    }

    /// The cup's mesh with a given target edge length (mm): rings from the outer apex up
    /// the outer wall, across the rim and down the inner wall to the inner apex.
    fn mesh_with_edge<R: Rng + ?Sized>(&self, edge: f64, rng: &mut R) -> Mesh {
        let spacing = edge * 3f64.sqrt() / 2.0;
        let (outer, inner) = (self.outer(), self.inner());
        let mut shapes = outer.ring_shapes(spacing, rng);
        let o = outer.base_shape();
        let i = inner.base_shape();
        let width = 0.5 * ((o[0] - i[0]) + (o[1] - i[1]));
        let n_rim = ((width / spacing).round() as usize).max(1);
        for k in 1..n_rim {
            let l = jittered_fraction(k, n_rim, rng);
            shapes.push([0, 1, 2].map(|d| o[d] + l * (i[d] - o[d])));
        }
        let mut inner_shapes = inner.ring_shapes(spacing, rng);
        inner_shapes.reverse();
        shapes.extend(inner_shapes);
        rings_mesh(&shapes, edge, rng)
    }
}

/// Fraction `k / n` along a profile, shifted at random for interior rings.
fn jittered_fraction<R: Rng + ?Sized>(k: usize, n: usize, rng: &mut R) -> f64 {
    if k == 0 || k == n {
        return k as f64 / n as f64;
    }
    let shift = rng.random_range(-RING_POSITION_JITTER..=RING_POSITION_JITTER);
    (k as f64 + shift) / n as f64
}

/// Vertices on elliptic rings `[radius_x, radius_y, z]` (a zero radius is a pole) and
/// their stitched triangles; each ring gets its own vertex count and angular offset.
fn rings_mesh<R: Rng + ?Sized>(shapes: &[[f64; 3]], edge: f64, rng: &mut R) -> Mesh {
    let mut vertices = Vec::new();
    let mut rings = Vec::with_capacity(shapes.len());
    for &[rx, ry, z] in shapes {
        let first = vertices.len() as u32;
        let ring = if rx <= 0.0 && ry <= 0.0 {
            Ring {
                first,
                count: 1,
                offset: 0.0,
            }
        } else {
            let spread = rng.random_range(1.0 - RING_COUNT_SPREAD..=1.0 + RING_COUNT_SPREAD);
            let count = (PI * (rx + ry) / edge * spread).round() as u32;
            Ring {
                first,
                count: count.max(MIN_RING_VERTICES),
                offset: rng.random_range(0.0..TAU),
            }
        };
        for j in 0..ring.count {
            let phi = ring.angle(j);
            vertices.push([rx * phi.cos(), ry * phi.sin(), z]);
        }
        rings.push(ring);
    }
    Mesh::new(vertices, stitch_sequence(&rings))
}

/// One wall: the ellipsoid `(a, b, c)` from its apex up to the base plane `z = h`,
/// parametrised by the polar angle `θ` (`z = −c cos θ`).
struct Meridian {
    a: f64,
    b: f64,
    c: f64,
    theta_base: f64,
    /// Arc length (of the mean-radius meridian) at `θ = theta_base · j / MERIDIAN_SAMPLES`.
    arc: Vec<f64>,
}

impl Meridian {
    fn new(a: f64, b: f64, c: f64, h: f64) -> Self {
        let theta_base = (-h / c).clamp(-1.0, 1.0).acos();
        let m = 0.5 * (a + b);
        let dt = theta_base / MERIDIAN_SAMPLES as f64;
        let speed = |t: f64| (m * m * t.cos().powi(2) + c * c * t.sin().powi(2)).sqrt();
        let mut arc = Vec::with_capacity(MERIDIAN_SAMPLES + 1);
        arc.push(0.0);
        for j in 0..MERIDIAN_SAMPLES {
            let t = dt * (j as f64 + 0.5);
            arc.push(arc[j] + speed(t) * dt);
        }
        Self {
            a,
            b,
            c,
            theta_base,
            arc,
        }
    }

    fn length(&self) -> f64 {
        self.arc[MERIDIAN_SAMPLES]
    }

    fn mean_radius_at_base(&self) -> f64 {
        0.5 * (self.a + self.b) * self.theta_base.sin()
    }

    /// Area of the mean-radius surface of revolution, mm².
    fn area_mm2(&self) -> f64 {
        let m = 0.5 * (self.a + self.b);
        let dt = self.theta_base / MERIDIAN_SAMPLES as f64;
        (0..MERIDIAN_SAMPLES)
            .map(|j| TAU * m * (dt * (j as f64 + 0.5)).sin() * (self.arc[j + 1] - self.arc[j]))
            .sum()
    }

    /// Polar angle at arc length `s` (linear in the table).
    fn theta_at(&self, s: f64) -> f64 {
        if s >= self.length() {
            return self.theta_base;
        }
        let j = self.arc.partition_point(|&x| x <= s).saturating_sub(1);
        let (s0, s1) = (self.arc[j], self.arc[j + 1]);
        let dt = self.theta_base / MERIDIAN_SAMPLES as f64;
        dt * (j as f64 + ((s - s0) / (s1 - s0)).clamp(0.0, 1.0))
    }

    fn shape_at(&self, theta: f64) -> [f64; 3] {
        let s = theta.sin();
        [self.a * s, self.b * s, -self.c * theta.cos()]
    }

    fn base_shape(&self) -> [f64; 3] {
        self.shape_at(self.theta_base)
    }

    /// Ring shapes from the apex (a pole) to the base, about `spacing` apart.
    fn ring_shapes<R: Rng + ?Sized>(&self, spacing: f64, rng: &mut R) -> Vec<[f64; 3]> {
        let n = ((self.length() / spacing).round() as usize).max(2);
        (0..=n)
            .map(|k| match k {
                0 => [0.0, 0.0, -self.c],
                k if k == n => self.base_shape(),
                k => self.shape_at(self.theta_at(jittered_fraction(k, n, rng) * self.length())),
            })
            .collect()
    }
}

#[cfg(test)]
#[path = "lv_tests.rs"]
mod tests;
