//! Triangle meshes: the [`Mesh`] type, its validation, file I/O (OBJ, PLY,
//! OFF), procedurally generated meshes, topology and triangle quality.
//!
//! A [`Mesh`] is always valid: every constructor checks the invariants below
//! and returns a typed [`MeshError`] naming the offending element otherwise.
//!
//! Invariants of a `Mesh`:
//! - at least one vertex and one face;
//! - every coordinate finite;
//! - every face index `< n_vertices`, no face repeating a vertex;
//! - no two faces with the same vertex set;
//! - every vertex used by at least one face (an unreferenced vertex has an
//!   empty Laplacian row and makes every system singular).
//!
//! Non-manifold edges (more than two faces) are *accepted* and reported by
//! [`Mesh::warnings`]: every operator of this crate is assembled face by face
//! (the discrete Dirichlet energy is a sum over triangles), so it stays well
//! defined on a non-manifold complex, and scans and CAD exports often carry a
//! few such edges that carry no numerical risk. Operators that need a
//! manifold surface (the intrinsic Delaunay Laplacian) refuse them with an
//! error of their own.
//!
//! Faces of (numerically) zero area are *accepted* too and reported by
//! [`Mesh::warnings`] ([`Mesh::degenerate_face`]: `|e1 × e2| ≤ 64 ε ℓ²`,
//! with `ℓ` the face's longest edge — below that bound the cross product is
//! rounding noise and the face's angles are undefined; areas are computed
//! from squared lengths, so edge lengths must lie roughly within
//! `1e-75 ..= 1e75`, beyond which faces count as degenerate). A deformation
//! can collapse a face, and what needs only the connectivity and positions
//! (writing, reading back, rendering, the uniform Laplacian) works on the
//! result; the operators built from the rest shape's angles (the cotangent
//! Laplacians, [`crate::laplacian::laplacian`]) refuse such a rest mesh
//! with [`MeshError::DegenerateFace`], naming the face.

use crate::error::MeshError;

pub mod fingerprint;
pub mod generate;
pub mod io;
pub mod quality;
pub mod topology;
mod types;

pub use fingerprint::MeshSignature;
pub use io::{
    LoadedMesh, MeshFormat, PlyEncoding, check_mesh_output, check_writable, read_mesh,
    read_mesh_bytes, write_mesh,
};
pub use quality::Quality;
pub use topology::Topology;
pub use types::{Mesh, MeshWarning, validate};

impl Mesh {
    /// The unit of the mesh's numerics: its mean edge length (each face's
    /// three edges; 1 for a mesh where that is zero or not finite). The
    /// deformer assembles its problem on the positions and targets divided
    /// by it, so that the answer does not depend on the units, position or
    /// orientation of the mesh — a mesh moved by a similarity `x ↦ s R x + t`
    /// deforms to the same result moved (to rounding; the unit is invariant
    /// under rotations and translations, unlike the bounding box), soft
    /// weights mean the same in every unit, and no product of coordinates
    /// overflows or underflows for meshes from 1e-300 to 1e300.
    pub fn length_unit(&self) -> f64 {
        let p = &self.positions;
        let mut sum = 0.0;
        for f in &self.faces {
            for k in 0..3 {
                sum += quality::distance(p[f[k]], p[f[(k + 1) % 3]]);
            }
        }
        let mean = sum / (3 * self.faces.len()).max(1) as f64;
        if mean > 0.0 && mean.is_finite() {
            mean
        } else {
            1.0
        }
    }

    /// Warnings about a valid mesh (faces of zero area, non-manifold
    /// edges).
    pub fn warnings(&self) -> Vec<MeshWarning> {
        let degenerate =
            self.first_degenerate_face()
                .map(|(face, _)| MeshWarning::DegenerateFaces {
                    face,
                    vertices: self.faces[face],
                    total: self
                        .faces
                        .iter()
                        .filter(|f| self.face_is_degenerate(**f))
                        .count(),
                });
        degenerate
            .into_iter()
            .chain(topology::non_manifold_warning(self))
            .collect()
    }

    /// The first face of (numerically) zero area (see the module
    /// documentation) as the error an operator that needs the faces'
    /// angles returns, or `None`.
    pub fn degenerate_face(&self) -> Option<MeshError> {
        self.first_degenerate_face()
            .map(|(face, size)| MeshError::DegenerateFace {
                face,
                vertices: self.faces[face],
                area: size.area,
                longest_edge: size.longest_edge,
                relative_area: size.relative_area,
                line: None,
            })
    }

    /// The first face of zero area and its size.
    fn first_degenerate_face(&self) -> Option<(usize, quality::TriangleSize)> {
        let p = &self.positions;
        self.faces.iter().enumerate().find_map(|(f, &[a, b, c])| {
            let size = quality::triangle_size(p[a], p[b], p[c]);
            (!size.clearly_positive).then_some((f, size))
        })
    }

    fn face_is_degenerate(&self, [a, b, c]: [usize; 3]) -> bool {
        let p = &self.positions;
        !quality::area_is_clearly_positive(p[a], p[b], p[c]).0
    }
}
