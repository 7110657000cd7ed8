//! Formulations of the constrained least-squares problem: the same inputs
//! (`A, C, B, D` of an [`LseProblem`]) and the same [`PrecomputeRecord`]
//! (which the solver turns into the [`crate::report::Report`]), so that the
//! paper's method can be compared with the alternatives on equal terms.
//!
//! | formulation | matrix factored | hard rows |
//! |---|---|---|
//! | [`NullSpaceQr`] (the paper) | `(AQ2)ᵀ(AQ2)`, SPD | exact; dependent rows skipped in list order |
//! | [`Penalty`] | `AᵀA + w²BᵀB`, SPD | approximated (`exact() == false`) |
//! | [`Kkt`] | `[AᵀA sBᵀ; sB 0]`, symmetric indefinite | exact; dependent rows make it singular (an error) |
//! | [`Elimination`] | `A_Uᵀ A_U`, SPD | exact; position constraints only |

use faer::sparse::SparseColMat;
use faer::{Mat, MatMut};

use crate::backend::FactorStorage;
use crate::backend::qr::QrKind;
use crate::backend::spd::SpdKind;
pub use crate::choice::Method;
use crate::condition::ConditionEstimate;
use crate::error::{Error, ProblemError, SolveOption};
use crate::limits::MemoryBudget;
use crate::problem::LseProblem;

mod elimination;
mod iterative_refinement;
mod kkt;
mod null_space;
mod penalty;
mod record;
mod util;

pub use elimination::Elimination;
#[allow(deprecated)]
pub use iterative_refinement::refine_with_memory;
pub use iterative_refinement::{
    AUTO_MAX_STEPS, CONVERGED_ULPS, FORWARD_ERROR_WARNING, FactorRounding, REMEASURE_EVERY, Refine,
    RefineStop, Refinement, max_hard_residual, refine, refine_with_rounding,
};
pub use kkt::{KKT_BACKWARD_ERROR_TOLERANCE, KKT_PIVOT_TOLERANCE, Kkt, kkt_ordering};
pub use null_space::NullSpaceQr;
pub use penalty::{
    PENALTY_FORWARD_ERROR_LIMIT, Penalty, PenaltyPoint, PenaltySolution, PenaltySweep,
};
pub use record::{FactorSizes, PhaseTimings, PrecomputeRecord, Precomputed};

/// A way to solve `min ‖AX − C‖ s.t. BX = D`.
pub trait Formulation: Send + Sync {
    /// The method this formulation implements.
    fn method(&self) -> Method;

    /// Short name for messages: the method's word.
    fn name(&self) -> String {
        self.method().name().into()
    }

    /// The precompute phase: factor everything that depends on the matrices
    /// only, refusing with [`ProblemError::TooLarge`] a factor whose
    /// estimated size exceeds `budget` (checked before it is allocated).
    /// Returns the system with the record of what was computed (sizes,
    /// timings, rank, warnings, the method's own facts).
    fn precompute_within(
        &self,
        problem: &LseProblem,
        budget: MemoryBudget,
    ) -> Result<Precomputed, Error>;

    /// [`Formulation::precompute_within`] the default memory budget
    /// ([`MemoryBudget::default`]).
    fn precompute(&self, problem: &LseProblem) -> Result<Precomputed, Error> {
        self.precompute_within(problem, MemoryBudget::default())
    }
}

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

/// A formulation with its back ends (the CLI's `--method`, `--qr`,
/// `--spd`, `--weight`); [`FormulationChoice::build`] makes it.
///
/// - `NullSpaceQr`: any QR back end × any SPD back end;
/// - `Penalty`: any SPD back end, `weight` required (there is no weight that
///   is right for every mesh: it competes with the scale of `L`);
/// - `Kkt`: faer's `LDLᵀ`; `spd` selects its variant (`FaerAuto`,
///   `FaerSimplicial`, `FaerSupernodal`), other SPD kinds are refused;
/// - `Eliminate`: any SPD back end (position constraints only).
///
/// `qr` is used by `NullSpaceQr` only; `weight` by `Penalty` only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FormulationChoice {
    /// The formulation.
    pub method: Method,
    /// The QR back end of `NullSpaceQr`.
    pub qr: QrKind,
    /// The SPD back end (for `Kkt`: the faer `LDLᵀ` variant).
    pub spd: SpdKind,
    /// The relative weight of the hard rows under `Penalty`.
    pub weight: Option<f64>,
}

impl FormulationChoice {
    /// `method` with the default back ends: sparse Givens QR, faer's
    /// automatic Cholesky, no weight.
    pub fn new(method: Method) -> FormulationChoice {
        FormulationChoice {
            method,
            qr: QrKind::SparseGivens,
            spd: SpdKind::FaerAuto,
            weight: None,
        }
    }

    /// The formulation.
    ///
    /// Errors: [`ProblemError::InvalidOption`] for a penalty without a
    /// finite positive weight or an SPD kind that KKT cannot use;
    /// [`ProblemError::InvalidArgument`] for a back end missing from this
    /// build.
    pub fn build(&self) -> Result<Box<dyn Formulation>, ProblemError> {
        self.build_with(&FactorStorage::InCore)
    }

    /// The formulation, its factor kept in `storage` (out of core: the
    /// `mumps` back end only).
    ///
    /// Errors: as [`FormulationChoice::build`], and
    /// [`ProblemError::InvalidArgument`] for out-of-core storage with
    /// another back end.
    pub fn build_with(
        &self,
        storage: &FactorStorage,
    ) -> Result<Box<dyn Formulation>, ProblemError> {
        storage.check()?;
        let invalid =
            |option: SolveOption, message: String| ProblemError::InvalidOption { option, message };
        match self.method {
            Method::NullSpaceQr => Ok(Box::new(NullSpaceQr::new(
                self.qr.backend()?,
                self.spd.backend_with(storage)?,
            ))),
            Method::Penalty => {
                let w = self.weight.ok_or_else(|| {
                    invalid(
                        SolveOption::Weight,
                        "the penalty method needs a weight (the relative weight of the former hard rows)".into(),
                    )
                })?;
                if !(w.is_finite() && w > 0.0) {
                    return Err(invalid(
                        SolveOption::Weight,
                        format!("weight {w} must be finite and > 0"),
                    ));
                }
                Ok(Box::new(Penalty::with_backend(
                    w,
                    self.spd.backend_with(storage)?,
                )))
            }
            Method::Kkt => match Kkt::for_spd(self.spd) {
                Some(kkt) => {
                    // Refuses out-of-core storage with faer's LDLᵀ, and a
                    // build without MUMPS, here rather than at precompute.
                    kkt.ldlt.backend_with(storage)?;
                    Ok(Box::new(Kkt {
                        storage: storage.clone(),
                        ..kkt
                    }))
                }
                None => Err(invalid(
                    SolveOption::Spd,
                    format!(
                        "the KKT method factors a symmetric indefinite matrix with faer's or MUMPS's LDLᵀ: its SPD back end must be faer-auto, faer-simplicial, faer-supernodal or mumps, not '{}'",
                        self.spd
                    ),
                )),
            },
            Method::Eliminate => Ok(Box::new(Elimination::new(self.spd.backend_with(storage)?))),
        }
    }
}
