//! Sparse symmetric positive definite solvers.
//!
//! A back end analyses a sparsity pattern once ([`SpdBackend::analyze`]:
//! fill-reducing ordering and symbolic factorisation) and then factors any
//! matrix with that pattern numerically ([`SpdSymbolic::factorize`]) as
//! often as needed (a new penalty weight, new soft weights), without a new
//! analysis. Matrices are given as their **lower triangle** in CSC form with
//! sorted row indices, diagonal included.
//!
//! Numerical failure is a typed [`NumericalError`] naming the failing pivot
//! in the *original* (unpermuted) ordering: either a pivot that is not
//! positive, or a pivot that lost all its digits to cancellation
//! ([`BREAKDOWN_RATIO`]).

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, MatRef};

pub use crate::backend::kinds::SpdKind;
use crate::backend::ordering::{FactorPlan, PlanUsed};
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

#[cfg(feature = "suitesparse")]
mod cholmod;
mod factor_size;
mod faer_llt;
mod nalgebra;
mod permuted;
mod tree_split;
mod triangular;

#[cfg(feature = "suitesparse")]
pub use cholmod::Cholmod;
pub(crate) use factor_size::factor_size;
pub use faer_llt::FaerLlt;
pub use nalgebra::NalgebraCsc;

/// Threshold on `L_kk² / A_kk` below which a completed Cholesky
/// factorisation is declared broken down.
///
/// The computed pivot `L_kk² = A_kk − Σ_j L_kj²` carries a rounding error of a
/// small multiple of `ε·A_kk` (each `L_kj² ≤ A_kk` for an SPD matrix), so a
/// ratio below `1000 ε ≈ 2.2e-13` leaves at most about three significant
/// digits in the pivot. Since `L_kk² ≥ λ_min` and `A_kk ≤ λ_max`, such a ratio
/// also certifies `κ(A) > 4.5e12`: the solve would lose twelve or more of
/// sixteen digits. We stop there rather than return such a solution.
pub const BREAKDOWN_RATIO: f64 = 1000.0 * f64::EPSILON;

/// Refuses a factorisation whose factor, as the symbolic analysis sized it,
/// would not fit in the solve's memory `budget` ([`crate::limits`]) on top
/// of what the process holds ([`MemoryBudget::check_on_top`]): `matrix`
/// names the matrix for the message. The back end's workspace is not
/// counted (faer's back ends count theirs in their own check).
pub fn check_factor_size(
    factor_nnz: usize,
    dim: usize,
    matrix: &str,
    budget: MemoryBudget,
) -> Result<(), ProblemError> {
    let bytes = (factor_nnz as u64).saturating_mul(crate::limits::FACTOR_BYTES_PER_ENTRY);
    budget.check_on_top(bytes, || {
        format!("the Cholesky factor of {matrix} ({dim} unknowns, {factor_nnz} entries after fill-in) would need")
    })
    .map_err(|detail| ProblemError::TooLarge { detail })
}

/// A sparse SPD solver family: the crate's own ([`SpdKind`]'s catalogue)
/// or one brought from outside (docs/backends.md states the contract,
/// `lse_deform::testing::conformance::spd` checks it).
pub trait SpdBackend: Send + Sync {
    /// The back end's name in reports, `compare` rows, CSVs and plots
    /// (a built-in's word; an outside back end chooses its own).
    fn name(&self) -> BackendName;

    /// Symbolic analysis (ordering + symbolic factorisation) of the lower
    /// triangle pattern `lower` (square, sorted rows, diagonal present).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError>;

    /// Symbolic analysis under `plan`: its permutation instead of the back
    /// end's own ordering (when it has one), on its threads. Called only
    /// when the plan asks for something ([`FactorPlan::is_own`] is false);
    /// otherwise [`SpdBackend::analyze`] runs, unchanged.
    ///
    /// The default, for a back end that takes neither: the permutation is
    /// applied to the matrix (the back end analyses `P A Pᵀ`, and may
    /// reorder it again by itself; the report says `"… (applied to the
    /// matrix)"`), and the threads are the back end's own (the report's
    /// `"threads"` is then `null` unless it says,
    /// [`SpdSymbolic::plan_used`]). The crate's back ends override it
    /// (docs/equal-terms.md lists what each takes).
    fn analyze_planned(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
        permuted::analyze_permuted(self, lower, plan)
    }
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait SpdSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed). Several
    /// factors of one analysis may live at once, each solving with its own
    /// matrix.
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError>;

    /// Number of stored entries of the factor `L` (lower triangle, diagonal
    /// included), known after analysis; for a back end that stores no
    /// factor (an iterative one), what it stores instead, in `f64` values.
    fn factor_nnz(&self) -> usize;

    /// Refuses a factorisation that would not fit in `budget`: by default
    /// [`check_factor_size`] on [`SpdSymbolic::factor_nnz`]; a back end
    /// that knows better (one that counts every rank) checks its own
    /// estimate. `dim` and `matrix` are for the message.
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        check_factor_size(self.factor_nnz(), dim, matrix, budget)
    }

    /// The ordering and threads this analysis's factorisations use, as the
    /// report states them; by default `own` and not said (`None`).
    fn plan_used(&self) -> PlanUsed {
        PlanUsed {
            ordering: "own".into(),
            threads: None,
        }
    }
}

/// A numeric factorisation `P A Pᵀ = L Lᵀ` (or whatever an outside back
/// end keeps to solve with `A`).
pub trait SpdFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `A X = B` in place for all columns of `rhs` together.
    ///
    /// Errors: a typed [`NumericalError`] naming what failed (a file of an
    /// out-of-core factor, the back end's own code); `rhs` is then
    /// unspecified. A solve never signals failure by non-finite values.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError>;

    /// Number of stored entries of `L`.
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices (what a solve must
    /// read twice: the bandwidth floor of a solve).
    fn bytes(&self) -> usize;

    /// What the back end reports of this factorisation beyond the generic
    /// record, as a section of the report (MUMPS: its ranks); `None` by
    /// default.
    fn facts(&self) -> Option<BackendFacts> {
        None
    }

    /// How many times a solve had to factor the matrix again (a back end
    /// that keeps one numeric factorisation per analysis, when another
    /// factor of the same analysis solved in between); `0` by default.
    fn refactorizations(&self) -> usize {
        0
    }
}

/// Solves with a factor, returning the solution (convenience).
///
/// Errors: the factor's ([`SpdFactor::solve_in_place`]).
pub fn solve(
    factor: &mut dyn SpdFactor,
    rhs: MatRef<'_, f64>,
) -> Result<faer::Mat<f64>, NumericalError> {
    let mut x = rhs.to_owned();
    factor.solve_in_place(x.as_mut())?;
    Ok(x)
}

/// The breakdown check shared by every back end: rejects a completed factor
/// `P A Pᵀ = L Lᵀ` whose pivot ratio `L_kk² / A_kk` is below
/// [`BREAKDOWN_RATIO`] or not finite, naming the worst such pivot.
///
/// `l_diag[k]` is `L_kk` in the permuted order, `fwd[k]` the original index
/// of permuted unknown `k`, `lower` the factored matrix (lower triangle,
/// original order). A missing diagonal entry counts as `A_kk = 0`, which
/// makes the ratio infinite or NaN; NaN is rejected.
pub(crate) fn check_breakdown(
    l_diag: &[f64],
    fwd: &[usize],
    lower: SparseColMatRef<'_, usize, f64>,
) -> Result<(), NumericalError> {
    let (col_ptr, row_idx, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let a_diag = |j: usize| -> f64 {
        let range = col_ptr[j]..col_ptr[j + 1];
        row_idx[range.clone()]
            .iter()
            .position(|&i| i == j)
            .map(|p| val[range.start + p])
            .unwrap_or(0.0)
    };
    // Report the worst pivot, not the first below the threshold.
    let mut worst: Option<(usize, f64)> = None;
    for (k, &l) in l_diag.iter().enumerate() {
        let orig = fwd.get(k).copied().unwrap_or(k);
        let ratio = l * l / a_diag(orig);
        let healthy = ratio >= BREAKDOWN_RATIO; // false for NaN
        if !healthy && worst.is_none_or(|(_, r)| ratio < r || ratio.is_nan()) {
            worst = Some((orig, ratio));
        }
    }
    match worst {
        None => Ok(()),
        Some((unknown, ratio)) => Err(NumericalError::Breakdown {
            matrix: String::new(),
            unknown,
            vertex: None,
            ratio,
            threshold: BREAKDOWN_RATIO,
        }),
    }
}
