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

use faer::{Mat, MatMut, MatRef};

use crate::constraints::ConstraintSet;
use crate::error::{ConstraintError, Error, ProblemError};
use crate::formulation::{Formulation, Prepared, Refine};
use crate::laplacian::{self, LaplacianKind};
use crate::limits::MemoryBudget;
use crate::mesh::{Mesh, topology};
use crate::problem::{LseProblem, SoftWeightScale, check_pinned, target_in_unit};
use crate::report::Report;
use crate::solver::{LseSolver, SolveOptions};

/// Deformed positions and the report of how they were obtained.
#[derive(Debug, Clone)]
pub struct Solution {
    /// New vertex positions, in the mesh's vertex order.
    pub positions: Vec<[f64; 3]>,
    /// What happened.
    pub report: Report,
}

/// A mesh with constraints, ready to be deformed again and again: the mesh
/// layer (Laplacian, constraint kinds, component checks) over an
/// [`LseSolver`].
///
/// Invariant: `constraints` holds the current targets (those of the
/// problem), `rest[i]` the rest target of constraint `i` — the one given at
/// construction or by the last [`Deformer::set_target`],
/// [`Deformer::set_targets`] or [`Deformer::set_group_targets`];
/// [`Deformer::transform_group`] moves current targets relative to it.
///
/// **Units** (docs/units.md §1–§3). The energy minimised is the documented one
/// in the mesh's own units,
/// `‖L(X − P)‖²_F + Σ_soft w²‖b·X − d‖²` with every `w` as given. For the
/// numerics the problem is assembled on the mesh and targets divided by the
/// mesh's [`Mesh::length_unit`] `ℓ` (its mean edge length), every soft
/// row carries `w ℓᵃ` instead of `w` (`a` =
/// [`LaplacianKind::inverse_length_power`]; [`SoftWeightScale`] derives
/// why this keeps the minimiser), and the solution is multiplied back.
/// What the scaling changes: no product of coordinates overflows or
/// underflows for meshes from 1e-300 to 1e300, and tolerances are relative
/// to the mesh. What it does not change: the minimiser, the rank, the
/// redundant and conflicting sets. A mesh moved by a rigid motion deforms
/// to the same positions moved; scaled by `s`, it deforms to the result
/// scaled when hard constraints alone act, and with soft constraints when
/// every soft weight is scaled by `s⁻ᵃ` too (the energy is not scale-free
/// otherwise). Targets given to the deformer are in the mesh's units;
/// [`Deformer::problem`], [`Deformer::solve_matrix`],
/// [`Deformer::solve_into`] are in the problem's.
pub struct Deformer {
    mesh: Mesh,
    constraints: ConstraintSet,
    rest: Vec<[f64; 3]>,
    /// [`Mesh::length_unit`] of `mesh`: the problem is in lengths divided
    /// by it.
    unit: f64,
    solver: LseSolver,
}

/// A 3 × 4 affine map `p ↦ M[:, 0..3] p + M[:, 3]`, row-major: the
/// transform of a group of targets ([`Deformer::transform_group`]).
pub type Affine = [[f64; 4]; 3];

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
        crate::interrupt::check()?;
        let l = laplacian::laplacian(&unit_mesh, laplacian)?;
        crate::interrupt::check()?;
        let delta = laplacian::apply(&l, unit_mesh.positions());
        let mut unit_constraints = constraints.clone();
        for (i, c) in constraints.as_slice().iter().enumerate() {
            unit_constraints.set_rhs(i, target_in_unit(i, c.kind.rhs(), unit)?)?;
        }
        let soft_scale = SoftWeightScale {
            length: unit,
            power: laplacian.inverse_length_power(),
        };
        let problem = LseProblem::new(
            &l,
            &delta,
            &unit_constraints,
            unit_mesh.bbox_diagonal(),
            soft_scale,
        )?;
        let mut report = Report {
            energy: Some(crate::report::EnergyOperator::Laplacian(laplacian)),
            warnings: mesh.warnings().iter().map(Into::into).collect(),
            length_unit: unit,
            soft_weight_scale: Some(soft_scale.factor()),
            ..Report::default()
        };
        report.timings_s.setup = t.elapsed().as_secs_f64();
        let rest = constraints
            .as_slice()
            .iter()
            .map(|c| c.kind.rhs())
            .collect();
        Ok(Deformer {
            mesh,
            constraints,
            rest,
            unit,
            solver: LseSolver::with_report(problem, report),
        })
    }

    /// Sets the refinement of every following solve (see
    /// [`crate::formulation::refine`]); `None` restores the formulation's
    /// default ([`Refine::Auto`] for the exact formulations, [`Refine::Off`]
    /// for penalty).
    pub fn set_refine(&mut self, refine: Option<Refine>) {
        self.solver.set_refine(refine);
    }

    /// The refinement the next solve uses.
    pub fn refine_mode(&self) -> Refine {
        self.solver.refine_mode()
    }

    /// Precompute phase: factors the system with `formulation` within the
    /// memory budget ([`Deformer::set_memory_budget`]).
    pub fn precompute(&mut self, formulation: &dyn Formulation) -> Result<(), Error> {
        self.solver.precompute(formulation)
    }

    /// Precompute phase with `options`: its formulation, refinement and
    /// memory budget ([`LseSolver::precompute_with`]).
    pub fn precompute_with(&mut self, options: &SolveOptions) -> Result<(), Error> {
        self.solver.precompute_with(options)
    }

    /// Sets the memory budget of every following precompute and response
    /// basis (default: [`MemoryBudget::default`]).
    pub fn set_memory_budget(&mut self, budget: MemoryBudget) {
        self.solver.set_memory_budget(budget);
    }

    /// The memory budget of the next precompute.
    pub fn memory_budget(&self) -> MemoryBudget {
        self.solver.memory_budget()
    }

    /// Solve phase: positions for the current targets, in the mesh's units.
    pub fn solve(&mut self) -> Result<Solution, Error> {
        let x = self.solve_matrix()?;
        Ok(Solution {
            positions: self.positions_of(&x),
            report: self.report().clone(),
        })
    }

    /// [`Deformer::solve_into`] as positions in the mesh's units: refined
    /// unless the mode is [`Refine::Off`] (then no correction at all, so no
    /// forward-error estimate), without the solution diagnostics (the
    /// report's solution fields read "not computed",
    /// [`Report::clear_solution_diagnostics`], until [`Deformer::diagnose`]).
    pub fn solve_undiagnosed(&mut self) -> Result<Vec<[f64; 3]>, Error> {
        let mut x = Mat::zeros(self.problem().n(), 3);
        self.solve_into(x.as_mut())?;
        Ok(self.positions_of(&x))
    }

    /// The rows of `x` (problem units) as positions in the mesh's units.
    fn positions_of(&self, x: &Mat<f64>) -> Vec<[f64; 3]> {
        let u = self.unit;
        (0..x.nrows())
            .map(|i| [x[(i, 0)] * u, x[(i, 1)] * u, x[(i, 2)] * u])
            .collect()
    }

    /// Solve phase returning `X` (n × 3) of the assembled problem — in its
    /// units, the positions divided by [`Deformer::length_unit`] — after
    /// refinement ([`Deformer::refine_mode`]), updating
    /// [`Deformer::report`] with the solution diagnostics, the refinement
    /// and its warnings.
    pub fn solve_matrix(&mut self) -> Result<Mat<f64>, Error> {
        self.solver.solve()
    }

    /// Solve phase into `x` (n × 3, one row per vertex, in the problem's
    /// units: positions over [`Deformer::length_unit`]) without the solution
    /// diagnostics ([`Deformer::diagnose`] computes them when wanted): the
    /// call of an interactive loop. With the null-space formulation on the
    /// faer back ends it allocates no buffer. See [`LseSolver::solve_into`].
    pub fn solve_into(&mut self, x: MatMut<'_, f64>) -> Result<(), Error> {
        self.solver.solve_into(x)
    }

    /// Solves for right-hand sides `c` (l × k) and `d` (m × k) of the
    /// problem's shape in place of its own, in the problem's units, refined
    /// as `mode` says; returns `X` and its forward-error estimate. The
    /// problem's targets stay; the refinement becomes the one
    /// [`Deformer::diagnose`] reports. See [`LseSolver::solve_columns`].
    pub fn solve_columns(
        &mut self,
        c: MatRef<'_, f64>,
        d: MatRef<'_, f64>,
        mode: Refine,
    ) -> Result<(Mat<f64>, f64), Error> {
        self.solver.solve_columns(c, d, mode)
    }

    /// Fills the report's solution diagnostics (residuals, redundant and
    /// conflicting constraints) for `x`, the result of the last solve.
    pub fn diagnose(&mut self, x: MatRef<'_, f64>) -> &Report {
        self.solver.diagnose(x)
    }

    /// Moves the target of constraint `index` (a position, edge or face
    /// target, or a relative vector). The next [`Deformer::solve`] reuses
    /// the factorisation.
    /// The rest target becomes `target` too.
    pub fn set_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        self.set_targets(&[(index, target)])
    }

    /// Moves several targets at once (constraint index, new target or
    /// relative vector), which also become the rest targets. All updates
    /// are checked first: on error nothing changes.
    pub fn set_targets(&mut self, updates: &[(usize, [f64; 3])]) -> Result<(), Error> {
        for &(index, target) in updates {
            self.check_update(index, target)?;
        }
        for &(index, target) in updates {
            self.write_target(index, target)?;
            self.rest[index] = target;
        }
        Ok(())
    }

    /// Sets the targets of group `name`, one per member in increasing
    /// constraint index ([`ConstraintSet::group`]); they become the rest
    /// targets. On error (unknown group, wrong count, non-finite value)
    /// nothing changes.
    pub fn set_group_targets(&mut self, name: &str, targets: &[[f64; 3]]) -> Result<(), Error> {
        let members = self.group_members(name)?;
        if members.len() != targets.len() {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "group '{name}' has {} constraints, {} targets were given",
                    members.len(),
                    targets.len()
                ),
            }
            .into());
        }
        let updates: Vec<(usize, [f64; 3])> =
            members.into_iter().zip(targets.iter().copied()).collect();
        self.set_targets(&updates)
    }

    /// Applies the affine map `m` (3 × 4, row-major: `p ↦ R p + t` with
    /// `R = m[:, 0..3]`, `t = m[:, 3]`) to the **rest** targets of group
    /// `name`: a position, edge or face target `u` becomes `R u + t`, a
    /// relative vector `v` becomes `R v` (a difference does not
    /// translate). The rest targets stay, so successive calls with the
    /// transforms of a dragged handle do not accumulate; the identity puts
    /// the group back. The next solve reuses the factorisation. On error
    /// (unknown group, non-finite `m` or result) nothing changes.
    pub fn transform_group(&mut self, name: &str, m: &Affine) -> Result<(), Error> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(ProblemError::BadUpdate {
                message: format!("transform of group '{name}': the matrix has a non-finite entry"),
            }
            .into());
        }
        let members = self.group_members(name)?;
        let moved: Vec<(usize, [f64; 3])> = members
            .into_iter()
            .map(|i| {
                let u = self.rest[i];
                let translate = self.constraints[i].kind.pins_translation();
                let target = [0, 1, 2].map(|r| {
                    let linear = m[r][0] * u[0] + m[r][1] * u[1] + m[r][2] * u[2];
                    if translate { linear + m[r][3] } else { linear }
                });
                (i, target)
            })
            .collect();
        for &(index, target) in &moved {
            self.check_update(index, target)?;
        }
        for (index, target) in moved {
            self.write_target(index, target)?;
        }
        Ok(())
    }

    /// The constraint indices of group `name` (increasing); an error naming
    /// the groups there are if it has no member.
    pub fn group_members(&self, name: &str) -> Result<Vec<usize>, Error> {
        let members = self.constraints.group(name);
        if members.is_empty() {
            // The first few names: a set can hold 10⁵ groups.
            const SHOWN: usize = 20;
            let names = self.constraints.group_names();
            let listed = match names.len() {
                0 => "none".to_string(),
                k if k <= SHOWN => names.join(", "),
                k => format!("{}, … ({k} in all)", names[..SHOWN].join(", ")),
            };
            return Err(ProblemError::BadUpdate {
                message: format!("there is no constraint group '{name}' (groups: {listed})"),
            }
            .into());
        }
        Ok(members.to_vec())
    }

    /// The rest target of every constraint (see [`Deformer::transform_group`]).
    pub fn rest_targets(&self) -> &[[f64; 3]] {
        &self.rest
    }

    fn check_update(&self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        if index >= self.rest.len() {
            return Err(ProblemError::BadUpdate {
                message: format!(
                    "constraint {index} does not exist (there are {})",
                    self.rest.len()
                ),
            }
            .into());
        }
        if target.iter().any(|v| !v.is_finite()) {
            return Err(ConstraintError::NonFinite {
                index,
                field: "target",
            }
            .into());
        }
        // Finite, but perhaps not in the problem's unit.
        target_in_unit(index, target, self.unit)?;
        Ok(())
    }

    /// Writes a checked target (in the mesh's units) into the problem (in
    /// its units) and the constraints.
    fn write_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        let u = self.unit;
        self.solver
            .set_rhs(index, [target[0] / u, target[1] / u, target[2] / u])?;
        self.constraints.set_rhs(index, target)?;
        Ok(())
    }

    /// Estimates the 2-norm condition number of the matrix the formulation
    /// factored (see [`crate::condition`]) and records it in the report.
    pub fn estimate_condition(&mut self) -> Result<&crate::condition::ConditionEstimate, Error> {
        self.solver.estimate_condition()
    }

    /// The prepared system of the last precompute, if any (for export).
    pub fn prepared(&self) -> Option<&dyn Prepared> {
        self.solver.prepared()
    }

    /// The report of the last precompute and solve.
    pub fn report(&self) -> &Report {
        self.solver.report()
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
        self.solver.problem()
    }

    /// The length the problem's lengths are divided by: the mesh's mean
    /// edge length ([`Mesh::length_unit`]).
    pub fn length_unit(&self) -> f64 {
        self.unit
    }
}
