//! The ARAP energies as per-triangle sums of squares of gradients.
//!
//! Notation: triangle `t` with corners `f[0], f[1], f[2]`, area `A_t`; edge
//! `k` is opposite corner `k` and runs from `f[k+1]` to `f[k+2]`; `p_k` is
//! its rest vector and `x_k` its deformed vector; `c_k = ½ cot θ_k` with
//! `θ_k` the rest angle at corner `k` (libigl's `cotmatrix_entries`).
//! The energy, for per-vertex rotations `R_i`, is
//!
//! ```text
//! E(X, R) = Σ_t Σ_k c_k Σ_{o ∈ own(k)} ‖x_k − R_o p_k‖²
//! ```
//!
//! with `own(k)` the *rotation owners* of edge `k` in `t`:
//! - spokes-and-rims (Chao et al. 2010, libigl's default for triangles): all
//!   three corners of `t` (`K = 3` owners per edge);
//! - spokes (Sorkine & Alexa 2007): the edge's two endpoints (`K = 2`).
//!
//! **Global step as rows.** For a function linear on `t`,
//! `Σ_k c_k (f_{k+2} − f_{k+1})(g_{k+2} − g_{k+1}) = A_t ∇f·∇g` (the
//! cotangent formula), and `x_k = (∇X)ᵀ p_k` for the linear interpolant. So
//! for fixed rotations `E = ‖A_E X − C_E‖²_F + const(R)` with three rows per
//! triangle
//!
//! ```text
//! A_E[t] = √(K A_t) G_t                      (3 × n: G_t X = ∇X on t)
//! C_E[t] = Σ_k c_k p_k (Σ_{o∈own(k)} R_o p_k)ᵀ / √(K A_t)        (3 × 3)
//! ```
//!
//! since `A_E[t]ᵀ C_E[t]` has vertex `j` entry `Σ_k c_k (∇φ_j·p_k) v_kᵀ` and
//! `∇φ_j·p_k` is the incidence of `j` on edge `k`. `A_Eᵀ A_E = K · S` with `S`
//! the cotangent stiffness matrix, positive semidefinite whatever the signs
//! of the `c_k`: **negative cotangent weights are kept as they are** (no
//! clamping), and no square root of a weight is ever taken, for both
//! energies. (Spokes is not a sum of squares edge by edge when an angle is
//! obtuse; only its right-hand side needs the form above.) A triangle whose
//! doubled area underflows to zero gets zero rows (it carries no energy).
//!
//! For spokes-and-rims `Σ_o R_o = 3 R̄_t` and `C_E[t] = √(3 A_t) G_t P R̄_tᵀ`:
//! the averaged rotation of the three corners, as libigl's `arap_rhs`.

use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, MatMut};
use rayon::prelude::*;

use super::rotations::{IDENTITY, Mat3, fit_rotation_fast};
use crate::cpu::clear_upper_vector_state;
use crate::error::ProblemError;
use crate::mesh::Mesh;

pub use crate::choice::ArapEnergy;

impl ArapEnergy {
    /// Whether corner `corner` owns edge `edge` (opposite corner `edge`).
    fn owns(self, corner: usize, edge: usize) -> bool {
        match self {
            ArapEnergy::SpokesAndRims => true,
            ArapEnergy::Spokes => corner != edge,
        }
    }

    /// Rotation owners per edge, `K`.
    fn owners_per_edge(self) -> f64 {
        match self {
            ArapEnergy::SpokesAndRims => 3.0,
            ArapEnergy::Spokes => 2.0,
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

fn dot(u: [f64; 3], v: [f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

/// `R v`.
pub(crate) fn mat_vec(r: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// The rest geometry of every triangle and the vertex → corner incidence.
#[derive(Debug, Clone)]
pub struct ArapTriangles {
    energy: ArapEnergy,
    faces: Vec<[usize; 3]>,
    /// `c_k = ½ cot θ_k`.
    half_cot: Vec<[f64; 3]>,
    /// `p_k = P[f[k+2]] − P[f[k+1]]`.
    rest_edge: Vec<Mat3>,
    /// `∇φ_k`, the gradient of corner `k`'s hat function.
    gradient: Vec<Mat3>,
    /// `√(K A_t)`, zero for a triangle of zero area.
    row_scale: Vec<f64>,
    /// CSR: the `(triangle, corner)` pairs of each vertex.
    corner_ptr: Vec<usize>,
    corners: Vec<(usize, usize)>,
    /// `Σ c_k ‖p_k‖²` over the edges each vertex owns.
    rest_square: Vec<f64>,
}

/// One triangle's (or, for spokes, one corner's) share of a vertex's
/// covariance: `Σ c_k x_k p_kᵀ` and `Σ c_k ‖x_k‖²` over the edges a rotation
/// owner of the triangle owns.
#[derive(Debug, Clone, Copy, Default)]
pub struct CovarianceBlock {
    /// `Σ c_k x_k p_kᵀ`.
    pub cross: Mat3,
    /// `Σ c_k ‖x_k‖²`.
    pub square: f64,
}

impl ArapTriangles {
    /// Rest geometry of `mesh` for `energy`.
    pub fn new(mesh: &Mesh, energy: ArapEnergy) -> ArapTriangles {
        let p = mesh.positions();
        // Rows in the order of the triangles' smallest vertex (stable): the
        // triangles around a vertex then lie close together in memory, which
        // the local step's gather over them needs (the row order changes
        // nothing else).
        let mut faces = mesh.faces().to_vec();
        faces.sort_by_key(|f| f[0].min(f[1]).min(f[2]));
        let owners = energy.owners_per_edge();
        let mut half_cot = Vec::with_capacity(faces.len());
        let mut rest_edge = Vec::with_capacity(faces.len());
        let mut gradient = Vec::with_capacity(faces.len());
        let mut row_scale = Vec::with_capacity(faces.len());
        for f in &faces {
            let x = [p[f[0]], p[f[1]], p[f[2]]];
            let e: Mat3 = std::array::from_fn(|k| sub(x[(k + 2) % 3], x[(k + 1) % 3]));
            let normal = cross(sub(x[1], x[0]), sub(x[2], x[0]));
            let double_area = dot(normal, normal).sqrt();
            if double_area > 0.0 && double_area.is_finite() {
                let n = normal.map(|v| v / double_area);
                // Angle at corner k between the edges to k+1 and k+2:
                // cot = (u·v)/|u×v| with u = −e[k+2], v = e[k+1].
                let c = std::array::from_fn(|k| {
                    let (u, v) = (e[(k + 2) % 3].map(|a| -a), e[(k + 1) % 3]);
                    0.5 * dot(u, v) / double_area
                });
                half_cot.push(c);
                gradient.push(std::array::from_fn(|k| {
                    cross(n, e[k]).map(|a| a / double_area)
                }));
                row_scale.push((owners * double_area / 2.0).sqrt());
            } else {
                half_cot.push([0.0; 3]);
                gradient.push([[0.0; 3]; 3]);
                row_scale.push(0.0);
            }
            rest_edge.push(e);
        }
        let n = mesh.n_vertices();
        let mut corner_ptr = vec![0usize; n + 1];
        for f in &faces {
            for &v in f {
                corner_ptr[v + 1] += 1;
            }
        }
        for v in 0..n {
            corner_ptr[v + 1] += corner_ptr[v];
        }
        let mut fill = corner_ptr.clone();
        let mut corners = vec![(0, 0); corner_ptr[n]];
        for (t, f) in faces.iter().enumerate() {
            for (k, &v) in f.iter().enumerate() {
                corners[fill[v]] = (t, k);
                fill[v] += 1;
            }
        }
        let mut triangles = ArapTriangles {
            energy,
            faces,
            half_cot,
            rest_edge,
            gradient,
            row_scale,
            corner_ptr,
            corners,
            rest_square: Vec::new(),
        };
        triangles.rest_square = (0..n).map(|i| triangles.rest_square_of(i)).collect();
        triangles
    }

    fn rest_square_of(&self, i: usize) -> f64 {
        let mut s = 0.0;
        for &(t, corner) in &self.corners[self.corner_ptr[i]..self.corner_ptr[i + 1]] {
            for k in 0..3 {
                if self.energy.owns(corner, k) {
                    let p = self.rest_edge[t][k];
                    s += self.half_cot[t][k] * dot(p, p);
                }
            }
        }
        s
    }

    /// Covariance blocks per triangle: one (spokes-and-rims: every corner
    /// owns every edge) or three (spokes: one per corner).
    pub(crate) fn blocks_per_triangle(&self) -> usize {
        match self.energy {
            ArapEnergy::SpokesAndRims => 1,
            ArapEnergy::Spokes => 3,
        }
    }

    /// One pass over the triangles (in parallel): every
    /// [`CovarianceBlock`] of the positions `x` (n × 3) into `blocks`
    /// (resized to `#triangles × blocks_per_triangle`, reused between
    /// calls). Each edge vector is formed once per triangle.
    pub(crate) fn covariance_blocks_into(&self, x: &Mat<f64>, blocks: &mut Vec<CovarianceBlock>) {
        let per = self.blocks_per_triangle();
        blocks.resize(per * self.faces.len(), CovarianceBlock::default());
        let cols = [x.col_as_slice(0), x.col_as_slice(1), x.col_as_slice(2)];
        blocks
            .par_chunks_mut(per)
            .enumerate()
            .for_each_init(clear_upper_vector_state, |(), (t, out)| {
                self.triangle_blocks(t, &cols, out)
            });
    }

    fn triangle_blocks(&self, t: usize, x: &[&[f64]; 3], out: &mut [CovarianceBlock]) {
        let f = self.faces[t];
        let edge = |k: usize| {
            let (a, b) = (f[(k + 1) % 3], f[(k + 2) % 3]);
            [x[0][b] - x[0][a], x[1][b] - x[1][a], x[2][b] - x[2][a]]
        };
        let terms: [CovarianceBlock; 3] = std::array::from_fn(|k| {
            let (xe, p, w) = (edge(k), self.rest_edge[t][k], self.half_cot[t][k]);
            let wx = xe.map(|v| w * v);
            CovarianceBlock {
                cross: std::array::from_fn(|a| std::array::from_fn(|b| wx[a] * p[b])),
                square: dot(wx, xe),
            }
        });
        let all = out.len() == 1;
        for (corner, block) in out.iter_mut().enumerate() {
            *block = CovarianceBlock::default();
            for (k, term) in terms.iter().enumerate() {
                if all || self.energy.owns(corner, k) {
                    block.square += term.square;
                    for a in 0..3 {
                        for b in 0..3 {
                            block.cross[a][b] += term.cross[a][b];
                        }
                    }
                }
            }
        }
    }

    /// Vertex `i`'s covariance `M_i` (see [`ArapTriangles::covariance`])
    /// and `Σ c_k ‖x_k‖²` over its edges, summed from `blocks`
    /// ([`ArapTriangles::covariance_blocks_into`]).
    pub(crate) fn vertex_covariance(
        &self,
        i: usize,
        blocks: &[CovarianceBlock],
    ) -> CovarianceBlock {
        let per = self.blocks_per_triangle();
        let mut sum = CovarianceBlock::default();
        for &(t, corner) in &self.corners[self.corner_ptr[i]..self.corner_ptr[i + 1]] {
            let block = &blocks[per * t + if per == 1 { 0 } else { corner }];
            sum.square += block.square;
            for a in 0..3 {
                for b in 0..3 {
                    sum.cross[a][b] += block.cross[a][b];
                }
            }
        }
        sum
    }

    /// `E` at the positions `x` (n × 3) with the optimal rotation of every
    /// vertex (fitted from the identity): the ARAP energy of any
    /// deformation, e.g. another program's result or a linear solution.
    pub fn energy_at(&self, x: &Mat<f64>) -> f64 {
        let mut blocks = Vec::new();
        self.covariance_blocks_into(x, &mut blocks);
        (0..self.n_vertices())
            .map(|i| {
                let m = self.vertex_covariance(i, &blocks);
                let (r, _) = fit_rotation_fast(&m.cross, &IDENTITY);
                self.vertex_energy_from(i, &m, &r)
            })
            .sum()
    }

    /// Vertex `i`'s part of `E` from its covariance (orthogonal `R`):
    /// `Σ c_k ‖x_k − R p_k‖² = Σ c_k ‖x_k‖² − 2 tr(Rᵀ M_i) + Σ c_k ‖p_k‖²`.
    /// Rounding: `~ε (Σ |c_k| (‖x_k‖² + ‖p_k‖²))`, absolute; the tests
    /// compare it with [`ArapTriangles::vertex_energy`] (the direct sum).
    pub(crate) fn vertex_energy_from(&self, i: usize, m: &CovarianceBlock, r: &Mat3) -> f64 {
        let trace: f64 = (0..3)
            .map(|a| (0..3).map(|b| r[a][b] * m.cross[a][b]).sum::<f64>())
            .sum();
        m.square - 2.0 * trace + self.rest_square[i]
    }

    /// The energy these triangles evaluate.
    pub fn energy(&self) -> ArapEnergy {
        self.energy
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.corner_ptr.len() - 1
    }

    /// Number of energy rows, three per triangle.
    pub(crate) fn n_rows(&self) -> usize {
        3 * self.faces.len()
    }

    /// `A_E` (3 × #triangles rows, n columns): rows `3t..3t+3` are
    /// `√(K A_t) G_t`.
    ///
    /// An allocation that fails (under a memory or address-space limit) is
    /// [`ProblemError::TooLarge`], with the bytes it asked for.
    pub fn rows(&self) -> Result<SparseColMat<usize, f64>, ProblemError> {
        const WHAT: &str = "the ARAP energy rows";
        let entries = 9 * self.faces.len();
        // A triplet is two indices and a value; the matrix built from them
        // holds an index and a value per entry, and a column pointer per
        // vertex.
        let bytes = (entries as u64).saturating_mul(24 + 16) + 8 * self.n_vertices() as u64;
        let mut triplets = Vec::new();
        triplets
            .try_reserve_exact(entries)
            .map_err(|_| ProblemError::allocation_failed(WHAT, bytes))?;
        for (t, f) in self.faces.iter().enumerate() {
            let s = self.row_scale[t];
            if s == 0.0 {
                continue;
            }
            for (k, &v) in f.iter().enumerate() {
                for a in 0..3 {
                    triplets.push(Triplet::new(3 * t + a, v, s * self.gradient[t][k][a]));
                }
            }
        }
        // Rows `3t..3t+3` and a face's vertices are in range and unique per
        // (row, vertex): only an allocation can fail here.
        SparseColMat::try_new_from_triplets(self.n_rows(), self.n_vertices(), &triplets)
            .map_err(|e| ProblemError::from_creation(WHAT, bytes, e))
    }

    /// `C_E` for the rotations `r` (one per vertex), written into `c`
    /// (`n_rows × 3`, each column contiguous), in parallel over the
    /// triangles. Returns `false` if an entry is not finite.
    pub(crate) fn rhs_into(&self, r: &[Mat3], c: MatMut<'_, f64>) -> bool {
        let (c0, rest) = c.split_at_col_mut(1);
        let (c1, c2) = rest.split_at_col_mut(1);
        fn column(m: MatMut<'_, f64>) -> &mut [f64] {
            m.col_mut(0)
                .try_as_col_major_mut()
                .expect("the right-hand side's columns are contiguous")
                .as_slice_mut()
        }
        let (c0, c1, c2) = (column(c0), column(c1), column(c2));
        (
            c0.par_chunks_mut(3),
            c1.par_chunks_mut(3),
            c2.par_chunks_mut(3),
        )
            .into_par_iter()
            .enumerate()
            .map_init(clear_upper_vector_state, |(), (t, (a, b, c))| {
                let block = self.rhs_block(t, r);
                for row in 0..3 {
                    a[row] = block[row][0];
                    b[row] = block[row][1];
                    c[row] = block[row][2];
                }
                block.iter().flatten().all(|v| v.is_finite())
            })
            .reduce(|| true, |x, y| x && y)
    }

    fn rhs_block(&self, t: usize, r: &[Mat3]) -> Mat3 {
        let s = self.row_scale[t];
        let mut block = [[0.0; 3]; 3];
        if s == 0.0 {
            return block;
        }
        let f = self.faces[t];
        for k in 0..3 {
            let p = self.rest_edge[t][k];
            let mut v = [0.0; 3];
            for corner in 0..3 {
                if self.energy.owns(corner, k) {
                    let rp = mat_vec(&r[f[corner]], p);
                    for c in 0..3 {
                        v[c] += rp[c];
                    }
                }
            }
            let w = self.half_cot[t][k] / s;
            for a in 0..3 {
                for c in 0..3 {
                    block[a][c] += w * p[a] * v[c];
                }
            }
        }
        block
    }

    /// The rest rows' right-hand side `A_E P` (the rotations all identity,
    /// up to rounding); [`ProblemError::TooLarge`] when its allocation
    /// fails.
    pub(crate) fn rest_rhs(&self) -> Result<Mat<f64>, ProblemError> {
        const WHAT: &str = "the ARAP energy rows' right-hand side";
        let n = self.n_vertices();
        let mut c = crate::problem::zero_matrix(WHAT, self.n_rows(), 3)?;
        let mut identities = crate::problem::reserved::<Mat3>(WHAT, n)?;
        identities.resize(n, IDENTITY);
        self.rhs_into(&identities, c.as_mut());
        Ok(c)
    }

    /// Deformed edge `k` of triangle `t`.
    fn edge(&self, t: usize, k: usize, x: &Mat<f64>) -> [f64; 3] {
        let f = self.faces[t];
        let (a, b) = (f[(k + 1) % 3], f[(k + 2) % 3]);
        [
            x[(b, 0)] - x[(a, 0)],
            x[(b, 1)] - x[(a, 1)],
            x[(b, 2)] - x[(a, 2)],
        ]
    }

    /// `M_i = Σ c_k x_k p_kᵀ` over the edges vertex `i` owns: the rotation
    /// that minimises vertex `i`'s part of `E` maximises `tr(Rᵀ M_i)`.
    pub fn covariance(&self, i: usize, x: &Mat<f64>) -> Mat3 {
        let mut m = [[0.0; 3]; 3];
        for &(t, corner) in &self.corners[self.corner_ptr[i]..self.corner_ptr[i + 1]] {
            for k in 0..3 {
                if !self.energy.owns(corner, k) {
                    continue;
                }
                let xe = self.edge(t, k, x);
                let p = self.rest_edge[t][k];
                let w = self.half_cot[t][k];
                for a in 0..3 {
                    for b in 0..3 {
                        m[a][b] += w * xe[a] * p[b];
                    }
                }
            }
        }
        m
    }

    /// Vertex `i`'s part of `E`: `Σ c_k ‖x_k − R p_k‖²` over its edges.
    #[cfg(test)]
    pub(crate) fn vertex_energy(&self, i: usize, x: &Mat<f64>, r: &Mat3) -> f64 {
        let mut e = 0.0;
        for &(t, corner) in &self.corners[self.corner_ptr[i]..self.corner_ptr[i + 1]] {
            for k in 0..3 {
                if !self.energy.owns(corner, k) {
                    continue;
                }
                let d = sub(self.edge(t, k, x), mat_vec(r, self.rest_edge[t][k]));
                e += self.half_cot[t][k] * dot(d, d);
            }
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The rows' constructor reports an allocation failure as the typed
    /// refusal (exit 2) with the bytes asked for, where it panicked before.
    #[test]
    fn an_allocation_failure_of_the_rows_is_a_refusal() {
        use crate::error::ProblemError;
        use faer::sparse::{CreationError, FaerError};
        let e = ProblemError::from_creation(
            "the ARAP energy rows",
            3 << 30,
            CreationError::Generic(FaerError::OutOfMemory),
        );
        match &e {
            ProblemError::TooLarge { detail } => {
                assert!(detail.contains("the ARAP energy rows"), "{detail}");
                assert!(detail.contains("GiB"), "{detail}");
            }
            other => panic!("not TooLarge: {other:?}"),
        }
        assert_eq!(crate::Error::from(e).exit_code(), 2);
        let bounds = ProblemError::from_creation(
            "the ARAP energy rows",
            0,
            CreationError::OutOfBounds { row: 7, col: 1 },
        );
        assert!(matches!(bounds, ProblemError::Dimensions { .. }));
    }

    use super::{ArapEnergy, ArapTriangles};
    use crate::testing::random_surface;

    /// The local step's fused covariance blocks and energy-from-covariance
    /// against the per-vertex direct sums, both energies, on a bent random
    /// surface with random rotations.
    #[test]
    fn covariance_blocks_and_energy_from_covariance_match_the_direct_sums() {
        let (nx, ny) = (6, 7);
        let mesh = random_surface(nx, ny, 5);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let x = Mat::from_fn(mesh.n_vertices(), 3, |i, c| {
            mesh.positions()[i][c] * 1.3 + rng.random_range(-0.1..0.1)
        });
        for energy in [ArapEnergy::SpokesAndRims, ArapEnergy::Spokes] {
            let t = ArapTriangles::new(&mesh, energy);
            let mut blocks = Vec::new();
            t.covariance_blocks_into(&x, &mut blocks);
            for i in 0..mesh.n_vertices() {
                let m = t.vertex_covariance(i, &blocks);
                let direct = t.covariance(i, &x);
                let gap = m
                    .cross
                    .iter()
                    .flatten()
                    .zip(direct.iter().flatten())
                    .map(|(u, v)| (u - v).abs())
                    .fold(0.0, f64::max);
                assert!(gap <= 1e-13, "{energy:?} vertex {i}: {gap:e}");
                let q = nalgebra::UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-3.0..3.0),
                );
                let r = q.to_rotation_matrix();
                let r: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|b| r[(a, b)]));
                let (e1, e2) = (t.vertex_energy_from(i, &m, &r), t.vertex_energy(i, &x, &r));
                assert!(
                    (e1 - e2).abs() <= 1e-12 * (1.0 + e2.abs()),
                    "{energy:?} vertex {i}: {e1} vs {e2}"
                );
            }
        }
    }
}
