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
//! use lse_deform::SolveOptions;
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
//! let mut solver = LseSolver::new(problem, &SolveOptions::default()).unwrap();
//! let x = solver.solve().unwrap();
//! // The projection of c = (0, 1, 2) onto the plane: c − (Σc − 1)/3.
//! assert!((x[(0, 0)] + 2.0 / 3.0).abs() < 1e-14);
//! assert!((x[(2, 0)] - 4.0 / 3.0).abs() < 1e-14);
//! assert_eq!(solver.report().rank, Some(1));
//! ```
//!
//! **Right-hand-side blocks.** Formulations solve [`RHS_BLOCK`] `= 3`
//! columns at a time (their kernels interleave x, y, z). A problem with
//! `k > 3` columns is solved in one pass when the formulation can
//! ([`Prepared::solve_wide_into`]: the null-space method), else in
//! `⌈k/3⌉` blocks of three, the last padded with zero columns, each costing
//! what a mesh solve costs; `k < 3` is padded to one block.
//!
//! **Singular problems.** For a general problem a factorisation that meets
//! a zero pivot is reported as [`NumericalError::FreeUnknown`] naming the
//! unknown of `X` the pivot belongs to; for meshes the mesh layer has
//! already ruled this out (every component pinned) and the back end's error
//! is passed on with its vertex.

use std::time::Instant;

use faer::{Mat, MatMut, MatRef};

use crate::backend::FactorStorage;
use crate::condition::ConditionEstimate;
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{
    FORWARD_ERROR_WARNING, FactorRounding, Formulation, FormulationChoice, Method,
    PrecomputeRecord, Precomputed, Prepared, Refine, RefineStop, Refinement, refine,
    refine_with_rounding,
};
use crate::problem::{LseProblem, RHS_BLOCK};
use crate::report::{
    ConflictSources, Report, Warning, WarningKind, conflict_warnings, fill_solution_diagnostics,
    first_non_finite,
};
use crate::resources::Resources;

/// How to solve: the formulation with its back ends, the refinement and the
/// resources (memory budget, threads, ordering). What the CLI's flags,
/// Python's keywords and the editor's settings translate into;
/// [`LseSolver::precompute_with`] (and the `precompute_with` of
/// [`crate::Deformer`] and [`crate::arap::ArapDeformer`]) applies them all.
///
/// The default is the paper's method on the default back ends
/// ([`FormulationChoice::new`] of [`Method::NullSpaceQr`]), the
/// formulation's default refinement (`refine: None`) and the default
/// resources ([`Resources::default`]: the process's memory budget,
/// `LSE_MEMORY_LIMIT` when set, otherwise the smallest of the available
/// memory, the address-space limit and the cgroup's memory limit; each back
/// end's own threads and ordering), which is what a solve without options
/// does.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveOptions {
    /// The formulation and its back ends.
    pub formulation: FormulationChoice,
    /// The refinement of every solve; `None`: the formulation's default
    /// ([`Refine::Auto`] for the exact formulations, [`Refine::EstimateOnly`] for
    /// penalty).
    pub refine: Option<Refine>,
    /// The memory budget, threads and ordering of the precompute
    /// ([`crate::resources`]).
    pub resources: Resources,
    /// Where the factor is kept: in core, or out of core under a directory
    /// (the `mumps` back end only).
    pub factor_storage: FactorStorage,
}

impl Default for SolveOptions {
    fn default() -> SolveOptions {
        SolveOptions::new(FormulationChoice::new(Method::NullSpaceQr))
    }
}

impl SolveOptions {
    /// `formulation` with the default refinement and memory budget.
    pub fn new(formulation: FormulationChoice) -> SolveOptions {
        SolveOptions {
            formulation,
            refine: None,
            resources: Resources::default(),
            factor_storage: FactorStorage::InCore,
        }
    }
}

/// A problem with its precomputed system (the factorisation: a value, made
/// by [`LseSolver::new`] or [`LseSolver::with_formulation`], so that a
/// solve can only follow a precompute) and the report of the last
/// precompute and solve.
pub struct LseSolver {
    problem: LseProblem,
    system: Box<dyn Prepared>,
    /// What every precompute's report starts from (Laplacian, set-up time,
    /// mesh warnings).
    base: Report,
    report: Report,
    /// `None`: the formulation's default ([`Refine::Auto`] for the exact
    /// formulations, [`Refine::EstimateOnly`] for penalty, the classical baseline).
    refine: Option<Refine>,
    /// The warnings of set-up and precompute; each solve adds its own.
    precompute_warnings: Vec<Warning>,
    /// The refinement of the last solve.
    last_refinement: Option<Refinement>,
    /// The earlier constraints each conflicting one contradicts, found
    /// once per precompute (for the warnings).
    conflict_sources: ConflictSources,
    /// What the refinements of the current factor measured (contraction,
    /// rounding floor), so that later solves can stop refining on a
    /// prediction; reset at every precompute.
    rounding: FactorRounding,
}

/// What a precompute produced, before it is an [`LseSolver`]: the system,
/// the report it starts, and the earlier constraints each skipped one
/// contradicts.
struct Factored {
    system: Box<dyn Prepared>,
    report: Report,
    conflict_sources: ConflictSources,
}

/// Precompute phase: factors `problem` with `formulation` under
/// `resources`, the report starting from `base`.
fn factor(
    problem: &LseProblem,
    base: &Report,
    formulation: &dyn Formulation,
    resources: &Resources,
) -> Result<Factored, Error> {
    crate::interrupt::check()?;
    // Refused whatever the method, before anything is factored: also by a
    // method whose back end never reads the ordering.
    resources.ordering.check_in_build()?;
    resources.ordering.check_unknowns(problem.n())?;
    let Precomputed { system, record } = formulation
        .precompute_with(problem, resources)
        .map_err(|e| name_free_unknown(e, problem))?;
    let bytes = solve_bytes(problem);
    crate::limits::check_address_space(bytes, || {
        "its solves and their diagnostics would map".to_string()
    })
    .map_err(|detail| ProblemError::TooLarge {
        detail: format!("the system is factored, but {detail}"),
    })?;
    let mut report = base.clone();
    report.memory_budget = Some(resources.budget);
    apply_record(&mut report, record);
    let conflict_sources = ConflictSources::new(system.skipped());
    Ok(Factored {
        system,
        report,
        conflict_sources,
    })
}

/// An estimate, with margins, of the address space a solve and its
/// diagnostics map after the precompute, checked against the address-space limit once the
/// factor is made ([`factor`]): their allocations (faer's products among
/// them) are infallible, so under a limit they must be known to fit.
///
/// A solve holds a few dense blocks of `k` right-hand sides at once:
/// the solution and its refined copy, the correction, the residual
/// `A X − C` and the product `A X`, the constraints' residual, each of
/// them at most `(rows of A + rows of B + n) × k` values: six such blocks,
/// doubled because freed blocks stay mapped in the allocator's heap until
/// it trims them.
fn solve_bytes(problem: &LseProblem) -> u64 {
    let values = (problem.a().nrows() + problem.b().nrows() + problem.n()) as u64;
    let k = problem.c().ncols().max(1) as u64;
    values.saturating_mul(k).saturating_mul(8 * 6 * 2)
}

impl LseSolver {
    /// Precompute phase: factors `problem` as `options` say (their
    /// formulation and back ends, refinement and resources).
    ///
    /// Errors: those of [`FormulationChoice::build`] and of
    /// [`LseSolver::with_formulation`].
    pub fn new(problem: LseProblem, options: &SolveOptions) -> Result<LseSolver, Error> {
        LseSolver::with_base_report(problem, Report::default(), options)
    }

    /// Precompute phase with a formulation object (an outside one, or a
    /// built-in with settings [`SolveOptions`] does not name) under
    /// `resources` (the budget, and the threads and ordering of the
    /// factorisation, which the report states); the formulation's default
    /// refinement.
    pub fn with_formulation(
        problem: LseProblem,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<LseSolver, Error> {
        LseSolver::factored(problem, Report::default(), formulation, resources)
    }

    /// [`LseSolver::new`] with reports that start from `base` (the mesh
    /// layer's Laplacian, set-up time and warnings).
    pub fn with_base_report(
        problem: LseProblem,
        base: Report,
        options: &SolveOptions,
    ) -> Result<LseSolver, Error> {
        let formulation = options.formulation.build_with(&options.factor_storage)?;
        let mut solver =
            LseSolver::factored(problem, base, formulation.as_ref(), &options.resources)?;
        solver.refine = options.refine;
        Ok(solver)
    }

    /// [`LseSolver::with_formulation`] with reports that start from `base`.
    pub(crate) fn factored(
        problem: LseProblem,
        mut base: Report,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<LseSolver, Error> {
        if base.length_unit == 0.0 {
            base.length_unit = 1.0;
        }
        let made = factor(&problem, &base, formulation, resources)?;
        Ok(LseSolver {
            problem,
            system: made.system,
            precompute_warnings: made.report.warnings.clone(),
            report: made.report,
            base,
            refine: None,
            last_refinement: None,
            conflict_sources: made.conflict_sources,
            rounding: FactorRounding::default(),
        })
    }

    /// Precompute phase again, as `options` say: the matrices stay, the
    /// factorisation and the refinement are replaced. On error the solver
    /// keeps its previous factorisation and settings (both systems are
    /// held while the new one is made).
    pub fn refactor(&mut self, options: &SolveOptions) -> Result<(), Error> {
        let formulation = options.formulation.build_with(&options.factor_storage)?;
        self.refactor_with(formulation.as_ref(), &options.resources)?;
        self.refine = options.refine;
        Ok(())
    }

    /// [`LseSolver::refactor`] with a formulation object under
    /// `resources`; the refinement setting stays.
    pub fn refactor_with(
        &mut self,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<(), Error> {
        let made = factor(&self.problem, &self.base, formulation, resources)?;
        self.system = made.system;
        self.precompute_warnings = made.report.warnings.clone();
        self.report = made.report;
        self.conflict_sources = made.conflict_sources;
        self.rounding = FactorRounding::default();
        self.last_refinement = None;
        Ok(())
    }

    /// Sets the refinement of every following solve (see
    /// [`crate::formulation::iterative_refinement`]); `None` restores the formulation's
    /// default ([`Refine::Auto`] for the exact formulations, [`Refine::EstimateOnly`]
    /// for penalty).
    pub fn set_refine(&mut self, refine: Option<Refine>) {
        self.refine = refine;
    }

    /// Forgets what refinements measured about the current factor
    /// ([`FactorRounding`]): the next refinement measures its rounding floor
    /// again, with one more correction than a stop on a prediction needs
    /// (docs/refinement.md §6). A caller whose right-hand sides change in
    /// kind, not just in value, may want this; it also times the cost of a
    /// first refinement.
    pub fn forget_factor_rounding(&mut self) {
        self.rounding = FactorRounding::default();
    }

    /// The refinement the next solve uses.
    pub(crate) fn refine_mode(&self) -> Refine {
        match self.refine {
            Some(mode) => mode,
            None if !self.system.exact() => Refine::EstimateOnly,
            None => Refine::Auto,
        }
    }

    /// Solve phase: `X` (n × k) for the current `C` and `D`, refined as
    /// [`LseSolver::refine_mode`] says (with [`Refine::EstimateOnly`] one correction
    /// is still computed, for the forward-error estimate), with the report's
    /// diagnostics (residuals, redundant and conflicting rows, refinement,
    /// warnings).
    pub fn solve(&mut self) -> Result<Mat<f64>, Error> {
        let mut x = Mat::zeros(self.problem.n(), self.problem.n_rhs());
        self.solve_refined(x.as_mut(), self.refine_mode(), true)?;
        self.diagnose(x.as_ref());
        Ok(x)
    }

    /// Solve phase into `x` (n × k), refined unless the mode is
    /// [`Refine::EstimateOnly`], without diagnostics (call [`LseSolver::diagnose`]
    /// when they are wanted; until then the report's solution fields say
    /// "not computed", [`Report::clear_solution_diagnostics`]): what a drag
    /// loop calls every frame. Without
    /// refinement, a 3-column problem allocates no buffer with the
    /// null-space formulation on the faer back ends (they were sized at
    /// precompute or by the first solve; a factor solved on two threads
    /// hands rayon one small task per triangular solve); refinement and
    /// other formulations allocate their temporaries.
    ///
    /// Errors: a shape mismatch of `x`, the
    /// formulation's numerical errors, and a non-finite result
    /// ([`NumericalError::NonFiniteSolution`], naming the row of `X`). On
    /// error the contents of `x` are unspecified.
    pub fn solve_into(&mut self, x: MatMut<'_, f64>) -> Result<(), Error> {
        self.solve_refined(x, self.refine_mode(), false)
    }

    /// One solve into `x` without refinement, whatever the mode: an
    /// iteration of a method that solves afresh at every step (ARAP's
    /// global step, whose next local step absorbs the error of this solve),
    /// refined once at its end with [`LseSolver::refine_solution`].
    pub fn solve_unrefined_into(&mut self, x: MatMut<'_, f64>) -> Result<(), Error> {
        self.solve_refined(x, Refine::EstimateOnly, false)
    }

    /// Refines `x` (the unrefined solution of the current right-hand
    /// sides, n × 3) as [`LseSolver::refine_mode`] says (with
    /// [`Refine::EstimateOnly`] one correction is computed for the forward-error
    /// estimate and not applied), times it (`timings_s.refine`) and keeps
    /// the refinement for [`LseSolver::diagnose`]'s estimate and warnings.
    pub fn refine_solution(&mut self, x: &mut Mat<f64>) -> Result<&Refinement, Error> {
        let mode = self.refine_mode();
        check_finite(x.as_ref())?;
        let t = Instant::now();
        let rounding = Some(&mut self.rounding);
        let system = self.system.as_mut();
        let refinement = refine_with_rounding(system, &self.problem, x, mode, rounding)?;
        self.report.timings_s.refine = t.elapsed().as_secs_f64();
        Ok(self.last_refinement.insert(refinement))
    }

    /// The energy rows of `C` (all but the soft rows), for a caller that
    /// rewrites them between solves (ARAP's rotations): the matrices and
    /// the factor stay.
    pub(crate) fn energy_rhs_mut(&mut self) -> MatMut<'_, f64> {
        self.problem.energy_rhs_mut()
    }

    /// The solve and, when refinement (`mode`) is on or `estimate` asks for
    /// it, the refine phase (timed apart, `timings_s.refine`).
    fn solve_refined(
        &mut self,
        mut x: MatMut<'_, f64>,
        mode: Refine,
        estimate: bool,
    ) -> Result<(), Error> {
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
        let refining = mode != Refine::EstimateOnly || estimate;
        let system = &mut self.system;
        let t = Instant::now();
        let mut refinements = Vec::new();
        self.report.timings_s.refine = 0.0;
        if !estimate {
            self.report
                .clear_solution_diagnostics(&self.precompute_warnings);
        }
        if k == RHS_BLOCK {
            crate::interrupt::check()?;
            system.solve_into(&self.problem, x.as_mut())?;
            self.report.timings_s.solve = t.elapsed().as_secs_f64();
            if refining {
                check_finite(x.as_ref())?;
                let t = Instant::now();
                let mut refined = x.to_owned();
                let rounding = Some(&mut self.rounding);
                refinements.push(refine_with_rounding(
                    system.as_mut(),
                    &self.problem,
                    &mut refined,
                    mode,
                    rounding,
                )?);
                x.copy_from(&refined);
                self.report.timings_s.refine = t.elapsed().as_secs_f64();
            }
        } else {
            let blocks_mode = refining.then_some(mode);
            refinements =
                solve_in_blocks(system.as_mut(), &mut self.problem, x.as_mut(), blocks_mode)?;
            self.report.timings_s.solve = t.elapsed().as_secs_f64();
        }
        self.report.refactorizations = system.refactorizations();
        self.last_refinement = refinements.into_iter().max_by(|a, b| {
            a.forward_error_estimate
                .total_cmp(&b.forward_error_estimate)
        });
        check_finite(x.as_ref())
    }

    /// Solves for right-hand sides `c` (l × k) and `d` (m × k) in place of
    /// the problem's, any `k` (in one pass when the formulation can, else
    /// three columns at a time), refined as `mode` says: the columns of an
    /// affine response basis ([`crate::handle`]). Returns `X` and the
    /// largest forward-error estimate of its refinements (relative to the
    /// length scale; see [`crate::formulation::iterative_refinement`]). The problem's own
    /// `C` and `D` are left as they were; the refinement with that largest
    /// estimate becomes the one [`LseSolver::diagnose`] reports (for
    /// positions combined from these columns).
    pub(crate) fn solve_columns(
        &mut self,
        c: MatRef<'_, f64>,
        d: MatRef<'_, f64>,
        mode: Refine,
    ) -> Result<(Mat<f64>, f64), Error> {
        let (l, m, n) = (
            self.problem.a().nrows(),
            self.problem.b().nrows(),
            self.problem.n(),
        );
        if c.nrows() != l || d.nrows() != m || c.ncols() != d.ncols() {
            return Err(ProblemError::Dimensions {
                message: format!(
                    "C is {} × {} and D {} × {}, expected {l} and {m} rows and as many columns",
                    c.nrows(),
                    c.ncols(),
                    d.nrows(),
                    d.ncols()
                ),
            }
            .into());
        }
        let mut x = Mat::zeros(n, c.ncols());
        let refinements = solve_blocks_of(
            self.system.as_mut(),
            &mut self.problem,
            c,
            d,
            x.as_mut(),
            Some(mode),
        )?;
        check_finite(x.as_ref())?;
        self.last_refinement = refinements.into_iter().max_by(|a, b| {
            a.forward_error_estimate
                .total_cmp(&b.forward_error_estimate)
        });
        let estimate = self
            .last_refinement
            .as_ref()
            .map_or(0.0, |r| r.forward_error_estimate);
        Ok((x, estimate))
    }

    /// Fills the report's solution diagnostics for `x` (the result of the
    /// last solve): residual of every kept hard row, the skipped rows split
    /// into redundant and conflicting (or "not detected" for penalty),
    /// `‖AX − C‖`, soft residuals, sizes, and the last refinement with its
    /// forward-error estimate and warnings (a warning for each conflicting
    /// constraint, naming the earlier ones it contradicts where they are
    /// found, the first [`crate::report::CONFLICT_WARNINGS_SHOWN`] one by
    /// one and the rest counted).
    pub fn diagnose(&mut self, x: MatRef<'_, f64>) -> &Report {
        let t = Instant::now();
        let (skipped, exact) = (self.system.skipped().to_vec(), self.system.exact());
        fill_solution_diagnostics(
            &mut self.report,
            &self.problem,
            &x.to_owned(),
            &skipped,
            exact,
        );
        self.report.warnings = self.precompute_warnings.clone();
        let conflicts = conflict_warnings(&self.report, &self.problem, &mut self.conflict_sources);
        self.report.warnings.extend(conflicts);
        if let Some(r) = &self.last_refinement {
            self.report
                .warnings
                .extend(refinement_warnings(r, self.report.method));
        }
        self.report.forward_error_estimate = self
            .last_refinement
            .as_ref()
            .map(|r| r.forward_error_estimate);
        self.report.refinement = self.last_refinement.clone();
        self.report.timings_s.diagnostics = t.elapsed().as_secs_f64();
        &self.report
    }

    /// Sets the right-hand side of constraint `index` (a 3-column problem):
    /// the matrices stay, the next solve reuses the factorisation.
    pub(crate) fn set_rhs(&mut self, index: usize, value: [f64; 3]) -> Result<(), Error> {
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
        let estimate = self.system.estimate_condition()?;
        Ok(self.report.condition_estimate.insert(estimate))
    }

    /// The prepared system of the last precompute (for export).
    pub fn prepared(&self) -> &dyn Prepared {
        self.system.as_ref()
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

/// Writes what a precompute computed into `report` (a copy of the base
/// report: Laplacian, set-up time and mesh warnings, which come first): the
/// method and its back ends, the rank, the sizes, the phase timings, the
/// method's own facts, and the precompute's warnings after the base's.
fn apply_record(report: &mut Report, record: PrecomputeRecord) {
    let PrecomputeRecord {
        method,
        qr_backend,
        factor_backend,
        rank,
        sizes,
        timings,
        warnings,
        facts,
        backend_facts,
        ordering,
        threads,
    } = record;
    report.backend_facts = backend_facts;
    report.ordering = ordering.map(|o| o.into_owned());
    report.threads = threads;
    report.refactorizations = 0;
    report.method = method;
    report.qr_backend = qr_backend;
    report.factor_backend = Some(factor_backend);
    report.rank = rank;
    report.method_facts = Some(facts);
    report.nnz.aq2 = sizes.aq2;
    report.nnz.normal = sizes.normal;
    report.nnz.factor = sizes.factor;
    report.nnz.factor_bytes = sizes.factor_bytes;
    report.nnz.qr = sizes.qr;
    report.timings_s.qr = timings.qr;
    report.timings_s.preparation = timings.preparation;
    report.timings_s.normal_matrix = timings.normal_matrix;
    report.timings_s.symbolic = timings.symbolic;
    report.timings_s.numeric = timings.numeric;
    report.timings_s.ordering = timings.ordering;
    report.warnings.extend(warnings);
}

/// The first non-finite row of `x` as an error.
fn check_finite(x: MatRef<'_, f64>) -> Result<(), Error> {
    match first_non_finite(x) {
        Some(row) => Err(NumericalError::NonFiniteSolution { vertex: row }.into()),
        None => Ok(()),
    }
}

/// Solves a problem whose `k ≠ 3` columns are taken three at a time: each
/// block's `C` and `D` (zero-padded) are swapped into the problem, solved
/// (and refined with `refine_mode`, if given), and swapped back before any
/// error is returned. Returns each block's refinement.
fn solve_in_blocks(
    system: &mut dyn Prepared,
    problem: &mut LseProblem,
    x: MatMut<'_, f64>,
    refine_mode: Option<Refine>,
) -> Result<Vec<Refinement>, Error> {
    let (c, d) = (problem.c().clone(), problem.d().clone());
    solve_blocks_of(system, problem, c.as_ref(), d.as_ref(), x, refine_mode)
}

/// [`solve_in_blocks`] for the right-hand sides `c`, `d` (any width) in
/// place of the problem's.
fn solve_blocks_of(
    system: &mut dyn Prepared,
    problem: &mut LseProblem,
    c: MatRef<'_, f64>,
    d: MatRef<'_, f64>,
    mut x: MatMut<'_, f64>,
    refine_mode: Option<Refine>,
) -> Result<Vec<Refinement>, Error> {
    let k = c.ncols();
    if k > RHS_BLOCK {
        let (mut c_wide, mut d_wide) = (c.to_owned(), d.to_owned());
        let mut x_wide = Mat::<f64>::zeros(problem.n(), k);
        let (solved, refinement) = solve_with_rhs(
            system,
            problem,
            (&mut c_wide, &mut d_wide),
            &mut x_wide,
            refine_mode,
            |s, p, out| s.solve_wide_into(p, out),
        )?;
        if solved {
            x.copy_from(&x_wide);
            return Ok(refinement.into_iter().collect());
        }
    }
    let (l, m, n) = (problem.a().nrows(), problem.b().nrows(), problem.n());
    let mut x_block = Mat::<f64>::zeros(n, RHS_BLOCK);
    let mut refinements = Vec::new();
    for start in (0..k).step_by(RHS_BLOCK) {
        crate::interrupt::check()?;
        let width = RHS_BLOCK.min(k - start);
        let mut c_block = Mat::from_fn(l, RHS_BLOCK, |i, j| {
            if j < width { c[(i, start + j)] } else { 0.0 }
        });
        let mut d_block = Mat::from_fn(m, RHS_BLOCK, |i, j| {
            if j < width { d[(i, start + j)] } else { 0.0 }
        });
        let (_, refinement) = solve_with_rhs(
            system,
            problem,
            (&mut c_block, &mut d_block),
            &mut x_block,
            refine_mode,
            |s, p, out| s.solve_into(p, out).map(|()| true),
        )?;
        refinements.extend(refinement);
        x.as_mut()
            .submatrix_mut(0, start, n, width)
            .copy_from(x_block.as_ref().submatrix(0, 0, n, width));
    }
    Ok(refinements)
}

/// `solve` into `x` with `c`, `d` in place of the problem's right-hand
/// sides (swapped back whatever happens), then, when it solved (`true`:
/// [`Prepared::solve_wide_into`] may decline) and `refine_mode` says so,
/// the finiteness check and the refinement. Returns `solve`'s flag and the
/// refinement.
fn solve_with_rhs(
    system: &mut dyn Prepared,
    problem: &mut LseProblem,
    (c, d): (&mut Mat<f64>, &mut Mat<f64>),
    x: &mut Mat<f64>,
    refine_mode: Option<Refine>,
    solve: impl FnOnce(&mut dyn Prepared, &LseProblem, MatMut<'_, f64>) -> Result<bool, Error>,
) -> Result<(bool, Option<Refinement>), Error> {
    problem.swap_rhs(c, d);
    let result = solve(&mut *system, problem, x.as_mut()).and_then(|solved| {
        let refinement = match (solved, refine_mode) {
            (true, Some(mode)) => {
                check_finite(x.as_ref())?;
                Some(refine(system, problem, x, mode)?)
            }
            _ => None,
        };
        Ok((solved, refinement))
    });
    problem.swap_rhs(c, d);
    result
}

/// The warnings a refinement outcome calls for: an estimated forward error
/// above [`FORWARD_ERROR_WARNING`], and conflicting hard constraints found
/// by the method of multipliers.
pub(crate) fn refinement_warnings(r: &Refinement, method: Method) -> Vec<Warning> {
    let mut out = Vec::new();
    if r.stop_reason == RefineStop::ConflictingConstraints {
        out.push(Warning::new(
            WarningKind::RefinementStalled,
            format!(
                "{method}: the multiplier updates stopped after {} steps because the hard-constraint residual stopped shrinking at {:.1e} of the length scale: the hard constraints conflict, and no weight satisfies them all (use nullspace-qr to find which)",
                r.steps,
                r.constraint_residuals.last().copied().unwrap_or(f64::NAN)
            ),
        ));
    }
    let e = r.forward_error_estimate;
    if (e.is_nan() || e > FORWARD_ERROR_WARNING)
        && r.stop_reason != RefineStop::ConflictingConstraints
    {
        let (kind, how) = if r.mode.is_estimate_only() {
            (
                WarningKind::LostAccuracyUnrefined,
                "refinement is off; refinement `auto` would correct it",
            )
        } else if r.stop_reason == RefineStop::StepLimit {
            (
                WarningKind::LostAccuracyStepLimit,
                "refinement reached its step limit; allow more steps",
            )
        } else {
            (
                WarningKind::LostAccuracy,
                "after refinement: the conditioning puts the exact answer out of reach in double precision",
            )
        };
        out.push(Warning::new(
            kind,
            format!(
                "{method}: estimated forward error {e:.1e} of the length scale exceeds {FORWARD_ERROR_WARNING:.0e} ({how}; {} refinement steps, stopped: {:?})",
                r.steps, r.stop_reason
            ),
        ));
    }
    out
}

/// What could lower a forward error above the accepted one
/// ([`NumericalError::LostAccuracy`]) for the `method` and the refinement
/// `r` that produced it: refinement when it was off (or absent), more
/// steps when it hit its limit, a lower condition number always, and the
/// null-space method (which is tested to `1e-10`, docs/formulations.md)
/// only when another method was in use; for the penalty method also a
/// larger weight.
pub(crate) fn lost_accuracy_advice(method: Method, r: Option<&Refinement>) -> String {
    let mut ways = Vec::new();
    match r {
        None => ways.push("refine it with refinement `auto`"),
        Some(r) if r.mode.is_estimate_only() => ways.push("refine it with refinement `auto`"),
        Some(r) if r.stop_reason == RefineStop::StepLimit => {
            ways.push("allow more refinement steps")
        }
        Some(_) => {}
    }
    ways.push("lower the condition number");
    if method == Method::Penalty {
        ways.push("raise the penalty weight");
    }
    if method != Method::NullSpaceQr {
        ways.push("use the null-space method (nullspace-qr)");
    }
    match ways.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{}, or {last}", rest.join(", ")),
        None => String::new(),
    }
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

#[cfg(test)]
mod tests {
    use super::refinement_warnings;
    use crate::choice::Method;
    use crate::formulation::{Refine, RefineStop, Refinement};

    #[test]
    fn refinement_warnings_have_their_codes() {
        let r = |mode, stop_reason| Refinement {
            mode,
            stop_reason,
            steps: 2,
            forward_error_estimate: 1e-3,
            ..Refinement::default()
        };
        let kinds = |r: &Refinement| -> Vec<&str> {
            refinement_warnings(r, Method::Penalty)
                .iter()
                .map(|w| w.code())
                .collect()
        };
        assert_eq!(
            kinds(&r(Refine::EstimateOnly, RefineStop::Off)),
            ["lost-accuracy-unrefined"]
        );
        assert_eq!(
            kinds(&r(Refine::Steps(2), RefineStop::StepLimit)),
            ["lost-accuracy-step-limit"]
        );
        assert_eq!(
            kinds(&r(Refine::Auto, RefineStop::Stagnated)),
            ["lost-accuracy"]
        );
        assert_eq!(
            kinds(&r(Refine::Auto, RefineStop::ConflictingConstraints)),
            ["refinement-stalled"]
        );
    }
}
