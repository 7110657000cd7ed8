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
use crate::formulation::{Formulation, Prepared};
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
pub struct Deformer {
    mesh: Mesh,
    constraints: ConstraintSet,
    problem: LseProblem,
    system: Option<Box<dyn Prepared>>,
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
        let l = laplacian::laplacian(&mesh, laplacian)?;
        let delta = laplacian::apply(&l, mesh.positions());
        let problem = LseProblem::new(&l, &delta, &constraints, mesh.bbox_diagonal())?;
        let mut report = Report {
            laplacian: Some(laplacian.name().into()),
            warnings: mesh.warnings().iter().map(|w| w.to_string()).collect(),
            ..Report::default()
        };
        report.timings_s.setup = t.elapsed().as_secs_f64();
        Ok(Deformer {
            mesh,
            constraints,
            problem,
            system: None,
            report,
        })
    }

    /// Precompute phase: factors the system with `formulation`.
    pub fn precompute(&mut self, formulation: &dyn Formulation) -> Result<(), Error> {
        self.system = None;
        let mut report = Report {
            laplacian: self.report.laplacian.clone(),
            warnings: self.report.warnings.clone(),
            ..Report::default()
        };
        report.timings_s.setup = self.report.timings_s.setup;
        let system = formulation.precompute(&self.problem, &mut report)?;
        self.system = Some(system);
        self.report = report;
        Ok(())
    }

    /// Solve phase: positions for the current targets.
    pub fn solve(&mut self) -> Result<Solution, Error> {
        let x = self.solve_matrix()?;
        let positions = (0..x.nrows())
            .map(|i| [x[(i, 0)], x[(i, 1)], x[(i, 2)]])
            .collect();
        Ok(Solution {
            positions,
            report: self.report.clone(),
        })
    }

    /// Solve phase returning `X` (n × 3) and updating [`Deformer::report`].
    pub fn solve_matrix(&mut self) -> Result<Mat<f64>, Error> {
        let system = self
            .system
            .as_mut()
            .ok_or_else(|| ProblemError::BadUpdate {
                message: "solve called before precompute".into(),
            })?;
        let t = Instant::now();
        let x = system.solve(&self.problem)?;
        self.report.timings_s.solve = t.elapsed().as_secs_f64();
        if let Some(vertex) = first_non_finite(&x) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        let t = Instant::now();
        let skipped = system.skipped().to_vec();
        fill_solution_diagnostics(&mut self.report, &self.problem, &x, &skipped);
        self.report.timings_s.diagnostics = t.elapsed().as_secs_f64();
        Ok(x)
    }

    /// Moves the target of constraint `index` (a position, edge or face
    /// target, or a relative vector). The next [`Deformer::solve`] reuses
    /// the factorisation.
    pub fn set_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        self.problem.set_rhs(index, target)?;
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

    /// The assembled problem.
    pub fn problem(&self) -> &LseProblem {
        &self.problem
    }
}
