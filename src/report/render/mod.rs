//! Pictures of shapes: meshes drawn in three fixed views of the model frame with Lambert
//! shading, laid out on sheets (PNG). Pure: meshes in, bytes out.

pub mod camera;
pub mod colour;
pub mod pictures;
mod raster;
mod sheet;

pub use camera::View;
pub use sheet::{ColourBar, PANEL_PX, Panel, RenderError, Sheet};
