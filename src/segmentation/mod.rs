//! Label volumes (NIfTI-1) to closed surface meshes in millimetres. Pure: no async, SQL or HTTP.

pub mod field;
pub mod marching;
mod tables;
