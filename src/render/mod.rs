//! Software rendering of meshes to PNG (feature `render`, on with the
//! default feature `cli`): no GPU, no system library, no plotting stack.
//!
//! A front-door module: it imports [`crate::mesh`] only and holds no
//! numerics of the deformation; the CLI's `render` command and the
//! experiments use it.
//!
//! - [`raster`]: orthographic [`Camera`], [`View`] framing, the z-buffered
//!   smooth-shaded rasteriser ([`render`]) and the translucent ghost
//!   ([`render_with_ghost`]);
//! - [`frame`]: a camera that puts a deformation in the image plane
//!   ([`auto_camera`]);
//! - [`colour`]: the viridis [`ColourScale`] for displacements and
//!   differences and the [`Legend`] strip;
//! - [`compose`]: side-by-side panels with captions ([`render_side_by_side`]);
//! - [`text`]: captions in the embedded DejaVu Sans; [`output`]: PNG files.

pub mod colour;
pub mod compose;
mod error;
pub mod frame;
pub mod output;
pub mod raster;
pub mod text;

pub use colour::{ColourScale, LEGEND_HEIGHT, Legend, distances, viridis};
pub use compose::{Layout, Panel, compose, render_side_by_side};
pub(crate) use error::check_size;
pub use error::{MAX_SIDE, RenderError};
pub use frame::auto_camera;
pub use raster::{
    AUTO_EDGE_PIXELS, Camera, Colouring, Edges, Ghost, Image, RenderMesh, RenderStats, Style, View,
    render, render_with_ghost,
};
