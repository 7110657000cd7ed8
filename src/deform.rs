//! The high-level deformer with the paper's three phases: set-up
//! ([`Deformer::new`]), precompute ([`Deformer::precompute`]) and solve
//! ([`Deformer::solve`]); a dragged handle changes targets only
//! ([`Deformer::set_target`]) and re-solves without refactoring.
//!
//! ```
//! use lse_deform::{Deformer, LaplacianKind, NullSpaceQr};
//! use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
//! use lse_deform::mesh::generate;
//!
//! let mesh = generate::grid(8, 8).unwrap();
//! let mut constraints = ConstraintSet::new();
//! for v in 0..9 {
//!     // fix the bottom row, lift the top row
//!     let p = mesh.positions()[v];
//!     constraints.push(Constraint::hard(ConstraintKind::Position { vertex: v, target: p })).unwrap();
//!     let top = 72 + v;
//!     let q = mesh.positions()[top];
//!     constraints.push(Constraint::hard(ConstraintKind::Position { vertex: top, target: [q[0], q[1], 0.5] })).unwrap();
//! }
//! let mut deformer = Deformer::new(mesh, LaplacianKind::Cotangent, constraints).unwrap();
//! deformer.precompute(&NullSpaceQr::default()).unwrap();
//! let solution = deformer.solve().unwrap();
//! assert!(solution.report.max_constraint_residual < 1e-12);
//! assert!((solution.positions[76][2] - 0.5).abs() < 1e-12);
//! ```

use std::time::Instant;

use faer::Mat;

use crate::constraints::ConstraintSet;
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{
    FORWARD_ERROR_WARNING, Formulation, Prepared, Refine, RefineStop, refine,
};
use crate::laplacian::{self, LaplacianKind};
use crate::mesh::{Mesh, topology};
use crate::problem::{LseProblem, check_pinned};
use crate::report::{Report, fill_solution_diagnostics, first_non_finite};

/// Deformed positions and the report of how they were obtained.
#[derive(Debug, Clone)]
pub struct Solution {
    /// New vertex positions, in the mesh's vertex order.
    pub positions: Vec<[f64; 3]>,
    /// What happened.
    pub report: Report,
}

/// A mesh with constraints, ready to be deformed again and again.
///
/// **Units.** The problem is assembled on the mesh and targets divided by
/// the mesh's [`Mesh::length_unit`] (its mean edge length), and the
/// solution multiplied back: the result does not depend on the units the
/// mesh is given in (scaled by `s`, it deforms to the same positions scaled
/// by `s`, with the same rank and the same redundant and conflicting sets),
/// and no coordinate product overflows for meshes from 1e-300 to 1e300.
pub struct Deformer {
    mesh: Mesh,
    constraints: ConstraintSet,
    problem: LseProblem,
    /// [`Mesh::length_unit`] of `mesh`.
    unit: f64,
    system: Option<Box<dyn Prepared>>,
    /// `None`: the formulation's default ([`Refine::Auto`] for the exact
    /// formulations, [`Refine::Off`] for penalty, the classical baseline).
    refine: Option<Refine>,
    /// The warnings of set-up (the mesh's).
    setup_warnings: Vec<String>,
    /// The warnings of set-up and precompute; each solve adds its own.
    precompute_warnings: Vec<String>,
    report: Report,
}

impl Deformer {
    /// Set-up phase: checks the constraints against the mesh (vertex range,
    /// every component pinned), builds `L`, `δ = L P`, `A`, `C`, `B`, `D`.
    pub fn new(
        mesh: Mesh,
        laplacian: LaplacianKind,
        constraints: ConstraintSet,
    ) -> Result<Deformer, Error> {
        let t = Instant::now();
        let n = mesh.n_vertices();
        constraints.check_vertices(n)?;
        let (component_of, n_components) = topology::vertex_components(n, mesh.faces());
        check_pinned(&component_of, n_components, &constraints)?;
        let unit = mesh.length_unit();
        let unit_mesh = mesh.with_positions(
            mesh.positions()
                .iter()
                .map(|p| [p[0] / unit, p[1] / unit, p[2] / unit])
                .collect(),
        )?;
        let l = laplacian::laplacian(&unit_mesh, laplacian)?;
        let delta = laplacian::apply(&l, unit_mesh.positions());
        let mut unit_constraints = constraints.clone();
        for (i, c) in constraints.as_slice().iter().enumerate() {
            let r = c.kind.rhs();
            unit_constraints.set_rhs(i, [r[0] / unit, r[1] / unit, r[2] / unit])?;
        }
        let problem = LseProblem::new(&l, &delta, &unit_constraints, unit_mesh.bbox_diagonal())?;
        let warnings: Vec<String> = mesh.warnings().iter().map(|w| w.to_string()).collect();
        let mut report = Report {
            laplacian: Some(laplacian.name().into()),
            warnings: warnings.clone(),
            length_unit: unit,
            ..Report::default()
        };
        report.timings_s.setup = t.elapsed().as_secs_f64();
        Ok(Deformer {
            mesh,
            constraints,
            problem,
            unit,
            system: None,
            refine: None,
            setup_warnings: warnings.clone(),
            precompute_warnings: warnings,
            report,
        })
    }

    /// Sets the refinement of every following solve (see
    /// [`crate::formulation::refine`]); `None` restores the formulation's
    /// default ([`Refine::Auto`] for the exact formulations, [`Refine::Off`]
    /// for penalty).
    pub fn set_refine(&mut self, refine: Option<Refine>) {
        self.refine = refine;
    }

    /// The refinement the next solve uses.
    pub fn refine_mode(&self) -> Refine {
        match (self.refine, &self.system) {
            (Some(mode), _) => mode,
            (None, Some(system)) if !system.exact() => Refine::Off,
            _ => Refine::Auto,
        }
    }

    /// Precompute phase: factors the system with `formulation`.
    pub fn precompute(&mut self, formulation: &dyn Formulation) -> Result<(), Error> {
        self.system = None;
        let mut report = Report {
            laplacian: self.report.laplacian.clone(),
            warnings: self.setup_warnings.clone(),
            length_unit: self.unit,
            ..Report::default()
        };
        report.timings_s.setup = self.report.timings_s.setup;
        let system = formulation.precompute(&self.problem, &mut report)?;
        self.system = Some(system);
        self.precompute_warnings = report.warnings.clone();
        self.report = report;
        Ok(())
    }

    /// Solve phase: positions for the current targets, in the mesh's units.
    pub fn solve(&mut self) -> Result<Solution, Error> {
        let x = self.solve_matrix()?;
        let u = self.unit;
        let positions = (0..x.nrows())
            .map(|i| [x[(i, 0)] * u, x[(i, 1)] * u, x[(i, 2)] * u])
            .collect();
        Ok(Solution {
            positions,
            report: self.report.clone(),
        })
    }

    /// Solve phase returning `X` (n × 3) of the assembled problem
    /// [`Deformer::problem`] — in its units, i.e. the positions divided by
    /// [`Deformer::length_unit`] ([`Deformer::solve`] gives the positions in
    /// the mesh's units) — and updating [`Deformer::report`]: the solve, then refinement as
    /// [`Deformer::refine_mode`] says (its own phase, `timings_s.refine`),
    /// then the diagnostics. A forward-error estimate above
    /// [`FORWARD_ERROR_WARNING`] adds a warning to the report (the result is
    /// still returned: callers that want an error check
    /// [`Report::forward_error_estimate`]).
    pub fn solve_matrix(&mut self) -> Result<Mat<f64>, Error> {
        let mode = self.refine_mode();
        let system = self
            .system
            .as_mut()
            .ok_or_else(|| ProblemError::BadUpdate {
                message: "solve called before precompute".into(),
            })?;
        let t = Instant::now();
        let mut x = system.solve(&self.problem)?;
        self.report.timings_s.solve = t.elapsed().as_secs_f64();
        if let Some(vertex) = first_non_finite(&x) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        let t = Instant::now();
        let refinement = refine(system.as_mut(), &self.problem, &mut x, mode)?;
        self.report.timings_s.refine = t.elapsed().as_secs_f64();
        if let Some(vertex) = first_non_finite(&x) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        let t = Instant::now();
        let skipped = system.skipped().to_vec();
        let exact = system.exact();
        fill_solution_diagnostics(&mut self.report, &self.problem, &x, &skipped, exact);
        self.report.warnings = self.precompute_warnings.clone();
        self.report.warnings.extend(refinement_warnings(
            &refinement,
            self.report.method.as_str(),
        ));
        self.report.forward_error_estimate = Some(refinement.forward_error_estimate);
        self.report.refinement = Some(refinement);
        self.report.timings_s.diagnostics = t.elapsed().as_secs_f64();
        Ok(x)
    }

    /// Moves the target of constraint `index` (a position, edge or face
    /// target, or a relative vector; in the mesh's units). The next
    /// [`Deformer::solve`] reuses the factorisation.
    pub fn set_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        let u = self.unit;
        self.problem
            .set_rhs(index, [target[0] / u, target[1] / u, target[2] / u])?;
        self.constraints.set_rhs(index, target)?;
        Ok(())
    }

    /// Estimates the 2-norm condition number of the matrix the formulation
    /// factored (see [`crate::condition`]) and records it in the report.
    pub fn estimate_condition(&mut self) -> Result<&crate::condition::ConditionEstimate, Error> {
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

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The constraints with their current targets.
    pub fn constraints(&self) -> &ConstraintSet {
        &self.constraints
    }

    /// The assembled problem: on the mesh and targets divided by
    /// [`Deformer::length_unit`].
    pub fn problem(&self) -> &LseProblem {
        &self.problem
    }

    /// The length the problem's lengths are divided by: the mesh's mean
    /// edge length ([`Mesh::length_unit`]).
    pub fn length_unit(&self) -> f64 {
        self.unit
    }
}

/// The warnings a refinement outcome calls for: an estimated forward error
/// above [`FORWARD_ERROR_WARNING`], and conflicting hard constraints found
/// by the method of multipliers.
pub fn refinement_warnings(r: &crate::formulation::Refinement, method: &str) -> Vec<String> {
    let mut out = Vec::new();
    if r.stop_reason == RefineStop::ConflictingConstraints {
        out.push(format!(
            "{method}: the multiplier updates stopped after {} steps because the hard-constraint residual stopped shrinking at {:.1e} of the length scale: the hard constraints conflict, and no weight satisfies them all (use nullspace-qr to find which)",
            r.steps,
            r.constraint_residuals.last().copied().unwrap_or(f64::NAN)
        ));
    }
    let e = r.forward_error_estimate;
    if (e.is_nan() || e > FORWARD_ERROR_WARNING)
        && r.stop_reason != RefineStop::ConflictingConstraints
    {
        let how = if r.mode == "off" {
            "refinement is off; --refine auto would correct it"
        } else if r.stop_reason == RefineStop::StepLimit {
            "refinement reached its step limit; allow more steps"
        } else {
            "after refinement: the conditioning puts the exact answer out of reach in double precision"
        };
        out.push(format!(
            "{method}: estimated forward error {e:.1e} of the length scale exceeds {FORWARD_ERROR_WARNING:.0e} ({how}; {} refinement steps, stopped: {:?})",
            r.steps, r.stop_reason
        ));
    }
    out
}
