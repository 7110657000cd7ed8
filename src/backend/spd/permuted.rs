//! A given ordering for a back end that has none to take: the permutation
//! is applied to the matrix. The back end analyses and factors
//! `P A Pᵀ` (its lower triangle), and a solve permutes the right-hand
//! sides in and the solution out. What [`SpdBackend::analyze_planned`]
//! does by default, for back ends from outside; the report then says
//! `"<ordering> (applied to the matrix)"`, since the back end may reorder
//! the permuted matrix again by itself.

use std::sync::Arc;

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Mat, MatMut};

use super::{SpdBackend, SpdFactor, SpdSymbolic};
use crate::backend::BackendFacts;
use crate::backend::ordering::{FactorPlan, PlanUsed, inverse};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

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
