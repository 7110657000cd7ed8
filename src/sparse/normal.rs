//! The normal matrix `MᵀM` of a sparse `M`, lower triangle only, with the
//! symbolic (pattern) and numeric (values) phases kept apart so that a new
//! `M` with the same pattern (a new weight) reuses the pattern.
//!
//! Column `j` of `N = MᵀM` is `N[i, j] = Σ_r M[r, i] M[r, j]`: for every row
//! `r` in column `j` of `M`, every entry `M[r, i]` with `i ≥ j` of that row
//! contributes. Rows of `M` are read from its transpose (CSR view), built
//! once. Work: `½ Σ_r nnz(row r)²`.

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};

/// The pattern of the lower triangle of `MᵀM` plus the row-major copy of
/// `M`'s pattern used to fill it.
#[derive(Debug, Clone)]
pub struct NormalPattern {
    lower: SymbolicSparseColMat<usize>,
}

impl NormalPattern {
    /// Symbolic phase: the sorted pattern of `tril(MᵀM)` (diagonal always
    /// present, even for an empty column of `M`).
    pub fn new(m: SparseColMatRef<'_, usize, f64>) -> NormalPattern {
        let k = m.ncols();
        let rows_of = RowView::new(m);
        let (m_ptr, m_rows) = (m.symbolic().col_ptr(), m.symbolic().row_idx());
        let mut mark = vec![usize::MAX; k];
        let mut col_ptr = Vec::with_capacity(k + 1);
        col_ptr.push(0);
        let mut row_idx = Vec::new();
        for j in 0..k {
            let start = row_idx.len();
            mark[j] = j;
            row_idx.push(j);
            for &r in &m_rows[m_ptr[j]..m_ptr[j + 1]] {
                for &i in rows_of.cols_from(r, j) {
                    if mark[i] != j {
                        mark[i] = j;
                        row_idx.push(i);
                    }
                }
            }
            row_idx[start..].sort_unstable();
            col_ptr.push(row_idx.len());
        }
        NormalPattern {
            lower: SymbolicSparseColMat::new_checked(k, k, col_ptr, None, row_idx),
        }
    }

    /// The pattern.
    pub fn symbolic(&self) -> &SymbolicSparseColMat<usize> {
        &self.lower
    }

    /// Entries of the full symmetric matrix (`2 nnz(tril) − n`).
    pub(crate) fn full_nnz(&self) -> usize {
        2 * self.lower.row_idx().len() - self.lower.ncols()
    }

    /// Numeric phase: `tril(MᵀM)` for an `M` with the pattern analysed.
    pub fn numeric(&self, m: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        let k = m.ncols();
        let rows_of = RowView::new(m);
        let (m_ptr, m_rows, m_val) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
        let (n_ptr, n_rows) = (self.lower.col_ptr(), self.lower.row_idx());
        let mut values = vec![0.0; n_rows.len()];
        let mut acc = vec![0.0; k];
        for j in 0..k {
            for p in m_ptr[j]..m_ptr[j + 1] {
                let (r, mrj) = (m_rows[p], m_val[p]);
                let (cols, vals) = rows_of.entries_from(r, j);
                for (&i, &mri) in cols.iter().zip(vals) {
                    acc[i] += mri * mrj;
                }
            }
            for q in n_ptr[j]..n_ptr[j + 1] {
                let i = n_rows[q];
                values[q] = acc[i];
                acc[i] = 0.0;
            }
        }
        SparseColMat::new(self.lower.clone(), values)
    }
}

/// Row-major (CSR) copy of a CSC matrix: for each row, its columns
/// increasing, with values.
struct RowView {
    ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
}

impl RowView {
    fn new(m: SparseColMatRef<'_, usize, f64>) -> RowView {
        let l = m.nrows();
        let (m_ptr, m_rows, m_val) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
        let mut ptr = vec![0usize; l + 1];
        for &r in m_rows {
            ptr[r + 1] += 1;
        }
        for r in 0..l {
            ptr[r + 1] += ptr[r];
        }
        let mut fill = ptr.clone();
        let mut cols = vec![0usize; m_rows.len()];
        let mut vals = vec![0.0; m_rows.len()];
        for j in 0..m.ncols() {
            for p in m_ptr[j]..m_ptr[j + 1] {
                let r = m_rows[p];
                cols[fill[r]] = j;
                vals[fill[r]] = m_val[p];
                fill[r] += 1;
            }
        }
        RowView { ptr, cols, vals }
    }

    /// Columns `≥ j` of row `r` (columns are increasing within a row).
    fn cols_from(&self, r: usize, j: usize) -> &[usize] {
        let row = &self.cols[self.ptr[r]..self.ptr[r + 1]];
        &row[row.partition_point(|&c| c < j)..]
    }

    fn entries_from(&self, r: usize, j: usize) -> (&[usize], &[f64]) {
        let (a, b) = (self.ptr[r], self.ptr[r + 1]);
        let row = &self.cols[a..b];
        let s = row.partition_point(|&c| c < j);
        (&row[s..], &self.vals[a + s..b])
    }
}
