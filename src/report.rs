//! What happened in a deformation: the [`Report`], which the solver
//! assembles from a formulation's precompute record and its own solution
//! diagnostics, and its parts (typed warnings, the method's own facts).

use serde::{Serialize, Serializer};

use crate::backend::{BackendName, FactorKind};
use crate::choice::{ArapEnergy, ArapInit, Method};
use crate::laplacian::LaplacianKind;
use crate::problem::LseProblem;

mod conflicts;
mod facts;
mod warning;
mod wire;
use conflicts::conflict_warning;
pub use conflicts::{CONFLICT_WARNINGS_SHOWN, ConflictSources};
pub use facts::MethodFacts;
pub use warning::{Warning, WarningKind, WarningSubject};

/// A list that a method may or may not be able to produce — the redundant
/// and conflicting hard constraints, which only the methods with rank
/// detection find. Reads as a slice (empty when not detected); serialised
/// as the list, or as the string `"not detected"`.
#[derive(Debug, Clone, PartialEq)]
pub struct Detected<T>(Option<Vec<T>>);

impl<T> Default for Detected<T> {
    fn default() -> Self {
        Detected(Some(Vec::new()))
    }
}

impl<T> Detected<T> {
    /// The method does not detect this (penalty).
    pub(crate) fn not_detected() -> Self {
        Detected(None)
    }

    /// Whether the method detects this at all.
    pub fn is_detected(&self) -> bool {
        self.0.is_some()
    }

    /// Appends an item (making the list detected).
    pub fn push(&mut self, item: T) {
        self.0.get_or_insert_with(Vec::new).push(item);
    }
}

impl<T> std::ops::Deref for Detected<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        self.0.as_deref().unwrap_or(&[])
    }
}

impl<'a, T> IntoIterator for &'a Detected<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<T: PartialEq> PartialEq<Vec<T>> for Detected<T> {
    fn eq(&self, other: &Vec<T>) -> bool {
        self.0.as_ref() == Some(other)
    }
}

impl<T: PartialEq, const N: usize> PartialEq<[T; N]> for Detected<T> {
    fn eq(&self, other: &[T; N]) -> bool {
        self.0.as_deref() == Some(&other[..])
    }
}

impl<T: Serialize> Serialize for Detected<T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match &self.0 {
            Some(list) => list.serialize(serializer),
            None => serializer.serialize_str("not detected"),
        }
    }
}

/// How far a soft constraint fell short of its target.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SoftResidual {
    /// Constraint index in the constraints file.
    pub index: usize,
    /// Its weight `w`, as given (the energy's term is `w²‖b·X − d‖²` in
    /// the mesh's units, whatever the length unit of the assembly).
    pub weight: f64,
    /// `‖b·X − d‖₂` (unweighted), in the mesh's units.
    pub residual: f64,
}

/// A skipped hard constraint that the solution does not satisfy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Conflict {
    /// Constraint index in the constraints file.
    pub index: usize,
    /// `‖b·X − d‖₂`, the distance by which it is violated.
    pub residual: f64,
}

/// Entry counts of the matrices involved.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Nnz {
    /// `A = [L; w B_soft]`.
    pub a: usize,
    /// `B` (hard constraints).
    pub b: usize,
    /// `A Q2` (null-space method only).
    pub aq2: Option<usize>,
    /// The matrix that was factored, counted as a full symmetric matrix
    /// (both triangles): `(AQ2)ᵀ(AQ2)`, `AᵀA + w²BᵀB`, or the KKT matrix.
    pub normal: Option<usize>,
    /// The factor `L` (lower triangle).
    pub factor: Option<usize>,
    /// Bytes of the factor's values and row indices.
    pub factor_bytes: Option<usize>,
    /// Entries of the implicit `Q` and `R` of the constraint QR.
    pub qr: Option<usize>,
}

/// Wall-clock seconds of each phase (paper §4: set-up, precompute =
/// QR + preparation + normal matrix + symbolic + numeric, solution).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Building `L`, `δ`, `A`, `C`, `B`, `D` (and checks).
    pub setup: f64,
    /// QR of `Bᵀ` with rank detection.
    pub qr: f64,
    /// `A Q2` (and, for other formulations, assembling what they factor
    /// beyond the normal matrix).
    pub preparation: f64,
    /// The normal matrix (pattern and values).
    pub normal_matrix: f64,
    /// Symbolic analysis (ordering, elimination tree, supernodes).
    pub symbolic: f64,
    /// Numeric factorisation.
    pub numeric: f64,
    /// Computing a fill-reducing ordering held equal across back ends and
    /// given to the back end (0 when it ordered by itself, inside
    /// `symbolic`).
    pub ordering: f64,
    /// The last solve: `R1ᵀy = D`, right-hand side, two triangular solves,
    /// `X = Q[y; z]`.
    pub solve: f64,
    /// Iterative refinement after the last solve, including the
    /// forward-error estimate (one more correction when refinement is off).
    /// `0` after a solve that neither refined nor estimated
    /// (`solve_into` with refinement off), and after a solve of other than
    /// three columns, whose refinement of each block is timed in `solve`.
    pub refine: f64,
    /// Residual checks and conflict classification after the last solve
    /// (not part of the paper's phases).
    pub diagnostics: f64,
}

impl Timings {
    /// QR + preparation + normal matrix + ordering + symbolic + numeric.
    pub fn precompute(&self) -> f64 {
        self.qr
            + self.preparation
            + self.normal_matrix
            + self.ordering
            + self.symbolic
            + self.numeric
    }
}

/// The operator whose energy a mesh problem minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnergyOperator {
    /// A Laplacian of the given kind (Laplacian editing).
    Laplacian(LaplacianKind),
    /// The as-rigid-as-possible rows of the given energy.
    Arap(ArapEnergy),
}

impl std::fmt::Display for EnergyOperator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EnergyOperator::Laplacian(kind) => f.write_str(kind.name()),
            EnergyOperator::Arap(energy) => write!(f, "arap-{}", energy.name()),
        }
    }
}

impl Serialize for EnergyOperator {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// The report of a deformation. Serialised (JSON) with one key per field
/// under the field's name, except: `factor_backend` also as
/// `spd_backend` (its deprecated alias, kept for one release), `energy` as
/// `laplacian`, `warnings` as the array of their texts plus
/// `warning_codes`, the array of their codes ([`WarningKind::code`]), and
/// `method_facts` as the three keys `penalty_weight`,
/// `penalty_weight_unit` and `kkt_multiplier_scale` (`null` where they do
/// not apply).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Report {
    /// The formulation (serialised as its word, e.g. `nullspace-qr`).
    pub method: Method,
    /// The QR back end's name, if the method uses one.
    pub qr_backend: Option<BackendName>,
    /// The factorisation of the matrix factored: the SPD back end's
    /// Cholesky, or the KKT method's `LDLᵀ`. Serialised as
    /// `factor_backend` and, for one release, also as `spd_backend` (the
    /// deprecated name, from when every method factored an SPD matrix).
    pub factor_backend: Option<FactorKind>,
    /// The operator of the energy: a Laplacian kind, or ARAP's rows
    /// (serialised under the key `laplacian`, as `cotan`, `uniform`, … or
    /// `arap-spokes`, `arap-spokes-and-rims`); `None` for a problem given
    /// as matrices.
    pub energy: Option<EnergyOperator>,
    /// Number of vertices (unknowns).
    pub vertices: usize,
    /// Number of constraints (hard + soft).
    pub constraints: usize,
    /// Number of hard constraints.
    pub hard_constraints: usize,
    /// Number of soft constraints.
    pub soft_constraints: usize,
    /// Numerical rank of `B` (methods with rank detection).
    pub rank: Option<usize>,
    /// Hard constraints skipped as dependent on earlier ones and satisfied
    /// by the solution anyway (constraint indices, increasing); `"not
    /// detected"` for penalty, which has no rank detection.
    pub redundant: Detected<usize>,
    /// Hard constraints skipped as dependent and *not* satisfied: they
    /// contradict earlier constraints, which win. `"not detected"` for
    /// penalty.
    pub conflicting: Detected<Conflict>,
    /// `max ‖b_k·X − d_k‖₂` over the hard constraints that were kept.
    pub max_constraint_residual: f64,
    /// The same divided by the length scale (bounding-box diagonal).
    pub max_constraint_residual_relative: f64,
    /// `‖A X − C‖_F` of the assembled problem (for a mesh: assembled on
    /// the positions divided by `length_unit`).
    pub least_squares_residual: f64,
    /// `‖A X − C‖_F / ‖C‖_F` (0 when `C = 0`): independent of units.
    pub least_squares_residual_relative: f64,
    /// How far each soft constraint fell short of its target, in the
    /// constraints' order.
    pub soft_residuals: Vec<SoftResidual>,
    /// The length unit of tolerances: the mesh's bounding-box diagonal.
    pub length_scale: f64,
    /// The length the mesh and its targets were divided by before assembly
    /// (the mesh's mean edge length, [`crate::mesh::Mesh::length_unit`]; 1 for problems given
    /// as matrices). Positions, residuals and tolerances in this report are
    /// in the mesh's own units.
    pub length_unit: f64,
    /// `length_unitᵃ`, the factor the soft rows of the assembled problem
    /// carry on top of their weights, `a` the power of length in the
    /// Laplacian's entries (2 for `cotan` and `intrinsic-delaunay`, 0 for
    /// `uniform` and `cotan-symmetric`): it makes the assembled problem's
    /// minimiser that of the documented energy
    /// `‖L(X − P)‖² + Σ w²‖b·X − d‖²` in the mesh's units (docs/units.md §3).
    /// 1 for ARAP (its rows are dimensionless: `a = 0`); `None` for a
    /// problem given as matrices.
    pub soft_weight_scale: Option<f64>,
    /// Iterative refinement of the last solve: steps, the size of every
    /// correction, why it stopped.
    pub refinement: Option<crate::refinement_types::Refinement>,
    /// The estimated forward error of the last solution, as the largest
    /// vertex error over the length scale (docs/refinement.md §5 for how
    /// it is estimated); a warning is issued above
    /// [`crate::refinement_types::FORWARD_ERROR_WARNING`].
    pub forward_error_estimate: Option<f64>,
    /// The tolerance that classified skipped constraints as conflicting:
    /// a skipped constraint conflicts when its residual exceeds this times
    /// its row's norm (see [`CONFLICT_RELATIVE_TOLERANCE`]).
    pub conflict_tolerance: f64,
    /// Matrix sizes.
    pub nnz: Nnz,
    /// Seconds per phase.
    pub timings_s: Timings,
    /// Things the user should know (serialised as their texts under
    /// `warnings` and their codes under `warning_codes`).
    pub warnings: Vec<Warning>,
    /// Estimate of the 2-norm condition number of the factored matrix,
    /// when asked for (`Prepared::estimate_condition` of the formulation:
    /// it costs solves, so it is not computed by default).
    pub condition_estimate: Option<crate::condition::ConditionEstimate>,
    /// What the precomputed method fixed that the others have no notion
    /// of (the penalty weight, the KKT multiplier scale); `None` before a
    /// precompute.
    pub method_facts: Option<MethodFacts>,
    /// The as-rigid-as-possible iterations (`deform --energy arap` only).
    pub arap: Option<ArapReport>,
    /// The memory budget the precompute was checked against (serialised
    /// as `{"bytes": N, "source": "option"}`, `bytes` `null` when
    /// unlimited, the source one of `option`, `environment`, `available`,
    /// `rlimit`, `cgroup`, `unlimited`: [`crate::limits::BudgetSource`]);
    /// `None` before a precompute.
    pub memory_budget: Option<crate::limits::MemoryBudget>,
    /// The fill-reducing ordering the factorisation used (key `ordering`):
    /// `own (amd)`, `own (scotch)`, … when the back end chose (its method in
    /// brackets), `amd`, `metis`, `natural` or `given` when it was held
    /// equal, `… (kkt)` for KKT (vertices in that order, each multiplier
    /// after its last vertex), `… (applied to the matrix)` for a back end
    /// from outside that took no permutation; `None` before a precompute
    /// and when nothing was factored (docs/equal-terms.md).
    pub ordering: Option<String>,
    /// The threads the factorisation ran on (key `threads`; for MUMPS on
    /// the driving rank, its ranks under `mumps`); `None` when nothing was
    /// factored or a back end from outside does not say.
    pub threads: Option<usize>,
    /// What the factor's back end reports of its factorisation beyond the
    /// generic keys, serialised under the key its section names, present
    /// only when the back end reports something: for MUMPS the key `mumps`,
    /// `{"ranks", "factor_entries_per_rank", "peak_bytes_per_rank",
    /// "ordering", "out_of_core"}` ([`crate::backend::BackendFacts`]).
    pub backend_facts: Option<crate::backend::BackendFacts>,
    /// How many times the solves since the precompute had to factor the
    /// matrix again (key `refactorizations`): a back end that keeps one
    /// numeric factor per analysis refactors when another factorisation
    /// of the same analysis solved in between
    /// ([`crate::backend::spd::SpdFactor::refactorizations`]); `0` for the
    /// others.
    pub refactorizations: usize,
}

impl Report {
    /// The relative penalty weight `w` of hard rows (penalty formulation
    /// only; key `penalty_weight`).
    pub fn penalty_weight(&self) -> Option<f64> {
        self.method_facts.and_then(|f| f.penalty_weight())
    }

    /// `s`, the power of two the relative penalty weight is multiplied by:
    /// hard rows enter with weight `w s` (penalty formulation only; key
    /// `penalty_weight_unit`).
    pub(crate) fn penalty_weight_unit(&self) -> Option<f64> {
        self.method_facts.and_then(|f| f.penalty_weight_unit())
    }

    /// The power-of-two scale `s` of the multiplier rows and columns of the
    /// KKT matrix `[AᵀA sBᵀ; sB 0]` (KKT formulation only; key
    /// `kkt_multiplier_scale`).
    pub(crate) fn kkt_multiplier_scale(&self) -> Option<f64> {
        self.method_facts.and_then(|f| f.kkt_multiplier_scale())
    }

    /// Deprecated alias of [`Report::factor_backend`] (the key
    /// `spd_backend`, kept for one release).
    pub fn spd_backend(&self) -> Option<FactorKind> {
        self.factor_backend.clone()
    }

    /// The codes of [`Report::warnings`], in order (the key
    /// `warning_codes`).
    pub fn warning_codes(&self) -> Vec<&'static str> {
        self.warnings.iter().map(Warning::code).collect()
    }

    /// Marks the solution diagnostics as not computed, for a solve that
    /// skipped them ([`crate::solver::LseSolver::solve_into`]): the
    /// forward-error estimate and the refinement become `None`, the four
    /// residuals (`max_constraint_residual`, `least_squares_residual` and
    /// their relative forms) NaN (`null` in JSON), the soft residuals
    /// empty, the diagnostics time 0 and the warnings those of set-up and
    /// precompute (`warnings`). What the earlier solve measured would
    /// describe another solution. `redundant` and `conflicting` keep the
    /// classification of the last diagnosed solve (the rows skipped are the
    /// factor's). [`crate::solver::LseSolver::diagnose`] fills them all.
    pub(crate) fn clear_solution_diagnostics(&mut self, warnings: &[Warning]) {
        self.forward_error_estimate = None;
        self.refinement = None;
        self.max_constraint_residual = f64::NAN;
        self.max_constraint_residual_relative = f64::NAN;
        self.least_squares_residual = f64::NAN;
        self.least_squares_residual_relative = f64::NAN;
        self.soft_residuals.clear();
        self.timings_s.diagnostics = 0.0;
        self.warnings = warnings.to_vec();
    }
}

/// What the ARAP iterations did ([`crate::arap::ArapDeformer`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ArapReport {
    /// The energy (serialised as `spokes` or `spokes-and-rims`).
    pub energy: ArapEnergy,
    /// The initial guess (serialised as `rest` or `linear`).
    pub init: ArapInit,
    /// The objective (ARAP energy plus the soft constraints' `w²‖b·X − d‖²`)
    /// of the initial guess, with its optimal rotations.
    pub initial_energy: f64,
    /// The objective after each iteration, with the rotations fitted to
    /// that iteration's positions.
    pub energies: Vec<f64>,
    /// `max ‖b_k·X − d_k‖₂` over the kept hard constraints after each
    /// iteration.
    pub constraint_residuals: Vec<f64>,
    /// Iterations run.
    pub iterations: usize,
    /// Why the iterations stopped (`null` until [`crate::arap::ArapDeformer::run`]).
    pub stop_reason: Option<ArapStop>,
    /// Median wall-clock seconds of one iteration (local + global step).
    pub time_per_iteration_s: f64,
    /// Wall-clock seconds of each iteration.
    pub iteration_times_s: Vec<f64>,
    /// Seconds in local steps (rotation fits and the objective), all
    /// iterations.
    pub local_time_s: f64,
    /// Seconds in global steps (right-hand side and solve), all iterations.
    pub global_time_s: f64,
    /// Rotation fits that kept the previous rotation because the
    /// covariance was zero, non-finite or rank ≤ 1 with the previous
    /// rotation still optimal (summed over iterations).
    pub kept_rotations: usize,
}

/// Why [`crate::arap::ArapDeformer::run`] stopped, serialised as its word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ArapStop {
    /// The iteration cap was reached.
    Iterations,
    /// The relative decrease of the objective fell to the tolerance (or
    /// was not a number).
    Tolerance,
    /// The objective is zero: nothing left to decrease.
    Stationary,
}

impl std::fmt::Display for ArapStop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ArapStop::Iterations => "iterations",
            ArapStop::Tolerance => "tolerance",
            ArapStop::Stationary => "stationary",
        })
    }
}

/// Relative tolerance for classifying a skipped hard constraint as
/// conflicting: its residual over its row's norm, `‖b_k X − d_k‖ / ‖b_k‖`
/// (the distance by which `X` misses it, whatever the row's scaling), must
/// exceed `1e-8 ×` the length scale.
///
/// A skipped constraint that is consistent with the kept ones is satisfied
/// up to its own numerical remainder (`≤ η ‖b_j‖ ‖X‖`, with `η = 1e-10` the
/// rank tolerance) plus rounding of the kept rows (`~1e-15` relative): two
/// orders of magnitude below this bound while `‖X‖` is of the order of the
/// length scale. Where `‖X‖` is a hundred times the length scale or more (a
/// sliver mesh pulled apart by conflicting targets), a nearly dependent row
/// consistent with the kept ones can miss by more than this bound and is
/// then called conflicting (tests/rank_properties.rs, `classified_sets`).
/// A conflict smaller than `1e-8` of the model's size is invisible in any
/// rendering and below the precision of scanned data.
pub const CONFLICT_RELATIVE_TOLERANCE: f64 = 1e-8;

/// Fills the solution diagnostics of `report` for the solution `x` of
/// `problem`: the residual of every kept hard constraint, the split of the
/// `skipped` rows of `B` into redundant and conflicting (only when
/// `detects_dependence`: the penalty method has no rank detection, and its
/// lists say "not detected"), the soft residuals and `‖AX − C‖`.
///
/// Everything is computed in the problem's units and converted to the
/// mesh's by `report.length_unit` (set by the caller; 1 for a problem given
/// as matrices).
pub(crate) fn fill_solution_diagnostics(
    report: &mut Report,
    problem: &crate::problem::LseProblem,
    x: &faer::Mat<f64>,
    skipped: &[usize],
    detects_dependence: bool,
) {
    let unit = if report.length_unit > 0.0 {
        report.length_unit
    } else {
        1.0
    };
    let scale = problem.length_scale();
    let tolerance = CONFLICT_RELATIVE_TOLERANCE * scale;
    let hard = problem.hard_constraints();
    let mut is_skipped = vec![false; hard.len()];
    for &k in skipped {
        is_skipped[k] = true;
    }
    let mut max_kept = 0.0f64;
    let (mut redundant, mut conflicting) = if detects_dependence {
        (Detected::default(), Detected::default())
    } else {
        (Detected::not_detected(), Detected::not_detected())
    };
    for (k, &index) in hard.iter().enumerate() {
        let r = problem.hard_residual(k, x);
        if !is_skipped[k] {
            max_kept = max_kept.max(r);
        } else if r.is_nan() || r > tolerance * row_norm(problem, k) {
            // Beyond the tolerance, or not even a finite number: never
            // "redundant" (satisfied anyway) unless it is.
            if !r.is_finite() {
                report.warnings.push(Warning::new(
                    WarningKind::ConflictResidualOverflow,
                    format!(
                        "hard constraint {index} is conflicting and its residual overflows a double (its coefficients or target are near the limit of the number range)"
                    ),
                ));
            }
            conflicting.push(Conflict {
                index,
                residual: r * unit,
            });
        } else {
            redundant.push(index);
        }
    }
    report.redundant = redundant;
    report.conflicting = conflicting;
    report.max_constraint_residual = max_kept * unit;
    report.max_constraint_residual_relative = if scale > 0.0 {
        max_kept / scale
    } else {
        max_kept
    };
    let residual = problem.a_times(x) - problem.c();
    let n_lap = problem.n_laplacian_rows();
    report.soft_residuals = problem
        .soft_constraints()
        .iter()
        .enumerate()
        .map(|(k, soft)| {
            let row = residual.row(n_lap + k);
            let norm = (0..row.ncols())
                .map(|c| row[c] * row[c])
                .sum::<f64>()
                .sqrt();
            SoftResidual {
                index: soft.index,
                weight: soft.weight,
                residual: norm / soft.row_weight * unit,
            }
        })
        .collect();
    // In the units of the problem as given (A and C of a general problem
    // carry a power-of-two factor).
    report.least_squares_residual = residual.norm_l2() / problem.a_scale();
    let c_norm = problem.c().norm_l2() / problem.a_scale();
    report.least_squares_residual_relative = if c_norm > 0.0 {
        report.least_squares_residual / c_norm
    } else {
        report.least_squares_residual
    };
    report.length_scale = scale * unit;
    report.conflict_tolerance = tolerance * unit;
    report.hard_constraints = hard.len();
    report.soft_constraints = problem.soft_constraints().len();
    report.constraints = hard.len() + problem.soft_constraints().len();
    report.vertices = problem.n();
    report.nnz.a = problem.a().val().len();
    report.nnz.b = problem.b().val().len();
}

/// `‖b_k‖₂`, the norm of hard row `k` of `B`.
fn row_norm(problem: &crate::problem::LseProblem, k: usize) -> f64 {
    let b = problem.b();
    b.val()[b.symbolic().row_range(k)]
        .iter()
        .fold(0.0, |n, v| n.hypot(*v))
}

/// The first vertex (row) with a non-finite coordinate in `x`, if any.
pub(crate) fn first_non_finite(x: faer::MatRef<'_, f64>) -> Option<usize> {
    (0..x.nrows()).find(|&i| (0..x.ncols()).any(|c| !x[(i, c)].is_finite()))
}

/// The warnings of `report`'s conflicting constraints: one per conflict for
/// the first [`CONFLICT_WARNINGS_SHOWN`], naming the index, the residual
/// (in the report's units) and the earlier constraints it contradicts where
/// `sources` finds them, then one counting the rest.
pub(crate) fn conflict_warnings(
    report: &Report,
    problem: &LseProblem,
    sources: &mut ConflictSources,
) -> Vec<Warning> {
    let mut out = Vec::new();
    for c in report.conflicting.iter().take(CONFLICT_WARNINGS_SHOWN) {
        let with = sources.of(problem, c.index).unwrap_or_default().to_vec();
        out.push(conflict_warning(c.index, with, c.residual));
    }
    let more = report
        .conflicting
        .len()
        .saturating_sub(CONFLICT_WARNINGS_SHOWN);
    if more > 0 {
        out.push(Warning::new(
            WarningKind::MoreConflictingConstraints,
            format!(
                "… and {more} more conflicting constraints were dropped ({} in all; every one is listed in the report's \"conflicting\")",
                report.conflicting.len()
            ),
        ));
    }
    out
}
