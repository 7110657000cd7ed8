//! Intrinsic Delaunay triangulation by edge flips (Bobenko & Springborn
//! 2007; Fisher, Springborn, Schröder & Bobenko 2007; Sharp & Crane 2020).
//!
//! The surface is kept exactly — only its *triangulation* changes: an
//! intrinsic triangulation is described by its connectivity and the length
//! of every edge, measured along the surface. An edge `ij` between the
//! triangles `ijk` and `jil` is Delaunay iff the angles opposite it satisfy
//! `α_k + β_l ≤ π`, i.e. `cot α_k + cot β_l ≥ 0` — exactly the condition for
//! its cotangent weight to be non-negative. A non-Delaunay edge is flipped
//! to `kl`, whose length follows from laying the two triangles out in the
//! plane. Flipping until every edge is Delaunay terminates (each flip
//! decreases the harmonic index), and the cotangent Laplacian of the result
//! has only non-negative weights; on a planar mesh it is the Laplacian of the
//! Delaunay triangulation of the same points.
//!
//! Boundary edges are never flipped. The mesh must be an oriented 2-manifold
//! (with boundary): every directed edge used at most once.

use crate::error::MeshError;
use crate::mesh::Mesh;

use super::triangle::Triangle;

/// No twin: a boundary half-edge.
const NONE: usize = usize::MAX;

/// An edge is flipped when `cot α + cot β < −FLIP_TOLERANCE`. The cotangents
/// are dimensionless and computed from lengths with relative error of a few
/// ε times their magnitude; a small negative margin stops flips of
/// (numerically) cocircular pairs, which would otherwise flip back and forth
/// without changing the Laplacian.
const FLIP_TOLERANCE: f64 = 1e-12;

/// A triangulation given by half-edges and intrinsic edge lengths.
#[derive(Debug, Clone)]
pub(crate) struct IntrinsicTriangulation {
    /// Tail vertex of each half-edge.
    tail: Vec<usize>,
    /// Face of each half-edge.
    face_of: Vec<usize>,
    next: Vec<usize>,
    twin: Vec<usize>,
    /// Length of the edge of each half-edge (equal on both twins).
    length: Vec<f64>,
    /// One half-edge of each face.
    face_start: Vec<usize>,
    flips: usize,
}

impl IntrinsicTriangulation {
    /// The mesh's own triangulation with its Euclidean edge lengths. A face
    /// of zero area is refused ([`MeshError::DegenerateFace`]).
    pub(crate) fn new(mesh: &Mesh) -> Result<IntrinsicTriangulation, MeshError> {
        if let Some(e) = mesh.degenerate_face() {
            return Err(e);
        }
        let faces = mesh.faces();
        let p = mesh.positions();
        let m = 3 * faces.len();
        let mut tail = Vec::with_capacity(m);
        let mut next = Vec::with_capacity(m);
        let mut length = Vec::with_capacity(m);
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                tail.push(a);
                next.push(3 * f + (k + 1) % 3);
                let d = [0, 1, 2].map(|c| p[b][c] - p[a][c]);
                length.push((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
            }
        }
        // Twins by sorting directed edges (a, b) and looking up (b, a).
        let mut keyed: Vec<(usize, usize, usize)> =
            (0..m).map(|h| (tail[h], tail[next[h]], h)).collect();
        keyed.sort_unstable();
        for w in keyed.windows(2) {
            if w[0].0 == w[1].0 && w[0].1 == w[1].1 {
                return Err(MeshError::NotManifold {
                    edge: [w[0].0.min(w[0].1), w[0].0.max(w[0].1)],
                    reason: "the directed edge appears in two faces (a non-manifold edge, or neighbouring faces with opposite orientation)".into(),
                });
            }
        }
        let mut twin = vec![NONE; m];
        for &(a, b, h) in &keyed {
            if let Ok(pos) = keyed.binary_search_by(|probe| (probe.0, probe.1).cmp(&(b, a))) {
                twin[h] = keyed[pos].2;
            }
        }
        Ok(IntrinsicTriangulation {
            face_of: (0..m).map(|h| h / 3).collect(),
            tail,
            next,
            twin,
            length,
            face_start: (0..faces.len()).map(|f| 3 * f).collect(),
            flips: 0,
        })
    }

    /// Number of flips performed so far.
    #[cfg(test)]
    pub(crate) fn flips(&self) -> usize {
        self.flips
    }

    /// Cotangent of the angle opposite half-edge `h` in its face.
    fn cot_opposite(&self, h: usize) -> f64 {
        let (h1, h2) = (self.next[h], self.next[self.next[h]]);
        let t = Triangle::from_len_sq([
            self.length[h].powi(2),
            self.length[h1].powi(2),
            self.length[h2].powi(2),
        ]);
        // len_sq[0] is the edge of h, opposite corner 0 of this ordering.
        t.cot(0)
    }

    /// `true` if the interior edge of `h` violates the Delaunay condition.
    fn is_non_delaunay(&self, h: usize) -> bool {
        let t = self.twin[h];
        t != NONE && self.cot_opposite(h) + self.cot_opposite(t) < -FLIP_TOLERANCE
    }

    /// Flips the interior edge of `h` (triangles `i j k` and `j i l`) to the
    /// edge `l k`.
    fn flip(&mut self, h: usize) {
        let t = self.twin[h];
        let (h1, h2) = (self.next[h], self.next[self.next[h]]);
        let (t1, t2) = (self.next[t], self.next[self.next[t]]);
        let (i, j, k, l) = (self.tail[h], self.tail[t], self.tail[h2], self.tail[t2]);
        debug_assert_eq!(self.tail[h1], j);
        debug_assert_eq!(self.tail[t1], i);
        let _ = (i, j);
        // Lay out i = (0, 0), j = (ℓ_ij, 0), k above and l below the x-axis.
        let (lij, ljk, lki) = (self.length[h], self.length[h1], self.length[h2]);
        let (lil, llj) = (self.length[t1], self.length[t2]);
        let xk = (lij * lij + lki * lki - ljk * ljk) / (2.0 * lij);
        let yk = (lki * lki - xk * xk).max(0.0).sqrt();
        let xl = (lij * lij + lil * lil - llj * llj) / (2.0 * lij);
        let yl = -(lil * lil - xl * xl).max(0.0).sqrt();
        let lkl = ((xk - xl).powi(2) + (yk - yl).powi(2)).sqrt();
        // New faces: (k, i, l) = h2, t1, h  and  (l, j, k) = t2, h1, t.
        let (fh, ft) = (self.face_of[h], self.face_of[t]);
        self.tail[h] = l;
        self.tail[t] = k;
        self.next[h2] = t1;
        self.next[t1] = h;
        self.next[h] = h2;
        self.next[t2] = h1;
        self.next[h1] = t;
        self.next[t] = t2;
        self.length[h] = lkl;
        self.length[t] = lkl;
        self.face_of[t1] = fh;
        self.face_of[h1] = ft;
        self.face_start[fh] = h;
        self.face_start[ft] = t;
        self.flips += 1;
    }

    /// Flips non-Delaunay interior edges until none is left.
    ///
    /// Fails (instead of looping) if the number of flips exceeds
    /// `100 × edges`, which no valid input reaches.
    pub(crate) fn flip_to_delaunay(mut self) -> Result<IntrinsicTriangulation, MeshError> {
        let m = self.tail.len();
        let mut stack: Vec<usize> = (0..m)
            .filter(|&h| self.twin[h] != NONE && h < self.twin[h])
            .collect();
        let mut queued = vec![false; m];
        for &h in &stack {
            queued[h] = true;
        }
        let limit = 100 * m.max(1);
        while let Some(h) = stack.pop() {
            queued[h] = false;
            if !self.is_non_delaunay(h) {
                continue;
            }
            if self.flips >= limit {
                return Err(MeshError::NotManifold {
                    edge: [self.tail[h], self.tail[self.twin[h]]],
                    reason: format!(
                        "intrinsic Delaunay flipping did not terminate within {limit} flips"
                    ),
                });
            }
            let t = self.twin[h];
            let around = [
                self.next[h],
                self.next[self.next[h]],
                self.next[t],
                self.next[self.next[t]],
            ];
            self.flip(h);
            for e in around {
                let tw = self.twin[e];
                if tw == NONE {
                    continue;
                }
                let canon = e.min(tw);
                if !queued[canon] {
                    queued[canon] = true;
                    stack.push(canon);
                }
            }
        }
        Ok(self)
    }

    /// The faces (corner vertices, counter-clockwise).
    pub(crate) fn faces(&self) -> Vec<[usize; 3]> {
        self.face_start
            .iter()
            .map(|&h| {
                [
                    self.tail[h],
                    self.tail[self.next[h]],
                    self.tail[self.next[self.next[h]]],
                ]
            })
            .collect()
    }

    /// Faces with their corner geometry from the intrinsic lengths.
    pub(super) fn triangles(&self) -> impl Iterator<Item = ([usize; 3], Triangle)> + Clone + '_ {
        self.face_start.iter().map(move |&h| {
            let (h1, h2) = (self.next[h], self.next[self.next[h]]);
            let f = [self.tail[h], self.tail[h1], self.tail[h2]];
            // Corner 0 = tail(h) is opposite the edge of h1, corner 1 opposite
            // h2, corner 2 opposite h.
            let t = Triangle::from_len_sq([
                self.length[h1].powi(2),
                self.length[h2].powi(2),
                self.length[h].powi(2),
            ]);
            (f, t)
        })
    }

    /// The smallest `cot α + cot β` over interior edges (≥ −tolerance once
    /// Delaunay), for diagnostics and tests.
    #[cfg(test)]
    pub(crate) fn min_cotan_sum(&self) -> f64 {
        (0..self.tail.len())
            .filter(|&h| self.twin[h] != NONE && h < self.twin[h])
            .map(|h| self.cot_opposite(h) + self.cot_opposite(self.twin[h]))
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests;
