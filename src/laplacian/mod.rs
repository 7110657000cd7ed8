//! Discrete Laplacians of a triangle mesh as faer sparse matrices.
//!
//! Sign convention (docs/formulations.md §1, paper eq. 1–2): `δ_i = Σ_{j∈N(i)} w_ij (p_i − p_j)`,
//! so `L_ii = Σ_j w_ij`, `L_ij = −w_ij` and `δ = L P`. Every row sums to zero.
//!
//! - [`LaplacianKind::Uniform`] (eq. 8): `w_ij = 1/|N(i)|`.
//! - [`LaplacianKind::Cotangent`] (eq. 9): `w_ij = (cot α_ij + cot β_ij) / (2 A_i)`
//!   with `A_i` the mixed Voronoi area of Meyer et al. 2003
//!   ([`mixed_voronoi_areas`]). A boundary edge has one opposite angle only.
//!   This equals `−M⁻¹C` with libigl's `cotmatrix` `C` and
//!   `massmatrix(VORONOI)` `M`.
//! - [`LaplacianKind::CotangentSymmetric`]: `w_ij = ½(cot α_ij + cot β_ij)`,
//!   no area normalisation; the matrix is symmetric (it is libigl's `−C`).
//! - [`LaplacianKind::IntrinsicDelaunay`]: eq. 9 on the intrinsic Delaunay
//!   triangulation of the same surface (all weights ≥ 0), the modern fix for
//!   badly shaped triangles.
//!
//! All operators are assembled face by face, so non-manifold edges (more
//! than two incident faces) simply collect one cotangent per face.
//!
//! The sparsity pattern is that of the vertex adjacency plus the diagonal,
//! which is symmetric; column `j` holds the rows `{j} ∪ N(j)` in increasing
//! order.

use faer::sparse::{SparseColMat, SymbolicSparseColMat};

use crate::error::MeshError;
use crate::mesh::Mesh;

mod intrinsic_delaunay;
mod triangle;

use triangle::Triangle;

pub(crate) use intrinsic_delaunay::IntrinsicTriangulation;

/// Which Laplacian to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LaplacianKind {
    /// Uniform weights `1/|N(i)|` (paper eq. 8).
    Uniform,
    /// Cotangent weights over the mixed Voronoi area (paper eq. 9).
    #[serde(rename = "cotan")]
    Cotangent,
    /// Cotangent weights `½(cot α + cot β)` without area normalisation
    /// (symmetric).
    #[serde(rename = "cotan-symmetric")]
    CotangentSymmetric,
    /// Cotangent weights over mixed Voronoi areas computed on the intrinsic
    /// Delaunay triangulation of the surface (Bobenko & Springborn 2007;
    /// Sharp & Crane 2020): edge flips until every edge is Delaunay, so all
    /// weights are non-negative (`laplacian/intrinsic_delaunay.rs`).
    #[serde(rename = "intrinsic-delaunay")]
    IntrinsicDelaunay,
}

impl LaplacianKind {
    /// Every kind, for experiments that loop over them.
    pub const ALL: [LaplacianKind; 4] = [
        LaplacianKind::Uniform,
        LaplacianKind::Cotangent,
        LaplacianKind::CotangentSymmetric,
        LaplacianKind::IntrinsicDelaunay,
    ];

    /// The power `a` of length by which the operator's entries scale: the
    /// Laplacian of the mesh scaled by `s` is `s⁻ᵃ L`. `a = 0` for the
    /// uniform weights (pure numbers) and for `½(cot α + cot β)` (angles do
    /// not change under scaling); `a = 2` for the area-normalised kinds,
    /// whose weights are cotangents over an area `A_i` (eq. 9). With
    /// `X = s X̂`, `‖L(X − P)‖²` scales as `s^(2 − 2a)` and a soft term
    /// `w²‖b·X − d‖²` as `s²`: see [`crate::deform::Deformer`] for how the
    /// soft weights are compensated when the problem is assembled in another
    /// length unit (docs/units.md §2–§3).
    pub fn inverse_length_power(self) -> i32 {
        match self {
            LaplacianKind::Uniform | LaplacianKind::CotangentSymmetric => 0,
            LaplacianKind::Cotangent | LaplacianKind::IntrinsicDelaunay => 2,
        }
    }

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            LaplacianKind::Uniform => "uniform",
            LaplacianKind::Cotangent => "cotan",
            LaplacianKind::CotangentSymmetric => "cotan-symmetric",
            LaplacianKind::IntrinsicDelaunay => "intrinsic-delaunay",
        }
    }
}

impl crate::choice::Word for LaplacianKind {
    const WHAT: &'static str = "Laplacian";
    fn all() -> &'static [Self] {
        &LaplacianKind::ALL
    }
    fn name(self) -> &'static str {
        LaplacianKind::name(self)
    }
    fn aliases() -> &'static [(&'static str, Self)] {
        &[("cotangent", LaplacianKind::Cotangent)]
    }
}

impl std::fmt::Display for LaplacianKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for LaplacianKind {
    type Err = crate::error::ParseWordError;
    /// Errors: [`ParseWordError`](crate::error::ParseWordError) listing the
    /// kinds.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        <LaplacianKind as crate::choice::Word>::parse_word(s)
    }
}

/// Builds the Laplacian `L` (n × n) of the given kind. Fails for the
/// cotangent kinds on a mesh with a face of zero area (its angles and so its
/// cotangent weights are undefined: [`MeshError::DegenerateFace`] naming the
/// first one; the uniform Laplacian needs only the connectivity), and for
/// [`LaplacianKind::IntrinsicDelaunay`] on a mesh that is not an oriented
/// manifold.
pub fn laplacian(mesh: &Mesh, kind: LaplacianKind) -> Result<SparseColMat<usize, f64>, MeshError> {
    let n = mesh.n_vertices();
    if kind != LaplacianKind::Uniform
        && let Some(e) = mesh.degenerate_face()
    {
        return Err(e);
    }
    match kind {
        LaplacianKind::Uniform => {
            let pattern = AdjacencyPattern::new(n, mesh.faces());
            // deg(i) = nnz of column i − 1 (pattern symmetric, diagonal included).
            let inv_deg: Vec<f64> = (0..n)
                .map(|i| 1.0 / (pattern.col_ptr[i + 1] - pattern.col_ptr[i] - 1) as f64)
                .collect();
            let mut values = vec![0.0; pattern.row_idx.len()];
            for j in 0..n {
                for p in pattern.col_ptr[j]..pattern.col_ptr[j + 1] {
                    let i = pattern.row_idx[p];
                    values[p] = if i == j { 1.0 } else { -inv_deg[i] };
                }
            }
            Ok(pattern.into_matrix(values))
        }
        LaplacianKind::Cotangent | LaplacianKind::CotangentSymmetric => {
            let p = mesh.positions();
            let triangles = mesh
                .faces()
                .iter()
                .map(|f| (*f, Triangle::new([p[f[0]], p[f[1]], p[f[2]]])));
            Ok(cotangent_laplacian(
                n,
                mesh.faces(),
                triangles,
                kind == LaplacianKind::Cotangent,
            ))
        }
        LaplacianKind::IntrinsicDelaunay => {
            let tri = IntrinsicTriangulation::new(mesh)?.flip_to_delaunay()?;
            let faces = tri.faces();
            let triangles = tri.triangles();
            Ok(cotangent_laplacian(n, &faces, triangles, true))
        }
    }
}

/// The cotangent Laplacian of triangles given with their corner geometry:
/// symmetric weights `½(cot α + cot β)`, optionally divided row by row by
/// the mixed Voronoi areas.
fn cotangent_laplacian<I>(
    n: usize,
    faces: &[[usize; 3]],
    triangles: I,
    area_normalised: bool,
) -> SparseColMat<usize, f64>
where
    I: Iterator<Item = ([usize; 3], Triangle)> + Clone,
{
    let pattern = AdjacencyPattern::new(n, faces);
    let mut values = symmetric_cotangent_values(triangles.clone(), &pattern);
    if area_normalised {
        let area = mixed_areas(n, triangles);
        // Row i is divided by A_i.
        for p in 0..values.len() {
            values[p] /= area[pattern.row_idx[p]];
        }
    }
    pattern.into_matrix(values)
}

/// `δ = L P`: the Laplacian coordinates of the positions, one column per
/// coordinate (n × 3).
pub fn apply(l: &SparseColMat<usize, f64>, positions: &[[f64; 3]]) -> faer::Mat<f64> {
    let n = l.nrows();
    let mut delta = faer::Mat::<f64>::zeros(n, 3);
    let (col_ptr, row_idx, val) = (l.symbolic().col_ptr(), l.symbolic().row_idx(), l.val());
    for (j, p) in positions.iter().enumerate() {
        for q in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[q];
            for k in 0..3 {
                delta[(i, k)] += val[q] * p[k];
            }
        }
    }
    delta
}

/// Mixed Voronoi area of every vertex (Meyer, Desbrun, Schröder & Barr 2003,
/// fig. 4): a non-obtuse triangle gives each corner its Voronoi region
/// `(|PR|² cot Q + |PQ|² cot R)/8`; an obtuse one gives half its area to the
/// obtuse corner and a quarter to each other corner. The areas sum to the
/// surface area.
pub fn mixed_voronoi_areas(mesh: &Mesh) -> Vec<f64> {
    let p = mesh.positions();
    let triangles = mesh
        .faces()
        .iter()
        .map(|f| (*f, Triangle::new([p[f[0]], p[f[1]], p[f[2]]])));
    mixed_areas(mesh.n_vertices(), triangles)
}

fn mixed_areas(n: usize, triangles: impl Iterator<Item = ([usize; 3], Triangle)>) -> Vec<f64> {
    let mut area = vec![0.0; n];
    for (f, t) in triangles {
        if let Some(obtuse) = (0..3).find(|&k| t.dot[k] < 0.0) {
            for (k, &v) in f.iter().enumerate() {
                area[v] += if k == obtuse {
                    t.area / 2.0
                } else {
                    t.area / 4.0
                };
            }
        } else {
            for (k, &v) in f.iter().enumerate() {
                // Corner k = P with Q = k+1, R = k+2: (|PR|² cot Q + |PQ|² cot R)/8,
                // where PR is the edge opposite Q (len_sq[Q]) and PQ opposite R.
                let (q, r) = ((k + 1) % 3, (k + 2) % 3);
                area[v] += (t.len_sq[q] * t.cot(q) + t.len_sq[r] * t.cot(r)) / 8.0;
            }
        }
    }
    area
}

/// Values of the symmetric cotangent matrix `½(cot α + cot β)` off the
/// diagonal (negated: entry `(i, j)` is `−w_ij`) and the row sums on it, on
/// the adjacency pattern.
fn symmetric_cotangent_values(
    triangles: impl Iterator<Item = ([usize; 3], Triangle)>,
    pattern: &AdjacencyPattern,
) -> Vec<f64> {
    let mut values = vec![0.0; pattern.row_idx.len()];
    for (f, t) in triangles {
        for k in 0..3 {
            // The edge opposite corner k joins corners k+1 and k+2. An
            // intrinsic edge may join a vertex to itself: it contributes
            // w (p_i − p_i) = 0 and is skipped.
            let (i, j) = (f[(k + 1) % 3], f[(k + 2) % 3]);
            if i == j {
                continue;
            }
            let w = 0.5 * t.cot(k);
            values[pattern.position(i, j)] -= w;
            values[pattern.position(j, i)] -= w;
            values[pattern.position(i, i)] += w;
            values[pattern.position(j, j)] += w;
        }
    }
    values
}

/// Symmetric CSC pattern of the vertex adjacency plus the diagonal; rows of
/// every column sorted and unique.
pub(crate) struct AdjacencyPattern {
    pub(crate) col_ptr: Vec<usize>,
    pub(crate) row_idx: Vec<usize>,
}

impl AdjacencyPattern {
    /// Built in O(F + nnz log deg) by bucketing the directed edges of every
    /// face by column, then sorting and deduplicating each (short) column.
    pub(crate) fn new(n: usize, faces: &[[usize; 3]]) -> AdjacencyPattern {
        let mut count = vec![1usize; n]; // the diagonal
        for f in faces {
            for &v in f {
                count[v] += 2;
            }
        }
        let mut start = vec![0usize; n + 1];
        for j in 0..n {
            start[j + 1] = start[j] + count[j];
        }
        let mut fill = start.clone();
        let mut rows = vec![0usize; start[n]];
        for j in 0..n {
            rows[fill[j]] = j;
            fill[j] += 1;
        }
        for f in faces {
            for k in 0..3 {
                let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                rows[fill[a]] = b;
                rows[fill[a] + 1] = c;
                fill[a] += 2;
            }
        }
        // Compact: sort and dedup each column in place.
        let mut col_ptr = vec![0usize; n + 1];
        let mut out = 0;
        for j in 0..n {
            let seg = &mut rows[start[j]..start[j + 1]];
            seg.sort_unstable();
            let mut last = usize::MAX;
            let begin = start[j];
            let len = start[j + 1] - begin;
            for q in 0..len {
                let r = rows[begin + q];
                if r != last {
                    rows[out] = r;
                    out += 1;
                    last = r;
                }
            }
            col_ptr[j + 1] = out;
        }
        rows.truncate(out);
        rows.shrink_to_fit();
        AdjacencyPattern {
            col_ptr,
            row_idx: rows,
        }
    }

    /// Storage position of entry `(i, j)`; the entry must be in the pattern.
    pub(crate) fn position(&self, i: usize, j: usize) -> usize {
        let seg = &self.row_idx[self.col_ptr[j]..self.col_ptr[j + 1]];
        self.col_ptr[j] + seg.partition_point(|&r| r < i)
    }

    pub(crate) fn into_matrix(self, values: Vec<f64>) -> SparseColMat<usize, f64> {
        let n = self.col_ptr.len() - 1;
        // SAFETY-free construction: the pattern is sorted, unique and in
        // bounds by construction, which `new_checked` verifies once more.
        let symbolic = SymbolicSparseColMat::new_checked(n, n, self.col_ptr, None, self.row_idx);
        SparseColMat::new(symbolic, values)
    }
}
