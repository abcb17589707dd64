//! Shape geometry on point sets and meshes: rigid registration (CPD), nearest-neighbour
//! queries, PCA. Pure: no async, SQL or HTTP.

pub mod correspondence;
pub mod cpd;
pub mod distance;
mod error;
pub mod kdtree;
pub mod pca;
pub mod points;
pub mod procrustes;
pub mod transform;

pub use cpd::{CpdResult, RigidCpdParams, rigid_cpd, rigid_cpd_multistart};
pub use error::GeometryError;
pub use transform::{RigidTransform, axis_permutation_rotations};
