//! The fill of `R` in `Bᵀ = QR`, known before factoring, in near-linear
//! time; and the fill-reducing constraint order.
//!
//! `RᵀR = B Bᵀ` (for the columns kept), so the pattern of `R` in a column
//! order `π` is that of the Cholesky factor of `P B Bᵀ Pᵀ`: its column counts
//! follow from the column elimination tree of `Bᵀ` and the row structure of
//! `B`, without forming `B Bᵀ` (Gilbert, Ng & Peyton 1994, as in CSparse's
//! `cs_counts` with `ata`; faer's `qr::col_etree`, `qr::column_counts_ata`).
//! For structurally full-rank `B` this is exactly `nnz(R)`; numerical
//! cancellation and dependent constraints (empty rows of `R`) only lower it.
//! Both the order (COLAMD on `Bᵀ`, which also never forms `B Bᵀ`) and the
//! count cost about `O(nnz(B) α)`. This matters when many constraints share
//! an unknown: `B Bᵀ` then has a dense block whose size is quadratic in the
//! number of those constraints, while `B` stays linear.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::{colamd, qr};
use faer::sparse::{SparseRowMatRef, SymbolicSparseColMat};

use crate::error::{Error, ProblemError};

/// Bytes per stored entry of `R`: the `f64` value and its column index
/// (`usize`).
pub(super) const R_BYTES_PER_ENTRY: u64 = 16;

/// `Bᵀ`'s pattern (n × m, column `j` = row `j` of `B`), sorted, duplicates
/// merged.
fn bt_pattern(b: SparseRowMatRef<'_, usize, f64>) -> SymbolicSparseColMat<usize> {
    let (m, n) = (b.nrows(), b.ncols());
    let (ptr, col) = (b.symbolic().row_ptr(), b.symbolic().col_idx());
    let mut col_ptr = Vec::with_capacity(m + 1);
    col_ptr.push(0);
    let mut row_idx = Vec::with_capacity(col.len());
    for j in 0..m {
        let start = row_idx.len();
        row_idx.extend_from_slice(&col[ptr[j]..ptr[j + 1]]);
        row_idx[start..].sort_unstable();
        let mut w = start;
        for r in start..row_idx.len() {
            if r == start || row_idx[r] != row_idx[w - 1] {
                row_idx[w] = row_idx[r];
                w += 1;
            }
        }
        row_idx.truncate(w);
        col_ptr.push(row_idx.len());
    }
    SymbolicSparseColMat::new_checked(n, m, col_ptr, None, row_idx)
}

/// The transpose of a pattern (`B` as m × n CSC from `Bᵀ`).
fn transpose(a: &SymbolicSparseColMat<usize>) -> SymbolicSparseColMat<usize> {
    let (n, m) = (a.nrows(), a.ncols());
    let mut counts = vec![0usize; n + 1];
    for &r in a.row_idx() {
        counts[r + 1] += 1;
    }
    for r in 0..n {
        counts[r + 1] += counts[r];
    }
    let mut next = counts.clone();
    let mut idx = vec![0usize; a.row_idx().len()];
    for j in 0..m {
        for r in a.row_idx_of_col(j) {
            idx[next[r]] = j;
            next[r] += 1;
        }
    }
    SymbolicSparseColMat::new_checked(m, n, counts, None, idx)
}

fn ordering_error(e: impl std::fmt::Debug) -> Error {
    ProblemError::InvalidArgument {
        message: format!("ordering the hard constraints failed: {e:?}"),
    }
    .into()
}

fn scratch(req: StackReq) -> Result<MemBuffer, Error> {
    MemBuffer::try_new(req).map_err(ordering_error)
}

/// A fill-reducing order of the constraints (COLAMD on `Bᵀ`): `perm[k]` is
/// the constraint placed `k`-th. `None` when no two constraints share an
/// unknown (then `R` is diagonal in any order).
pub(super) fn fill_reducing_constraint_order(
    b: SparseRowMatRef<'_, usize, f64>,
) -> Result<Option<Vec<usize>>, Error> {
    let pattern = bt_pattern(b);
    let (n, m) = (pattern.nrows(), pattern.ncols());
    let mut uses = vec![0u8; n];
    let mut shared = false;
    for &u in pattern.row_idx() {
        uses[u] = uses[u].saturating_add(1);
        shared |= uses[u] > 1;
    }
    if !shared {
        return Ok(None);
    }
    let mut fwd = vec![0usize; m];
    let mut inv = vec![0usize; m];
    let nnz = pattern.row_idx().len();
    let mut mem = scratch(colamd::order_scratch::<usize>(n, m, nnz))?;
    colamd::order(
        &mut fwd,
        &mut inv,
        pattern.as_ref(),
        colamd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(ordering_error)?;
    Ok(Some(fwd))
}

/// `nnz(R)` of `Bᵀ = QR` with the constraints in the order `perm`
/// (`perm[k]` placed `k`-th; `None`: list order), assuming no cancellation
/// and full rank (an upper bound otherwise).
pub(super) fn r_nnz(
    b: SparseRowMatRef<'_, usize, f64>,
    perm: Option<&[usize]>,
) -> Result<u64, Error> {
    let bt = bt_pattern(b);
    let (n, m) = (bt.nrows(), bt.ncols());
    if m == 0 {
        return Ok(0);
    }
    let (fwd, inv) = match perm {
        Some(p) => {
            let mut inv = vec![0usize; m];
            for (k, &j) in p.iter().enumerate() {
                inv[j] = k;
            }
            (p.to_vec(), inv)
        }
        None => ((0..m).collect(), (0..m).collect()),
    };
    let perm = PermRef::new_checked(&fwd, &inv, m);
    let b_csc = transpose(&bt);
    let req = StackReq::any_of(&[
        qr::col_etree_scratch::<usize>(n, m),
        qr::postorder_scratch::<usize>(m),
        qr::column_counts_aat_scratch::<usize>(m, n),
    ]);
    let mut mem = scratch(req)?;
    let mut etree = vec![0usize; m];
    let tree = qr::col_etree(bt.as_ref(), Some(perm), &mut etree, MemStack::new(&mut mem));
    let mut post = vec![0usize; m];
    qr::postorder(&mut post, tree, MemStack::new(&mut mem));
    let mut counts = vec![0usize; m];
    let mut min_col = vec![0usize; n];
    qr::column_counts_ata(
        &mut counts,
        &mut min_col,
        b_csc.as_ref(),
        Some(perm),
        tree,
        &post,
        MemStack::new(&mut mem),
    );
    Ok(counts.iter().map(|&c| c as u64).sum())
}

/// Refuses, with the estimate, a factorisation whose `R` alone would not
/// fit in the solve's memory `budget` ([`crate::limits`]).
pub(super) fn check_r_fill(
    b: SparseRowMatRef<'_, usize, f64>,
    perm: Option<&[usize]>,
    what: &str,
    budget: crate::limits::MemoryBudget,
) -> Result<(), Error> {
    let nnz = r_nnz(b, perm)?;
    let bytes = nnz.saturating_mul(R_BYTES_PER_ENTRY);
    budget.check(bytes, || {
        format!(
            "the QR factor R of the {} hard constraints ({what}) has {nnz} entries (R's pattern is that of the Cholesky factor of B Bᵀ) and would need",
            b.nrows()
        )
    })
    .map_err(|detail| ProblemError::TooLarge { detail }.into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::{SparseRowMat, Triplet};

    fn b_of(n: usize, rows: &[&[usize]]) -> SparseRowMat<usize, f64> {
        let t: Vec<Triplet<usize, usize, f64>> = rows
            .iter()
            .enumerate()
            .flat_map(|(i, r)| r.iter().map(move |&u| Triplet::new(i, u, 1.0)))
            .collect();
        SparseRowMat::try_new_from_triplets(rows.len(), n, &t).unwrap()
    }

    #[test]
    fn counts_match_hand_computed_fill() {
        // Separate constraints: R diagonal.
        let b = b_of(4, &[&[0], &[1], &[2, 3]]);
        assert_eq!(r_nnz(b.as_ref(), None).unwrap(), 3);
        // A star of k constraints through unknown 0: B Bᵀ is dense, R has
        // k(k+1)/2 entries in any order.
        let b = b_of(6, &[&[0, 1], &[0, 2], &[0, 3], &[0, 4], &[0, 5]]);
        assert_eq!(r_nnz(b.as_ref(), None).unwrap(), 15);
        assert_eq!(r_nnz(b.as_ref(), Some(&[4, 2, 0, 1, 3])).unwrap(), 15);
        // A chain 0-1-2-3-4: B Bᵀ tridiagonal, R bidiagonal: 4 + 3.
        let b = b_of(5, &[&[0, 1], &[1, 2], &[2, 3], &[3, 4]]);
        assert_eq!(r_nnz(b.as_ref(), None).unwrap(), 7);
        // The same chain in the order 0, 3, 1, 2: eliminating c0 (adjacent
        // c1), c3 (adjacent c2), c1 (adjacent c2), then c2 creates no fill:
        // c2: R rows 0:{0,1}, 3:{3,2}, 1:{1,2}, 2:{2} — 7 entries, no fill.
        assert_eq!(r_nnz(b.as_ref(), Some(&[0, 3, 1, 2])).unwrap(), 7);
    }

    #[test]
    fn order_is_a_permutation_and_none_without_sharing() {
        let b = b_of(4, &[&[0], &[1], &[2, 3]]);
        assert_eq!(fill_reducing_constraint_order(b.as_ref()).unwrap(), None);
        let b = b_of(6, &[&[0, 1], &[1, 2], &[2, 3], &[3, 4], &[4, 5]]);
        let mut p = fill_reducing_constraint_order(b.as_ref()).unwrap().unwrap();
        p.sort_unstable();
        assert_eq!(p, vec![0, 1, 2, 3, 4]);
    }
}
