//! The driver of a solve, for any [`LseProblem`] — a mesh's (through
//! [`crate::Deformer`]) or one built from its matrices
//! ([`LseProblem::from_parts`]): precompute with a [`Formulation`], solve
//! for the current right-hand sides as often as needed, and the [`Report`].
//!
//! ```
//! use faer::Mat;
//! use faer::sparse::{SparseColMat, Triplet};
//! use lse_deform::problem::LseProblem;
//! use lse_deform::solver::LseSolver;
//! use lse_deform::NullSpaceQr;
//!
//! // min ‖x − c‖ subject to x0 + x1 + x2 = 1, one right-hand side.
//! let a = SparseColMat::<usize, f64>::try_new_from_triplets(
//!     3, 3, &[Triplet::new(0, 0, 1.0), Triplet::new(1, 1, 1.0), Triplet::new(2, 2, 1.0)],
//! ).unwrap();
//! let b = SparseColMat::<usize, f64>::try_new_from_triplets(
//!     1, 3, &[Triplet::new(0, 0, 1.0), Triplet::new(0, 1, 1.0), Triplet::new(0, 2, 1.0)],
//! ).unwrap();
//! let c = Mat::from_fn(3, 1, |i, _| i as f64);
//! let d = Mat::from_fn(1, 1, |_, _| 1.0);
//! let problem = LseProblem::from_parts(a.as_ref(), c.as_ref(), b.as_ref(), d.as_ref()).unwrap();
//! let mut solver = LseSolver::new(problem);
//! solver.precompute(&NullSpaceQr::default()).unwrap();
//! let x = solver.solve().unwrap();
//! // The projection of c = (0, 1, 2) onto the plane: c − (Σc − 1)/3.
//! assert!((x[(0, 0)] + 2.0 / 3.0).abs() < 1e-14);
//! assert!((x[(2, 0)] - 4.0 / 3.0).abs() < 1e-14);
//! assert_eq!(solver.report().rank, Some(1));
//! ```
//!
//! **Right-hand-side blocks.** Formulations solve [`RHS_BLOCK`] `= 3`
//! columns at a time (their kernels interleave x, y, z). A problem with
//! `k ≠ 3` columns is solved in `⌈k/3⌉` blocks of three, the last padded
//! with zero columns; each block costs what a mesh solve costs.
//!
//! **Singular problems.** For a general problem a factorisation that meets
//! a zero pivot is reported as [`NumericalError::FreeUnknown`] naming the
//! unknown of `X` the pivot belongs to; for meshes the mesh layer has
//! already ruled this out (every component pinned) and the back end's error
//! is passed on with its vertex.

use std::time::Instant;

use faer::{Mat, MatMut, MatRef};

use crate::condition::ConditionEstimate;
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{Formulation, Prepared};
use crate::problem::{LseProblem, RHS_BLOCK};
use crate::report::{Report, fill_solution_diagnostics};

/// A problem with its precomputed system and the report of the last
/// precompute and solve.
pub struct LseSolver {
    problem: LseProblem,
    system: Option<Box<dyn Prepared>>,
    /// What every precompute's report starts from (Laplacian, set-up time,
    /// mesh warnings).
    base: Report,
    report: Report,
}

impl LseSolver {
    /// A solver for `problem`, not yet precomputed.
    pub fn new(problem: LseProblem) -> LseSolver {
        LseSolver::with_report(problem, Report::default())
    }

    /// A solver whose reports start from `base` (the mesh layer's
    /// Laplacian, set-up time and warnings).
    pub fn with_report(problem: LseProblem, base: Report) -> LseSolver {
        LseSolver {
            problem,
            system: None,
            report: base.clone(),
            base,
        }
    }

    /// Precompute phase: factors the system with `formulation`. On error the
    /// previous system is gone (solve then fails until a precompute
    /// succeeds).
    pub fn precompute(&mut self, formulation: &dyn Formulation) -> Result<(), Error> {
        self.system = None;
        let mut report = self.base.clone();
        let system = formulation
            .precompute(&self.problem, &mut report)
            .map_err(|e| name_free_unknown(e, &self.problem))?;
        self.system = Some(system);
        self.report = report;
        Ok(())
    }

    /// Solve phase: `X` (n × k) for the current `C` and `D`, with the
    /// report's diagnostics (residuals, redundant and conflicting rows).
    pub fn solve(&mut self) -> Result<Mat<f64>, Error> {
        let mut x = Mat::zeros(self.problem.n(), self.problem.n_rhs());
        self.solve_into(x.as_mut())?;
        self.diagnose(x.as_ref());
        Ok(x)
    }

    /// Solve phase into `x` (n × k), without diagnostics (call
    /// [`LseSolver::diagnose`] when they are wanted): what a drag loop calls
    /// every frame. For a 3-column problem it allocates nothing with the
    /// null-space formulation on the faer back ends (the buffers were sized
    /// at precompute); other formulations allocate their temporaries.
    ///
    /// Errors: a shape mismatch of `x`, a solve before precompute, the
    /// formulation's numerical errors, and a non-finite result
    /// ([`NumericalError::NonFiniteSolution`], naming the row of `X`). On
    /// error the contents of `x` are unspecified.
    pub fn solve_into(&mut self, mut x: MatMut<'_, f64>) -> Result<(), Error> {
        let (n, k) = (self.problem.n(), self.problem.n_rhs());
        if x.nrows() != n || x.ncols() != k {
            return Err(ProblemError::Dimensions {
                message: format!(
                    "the output is {} × {}, the solution is {n} × {k}",
                    x.nrows(),
                    x.ncols()
                ),
            }
            .into());
        }
        let system = self
            .system
            .as_mut()
            .ok_or_else(|| ProblemError::BadUpdate {
                message: "solve called before precompute".into(),
            })?;
        let t = Instant::now();
        if k == RHS_BLOCK {
            system.solve_into(&self.problem, x.as_mut())?;
        } else {
            solve_in_blocks(system.as_mut(), &mut self.problem, x.as_mut())?;
        }
        self.report.timings_s.solve = t.elapsed().as_secs_f64();
        let x = x.as_ref();
        if let Some(row) = (0..n).find(|&i| (0..k).any(|c| !x[(i, c)].is_finite())) {
            return Err(NumericalError::NonFiniteSolution { vertex: row }.into());
        }
        Ok(())
    }

    /// Fills the report's solution diagnostics for `x` (the result of the
    /// last solve): residual of every kept hard row, the skipped rows split
    /// into redundant and conflicting, `‖AX − C‖`, sizes.
    pub fn diagnose(&mut self, x: MatRef<'_, f64>) -> &Report {
        let t = Instant::now();
        let skipped = self
            .system
            .as_ref()
            .map(|s| s.skipped().to_vec())
            .unwrap_or_default();
        fill_solution_diagnostics(&mut self.report, &self.problem, &x.to_owned(), &skipped);
        self.report.timings_s.diagnostics = t.elapsed().as_secs_f64();
        &self.report
    }

    /// Sets the right-hand side of constraint `index` (a 3-column problem):
    /// the matrices stay, the next solve reuses the factorisation.
    pub fn set_rhs(&mut self, index: usize, value: [f64; 3]) -> Result<(), Error> {
        self.problem.set_rhs(index, value)
    }

    /// Replaces `C` and `D` (same shapes); the next solve reuses the
    /// factorisation.
    pub fn set_rhs_matrices(
        &mut self,
        c: MatRef<'_, f64>,
        d: MatRef<'_, f64>,
    ) -> Result<(), Error> {
        self.problem.set_rhs_matrices(c, d)
    }

    /// Estimates the 2-norm condition number of the matrix the formulation
    /// factored (see [`crate::condition`]) and records it in the report.
    pub fn estimate_condition(&mut self) -> Result<&ConditionEstimate, Error> {
        let system = self
            .system
            .as_mut()
            .ok_or_else(|| ProblemError::BadUpdate {
                message: "estimate_condition called before precompute".into(),
            })?;
        let estimate = system.estimate_condition()?;
        Ok(self.report.condition_estimate.insert(estimate))
    }

    /// The prepared system of the last precompute, if any (for export).
    pub fn prepared(&self) -> Option<&dyn Prepared> {
        self.system.as_deref()
    }

    /// The report of the last precompute and solve.
    pub fn report(&self) -> &Report {
        &self.report
    }

    /// The problem.
    pub fn problem(&self) -> &LseProblem {
        &self.problem
    }
}

/// Solves a problem whose `k ≠ 3` columns are taken three at a time: each
/// block's `C` and `D` (zero-padded) are swapped into the problem, solved,
/// and swapped back before any error is returned.
fn solve_in_blocks(
    system: &mut dyn Prepared,
    problem: &mut LseProblem,
    mut x: MatMut<'_, f64>,
) -> Result<(), Error> {
    let k = problem.n_rhs();
    let (l, m, n) = (problem.a().nrows(), problem.b().nrows(), problem.n());
    let mut x_block = Mat::<f64>::zeros(n, RHS_BLOCK);
    for start in (0..k).step_by(RHS_BLOCK) {
        let width = RHS_BLOCK.min(k - start);
        let (c, d) = (problem.c(), problem.d());
        let mut c_block = Mat::from_fn(l, RHS_BLOCK, |i, j| {
            if j < width { c[(i, start + j)] } else { 0.0 }
        });
        let mut d_block = Mat::from_fn(m, RHS_BLOCK, |i, j| {
            if j < width { d[(i, start + j)] } else { 0.0 }
        });
        problem.swap_rhs(&mut c_block, &mut d_block);
        let result = system.solve_into(problem, x_block.as_mut());
        problem.swap_rhs(&mut c_block, &mut d_block);
        result?;
        x.as_mut()
            .submatrix_mut(0, start, n, width)
            .copy_from(x_block.as_ref().submatrix(0, 0, n, width));
    }
    Ok(())
}

/// For a general problem, a zero or lost pivot names the free unknown of
/// `X` ([`NumericalError::FreeUnknown`]); other errors pass unchanged.
fn name_free_unknown(e: Error, problem: &LseProblem) -> Error {
    if !problem.is_general() {
        return e;
    }
    match e {
        Error::Numerical(NumericalError::NotPositiveDefinite {
            matrix,
            unknown,
            vertex: Some(x_unknown),
            pivot,
        }) => NumericalError::FreeUnknown {
            matrix,
            unknown: x_unknown,
            detail: format!(
                "the pivot of unknown {unknown} of the factored matrix is not positive{}",
                pivot.map(|p| format!(" ({p:e})")).unwrap_or_default()
            ),
        }
        .into(),
        Error::Numerical(NumericalError::Breakdown {
            matrix,
            unknown,
            vertex: Some(x_unknown),
            ratio,
            threshold,
        }) => NumericalError::FreeUnknown {
            matrix,
            unknown: x_unknown,
            detail: format!(
                "the pivot of unknown {unknown} of the factored matrix lost its digits: pivot/diagonal = {ratio:e} < {threshold:e}"
            ),
        }
        .into(),
        other => other,
    }
}
