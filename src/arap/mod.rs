//! As-rigid-as-possible deformation (Sorkine & Alexa 2007; Chao et al.
//! 2010) with every constraint kind of the paper, hard or soft, through the
//! same formulations as the Laplacian deformer.
//!
//! The energy is written as rows (see [`energy`]): for fixed rotations,
//! `E(X, R) = ‖A_E X − C_E(R)‖² + const`, three rows per triangle, so the
//! global step is the problem `min ‖A X − C‖ s.t. B X = D` with
//! `A = [A_E; w B_soft]` — one [`crate::formulation::Prepared`] factor for
//! all iterations, only `C_E` changes ([`LseProblem::set_energy_rhs`]).
//! Hard constraints therefore hold to rounding after every iteration, and
//! every iteration decreases the objective `E + Σ_soft w²‖b·X − d‖²`
//! (local step: optimal rotations for fixed `X`; global step: optimal `X`
//! for fixed rotations), up to rounding.
//!
//! **Units.** As for the Laplacian deformer ([`crate::Deformer`]), the
//! problem is assembled on the mesh and targets divided by the mesh's
//! [`Mesh::length_unit`] `ℓ` (its mean edge length), and positions, energies
//! and residuals are multiplied back: the iterations do not depend on the
//! units the mesh is given in, and no square of a coordinate (a triangle's
//! area, the energy) overflows or underflows for meshes from 1e-150 to
//! 1e150 (unscaled, a Bunny at 1e±100 loses every triangle's area to
//! overflow or underflow, and its system is singular). Soft weights are
//! used as given ([`crate::problem::SoftWeightScale`] with `a = 0`, the report's
//! `soft_weight_scale` 1; docs/units.md §4): a row of `A_E` is
//! `√(K A_t) ∇φ`, an area's square root (a length) times a gradient (one
//! over a length), so its entries are dimensionless (the power of length
//! in the operator's entries is `a = 0`), and `C_E` is a length; a soft
//! row `w b·X − w d` has dimensionless coefficients `b` and a length `d`.
//! Dividing every length by `ℓ` therefore divides the energy `E` and every
//! soft term `w²‖b·X − d‖²` alike by `ℓ²`: their balance, and the
//! minimiser, stay as they are with the weights unscaled. The energies of
//! [`ArapReport`] and [`Step`] are in the mesh's units (length², the
//! problem's times `ℓ²`).
//!
//! **Failures.** An energy or a position that is not finite in the mesh's
//! units (a target so far outside the mesh that the squares of the
//! deformed edges overflow) stops the iterations with
//! [`NumericalError::NonFiniteEnergy`] or
//! [`NumericalError::NonFiniteSolution`]; the stop rule of
//! [`ArapDeformer::run`] stops on a NaN too, whatever it meets.
//!
//! The local step fits one rotation per vertex ([`rotations`]), in
//! parallel (rayon). The step-wise API ([`ArapDeformer::iterate`]) is the
//! hook for interactive use: move targets with
//! [`ArapDeformer::set_target`], then run a few iterations per frame,
//! warm-started from the last positions and rotations.
//!
//! ```
//! use lse_deform::arap::{ArapDeformer, ArapEnergy, ArapInit};
//! use lse_deform::constraints::{Constraint, ConstraintKind, ConstraintSet};
//! use lse_deform::{SolveOptions, mesh::generate};
//!
//! let mesh = generate::grid(6, 6).unwrap();
//! let mut constraints = ConstraintSet::new();
//! for v in 0..7 {
//!     let p = mesh.positions()[v];
//!     constraints.push(Constraint::hard(ConstraintKind::Position { vertex: v, target: p })).unwrap();
//!     let q = mesh.positions()[42 + v];
//!     constraints.push(Constraint::hard(ConstraintKind::Position { vertex: 42 + v, target: [q[0], q[1], 0.5] })).unwrap();
//! }
//! let options = SolveOptions::default();
//! let mut arap = ArapDeformer::new(mesh, constraints, ArapEnergy::SpokesAndRims, &options).unwrap();
//! arap.initialize(ArapInit::Rest).unwrap();
//! let report = arap.run(20, 0.0).unwrap();
//! assert_eq!(report.iterations, 20);
//! assert!(report.energies.windows(2).all(|e| e[1] <= e[0] * (1.0 + 1e-12)));
//! assert!((arap.positions()[45][2] - 0.5).abs() < 1e-12);
//! ```

use std::time::Instant;

use faer::Mat;
use rayon::prelude::*;

use crate::constraints::{ConstraintKind, ConstraintSet};
use crate::cpu::clear_upper_vector_state;
use crate::deform::UnitScaled;
use crate::error::{Error, NumericalError, ProblemError};
use crate::formulation::{Formulation, Refine};
use crate::mesh::Mesh;
use crate::problem::{LseProblem, target_in_unit};

/// What the iteration's positions and rotations are called in a refusal.
const POSITIONS: &str = "the ARAP iteration's positions and rotations";
use crate::report::{ArapReport, ArapStop, EnergyOperator, Report, first_non_finite};
use crate::resources::Resources;
use crate::solver::{LseSolver, SolveOptions};

pub mod energy;
pub mod rotations;

pub use crate::choice::ArapInit;
use energy::CovarianceBlock;
pub use energy::{ArapEnergy, ArapTriangles};
pub use rotations::Mat3;
use rotations::{Fit, IDENTITY, fit_rotation_fast};

/// What one call of [`ArapDeformer::iterate`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The objective after the step, with rotations fitted to its
    /// positions (in the mesh's units, length²).
    pub energy: f64,
    /// `max ‖b_k·X − d_k‖₂` over the kept hard constraints (in the mesh's
    /// units).
    pub max_constraint_residual: f64,
    /// Seconds of the local step (rotation fits and objective).
    pub local_s: f64,
    /// Seconds of the global step (right-hand side and solve).
    pub global_s: f64,
}

/// ARAP on a mesh with constraints: set-up and precompute
/// ([`ArapDeformer::new`]), initial guess
/// ([`ArapDeformer::initialize`]), iterations ([`ArapDeformer::iterate`] or
/// [`ArapDeformer::run`]).
pub struct ArapDeformer {
    mesh: Mesh,
    /// [`Mesh::length_unit`] of `mesh`: the problem is in lengths divided
    /// by it.
    unit: f64,
    /// The constraints with their current targets, in the mesh's units.
    constraints: ConstraintSet,
    /// The same in the problem's units (targets divided by `unit`).
    unit_constraints: ConstraintSet,
    /// The rest geometry in the problem's units.
    triangles: ArapTriangles,
    /// The global step's problem and factor: the driver every solve of the
    /// crate goes through (its refinement rule, diagnostics and warnings).
    solver: LseSolver,
    /// The solver's report of the last precompute or
    /// [`ArapDeformer::finish`], with the ARAP history.
    report: Report,
    /// Current positions (n × 3), in the problem's units.
    x: Mat<f64>,
    /// Rotations fitted to `x`, and the objective with them (in the
    /// problem's units: the mesh's divided by `unit²`).
    rotations: Vec<Mat3>,
    energy: f64,
    /// Scratch: the global step's solution, swapped with `x` when finite.
    x_next: Mat<f64>,
    /// Scratch of the local step: covariance blocks, per-vertex energies.
    blocks: Vec<CovarianceBlock>,
    vertex_energies: Vec<f64>,
    arap: ArapReport,
    init: ArapInit,
}

impl ArapDeformer {
    /// Set-up: checks the constraints (vertex range, every component
    /// pinned), builds the energy rows and the problem on the mesh and
    /// targets divided by [`Mesh::length_unit`] (see the module
    /// documentation). The positions start at the rest pose.
    ///
    /// Errors: besides those of the constraints,
    /// [`NumericalError::TargetOutOfRange`] for a target that is not finite
    /// once divided by the length unit.
    pub fn new(
        mesh: Mesh,
        constraints: ConstraintSet,
        energy: ArapEnergy,
        options: &SolveOptions,
    ) -> Result<ArapDeformer, Error> {
        ArapDeformer::set_up(mesh, constraints, energy, |problem, report| {
            LseSolver::with_base_report(problem, report, options)
        })
    }

    /// [`ArapDeformer::new`] with a formulation object under `resources`
    /// ([`LseSolver::with_formulation`]).
    pub fn with_formulation(
        mesh: Mesh,
        constraints: ConstraintSet,
        energy: ArapEnergy,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<ArapDeformer, Error> {
        ArapDeformer::set_up(mesh, constraints, energy, |problem, report| {
            LseSolver::factored(problem, report, formulation, resources)
        })
    }

    /// The set-up of [`ArapDeformer::new`], then the precompute `factor`
    /// makes of the problem and its base report.
    fn set_up(
        mesh: Mesh,
        constraints: ConstraintSet,
        energy: ArapEnergy,
        factor: impl FnOnce(LseProblem, Report) -> Result<LseSolver, Error>,
    ) -> Result<ArapDeformer, Error> {
        let t = Instant::now();
        let n = mesh.n_vertices();
        let scaled = UnitScaled::new(&mesh, &constraints)?;
        let triangles = ArapTriangles::new(&scaled.mesh, energy);
        // Soft weights as given: `a = 0` (the module documentation).
        let operator = EnergyOperator::Arap(energy);
        let (rows, rhs) = (triangles.rows()?, triangles.rest_rhs()?);
        let (problem, base) = scaled.problem(&rows, &rhs, operator, 0, &mesh, t)?;
        let solver = factor(problem, base)?;
        let x =
            crate::problem::matrix_from_fn(POSITIONS, n, 3, |i, c| scaled.mesh.positions()[i][c])?;
        let mut rotations = crate::problem::reserved(POSITIONS, n)?;
        rotations.resize(n, IDENTITY);
        let report = solver.report().clone();
        let (unit, unit_constraints) = (scaled.unit, scaled.constraints);
        Ok(ArapDeformer {
            mesh,
            unit,
            constraints,
            unit_constraints,
            triangles,
            solver,
            report,
            x_next: x.clone(),
            x,
            rotations,
            energy: f64::NAN,
            blocks: Vec::new(),
            vertex_energies: Vec::new(),
            arap: ArapReport {
                energy,
                ..ArapReport::default()
            },
            init: ArapInit::Rest,
        })
    }

    /// The global step's solver (in the problem's units: lengths divided
    /// by [`ArapDeformer::length_unit`]): its refinement,
    /// prepared system and report of the last precompute. Read-only: a
    /// new precompute goes through [`ArapDeformer::refactor`] (which keeps
    /// the ARAP report) and targets through [`ArapDeformer::set_target`]
    /// (which keeps them in the mesh's units).
    pub fn solver(&self) -> &LseSolver {
        &self.solver
    }

    /// Precompute again: factors the global step's system with
    /// `formulation` under `resources`, once for all iterations; on error
    /// the previous factorisation stays.
    pub fn refactor_with(
        &mut self,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<(), Error> {
        self.solver.refactor_with(formulation, resources)?;
        self.report = self.solver.report().clone();
        Ok(())
    }

    /// Precompute again with `options`: its formulation, refinement (the
    /// one [`ArapDeformer::finish`] applies) and resources
    /// ([`LseSolver::refactor`]).
    pub fn refactor(&mut self, options: &SolveOptions) -> Result<(), Error> {
        self.solver.refactor(options)?;
        self.report = self.solver.report().clone();
        Ok(())
    }

    /// Sets the initial guess (see [`ArapInit`]), fits its rotations and
    /// clears the iteration history.
    ///
    /// Errors: [`NumericalError::NonFiniteEnergy`] when the initial guess's
    /// energy is not finite in the mesh's units.
    pub fn initialize(&mut self, init: ArapInit) -> Result<(), Error> {
        let n = self.mesh.n_vertices();
        self.rotations = vec![IDENTITY; n];
        let unit = self.unit;
        self.x = Mat::from_fn(n, 3, |i, c| self.mesh.positions()[i][c] / unit);
        match init {
            ArapInit::Rest => {
                for c in self.unit_constraints.as_slice() {
                    if let (None, ConstraintKind::Position { vertex, target }) = (c.weight, &c.kind)
                    {
                        for k in 0..3 {
                            self.x[(*vertex, k)] = target[k];
                        }
                    }
                }
            }
            ArapInit::Linear => {
                self.global_step()?;
            }
        }
        self.local_step();
        let initial_energy = self.energy_checked(0)?;
        self.init = init;
        self.arap = ArapReport {
            energy: self.triangles.energy(),
            init,
            initial_energy,
            ..ArapReport::default()
        };
        Ok(())
    }

    /// Runs `n` iterations (global step with the current rotations, then
    /// the local step on the new positions), warm-started from the current
    /// positions and rotations — after [`ArapDeformer::set_target`] too,
    /// which is how an editor runs a few iterations per frame. Appends to
    /// the report's history and returns the last step (`None` for `n = 0`).
    ///
    /// Errors: [`NumericalError::NonFiniteSolution`] for a position and
    /// [`NumericalError::NonFiniteEnergy`] for an energy that is not finite
    /// in the mesh's units (the failed step's positions stay current).
    pub fn iterate(&mut self, n: usize) -> Result<Option<Step>, Error> {
        let mut last = None;
        for _ in 0..n {
            crate::interrupt::check()?;
            let t = Instant::now();
            self.global_step()?;
            let global_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let kept = self.local_step();
            let local_s = t.elapsed().as_secs_f64();
            let energy = self.energy_checked(self.arap.iterations + 1)?;
            let residual = self.max_constraint_residual() * self.unit;
            let a = &mut self.arap;
            a.energies.push(energy);
            a.constraint_residuals.push(residual);
            a.iterations += 1;
            a.local_time_s += local_s;
            a.global_time_s += global_s;
            a.kept_rotations += kept;
            a.iteration_times_s.push(local_s + global_s);
            last = Some(Step {
                energy,
                max_constraint_residual: residual,
                local_s,
                global_s,
            });
        }
        Ok(last)
    }

    /// Iterates until `max_iterations` or until the relative decrease of
    /// the objective `(E_{k−1} − E_k)/E_{k−1}` is `≤ tolerance` (checked
    /// from the second iteration on, the first starting from a guess that
    /// may violate the constraints; `tolerance = 0` runs all iterations
    /// unless the objective reaches zero). The rule stops on a NaN as on a
    /// small decrease (a NaN comparison is false, which must not mean "go
    /// on"); a non-finite energy is an error before it is reached (see
    /// [`ArapDeformer::iterate`]). Fills the solution diagnostics and
    /// returns the ARAP report.
    pub fn run(&mut self, max_iterations: usize, tolerance: f64) -> Result<ArapReport, Error> {
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(ProblemError::InvalidArgument {
                message: format!("ARAP tolerance {tolerance} must be finite and ≥ 0"),
            }
            .into());
        }
        let mut stop = ArapStop::Iterations;
        for k in 0..max_iterations {
            let before = self.energy;
            self.iterate(1)?;
            if self.energy == 0.0 {
                stop = ArapStop::Stationary;
                break;
            }
            if k > 0 && tolerance > 0.0 && !decreased_by_more_than(before, self.energy, tolerance) {
                stop = ArapStop::Tolerance;
                break;
            }
        }
        self.arap.stop_reason = Some(stop);
        self.finish()?;
        Ok(self.arap.clone())
    }

    /// Refines the current positions — the last global step's solution —
    /// with the same factor as [`ArapDeformer::set_refine`] says (see
    /// [`crate::formulation::iterative_refinement`]; with [`Refine::EstimateOnly`] one correction
    /// is computed for the forward-error estimate and not applied), refits
    /// the rotations and the objective if they moved, and fills the
    /// report's solution diagnostics, refinement and forward-error
    /// estimate. The iterations before the last are not refined: each
    /// global step solves afresh from the fitted rotations, so the error of
    /// one solve does not carry over, and the next local step absorbs it.
    pub fn finish(&mut self) -> Result<&Report, Error> {
        self.refine_last()?;
        self.report = self.solver.diagnose(self.x.as_ref()).clone();
        let mut times = self.arap.iteration_times_s.clone();
        times.sort_by(f64::total_cmp);
        self.arap.time_per_iteration_s = times.get(times.len() / 2).copied().unwrap_or(0.0);
        self.report.arap = Some(self.arap.clone());
        Ok(&self.report)
    }

    /// Sets the refinement [`ArapDeformer::finish`] applies; `None` (the
    /// default) is the formulation's default, as for the Laplacian deformer:
    /// [`Refine::Auto`] for the exact formulations, [`Refine::EstimateOnly`] for
    /// penalty.
    pub fn set_refine(&mut self, refine: Option<Refine>) {
        self.solver.set_refine(refine);
    }

    /// Refines the last global step's solution through the solver (which
    /// keeps the refinement for the report) and keeps it when its energy
    /// is finite.
    fn refine_last(&mut self) -> Result<(), Error> {
        if self.arap.iterations == 0 && self.init != ArapInit::Linear {
            return Ok(());
        }
        let mut x = self.x.clone();
        let steps = self.solver.refine_solution(&mut x)?.steps;
        if self.first_non_finite_in_mesh_units(&x).is_none() && steps > 0 {
            let (x_before, energy_before) = (std::mem::replace(&mut self.x, x), self.energy);
            let rotations_before = self.rotations.clone();
            self.local_step();
            if self.energy_checked(self.arap.iterations).is_err() {
                // The refined positions are kept only with a finite energy.
                self.x = x_before;
                self.energy = energy_before;
                self.rotations = rotations_before;
            }
        }
        Ok(())
    }

    /// Moves the target of constraint `index` (in the mesh's units); the
    /// next [`ArapDeformer::iterate`] reuses the factor and starts from the
    /// current positions. On error nothing changes.
    pub fn set_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        if target.iter().any(|v| !v.is_finite()) {
            return Err(crate::error::ConstraintError::NonFinite {
                index,
                field: "target",
            }
            .into());
        }
        let scaled = target_in_unit(index, target, self.unit)?;
        self.solver.set_rhs(index, scaled)?;
        self.unit_constraints.set_rhs(index, scaled)?;
        self.constraints.set_rhs(index, target)?;
        Ok(())
    }

    /// Global step: `C_E` from the current rotations, then the solve.
    /// `C_E` is written in place into the problem's right-hand side and
    /// the solution into the current positions: no buffer allocated.
    fn global_step(&mut self) -> Result<(), Error> {
        let finite = self
            .triangles
            .rhs_into(&self.rotations, self.solver.energy_rhs_mut());
        if !finite {
            return Err(ProblemError::BadUpdate {
                message: "ARAP right-hand side is not finite (degenerate rest triangles?)".into(),
            }
            .into());
        }
        self.solver.solve_unrefined_into(self.x_next.as_mut())?;
        if let Some(vertex) = self.first_non_finite_in_mesh_units(&self.x_next) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        std::mem::swap(&mut self.x, &mut self.x_next);
        Ok(())
    }

    /// Local step: one rotation per vertex fitted to the current positions
    /// (in parallel), and the objective with them. Returns how many
    /// rotations were kept from before.
    ///
    /// One parallel pass over the triangles forms the covariance blocks,
    /// one parallel pass over the vertices sums them, fits the rotation
    /// and evaluates the vertex's energy from its covariance; the energy
    /// is then summed in vertex order (reproducible whatever the thread
    /// count). No allocation after the first call.
    fn local_step(&mut self) -> usize {
        let triangles = &self.triangles;
        triangles.covariance_blocks_into(&self.x, &mut self.blocks);
        let blocks = &self.blocks;
        self.vertex_energies.resize(self.rotations.len(), 0.0);
        let kept: usize = self
            .rotations
            .par_iter_mut()
            .zip(self.vertex_energies.par_iter_mut())
            .enumerate()
            .map_init(clear_upper_vector_state, |(), (i, (r, e))| {
                let m = triangles.vertex_covariance(i, blocks);
                let (fit, how) = fit_rotation_fast(&m.cross, r);
                *r = fit;
                *e = triangles.vertex_energy_from(i, &m, &fit);
                usize::from(how == Fit::Kept)
            })
            .sum();
        self.energy = self.vertex_energies.iter().sum::<f64>() + self.soft_energy();
        kept
    }

    /// `Σ_soft w² ‖b·X − d‖²`.
    fn soft_energy(&self) -> f64 {
        let problem = self.solver.problem();
        if problem.soft_constraints().is_empty() {
            return 0.0;
        }
        let positions = self.problem_positions();
        problem
            .soft_constraints()
            .iter()
            .map(|row| {
                let (kind, w) = (&self.unit_constraints[row.index].kind, row.row_weight);
                let (value, target) = (kind.row().apply(&positions), kind.rhs());
                (0..3)
                    .map(|c| (w * (value[c] - target[c])).powi(2))
                    .sum::<f64>()
            })
            .sum()
    }

    fn max_constraint_residual(&self) -> f64 {
        let skipped = self.solver.prepared().skipped();
        let problem = self.solver.problem();
        (0..problem.hard_constraints().len())
            .filter(|k| skipped.binary_search(k).is_err())
            .map(|k| problem.hard_residual(k, &self.x))
            .fold(0.0, f64::max)
    }

    /// The objective in the mesh's units (`E ℓ²`, multiplied in two steps
    /// so that `ℓ²` alone cannot overflow), or
    /// [`NumericalError::NonFiniteEnergy`] naming `iteration` (0: the
    /// initial guess).
    fn energy_checked(&self, iteration: usize) -> Result<f64, Error> {
        let value = self.energy * self.unit * self.unit;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(NumericalError::NonFiniteEnergy {
                iteration,
                value: if self.energy.is_nan() {
                    f64::NAN
                } else {
                    value
                },
            }
            .into())
        }
    }

    /// The first vertex of `x` (in the problem's units) whose position in
    /// the mesh's units is not finite.
    fn first_non_finite_in_mesh_units(&self, x: &Mat<f64>) -> Option<usize> {
        if self.unit <= 1.0 {
            return first_non_finite(x.as_ref());
        }
        let unit = self.unit;
        (0..x.nrows()).find(|&i| (0..x.ncols()).any(|c| !(x[(i, c)] * unit).is_finite()))
    }

    /// Current positions in the problem's units.
    fn problem_positions(&self) -> Vec<[f64; 3]> {
        (0..self.x.nrows())
            .map(|i| [self.x[(i, 0)], self.x[(i, 1)], self.x[(i, 2)]])
            .collect()
    }

    /// Current positions, in the mesh's vertex order and units.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        let u = self.unit;
        (0..self.x.nrows())
            .map(|i| [self.x[(i, 0)] * u, self.x[(i, 1)] * u, self.x[(i, 2)] * u])
            .collect()
    }

    /// The length the problem's lengths are divided by: the mesh's mean
    /// edge length ([`Mesh::length_unit`]).
    pub fn length_unit(&self) -> f64 {
        self.unit
    }

    /// The objective at the current positions (with their fitted
    /// rotations), in the mesh's units (length²); NaN before
    /// [`ArapDeformer::initialize`].
    pub fn energy(&self) -> f64 {
        self.energy * self.unit * self.unit
    }

    /// The rotations fitted to the current positions.
    pub fn rotations(&self) -> &[Mat3] {
        &self.rotations
    }

    /// The initial guess of the last [`ArapDeformer::initialize`].
    pub fn init(&self) -> ArapInit {
        self.init
    }

    /// The report (precompute, and after [`ArapDeformer::finish`] or
    /// [`ArapDeformer::run`] the solution diagnostics and the ARAP history).
    pub fn report(&self) -> &Report {
        &self.report
    }

    /// The mesh (rest pose).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The constraints with their current targets, in the mesh's units.
    pub fn constraints(&self) -> &ConstraintSet {
        &self.constraints
    }

    /// The assembled global-step problem, in the problem's units (lengths
    /// divided by [`ArapDeformer::length_unit`]).
    pub fn problem(&self) -> &LseProblem {
        self.solver.problem()
    }

    /// The energy rows and rest geometry, in the problem's units.
    pub fn triangles(&self) -> &ArapTriangles {
        &self.triangles
    }
}

/// Whether the objective fell from `before` to `after` by more than
/// `tolerance` relative to `before`. `false` when either is NaN: a stop
/// rule written as "go on while this holds" stops on a NaN.
fn decreased_by_more_than(before: f64, after: f64, tolerance: f64) -> bool {
    matches!(
        (before - after).partial_cmp(&(tolerance * before.abs())),
        Some(std::cmp::Ordering::Greater)
    )
}

#[cfg(test)]
mod tests {
    use super::decreased_by_more_than;

    #[test]
    fn the_stop_rule_stops_on_nan() {
        assert!(decreased_by_more_than(1.0, 0.5, 1e-6));
        assert!(!decreased_by_more_than(1.0, 1.0 - 1e-9, 1e-6));
        assert!(!decreased_by_more_than(1.0, 2.0, 1e-6));
        for (before, after) in [(f64::NAN, 1.0), (1.0, f64::NAN), (f64::NAN, f64::NAN)] {
            assert!(!decreased_by_more_than(before, after, 1e-6));
        }
        assert!(!decreased_by_more_than(f64::INFINITY, f64::INFINITY, 1e-6));
    }
}
