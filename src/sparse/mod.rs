//! Sparse kernels below the formulations and the condition estimator:
//! stacking `[A; s·B]`, products with `Aᵀ` and `Bᵀ`, residuals, symmetric
//! products from a stored lower triangle, and the normal matrix `MᵀM`
//! ([`NormalPattern`]). Pure matrix code: nothing here knows what a mesh, a
//! constraint or a formulation is, so every layer above may import it.

mod normal;

pub use normal::NormalPattern;

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef, SymbolicSparseColMat};
use faer::{Mat, MatMut, MatRef};

/// `[A; s·B]` in CSC form with sorted row indices: `A` (l × n) on top, the
/// rows of `B` (m × n, CSR) scaled by `s` below it (rows `l..l+m`).
pub(crate) fn stack_rows(
    a: SparseColMatRef<'_, usize, f64>,
    b: SparseRowMatRef<'_, usize, f64>,
    s: f64,
) -> SparseColMat<usize, f64> {
    let (l, n, m) = (a.nrows(), a.ncols(), b.nrows());
    let (a_ptr, a_rows, a_val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let (b_ptr, b_cols, b_val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    // Column counts of B.
    let mut b_count = vec![0usize; n + 1];
    for &j in b_cols {
        b_count[j + 1] += 1;
    }
    for j in 0..n {
        b_count[j + 1] += b_count[j];
    }
    let mut bt_rows = vec![0usize; b_cols.len()];
    let mut bt_vals = vec![0.0; b_cols.len()];
    let mut fill = b_count.clone();
    // Rows of B in increasing order, so each column's rows come out sorted.
    for k in 0..m {
        for p in b_ptr[k]..b_ptr[k + 1] {
            let j = b_cols[p];
            bt_rows[fill[j]] = l + k;
            bt_vals[fill[j]] = s * b_val[p];
            fill[j] += 1;
        }
    }
    let nnz = a_rows.len() + b_cols.len();
    let mut col_ptr = Vec::with_capacity(n + 1);
    col_ptr.push(0);
    let mut rows = Vec::with_capacity(nnz);
    let mut vals = Vec::with_capacity(nnz);
    for j in 0..n {
        let range = a_ptr[j]..a_ptr[j + 1];
        // A's rows are sorted within a column by construction of LseProblem
        // (and checked by faer's constructor below).
        rows.extend_from_slice(&a_rows[range.clone()]);
        vals.extend_from_slice(&a_val[range]);
        rows.extend_from_slice(&bt_rows[b_count[j]..b_count[j + 1]]);
        vals.extend_from_slice(&bt_vals[b_count[j]..b_count[j + 1]]);
        col_ptr.push(rows.len());
    }
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(l + m, n, col_ptr, None, rows),
        vals,
    )
}

/// The matrix whose `t`-th column is column `cols[t]` of `a` (rows kept).
pub(crate) fn gather_columns(
    a: SparseColMatRef<'_, usize, f64>,
    cols: &[usize],
) -> SparseColMat<usize, f64> {
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let mut col_ptr = Vec::with_capacity(cols.len() + 1);
    col_ptr.push(0);
    let (mut row_idx, mut values) = (Vec::new(), Vec::new());
    for &j in cols {
        row_idx.extend_from_slice(&rows[ptr[j]..ptr[j + 1]]);
        values.extend_from_slice(&val[ptr[j]..ptr[j + 1]]);
        col_ptr.push(row_idx.len());
    }
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(a.nrows(), cols.len(), col_ptr, None, row_idx),
        values,
    )
}

/// `Aᵀ C` for a sparse `A` (l × n) and a dense `C` (l × k).
pub(crate) fn at_times(a: SparseColMatRef<'_, usize, f64>, c: MatRef<'_, f64>) -> Mat<f64> {
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let mut out = Mat::<f64>::zeros(a.ncols(), c.ncols());
    for col in 0..c.ncols() {
        for j in 0..a.ncols() {
            let mut s = 0.0;
            for p in ptr[j]..ptr[j + 1] {
                s += val[p] * c[(rows[p], col)];
            }
            out[(j, col)] = s;
        }
    }
    out
}

/// `Aᵀ (C − A X)` for a sparse `A` (l × n) and dense `C` (l × k), `X`
/// (n × k): the gradient of `½‖A X − C‖²` (negated) computed from the
/// residual of the original rows, never as `AᵀC − AᵀA X`
/// ([`mt_residual`] with `M = A`).
pub(crate) fn at_residual(
    a: SparseColMatRef<'_, usize, f64>,
    c: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Mat<f64> {
    mt_residual(a, a, None, c, x)
}

/// `Mᵀ (C − A X)` for sparse `M` (l × p) and `A`, dense `C` (l × k) and `X`
/// (n × k), where `a` holds the columns of `A` at which `X` can be
/// non-zero: column `t` of `a` is column `unknowns[t]` of `A` (all of `A`
/// in order when `unknowns` is `None`). The columns are taken
/// [`AT_RESIDUAL_WIDTH`] at a time, row-major (a row of `C − A X` is one
/// 32-byte block, and a block's residual for a mesh of 35 k vertices stays
/// in a core's L2 cache): per block a scatter pass over `a` for
/// `C − A X` and a dot product per column of `M` for `Mᵀ r`. Several
/// blocks run on separate threads; a single block (three coordinates)
/// splits its `Mᵀ r` pass over columns of `M` instead.
pub(crate) fn mt_residual(
    m: SparseColMatRef<'_, usize, f64>,
    a: SparseColMatRef<'_, usize, f64>,
    unknowns: Option<&[usize]>,
    c: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Mat<f64> {
    let k = c.ncols();
    let block = |c0: usize, split: bool| {
        let width = AT_RESIDUAL_WIDTH.min(k - c0);
        let r = residual_rows(a, unknowns, c.subcols(c0, width), x.subcols(c0, width));
        at_rows(m, &r, split)
    };
    let starts: Vec<usize> = (0..k).step_by(AT_RESIDUAL_WIDTH).collect();
    let mut blocks: Vec<Vec<Row>> = vec![Vec::new(); starts.len()];
    if let [only] = starts[..] {
        blocks[0] = block(only, true);
    } else {
        // The first block on this thread, the others on the pool
        // (`in_place_scope`: see the faer back end's wide solve).
        let (first, rest) = blocks.split_at_mut(1);
        rayon::in_place_scope(|scope| {
            for (out, &c0) in rest.iter_mut().zip(&starts[1..]) {
                scope.spawn(move |_| *out = block(c0, false));
            }
            first[0] = block(0, false);
        });
    }
    let mut out = Mat::<f64>::zeros(m.ncols(), k);
    for (g, &c0) in blocks.iter().zip(&starts) {
        for col in 0..AT_RESIDUAL_WIDTH.min(k - c0) {
            for (o, row) in out.col_mut(c0 + col).iter_mut().zip(g) {
                *o = row[col];
            }
        }
    }
    out
}

/// Right-hand-side columns per block of [`at_residual`] (unused columns
/// are zero).
const AT_RESIDUAL_WIDTH: usize = 4;

/// Columns of `A` per parallel task of a split `Aᵀ r` pass.
const AT_RESIDUAL_MIN_LEN: usize = 2048;

/// A row of up to [`AT_RESIDUAL_WIDTH`] columns.
type Row = [f64; AT_RESIDUAL_WIDTH];

/// The rows of `m` (at most [`AT_RESIDUAL_WIDTH`] columns) as [`Row`]s.
fn row_major(m: MatRef<'_, f64>) -> Vec<Row> {
    let mut rows = vec![[0.0; AT_RESIDUAL_WIDTH]; m.nrows()];
    for col in 0..m.ncols() {
        match m.col(col).try_as_col_major() {
            Some(column) => {
                for (row, &v) in rows.iter_mut().zip(column.as_slice()) {
                    row[col] = v;
                }
            }
            None => {
                for (row, &v) in rows.iter_mut().zip(m.col(col).iter()) {
                    row[col] = v;
                }
            }
        }
    }
    rows
}

/// `C − A X` row-major, for at most [`AT_RESIDUAL_WIDTH`] columns, over
/// the columns `a` of `A` (see [`mt_residual`]).
fn residual_rows(
    a: SparseColMatRef<'_, usize, f64>,
    unknowns: Option<&[usize]>,
    c: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Vec<Row> {
    crate::cpu::clear_upper_vector_state();
    let mut r = row_major(c);
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let x_rows = row_major(x);
    for j in 0..a.ncols() {
        let xj = &x_rows[unknowns.map_or(j, |u| u[j])];
        for (&i, &v) in rows[ptr[j]..ptr[j + 1]]
            .iter()
            .zip(&val[ptr[j]..ptr[j + 1]])
        {
            let ri = &mut r[i];
            for col in 0..AT_RESIDUAL_WIDTH {
                ri[col] -= v * xj[col];
            }
        }
    }
    r
}

/// `Aᵀ r` row-major for a row-major `r` (l rows), split over columns of
/// `A` on the pool when `split`.
fn at_rows(a: SparseColMatRef<'_, usize, f64>, r: &[Row], split: bool) -> Vec<Row> {
    use rayon::prelude::*;
    let (ptr, rows, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    let dot = |j: usize, gj: &mut Row| {
        for (&i, &v) in rows[ptr[j]..ptr[j + 1]]
            .iter()
            .zip(&val[ptr[j]..ptr[j + 1]])
        {
            let ri = &r[i];
            for col in 0..AT_RESIDUAL_WIDTH {
                gj[col] += v * ri[col];
            }
        }
    };
    let mut g = vec![[0.0; AT_RESIDUAL_WIDTH]; a.ncols()];
    if split {
        g.par_iter_mut()
            .enumerate()
            .with_min_len(AT_RESIDUAL_MIN_LEN)
            .for_each_init(crate::cpu::clear_upper_vector_state, |(), (j, gj)| {
                dot(j, gj)
            });
    } else {
        crate::cpu::clear_upper_vector_state();
        for (j, gj) in g.iter_mut().enumerate() {
            dot(j, gj);
        }
    }
    g
}

/// `D − B X` for a sparse `B` (m × n, CSR) and dense `D` (m × k), `X`
/// (n × k).
pub(crate) fn hard_residual(
    b: SparseRowMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Mat<f64> {
    let (ptr, cols, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    Mat::from_fn(b.nrows(), d.ncols(), |k, col| {
        let mut s = d[(k, col)];
        for p in ptr[k]..ptr[k + 1] {
            s -= val[p] * x[(cols[p], col)];
        }
        s
    })
}

/// [`hard_residual`] as if evaluated in twice the working precision and
/// rounded once (the products split exactly by a fused multiply–add, the
/// sums compensated: Ogita, Rump & Oishi's Dot2). A row with a small
/// remainder amplifies its rounding in the solution by the inverse of that
/// remainder, and reproduces the same rounding when its residual is
/// evaluated in working precision — where the residual reads zero; this
/// one sees it.
pub(crate) fn hard_residual_compensated(
    b: SparseRowMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Mat<f64> {
    let (ptr, cols, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    Mat::from_fn(b.nrows(), d.ncols(), |k, col| {
        let (mut s, mut e) = (d[(k, col)], 0.0);
        for p in ptr[k]..ptr[k + 1] {
            let (a, y) = (-val[p], x[(cols[p], col)]);
            let product = a * y;
            let product_error = a.mul_add(y, -product);
            let sum = s + product;
            let bb = sum - s;
            e += (s - (sum - bb)) + (product - bb) + product_error;
            s = sum;
        }
        s + e
    })
}

/// `out += s · Bᵀ D` for a sparse `B` (m × n, CSR) and a dense `D` (m × k).
pub(crate) fn add_bt_times(
    b: SparseRowMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
    s: f64,
    mut out: MatMut<'_, f64>,
) {
    let (ptr, cols, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    for col in 0..d.ncols() {
        for k in 0..b.nrows() {
            let dk = s * d[(k, col)];
            if dk != 0.0 {
                for p in ptr[k]..ptr[k + 1] {
                    out[(cols[p], col)] += val[p] * dk;
                }
            }
        }
    }
}

/// `y = N x` for the symmetric `N` whose lower triangle `lower` (CSC,
/// diagonal included) is stored.
pub(crate) fn lower_sym_mul(
    lower: SparseColMatRef<'_, usize, f64>,
    x: MatRef<'_, f64>,
    mut y: MatMut<'_, f64>,
) {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    y.fill(0.0);
    for col in 0..x.ncols() {
        for j in 0..lower.ncols() {
            let xj = x[(j, col)];
            let mut acc = 0.0;
            for p in ptr[j]..ptr[j + 1] {
                let (i, v) = (rows[p], val[p]);
                if i == j {
                    acc += v * xj;
                } else {
                    // N[i, j] = N[j, i] = v.
                    y[(i, col)] += v * xj;
                    acc += v * x[(i, col)];
                }
            }
            y[(j, col)] += acc;
        }
    }
}

/// `y = |N| x` (entrywise absolute values of `N`) for the symmetric `N`
/// whose lower triangle is stored.
pub(crate) fn lower_sym_abs_mul(
    lower: SparseColMatRef<'_, usize, f64>,
    x: MatRef<'_, f64>,
    y: MatMut<'_, f64>,
) {
    let abs: Vec<f64> = lower.val().iter().map(|v| v.abs()).collect();
    lower_sym_mul(SparseColMatRef::new(lower.symbolic(), &abs), x, y);
}

/// The largest number of stored entries in a row of the full symmetric
/// matrix whose lower triangle is `lower`.
pub(crate) fn lower_sym_max_row_nnz(lower: SparseColMatRef<'_, usize, f64>) -> usize {
    let (ptr, rows) = (lower.symbolic().col_ptr(), lower.symbolic().row_idx());
    let mut count = vec![0usize; lower.ncols()];
    for j in 0..lower.ncols() {
        for &i in &rows[ptr[j]..ptr[j + 1]] {
            count[j] += 1;
            if i != j {
                count[i] += 1;
            }
        }
    }
    count.into_iter().max().unwrap_or(0)
}

/// `‖N‖∞` (largest absolute row sum) of the symmetric `N` given by its lower
/// triangle.
pub(crate) fn lower_sym_norm_inf(lower: SparseColMatRef<'_, usize, f64>) -> f64 {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let mut sums = vec![0.0f64; lower.ncols()];
    for j in 0..lower.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            let i = rows[p];
            sums[j] += val[p].abs();
            if i != j {
                sums[i] += val[p].abs();
            }
        }
    }
    sums.into_iter().fold(0.0, f64::max)
}

/// The full symmetric matrix (both triangles, sorted rows) of the lower
/// triangle `lower`.
pub(crate) fn lower_to_full(lower: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
    let n = lower.ncols();
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    // Column j of the full matrix: the strictly upper part (row i < j) comes
    // from column i of the lower triangle (entry (j, i)), then column j of
    // the lower triangle.
    let mut count = vec![0usize; n + 1];
    for j in 0..n {
        for &i in &rows[ptr[j]..ptr[j + 1]] {
            count[i + 1] += 1;
            if i != j {
                count[j + 1] += 1;
            }
        }
    }
    for j in 0..n {
        count[j + 1] += count[j];
    }
    let nnz = count[n];
    let mut out_rows = vec![0usize; nnz];
    let mut out_vals = vec![0.0; nnz];
    let mut fill = count.clone();
    // Upper part first: iterating source columns i in increasing order puts
    // rows i in increasing order in every target column.
    for i in 0..n {
        for p in ptr[i]..ptr[i + 1] {
            let j = rows[p];
            if j != i {
                // lower entry (j, i) → upper entry (i, j) in column j.
                out_rows[fill[j]] = i;
                out_vals[fill[j]] = val[p];
                fill[j] += 1;
            }
        }
    }
    for j in 0..n {
        for p in ptr[j]..ptr[j + 1] {
            out_rows[fill[j]] = rows[p];
            out_vals[fill[j]] = val[p];
            fill[j] += 1;
        }
    }
    SparseColMat::new(
        SymbolicSparseColMat::new_checked(n, n, count, None, out_rows),
        out_vals,
    )
}

/// The vertices of hard row `k` of `B` with their coefficients.
pub(crate) fn row_entries(b: SparseRowMatRef<'_, usize, f64>, k: usize) -> (&[usize], &[f64]) {
    let range = b.symbolic().row_range(k);
    (&b.symbolic().col_idx()[range.clone()], &b.val()[range])
}

/// The diagonal entry `N[j, j]` of a lower triangle with sorted rows (0 if
/// absent).
pub(crate) fn lower_diag(lower: SparseColMatRef<'_, usize, f64>, j: usize) -> f64 {
    let (ptr, rows, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let range = ptr[j]..ptr[j + 1];
    match rows[range.clone()].binary_search(&j) {
        Ok(p) => val[range.start + p],
        Err(_) => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::{SparseRowMat, SymbolicSparseRowMat, Triplet};

    fn small() -> (SparseColMat<usize, f64>, SparseRowMat<usize, f64>) {
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(
            3,
            3,
            &[
                Triplet::new(0, 0, 2.0),
                Triplet::new(1, 0, -1.0),
                Triplet::new(1, 1, 3.0),
                Triplet::new(2, 2, 1.5),
                Triplet::new(0, 2, 0.5),
            ],
        )
        .unwrap();
        let b = SparseRowMat::new(
            SymbolicSparseRowMat::new_checked(2, 3, vec![0, 1, 3], None, vec![1, 0, 2]),
            vec![1.0, 0.3, 0.7],
        );
        (a, b)
    }

    #[test]
    fn stacking_and_products_match_dense() {
        let (a, b) = small();
        let m = stack_rows(a.as_ref(), b.as_ref(), 2.0);
        let dense = m.to_dense();
        let (ad, bd) = (a.to_dense(), b.to_dense());
        for i in 0..3 {
            for j in 0..3 {
                assert_eq!(dense[(i, j)], ad[(i, j)]);
            }
        }
        for k in 0..2 {
            for j in 0..3 {
                assert_eq!(dense[(3 + k, j)], 2.0 * bd[(k, j)]);
            }
        }
        let c = Mat::from_fn(3, 2, |i, j| (i + 2 * j) as f64 - 1.0);
        let atc = at_times(a.as_ref(), c.as_ref());
        let expected = ad.transpose() * &c;
        assert!((atc - expected).norm_max() < 1e-15);
        let d = Mat::from_fn(2, 2, |i, j| (i * 3 + j) as f64 + 0.5);
        let mut out = Mat::<f64>::zeros(3, 2);
        add_bt_times(b.as_ref(), d.as_ref(), 3.0, out.as_mut());
        let expected = bd.transpose() * &d * faer::Scale(3.0);
        assert!((out - expected).norm_max() < 1e-15);
    }

    #[test]
    fn symmetric_helpers_match_dense() {
        let lower = SparseColMat::<usize, f64>::try_new_from_triplets(
            3,
            3,
            &[
                Triplet::new(0, 0, 4.0),
                Triplet::new(2, 0, -1.0),
                Triplet::new(1, 1, 5.0),
                Triplet::new(2, 1, 2.0),
                Triplet::new(2, 2, 6.0),
            ],
        )
        .unwrap();
        let full = lower_to_full(lower.as_ref());
        let fd = full.to_dense();
        assert!((fd.clone() - fd.transpose()).norm_max() == 0.0);
        assert_eq!(fd[(0, 2)], -1.0);
        assert_eq!(fd[(1, 2)], 2.0);
        let x = Mat::from_fn(3, 1, |i, _| i as f64 + 1.0);
        let mut y = Mat::zeros(3, 1);
        lower_sym_mul(lower.as_ref(), x.as_ref(), y.as_mut());
        assert!((y - &fd * &x).norm_max() < 1e-15);
        assert_eq!(lower_sym_norm_inf(lower.as_ref()), 9.0);
        assert_eq!(lower_diag(lower.as_ref(), 1), 5.0);
    }
}
