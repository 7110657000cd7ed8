//! Why a render fails ([`RenderError`]) and the image-size check every
//! renderer makes first: the leaf of `render` that its other files import.

use std::path::PathBuf;

/// Largest accepted image side (after supersampling), in pixels.
pub const MAX_SIDE: u32 = 8_192;

/// Why a render failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A mesh without vertices or faces.
    #[error("mesh {mesh}: no {what}")]
    Empty {
        /// Index of the mesh (panel) in the call.
        mesh: usize,
        /// `"vertices"` or `"faces"`.
        what: &'static str,
    },
    /// A face referring to a vertex that does not exist.
    #[error("mesh {mesh}: face {face} refers to vertex {vertex}, but there are {n} vertices")]
    FaceIndex {
        /// Index of the mesh.
        mesh: usize,
        /// The face.
        face: usize,
        /// The bad index.
        vertex: usize,
        /// Number of vertices.
        n: usize,
    },
    /// A highlighted vertex that does not exist.
    #[error("mesh {mesh}: highlighted vertex {vertex} is out of range ({n} vertices)")]
    HighlightIndex {
        /// Index of the mesh.
        mesh: usize,
        /// The bad index.
        vertex: usize,
        /// Number of vertices.
        n: usize,
    },
    /// Per-vertex colours of the wrong length.
    #[error("mesh {mesh}: {got} vertex colours for {n} vertices")]
    ColourCount {
        /// Index of the mesh.
        mesh: usize,
        /// Colours given.
        got: usize,
        /// Number of vertices.
        n: usize,
    },
    /// A NaN or infinite coordinate.
    #[error("mesh {mesh}: vertex {vertex} has a non-finite coordinate")]
    NonFinite {
        /// Index of the mesh.
        mesh: usize,
        /// The vertex.
        vertex: usize,
    },
    /// A camera or style parameter that cannot be used.
    #[error("invalid {what}: {message}")]
    Invalid {
        /// The parameter.
        what: &'static str,
        /// Why.
        message: String,
    },
    /// An image size of zero or too large.
    #[error(
        "image size {width}×{height} (×{supersample} supersampling) is invalid: each side must be in 1..={MAX_SIDE}"
    )]
    BadSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Supersampling factor.
        supersample: u32,
    },
    /// No panel to compose.
    #[error("no panel to render")]
    NoPanels,
    /// Writing the PNG or drawing a caption failed.
    #[error("writing {path}: {message}")]
    Output {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The embedded font could not be parsed.
    #[error("font: {0}")]
    Font(String),
    /// Two meshes that must share their vertices do not.
    #[error("{what}: {got} vertices, but the mesh has {n}")]
    VertexCount {
        /// Which mesh.
        what: String,
        /// Its vertex count.
        got: usize,
        /// The reference vertex count.
        n: usize,
    },
}

/// Checks an output size (times the supersampling factor).
pub(crate) fn check_size(width: u32, height: u32, supersample: u32) -> Result<(), RenderError> {
    let ok = |side: u32| side >= 1 && side.checked_mul(supersample).is_some_and(|s| s <= MAX_SIDE);
    if ok(width) && ok(height) && supersample >= 1 {
        Ok(())
    } else {
        Err(RenderError::BadSize {
            width,
            height,
            supersample,
        })
    }
}
