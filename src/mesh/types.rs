//! The [`Mesh`] type, the invariants its constructors check ([`validate`])
//! and what a valid mesh may still warn about ([`MeshWarning`]). A leaf of
//! [`crate::mesh`], which re-exports all three and adds the measures that
//! need the mesh's quality and topology ([`Mesh::length_unit`],
//! [`Mesh::warnings`], [`Mesh::degenerate_face`]): the readers, the
//! generators, the quality and the topology modules import it, it imports
//! none of them. The fields are visible in `mesh` for those measures only.

use crate::error::MeshError;

/// A valid triangle mesh (see the [module documentation](crate::mesh) for
/// the invariants).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    pub(super) positions: Vec<[f64; 3]>,
    pub(super) faces: Vec<[usize; 3]>,
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
    /// Builds a mesh, checking every invariant of the [module
    /// documentation](crate::mesh).
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
}

/// Checks the invariants of the [module documentation](crate::mesh),
/// reporting the first violation in this order: empty, non-finite
/// coordinate, index out of range, repeated vertex, duplicate face,
/// unreferenced vertex. (Faces of zero area are valid: see
/// [`Mesh::degenerate_face`].)
pub fn validate(positions: &[[f64; 3]], faces: &[[usize; 3]]) -> Result<(), MeshError> {
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
