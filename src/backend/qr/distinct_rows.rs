//! Repeated constraint rows are decided before the QR, in linear time.
//!
//! A row `b_j` of `B` that equals an earlier row `b_i` (`i < j`) up to sign
//! is dependent on the earlier constraints whatever the tolerance: `b_i` is
//! either kept (then `b_j`'s remainder after projecting out the kept rows is
//! zero) or itself skipped as a combination of kept rows (then so is `b_j`).
//! Removing `b_j` changes neither the span of any prefix of the list nor,
//! therefore, any later decision. So every back end factors only the first
//! occurrence of each distinct row and reports the repeats as skipped —
//! exactly what the full factorisation returns in exact arithmetic (and, in
//! floating point, what it returns whenever the repeat's rounding remainder
//! `O(ε)` is below `η`, which it always is).
//!
//! Why: a block of `k` constraints sharing one unknown (a position
//! constraint repeated `k` times, relative constraints from one hub to a few
//! vertices over and over) makes `B Bᵀ` a dense `k × k` block. Every
//! ordering built from `B Bᵀ` and every QR of `Bᵀ` then costs `O(k²)` or
//! more (20,000 repeats of one position constraint took 55 s and 7.8 GB),
//! although the answer — one kept, `k − 1` dependent — is clear from the
//! rows themselves.
//!
//! "Equal" is bitwise after putting each row in a canonical form: entries
//! sorted by unknown, duplicates summed, zeros dropped, and the whole row
//! negated if its first entry is negative (negation is exact, so `p_i − p_j`
//! and `p_j − p_i` are the same row). Rows with a non-finite coefficient are
//! left to the back end, which reports them. Cost: `O(nnz(B) log)` for the
//! sort within rows and one hash-map entry per row.

use std::collections::HashMap;

use faer::sparse::{
    SparseColMat, SparseColMatRef, SparseRowMat, SparseRowMatRef, SymbolicSparseRowMat,
};
use faer::{Mat, MatMut, MatRef};

use super::ConstraintQr;
use crate::error::Error;

/// Factors the distinct rows of `b` with `factor` and reports the repeats
/// as skipped (see the module documentation). Calls `factor` on `b` itself
/// when no row repeats.
pub(super) fn factor_distinct_rows(
    b: SparseRowMatRef<'_, usize, f64>,
    factor: impl FnOnce(SparseRowMatRef<'_, usize, f64>) -> Result<Box<dyn ConstraintQr>, Error>,
) -> Result<Box<dyn ConstraintQr>, Error> {
    let Some(first) = first_occurrences(b) else {
        return factor(b);
    };
    let distinct: Vec<usize> = (0..b.nrows()).filter(|&j| first[j] == j).collect();
    if distinct.len() == b.nrows() {
        return factor(b);
    }
    let reduced = select_rows(b, &distinct);
    let inner = factor(reduced.as_ref())?;
    let kept: Vec<usize> = inner.kept().iter().map(|&k| distinct[k]).collect();
    let mut skipped: Vec<usize> = inner.skipped().iter().map(|&k| distinct[k]).collect();
    skipped.extend((0..b.nrows()).filter(|&j| first[j] != j));
    skipped.sort_unstable();
    Ok(Box::new(WithRepeats {
        inner,
        distinct,
        kept,
        skipped,
    }))
}

/// `first[j]`: the first row equal to row `j` up to sign (`j` itself when it
/// is the first). `None` when a coefficient is not finite.
fn first_occurrences(b: SparseRowMatRef<'_, usize, f64>) -> Option<Vec<usize>> {
    let (ptr, col, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    let mut seen: HashMap<Vec<(usize, u64)>, usize> = HashMap::with_capacity(b.nrows());
    let mut first = Vec::with_capacity(b.nrows());
    let mut entries: Vec<(usize, f64)> = Vec::new();
    for j in 0..b.nrows() {
        entries.clear();
        for p in ptr[j]..ptr[j + 1] {
            if !val[p].is_finite() {
                return None;
            }
            entries.push((col[p], val[p]));
        }
        entries.sort_unstable_by_key(|e| e.0);
        let mut key: Vec<(usize, f64)> = Vec::with_capacity(entries.len());
        for &(u, v) in &entries {
            match key.last_mut() {
                Some(last) if last.0 == u => last.1 += v,
                _ => key.push((u, v)),
            }
        }
        key.retain(|e| e.1 != 0.0);
        let sign = if key.first().is_some_and(|e| e.1 < 0.0) {
            -1.0
        } else {
            1.0
        };
        let key: Vec<(usize, u64)> = key
            .iter()
            .map(|&(u, v)| (u, (sign * v).to_bits()))
            .collect();
        first.push(*seen.entry(key).or_insert(j));
    }
    Some(first)
}

/// The rows `rows` of `b`, in that order.
fn select_rows(b: SparseRowMatRef<'_, usize, f64>, rows: &[usize]) -> SparseRowMat<usize, f64> {
    let (ptr, col, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    let mut new_ptr = Vec::with_capacity(rows.len() + 1);
    new_ptr.push(0);
    let mut new_col = Vec::new();
    let mut new_val = Vec::new();
    for &i in rows {
        new_col.extend_from_slice(&col[ptr[i]..ptr[i + 1]]);
        new_val.extend_from_slice(&val[ptr[i]..ptr[i + 1]]);
        new_ptr.push(new_col.len());
    }
    let symbolic = SymbolicSparseRowMat::new_checked(rows.len(), b.ncols(), new_ptr, None, new_col);
    SparseRowMat::new(symbolic, new_val)
}

/// The factorisation of the distinct rows, answering for all rows of `B`.
struct WithRepeats {
    inner: Box<dyn ConstraintQr>,
    /// Row of `B` of each row the inner factorisation saw, increasing.
    distinct: Vec<usize>,
    kept: Vec<usize>,
    skipped: Vec<usize>,
}

impl ConstraintQr for WithRepeats {
    fn n(&self) -> usize {
        self.inner.n()
    }

    fn rank(&self) -> usize {
        self.inner.rank()
    }

    fn kept(&self) -> &[usize] {
        &self.kept
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn solve_r1t(&self, d: MatRef<'_, f64>, y: MatMut<'_, f64>) {
        let reduced = Mat::from_fn(self.distinct.len(), d.ncols(), |i, c| {
            d[(self.distinct[i], c)]
        });
        self.inner.solve_r1t(reduced.as_ref(), y);
    }

    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, x: MatMut<'_, f64>) {
        self.inner.apply_q(y, z, x);
    }

    fn apply_qt(&self, x: MatRef<'_, f64>, y: MatMut<'_, f64>, z: MatMut<'_, f64>) {
        self.inner.apply_qt(x, y, z);
    }

    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        self.inner.mul_a_q2(a)
    }

    fn free_unknown(&self, k: usize) -> usize {
        self.inner.free_unknown(k)
    }

    fn storage_nnz(&self) -> usize {
        self.inner.storage_nnz()
    }
}

#[cfg(test)]
mod tests;
