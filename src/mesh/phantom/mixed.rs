//! A population of two labelled sub-populations of different shape and topology, for
//! measuring how well a multi-atlas model recovers clusters:
//!
//! - `bean` (genus 0): an ellipsoid with semi-axes `radius_{x,y,z}_mm`, meshed as the
//!   convex hull of jittered points on it;
//! - `ring` (genus 1): a torus around the z axis with major radius `major_radius_mm` and an
//!   elliptical tube of radial half-width `tube_radius_mm` and half-height
//!   `tube_half_height_mm`, meshed as a jittered `n_around × n_tube` grid.
//!
//! Both have volumes of the same range (about 140–220 ml), so the sub-populations differ by
//! shape and topology, not by size. Each subject is a ring with probability
//! [`RING_SHARE`].

use std::f64::consts::{PI, TAU};

use rand::Rng;

use super::hull::convex_hull;
use crate::mesh::Mesh;
use crate::mesh::measures::MM3_PER_ML;

/// Probability that a subject is a ring.
pub const RING_SHARE: f64 = 0.4;

/// Which sub-population a subject comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SubPopulation {
    /// Genus 0: an ellipsoid.
    Bean,
    /// Genus 1: a torus.
    Ring,
}

impl SubPopulation {
    /// The label written to `params.csv`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Bean => "bean",
            Self::Ring => "ring",
        }
    }

    /// The genus of its surfaces.
    pub fn genus(self) -> u32 {
        match self {
            Self::Bean => 0,
            Self::Ring => 1,
        }
    }
}

/// Generating parameters of a mixed-population subject (mm).
#[derive(Debug, Clone, PartialEq)]
pub enum MixedParams {
    /// An ellipsoid.
    Bean {
        /// Semi-axes along x, y, z, mm.
        radius_mm: [f64; 3],
        /// Points on the surface before the hull.
        points: usize,
        /// Jitter of the points, as a share of their spacing.
        jitter: f64,
    },
    /// A torus with an elliptical tube.
    Ring {
        /// Distance from the z axis to the tube's centre line, mm.
        major_radius_mm: f64,
        /// Radial half-width of the tube, mm.
        tube_radius_mm: f64,
        /// Half-height of the tube, mm.
        tube_half_height_mm: f64,
        /// Vertices around the z axis.
        n_around: usize,
        /// Vertices around the tube.
        n_tube: usize,
    },
}

impl MixedParams {
    /// The sub-population.
    pub fn sub_population(&self) -> SubPopulation {
        match self {
            Self::Bean { .. } => SubPopulation::Bean,
            Self::Ring { .. } => SubPopulation::Ring,
        }
    }

    /// Exact volume of the continuous shape, ml (ellipsoid `4/3·π·abc`; torus by Pappus,
    /// `2π·R · π·r·h`).
    pub fn volume_ml(&self) -> f64 {
        match self {
            Self::Bean { radius_mm: r, .. } => 4.0 / 3.0 * PI * r[0] * r[1] * r[2] / MM3_PER_ML,
            Self::Ring {
                major_radius_mm,
                tube_radius_mm,
                tube_half_height_mm,
                ..
            } => {
                2.0 * PI * PI * major_radius_mm * tube_radius_mm * tube_half_height_mm / MM3_PER_ML
            }
        }
    }

    pub(super) fn sample<R: Rng + ?Sized>(rng: &mut R) -> Self {
        if rng.random_bool(RING_SHARE) {
            Self::Ring {
                major_radius_mm: rng.random_range(30.0..=40.0),
                tube_radius_mm: rng.random_range(12.0..=17.0),
                tube_half_height_mm: rng.random_range(14.0..=19.0),
                n_around: rng.random_range(40..=64),
                n_tube: rng.random_range(24..=36),
            }
        } else {
            Self::Bean {
                radius_mm: [
                    rng.random_range(52.0..=64.0),
                    rng.random_range(26.0..=33.0),
                    rng.random_range(21.0..=26.0),
                ],
                points: rng.random_range(600..=1600),
                jitter: rng.random_range(0.1..=0.3),
            }
        }
    }

    pub(super) fn mesh<R: Rng + ?Sized>(&self, rng: &mut R) -> Mesh {
        match *self {
            Self::Bean {
                radius_mm,
                points,
                jitter,
            } => bean(radius_mm, points, jitter, rng),
            Self::Ring {
                major_radius_mm,
                tube_radius_mm,
                tube_half_height_mm,
                n_around,
                n_tube,
            } => ring(
                [major_radius_mm, tube_radius_mm, tube_half_height_mm],
                n_around,
                n_tube,
                rng,
            ),
        }
    }
}

/// Jittered Fibonacci points on the unit sphere, hulled, then scaled to the ellipsoid (a
/// linear map keeps the hull's triangles valid and outward).
fn bean<R: Rng + ?Sized>(radius: [f64; 3], n: usize, jitter: f64, rng: &mut R) -> Mesh {
    let golden = PI * (3.0 - 5f64.sqrt());
    loop {
        let points: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let z =
                    1.0 - 2.0 * (i as f64 + 0.5 + rng.random_range(-jitter..=jitter)) / n as f64;
                let z = z.clamp(-1.0, 1.0);
                let angle = golden * i as f64 + rng.random_range(-jitter..=jitter);
                let s = (1.0 - z * z).max(0.0).sqrt();
                [s * angle.cos(), s * angle.sin(), z]
            })
            .collect();
        if let Ok(faces) = convex_hull(&points) {
            let vertices = points
                .iter()
                .map(|p| [radius[0] * p[0], radius[1] * p[1], radius[2] * p[2]])
                .collect();
            return Mesh::new(vertices, faces);
        }
    }
}

/// A torus grid around the z axis with jittered angles; faces counter-clockwise from
/// outside (`∂p/∂u × ∂p/∂v` points out).
fn ring<R: Rng + ?Sized>(
    [major, tube, half_height]: [f64; 3],
    n_around: usize,
    n_tube: usize,
    rng: &mut R,
) -> Mesh {
    let phase = rng.random_range(0.0..TAU);
    let jitter = 0.2;
    let mut vertices = Vec::with_capacity(n_around * n_tube);
    for i in 0..n_around {
        let u = TAU * (i as f64 + rng.random_range(-jitter..=jitter)) / n_around as f64;
        for j in 0..n_tube {
            let v = phase + TAU * (j as f64 + rng.random_range(-jitter..=jitter)) / n_tube as f64;
            let radius = major + tube * v.cos();
            vertices.push([radius * u.cos(), radius * u.sin(), half_height * v.sin()]);
        }
    }
    let index = |i: usize, j: usize| ((i % n_around) * n_tube + j % n_tube) as u32;
    let mut faces = Vec::with_capacity(2 * n_around * n_tube);
    for i in 0..n_around {
        for j in 0..n_tube {
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    Mesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::super::{Family, ShapeParams, generate, params_csv};
    use crate::mesh::measures::volume_ml;
    use crate::mesh::topology::{connected_components, euler_characteristic};

    #[test]
    fn both_sub_populations_are_closed_of_their_genus_and_exact_volume() {
        let phantoms = generate(Family::Mixed, 30, 5);
        let mut seen = [0usize; 2];
        for p in &phantoms {
            let ShapeParams::Mixed(params) = &p.params.shape else {
                panic!("a mixed phantom has mixed parameters")
            };
            let sub = params.sub_population();
            seen[sub.genus() as usize] += 1;
            assert_eq!(
                euler_characteristic(&p.mesh),
                2 - 2 * i64::from(sub.genus()),
                "{}",
                p.name
            );
            assert_eq!(connected_components(&p.mesh).0, 1);
            let exact = p.params.volume_ml;
            let measured = volume_ml(&p.mesh);
            assert!(
                (measured / exact - 1.0).abs() < 0.03,
                "{}: {measured} vs {exact} ml",
                p.name
            );
            assert!((120.0..=260.0).contains(&exact), "{}: {exact} ml", p.name);
            let report = crate::mesh::validate::ingest(
                &crate::mesh::io::write(&p.mesh, crate::mesh::Format::Stl),
                crate::mesh::Format::Stl,
                &crate::mesh::validate::IngestOptions::default(),
            )
            .unwrap();
            assert!(report.summary.watertight, "{}", p.name);
        }
        assert!(seen[0] >= 10 && seen[1] >= 6, "beans and rings: {seen:?}");
        let csv = params_csv(&phantoms);
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let column = header.iter().position(|h| *h == "subpopulation").unwrap();
        let labels: Vec<&str> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(column).unwrap())
            .collect();
        assert_eq!(labels.iter().filter(|l| **l == "ring").count(), seen[1]);
        assert_eq!(labels.iter().filter(|l| **l == "bean").count(), seen[0]);
    }
}
