//! Conversions between faer's sparse matrices (what this crate computes
//! with) and those of `sprs` and `nalgebra-sparse`, so that a problem or a
//! factored matrix can be handed to other Rust code.
//!
//! All conversions copy; none changes a value. Invariants on the way out:
//! compressed-column (or row, where said) storage with sorted, unique
//! indices; explicitly stored zeros are kept; duplicate entries of an
//! unsorted faer input (which faer's unsorted constructors permit) are
//! summed. Shapes are preserved, including empty rows and columns.

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef, SymbolicSparseColMat};
use nalgebra_sparse::CscMatrix;
use sprs::{CsMat, CsMatView};

/// Column `j` of a faer CSC matrix as sorted `(row, value)` pairs with
/// duplicates summed.
fn sorted_column(m: SparseColMatRef<'_, usize, f64>, j: usize) -> Vec<(usize, f64)> {
    let range = m.symbolic().col_range(j);
    let rows = &m.symbolic().row_idx()[range.clone()];
    let vals = &m.val()[range];
    let mut pairs: Vec<(usize, f64)> = rows.iter().copied().zip(vals.iter().copied()).collect();
    if !pairs.windows(2).all(|w| w[0].0 < w[1].0) {
        pairs.sort_by_key(|p| p.0);
        pairs.dedup_by(|later, earlier| {
            if later.0 == earlier.0 {
                earlier.1 += later.1;
                true
            } else {
                false
            }
        });
    }
    pairs
}

/// Compressed arrays (pointers, indices, values) of a faer CSC matrix with
/// sorted unique row indices.
fn csc_arrays(m: SparseColMatRef<'_, usize, f64>) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let mut ptr = Vec::with_capacity(m.ncols() + 1);
    ptr.push(0);
    let mut idx = Vec::with_capacity(m.val().len());
    let mut val = Vec::with_capacity(m.val().len());
    for j in 0..m.ncols() {
        for (i, v) in sorted_column(m, j) {
            idx.push(i);
            val.push(v);
        }
        ptr.push(idx.len());
    }
    (ptr, idx, val)
}

/// faer CSC → `sprs::CsMat` in CSC storage.
pub(crate) fn faer_to_sprs(m: SparseColMatRef<'_, usize, f64>) -> CsMat<f64> {
    let (ptr, idx, val) = csc_arrays(m);
    // Sorted unique indices within bounds by construction: cannot fail.
    CsMat::try_new_csc((m.nrows(), m.ncols()), ptr, idx, val)
        .unwrap_or_else(|e| unreachable!("valid CSC arrays rejected by sprs: {:?}", e.3))
}

/// faer CSR (e.g. the constraint matrix `B`) → `sprs::CsMat` in CSR
/// storage.
pub fn faer_rows_to_sprs(m: SparseRowMatRef<'_, usize, f64>) -> CsMat<f64> {
    // The transpose of a CSR matrix is a CSC matrix with the same arrays.
    let t = faer_to_sprs(m.transpose());
    t.transpose_into()
}

/// `sprs::CsMat` (CSC or CSR storage) → faer CSC.
pub fn sprs_to_faer(m: CsMatView<'_, f64>) -> SparseColMat<usize, f64> {
    let csc;
    let m = if m.is_csc() {
        m
    } else {
        csc = m.to_csc();
        csc.view()
    };
    let (nrows, ncols) = m.shape();
    let mut ptr = Vec::with_capacity(ncols + 1);
    ptr.push(0);
    let mut idx = Vec::with_capacity(m.nnz());
    let mut val = Vec::with_capacity(m.nnz());
    for col in m.outer_iterator() {
        // sprs keeps indices sorted and unique within an outer slice.
        idx.extend_from_slice(col.indices());
        val.extend_from_slice(col.data());
        ptr.push(idx.len());
    }
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(nrows, ncols, ptr, None, idx),
        val,
    )
}

/// faer CSC → `nalgebra_sparse::CscMatrix`.
pub fn faer_to_nalgebra(m: SparseColMatRef<'_, usize, f64>) -> CscMatrix<f64> {
    let (ptr, idx, val) = csc_arrays(m);
    CscMatrix::try_from_csc_data(m.nrows(), m.ncols(), ptr, idx, val)
        .unwrap_or_else(|e| unreachable!("valid CSC arrays rejected by nalgebra-sparse: {e}"))
}

/// `nalgebra_sparse::CscMatrix` → faer CSC.
pub fn nalgebra_to_faer(m: &CscMatrix<f64>) -> SparseColMat<usize, f64> {
    // CscMatrix guarantees sorted unique row indices and offsets from 0.
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(
            m.nrows(),
            m.ncols(),
            m.col_offsets().to_vec(),
            None,
            m.row_indices().to_vec(),
        ),
        m.values().to_vec(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::{SparseRowMat, SymbolicSparseRowMat, Triplet};

    fn sample() -> SparseColMat<usize, f64> {
        // 4 × 5 with an empty column (3), an empty row (2) and an explicit
        // zero at (1, 4).
        SparseColMat::try_new_from_triplets(
            4,
            5,
            &[
                Triplet::new(0, 0, 1.5),
                Triplet::new(3, 0, -2.0),
                Triplet::new(1, 1, 1e-300),
                Triplet::new(0, 2, 7.25),
                Triplet::new(3, 2, 1e300),
                Triplet::new(1, 4, 0.0),
            ],
        )
        .unwrap()
    }

    fn same(x: &SparseColMat<usize, f64>, y: &SparseColMat<usize, f64>) {
        assert_eq!((x.nrows(), x.ncols()), (y.nrows(), y.ncols()));
        assert_eq!(x.symbolic().col_ptr(), y.symbolic().col_ptr());
        assert_eq!(x.symbolic().row_idx(), y.symbolic().row_idx());
        assert_eq!(x.val(), y.val());
    }

    #[test]
    fn sprs_round_trip() {
        let m = sample();
        let s = faer_to_sprs(m.as_ref());
        assert!(s.is_csc());
        assert_eq!(s.shape(), (4, 5));
        assert_eq!(s.nnz(), 6);
        assert_eq!(s.get(3, 2), Some(&1e300));
        assert_eq!(s.get(1, 4), Some(&0.0));
        same(&sprs_to_faer(s.view()), &m);
        // Through CSR storage.
        let csr = s.to_csr();
        same(&sprs_to_faer(csr.view()), &m);
    }

    #[test]
    fn nalgebra_round_trip() {
        let m = sample();
        let n = faer_to_nalgebra(m.as_ref());
        assert_eq!((n.nrows(), n.ncols(), n.nnz()), (4, 5, 6));
        assert_eq!(n.col(2).values(), &[7.25, 1e300]);
        same(&nalgebra_to_faer(&n), &m);
    }

    #[test]
    fn rows_and_unsorted_inputs() {
        let b = SparseRowMat::new(
            SymbolicSparseRowMat::new_checked(2, 3, vec![0, 1, 3], None, vec![2, 0, 1]),
            vec![1.0, 0.25, 0.75],
        );
        let s = faer_rows_to_sprs(b.as_ref());
        assert!(s.is_csr());
        assert_eq!(s.get(0, 2), Some(&1.0));
        assert_eq!(s.get(1, 1), Some(&0.75));
        // An unsorted faer column with a duplicate: sorted and summed.
        let u = SparseColMat::new(
            SymbolicSparseColMat::new_unsorted_checked(3, 1, vec![0, 3], None, vec![2, 0, 2]),
            vec![1.0, 2.0, 3.0],
        );
        let n = faer_to_nalgebra(u.as_ref());
        assert_eq!(n.row_indices(), &[0, 2]);
        assert_eq!(n.values(), &[2.0, 4.0]);
    }
}
