//! SuiteSparseQR (SPQR) of `Bᵀ` (feature `suitesparse`; links the system's
//! `libspqr` and `libcholmod`).
//!
//! **Call.** One `SuiteSparseQR_C` call on the `n × m` matrix `Bᵀ S` with
//! - `ordering = SPQR_ORDERING_FIXED`: no column permutation, so the columns
//!   (constraints) are processed in list order = priority order;
//! - `S = diag(1/‖b_j‖₂)` (zero columns left as they are) and `tol = η`
//!   ([`RankTolerance`]): SPQR declares a column dead when the 2-norm of what
//!   remains of it in its front is `≤ tol`; on the scaled matrix that is
//!   exactly our relative test `‖remainder of b_j‖ ≤ η ‖b_j‖`;
//! - `econ = 0`: `R` has `rank` rows;
//! - outputs `R`, `E` (the column permutation; `NULL` = identity under the
//!   fixed ordering), and `Q` in Householder form: `H` (`n × nh`, first
//!   entry of each column 1), `HTau` and `HPinv`.
//!
//! `R` comes back "squeezed" upper trapezoidal: dead columns get no row, and
//! row `k`'s leading entry is in the column of the `k`-th live constraint.
//! The kept constraints are read off as those leading columns; `R` is
//! unscaled (`R = R_S S⁻¹`, column `j` times `‖b_j‖`), and `R1` (the kept
//! columns) is stored by columns for `R1ᵀ y = d_kept`.
//!
//! **Q.** `Qᵀ x`: scatter `w[HPinv[i]] = x[i]`, then apply
//! `H_h = I − τ_h h_h h_hᵀ` for `h = 0, 1, …`; `Q [y; z]`: the reverse. This
//! is what SPQR's own `SuiteSparseQR_qmult` does (`spqr_happly`; a unit test
//! checks the two agree). We replay it in Rust because SPQR's C interface
//! applies `Q` only from the opaque object of `SuiteSparseQR_C_factorize`,
//! which does not give `R`, and because its sparse `X Q` works on dense
//! chunks of rows of `X`, `O(l · n)` for `A` — far too slow for `A Q2`.
//! `A Q2` applies the reflectors to sparse columns of `A Pᵀ` (the support of
//! each `h`) and keeps permuted coordinates `r..n`; free direction `t` is
//! associated with the unknown in permuted position `r + t`.
//!
//! **Rank detection versus [`DenseHouseholder`](super::DenseHouseholder).**
//! SPQR's test is Heath's method applied per frontal matrix: the norm tested
//! is what remains of the column within its front after the pivots of its
//! descendants, which equals the dense remainder except when an earlier
//! column was dead: its small leftover entries stay in the contribution
//! block and can perturb later tests by up to `η` (relative). So, as for
//! [`SparseGivens`](super::SparseGivens), decisions agree exactly when
//! dependencies are well separated from the tolerance and can differ within
//! a small factor of it.
//!
//! All FFI is confined to this module; every SPQR/CHOLMOD allocation is held
//! by an owner whose `Drop` frees it; the factorisation itself keeps only
//! Rust vectors.

use std::os::raw::c_int;
use std::ptr;

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef};
use faer::{Mat, MatMut, MatRef};
use suitesparse_sys as ss;

use super::distinct_rows::factor_distinct_rows;
use super::fill::check_r_fill;
use super::graph_rows::factor_graph_rows;
use super::sparse_columns::ColumnWorkspace;
use super::{ConstraintQr, QrBackend, RankTolerance};
use crate::backend::suitesparse::{Common, Long, sparse_header, status_error};
use crate::error::{Error, NumericalError, ProblemError};

const NAME: &str = "spqr";

/// `SPQR_ORDERING_FIXED` from `SuiteSparseQR_definitions.h`.
const SPQR_ORDERING_FIXED: c_int = 0;

#[link(name = "spqr")]
unsafe extern "C" {
    /// `SuiteSparseQR_C.h`: `[Z, R, E, H, HPinv, HTau] = qr(A)`; returns the
    /// rank estimate, or −1 on failure.
    fn SuiteSparseQR_C(
        ordering: c_int,
        tol: f64,
        econ: Long,
        get_ctx: c_int,
        a: *mut ss::cholmod_sparse,
        b_sparse: *mut ss::cholmod_sparse,
        b_dense: *mut ss::cholmod_dense,
        z_sparse: *mut *mut ss::cholmod_sparse,
        z_dense: *mut *mut ss::cholmod_dense,
        r: *mut *mut ss::cholmod_sparse,
        e: *mut *mut Long,
        h: *mut *mut ss::cholmod_sparse,
        hpinv: *mut *mut Long,
        htau: *mut *mut ss::cholmod_dense,
        cc: *mut ss::cholmod_common,
    ) -> Long;
}

#[cfg(test)]
#[link(name = "spqr")]
unsafe extern "C" {
    fn SuiteSparseQR_C_factorize(
        ordering: c_int,
        tol: f64,
        a: *mut ss::cholmod_sparse,
        cc: *mut ss::cholmod_common,
    ) -> *mut std::ffi::c_void;
    fn SuiteSparseQR_C_qmult(
        method: c_int,
        qr: *mut std::ffi::c_void,
        x: *mut ss::cholmod_dense,
        cc: *mut ss::cholmod_common,
    ) -> *mut ss::cholmod_dense;
    fn SuiteSparseQR_C_free(qr: *mut *mut std::ffi::c_void, cc: *mut ss::cholmod_common) -> c_int;
}

/// SuiteSparseQR with fixed column ordering and relative rank tolerance.
#[derive(Debug, Clone, Copy, Default)]
pub struct Spqr;

impl QrBackend for Spqr {
    fn name(&self) -> crate::backend::BackendName {
        super::QrKind::Spqr.name().into()
    }

    fn factor_with(
        &self,
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        resources: &crate::resources::Resources,
    ) -> Result<Box<dyn ConstraintQr>, Error> {
        let budget = resources.budget;
        factor_distinct_rows(b, |b| {
            factor_graph_rows(b, |b| {
                // Fixed ordering: R's fill is that of B Bᵀ in list order.
                check_r_fill(b, None, "spqr, fixed order", budget)?;
                Ok(Box::new(SpqrQr::new(b, tolerance)?) as Box<dyn ConstraintQr>)
            })
        })
    }
}

fn backend_error(message: impl Into<String>) -> Error {
    NumericalError::Backend {
        backend: NAME.to_string(),
        message: message.into(),
    }
    .into()
}

/// `Bᵀ` (n × m) in CHOLMOD's 64-bit CSC layout, columns scaled to unit norm.
struct ScaledBt {
    n: usize,
    m: usize,
    p: Vec<Long>,
    i: Vec<Long>,
    x: Vec<f64>,
    /// `‖b_j‖₂` (1 for an empty column).
    norms: Vec<f64>,
}

impl ScaledBt {
    /// Column `j` of `Bᵀ` is row `j` of `B`: entries sorted by unknown,
    /// duplicates summed, explicit zeros dropped.
    fn new(b: SparseRowMatRef<'_, usize, f64>) -> Result<ScaledBt, Error> {
        let (m, n) = (b.nrows(), b.ncols());
        let (ptr, col, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
        let mut p = Vec::with_capacity(m + 1);
        let mut i = Vec::new();
        let mut x = Vec::new();
        let mut norms = Vec::with_capacity(m);
        let mut entries: Vec<(usize, f64)> = Vec::new();
        p.push(0);
        for j in 0..m {
            entries.clear();
            for q in ptr[j]..ptr[j + 1] {
                if !val[q].is_finite() {
                    return Err(ProblemError::InvalidArgument {
                        message: format!(
                            "hard constraint row {j} has a non-finite coefficient {} on unknown {}",
                            val[q], col[q]
                        ),
                    }
                    .into());
                }
                entries.push((col[q], val[q]));
            }
            entries.sort_unstable_by_key(|e| e.0);
            let start = i.len();
            for &(u, v) in &entries {
                if i.len() > start && *i.last().unwrap_or(&-1) == u as Long {
                    if let Some(last) = x.last_mut() {
                        *last += v;
                    }
                } else {
                    i.push(u as Long);
                    x.push(v);
                }
            }
            // Drop zeros (after summing).
            let mut w = start;
            for q in start..i.len() {
                if x[q] != 0.0 {
                    i[w] = i[q];
                    x[w] = x[q];
                    w += 1;
                }
            }
            i.truncate(w);
            x.truncate(w);
            let norm = x[start..].iter().map(|v| v * v).sum::<f64>().sqrt();
            let norm = if norm > 0.0 { norm } else { 1.0 };
            for v in &mut x[start..] {
                *v /= norm;
            }
            norms.push(norm);
            p.push(i.len() as Long);
        }
        Ok(ScaledBt {
            n,
            m,
            p,
            i,
            x,
            norms,
        })
    }

    /// A `cholmod_sparse` header over the arrays (valid while `self` is
    /// borrowed; SPQR only reads its input).
    fn header(&mut self) -> ss::cholmod_sparse {
        sparse_header(self.n, self.m, &mut self.p, &mut self.i, &mut self.x, 0)
    }
}

/// The outputs of one `SuiteSparseQR_C` call; `Drop` frees them.
struct SpqrOutputs {
    common: Common,
    r: *mut ss::cholmod_sparse,
    e: *mut Long,
    h: *mut ss::cholmod_sparse,
    hpinv: *mut Long,
    htau: *mut ss::cholmod_dense,
    /// Sizes of `e` (columns) and `hpinv` (rows), for freeing.
    m: usize,
    n: usize,
}

impl Drop for SpqrOutputs {
    fn drop(&mut self) {
        let cc = self.common.ptr();
        // SAFETY: each pointer is null or was allocated by SPQR with this
        // common's allocator, and is freed once.
        unsafe {
            if !self.r.is_null() {
                ss::cholmod_l_free_sparse(&mut self.r, cc);
            }
            if !self.h.is_null() {
                ss::cholmod_l_free_sparse(&mut self.h, cc);
            }
            if !self.htau.is_null() {
                ss::cholmod_l_free_dense(&mut self.htau, cc);
            }
            if !self.e.is_null() {
                ss::cholmod_l_free(self.m, std::mem::size_of::<Long>(), self.e.cast(), cc);
                self.e = ptr::null_mut();
            }
            if !self.hpinv.is_null() {
                ss::cholmod_l_free(self.n, std::mem::size_of::<Long>(), self.hpinv.cast(), cc);
                self.hpinv = ptr::null_mut();
            }
        }
    }
}

/// A CSC matrix copied out of a `cholmod_sparse`.
struct Csc {
    nrow: usize,
    ncol: usize,
    p: Vec<usize>,
    i: Vec<usize>,
    x: Vec<f64>,
}

/// Copies a packed or unpacked real `cholmod_sparse`.
///
/// # Safety
/// `a` must be a valid real `cholmod_sparse` with 64-bit indices.
unsafe fn copy_sparse(a: *const ss::cholmod_sparse) -> Result<Csc, Error> {
    // SAFETY: guaranteed by the caller.
    let a = unsafe { &*a };
    if a.xtype != ss::CHOLMOD_REAL as i32 || a.itype != ss::CHOLMOD_LONG as i32 {
        return Err(backend_error("unexpected matrix type from SPQR"));
    }
    let (nrow, ncol) = (a.nrow, a.ncol);
    // SAFETY: p has ncol + 1 entries, nz (if unpacked) ncol, i and x nzmax.
    unsafe {
        let ap = std::slice::from_raw_parts(a.p as *const Long, ncol + 1);
        let anz = if a.packed == 0 {
            Some(std::slice::from_raw_parts(a.nz as *const Long, ncol))
        } else {
            None
        };
        let ai = a.i as *const Long;
        let ax = a.x as *const f64;
        let mut p = Vec::with_capacity(ncol + 1);
        let mut i = Vec::new();
        let mut x = Vec::new();
        p.push(0);
        for j in 0..ncol {
            let start = ap[j] as usize;
            let end = match anz {
                Some(nz) => start + nz[j] as usize,
                None => ap[j + 1] as usize,
            };
            let mut col: Vec<(usize, f64)> = (start..end)
                .map(|q| (*ai.add(q) as usize, *ax.add(q)))
                .collect();
            col.sort_unstable_by_key(|e| e.0);
            for (r, v) in col {
                i.push(r);
                x.push(v);
            }
            p.push(i.len());
        }
        Ok(Csc {
            nrow,
            ncol,
            p,
            i,
            x,
        })
    }
}

/// What SPQR returns, copied out: the rank, `R` (`rank × m`, squeezed),
/// the Householder vectors `H` (`n × nh`) and their `τ`, `HPinv` and the
/// column permutation `E` (identity when SPQR returns none).
struct Factored {
    rank: usize,
    r: Csc,
    h: Csc,
    tau: Vec<f64>,
    hpinv: Vec<usize>,
    e: Vec<usize>,
}

/// Calls `SuiteSparseQR_C` on the scaled `Bᵀ` (`n × m`) with the fixed
/// ordering and `η` ([`RankTolerance::relative`]; the columns have unit
/// norm, so it is relative to each constraint's norm) and copies the
/// results out (SPQR's are freed on return). Errors: SPQR's failure, or
/// results of unexpected shape.
fn factor_scaled(
    bt: &mut ScaledBt,
    tolerance: RankTolerance,
    m: usize,
    n: usize,
) -> Result<Factored, Error> {
    let mut out = SpqrOutputs {
        common: Common::new()?,
        r: ptr::null_mut(),
        e: ptr::null_mut(),
        h: ptr::null_mut(),
        hpinv: ptr::null_mut(),
        htau: ptr::null_mut(),
        m,
        n,
    };
    let mut header = bt.header();
    let cc = out.common.ptr();
    // SAFETY: `header` describes arrays owned by `bt`, alive for the
    // call; outputs are written into `out`, which frees them on drop.
    let rank = unsafe {
        SuiteSparseQR_C(
            SPQR_ORDERING_FIXED,
            tolerance.relative,
            0,
            0,
            &mut header,
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            &mut out.r,
            &mut out.e,
            &mut out.h,
            &mut out.hpinv,
            &mut out.htau,
            cc,
        )
    };
    if rank < 0 || out.r.is_null() || out.h.is_null() || out.htau.is_null() {
        return Err(status_error(NAME, "SuiteSparseQR_C", out.common.status()).into());
    }
    let rank = rank as usize;

    // SAFETY: R and H are valid real sparse matrices returned by SPQR.
    let r = unsafe { copy_sparse(out.r)? };
    let h = unsafe { copy_sparse(out.h)? };
    if r.ncol != m || r.nrow != rank || h.nrow != n {
        return Err(backend_error(format!(
            "unexpected shapes: R {}×{}, H {}×{} (rank {rank}, n {n}, m {m})",
            r.nrow, r.ncol, h.nrow, h.ncol
        )));
    }
    let nh = h.ncol;
    // SAFETY: HTau is 1 × nh dense, HPinv has n entries, E (if any) m.
    let (tau, hpinv, e) = unsafe {
        let t = &*out.htau;
        if (t.nrow as usize) * (t.ncol as usize) < nh {
            return Err(backend_error("HTau too short"));
        }
        let tau = std::slice::from_raw_parts(t.x as *const f64, nh).to_vec();
        let hpinv: Vec<usize> = if out.hpinv.is_null() {
            (0..n).collect()
        } else {
            std::slice::from_raw_parts(out.hpinv, n)
                .iter()
                .map(|&v| v as usize)
                .collect()
        };
        let e: Vec<usize> = if out.e.is_null() {
            (0..m).collect()
        } else {
            std::slice::from_raw_parts(out.e, m)
                .iter()
                .map(|&v| v as usize)
                .collect()
        };
        (tau, hpinv, e)
    };
    drop(out);
    Ok(Factored {
        rank,
        r,
        h,
        tau,
        hpinv,
        e,
    })
}

/// The inverse of `hpinv` (a permutation of `0..n`), checked.
fn inverse_permutation(hpinv: &[usize], n: usize) -> Result<Vec<usize>, Error> {
    let mut perm = vec![usize::MAX; n];
    for (i, &pi) in hpinv.iter().enumerate() {
        if pi >= n || perm[pi] != usize::MAX {
            return Err(backend_error("HPinv is not a permutation"));
        }
        perm[pi] = i;
    }
    Ok(perm)
}

/// The leading column of each row of the squeezed `R` (`rank` rows, `m`
/// columns, rows sorted within columns): strictly increasing, each the
/// last entry of its column (squeezed upper trapezoidal), checked.
fn leading_columns(r: &Csc, rank: usize, m: usize) -> Result<Vec<usize>, Error> {
    let mut lead = vec![usize::MAX; rank];
    for c in 0..m {
        for q in r.p[c]..r.p[c + 1] {
            let row = r.i[q];
            if lead[row] == usize::MAX {
                lead[row] = c;
            }
        }
    }
    for k in 0..rank {
        let ok = lead[k] != usize::MAX
            && (k == 0 || lead[k] > lead[k - 1])
            && r.p[lead[k] + 1] > r.p[lead[k]]
            && r.i[r.p[lead[k] + 1] - 1] == k;
        if !ok {
            return Err(backend_error(format!(
                "R is not squeezed upper trapezoidal at row {k}"
            )));
        }
    }
    Ok(lead)
}

/// The kept constraints and `R1` by columns, unscaled: column `k` of `R1`
/// is column `lead[k]` of `R` times `‖b_j‖` (`norms`) for the constraint
/// `j = E[lead[k]]`.
fn unscaled_r1(
    r: &Csc,
    lead: &[usize],
    e: &[usize],
    norms: &[f64],
) -> (Vec<usize>, Vec<usize>, Vec<usize>, Vec<f64>) {
    let mut kept = Vec::with_capacity(lead.len());
    let mut r1_ptr = vec![0usize];
    let mut r1_row = Vec::new();
    let mut r1_val = Vec::new();
    for &c in lead {
        let j = e[c];
        kept.push(j);
        for q in r.p[c]..r.p[c + 1] {
            r1_row.push(r.i[q]);
            r1_val.push(r.x[q] * norms[j]);
        }
        r1_ptr.push(r1_row.len());
    }
    (kept, r1_ptr, r1_row, r1_val)
}

/// The factorisation produced by [`Spqr`]: `Bᵀ = Q R` with `Q` kept as
/// SPQR's Householder vectors.
#[derive(Debug, Clone)]
pub struct SpqrQr {
    n: usize,
    rank: usize,
    /// Kept constraints in `y` order (= increasing under the fixed ordering).
    kept: Vec<usize>,
    skipped: Vec<usize>,
    /// `R1` by columns: column `k` holds rows `≤ k`, diagonal last.
    r1_ptr: Vec<usize>,
    r1_row: Vec<usize>,
    r1_val: Vec<f64>,
    /// Householder vectors (rows in the permuted order), `τ`.
    h_ptr: Vec<usize>,
    h_row: Vec<usize>,
    h_val: Vec<f64>,
    tau: Vec<f64>,
    /// `hpinv[i]`: permuted position of unknown `i`; `perm` its inverse.
    hpinv: Vec<usize>,
    perm: Vec<usize>,
}

impl SpqrQr {
    /// Factors `Bᵀ` for `b` (m × n, one row per constraint in priority
    /// order).
    ///
    /// Phases: the scaled `Bᵀ`, SPQR's factorisation copied out
    /// ([`factor_scaled`]), `HPinv`'s inverse ([`inverse_permutation`]),
    /// the rows of the squeezed `R` ([`leading_columns`]) and `R1` unscaled
    /// ([`unscaled_r1`]).
    pub fn new(
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
    ) -> Result<SpqrQr, Error> {
        let (m, n) = (b.nrows(), b.ncols());
        let mut bt = ScaledBt::new(b)?;
        if m == 0 || n == 0 || bt.x.is_empty() {
            // Nothing to factor: every constraint is empty (dependent), every
            // unknown free.
            return Ok(SpqrQr::nothing(m, n));
        }
        let Factored {
            rank,
            r,
            h,
            tau,
            hpinv,
            e,
        } = factor_scaled(&mut bt, tolerance, m, n)?;
        let perm = inverse_permutation(&hpinv, n)?;
        if e.iter().any(|&c| c >= m) {
            return Err(backend_error("E is not a permutation"));
        }
        let lead = leading_columns(&r, rank, m)?;
        let (kept, r1_ptr, r1_row, r1_val) = unscaled_r1(&r, &lead, &e, &bt.norms);
        let mut is_kept = vec![false; m];
        for &j in &kept {
            is_kept[j] = true;
        }
        let skipped = (0..m).filter(|&j| !is_kept[j]).collect();
        Ok(SpqrQr {
            n,
            rank,
            kept,
            skipped,
            r1_ptr,
            r1_row,
            r1_val,
            h_ptr: h.p,
            h_row: h.i,
            h_val: h.x,
            tau,
            hpinv,
            perm,
        })
    }

    /// The factorisation of nothing: `m` constraints all skipped, `n`
    /// unknowns all free.
    fn nothing(m: usize, n: usize) -> SpqrQr {
        SpqrQr {
            n,
            rank: 0,
            kept: Vec::new(),
            skipped: (0..m).collect(),
            r1_ptr: vec![0],
            r1_row: Vec::new(),
            r1_val: Vec::new(),
            h_ptr: vec![0],
            h_row: Vec::new(),
            h_val: Vec::new(),
            tau: Vec::new(),
            hpinv: (0..n).collect(),
            perm: (0..n).collect(),
        }
    }

    /// `w ← H_h w` on all columns of `w` (permuted coordinates).
    fn reflect(&self, h: usize, w: &mut Mat<f64>) {
        let range = self.h_ptr[h]..self.h_ptr[h + 1];
        let tau = self.tau[h];
        if tau == 0.0 {
            return;
        }
        for c in 0..w.ncols() {
            let mut s = 0.0;
            for q in range.clone() {
                s += self.h_val[q] * w[(self.h_row[q], c)];
            }
            s *= tau;
            if s != 0.0 {
                for q in range.clone() {
                    w[(self.h_row[q], c)] -= s * self.h_val[q];
                }
            }
        }
    }
}

impl ConstraintQr for SpqrQr {
    fn n(&self) -> usize {
        self.n
    }

    fn rank(&self) -> usize {
        self.rank
    }

    fn kept(&self) -> &[usize] {
        &self.kept
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn solve_r1t(&self, d: MatRef<'_, f64>, mut y: MatMut<'_, f64>) {
        for c in 0..d.ncols() {
            for k in 0..self.rank {
                let range = self.r1_ptr[k]..self.r1_ptr[k + 1];
                let mut s = d[(self.kept[k], c)];
                let mut diag = 0.0;
                for q in range {
                    let h = self.r1_row[q];
                    if h < k {
                        s -= self.r1_val[q] * y[(h, c)];
                    } else {
                        diag = self.r1_val[q];
                    }
                }
                y[(k, c)] = s / diag;
            }
        }
    }

    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, mut x: MatMut<'_, f64>) {
        let k = x.ncols();
        let mut w = Mat::<f64>::zeros(self.n, k);
        for c in 0..k {
            for t in 0..self.rank {
                w[(t, c)] = y[(t, c)];
            }
            for t in 0..self.n - self.rank {
                w[(self.rank + t, c)] = z[(t, c)];
            }
        }
        for h in (0..self.tau.len()).rev() {
            self.reflect(h, &mut w);
        }
        for c in 0..k {
            for (i, &pi) in self.hpinv.iter().enumerate() {
                x[(i, c)] = w[(pi, c)];
            }
        }
    }

    fn apply_qt(&self, x: MatRef<'_, f64>, mut y: MatMut<'_, f64>, mut z: MatMut<'_, f64>) {
        let k = x.ncols();
        let mut w = Mat::<f64>::zeros(self.n, k);
        for c in 0..k {
            for (i, &pi) in self.hpinv.iter().enumerate() {
                w[(pi, c)] = x[(i, c)];
            }
        }
        for h in 0..self.tau.len() {
            self.reflect(h, &mut w);
        }
        for c in 0..k {
            for t in 0..self.rank {
                y[(t, c)] = w[(t, c)];
            }
            for t in 0..self.n - self.rank {
                z[(t, c)] = w[(self.rank + t, c)];
            }
        }
    }

    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        // A Q = (A Pᵀ) H_0 H_1 ⋯ with column HPinv[i] of A Pᵀ = column i of
        // A: work on A's own columns, translating each support to them.
        let mut ws = ColumnWorkspace::new(a);
        let mut support = Vec::new();
        for h in 0..self.tau.len() {
            let range = self.h_ptr[h]..self.h_ptr[h + 1];
            support.clear();
            support.extend(self.h_row[range.clone()].iter().map(|&r| self.perm[r]));
            ws.reflect(&support, &self.h_val[range], self.tau[h]);
        }
        ws.gather(&self.perm[self.rank..])
    }

    fn free_unknown(&self, k: usize) -> usize {
        self.perm.get(self.rank + k).copied().unwrap_or(k)
    }

    fn storage_nnz(&self) -> usize {
        self.h_val.len() + self.tau.len() + self.r1_val.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::{SparseRowMat, Triplet};

    /// `R` (2 × 3) with rows leading at columns 0 and 2:
    /// `[2 1 3; 0 0 4]`.
    fn squeezed() -> Csc {
        Csc {
            nrow: 2,
            ncol: 3,
            p: vec![0, 1, 2, 4],
            i: vec![0, 0, 0, 1],
            x: vec![2.0, 1.0, 3.0, 4.0],
        }
    }

    #[test]
    fn permutation_is_inverted_and_checked() {
        assert_eq!(inverse_permutation(&[2, 0, 1], 3).unwrap(), [1, 2, 0]);
        assert!(inverse_permutation(&[0, 0, 1], 3).is_err());
        assert!(inverse_permutation(&[0, 3, 1], 3).is_err());
    }

    #[test]
    fn leading_columns_of_a_squeezed_r_and_r1_unscaled() {
        let r = squeezed();
        assert_eq!(leading_columns(&r, 2, 3).unwrap(), [0, 2]);
        // E swaps constraints 0 and 2; their norms 10 and 100.
        let (kept, ptr, row, val) = unscaled_r1(&r, &[0, 2], &[2, 1, 0], &[10.0, 1.0, 100.0]);
        assert_eq!((kept, ptr, row), (vec![2, 0], vec![0, 1, 3], vec![0, 0, 1]));
        assert_eq!(val, [200.0, 30.0, 40.0]);
        // Row 1 leading before row 0 is not upper trapezoidal.
        let mut bad = squeezed();
        bad.i = vec![1, 0, 0, 1];
        assert!(leading_columns(&bad, 2, 3).is_err());
    }

    /// Our replay of `(H, τ, HPinv)` equals SPQR's own `SuiteSparseQR_C_qmult`
    /// on a `SuiteSparseQR_C_factorize` object of the same scaled matrix.
    #[test]
    fn householder_replay_matches_spqr_qmult() {
        // 3 constraints on 6 unknowns, the third dependent on the first two.
        let trip = vec![
            Triplet::new(0, 0, 1.0),
            Triplet::new(0, 2, 0.5),
            Triplet::new(1, 1, 1.0),
            Triplet::new(1, 2, -0.3),
            Triplet::new(1, 4, 0.7),
            Triplet::new(2, 0, 2.0),
            Triplet::new(2, 2, 1.0),
            Triplet::new(3, 3, 0.4),
            Triplet::new(3, 5, 0.6),
            Triplet::new(3, 4, 0.2),
        ];
        let b = SparseRowMat::<usize, f64>::try_new_from_triplets(4, 6, &trip).unwrap();
        let tol = RankTolerance::default();
        let qr = SpqrQr::new(b.as_ref(), tol).unwrap();
        assert_eq!(qr.rank(), 3);
        assert_eq!(qr.skipped(), &[2]);

        let n = 6;
        let x = Mat::<f64>::from_fn(n, 2, |i, j| (i as f64 + 1.0) * (j as f64 + 0.5) - 2.0);
        let mut y = Mat::zeros(qr.rank(), 2);
        let mut z = Mat::zeros(n - qr.rank(), 2);
        qr.apply_qt(x.as_ref(), y.as_mut(), z.as_mut());

        let mut bt = ScaledBt::new(b.as_ref()).unwrap();
        let mut header = bt.header();
        let mut common = Common::new().unwrap();
        let cc = common.ptr();
        let xr = &x;
        let mut data: Vec<f64> = (0..2)
            .flat_map(|c| (0..n).map(move |i| xr[(i, c)]))
            .collect();
        unsafe {
            let mut f =
                SuiteSparseQR_C_factorize(SPQR_ORDERING_FIXED, tol.relative, &mut header, cc);
            assert!(!f.is_null());
            let mut xd: ss::cholmod_dense = std::mem::zeroed();
            xd.nrow = n as _;
            xd.ncol = 2;
            xd.nzmax = (2 * n) as _;
            xd.d = n as _;
            xd.x = data.as_mut_ptr().cast();
            xd.xtype = ss::CHOLMOD_REAL as _;
            xd.dtype = ss::CHOLMOD_DOUBLE as _;
            let mut out = SuiteSparseQR_C_qmult(0, f, &mut xd, cc);
            assert!(!out.is_null());
            let o = &*out;
            let ox = o.x as *const f64;
            for c in 0..2 {
                for t in 0..n {
                    let mine = if t < qr.rank() {
                        y[(t, c)]
                    } else {
                        z[(t - qr.rank(), c)]
                    };
                    let theirs = *ox.add(c * o.d as usize + t);
                    assert!((mine - theirs).abs() < 1e-12, "{t},{c}: {mine} vs {theirs}");
                }
            }
            ss::cholmod_l_free_dense(&mut out, cc);
            SuiteSparseQR_C_free(&mut f, cc);
        }
    }
}
