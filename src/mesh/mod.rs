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

pub use fingerprint::MeshSignature;
pub use io::{
    LoadedMesh, MeshFormat, PlyEncoding, check_mesh_output, check_writable, read_mesh,
    read_mesh_bytes, write_mesh,
};
pub use quality::Quality;
pub use topology::Topology;

/// A valid triangle mesh (see the module documentation for the invariants).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    positions: Vec<[f64; 3]>,
    faces: Vec<[usize; 3]>,
}

/// Something about a valid mesh a user should know.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshWarning {
    /// Faces of (numerically) zero area: fine to write, read and render,
    /// refused as the rest shape of a cotangent Laplacian.
    DegenerateFaces {
        /// The first such face.
        face: usize,
        /// Its vertices.
        vertices: [usize; 3],
        /// How many there are.
        total: usize,
    },
    /// An edge shared by more than two faces.
    NonManifoldEdge {
        /// The edge's vertices (smaller first).
        edge: [usize; 2],
        /// Number of faces using it.
        faces: usize,
        /// Total number of non-manifold edges in the mesh.
        total: usize,
    },
}

impl std::fmt::Display for MeshWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshWarning::DegenerateFaces {
                face,
                vertices,
                total,
            } => write!(
                f,
                "{total} face(s) of zero area, e.g. face {face} (vertices {vertices:?}): the cotangent Laplacians cannot be built on this mesh as a rest shape (its angles are undefined there); the uniform Laplacian and rendering take it"
            ),
            MeshWarning::NonManifoldEdge { edge, faces, total } => write!(
                f,
                "{total} non-manifold edge(s), e.g. edge ({}, {}) used by {faces} faces; operators are assembled per face and stay well defined",
                edge[0], edge[1]
            ),
        }
    }
}

impl Mesh {
    /// Builds a mesh, checking every invariant of the module documentation.
    pub fn new(positions: Vec<[f64; 3]>, faces: Vec<[usize; 3]>) -> Result<Mesh, MeshError> {
        validate(&positions, &faces)?;
        Ok(Mesh { positions, faces })
    }

    /// Vertex positions, in file order.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.positions
    }

    /// Triangles (vertex indices, counter-clockwise as given).
    pub fn faces(&self) -> &[[usize; 3]] {
        &self.faces
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    /// A copy of this mesh with other positions (same connectivity), e.g. the
    /// deformed mesh. Fails if a position is not finite, or the count differs.
    pub fn with_positions(&self, positions: Vec<[f64; 3]>) -> Result<Mesh, MeshError> {
        if positions.len() != self.positions.len() {
            return Err(MeshError::Parse {
                format: "positions",
                line: None,
                message: format!(
                    "expected {} positions, got {}",
                    self.positions.len(),
                    positions.len()
                ),
            });
        }
        for (v, p) in positions.iter().enumerate() {
            if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
                return Err(MeshError::NonFiniteCoordinate {
                    vertex: v,
                    value,
                    line: None,
                });
            }
        }
        Ok(Mesh {
            positions,
            faces: self.faces.clone(),
        })
    }

    /// Axis-aligned bounding box `(min, max)`.
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Length of the bounding box diagonal: the length scale that absolute
    /// tolerances (constraint residuals) are measured against.
    pub fn bbox_diagonal(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        let extent = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        // Scaled by the largest extent so that the squares neither overflow
        // nor underflow (meshes in units from 1e-300 to 1e300).
        let m = extent.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        if m == 0.0 || !m.is_finite() {
            return m;
        }
        m * extent.iter().map(|e| (e / m) * (e / m)).sum::<f64>().sqrt()
    }

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

/// Checks the invariants of the module documentation, reporting the first
/// violation in this order: empty, non-finite coordinate, index out of range,
/// repeated vertex, duplicate face, unreferenced vertex. (Faces of zero area
/// are valid: see [`Mesh::degenerate_face`].)
pub(crate) fn validate(positions: &[[f64; 3]], faces: &[[usize; 3]]) -> Result<(), MeshError> {
    if positions.is_empty() || faces.is_empty() {
        return Err(MeshError::Empty {
            vertices: positions.len(),
            faces: faces.len(),
        });
    }
    for (v, p) in positions.iter().enumerate() {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate {
                vertex: v,
                value,
                line: None,
            });
        }
    }
    let n = positions.len();
    let mut used = vec![false; n];
    for (f, face) in faces.iter().enumerate() {
        for &i in face {
            if i >= n {
                return Err(MeshError::IndexOutOfRange {
                    face: f,
                    index: i64::try_from(i).unwrap_or(i64::MAX),
                    vertex_count: n,
                    line: None,
                });
            }
        }
        let [a, b, c] = *face;
        if a == b || a == c {
            return Err(MeshError::RepeatedVertex {
                face: f,
                vertex: a,
                line: None,
            });
        }
        if b == c {
            return Err(MeshError::RepeatedVertex {
                face: f,
                vertex: b,
                line: None,
            });
        }
        used[a] = true;
        used[b] = true;
        used[c] = true;
    }
    let mut keyed: Vec<([usize; 3], usize)> = faces
        .iter()
        .enumerate()
        .map(|(f, face)| {
            let mut k = *face;
            k.sort_unstable();
            (k, f)
        })
        .collect();
    keyed.sort_unstable();
    for w in keyed.windows(2) {
        if w[0].0 == w[1].0 {
            let (first, face) = (w[0].1.min(w[1].1), w[0].1.max(w[1].1));
            return Err(MeshError::DuplicateFace {
                face,
                first,
                vertices: faces[face],
                line: None,
            });
        }
    }
    if let Some(vertex) = used.iter().position(|u| !u) {
        let count = used.iter().filter(|u| !**u).count();
        return Err(MeshError::UnreferencedVertex {
            vertex,
            count,
            line: None,
        });
    }
    Ok(())
}
