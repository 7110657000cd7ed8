//! `A Q` for a sparse `A` and a `Q` given as a sequence of elementary
//! orthogonal operations (Givens rotations, Householder reflectors) acting on
//! the column index space of `A` — without forming `Q`.
//!
//! `M ← M G` for an elementary `G` changes only the columns of `M` in `G`'s
//! support, so only those columns are ever copied out of `A` ("materialised")
//! and kept as sorted sparse vectors; every other column of `A Q` is a column
//! of `A` unchanged. Exact zeros produced by cancellation are dropped; no other
//! entry is, so the result equals the dense product up to rounding.

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};

use super::givens_merge::rotate_merge;

/// A sorted sparse column.
#[derive(Debug, Clone, Default)]
struct Col {
    rows: Vec<usize>,
    vals: Vec<f64>,
}

/// The columns of `M = A · (operations applied so far)`.
pub(super) struct ColumnWorkspace<'a> {
    a: SparseColMatRef<'a, usize, f64>,
    /// Materialised columns (`None`: still column `j` of `A`).
    cols: Vec<Option<Col>>,
    /// Dense accumulator over the rows of `A` (all zero between uses).
    #[cfg_attr(not(feature = "suitesparse"), allow(dead_code))]
    acc: Vec<f64>,
    /// Row marks for the accumulator (`false` between uses).
    #[cfg_attr(not(feature = "suitesparse"), allow(dead_code))]
    mark: Vec<bool>,
    /// Scratch pattern.
    #[cfg_attr(not(feature = "suitesparse"), allow(dead_code))]
    pattern: Vec<usize>,
}

impl<'a> ColumnWorkspace<'a> {
    /// Starts from `M = A`.
    pub(super) fn new(a: SparseColMatRef<'a, usize, f64>) -> Self {
        ColumnWorkspace {
            a,
            cols: vec![None; a.ncols()],
            acc: Vec::new(),
            mark: Vec::new(),
            pattern: Vec::new(),
        }
    }

    fn a_col(&self, j: usize) -> (&[usize], &[f64]) {
        let ptr = self.a.symbolic().col_ptr();
        let range = ptr[j]..ptr[j + 1];
        (
            &self.a.symbolic().row_idx()[range.clone()],
            &self.a.val()[range],
        )
    }

    /// Column `j` of `M` as (sorted rows, values).
    pub(super) fn col(&self, j: usize) -> (&[usize], &[f64]) {
        match &self.cols[j] {
            Some(c) => (&c.rows, &c.vals),
            None => self.a_col(j),
        }
    }

    fn take(&mut self, j: usize) -> Col {
        match self.cols[j].take() {
            Some(c) => c,
            None => {
                let (r, v) = self.a_col(j);
                Col {
                    rows: r.to_vec(),
                    vals: v.to_vec(),
                }
            }
        }
    }

    /// `[M_p, M_q] ← [c M_p + s M_q, −s M_p + c M_q]` (a rotation acting on
    /// columns `p ≠ q` from the right).
    pub(super) fn rotate(&mut self, p: usize, q: usize, c: f64, s: f64) {
        let mp = self.take(p);
        let mq = self.take(q);
        let cap = mp.rows.len() + mq.rows.len();
        let mut np = Col {
            rows: Vec::with_capacity(cap),
            vals: Vec::with_capacity(cap),
        };
        let mut nq = Col {
            rows: Vec::with_capacity(cap),
            vals: Vec::with_capacity(cap),
        };
        rotate_merge(
            (&mp.rows, &mp.vals),
            (&mq.rows, &mq.vals),
            c,
            s,
            (&mut np.rows, &mut np.vals),
            (&mut nq.rows, &mut nq.vals),
        );
        self.cols[p] = Some(np);
        self.cols[q] = Some(nq);
    }

    /// `M ← M (I − τ h hᵀ)` for a sparse `h` with support `support` (distinct
    /// column indices) and values `h`: `w = M h`, then `M_j ← M_j − τ h_j w`
    /// for `j` in the support.
    #[cfg_attr(not(feature = "suitesparse"), allow(dead_code))]
    pub(super) fn reflect(&mut self, support: &[usize], h: &[f64], tau: f64) {
        if tau == 0.0 || support.is_empty() {
            return;
        }
        let l = self.a.nrows();
        if self.acc.len() != l {
            self.acc = vec![0.0; l];
            self.mark = vec![false; l];
        }
        let mut pattern = std::mem::take(&mut self.pattern);
        pattern.clear();
        for (&j, &hj) in support.iter().zip(h) {
            let (rows, vals) = match &self.cols[j] {
                Some(c) => (&c.rows[..], &c.vals[..]),
                None => {
                    let ptr = self.a.symbolic().col_ptr();
                    let range = ptr[j]..ptr[j + 1];
                    (
                        &self.a.symbolic().row_idx()[range.clone()],
                        &self.a.val()[range],
                    )
                }
            };
            for (&r, &v) in rows.iter().zip(vals) {
                if !self.mark[r] {
                    self.mark[r] = true;
                    pattern.push(r);
                }
                self.acc[r] += hj * v;
            }
        }
        pattern.sort_unstable();
        for (&j, &hj) in support.iter().zip(h) {
            let f = tau * hj;
            let old = self.take(j);
            let mut new = Col {
                rows: Vec::with_capacity(pattern.len()),
                vals: Vec::with_capacity(pattern.len()),
            };
            // `old`'s pattern is a subset of `pattern`, both sorted.
            let mut k = 0;
            for &r in &pattern {
                let mut v = -f * self.acc[r];
                if k < old.rows.len() && old.rows[k] == r {
                    v += old.vals[k];
                    k += 1;
                }
                if v != 0.0 {
                    new.rows.push(r);
                    new.vals.push(v);
                }
            }
            self.cols[j] = Some(new);
        }
        for &r in &pattern {
            self.acc[r] = 0.0;
            self.mark[r] = false;
        }
        self.pattern = pattern;
    }

    /// The matrix whose `t`-th column is column `coords[t]` of `M`.
    pub(super) fn gather(&self, coords: &[usize]) -> SparseColMat<usize, f64> {
        let mut col_ptr = Vec::with_capacity(coords.len() + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        for &j in coords {
            let (r, v) = self.col(j);
            row_idx.extend_from_slice(r);
            values.extend_from_slice(v);
            col_ptr.push(row_idx.len());
        }
        // Every column is sorted and duplicate-free by construction.
        let symbolic =
            SymbolicSparseColMat::new_checked(self.a.nrows(), coords.len(), col_ptr, None, row_idx);
        SparseColMat::new(symbolic, values)
    }
}
