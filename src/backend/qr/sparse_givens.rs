//! Row-by-row Givens QR of the whole sparse `Bᵀ` in the manner of George &
//! Heath (1980), with Heath's rank test.
//!
//! **Shapes.** `Bᵀ` is `n × m`: row `u` is unknown `u` (a mesh vertex), column
//! `j` is constraint `j`, and the column order is the priority order (the
//! list order). `R` is `m × m` upper triangular, stored by rows; row `j` of
//! `R` has its leading entry in column `j` or is empty.
//!
//! **Factorisation.** The rows of `Bᵀ` enter one at a time (see
//! [`GivensRowOrder`]). An incoming row `a` is reduced left to right. Let `j`
//! be the column of its leading nonzero `a_j`:
//! - if row `j` of `R` is occupied (leading entry `ρ = R_jj ≠ 0`), a rotation
//!   with `c = ρ/h`, `s = a_j/h`, `h = hypot(ρ, a_j)` maps the pair
//!   `(R_j, a)` to `(c R_j + s a, −s R_j + c a)`, which zeroes `a_j` exactly;
//! - if row `j` of `R` is empty and `|a_j| > η ‖b_j‖₂` ([`RankTolerance`]),
//!   `a` becomes row `j` of `R`;
//! - if row `j` of `R` is empty and `|a_j| ≤ η ‖b_j‖₂`, the entry is
//!   numerically zero and is **dropped** (Heath's test: a negligible entry may
//!   not occupy a pivot), and the reduction continues with the next nonzero.
//!
//! A row that reduces to nothing is a **free direction** associated with its
//! unknown. At the end the columns whose `R` row stayed empty are the
//! **skipped** (dependent) constraints; the others are kept, in increasing
//! order (= priority order). Unknowns that no constraint touches are free
//! without any work.
//!
//! **Q.** Each rotation acts on two row slots `(p, q)` of the `n`-dimensional
//! unknown space (`p` holds row `j` of `R`, `q` the incoming row):
//! `Qᵀ = G_T ⋯ G_1`. After the last rotation, `Qᵀ Bᵀ` holds row `j` of `R` in
//! the slot of the unknown that first occupied it and zero rows in the free
//! slots. The coordinates are `y_k` = slot of the `k`-th kept constraint and
//! `z_t` = the `t`-th free unknown (increasing), so `x = Q [y; z]`
//! scatters `y, z` to their slots and applies `G_Tᵀ, …, G_1ᵀ`, and `A Q2`
//! applies the rotations to columns of `A` from the right
//! (`[A_p, A_q] ← [c A_p + s A_q, −s A_p + c A_q]`, in order) and keeps the
//! free slots — on sparse columns, never forming `Q`.
//!
//! **Agreement with [`DenseHouseholder`](super::DenseHouseholder).** In exact
//! arithmetic `|R_jj|` is the norm of what remains of constraint `j` after
//! projecting out the earlier kept ones, for any row order, and an entry
//! arriving at an empty row `j` is exactly zero iff that remainder is zero; so
//! both methods keep the same constraints. In floating point they can differ
//! only near the tolerance:
//! - Heath's test looks at one arriving entry at a time, the dense test at the
//!   norm of the whole remainder. A constraint whose remainder `ρ` exceeds
//!   `η ‖b_j‖` but is spread over `k` arriving entries each below it is
//!   skipped here and kept there; this needs `ρ ≤ √k · η ‖b_j‖`.
//! - A dropped entry (at most `η ‖b_j‖` in size) is lost. If column `j` is
//!   later occupied after all (a small genuine coefficient, not rounding
//!   noise), `B_kept Q2` is off by up to that amount in row `j`, not by
//!   rounding, and the decisions for later columns see a perturbation of the
//!   same size.
//!
//! On inputs whose dependencies are well separated from the tolerance (exact
//! duplicates and combinations leave remainders of `O(ε)`, independent ones
//! of `O(‖b_j‖)`) both return exactly the same rank and skipped set.
//!
//! **Cost.** Work and storage follow the fill of `R`, whose pattern is that
//! of the Cholesky factor of `B Bᵀ` in priority order (independent of the row
//! order), plus the intermediate fill of the incoming rows, which the row
//! order controls. Separate position constraints cost `O(1)` each (no
//! rotation at all), so "fix a region, drag a handle" factors in `O(nnz(B))`
//! and `A Q2` is `A` without the fixed columns. Constraints linking a
//! connected region cost about `Σ_j nnz(R_j)²` flops in the worst case and
//! `A Q2` densifies within the region along the rotations.

use faer::sparse::{SparseColMat, SparseColMatRef, SparseRowMatRef};
use faer::{MatMut, MatRef};

use super::distinct_rows::factor_distinct_rows;
use super::fill::{check_r_fill, fill_reducing_constraint_order};
use super::givens_merge::rotate_merge;
use super::graph_rows::factor_graph_rows;
use super::sparse_columns::ColumnWorkspace;
use super::{ConstraintQr, QrBackend, RankTolerance};
use crate::error::{Error, ProblemError};
use crate::limits::MemoryBudget;

/// The order in which the rows of `Bᵀ` (the unknowns touched by
/// constraints) are rotated into `R`. It does not change `R`'s final pattern
/// (that is fixed by the priority order of the columns) nor, in exact
/// arithmetic, which constraints are kept; it changes the intermediate fill,
/// hence the work and the number of stored rotations.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum GivensRowOrder {
    /// By the index of the row's leading constraint (its first nonzero
    /// column), ties by unknown index — George & Heath's recommendation:
    /// rows whose leading column is early meet a short `R` and reduce
    /// quickly, and the unknowns of one constraint enter together.
    #[default]
    LeadingConstraint,
    /// By unknown index (the mesh's vertex order).
    Natural,
}

/// Row-by-row sparse Givens QR of `Bᵀ` with Heath's rank test.
#[derive(Debug, Clone, Copy, Default)]
pub struct SparseGivens {
    /// Row order (default: [`GivensRowOrder::LeadingConstraint`]).
    pub order: GivensRowOrder,
}

impl SparseGivens {}

impl QrBackend for SparseGivens {
    fn name(&self) -> crate::backend::BackendName {
        super::QrKind::SparseGivens.name().into()
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
                Ok(
                    Box::new(GivensQr::with_budget(b, tolerance, self.order, budget)?)
                        as Box<dyn ConstraintQr>,
                )
            })
        })
    }
}

/// One stored rotation: `[x_p; x_q] ← [c s; −s c] [x_p; x_q]` in `Qᵀ`.
#[derive(Debug, Clone, Copy)]
struct Rotation {
    p: usize,
    q: usize,
    c: f64,
    s: f64,
}

/// A sparse row: sorted column indices and values.
#[derive(Debug, Clone, Default)]
struct SparseRow {
    cols: Vec<usize>,
    vals: Vec<f64>,
}

/// The factorisation produced by [`SparseGivens`].
#[derive(Debug, Clone)]
pub struct GivensQr {
    n: usize,
    rotations: Vec<Rotation>,
    /// Kept constraints, increasing (the order of `y`).
    kept: Vec<usize>,
    skipped: Vec<usize>,
    /// Slot (unknown) holding the `R` row of `kept[k]`.
    y_slot: Vec<usize>,
    /// Free unknowns, increasing (the order of `z`).
    free: Vec<usize>,
    /// Position of constraint `j` in `kept`, `usize::MAX` if skipped.
    kept_pos: Vec<usize>,
    /// Row of `D` (original constraint index) of `y_k`: `kept` itself, or
    /// its image under the fill-reducing order the factorisation used.
    d_row: Vec<usize>,
    /// `R` rows of the kept constraints, in `kept` order: CSR with column
    /// indices in constraint numbering, leading entry on the diagonal.
    r_ptr: Vec<usize>,
    r_col: Vec<usize>,
    r_val: Vec<f64>,
}

impl GivensQr {
    /// Factors `Bᵀ` for `b` (m × n, one row per constraint in priority
    /// order).
    ///
    /// **Column order.** When constraints share unknowns (relative, edge and
    /// face constraints linking a region), the fill of `R` depends on the
    /// column order, and the priority order can be a bad one (a breadth-first
    /// chain of relative constraints fills `R` along the BFS front). The
    /// factorisation is therefore first tried in a fill-reducing order
    /// (COLAMD on `Bᵀ`, which never forms `B Bᵀ`; see `fill.rs`). If that
    /// finds full rank, every constraint is kept — which is exactly what the
    /// priority order keeps when `B` has full row rank — and the result is
    /// used (the minimiser on `{X : BX = D}` does not depend on the basis of
    /// the null space). If it finds a dependent constraint, the priority
    /// decides which one to drop, so the factorisation is redone in priority
    /// order.
    ///
    /// Errors: a non-finite coefficient; [`ProblemError::TooLarge`] when the
    /// `R` of an order, counted before that factorisation starts
    /// (`nnz(R)` from the symbolic analysis of `B Bᵀ`, 16 bytes an entry),
    /// would not fit in the default memory budget ([`crate::limits`]).
    pub fn new(
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        order: GivensRowOrder,
    ) -> Result<GivensQr, Error> {
        GivensQr::with_budget(b, tolerance, order, MemoryBudget::default())
    }

    /// [`GivensQr::new`] within a solve's memory `budget`.
    pub(crate) fn with_budget(
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        order: GivensRowOrder,
        budget: MemoryBudget,
    ) -> Result<GivensQr, Error> {
        // With no two constraints sharing an unknown there is no
        // fill-reducing order to try: the priority order, checked as well.
        if let Some(perm) = fill_reducing_constraint_order(b)? {
            check_r_fill(b, Some(&perm), "sparse-givens, fill-reducing order", budget)?;
            let permuted = permute_rows(b, &perm)?;
            let mut qr = GivensQr::in_column_order(permuted.as_ref(), tolerance, order)?;
            if qr.skipped.is_empty() {
                for r in &mut qr.d_row {
                    *r = perm[*r];
                }
                // All kept: in the original numbering too, 0..m.
                qr.kept = (0..b.nrows()).collect();
                return Ok(qr);
            }
        }
        check_r_fill(b, None, "sparse-givens, priority order", budget)?;
        GivensQr::in_column_order(b, tolerance, order)
    }

    /// The factorisation with the columns of `Bᵀ` in the order of `b`'s rows:
    /// `Bᵀ` ([`transpose_summed`]), the column tolerances
    /// ([`column_tolerances`]), the row order ([`givens_row_order`]), the
    /// sweep ([`Sweep::eliminate`], row by row) and the assembly
    /// ([`Sweep::finish`]).
    fn in_column_order(
        b: SparseRowMatRef<'_, usize, f64>,
        tolerance: RankTolerance,
        order: GivensRowOrder,
    ) -> Result<GivensQr, Error> {
        let (m, n) = (b.nrows(), b.ncols());
        let bt = transpose_summed(b)?;
        let tol = column_tolerances(&bt, m, tolerance);
        let rows = givens_row_order(&bt, order);
        let mut sweep = Sweep::new(m);
        let mut row = SparseRow::default();
        for (i, &u) in rows.iter().enumerate() {
            // A row's rotations can be few: check every 256th row.
            if i % 256 == 0 {
                crate::interrupt::check()?;
            }
            row.cols.clear();
            row.vals.clear();
            for p in bt.ptr[u]..bt.ptr[u + 1] {
                if bt.val[p] != 0.0 {
                    row.cols.push(bt.col[p]);
                    row.vals.push(bt.val[p]);
                }
            }
            sweep.eliminate(u, &mut row, &tol);
        }
        Ok(sweep.finish(n))
    }

    /// Number of stored rotations.
    pub fn n_rotations(&self) -> usize {
        self.rotations.len()
    }
}

impl ConstraintQr for GivensQr {
    fn n(&self) -> usize {
        self.n
    }

    fn rank(&self) -> usize {
        self.kept.len()
    }

    fn kept(&self) -> &[usize] {
        // In the fill-reduced case `kept` was replaced by 0..m (all kept);
        // `kept_pos`, `r_col` stay in the numbering the factorisation used.
        &self.kept
    }

    fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    fn solve_r1t(&self, d: MatRef<'_, f64>, mut y: MatMut<'_, f64>) {
        // R1ᵀ y = d_kept, R1ᵀ lower triangular; R is stored by rows, which are
        // the columns of R1ᵀ: column-oriented forward substitution.
        let r = self.kept.len();
        for c in 0..d.ncols() {
            for k in 0..r {
                y[(k, c)] = d[(self.d_row[k], c)];
            }
            for k in 0..r {
                let range = self.r_ptr[k]..self.r_ptr[k + 1];
                let yk = y[(k, c)] / self.r_val[range.start];
                y[(k, c)] = yk;
                for p in range.start + 1..range.end {
                    let h = self.kept_pos[self.r_col[p]];
                    if h != usize::MAX {
                        y[(h, c)] -= self.r_val[p] * yk;
                    }
                }
            }
        }
    }

    fn apply_q(&self, y: MatRef<'_, f64>, z: MatRef<'_, f64>, mut x: MatMut<'_, f64>) {
        let k = x.ncols();
        for c in 0..k {
            for (t, &slot) in self.y_slot.iter().enumerate() {
                x[(slot, c)] = y[(t, c)];
            }
            for (t, &slot) in self.free.iter().enumerate() {
                x[(slot, c)] = z[(t, c)];
            }
        }
        for rot in self.rotations.iter().rev() {
            for col in 0..k {
                let (xp, xq) = (x[(rot.p, col)], x[(rot.q, col)]);
                x[(rot.p, col)] = rot.c * xp - rot.s * xq;
                x[(rot.q, col)] = rot.s * xp + rot.c * xq;
            }
        }
    }

    fn apply_qt(&self, x: MatRef<'_, f64>, mut y: MatMut<'_, f64>, mut z: MatMut<'_, f64>) {
        let mut w = x.to_owned();
        let k = x.ncols();
        for rot in &self.rotations {
            for col in 0..k {
                let (xp, xq) = (w[(rot.p, col)], w[(rot.q, col)]);
                w[(rot.p, col)] = rot.c * xp + rot.s * xq;
                w[(rot.q, col)] = -rot.s * xp + rot.c * xq;
            }
        }
        for c in 0..k {
            for (t, &slot) in self.y_slot.iter().enumerate() {
                y[(t, c)] = w[(slot, c)];
            }
            for (t, &slot) in self.free.iter().enumerate() {
                z[(t, c)] = w[(slot, c)];
            }
        }
    }

    fn mul_a_q2(&self, a: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        let mut ws = ColumnWorkspace::new(a);
        for rot in &self.rotations {
            ws.rotate(rot.p, rot.q, rot.c, rot.s);
        }
        ws.gather(&self.free)
    }

    fn free_unknown(&self, k: usize) -> usize {
        self.free.get(k).copied().unwrap_or(k)
    }

    fn storage_nnz(&self) -> usize {
        self.rotations.len() + self.r_val.len()
    }
}

/// `Bᵀ` in compressed rows (one row per unknown), column indices
/// (constraints) increasing.
#[derive(Debug, Clone, PartialEq)]
struct Transposed {
    ptr: Vec<usize>,
    col: Vec<usize>,
    val: Vec<f64>,
}

/// `Bᵀ` of `b`: constraint indices come out increasing because constraints
/// are visited in order; duplicate (constraint, unknown) entries are summed
/// (in the order they appear in `b`), and their freed slots compacted away.
/// Errors: a non-finite coefficient, named by row and unknown.
fn transpose_summed(b: SparseRowMatRef<'_, usize, f64>) -> Result<Transposed, Error> {
    let (m, n) = (b.nrows(), b.ncols());
    let (b_ptr, b_col, b_val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    let mut count = vec![0usize; n + 1];
    for i in 0..m {
        for p in b_ptr[i]..b_ptr[i + 1] {
            let v = b_val[p];
            if !v.is_finite() {
                return Err(ProblemError::InvalidArgument {
                    message: format!(
                        "hard constraint row {i} has a non-finite coefficient {v} on unknown {}",
                        b_col[p]
                    ),
                }
                .into());
            }
            count[b_col[p] + 1] += 1;
        }
    }
    for u in 0..n {
        count[u + 1] += count[u];
    }
    let mut bt_ptr = count.clone();
    let mut next = count;
    let nnz = bt_ptr[n];
    let mut bt_col = vec![0usize; nnz];
    let mut bt_val = vec![0.0f64; nnz];
    for i in 0..m {
        for p in b_ptr[i]..b_ptr[i + 1] {
            let u = b_col[p];
            let slot = next[u];
            if slot > bt_ptr[u] && bt_col[slot - 1] == i {
                bt_val[slot - 1] += b_val[p];
            } else {
                bt_col[slot] = i;
                bt_val[slot] = b_val[p];
                next[u] += 1;
            }
        }
    }
    // Compact away the slots freed by summed duplicates.
    let mut w = 0;
    for u in 0..n {
        let (start, end) = (bt_ptr[u], next[u]);
        bt_ptr[u] = w;
        for p in start..end {
            bt_col[w] = bt_col[p];
            bt_val[w] = bt_val[p];
            w += 1;
        }
    }
    bt_ptr[n] = w;
    bt_col.truncate(w);
    bt_val.truncate(w);
    Ok(Transposed {
        ptr: bt_ptr,
        col: bt_col,
        val: bt_val,
    })
}

/// Heath's column tolerances `η ‖b_j‖₂` for the `m` constraints (`η`:
/// [`RankTolerance::relative`]): an entry at most this may not pivot.
/// The squares are summed in `Bᵀ`'s storage order.
fn column_tolerances(bt: &Transposed, m: usize, tolerance: RankTolerance) -> Vec<f64> {
    let mut tol = vec![0.0f64; m];
    for (&j, &v) in bt.col.iter().zip(&bt.val) {
        tol[j] += v * v;
    }
    for t in &mut tol {
        *t = tolerance.relative * t.sqrt();
    }
    tol
}

/// The non-empty rows of `Bᵀ` (unknowns) in the order the sweep takes them:
/// increasing, or by their leading constraint (ties by unknown) for
/// [`GivensRowOrder::LeadingConstraint`].
fn givens_row_order(bt: &Transposed, order: GivensRowOrder) -> Vec<usize> {
    let n = bt.ptr.len() - 1;
    let mut rows: Vec<usize> = (0..n).filter(|&u| bt.ptr[u + 1] > bt.ptr[u]).collect();
    if order == GivensRowOrder::LeadingConstraint {
        rows.sort_by_key(|&u| (bt.col[bt.ptr[u]], u));
    }
    rows
}

/// The state of the row sweep: `R`'s row of each constraint, the unknown
/// (row of `Bᵀ`) holding it (`usize::MAX`: none yet), the rotations so far,
/// and scratch rows.
struct Sweep {
    r_rows: Vec<SparseRow>,
    holder: Vec<usize>,
    rotations: Vec<Rotation>,
    new_r: SparseRow,
    new_row: SparseRow,
}

impl Sweep {
    fn new(m: usize) -> Sweep {
        Sweep {
            r_rows: vec![SparseRow::default(); m],
            holder: vec![usize::MAX; m],
            rotations: Vec::new(),
            new_r: SparseRow::default(),
            new_row: SparseRow::default(),
        }
    }

    /// Eliminates `row` (row `u` of `Bᵀ`, zeros dropped) into `R`: its
    /// leading entry in column `j` either becomes `R`'s row `j` (when no
    /// row holds `j` yet and it is significant, `|a| > tol[j]`; Heath:
    /// a negligible entry may not pivot, and is skipped) or is rotated
    /// away against it (`h = hypot(ρ, a)`, `c = ρ/h`, `s = a/h`), until
    /// nothing is left.
    fn eliminate(&mut self, u: usize, row: &mut SparseRow, tol: &[f64]) {
        // `start`: the row's leading entry (entries before it are gone).
        let mut start = 0;
        while start < row.cols.len() {
            let j = row.cols[start];
            let a = row.vals[start];
            if self.holder[j] == usize::MAX {
                // NaN-safe: coefficients were checked finite.
                let significant = a.abs() > tol[j];
                if !significant {
                    start += 1;
                    continue;
                }
                let r = &mut self.r_rows[j];
                r.cols.clear();
                r.vals.clear();
                r.cols.extend_from_slice(&row.cols[start..]);
                r.vals.extend_from_slice(&row.vals[start..]);
                self.holder[j] = u;
                start = row.cols.len();
                break;
            }
            // Rotate the row into R's row j.
            let r = &mut self.r_rows[j];
            let rho = r.vals[0];
            let h = rho.hypot(a);
            let (c, s) = (rho / h, a / h);
            self.rotations.push(Rotation {
                p: self.holder[j],
                q: u,
                c,
                s,
            });
            let (new_r, new_row) = (&mut self.new_r, &mut self.new_row);
            new_r.cols.clear();
            new_r.vals.clear();
            new_row.cols.clear();
            new_row.vals.clear();
            new_r.cols.push(j);
            new_r.vals.push(h);
            rotate_merge(
                (&r.cols[1..], &r.vals[1..]),
                (&row.cols[start + 1..], &row.vals[start + 1..]),
                c,
                s,
                (&mut new_r.cols, &mut new_r.vals),
                (&mut new_row.cols, &mut new_row.vals),
            );
            std::mem::swap(r, new_r);
            std::mem::swap(row, new_row);
            start = 0;
        }
        debug_assert!(start >= row.cols.len());
    }

    /// The factorisation of `n` unknowns: constraints with an `R` row kept
    /// (in increasing order, their rows concatenated), the others skipped,
    /// and the unknowns holding no row free.
    fn finish(self, n: usize) -> GivensQr {
        let m = self.holder.len();
        let mut kept = Vec::new();
        let mut skipped = Vec::new();
        let mut kept_pos = vec![usize::MAX; m];
        let mut y_slot = Vec::new();
        let mut r_ptr = vec![0usize];
        let mut r_col = Vec::new();
        let mut r_val = Vec::new();
        let mut is_holder = vec![false; n];
        for j in 0..m {
            let holder = self.holder[j];
            if holder == usize::MAX {
                skipped.push(j);
            } else {
                kept_pos[j] = kept.len();
                kept.push(j);
                y_slot.push(holder);
                is_holder[holder] = true;
                r_col.extend_from_slice(&self.r_rows[j].cols);
                r_val.extend_from_slice(&self.r_rows[j].vals);
                r_ptr.push(r_col.len());
            }
        }
        let free = (0..n).filter(|&u| !is_holder[u]).collect();
        GivensQr {
            n,
            rotations: self.rotations,
            d_row: kept.clone(),
            kept,
            skipped,
            y_slot,
            free,
            kept_pos,
            r_ptr,
            r_col,
            r_val,
        }
    }
}

/// `b` with its rows in the order `perm` (row `k` of the result is row
/// `perm[k]` of `b`).
fn permute_rows(
    b: SparseRowMatRef<'_, usize, f64>,
    perm: &[usize],
) -> Result<faer::sparse::SparseRowMat<usize, f64>, Error> {
    let (ptr, col, val) = (b.symbolic().row_ptr(), b.symbolic().col_idx(), b.val());
    let mut new_ptr = Vec::with_capacity(perm.len() + 1);
    new_ptr.push(0);
    let mut new_col = Vec::with_capacity(col.len());
    let mut new_val = Vec::with_capacity(val.len());
    for &i in perm {
        new_col.extend_from_slice(&col[ptr[i]..ptr[i + 1]]);
        new_val.extend_from_slice(&val[ptr[i]..ptr[i + 1]]);
        new_ptr.push(new_col.len());
    }
    let symbolic = faer::sparse::SymbolicSparseRowMat::new_checked(
        b.nrows(),
        b.ncols(),
        new_ptr,
        None,
        new_col,
    );
    Ok(faer::sparse::SparseRowMat::new(symbolic, new_val))
}

#[cfg(test)]
mod phase_tests {
    use faer::sparse::{SparseRowMat, Triplet};

    use super::*;

    fn rows(m: usize, n: usize, t: &[(usize, usize, f64)]) -> SparseRowMat<usize, f64> {
        let t: Vec<_> = t.iter().map(|&(i, j, v)| Triplet::new(i, j, v)).collect();
        SparseRowMat::try_new_from_triplets(m, n, &t).unwrap()
    }

    #[test]
    fn transpose_lists_each_unknowns_constraints_in_order() {
        // B = [1 0 2; 0 3 4]: Bᵀ rows u0: (0,1); u1: (1,3); u2: (0,2) (1,4).
        let b = rows(2, 3, &[(0, 0, 1.0), (0, 2, 2.0), (1, 1, 3.0), (1, 2, 4.0)]);
        assert_eq!(
            transpose_summed(b.as_ref()).unwrap(),
            Transposed {
                ptr: vec![0, 1, 2, 4],
                col: vec![0, 1, 0, 1],
                val: vec![1.0, 3.0, 2.0, 4.0],
            }
        );
        let bad = rows(2, 3, &[(0, 0, 1.0), (1, 2, f64::INFINITY)]);
        assert_eq!(
            transpose_summed(bad.as_ref()).unwrap_err().to_string(),
            "invalid argument: hard constraint row 1 has a non-finite coefficient inf on unknown 2"
        );
    }

    #[test]
    fn tolerances_are_eta_times_column_norms_and_rows_go_by_leading_constraint() {
        // Columns of Bᵀ: constraint 0 = (3, 4), constraint 1 = (0, 5, 12).
        let bt = Transposed {
            ptr: vec![0, 1, 3, 4, 4],
            col: vec![0, 0, 1, 1],
            val: vec![3.0, 4.0, 5.0, 12.0],
        };
        let tol = column_tolerances(&bt, 2, RankTolerance { relative: 0.5 });
        assert_eq!(tol, [2.5, 6.5]);
        // Unknown 3 is empty; 2 leads with constraint 1.
        let lead = Transposed {
            ptr: vec![0, 1, 2, 3, 3],
            col: vec![1, 0, 0],
            val: vec![1.0; 3],
        };
        assert_eq!(givens_row_order(&lead, GivensRowOrder::Natural), [0, 1, 2]);
        assert_eq!(
            givens_row_order(&lead, GivensRowOrder::LeadingConstraint),
            [1, 2, 0]
        );
    }

    #[test]
    fn sweep_rotates_a_second_row_into_r_and_skips_a_dependent_constraint() {
        // B = [3 4; 6 8]: constraint 1 is twice constraint 0.
        let mut sweep = Sweep::new(2);
        let tol = [5e-10, 1e-9];
        let mut row = SparseRow {
            cols: vec![0, 1],
            vals: vec![3.0, 6.0],
        };
        sweep.eliminate(0, &mut row, &tol);
        assert_eq!(sweep.holder, [0, usize::MAX]);
        let mut row = SparseRow {
            cols: vec![0, 1],
            vals: vec![4.0, 8.0],
        };
        sweep.eliminate(1, &mut row, &tol);
        // hypot(3, 4) = 5, c = 3/5, s = 4/5; the remainder of constraint 1
        // is zero up to rounding, below its tolerance: no pivot.
        assert_eq!(sweep.r_rows[0].vals[0], 5.0);
        assert_eq!((sweep.rotations[0].p, sweep.rotations[0].q), (0, 1));
        assert_eq!((sweep.rotations[0].c, sweep.rotations[0].s), (0.6, 0.8));
        let qr = sweep.finish(2);
        assert_eq!((qr.kept, qr.skipped, qr.free), (vec![0], vec![1], vec![1]));
        assert_eq!((qr.y_slot, qr.r_ptr[..2].to_vec()), (vec![0], vec![0, 2]));
    }
}
