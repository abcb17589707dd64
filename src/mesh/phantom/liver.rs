//! Liver phantom: a lobed star-shaped closed surface.
//!
//! Canonical frame (mm): `x` from the patient's right to left, `y` anterior, `z` superior,
//! centred on the origin. The surface is `r(u) u` for unit directions `u` with
//!
//! `r(u) = scale · e(u) · (1 + Σ_k α_k exp(κ_k (u·d_k − 1)))`,
//!
//! `e(u) = 1/√(u_x²/A² + u_y²/B² + u_z²/C²)` the radius of the base ellipsoid and the sum a
//! few smooth lobes (von Mises–Fisher bumps): a big right lobe, a narrow left lobe, a dent
//! that thins the left side, the concave visceral surface and a random bump. The exact volume is
//! `V = ⅓ ∮ r(u)³ dΩ`, evaluated by quadrature.

use std::f64::consts::{PI, TAU};

use rand::Rng;

use super::hull::convex_hull;
use super::pose::RigidPose;
use super::quadrature::sphere_integral;
use super::rings::{Ring, stitch_sequence};
use crate::mesh::Mesh;
use crate::mesh::measures::{MM3_PER_ML, cross, dot, norm};

/// Number of lobes of every liver.
pub const LOBE_COUNT: usize = 5;
/// Names of the lobes in [`LiverParams::lobes`] order.
pub const LOBE_NAMES: [&str; LOBE_COUNT] = [
    "right_lobe",
    "left_lobe",
    "left_taper",
    "visceral_dent",
    "bump",
];
/// Gauss–Legendre nodes in `cos θ` for the exact volume (converged far below 1e-7).
pub const VOLUME_NODES_THETA: usize = 96;
/// Trapezoid steps in `φ` for the exact volume.
pub const VOLUME_STEPS_PHI: usize = 192;
/// Triangulation attempts with fresh jitter before falling back to rings.
const HULL_ATTEMPTS: usize = 4;

/// A smooth bump `α exp(κ (u·d − 1))` on the unit sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lobe {
    /// Unit direction `d` of the bump's peak.
    pub direction: [f64; 3],
    /// Relative height `α` at the peak (negative: a dent).
    pub amplitude: f64,
    /// Concentration `κ` (larger: narrower bump; width about `1/√κ` rad).
    pub concentration: f64,
}

/// Ranges one lobe is drawn from (uniformly); the direction is normalised after drawing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LobeRanges {
    /// Ranges of the direction's `x`, `y`, `z` components before normalising.
    pub direction: [(f64, f64); 3],
    /// Amplitude `α` range.
    pub amplitude: (f64, f64),
    /// Concentration `κ` range.
    pub concentration: (f64, f64),
}

/// Ranges the liver parameters are drawn from (uniformly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiverRanges {
    /// Base ellipsoid semi-axis `B` (anterior–posterior) relative to `A = 1` (left–right).
    pub axis_y: (f64, f64),
    /// Base ellipsoid semi-axis `C` (inferior–superior) relative to `A = 1`.
    pub axis_z: (f64, f64),
    /// The placed lobes, in [`LOBE_NAMES`] order.
    pub lobes: [LobeRanges; LOBE_COUNT - 1],
    /// Amplitude and concentration of the last lobe, a bump in a uniform random direction.
    pub random_bump: ((f64, f64), (f64, f64)),
    /// Exact volume in ml; the shape is scaled to it.
    pub volume_ml: (f64, f64),
    /// Number of points on the sphere (the vertex count).
    pub sphere_points: (usize, usize),
    /// Tangential jitter of the points, as a fraction of their mean spacing.
    pub jitter: (f64, f64),
}

impl Default for LiverRanges {
    fn default() -> Self {
        let lobe = |direction, amplitude, concentration| LobeRanges {
            direction,
            amplitude,
            concentration,
        };
        Self {
            axis_y: (0.6, 0.75),
            axis_z: (0.45, 0.6),
            lobes: [
                // Right lobe: big and broad.
                lobe(
                    [(-1.0, -1.0), (-0.2, 0.2), (0.0, 0.3)],
                    (0.4, 0.6),
                    (1.5, 2.5),
                ),
                // Left lobe: a narrow tongue to the left and front.
                lobe(
                    [(1.0, 1.0), (0.2, 0.5), (0.0, 0.2)],
                    (0.15, 0.3),
                    (6.0, 10.0),
                ),
                // The left side thins out below.
                lobe(
                    [(0.7, 0.9), (-0.2, 0.2), (-0.7, -0.5)],
                    (-0.45, -0.3),
                    (2.0, 3.5),
                ),
                // Concave visceral surface, below and behind.
                lobe(
                    [(-0.2, 0.3), (-0.7, -0.4), (-0.7, -0.7)],
                    (-0.25, -0.1),
                    (3.0, 5.0),
                ),
            ],
            random_bump: ((-0.08, 0.12), (3.0, 8.0)),
            volume_ml: (1000.0, 1800.0),
            sphere_points: (400, 3000),
            jitter: (0.1, 0.35),
        }
    }
}

/// Parameters of a liver in its canonical frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LiverParams {
    /// Base ellipsoid semi-axes `[A, B, C]` before scaling (`A = 1`).
    pub axes: [f64; 3],
    /// The lobes, in [`LOBE_NAMES`] order: right lobe, left lobe, left taper, visceral
    /// dent, random bump.
    pub lobes: [Lobe; LOBE_COUNT],
    /// Scale in mm (chosen so that the exact volume hits the drawn target).
    pub scale_mm: f64,
    /// Number of points on the sphere that are triangulated.
    pub sphere_points: usize,
    /// Tangential jitter of the points, as a fraction of their mean spacing.
    pub jitter: f64,
}

impl LiverParams {
    /// Radius `r(u)` in mm in the unit direction `u`.
    pub fn radius_mm(&self, u: [f64; 3]) -> f64 {
        let lobes: f64 = self
            .lobes
            .iter()
            .map(|l| l.amplitude * (l.concentration * (dot(u, l.direction) - 1.0)).exp())
            .sum();
        self.scale_mm * ellipsoid_radius(self.axes, u) * (1.0 + lobes)
    }

    /// Exact volume in ml by `⅓ ∮ r³ dΩ` on a `n_theta × n_phi` quadrature grid.
    pub fn volume_ml_with(&self, n_theta: usize, n_phi: usize) -> f64 {
        sphere_integral(|u| self.radius_mm(u).powi(3) / 3.0, n_theta, n_phi) / MM3_PER_ML
    }

    /// Exact volume of the continuous shape in ml.
    pub fn volume_ml(&self) -> f64 {
        self.volume_ml_with(VOLUME_NODES_THETA, VOLUME_STEPS_PHI)
    }

    /// Draws a liver from the default ranges and scales it to a drawn volume.
    pub(super) fn sample<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let r = LiverRanges::default();
        let axes = [
            1.0,
            rng.random_range(r.axis_y.0..=r.axis_y.1),
            rng.random_range(r.axis_z.0..=r.axis_z.1),
        ];
        let placed = r.lobes.map(|l| {
            let direction = unit(l.direction.map(|range| rng.random_range(range.0..=range.1)));
            draw_lobe(rng, direction, (l.amplitude, l.concentration))
        });
        let bump = random_direction(rng);
        let last = draw_lobe(rng, bump, r.random_bump);
        let lobes = [placed[0], placed[1], placed[2], placed[3], last];
        let mut p = Self {
            axes,
            lobes,
            scale_mm: 1.0,
            sphere_points: rng.random_range(r.sphere_points.0..=r.sphere_points.1),
            jitter: rng.random_range(r.jitter.0..=r.jitter.1),
        };
        let target = rng.random_range(r.volume_ml.0..=r.volume_ml.1);
        p.scale_mm = (target / p.volume_ml()).cbrt();
        p
    }

    /// The liver's mesh: jittered Fibonacci points in a random orientation, stretched by the
    /// base ellipsoid's axes (denser where it curves most, which keeps the inscribed mesh's
    /// volume deficit small), triangulated by their convex hull (spherical Delaunay) and
    /// moved out to `r(u) u`.
    pub(super) fn mesh<R: Rng + ?Sized>(&self, rng: &mut R) -> Mesh {
        let n = self.sphere_points.max(4);
        for _ in 0..HULL_ATTEMPTS {
            let spin = RigidPose::random(rng, 0.0);
            let points: Vec<[f64; 3]> = jittered_fibonacci(n, self.jitter, rng)
                .into_iter()
                .map(|p| {
                    let q = spin.apply(p);
                    unit([0, 1, 2].map(|k| self.axes[k] * q[k]))
                })
                .collect();
            if let Ok(faces) = convex_hull(&points) {
                return self.radial_mesh(points, faces);
            }
        }
        let (points, faces) = ring_sphere(n);
        self.radial_mesh(points, faces)
    }

    /// Moves unit-sphere vertices out to the surface, dropping unreferenced ones.
    fn radial_mesh(&self, directions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Mesh {
        let mut new_index = vec![u32::MAX; directions.len()];
        let mut vertices = Vec::with_capacity(directions.len());
        let faces = faces
            .into_iter()
            .map(|f| {
                f.map(|i| {
                    let slot = &mut new_index[i as usize];
                    if *slot == u32::MAX {
                        let u = directions[i as usize];
                        *slot = vertices.len() as u32;
                        vertices.push(u.map(|x| x * self.radius_mm(u)));
                    }
                    *slot
                })
            })
            .collect();
        Mesh::new(vertices, faces)
    }
}

/// A lobe at `direction` with amplitude and concentration drawn from their ranges.
fn draw_lobe<R: Rng + ?Sized>(
    rng: &mut R,
    direction: [f64; 3],
    (amplitude, concentration): ((f64, f64), (f64, f64)),
) -> Lobe {
    Lobe {
        direction,
        amplitude: rng.random_range(amplitude.0..=amplitude.1),
        concentration: rng.random_range(concentration.0..=concentration.1),
    }
}

/// Radius of the ellipsoid with semi-axes `axes` in the unit direction `u`.
fn ellipsoid_radius([a, b, c]: [f64; 3], u: [f64; 3]) -> f64 {
    1.0 / ((u[0] / a).powi(2) + (u[1] / b).powi(2) + (u[2] / c).powi(2)).sqrt()
}

fn unit(p: [f64; 3]) -> [f64; 3] {
    let n = norm(p);
    p.map(|x| x / n)
}

/// A direction uniform on the unit sphere.
fn random_direction<R: Rng + ?Sized>(rng: &mut R) -> [f64; 3] {
    let z: f64 = rng.random_range(-1.0..=1.0);
    let phi = rng.random_range(0.0..TAU);
    let s = (1.0 - z * z).max(0.0).sqrt();
    [s * phi.cos(), s * phi.sin(), z]
}

/// `n` Fibonacci points on the unit sphere, each moved at random in its tangent plane by
/// up to `±jitter/2` mean spacings per tangent axis.
fn jittered_fibonacci<R: Rng + ?Sized>(n: usize, jitter: f64, rng: &mut R) -> Vec<[f64; 3]> {
    let golden_angle = PI * (3.0 - 5f64.sqrt());
    let step = jitter * (4.0 * PI / n as f64).sqrt();
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let phi = golden_angle * i as f64;
            let u = [s * phi.cos(), s * phi.sin(), z];
            let helper = if u[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let e1 = unit(cross(u, helper));
            let e2 = cross(u, e1);
            let (g1, g2) = (rng.random_range(-0.5..=0.5), rng.random_range(-0.5..=0.5));
            unit([0, 1, 2].map(|k| u[k] + step * (g1 * e1[k] + g2 * e2[k])))
        })
        .collect()
}

/// Fallback triangulation of about `n` sphere points on latitude rings.
fn ring_sphere(n: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let m = ((PI * n as f64 / 4.0).sqrt().round() as usize).max(3);
    let mut points = vec![[0.0, 0.0, -1.0]];
    let mut rings = vec![Ring {
        first: 0,
        count: 1,
        offset: 0.0,
    }];
    for k in 1..=m {
        let theta = PI * k as f64 / (m + 1) as f64;
        let count = ((2.0 * m as f64 * theta.sin()).round() as u32).max(5);
        let ring = Ring {
            first: points.len() as u32,
            count,
            offset: 0.5 * k as f64,
        };
        for j in 0..count {
            let phi = ring.angle(j);
            points.push([
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                -theta.cos(),
            ]);
        }
        rings.push(ring);
    }
    rings.push(Ring {
        first: points.len() as u32,
        count: 1,
        offset: 0.0,
    });
    points.push([0.0, 0.0, 1.0]);
    let faces = stitch_sequence(&rings);
    (points, faces)
}

#[cfg(test)]
#[path = "liver_tests.rs"]
mod tests;
