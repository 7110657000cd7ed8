//! The `LDLᵀ` seam: the traits a sparse symmetric indefinite back end
//! implements ([`LdltBackend`], [`LdltSymbolic`], [`LdltFactor`]) and the
//! pivot protocol they share ([`Pivot`], [`PivotRule`], [`PivotFault`],
//! [`first_fault`]). A leaf under [`crate::backend::ldlt`], which
//! re-exports it: the back ends import it, it imports none of them.

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use crate::backend::spd::check_factor_size;
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;

/// A sparse `LDLᵀ` family: the crate's own ([`LdltKind`]'s catalogue) or
/// one brought from outside (docs/backends.md,
/// `lse_deform::testing::conformance::ldlt`).
pub trait LdltBackend: Send + Sync {
    /// The back end's name in reports and `compare` rows.
    fn name(&self) -> BackendName;

    /// Symbolic factorisation of the lower-triangle pattern `lower`
    /// (square, sorted rows, every diagonal entry stored) with the unknowns
    /// eliminated in `order` (`order[i]` is the unknown eliminated `i`-th;
    /// a permutation of `0..lower.ncols()`).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError>;

    /// [`LdltBackend::analyze`] with the factorisations on `threads`
    /// (called only when a count is asked for). The default ignores the
    /// count: the report's `"threads"` is then what
    /// [`LdltSymbolic::plan_used`] says (`null` unless the back end says).
    fn analyze_on_threads(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        threads: Threads,
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let _ = threads;
        self.analyze(lower, order)
    }

    /// Refuses, before [`LdltBackend::analyze`], an `order` whose factor
    /// would not fit in `budget` when the analysis itself would allocate
    /// the factor's structure (faer's does: with the natural ordering of
    /// the KKT matrix it held several times the budget before the check
    /// after it). `matrix` names the matrix for the message. By default
    /// nothing is checked here ([`LdltSymbolic::check_budget`] remains).
    fn check_order_budget(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        budget: MemoryBudget,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let _ = (lower, order, budget, matrix);
        Ok(())
    }
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait LdltSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed), without
    /// pivoting. A pivot that the back end itself finds unusable (an exact
    /// zero) does not fail the call: it is reported by
    /// [`LdltFactor::pivot_fault`], so that the caller's rule names it.
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError>;

    /// Number of `f64` values the numeric factor will store, known after
    /// analysis (what the memory budget is checked against).
    fn factor_values(&self) -> usize;

    /// Refuses a factorisation that would not fit in `budget`: by default
    /// [`check_factor_size`] on [`LdltSymbolic::factor_values`]; MUMPS
    /// checks its own estimate on every rank.
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        check_factor_size(self.factor_values(), dim, matrix, budget)
    }

    /// The threads this analysis's factorisations use (the ordering is
    /// always the caller's); `None` by default: not said.
    fn threads_used(&self) -> Option<usize> {
        None
    }
}

/// A pivot `d_i` of the factorisation, in elimination order, with the
/// magnitude it was computed from: `d_i = K_jj − Σ_{k<i} L_ik² d_k` for the
/// unknown `j` eliminated `i`-th, and
/// `magnitude = |K_jj| + Σ_{k<i} L_ik² |d_k|` (its rounding error is a
/// small multiple of `ε` times that).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pivot {
    /// The original unknown `j`.
    pub unknown: usize,
    /// `d_i`.
    pub value: f64,
    /// `|K_jj| + Σ_{k<i} L_ik² |d_k|`.
    pub magnitude: f64,
}

/// What the caller requires of the pivots `d_i` of a static-order
/// `LDLᵀ`: the unknowns `j < positive` must have `d > 0`, the others
/// `d < 0`, each with `|d| > tolerance · magnitude` (the magnitude it was
/// computed from, [`Pivot::magnitude`]). For the KKT matrix
/// `[AᵀA sBᵀ; sB 0]`, `positive = n` (the vertices) and the tolerance is
/// the KKT formulation's pivot tolerance `1000 ε` (docs/formulations.md
/// §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PivotRule {
    /// Unknowns below this index expect a positive pivot, the rest a
    /// negative one.
    pub positive: usize,
    /// The least `|d| / magnitude` of a pivot that keeps its digits.
    pub tolerance: f64,
}

impl PivotRule {
    /// Whether `pivot` keeps the rule (a non-finite value or ratio never
    /// does).
    pub fn holds(&self, pivot: &Pivot) -> bool {
        let ratio = pivot.value.abs() / pivot.magnitude;
        let right_sign = if pivot.unknown < self.positive {
            pivot.value > 0.0
        } else {
            pivot.value < 0.0
        };
        pivot.value.is_finite() && ratio.is_finite() && ratio > self.tolerance && right_sign
    }
}

/// The first pivot, in elimination order, that breaks a [`PivotRule`], as
/// the back end knows it.
#[derive(Clone, Debug, PartialEq)]
pub enum PivotFault {
    /// A computed pivot: its position in the elimination order (of `dim`
    /// pivots) and the pivot with its magnitude.
    Computed {
        /// 0-based position in the elimination order.
        position: usize,
        /// Number of pivots.
        dim: usize,
        /// The pivot.
        pivot: Pivot,
    },
    /// A pivot the back end found null by its own test, without handing
    /// out its value: the unknown (original order), and the test in words.
    /// A back end whose elimination may merge unknowns (so that the one it
    /// flags need not be the first of a dependent group in the given
    /// order) says so by flagging; the caller may then name the group's
    /// first member itself.
    Null {
        /// The unknown.
        unknown: usize,
        /// What the back end tested, for the message.
        test: String,
    },
    /// A failure the back end met during the numeric factorisation but did
    /// not attribute to a pivot that breaks the rule: its own words.
    Reported {
        /// The back end's message.
        message: String,
    },
}

/// The first of `pivots` (in elimination order) that breaks `rule`, as a
/// [`PivotFault::Computed`]; else, when the back end reported a `failure`
/// of its own, [`PivotFault::Reported`]. For back ends that compute their
/// pivots.
pub fn first_fault(pivots: &[Pivot], rule: PivotRule, failure: Option<&str>) -> Option<PivotFault> {
    let dim = pivots.len();
    match pivots.iter().position(|p| !rule.holds(p)) {
        Some(position) => Some(PivotFault::Computed {
            position,
            dim,
            pivot: pivots[position],
        }),
        None => failure.map(|message| PivotFault::Reported {
            message: message.to_string(),
        }),
    }
}

/// A numeric factorisation `P K Pᵀ = L D Lᵀ`.
pub trait LdltFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `K X = B` in place for all columns of `rhs` together.
    ///
    /// Errors: a typed [`NumericalError`] naming what failed; `rhs` is
    /// then unspecified. Never non-finite values as a signal.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError>;

    /// Number of stored entries of `L` (lower triangle, diagonal included,
    /// the diagonal holding `D`).
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices.
    fn bytes(&self) -> usize;

    /// The first pivot that breaks `rule` ([`PivotFault`]), `None` when
    /// every pivot keeps it; `lower` is the matrix factored (for `K_jj`).
    fn pivot_fault(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
        rule: PivotRule,
    ) -> Option<PivotFault>;

    /// What the back end reports of this factorisation beyond the generic
    /// record, as a section of the report; `None` by default.
    fn facts(&self) -> Option<BackendFacts> {
        None
    }

    /// How many times a solve had to factor the matrix again; `0` by
    /// default ([`crate::backend::spd::SpdFactor::refactorizations`]).
    fn refactorizations(&self) -> usize {
        0
    }
}
