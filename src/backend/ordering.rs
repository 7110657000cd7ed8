//! What a factorisation is asked to use: the fill-reducing permutation,
//! computed once per matrix from [`FillOrdering`] ([`FactorPlan::new`]),
//! and the thread count; and what it used ([`PlanUsed`]), which the
//! report's `"ordering"` and `"threads"` state (docs/equal-terms.md).

use std::borrow::Cow;
use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::amd;

use crate::error::ProblemError;
use crate::resources::{FillOrdering, Threads};

/// The plan of one factorisation: a permutation (`None`: the back end's
/// own ordering) and the threads.
#[derive(Clone, Debug, PartialEq)]
pub struct FactorPlan {
    /// `perm[i]`: the unknown (of the matrix factored) eliminated `i`-th;
    /// `None`: the back end orders by itself.
    pub permutation: Option<Arc<[usize]>>,
    /// The word of the ordering the permutation came from (`amd`, `metis`,
    /// `natural`, `given`), for the report.
    pub ordering: &'static str,
    /// The threads to use.
    pub threads: Threads,
}

/// What a factorisation used, as the report states it.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanUsed {
    /// `own (amd)`, `own (scotch)`, … for a back end's own ordering (the
    /// method it chose in brackets when it says); `amd`, `metis`,
    /// `natural`, `given` when one was given; `… (applied to the matrix)`
    /// when a back end without orderings of its own factored the permuted
    /// matrix.
    pub ordering: Cow<'static, str>,
    /// The threads the factorisation ran on; `None` when the back end does
    /// not say (one from outside).
    pub threads: Option<usize>,
}

impl FactorPlan {
    /// The plan for the matrix with lower-triangle pattern `lower`, whose
    /// unknown `k` is the problem's unknown `original_of(k)` (of
    /// `n_original`): the permutation `ordering` asks for, computed on
    /// `lower` (AMD, METIS), the identity (natural), or the order a given
    /// permutation of the problem's unknowns induces on the matrix's.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for a given permutation
    /// that is not one of `0..n_original`, or METIS in a build without it.
    pub fn new(
        ordering: &FillOrdering,
        threads: Threads,
        lower: SymbolicSparseColMatRef<'_, usize>,
        original_of: &dyn Fn(usize) -> usize,
        n_original: usize,
    ) -> Result<FactorPlan, ProblemError> {
        let n = lower.ncols();
        let permutation: Option<Vec<usize>> = match ordering {
            FillOrdering::Own => None,
            FillOrdering::Natural => Some((0..n).collect()),
            FillOrdering::Amd => Some(amd_permutation(lower)?),
            FillOrdering::Metis => Some(metis_permutation(lower)?),
            FillOrdering::Given(order) => {
                ordering.check_unknowns(n_original)?;
                Some(induced(order, n_original, n, original_of))
            }
        };
        Ok(FactorPlan {
            permutation: permutation.map(Arc::from),
            ordering: ordering.name(),
            threads,
        })
    }

    /// The back ends' own ordering with `threads`.
    pub fn own(threads: Threads) -> FactorPlan {
        FactorPlan {
            permutation: None,
            ordering: "own",
            threads,
        }
    }

    /// Whether this plan asks for nothing (the back end's own ordering and
    /// threads).
    pub fn is_own(&self) -> bool {
        self.permutation.is_none() && self.threads == Threads::Own
    }

    /// The report's word for a back end that used this plan's permutation
    /// (`own_method` names its own ordering when there was none given).
    pub(crate) fn ordering_used(&self, own_method: &str) -> Cow<'static, str> {
        match self.permutation {
            Some(_) => Cow::Borrowed(self.ordering),
            None => Cow::Owned(format!("own ({own_method})")),
        }
    }
}

fn invalid(message: String) -> ProblemError {
    ProblemError::InvalidArgument { message }
}

/// Why faer's AMD gave no ordering: its workspace could not be had, or
/// the ordering itself failed (each with faer's words).
pub(crate) enum AmdFailure {
    Workspace(String),
    Order(String),
}

/// faer's AMD (default controls) on the pattern of `lower`: `(fwd, inv)`,
/// `fwd[i]` eliminated `i`-th (one implementation for the held ordering
/// and nalgebra's own).
pub(crate) fn amd_order(
    lower: SymbolicSparseColMatRef<'_, usize>,
) -> Result<(Vec<usize>, Vec<usize>), AmdFailure> {
    let n = lower.ncols();
    let nnz = lower.compute_nnz();
    let mut fwd = vec![0usize; n];
    let mut inv = vec![0usize; n];
    let mut mem = MemBuffer::try_new(amd::order_maybe_unsorted_scratch::<usize>(n, nnz))
        .map_err(|e| AmdFailure::Workspace(format!("{e:?}")))?;
    amd::order_maybe_unsorted(
        &mut fwd,
        &mut inv,
        lower,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| AmdFailure::Order(format!("{e:?}")))?;
    Ok((fwd, inv))
}

/// [`amd_order`]'s permutation, its failures as the plan's errors.
fn amd_permutation(lower: SymbolicSparseColMatRef<'_, usize>) -> Result<Vec<usize>, ProblemError> {
    let n = lower.ncols();
    match amd_order(lower) {
        Ok((fwd, _)) => Ok(fwd),
        Err(AmdFailure::Workspace(e)) => Err(ProblemError::TooLarge {
            detail: format!("the AMD ordering's workspace ({n} unknowns): {e}"),
        }),
        Err(AmdFailure::Order(e)) => Err(invalid(format!("the AMD ordering failed: {e}"))),
    }
}

#[cfg(feature = "suitesparse")]
fn metis_permutation(
    lower: SymbolicSparseColMatRef<'_, usize>,
) -> Result<Vec<usize>, ProblemError> {
    crate::backend::suitesparse::metis(lower)
        .map_err(|e| invalid(format!("the METIS ordering failed: {e}")))
}

#[cfg(not(feature = "suitesparse"))]
fn metis_permutation(
    _lower: SymbolicSparseColMatRef<'_, usize>,
) -> Result<Vec<usize>, ProblemError> {
    Err(invalid(crate::resources::METIS_NOT_IN_BUILD.into()))
}

/// The order `order` (a permutation of `0..n_original`, checked by
/// [`FillOrdering::check_unknowns`]) induces on the `n` unknowns of a
/// matrix whose unknown `k` is `original_of(k)`.
fn induced(
    order: &[usize],
    n_original: usize,
    n: usize,
    original_of: &dyn Fn(usize) -> usize,
) -> Vec<usize> {
    let mut position = vec![usize::MAX; n_original];
    for (i, &unknown) in order.iter().enumerate() {
        position[unknown] = i;
    }
    let mut local: Vec<usize> = (0..n).collect();
    local.sort_by_key(|&k| position[original_of(k)]);
    local
}

/// The inverse of `perm` (`inverse[perm[i]] = i`).
pub fn inverse(perm: &[usize]) -> Vec<usize> {
    let mut inv = vec![0; perm.len()];
    for (i, &p) in perm.iter().enumerate() {
        inv[p] = i;
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::sparse::SymbolicSparseColMat;

    /// The lower triangle of an arrow matrix: unknown 0 coupled to all.
    fn arrow(n: usize) -> SymbolicSparseColMat<usize> {
        let mut col_ptr = vec![0];
        let mut rows = Vec::new();
        for j in 0..n {
            rows.push(j);
            if j == 0 {
                rows.extend(1..n);
            }
            col_ptr.push(rows.len());
        }
        SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows)
    }

    #[test]
    fn amd_puts_the_hub_of_an_arrow_last() {
        // Eliminating the hub first fills the whole matrix; AMD (minimum
        // degree) eliminates every leaf first (degree 1) and the hub last.
        let a = arrow(6);
        let plan =
            FactorPlan::new(&FillOrdering::Amd, Threads::Own, a.as_ref(), &|k| k, 6).unwrap();
        assert_eq!(plan.permutation.unwrap().last(), Some(&0));
    }

    #[test]
    fn a_given_order_induces_the_subset_order_and_is_checked() {
        // Matrix unknowns 0, 1, 2 are the problem's 4, 1, 3.
        let map = [4usize, 1, 3];
        let a = arrow(3);
        let order: Arc<[usize]> = Arc::from(vec![3usize, 0, 4, 2, 1]);
        let plan = FactorPlan::new(
            &FillOrdering::Given(order),
            Threads::Own,
            a.as_ref(),
            &|k| map[k],
            5,
        )
        .unwrap();
        // Positions: 3 → 0, 4 → 2, 1 → 4: matrix unknowns 2, 0, 1.
        assert_eq!(&*plan.permutation.unwrap(), &[2, 0, 1]);
        for bad in [
            vec![0usize, 1, 2, 3],
            vec![0, 1, 2, 3, 3],
            vec![0, 1, 2, 3, 5],
        ] {
            let err = FactorPlan::new(
                &FillOrdering::Given(Arc::from(bad)),
                Threads::Own,
                a.as_ref(),
                &|k| map[k],
                5,
            )
            .unwrap_err();
            assert!(matches!(err, ProblemError::InvalidArgument { .. }), "{err}");
        }
        assert_eq!(inverse(&[2, 0, 1]), vec![1, 2, 0]);
    }
}
