//! Synthetic shape phantoms with exact ground truth.
//!
//! Families of closed, outward-oriented triangle meshes in mm:
//!
//! - [`Family::Lv`]: a thick-walled truncated ellipsoidal cup, like the myocardium of a left
//!   ventricle ([`LvParams`]), genus 0;
//! - [`Family::Liver`]: a lobed star-shaped surface, like a liver ([`LiverParams`]), genus 0;
//! - [`Family::Mixed`]: two labelled sub-populations of different topology, genus-0
//!   ellipsoids (`bean`) and genus-1 tori (`ring`), for cluster recovery ([`MixedParams`]).
//!
//! Every subject has its own resolution and connectivity (vertex counts and triangulations
//! differ between subjects, as they do between segmented organs), the exact volume of its
//! continuous generating shape, and a random rigid pose. Subject `i` depends only on
//! `(family, seed, i)`: the same seed gives the same meshes bit for bit.

mod csv;
mod hull;
mod liver;
mod lv;
mod mixed;
mod pose;
mod quadrature;
mod rings;

#[cfg(test)]
mod check;

use std::fmt;
use std::str::FromStr;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::Mesh;

pub use csv::params_csv;
pub use liver::{LOBE_COUNT, LOBE_NAMES, LiverParams, LiverRanges, Lobe};
pub use lv::{LvParams, LvRanges, ellipsoid_segment_volume_mm3};
pub use mixed::{MixedParams, RING_SHARE, SubPopulation};
pub use pose::RigidPose;

/// Largest translation of the random pose along each axis, in mm.
pub const MAX_POSE_TRANSLATION_MM: f64 = 60.0;

/// A phantom family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Left-ventricle myocardium: a thick-walled truncated ellipsoidal cup.
    Lv,
    /// Liver: a lobed star-shaped closed surface.
    Liver,
    /// Two labelled sub-populations: ellipsoids (genus 0) and tori (genus 1).
    Mixed,
}

impl Family {
    /// Every family.
    pub const ALL: [Family; 3] = [Family::Lv, Family::Liver, Family::Mixed];

    /// The family's name as used in phantom names and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Family::Lv => "lv",
            Family::Liver => "liver",
            Family::Mixed => "mixed",
        }
    }

    /// Distinguishes the random streams of the families under one seed.
    fn stream_tag(self) -> u64 {
        match self {
            Family::Lv => 1 << 48,
            Family::Liver => 2 << 48,
            Family::Mixed => 3 << 48,
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Errors of the phantom module.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PhantomError {
    /// The family name is not one of `lv`, `liver`, `mixed`.
    #[error("unknown phantom family {0:?}: expected \"lv\", \"liver\" or \"mixed\"")]
    UnknownFamily(String),
}

impl FromStr for Family {
    type Err = PhantomError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "lv" => Ok(Family::Lv),
            "liver" => Ok(Family::Liver),
            "mixed" => Ok(Family::Mixed),
            _ => Err(PhantomError::UnknownFamily(s.to_string())),
        }
    }
}

/// The generating parameters of the shape in its canonical frame.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeParams {
    /// Parameters of an LV cup.
    Lv(LvParams),
    /// Parameters of a liver.
    Liver(LiverParams),
    /// Parameters of a mixed-population subject (with its sub-population).
    Mixed(MixedParams),
}

/// Everything needed to rebuild a phantom's ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct PhantomParams {
    /// Shape parameters in the canonical frame (mm).
    pub shape: ShapeParams,
    /// Exact volume of the continuous generating shape, in ml.
    pub volume_ml: f64,
    /// Pose mapping the canonical frame to the mesh: `x_mesh = R x_canonical + t`.
    pub pose: RigidPose,
}

/// A synthetic subject: its mesh (posed, mm) and ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    /// Subject name, e.g. `lv_007`.
    pub name: String,
    /// The posed surface mesh in mm.
    pub mesh: Mesh,
    /// Generating parameters, exact volume and pose.
    pub params: PhantomParams,
}

impl Phantom {
    /// The family of this phantom.
    pub fn family(&self) -> Family {
        match self.params.shape {
            ShapeParams::Lv(_) => Family::Lv,
            ShapeParams::Liver(_) => Family::Liver,
            ShapeParams::Mixed(_) => Family::Mixed,
        }
    }

    /// The mesh moved back into the canonical frame (pose undone).
    pub fn canonical_mesh(&self) -> Mesh {
        let pose = &self.params.pose;
        Mesh::new(
            self.mesh
                .vertices
                .iter()
                .map(|&p| pose.apply_inverse(p))
                .collect(),
            self.mesh.faces.clone(),
        )
    }
}

/// Generates subjects `0..count` of a family; subject `i` depends only on `(family, seed, i)`.
pub fn generate(family: Family, count: usize, seed: u64) -> Vec<Phantom> {
    (0..count).map(|i| subject(family, seed, i)).collect()
}

/// The meshes of [`generate`]'s phantoms (mm), without their parameters.
pub fn meshes(family: Family, count: usize, seed: u64) -> Vec<Mesh> {
    generate(family, count, seed)
        .into_iter()
        .map(|p| p.mesh)
        .collect()
}

/// Generates subject `index` of a family under a seed.
pub fn subject(family: Family, seed: u64, index: usize) -> Phantom {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(family.stream_tag() | index as u64);
    let (shape, volume_ml, mut mesh) = match family {
        Family::Lv => {
            let p = LvParams::sample(&mut rng);
            let mesh = p.mesh(&mut rng);
            let volume_ml = p.volume_ml();
            (ShapeParams::Lv(p), volume_ml, mesh)
        }
        Family::Liver => {
            let p = LiverParams::sample(&mut rng);
            let mesh = p.mesh(&mut rng);
            let volume_ml = p.volume_ml();
            (ShapeParams::Liver(p), volume_ml, mesh)
        }
        Family::Mixed => {
            let p = MixedParams::sample(&mut rng);
            let mesh = p.mesh(&mut rng);
            let volume_ml = p.volume_ml();
            (ShapeParams::Mixed(p), volume_ml, mesh)
        }
    };
    let pose = RigidPose::random(&mut rng, MAX_POSE_TRANSLATION_MM);
    for v in &mut mesh.vertices {
        *v = pose.apply(*v);
    }
    Phantom {
        name: format!("{}_{:03}", family, index),
        mesh,
        params: PhantomParams {
            shape,
            volume_ml,
            pose,
        },
    }
}

#[cfg(test)]
mod tests;
