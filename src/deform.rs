//! The high-level deformer with the paper's three phases: set-up and
//! precompute ([`Deformer::new`], which returns the factored deformer)
//! and solve ([`Deformer::solve`]); a dragged handle changes targets only
//! ([`Deformer::set_target`]) and re-solves without refactoring.
//!
//! ```
//! use lse_deform::{Deformer, LaplacianKind, SolveOptions};
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
//! let options = SolveOptions::default();
//! let mut deformer = Deformer::new(mesh, LaplacianKind::Cotangent, constraints, &options).unwrap();
//! let solution = deformer.solve().unwrap();
//! assert!(solution.report.max_constraint_residual < 1e-12);
//! assert!((solution.positions[76][2] - 0.5).abs() < 1e-12);
//! ```

use std::time::Instant;

use faer::Mat;
use faer::sparse::SparseColMat;

use crate::constraints::ConstraintSet;
use crate::error::{ConstraintError, Error, ProblemError};
use crate::formulation::Formulation;
use crate::laplacian::{self, LaplacianKind};
use crate::mesh::{Mesh, topology};
use crate::problem::{LseProblem, SoftWeightScale, check_pinned, target_in_unit};
use crate::report::{EnergyOperator, Report};
use crate::resources::Resources;
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
/// [`Deformer::solver`] are in the problem's.
pub struct Deformer {
    mesh: Mesh,
    targets: GroupTargets,
    solver: LseSolver,
}

/// The constraints' targets in the mesh's units with their rest targets
/// and groups: what [`Deformer`] adds to its solver, and what the editor's
/// ARAP engine moves groups with.
///
/// Invariant: `constraints` holds the current targets, `rest[i]` the rest
/// target of constraint `i`; `unit` is the length the problem's lengths
/// are divided by.
pub struct GroupTargets {
    constraints: ConstraintSet,
    rest: Vec<[f64; 3]>,
    /// [`Mesh::length_unit`] of the mesh: the problem is in lengths
    /// divided by it.
    unit: f64,
}

/// A mesh and its constraints in the problem's units — positions and
/// targets divided by the mesh's [`Mesh::length_unit`] `ℓ` (docs/units.md
/// §1–§3) — checked (vertex range, every component pinned): the set-up the
/// Laplacian deformer and [`crate::arap::ArapDeformer`] share.
pub(crate) struct UnitScaled {
    /// `ℓ`, the mesh's mean edge length.
    pub unit: f64,
    /// The mesh with its positions divided by `ℓ`.
    pub mesh: Mesh,
    /// The constraints with their targets divided by `ℓ`.
    pub constraints: ConstraintSet,
}

impl UnitScaled {
    /// Checks `constraints` against `mesh` and divides both by the mesh's
    /// length unit.
    ///
    /// Errors: those of the constraint checks, and
    /// [`crate::error::NumericalError::TargetOutOfRange`] for a target that
    /// is not finite once divided by the unit.
    pub(crate) fn new(mesh: &Mesh, constraints: &ConstraintSet) -> Result<UnitScaled, Error> {
        let n = mesh.n_vertices();
        let setup = setup_bytes(n, mesh.faces().len(), constraints.len());
        crate::limits::check_address_space(setup, || {
            format!("the set-up of {n} vertices (their units, energy rows and problem) would map")
        })
        .map_err(|detail| ProblemError::TooLarge { detail })?;
        constraints.check_vertices(n)?;
        let (component_of, n_components) = topology::vertex_components(n, mesh.faces());
        check_pinned(&component_of, n_components, constraints)?;
        let unit = mesh.length_unit();
        let unit_mesh = mesh.with_positions(
            mesh.positions()
                .iter()
                .map(|p| p.map(|v| v / unit))
                .collect(),
        )?;
        crate::interrupt::check()?;
        let mut unit_constraints = constraints.clone();
        for (i, c) in constraints.as_slice().iter().enumerate() {
            unit_constraints.set_rhs(i, target_in_unit(i, c.kind.rhs(), unit)?)?;
        }
        Ok(UnitScaled {
            unit,
            mesh: unit_mesh,
            constraints: unit_constraints,
        })
    }

    /// The problem `min ‖A X − C‖ s.t. B X = D` with the energy rows
    /// `a X ≈ c` (in the problem's units) and the constraints' rows, each
    /// soft weight `w` carrying `w ℓ^power` ([`SoftWeightScale`]), and the
    /// report its solver's reports start from: `operator`, the warnings of
    /// `mesh` (the mesh as given), the length unit, the soft weight scale
    /// and the seconds since `started`.
    pub(crate) fn problem(
        &self,
        a: &SparseColMat<usize, f64>,
        c: &Mat<f64>,
        operator: EnergyOperator,
        power: i32,
        mesh: &Mesh,
        started: Instant,
    ) -> Result<(LseProblem, Report), Error> {
        let soft_scale = SoftWeightScale {
            length: self.unit,
            power,
        };
        let problem = LseProblem::new(
            a,
            c,
            &self.constraints,
            self.mesh.bbox_diagonal(),
            soft_scale,
        )?;
        let mut report = Report {
            energy: Some(operator),
            warnings: mesh.warnings().iter().map(Into::into).collect(),
            length_unit: self.unit,
            soft_weight_scale: Some(soft_scale.factor()),
            ..Report::default()
        };
        report.timings_s.setup = started.elapsed().as_secs_f64();
        Ok((problem, report))
    }
}

/// An estimate, with margins, of the address space the set-up maps at its
/// peak, from the mesh's and the constraint list's sizes, checked against the
/// address-space limit before it starts ([`UnitScaled::new`]): under a
/// limit its allocations, most of them infallible, must then fit, and the
/// next check is the factorisation's.
///
/// Per face: the ARAP rows' 9 entries as triplets (24 bytes) and as
/// compressed columns (16), the problem's copy (16), the 3 × 3 right-hand
/// side and its copy (144), the face in the unit mesh (24): 672, rounded
/// to 700. Per vertex: the Laplacian's ~7 entries assembled (40) and
/// copied (16), `δ` and its copy (48), the unit position (24), the
/// component label (16) and the normal matrix's ~19 pattern entries (16
/// each): 784, rounded to 800. Per constraint: its copy in units and its
/// row (256). Both energies' rows are counted, whichever is built. The
/// sum is doubled: freed blocks stay mapped in the allocator's heap
/// until it trims them, so what is mapped exceeds what is live.
fn setup_bytes(n_vertices: usize, n_faces: usize, n_constraints: usize) -> u64 {
    let live = 700 * n_faces as u64 + 800 * n_vertices as u64 + 256 * n_constraints as u64;
    live.saturating_mul(2)
}

/// A 3 × 4 affine map `p ↦ M[:, 0..3] p + M[:, 3]`, row-major: the
/// transform of a group of targets ([`Deformer::transform_group`]).
pub type Affine = [[f64; 4]; 3];

/// What [`Deformer::new`] and [`Deformer::with_formulation`] share: the
/// set-up phase (checks, `L`, `δ = L P`, `A`, `C`, `B`, `D`), then the
/// precompute `factor` makes of the problem and its base report.
fn set_up(
    mesh: Mesh,
    laplacian: LaplacianKind,
    constraints: ConstraintSet,
    factor: impl FnOnce(LseProblem, Report) -> Result<LseSolver, Error>,
) -> Result<Deformer, Error> {
    let (unit, problem, report) = assembled(&mesh, laplacian, &constraints)?;
    let solver = factor(problem, report)?;
    Ok(Deformer {
        mesh,
        targets: GroupTargets::new(constraints, unit),
        solver,
    })
}

/// The set-up phase: the length unit, the assembled problem in its units
/// and the report its solver's reports start from.
fn assembled(
    mesh: &Mesh,
    laplacian: LaplacianKind,
    constraints: &ConstraintSet,
) -> Result<(f64, LseProblem, Report), Error> {
    let t = Instant::now();
    let scaled = UnitScaled::new(mesh, constraints)?;
    let l = laplacian::laplacian(&scaled.mesh, laplacian)?;
    crate::interrupt::check()?;
    let delta = laplacian::apply(&l, scaled.mesh.positions());
    let operator = EnergyOperator::Laplacian(laplacian);
    let power = laplacian.inverse_length_power();
    let (problem, report) = scaled.problem(&l, &delta, operator, power, mesh, t)?;
    Ok((scaled.unit, problem, report))
}

impl GroupTargets {
    /// `constraints` as given, their targets the rest targets; `unit` the
    /// mesh's length unit.
    pub(crate) fn new(constraints: ConstraintSet, unit: f64) -> GroupTargets {
        let rest = constraints
            .as_slice()
            .iter()
            .map(|c| c.kind.rhs())
            .collect();
        GroupTargets {
            constraints,
            rest,
            unit,
        }
    }

    /// The constraints with their current targets.
    pub fn constraints(&self) -> &ConstraintSet {
        &self.constraints
    }

    /// [`Deformer::transform_group`] on the targets alone: returns the
    /// constraints it moved with their new targets (mesh units).
    pub fn transform_group(
        &mut self,
        name: &str,
        m: &Affine,
    ) -> Result<Vec<(usize, [f64; 3])>, Error> {
        let moved = self.transformed_targets(name, m)?;
        for &(index, target) in &moved {
            self.constraints.set_rhs(index, target)?;
        }
        Ok(moved)
    }

    /// The targets `m` gives the members of group `name`, checked.
    fn transformed_targets(&self, name: &str, m: &Affine) -> Result<Vec<(usize, [f64; 3])>, Error> {
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
        Ok(moved)
    }

    /// The constraint indices of group `name` (increasing); an error naming
    /// the groups there are if it has no member.
    pub(crate) fn group_members(&self, name: &str) -> Result<Vec<usize>, Error> {
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

    /// Checks a new target of constraint `index` (mesh units): it exists,
    /// and the target is finite and representable in the problem's unit.
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
}

impl Deformer {
    /// The set-up phase alone: the problem `min ‖A X − C‖ s.t. B X = D`
    /// that [`Deformer::new`] factors, in its units (lengths divided by
    /// the mesh's [`Mesh::length_unit`]), for a caller that factors it
    /// itself or exports it.
    pub fn assemble(
        mesh: &Mesh,
        laplacian: LaplacianKind,
        constraints: &ConstraintSet,
    ) -> Result<LseProblem, Error> {
        Ok(assembled(mesh, laplacian, constraints)?.1)
    }

    /// Set-up and precompute phases: checks the constraints against the
    /// mesh (vertex range, every component pinned), builds `L`, `δ = L P`,
    /// `A`, `C`, `B`, `D`, and factors the system as `options` say
    /// ([`LseSolver::new`]). Set-up errors come before any factorisation.
    pub fn new(
        mesh: Mesh,
        laplacian: LaplacianKind,
        constraints: ConstraintSet,
        options: &SolveOptions,
    ) -> Result<Deformer, Error> {
        set_up(mesh, laplacian, constraints, |problem, report| {
            LseSolver::with_base_report(problem, report, options)
        })
    }

    /// [`Deformer::new`] with a formulation object under `resources`
    /// ([`LseSolver::with_formulation`]).
    pub fn with_formulation(
        mesh: Mesh,
        laplacian: LaplacianKind,
        constraints: ConstraintSet,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<Deformer, Error> {
        set_up(mesh, laplacian, constraints, |problem, report| {
            LseSolver::factored(problem, report, formulation, resources)
        })
    }

    /// The solver of the assembled problem (in its units: lengths divided
    /// by [`Deformer::length_unit`]): its refinement
    /// ([`LseSolver::refine_mode`]), prepared system,
    /// condition estimate, diagnostics and its solves in the problem's
    /// units. The mesh-level phases below go through it.
    pub fn solver(&self) -> &LseSolver {
        &self.solver
    }

    /// The solver, to change its settings ([`LseSolver::set_refine`]), solve in the problem's units
    /// ([`LseSolver::solve_into`], [`LseSolver::solve_columns`]), diagnose
    /// or estimate the condition. Targets are moved through the deformer
    /// ([`Deformer::set_target`] and the like), which keeps them in the
    /// mesh's units and the rest targets: [`LseSolver::set_rhs`] here would
    /// leave [`Deformer::constraints`] behind.
    pub fn solver_mut(&mut self) -> &mut LseSolver {
        &mut self.solver
    }

    /// Precompute phase again with `options` ([`LseSolver::refactor`]):
    /// on error the previous factorisation stays.
    pub fn refactor(&mut self, options: &SolveOptions) -> Result<(), Error> {
        self.solver.refactor(options)
    }

    /// Precompute phase again with a formulation object under `resources`
    /// ([`LseSolver::refactor_with`]).
    pub fn refactor_with(
        &mut self,
        formulation: &dyn Formulation,
        resources: &Resources,
    ) -> Result<(), Error> {
        self.solver.refactor_with(formulation, resources)
    }

    /// Solve phase: positions for the current targets, in the mesh's units.
    pub fn solve(&mut self) -> Result<Solution, Error> {
        let x = self.solve_matrix()?;
        Ok(Solution {
            positions: self.positions_of(&x),
            report: self.report().clone(),
        })
    }

    /// [`LseSolver::solve_into`] as positions in the mesh's units: refined
    /// unless the mode is [`crate::formulation::Refine::EstimateOnly`] (then no correction at all, so no
    /// forward-error estimate), without the solution diagnostics (the
    /// report's solution fields read "not computed",
    /// [`Report::clear_solution_diagnostics`], until
    /// [`LseSolver::diagnose`]).
    pub fn solve_undiagnosed(&mut self) -> Result<Vec<[f64; 3]>, Error> {
        let mut x = Mat::zeros(self.problem().n(), 3);
        self.solver.solve_into(x.as_mut())?;
        Ok(self.positions_of(&x))
    }

    /// The rows of `x` (problem units) as positions in the mesh's units.
    fn positions_of(&self, x: &Mat<f64>) -> Vec<[f64; 3]> {
        let u = self.targets.unit;
        (0..x.nrows())
            .map(|i| [x[(i, 0)] * u, x[(i, 1)] * u, x[(i, 2)] * u])
            .collect()
    }

    /// Solve phase returning `X` (n × 3) of the assembled problem — in its
    /// units, the positions divided by [`Deformer::length_unit`] — after
    /// refinement ([`LseSolver::refine_mode`]), updating
    /// [`Deformer::report`] with the solution diagnostics, the refinement
    /// and its warnings.
    pub fn solve_matrix(&mut self) -> Result<Mat<f64>, Error> {
        self.solver.solve()
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
            self.targets.check_update(index, target)?;
        }
        for &(index, target) in updates {
            self.write_target(index, target)?;
            self.targets.rest[index] = target;
        }
        Ok(())
    }

    /// Sets the targets of group `name`, one per member in increasing
    /// constraint index ([`ConstraintSet::group`]); they become the rest
    /// targets. On error (unknown group, wrong count, non-finite value)
    /// nothing changes.
    pub fn set_group_targets(&mut self, name: &str, targets: &[[f64; 3]]) -> Result<(), Error> {
        let members = self.targets.group_members(name)?;
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
        for (index, target) in self.targets.transformed_targets(name, m)? {
            self.write_target(index, target)?;
        }
        Ok(())
    }

    /// Whether [`Deformer::transform_group`]`(name, m)` would succeed,
    /// changing nothing: the same checks (a known group, a finite `m`,
    /// targets finite and representable in the problem's unit), for
    /// callers that apply `m` another way (a response basis).
    pub fn check_transform(&self, name: &str, m: &Affine) -> Result<(), Error> {
        self.targets.transformed_targets(name, m).map(|_| ())
    }

    /// The rest target of every constraint (see [`Deformer::transform_group`]).
    pub fn rest_targets(&self) -> &[[f64; 3]] {
        &self.targets.rest
    }

    /// The constraint indices of group `name` (increasing); an error naming
    /// the groups there are if it has no member.
    pub fn group_members(&self, name: &str) -> Result<Vec<usize>, Error> {
        self.targets.group_members(name)
    }

    /// Writes a checked target (in the mesh's units) into the problem (in
    /// its units) and the constraints.
    fn write_target(&mut self, index: usize, target: [f64; 3]) -> Result<(), Error> {
        let u = self.targets.unit;
        self.solver
            .set_rhs(index, [target[0] / u, target[1] / u, target[2] / u])?;
        self.targets.constraints.set_rhs(index, target)?;
        Ok(())
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
        &self.targets.constraints
    }

    /// The assembled problem: on the mesh and targets divided by
    /// [`Deformer::length_unit`].
    pub fn problem(&self) -> &LseProblem {
        self.solver.problem()
    }

    /// The length the problem's lengths are divided by: the mesh's mean
    /// edge length ([`Mesh::length_unit`]).
    pub fn length_unit(&self) -> f64 {
        self.targets.unit
    }
}
