//! Shape geometry on point sets and meshes: rigid registration (CPD), nearest-neighbour
//! queries, PCA. Pure: no async, SQL or HTTP.

pub mod bvh;
pub mod correspondence;
pub mod cpd;
pub mod distance;
mod error;
pub mod gpa;
pub mod kdtree;
pub mod pca;
pub mod points;
pub mod procrustes;
pub mod transform;
pub mod triangle;

pub use correspondence::normalised_shape;
pub use cpd::{CpdResult, RigidCpdParams, rigid_cpd, rigid_cpd_from, rigid_cpd_multistart};
pub use distance::{SurfaceDistances, surface_distances, surface_distances_indexed};
pub use error::GeometryError;
pub use kdtree::PointCloudIndex;
pub use pca::{PcaModel, PcaParams, Sampling};
pub use transform::{RigidTransform, axis_permutation_rotations};
