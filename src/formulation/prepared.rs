//! A precomputed system ([`Prepared`]): the value a formulation's
//! precompute returns, which solves for new right-hand sides of the same
//! matrices without refactoring.

use faer::sparse::SparseColMat;
use faer::{Mat, MatMut};

use crate::condition::ConditionEstimate;
use crate::error::Error;
use crate::problem::LseProblem;

/// A precomputed system: solves for new right-hand sides (`C`, `D`) of the
/// same matrices without refactoring.
pub trait Prepared: Send {
    /// Solves for the current `C` and `D` of `problem` (which must have the
    /// matrices the system was prepared with, and
    /// [`RHS_BLOCK`](crate::problem::RHS_BLOCK) `= 3` right-hand-side
    /// columns: [`crate::solver::LseSolver`] splits other widths). Returns
    /// `X` (n × 3).
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error>;

    /// One step of iterative refinement (see [`refine`]): the correction
    /// `ΔX` to add to `x`, an approximation of the last [`Prepared::solve`]'s
    /// result or of a refined one, computed from the residuals of the
    /// original rows of `problem` and the existing factor (no new
    /// factorisation). `None` when nothing was factored (every unknown is
    /// fixed, so `x` is exact). State that a step advances (the KKT
    /// multipliers, the penalty method's shifted targets) changes only
    /// through [`Prepared::accept_correction`].
    fn correction(&mut self, problem: &LseProblem, x: &Mat<f64>)
    -> Result<Option<Mat<f64>>, Error>;

    /// Commits the state of the last [`Prepared::correction`] after the
    /// caller added it to `x`.
    fn accept_correction(&mut self) {}

    /// [`Prepared::solve`] into `out` (n × 3). The default copies the
    /// result of `solve`; formulations that keep their buffers from
    /// precompute (the null-space method) write `out` directly and allocate
    /// nothing.
    fn solve_into(&mut self, problem: &LseProblem, mut out: MatMut<'_, f64>) -> Result<(), Error> {
        let x = self.solve(problem)?;
        out.copy_from(&x);
        Ok(())
    }

    /// Solves for the current `C` and `D` of `problem` with **any** number
    /// `k` of columns in one pass (`out` n × k), when the formulation's
    /// kernels allow it; `Ok(false)` (and `out` untouched) when it solves
    /// [`RHS_BLOCK`](crate::problem::RHS_BLOCK) columns at a time only (the
    /// default). One pass over the factor for all `k` columns costs far less
    /// than `⌈k/3⌉` passes: what a response basis of `3 + 4G` columns
    /// needs.
    fn solve_wide_into(
        &mut self,
        _problem: &LseProblem,
        _out: MatMut<'_, f64>,
    ) -> Result<bool, Error> {
        Ok(false)
    }

    /// How many times a solve of this system had to factor its matrix
    /// again ([`crate::backend::spd::SpdFactor::refactorizations`]); `0`
    /// by default.
    fn refactorizations(&self) -> usize {
        0
    }

    /// Rows of `B` that the method does not enforce because they depend on
    /// earlier ones (increasing). Empty for methods that enforce all rows
    /// or fail.
    fn skipped(&self) -> &[usize];

    /// `false` for methods that only approximate hard constraints
    /// (penalty), whose residuals are then reported but not "kept exactly".
    fn exact(&self) -> bool {
        true
    }

    /// An estimate of the 2-norm condition number of the matrix that was
    /// factored ([`Prepared::factored_matrix`]), by Lanczos on the matrix and
    /// on its inverse through the factor (see [`crate::condition`]). Costs
    /// up to a few hundred products and solves, hence on demand; store the
    /// result in [`crate::report::Report::condition_estimate`].
    ///
    /// Fails when nothing was factored (every unknown fixed by the hard
    /// constraints) or when a solve produces a non-finite vector.
    fn estimate_condition(&mut self) -> Result<ConditionEstimate, Error>;

    /// The matrix that was factored, as a **full symmetric** matrix (both
    /// triangles, sorted row indices) in the formulation's own unknown order
    /// (not the fill-reducing permutation): the free directions `z` for
    /// [`NullSpaceQr`], the vertices for [`Penalty`], the unknown
    /// (non-fixed) vertices in increasing order for [`Elimination`], and the
    /// vertices followed by the scaled multipliers for [`Kkt`]. `None` when
    /// nothing was factored.
    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>>;
}
