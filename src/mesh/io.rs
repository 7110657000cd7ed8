//! Mesh file I/O: OBJ, PLY (ASCII and binary), OFF; optionally gzip-compressed.
//! Vertex order is always kept as in the file.

use std::path::Path;

use super::Mesh;
use crate::error::{Error, MeshError};

/// A supported mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY.
    Ply,
    /// Object File Format.
    Off,
}

/// A mesh read from a file, with notes on what the reader did (e.g. polygons
/// fan-triangulated).
#[derive(Debug, Clone)]
pub struct LoadedMesh {
    /// The mesh.
    pub mesh: Mesh,
    /// Human-readable notes for the user.
    pub notes: Vec<String>,
}

/// Reads a mesh, choosing the format from the extension (`.obj`, `.ply`,
/// `.off`, each optionally followed by `.gz`).
pub fn read_mesh(path: &Path) -> Result<LoadedMesh, Error> {
    let _ = path;
    todo!()
}

/// Writes a mesh, choosing the format from the extension.
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<(), Error> {
    let _ = (mesh, path);
    todo!()
}
