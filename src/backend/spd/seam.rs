//! The SPD seam: the traits a sparse SPD back end implements
//! ([`SpdBackend`], [`SpdSymbolic`], [`SpdFactor`]), the checks every back
//! end shares ([`BREAKDOWN_RATIO`], [`check_factor_size`]) and
//! [`SpdBackend::analyze_planned`]'s default for a back end that takes no
//! given ordering (the permutation applied to the matrix). A leaf under
//! [`crate::backend::spd`], which re-exports it: the back ends beside it
//! import it, it imports none of them.

use std::sync::Arc;

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Mat, MatMut, MatRef};

use crate::backend::ordering::{FactorPlan, PlanUsed, inverse};
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

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
        analyze_permuted(self, lower, plan)
    }

    /// Refuses, before [`SpdBackend::analyze_planned`], a plan whose
    /// factor would not fit in `budget` when the back end's analysis
    /// itself would allocate the factor's pattern (faer's does: with a
    /// fill-heavy ordering such as `natural` it held several times the
    /// budget before the check after it). `matrix` names the matrix for
    /// the message. By default nothing is checked here (the check after
    /// the analysis, [`SpdSymbolic::check_budget`], remains).
    fn check_plan_budget(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        plan: &FactorPlan,
        budget: MemoryBudget,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        let _ = (lower, plan, budget, matrix);
        Ok(())
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

// A given ordering for a back end that has none to take (what
// `analyze_planned` does by default, for back ends from outside): the
// permutation is applied to the matrix. The back end analyses and factors
// `P A Pᵀ` (its lower triangle), and a solve permutes the right-hand sides
// in and the solution out; the report then says `"<ordering> (applied to
// the matrix)"`, since the back end may reorder the permuted matrix again by
// itself.

/// The lower triangle of `P A Pᵀ` for `perm[i]` eliminated `i`-th: its
/// pattern, and where each input entry lands.
struct PermutedPattern {
    pattern: SymbolicSparseColMat<usize>,
    /// `place[p]`: the position in the permuted values of input entry `p`
    /// (`usize::MAX` for an entry above the diagonal, which is ignored).
    place: Vec<usize>,
}

impl PermutedPattern {
    /// The permuted lower triangle of `lower` (upper entries ignored).
    fn new(lower: SymbolicSparseColMatRef<'_, usize>, perm: &[usize]) -> Self {
        let n = lower.ncols();
        let inv = inverse(perm);
        let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(lower.compute_nnz());
        for j in 0..n {
            for (p, &i) in lower.col_range(j).zip(lower.row_idx_of_col_raw(j)) {
                if i >= j {
                    let (a, b) = (inv[i], inv[j]);
                    entries.push((a.min(b), a.max(b), p));
                }
            }
        }
        entries.sort_unstable();
        let mut col_ptr = vec![0usize; n + 1];
        let mut rows = Vec::with_capacity(entries.len());
        let mut place = vec![usize::MAX; lower.row_idx().len()];
        for (k, &(c, r, p)) in entries.iter().enumerate() {
            col_ptr[c + 1] += 1;
            rows.push(r);
            place[p] = k;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows);
        PermutedPattern { pattern, place }
    }

    /// The permuted matrix with the values of `lower` (same pattern as
    /// analysed).
    fn values(&self, lower: SparseColMatRef<'_, usize, f64>) -> SparseColMat<usize, f64> {
        let mut values = vec![0.0; self.pattern.row_idx().len()];
        for (p, &v) in lower.val().iter().enumerate() {
            if let Some(&k) = self.place.get(p).filter(|&&k| k != usize::MAX) {
                values[k] += v;
            }
        }
        SparseColMat::new(self.pattern.clone(), values)
    }
}

/// [`SpdBackend::analyze_planned`]'s default: `backend` analyses the
/// permuted matrix when the plan has a permutation, its own otherwise.
pub(crate) fn analyze_permuted<B: SpdBackend + ?Sized>(
    backend: &B,
    lower: SymbolicSparseColMatRef<'_, usize>,
    plan: &FactorPlan,
) -> Result<Box<dyn SpdSymbolic>, NumericalError> {
    let Some(perm) = plan.permutation.clone() else {
        return backend.analyze(lower);
    };
    let permuted = PermutedPattern::new(lower, &perm);
    let inner = backend.analyze(permuted.pattern.as_ref())?;
    let ordering = format!("{} (applied to the matrix)", plan.ordering);
    Ok(Box::new(PermutedSymbolic {
        inner,
        permuted,
        perm,
        ordering,
    }))
}

struct PermutedSymbolic {
    inner: Box<dyn SpdSymbolic>,
    permuted: PermutedPattern,
    perm: Arc<[usize]>,
    ordering: String,
}

impl SpdSymbolic for PermutedSymbolic {
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError> {
        let matrix = self.permuted.values(lower);
        let inner = self.inner.factorize(matrix.as_ref()).map_err(|e| match e {
            NumericalError::NotPositiveDefinite {
                matrix,
                unknown,
                vertex,
                pivot,
            } => NumericalError::NotPositiveDefinite {
                matrix,
                unknown: self.perm.get(unknown).copied().unwrap_or(unknown),
                vertex,
                pivot,
            },
            other => other,
        })?;
        Ok(Box::new(PermutedFactor {
            inner,
            perm: Arc::clone(&self.perm),
        }))
    }

    fn factor_nnz(&self) -> usize {
        self.inner.factor_nnz()
    }

    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        self.inner.check_budget(budget, dim, matrix)
    }

    fn plan_used(&self) -> PlanUsed {
        PlanUsed {
            ordering: self.ordering.clone().into(),
            threads: self.inner.plan_used().threads,
        }
    }
}

struct PermutedFactor {
    inner: Box<dyn SpdFactor>,
    perm: Arc<[usize]>,
}

impl SpdFactor for PermutedFactor {
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    /// `A X = B` as `(P A Pᵀ)(P X) = P B`.
    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) -> Result<(), NumericalError> {
        let (n, k) = (rhs.nrows(), rhs.ncols());
        let mut permuted = Mat::<f64>::zeros(n, k);
        for (i, &p) in self.perm.iter().enumerate() {
            for c in 0..k {
                permuted[(i, c)] = rhs[(p, c)];
            }
        }
        self.inner.solve_in_place(permuted.as_mut())?;
        for (i, &p) in self.perm.iter().enumerate() {
            for c in 0..k {
                rhs[(p, c)] = permuted[(i, c)];
            }
        }
        Ok(())
    }

    fn nnz(&self) -> usize {
        self.inner.nnz()
    }

    fn bytes(&self) -> usize {
        self.inner.bytes()
    }

    fn facts(&self) -> Option<BackendFacts> {
        self.inner.facts()
    }

    fn refactorizations(&self) -> usize {
        self.inner.refactorizations()
    }
}
