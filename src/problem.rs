//! The constrained least-squares problem (paper eq. 11):
//! `min ‖A X − C‖  subject to  B X = D`, all right-hand sides together.
//!
//! Two ways in:
//! - [`LseProblem::new`], a mesh: `A = [L; w·B_soft]` (l × n) and
//!   `C = [δ; w·D_soft]` (l × 3): the Laplacian rows first, then one row per
//!   soft constraint scaled by its weight (times the problem's
//!   [`SoftWeightScale`] when the mesh was divided by a length unit:
//!   docs/units.md §3). `B` (m × n) and `D` (m × 3) hold
//!   the hard constraints, one row each, in the constraints' list order
//!   (their priority).
//! - [`LseProblem::from_parts`], any sparse `A` (l × n) and `B` (m × n) with
//!   dense `C` (l × k) and `D` (m × k), `k ≥ 1`: the rows of `B` are the
//!   hard constraints in priority order (constraint `i` is row `i`), every
//!   row of `A` is an energy row.
//!
//! The formulations solve three right-hand-side columns at a time
//! ([`RHS_BLOCK`]); [`crate::solver::LseSolver`] splits other `k` into
//! blocks of three.

use faer::sparse::{
    SparseColMat, SparseColMatRef, SparseRowMat, SymbolicSparseColMat, SymbolicSparseRowMat,
    Triplet,
};
use faer::{Mat, MatRef};

use crate::constraints::ConstraintSet;
use crate::error::{ConstraintError, Error, NumericalError, ProblemError};

/// Where a constraint lives in the assembled system.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowPlace {
    /// Row `k` of `B` and `D`.
    Hard(usize),
    /// Row `n_laplacian_rows + k` of `A` and `C`.
    Soft(usize),
}

/// The assembled problem.
#[derive(Debug, Clone)]
pub struct LseProblem {
    a: SparseColMat<usize, f64>,
    c: Mat<f64>,
    b: SparseRowMat<usize, f64>,
    d: Mat<f64>,
    n_laplacian_rows: usize,
    places: Vec<RowPlace>,
    hard: Vec<usize>,
    soft: Vec<SoftRow>,
    length_scale: f64,
    general: bool,
    /// The power of two `s` that `A` and `C` of a general problem were
    /// multiplied by (1 for a mesh's problem); see [`LseProblem::a_scale`].
    a_scale: f64,
}

/// A soft constraint's row of `A` and `C`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoftRow {
    /// The constraint's index in the constraint list.
    pub index: usize,
    /// Its weight `w`, as given.
    pub weight: f64,
    /// The weight its row of `A` and `C` carries: `w` times the problem's
    /// [`SoftWeightScale`] (`w` itself for a problem in the mesh's units).
    pub row_weight: f64,
}

/// The factor `ℓᵃ` every soft weight is multiplied by when a mesh problem
/// is assembled on the positions divided by a length `ℓ` (docs/units.md §3,
/// "Soft weights").
///
/// With `X = ℓ X̂`, `P = ℓ P̂`, `d = ℓ d̂` and a Laplacian whose entries
/// scale as `length⁻ᵃ` (`L = ℓ⁻ᵃ L̂`,
/// [`crate::LaplacianKind::inverse_length_power`]),
/// `‖L(X − P)‖² + Σ w²‖b·X − d‖² = ℓ^(2−2a) (‖L̂(X̂ − P̂)‖² + Σ (w ℓᵃ)² ‖b·X̂ − d̂‖²)`:
/// the two energies differ by a positive constant factor, so they have the
/// same minimiser exactly when every soft row of the scaled problem carries
/// `w ℓᵃ`. The hard rows are unaffected (`b·X = d ⇔ b·X̂ = d̂`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SoftWeightScale {
    /// `ℓ`, the length the mesh was divided by.
    pub length: f64,
    /// `a`, the power of length in `L`'s entries.
    pub power: i32,
}

impl SoftWeightScale {
    /// No scaling: weights as given (a problem in the mesh's own units).
    pub const NONE: SoftWeightScale = SoftWeightScale {
        length: 1.0,
        power: 0,
    };

    /// `w ℓᵃ`, multiplied one factor of `ℓ` at a time so that no
    /// intermediate power of `ℓ` overflows when the product is
    /// representable (`ℓ = 1e200`, `w = 1e-390`… is not, `ℓ = 1e150`,
    /// `w = 1e-300` is: `w ℓ² = 1`).
    pub fn apply(self, w: f64) -> f64 {
        let mut r = w;
        for _ in 0..self.power.unsigned_abs() {
            if self.power > 0 {
                r *= self.length;
            } else {
                r /= self.length;
            }
        }
        r
    }

    /// `ℓᵃ` (infinite or zero when it is not representable; the report's
    /// `soft_weight_scale`).
    pub fn factor(self) -> f64 {
        self.apply(1.0)
    }
}

/// The number of right-hand-side columns a formulation's
/// [`Prepared::solve`](crate::formulation::Prepared::solve) works on: the
/// x, y and z coordinates of a mesh. Problems with another number of
/// columns are solved in blocks of this many by
/// [`crate::solver::LseSolver`].
pub const RHS_BLOCK: usize = 3;

impl LseProblem {
    /// A general problem `min ‖A X − C‖ s.t. B X = D` from its matrices:
    /// `A` (l × n) and `B` (m × n) sparse, `C` (l × k) and `D` (m × k)
    /// dense, `k ≥ 1`, `n ≥ 1`; `l` or `m` may be zero. Row `i` of `B` is
    /// hard constraint `i` (list order = priority: of two dependent rows the
    /// earlier is kept).
    ///
    /// The matrices are copied into canonical form: duplicate entries
    /// summed, row indices sorted; stored zeros are kept in `A` (they are
    /// harmless) and dropped from `B` (so that a row's entries are its
    /// coefficients). Checks, each a [`ProblemError`] naming the place:
    /// shapes ([`ProblemError::Dimensions`]), NaN or infinite entries
    /// ([`ProblemError::NonFiniteEntry`], matrix, row and column), rows of
    /// `B` without a nonzero ([`ProblemError::EmptyConstraintRow`]) and
    /// unknowns in no row of `A` or `B` ([`ProblemError::UnusedUnknown`]).
    /// Other rank deficiencies are found by the factorisation
    /// ([`crate::error::NumericalError::FreeUnknown`]).
    ///
    /// The length scale of the conflict tolerance
    /// ([`LseProblem::length_scale`]) is the largest `|D_kj| / ‖b_k‖₂`, the
    /// size of `X` the rows of `B` imply whatever their scaling (1 when `D`
    /// is zero or empty); [`LseProblem::with_length_scale`] overrides it.
    pub fn from_parts(
        a: SparseColMatRef<'_, usize, f64>,
        c: MatRef<'_, f64>,
        b: SparseColMatRef<'_, usize, f64>,
        d: MatRef<'_, f64>,
    ) -> Result<LseProblem, ProblemError> {
        check_shapes(a, c, b, d)?;
        check_dense_finite("C", c)?;
        check_dense_finite("D", d)?;
        let mut a = canonical_csc("A", a, true)?;
        let mut c = c.to_owned();
        let a_scale = equilibrate_objective(&mut a, &mut c);
        let b_csc = canonical_csc("B", b, false)?;
        let b = csc_to_csr(b_csc.as_ref());
        let (l, n, m) = (a.nrows(), a.ncols(), b.nrows());
        if let Some(row) = (0..m).find(|&k| b.symbolic().row_range(k).is_empty()) {
            return Err(ProblemError::EmptyConstraintRow { row });
        }
        let a_ptr = a.symbolic().col_ptr();
        let b_ptr = b_csc.symbolic().col_ptr();
        if let Some(unknown) =
            (0..n).find(|&j| a_ptr[j] == a_ptr[j + 1] && b_ptr[j] == b_ptr[j + 1])
        {
            return Err(ProblemError::UnusedUnknown { unknown });
        }
        // The size of X that the rows imply, |D_kj| / ‖b_k‖: a row scaled
        // with its target leaves it unchanged.
        let max_d = (0..m).fold(0.0f64, |acc, k| {
            let values = &b.val()[b.symbolic().row_range(k)];
            let norm = values.iter().map(|v| v * v).sum::<f64>().sqrt();
            (0..d.ncols()).fold(acc, |acc, j| acc.max(d[(k, j)].abs() / norm))
        });
        Ok(LseProblem {
            a,
            c,
            b,
            d: d.to_owned(),
            n_laplacian_rows: l,
            places: (0..m).map(RowPlace::Hard).collect(),
            hard: (0..m).collect(),
            soft: Vec::new(),
            length_scale: if max_d > 0.0 && max_d.is_finite() {
                max_d
            } else {
                1.0
            },
            general: true,
            a_scale,
        })
    }

    /// Assembles `A, C, B, D` from a Laplacian `l` (n × n), the Laplacian
    /// coordinates `delta = L P` (n × 3) and the constraints (whose vertices
    /// must be `< n`). `length_scale` (the mesh's bounding-box diagonal) is
    /// the unit of absolute tolerances on constraint residuals. Soft row
    /// `k` carries `soft_scale.apply(w_k)` ([`SoftWeightScale::NONE`] for a
    /// problem in the mesh's own units); a product that is not a finite
    /// positive number is a [`NumericalError::SoftWeightOutOfRange`], and
    /// one whose square overflows (`(w ℓᵃ)² = ∞`, which the normal
    /// equations of every formulation would hold) a
    /// [`NumericalError::SoftWeightTooLarge`].
    pub fn new(
        l: &SparseColMat<usize, f64>,
        delta: &Mat<f64>,
        constraints: &ConstraintSet,
        length_scale: f64,
        soft_scale: SoftWeightScale,
    ) -> Result<LseProblem, Error> {
        let n = l.ncols();
        constraints.check_vertices(n)?;
        let n_lap = l.nrows();
        let (places, hard, soft) = split_rows(constraints, soft_scale)?;
        let (b, d) = assemble_hard(constraints, &hard, n);
        let a = assemble_a(l, constraints, &soft)?;
        let mut c = Mat::<f64>::zeros(n_lap + soft.len(), 3);
        c.as_mut().submatrix_mut(0, 0, n_lap, 3).copy_from(delta);
        let mut problem = LseProblem {
            a,
            c,
            b,
            d,
            n_laplacian_rows: n_lap,
            places,
            hard,
            soft,
            length_scale,
            general: false,
            a_scale: 1.0,
        };
        for (i, c) in constraints.as_slice().iter().enumerate() {
            problem.write_rhs(i, c.kind.rhs());
        }
        Ok(problem)
    }

    fn write_rhs(&mut self, index: usize, value: [f64; 3]) {
        match self.places[index] {
            RowPlace::Hard(k) => {
                for c in 0..3 {
                    self.d[(k, c)] = value[c];
                }
            }
            RowPlace::Soft(k) => {
                let w = self.soft[k].row_weight;
                for c in 0..3 {
                    self.c[(self.n_laplacian_rows + k, c)] = w * value[c];
                }
            }
        }
    }

    /// Sets the target (or relative vector) of constraint `index`: the only
    /// change a dragged handle makes. The matrices are untouched, so a
    /// prepared system re-solves without refactoring.
    pub(crate) fn set_rhs(&mut self, index: usize, value: [f64; 3]) -> Result<(), Error> {
        if index >= self.places.len() {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "constraint {index} does not exist (there are {})",
                    self.places.len()
                ),
            }
            .into());
        }
        if self.c.ncols() != RHS_BLOCK {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "a 3-vector target needs a problem with 3 right-hand-side columns, this one has {} (use set_rhs_matrices)",
                    self.c.ncols()
                ),
            }
            .into());
        }
        if value.iter().any(|v| !v.is_finite()) {
            return Err(ConstraintError::NonFinite {
                index,
                field: "target",
            }
            .into());
        }
        self.write_rhs(index, value);
        Ok(())
    }

    /// Replaces `C` and `D` (same shapes, finite entries); the matrices stay,
    /// so a prepared system re-solves without refactoring. On error nothing
    /// changes.
    pub fn set_rhs_matrices(
        &mut self,
        c: MatRef<'_, f64>,
        d: MatRef<'_, f64>,
    ) -> Result<(), Error> {
        let same = |m: MatRef<'_, f64>, old: &Mat<f64>| {
            m.nrows() == old.nrows() && m.ncols() == old.ncols()
        };
        if !same(c, &self.c) || !same(d, &self.d) {
            return Err(ProblemError::Dimensions {
                message: format!(
                    "new C is {} × {} and D {} × {}, expected {} × {} and {} × {}",
                    c.nrows(),
                    c.ncols(),
                    d.nrows(),
                    d.ncols(),
                    self.c.nrows(),
                    self.c.ncols(),
                    self.d.nrows(),
                    self.d.ncols()
                ),
            }
            .into());
        }
        check_dense_finite("C", c)?;
        check_dense_finite("D", d)?;
        self.c.copy_from(c);
        self.d.copy_from(d);
        Ok(())
    }

    /// Replaces the energy rows' right-hand side (the top
    /// [`LseProblem::n_laplacian_rows`] rows of `C`, e.g. the rotated rest
    /// gradients of an ARAP global step). The matrices are untouched, so a
    /// prepared system re-solves without refactoring. `rhs` must be
    /// `n_laplacian_rows × 3` and finite.
    pub fn set_energy_rhs(&mut self, rhs: faer::MatRef<'_, f64>) -> Result<(), Error> {
        if rhs.nrows() != self.n_laplacian_rows || rhs.ncols() != 3 {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "energy right-hand side is {} × {}, expected {} × 3",
                    rhs.nrows(),
                    rhs.ncols(),
                    self.n_laplacian_rows
                ),
            }
            .into());
        }
        if let Some(row) = (0..rhs.nrows()).find(|&i| (0..3).any(|c| !rhs[(i, c)].is_finite())) {
            return Err(ProblemError::BadUpdate {
                message: format!("energy right-hand side row {row} is not finite"),
            }
            .into());
        }
        self.c
            .as_mut()
            .submatrix_mut(0, 0, self.n_laplacian_rows, 3)
            .copy_from(rhs);
        Ok(())
    }

    /// The first [`LseProblem::n_laplacian_rows`] rows of `C`, to be
    /// overwritten in place by an iterative method that changes only them
    /// (the ARAP global step); unlike [`LseProblem::set_energy_rhs`] nothing
    /// is checked: the caller writes finite values.
    pub(crate) fn energy_rhs_mut(&mut self) -> faer::MatMut<'_, f64> {
        self.c
            .as_mut()
            .submatrix_mut(0, 0, self.n_laplacian_rows, 3)
    }

    /// Swaps `C` and `D` with the given matrices (for solving a block of
    /// columns at a time; the caller swaps back).
    pub(crate) fn swap_rhs(&mut self, c: &mut Mat<f64>, d: &mut Mat<f64>) {
        std::mem::swap(&mut self.c, c);
        std::mem::swap(&mut self.d, d);
    }

    /// Sets the length unit of absolute constraint tolerances (see
    /// [`LseProblem::length_scale`]); non-finite or non-positive values are
    /// ignored.
    pub(crate) fn with_length_scale(mut self, scale: f64) -> LseProblem {
        if scale.is_finite() && scale > 0.0 {
            self.length_scale = scale;
        }
        self
    }

    /// Declares the first `rows` rows of `A` to be the Laplacian (the rows
    /// whose null space is the translations of mesh components) and the
    /// rest soft constraint rows, as [`LseProblem::new`] assembles them:
    /// what `export-system` records in `meta.json`, so that a problem read
    /// back from files is ordered for KKT exactly as the mesh problem was.
    /// Ignored when `rows > l`.
    pub(crate) fn with_laplacian_rows(mut self, rows: usize) -> LseProblem {
        if rows <= self.a.nrows() {
            self.n_laplacian_rows = rows;
        }
        self
    }

    /// `true` for a problem built by [`LseProblem::from_parts`] (no mesh:
    /// errors name unknowns, not vertices or components).
    pub(crate) fn is_general(&self) -> bool {
        self.general
    }

    /// `k`, the number of right-hand-side columns of `C` and `D`.
    pub(crate) fn n_rhs(&self) -> usize {
        self.c.ncols()
    }

    /// `A` (l × n).
    pub fn a(&self) -> &SparseColMat<usize, f64> {
        &self.a
    }

    /// `C` (l × k).
    pub fn c(&self) -> &Mat<f64> {
        &self.c
    }

    /// `B` (m × n), one row per hard constraint in priority order.
    pub fn b(&self) -> &SparseRowMat<usize, f64> {
        &self.b
    }

    /// `D` (m × k).
    pub fn d(&self) -> &Mat<f64> {
        &self.d
    }

    /// Number of unknowns `n` (vertices, for a mesh).
    pub fn n(&self) -> usize {
        self.a.ncols()
    }

    /// Number of Laplacian rows at the top of `A`.
    pub(crate) fn n_laplacian_rows(&self) -> usize {
        self.n_laplacian_rows
    }

    /// The constraint index of each row of `B`.
    pub fn hard_constraints(&self) -> &[usize] {
        &self.hard
    }

    /// Each soft row of `A`: its constraint, its weight as given and the
    /// weight the row carries.
    pub(crate) fn soft_constraints(&self) -> &[SoftRow] {
        &self.soft
    }

    /// Where constraint `index` lives in the system.
    pub fn place(&self, index: usize) -> Option<RowPlace> {
        self.places.get(index).copied()
    }

    /// The length unit of absolute constraint tolerances.
    pub fn length_scale(&self) -> f64 {
        self.length_scale
    }

    /// The power of two `A` and `C` of a general problem were multiplied by
    /// ([`LseProblem::from_parts`]: `A`'s largest entry brought near 1, so
    /// that normal matrices of entries near 1e±300 neither overflow nor
    /// underflow; the minimiser is unchanged). `‖AX − C‖` of the problem as
    /// given is that of [`LseProblem::a`] and [`LseProblem::c`] divided by
    /// it. 1 for a mesh's problem (docs/units.md §8).
    pub(crate) fn a_scale(&self) -> f64 {
        self.a_scale
    }

    /// Euclidean norm of the residual `b_k·X − d_k` of hard row `k` (over
    /// all `k` columns).
    pub fn hard_residual(&self, k: usize, x: &Mat<f64>) -> f64 {
        let range = self.b.symbolic().row_range(k);
        let cols = &self.b.symbolic().col_idx()[range.clone()];
        let vals = &self.b.val()[range];
        let mut s = 0.0f64;
        for c in 0..self.d.ncols() {
            let mut r = -self.d[(k, c)];
            for (&v, &a) in cols.iter().zip(vals) {
                r += a * x[(v, c)];
            }
            // Without overflow: rows near ±1e308 have residuals whose
            // squares are not doubles.
            s = s.hypot(r);
        }
        s
    }

    /// `‖A X − C‖_F`.
    pub fn least_squares_residual(&self, x: &Mat<f64>) -> f64 {
        let r = self.a_times(x) - &self.c;
        r.norm_l2()
    }

    /// `A X` for an n × k dense `X`.
    pub fn a_times(&self, x: &Mat<f64>) -> Mat<f64> {
        let (ptr, rows, val) = (
            self.a.symbolic().col_ptr(),
            self.a.symbolic().row_idx(),
            self.a.val(),
        );
        let mut out = Mat::<f64>::zeros(self.a.nrows(), x.ncols());
        for c in 0..x.ncols() {
            for j in 0..self.a.ncols() {
                let xj = x[(j, c)];
                if xj != 0.0 {
                    for p in ptr[j]..ptr[j + 1] {
                        out[(rows[p], c)] += val[p] * xj;
                    }
                }
            }
        }
        out
    }
}

/// Shapes of [`LseProblem::from_parts`]'s inputs.
fn check_shapes(
    a: SparseColMatRef<'_, usize, f64>,
    c: MatRef<'_, f64>,
    b: SparseColMatRef<'_, usize, f64>,
    d: MatRef<'_, f64>,
) -> Result<(), ProblemError> {
    check_part_shapes(
        (a.nrows(), a.ncols()),
        (c.nrows(), c.ncols()),
        (b.nrows(), b.ncols()),
        (d.nrows(), d.ncols()),
    )
}

/// The shape checks of [`LseProblem::from_parts`] on `(rows, cols)` alone
/// (a reader checks them before it reads any entry).
pub(crate) fn check_part_shapes(
    a: (usize, usize),
    c: (usize, usize),
    b: (usize, usize),
    d: (usize, usize),
) -> Result<(), ProblemError> {
    let dims = |message: String| Err(ProblemError::Dimensions { message });
    let shape = |(r, c): (usize, usize)| format!("{r} × {c}");
    let all = format!(
        "A is {}, C {}, B {}, D {}",
        shape(a),
        shape(c),
        shape(b),
        shape(d)
    );
    if a.1 == 0 {
        return dims(format!("no unknowns ({all})"));
    }
    if b.1 != a.1 {
        return dims(format!(
            "A and B must have the same number of columns (unknowns): {all}"
        ));
    }
    if c.0 != a.0 {
        return dims(format!("C must have as many rows as A: {all}"));
    }
    if d.0 != b.0 {
        return dims(format!("D must have as many rows as B: {all}"));
    }
    if c.1 != d.1 {
        return dims(format!(
            "C and D must have the same number of columns (right-hand sides): {all}"
        ));
    }
    if c.1 == 0 {
        return dims(format!("C and D need at least one column: {all}"));
    }
    if a.0 == 0 && b.0 == 0 {
        return dims(format!("A and B have no rows: {all}"));
    }
    Ok(())
}

/// The first non-finite entry of a dense matrix as an error.
fn check_dense_finite(matrix: &'static str, m: MatRef<'_, f64>) -> Result<(), ProblemError> {
    for col in 0..m.ncols() {
        for row in 0..m.nrows() {
            let value = m[(row, col)];
            if !value.is_finite() {
                return Err(ProblemError::NonFiniteEntry {
                    matrix,
                    row,
                    col,
                    value,
                });
            }
        }
    }
    Ok(())
}

/// A copy of `m` in canonical CSC form (compact column pointers, sorted
/// rows, duplicates summed), refusing non-finite entries; stored zeros are
/// kept when `keep_zeros`, dropped otherwise.
fn canonical_csc(
    matrix: &'static str,
    m: SparseColMatRef<'_, usize, f64>,
    keep_zeros: bool,
) -> Result<SparseColMat<usize, f64>, ProblemError> {
    let mut triplets = Vec::with_capacity(m.compute_nnz());
    for col in 0..m.ncols() {
        let range = m.symbolic().col_range(col);
        let rows = &m.symbolic().row_idx()[range.clone()];
        for (&row, &value) in rows.iter().zip(&m.val()[range]) {
            if !value.is_finite() {
                return Err(ProblemError::NonFiniteEntry {
                    matrix,
                    row,
                    col,
                    value,
                });
            }
            triplets.push(Triplet::new(row, col, value));
        }
    }
    let summed =
        SparseColMat::try_new_from_triplets(m.nrows(), m.ncols(), &triplets).map_err(|e| {
            ProblemError::Dimensions {
                message: format!("{matrix}: {e:?}"),
            }
        })?;
    if keep_zeros {
        return Ok(summed);
    }
    let (ptr, rows, val) = (
        summed.symbolic().col_ptr(),
        summed.symbolic().row_idx(),
        summed.val(),
    );
    let mut col_ptr = Vec::with_capacity(m.ncols() + 1);
    col_ptr.push(0);
    let (mut out_rows, mut out_vals) = (Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            if val[p] != 0.0 {
                out_rows.push(rows[p]);
                out_vals.push(val[p]);
            }
        }
        col_ptr.push(out_rows.len());
    }
    Ok(SparseColMat::new(
        SymbolicSparseColMat::new_checked(m.nrows(), m.ncols(), col_ptr, None, out_rows),
        out_vals,
    ))
}

/// The CSR copy (sorted columns) of a canonical CSC matrix.
fn csc_to_csr(m: SparseColMatRef<'_, usize, f64>) -> SparseRowMat<usize, f64> {
    let (ptr, rows, val) = (m.symbolic().col_ptr(), m.symbolic().row_idx(), m.val());
    let mut row_ptr = vec![0usize; m.nrows() + 1];
    for &r in rows {
        row_ptr[r + 1] += 1;
    }
    for r in 0..m.nrows() {
        row_ptr[r + 1] += row_ptr[r];
    }
    let mut fill = row_ptr.clone();
    let mut cols = vec![0usize; rows.len()];
    let mut vals = vec![0.0; rows.len()];
    for j in 0..m.ncols() {
        for p in ptr[j]..ptr[j + 1] {
            let r = rows[p];
            cols[fill[r]] = j;
            vals[fill[r]] = val[p];
            fill[r] += 1;
        }
    }
    SparseRowMat::new(
        SymbolicSparseRowMat::new_checked(m.nrows(), m.ncols(), row_ptr, None, cols),
        vals,
    )
}

/// Which columns of the small dense matrix `rows` (row-major, `ncols`
/// columns: coefficient sums of constraint rows per mesh component) get a
/// pivot in Gaussian elimination with partial pivoting. The pivot columns
/// are linearly independent and every other column is a combination of
/// them, so fixing the translations of the pivot-less components pins all
/// the others. An entry counts as zero at `≤ 1e-12` in absolute value (the
/// callers scale rows so that their coefficient norm is about 1 or drop sums
/// below `1e-12 ×` that norm first). `rows` is overwritten.
pub(crate) fn pivot_columns(rows: &mut [Vec<f64>], ncols: usize) -> Vec<bool> {
    let mut has_pivot = vec![false; ncols];
    let mut next = 0;
    for col in 0..ncols {
        let pivot = (next..rows.len())
            .max_by(|&a, &b| rows[a][col].abs().total_cmp(&rows[b][col].abs()))
            .filter(|&p| rows[p][col].abs() > 1e-12);
        let Some(p) = pivot else { continue };
        rows.swap(next, p);
        let pivot_row = rows[next].clone();
        for r in rows.iter_mut().skip(next + 1) {
            let f = r[col] / pivot_row[col];
            if f != 0.0 {
                for (x, &y) in r.iter_mut().zip(&pivot_row).skip(col) {
                    *x -= f * y;
                }
            }
        }
        has_pivot[col] = true;
        next += 1;
    }
    has_pivot
}

/// Checks that no connected component of the mesh is free to translate.
///
/// `L` annihilates every vector that is constant on a component, so a
/// component's translation is fixed only by constraints whose coefficients
/// on it do not sum to zero (position, edge, face — hard or soft; a relative
/// constraint sums to zero). With `s_c(k)` the coefficient sum of constraint
/// `k` on component `c`, the translations `T_c` are fixed iff the matrix
/// `S = [s_c(k)]` (constraints × components) has full column rank. We decide
/// that by Gaussian elimination with partial pivoting over the components
/// not already pinned by a single-component constraint; a zero pivot column
/// names the component. A coefficient sum counts as nonzero above
/// `1e-12 × the row's coefficient norm`.
pub(crate) fn check_pinned(
    component_of: &[usize],
    n_components: usize,
    constraints: &ConstraintSet,
) -> Result<(), ProblemError> {
    if constraints.is_empty() {
        return Err(ProblemError::NoConstraints);
    }
    let mut pinned = vec![false; n_components];
    let mut coupling: Vec<Vec<(usize, f64)>> = Vec::new();
    for c in constraints.as_slice() {
        let row = c.kind.row();
        let mut sums: Vec<(usize, f64)> = Vec::with_capacity(3);
        for &(v, a) in row.entries() {
            let comp = component_of[v];
            match sums.iter_mut().find(|s| s.0 == comp) {
                Some(s) => s.1 += a,
                None => sums.push((comp, a)),
            }
        }
        let tol = 1e-12 * row.norm();
        sums.retain(|s| s.1.abs() > tol);
        match sums.len() {
            0 => {}
            1 => pinned[sums[0].0] = true,
            _ => coupling.push(sums),
        }
    }
    let unpinned: Vec<usize> = (0..n_components).filter(|&c| !pinned[c]).collect();
    if unpinned.is_empty() {
        return Ok(());
    }
    // Dense elimination on the coupling rows restricted to unpinned
    // components (small: one column per unpinned component).
    let col_of: std::collections::HashMap<usize, usize> =
        unpinned.iter().enumerate().map(|(k, &c)| (c, k)).collect();
    let mut rows: Vec<Vec<f64>> = coupling
        .iter()
        .map(|sums| {
            let mut r = vec![0.0; unpinned.len()];
            for &(comp, s) in sums {
                if let Some(&k) = col_of.get(&comp) {
                    r[k] = s;
                }
            }
            r
        })
        .filter(|r| r.iter().any(|&v| v != 0.0))
        .collect();
    if let Some(col) = pivot_columns(&mut rows, unpinned.len())
        .iter()
        .position(|&has_pivot| !has_pivot)
    {
        let comp = unpinned[col];
        let vertices = component_of.iter().filter(|&&c| c == comp).count();
        let example_vertex = component_of.iter().position(|&c| c == comp).unwrap_or(0);
        return Err(ProblemError::UnpinnedComponent {
            component: comp,
            vertices,
            example_vertex,
        });
    }
    Ok(())
}

/// Multiplies `A` and `C` by the power of two `s` that brings `A`'s largest
/// entry into `[2^-1/2, 2^1/2)`, and returns `s` (1 when `A` has no entry or
/// when `s C` would not be finite). `min ‖sA X − sC‖` has the minimiser of
/// `min ‖A X − C‖` (the objective is multiplied by `s²`), and a power of two
/// changes no digit; but the normal matrices the formulations form square
/// `A`'s entries, which for entries near 1e±300 overflow or underflow (an
/// `A` of full rank then looked singular, "unknown 1 is free").
fn equilibrate_objective(a: &mut SparseColMat<usize, f64>, c: &mut Mat<f64>) -> f64 {
    let largest = a.val().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(largest > 0.0 && largest.is_finite()) {
        return 1.0;
    }
    let s = (-largest.log2().round()).exp2();
    let c_largest = c.norm_max();
    if s == 1.0 || !(s.is_finite() && (s * c_largest).is_finite() && s > 0.0) {
        return 1.0;
    }
    for v in a.val_mut() {
        *v *= s;
    }
    for j in 0..c.ncols() {
        for i in 0..c.nrows() {
            c[(i, j)] *= s;
        }
    }
    s
}

/// Target `value` of constraint `index` divided by the length unit, or
/// [`NumericalError::TargetOutOfRange`] if that is not finite (a finite
/// target so large that dividing by a unit below 1 overflows).
pub(crate) fn target_in_unit(index: usize, value: [f64; 3], unit: f64) -> Result<[f64; 3], Error> {
    let scaled = value.map(|v| v / unit);
    if scaled.iter().all(|v| v.is_finite()) {
        return Ok(scaled);
    }
    let largest = value.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    Err(NumericalError::TargetOutOfRange {
        index,
        value: largest,
        unit,
        ratio: largest / unit,
    }
    .into())
}

/// Each constraint's place, the hard constraints' indices, the soft rows.
type SplitRows = (Vec<RowPlace>, Vec<usize>, Vec<SoftRow>);

/// Sorts the constraints into hard rows (of `B`) and soft rows (of `A`),
/// in list order: each constraint's place, the hard constraints' indices,
/// and the soft rows ([`soft_row`]).
fn split_rows(
    constraints: &ConstraintSet,
    soft_scale: SoftWeightScale,
) -> Result<SplitRows, NumericalError> {
    let mut places = Vec::with_capacity(constraints.len());
    let mut hard = Vec::new();
    let mut soft = Vec::new();
    for (i, c) in constraints.as_slice().iter().enumerate() {
        match c.weight {
            None => {
                places.push(RowPlace::Hard(hard.len()));
                hard.push(i);
            }
            Some(w) => {
                places.push(RowPlace::Soft(soft.len()));
                soft.push(soft_row(i, w, soft_scale)?);
            }
        }
    }
    Ok((places, hard, soft))
}

/// Constraint `index`'s soft row, weight `w` scaled by `soft_scale`: the
/// row weight must be finite and positive, and its square (the weight in
/// the normal matrix `AᵀA`) finite.
fn soft_row(index: usize, w: f64, soft_scale: SoftWeightScale) -> Result<SoftRow, NumericalError> {
    let row_weight = soft_scale.apply(w);
    if !(row_weight.is_finite() && row_weight > 0.0) {
        return Err(NumericalError::SoftWeightOutOfRange {
            index,
            weight: w,
            length: soft_scale.length,
            power: soft_scale.power,
        });
    }
    if (row_weight * row_weight).is_infinite() {
        return Err(NumericalError::SoftWeightTooLarge {
            index,
            weight: w,
            row_weight,
            power: soft_scale.power,
        });
    }
    Ok(SoftRow {
        index,
        weight: w,
        row_weight,
    })
}

/// `B` (CSR over `n` unknowns, columns sorted within each row) and `D` of
/// the `hard` constraints, in that order.
fn assemble_hard(
    constraints: &ConstraintSet,
    hard: &[usize],
    n: usize,
) -> (SparseRowMat<usize, f64>, Mat<f64>) {
    let mut row_ptr = Vec::with_capacity(hard.len() + 1);
    row_ptr.push(0);
    let mut col_idx = Vec::new();
    let mut b_val = Vec::new();
    let mut d = Mat::<f64>::zeros(hard.len(), 3);
    for (k, &i) in hard.iter().enumerate() {
        let kind = &constraints[i].kind;
        let mut entries: Vec<(usize, f64)> = kind.row().entries().to_vec();
        entries.sort_unstable_by_key(|e| e.0);
        for (v, a) in entries {
            col_idx.push(v);
            b_val.push(a);
        }
        row_ptr.push(col_idx.len());
        let rhs = kind.rhs();
        for c in 0..3 {
            d[(k, c)] = rhs[c];
        }
    }
    let b = SparseRowMat::new(
        SymbolicSparseRowMat::new_checked(hard.len(), n, row_ptr, None, col_idx),
        b_val,
    );
    (b, d)
}

/// `A = [L; w B_soft]` (CSC): column `j` holds `L`'s column, then the soft
/// entries on `j` (rows `n_lap + k`, increasing in `k`), each the row
/// weight times the coefficient.
fn assemble_a(
    l: &SparseColMat<usize, f64>,
    constraints: &ConstraintSet,
    soft: &[SoftRow],
) -> Result<SparseColMat<usize, f64>, ProblemError> {
    const WHAT: &str = "the matrix A = [L; w B_soft]";
    let (n_lap, n) = (l.nrows(), l.ncols());
    let mut soft_count = zeroed::<usize>(WHAT, n + 1)?;
    for row in soft {
        for &(v, _) in constraints[row.index].kind.row().entries() {
            soft_count[v + 1] += 1;
        }
    }
    for j in 0..n {
        soft_count[j + 1] += soft_count[j];
    }
    let mut soft_rows = zeroed::<usize>(WHAT, soft_count[n])?;
    let mut soft_vals = zeroed::<f64>(WHAT, soft_count[n])?;
    let mut fill = zeroed::<usize>(WHAT, n + 1)?;
    fill.copy_from_slice(&soft_count);
    for (k, row) in soft.iter().enumerate() {
        for &(v, a) in constraints[row.index].kind.row().entries() {
            soft_rows[fill[v]] = n_lap + k;
            soft_vals[fill[v]] = row.row_weight * a;
            fill[v] += 1;
        }
    }
    let (l_ptr, l_rows, l_val) = (l.symbolic().col_ptr(), l.symbolic().row_idx(), l.val());
    let nnz = l_rows.len() + soft_rows.len();
    let mut a_ptr = reserved::<usize>(WHAT, n + 1)?;
    a_ptr.push(0);
    let mut a_rows = reserved::<usize>(WHAT, nnz)?;
    let mut a_val = reserved::<f64>(WHAT, nnz)?;
    for j in 0..n {
        a_rows.extend_from_slice(&l_rows[l_ptr[j]..l_ptr[j + 1]]);
        a_val.extend_from_slice(&l_val[l_ptr[j]..l_ptr[j + 1]]);
        a_rows.extend_from_slice(&soft_rows[soft_count[j]..soft_count[j + 1]]);
        a_val.extend_from_slice(&soft_vals[soft_count[j]..soft_count[j + 1]]);
        a_ptr.push(a_rows.len());
    }
    Ok(SparseColMat::new(
        SymbolicSparseColMat::new_checked(n_lap + soft.len(), n, a_ptr, None, a_rows),
        a_val,
    ))
}

/// An empty vector with room for `len` values, or
/// [`ProblemError::TooLarge`] naming `what` when the allocator refuses it:
/// the fallible form of `Vec::with_capacity` for arrays that scale with
/// the input, which the memory budget cannot see before they are made.
pub(crate) fn reserved<T>(what: &str, len: usize) -> Result<Vec<T>, ProblemError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| {
        ProblemError::allocation_failed(
            what,
            (len as u64).saturating_mul(std::mem::size_of::<T>() as u64),
        )
    })?;
    Ok(v)
}

/// `len` default values (zeros), fallibly as [`reserved`].
pub(crate) fn zeroed<T: Default + Clone>(what: &str, len: usize) -> Result<Vec<T>, ProblemError> {
    let mut v = reserved(what, len)?;
    v.resize(len, T::default());
    Ok(v)
}

/// An `rows × cols` matrix with entry `(i, j) = f(i, j)`, or
/// [`ProblemError::TooLarge`] naming `what` when the allocator refuses it:
/// the fallible form of `Mat::from_fn` (which panics when its allocation
/// fails) for dense blocks that scale with the input.
pub(crate) fn matrix_from_fn(
    what: &str,
    rows: usize,
    cols: usize,
    f: impl FnMut(usize, usize) -> f64,
) -> Result<Mat<f64>, ProblemError> {
    let mut m = Mat::new();
    m.try_reserve(rows, cols).map_err(|_| {
        ProblemError::allocation_failed(
            what,
            (rows as u64).saturating_mul(cols as u64).saturating_mul(8),
        )
    })?;
    m.resize_with(rows, cols, f);
    Ok(m)
}

/// An `rows × cols` matrix of zeros, fallibly as [`matrix_from_fn`].
pub(crate) fn zero_matrix(what: &str, rows: usize, cols: usize) -> Result<Mat<f64>, ProblemError> {
    matrix_from_fn(what, rows, cols, |_, _| 0.0)
}

#[cfg(test)]
mod tests {
    use faer::sparse::Triplet;

    use super::*;
    use crate::constraints::{Constraint, ConstraintKind};

    /// Hard `p_2 = (1, 2, 3)`, soft (weight 4) `p_0 − p_1 = (0, 0, 1)`,
    /// hard on-edge `0.75 p_1 + 0.25 p_0 = (5, 6, 7)`.
    fn three() -> ConstraintSet {
        ConstraintSet::from_vec(vec![
            Constraint::hard(ConstraintKind::Position {
                vertex: 2,
                target: [1.0, 2.0, 3.0],
            }),
            Constraint::soft(
                ConstraintKind::Relative {
                    vertices: [0, 1],
                    vector: [0.0, 0.0, 1.0],
                },
                4.0,
            ),
            Constraint::hard(ConstraintKind::Edge {
                vertices: [1, 0],
                t: 0.75,
                target: [5.0, 6.0, 7.0],
            }),
        ])
        .unwrap()
    }

    #[test]
    fn rows_split_into_hard_and_soft_in_list_order() {
        let (places, hard, soft) = split_rows(&three(), SoftWeightScale::NONE).unwrap();
        assert_eq!(
            places,
            [RowPlace::Hard(0), RowPlace::Soft(0), RowPlace::Hard(1)]
        );
        assert_eq!(hard, [0, 2]);
        assert_eq!(
            soft,
            [SoftRow {
                index: 1,
                weight: 4.0,
                row_weight: 4.0
            }]
        );
    }

    #[test]
    fn soft_row_weights_are_scaled_and_checked() {
        let scale = SoftWeightScale {
            length: 2.0,
            power: 2,
        };
        assert_eq!(soft_row(3, 0.5, scale).unwrap().row_weight, 2.0);
        assert_eq!(
            soft_row(3, -1.0, scale),
            Err(NumericalError::SoftWeightOutOfRange {
                index: 3,
                weight: -1.0,
                length: 2.0,
                power: 2
            })
        );
        assert_eq!(
            soft_row(4, 1e200, SoftWeightScale::NONE),
            Err(NumericalError::SoftWeightTooLarge {
                index: 4,
                weight: 1e200,
                row_weight: 1e200,
                power: 0
            })
        );
    }

    #[test]
    fn hard_rows_and_soft_columns_are_assembled_sorted() {
        let set = three();
        let (b, d) = assemble_hard(&set, &[0, 2], 3);
        assert_eq!(b.symbolic().row_ptr(), [0, 1, 3]);
        assert_eq!(b.symbolic().col_idx(), [2, 0, 1]);
        assert_eq!(b.val(), [1.0, 0.25, 0.75]);
        assert_eq!(d, faer::mat![[1.0, 2.0, 3.0], [5.0, 6.0, 7.0]]);
        // L = 2 I (3 × 3); the soft row 3 is 4 (p_0 − p_1).
        let l =
            SparseColMat::try_new_from_triplets(3, 3, &[0, 1, 2].map(|i| Triplet::new(i, i, 2.0)))
                .unwrap();
        let soft = [SoftRow {
            index: 1,
            weight: 4.0,
            row_weight: 4.0,
        }];
        let a = assemble_a(&l, &set, &soft).unwrap();
        assert_eq!((a.nrows(), a.ncols()), (4, 3));
        assert_eq!(a.symbolic().col_ptr(), [0, 2, 4, 5]);
        assert_eq!(a.symbolic().row_idx(), [0, 3, 1, 3, 2]);
        assert_eq!(a.val(), [2.0, 4.0, 2.0, -4.0, 2.0]);
    }
}
