//! Penalty weights — the paper's "only soft constraints" (its eq. 7 with the
//! hard rows appended): every hard row becomes a soft row of weight `w s`,
//! and `X` solves the normal equations
//!
//! `(AᵀA + (ws)² BᵀB) X = AᵀC + (ws)² BᵀD`
//!
//! with the SPD back end.
//!
//! **The weight is relative.** `s = 2^round(log₂ max_j ‖A e_j‖₂)`, the
//! power of two nearest to the largest column norm of `A` (as the KKT
//! formulation scales its multiplier rows), so `w = 1` weighs a hard row
//! like the heaviest column of the Laplacian rows. Cotangent Laplacian
//! entries grow like `1/h²` with the edge length `h`, so an absolute weight
//! would mean something different on every mesh resolution; the relative
//! one does not, and `s` is exact (a power of two) and in the report
//! (`penalty_weight_unit`). In the rest of this module `w` stands for the
//! effective weight `w s`. The hard rows then hold only approximately: their
//! residual is `O(1/w²)` while `w` is moderate, and the matrix's condition
//! grows like `w²`, so past some weight the factorisation breaks down (a
//! typed [`NumericalError::Breakdown`] or
//! [`NumericalError::NotPositiveDefinite`], never a garbage solution): the
//! curve the paper's Table 1 samples.
//!
//! The pattern of `AᵀA + w²BᵀB` does not depend on `w > 0`, so
//! [`PenaltySweep`] builds it and runs the back end's symbolic analysis
//! once, keeps `AᵀA` and `BᵀB` as values on that pattern, and then each
//! weight costs one sum of value arrays and one numeric factorisation.

use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};

use super::iterative_refinement::{Refine, Refinement, refine};
use super::record::{PrecomputeRecord, Precomputed};
use super::util::{Analysed, analyze_under, split_normal, with_context};
use super::{Formulation, Prepared};
use crate::backend::FactorKind;
use crate::backend::spd::{FaerLlt, SpdBackend, SpdFactor, SpdSymbolic};
use crate::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use crate::error::{Error, NumericalError, ProblemError};
use crate::problem::LseProblem;
use crate::report::{MethodFacts, Warning, WarningKind, first_non_finite};
use crate::resources::Resources;
use crate::sparse::{
    add_bt_times, at_residual, at_times, hard_residual, lower_diag, lower_sym_abs_mul,
    lower_sym_max_row_nnz, lower_sym_mul, lower_sym_norm_inf, lower_to_full,
};

/// The penalty formulation with weight `w` on every hard row, over an SPD
/// back end.
#[derive(Clone)]
pub struct Penalty {
    /// `w` (finite, `> 0`, and `w² < f64::MAX`).
    pub weight: f64,
    /// The Cholesky back end for `AᵀA + w²BᵀB`.
    pub spd: Arc<dyn SpdBackend>,
}

impl Penalty {
    /// Weight `w` over faer's sparse Cholesky (AMD, automatic supernodal).
    pub fn new(weight: f64) -> Penalty {
        Penalty {
            weight,
            spd: Arc::new(FaerLlt::auto()),
        }
    }

    /// Weight `w` over the given back end.
    pub fn with_backend(weight: f64, spd: Arc<dyn SpdBackend>) -> Penalty {
        Penalty { weight, spd }
    }
}

/// Rejects relative weights `w` whose effective square `(w s)²` is not a
/// finite positive number.
fn check_weight(w: f64, unit: f64) -> Result<(), Error> {
    let effective = w * unit;
    let square = effective * effective;
    if w.is_nan() || w <= 0.0 || !square.is_finite() || square == 0.0 {
        return Err(ProblemError::InvalidArgument {
            message: format!(
                "penalty weight {w:e} is invalid: it must be finite and > 0, and the effective weight w·s = {effective:e} (s = {unit:e}, the scale of A's columns) must have a finite nonzero square"
            ),
        }
        .into());
    }
    Ok(())
}

/// The weight sweep's verdict on a penalty solve: a
/// [`PenaltySolution::forward_error_estimate`] (against the exact solution
/// of the *penalty* system) above `1e-2` means fewer than about two correct
/// digits estimated — the estimate over-states the true error by two to
/// three orders of magnitude on the test problems (it replaces `|N⁻¹|` by
/// `N⁻¹` in LAPACK's bound), so such a solve has at most four to five
/// correct digits left: the weight has eaten the precision. The [`Penalty`]
/// formulation itself returns every finite solution and leaves the verdict
/// to the refine phase's forward-error estimate against the *constrained*
/// solution ([`super::FORWARD_ERROR_WARNING`]: a warning, or an error for
/// callers that ask to be strict).
pub const PENALTY_FORWARD_ERROR_LIMIT: f64 = 1e-2;

/// The description of the penalty matrix used in error messages.
fn matrix_name(w: f64) -> String {
    format!("the penalty normal matrix AᵀA + w²BᵀB (w = {w:e})")
}

impl Formulation for Penalty {
    fn method(&self) -> super::Method {
        super::Method::Penalty
    }

    fn precompute_with(
        &self,
        problem: &LseProblem,
        resources: &Resources,
    ) -> Result<Precomputed, Error> {
        check_weight(self.weight, 1.0)?;
        let sweep = PenaltySweep::with_resources(problem, self.spd.as_ref(), resources)?;
        let mut record = PrecomputeRecord::new(
            self.method(),
            FactorKind::Cholesky(self.spd.name()),
            MethodFacts::Penalty {
                weight: self.weight,
                weight_unit: sweep.weight_unit,
            },
        );
        record.timings.normal_matrix = sweep.normal_matrix_s;
        sweep.analysed.record(&mut record);
        record.sizes.normal = Some(sweep.full_nnz());
        crate::interrupt::check()?;
        let t = Instant::now();
        let prepared = sweep.factorize(self.weight)?;
        crate::interrupt::check()?;
        record.timings.numeric = t.elapsed().as_secs_f64();
        record.sizes.factor = Some(prepared.factor.nnz());
        record.sizes.factor_bytes = Some(prepared.factor.bytes());
        record.backend_facts = prepared.factor.facts();
        if problem.b().nrows() > 0 {
            record.warnings.push(Warning::new(
                WarningKind::PenaltyApproximate,
                format!(
                    "penalty method: the {} hard constraints are soft rows of relative weight {:e}; they hold only approximately (see max_constraint_residual) unless refined (refinement `auto`: the method of multipliers)",
                    problem.b().nrows(),
                    self.weight
                ),
            ));
        }
        Ok(Precomputed {
            system: Box::new(prepared),
            record,
        })
    }
}

/// The penalty system of one problem analysed once, ready to be factored
/// numerically for any number of weights.
///
/// Invariant: `ata` and `btb` are the values of `AᵀA` and `BᵀB` on
/// `pattern = tril(pattern(AᵀA + BᵀB))`, and `symbolic` is the back end's
/// analysis of `pattern`. `AᵀA + w²BᵀB` for any `w > 0` has exactly this
/// pattern (entries of both terms are kept even where one is zero).
pub struct PenaltySweep {
    /// `s`, the power of two the relative weight is multiplied by (see the
    /// module documentation).
    pub weight_unit: f64,
    pattern: SymbolicSparseColMat<usize>,
    ata: Vec<f64>,
    btb: Vec<f64>,
    symbolic: Box<dyn SpdSymbolic>,
    backend: crate::backend::BackendName,
    /// Seconds spent building the pattern and the values of `AᵀA`, `BᵀB`.
    pub normal_matrix_s: f64,
    /// Seconds spent in the (single) symbolic analysis.
    pub symbolic_s: f64,
    /// The analysis's ordering and threads.
    analysed: Analysed,
}

/// The outcome of one weight of a sweep.
#[derive(Debug)]
pub struct PenaltyPoint {
    /// The weight `w`.
    pub weight: f64,
    /// The solution, or the typed reason there is none (breakdown, not
    /// positive definite, non-finite solution, invalid weight).
    pub result: Result<PenaltySolution, Error>,
}

/// A penalty solution and its a-posteriori accuracy, computed from `X`
/// itself (not trusted from the factorisation).
#[derive(Debug, Clone)]
pub struct PenaltySolution {
    /// `X` (n × 3), finite.
    pub x: Mat<f64>,
    /// `max_k ‖b_k·X − d_k‖₂` over the hard rows: how far from exact.
    pub max_constraint_residual: f64,
    /// `‖A X − C‖_F`.
    pub least_squares_residual: f64,
    /// Normwise backward error of the solve,
    /// `max_c ‖N x_c − r_c‖∞ / (‖N‖∞ ‖x_c‖∞ + ‖r_c‖∞)` with
    /// `N = AᵀA + w²BᵀB` and `r = AᵀC + w²BᵀD`: how well the penalty
    /// system itself was solved (≈ 1e-16 for a stable solve; large when the
    /// factorisation lost its digits).
    pub backward_error: f64,
    /// Estimate of the relative forward error `‖X − X*‖∞ / ‖X‖∞` against
    /// the exact solution `X*` of the penalty system, from one extra solve:
    /// `max_c ‖N⁻¹(|r_c| + γ |N| |x_c|)‖∞ / ‖x_c‖∞` with `r = rhs − N X` and
    /// `γ = (k+1) ε`, `k` the most entries in a row of `N` — the bound of
    /// LAPACK's `xPORFS` with `N⁻¹` in place of `|N⁻¹|` (which would need a
    /// norm estimator), so an estimate of the error's size, not a bound.
    /// Unlike the backward error, it grows like `κ(N) ε` as `w` grows: it is
    /// what says that a large weight has lost digits before the
    /// factorisation breaks down.
    pub forward_error_estimate: f64,
    /// Seconds of the numeric factorisation.
    pub numeric_s: f64,
    /// Seconds of the solve (right-hand side and triangular solves).
    pub solve_s: f64,
}

impl PenaltySweep {
    /// Builds `tril(pattern(AᵀA + BᵀB))`, the values of `AᵀA` and `BᵀB` on
    /// it, and the back end's symbolic analysis (the only one of the sweep).
    /// The factor's size is checked against the default memory budget.
    pub fn new(problem: &LseProblem, spd: &dyn SpdBackend) -> Result<PenaltySweep, Error> {
        PenaltySweep::with_resources(problem, spd, &Resources::default())
    }

    /// [`PenaltySweep::new`] under `resources` (the budget, and the
    /// ordering and threads of the one analysis and every factorisation).
    pub(crate) fn with_resources(
        problem: &LseProblem,
        spd: &dyn SpdBackend,
        resources: &Resources,
    ) -> Result<PenaltySweep, Error> {
        let t = Instant::now();
        let (pattern, ata, btb) = split_normal(problem);
        let normal_matrix_s = t.elapsed().as_secs_f64();

        crate::interrupt::check()?;
        let (symbolic, analysed) = analyze_under(
            spd,
            pattern.as_ref(),
            resources,
            (&|k| k, problem.n()),
            "AᵀA + w²BᵀB",
        )?;
        let symbolic_s = analysed.symbolic_s;
        let ata_lower = faer::sparse::SparseColMatRef::new(pattern.as_ref(), &ata);
        let max_diagonal = (0..pattern.ncols())
            .map(|j| lower_diag(ata_lower, j))
            .fold(0.0f64, f64::max);
        Ok(PenaltySweep {
            weight_unit: crate::mesh::quality::power_of_two_unit(max_diagonal.sqrt()),
            ata,
            btb,
            pattern,
            symbolic,
            backend: spd.name(),
            normal_matrix_s,
            symbolic_s,
            analysed,
        })
    }

    /// Entries of the full symmetric `AᵀA + w²BᵀB`.
    pub(crate) fn full_nnz(&self) -> usize {
        2 * self.pattern.row_idx().len() - self.pattern.ncols()
    }

    /// The SPD back end's name.
    pub fn backend(&self) -> &str {
        &self.backend
    }

    /// `tril(AᵀA + (ws)²BᵀB)` for the relative weight `w` (values summed on
    /// the analysed pattern).
    pub fn normal_matrix(&self, w: f64) -> Result<SparseColMat<usize, f64>, Error> {
        check_weight(w, self.weight_unit)?;
        let w2 = (w * self.weight_unit).powi(2);
        let values = self
            .ata
            .iter()
            .zip(&self.btb)
            .map(|(&a, &b)| a + w2 * b)
            .collect();
        Ok(SparseColMat::new(self.pattern.clone(), values))
    }

    /// Numeric factorisation for weight `w` (reusing the analysis).
    fn factorize(&self, w: f64) -> Result<PreparedPenalty, Error> {
        let lower = self.normal_matrix(w)?;
        let factor = self
            .symbolic
            .factorize(lower.as_ref())
            .map_err(|e| with_context(e, &matrix_name(w), Some))?;
        Ok(PreparedPenalty {
            weight: w * self.weight_unit,
            lower,
            factor,
            shifted_targets: None,
            pending_targets: None,
        })
    }

    /// Factors for the relative weight `w` and solves for the current `C`,
    /// `D` of `problem` (the problem this sweep was built from), with the
    /// accuracy of the result measured from `X`.
    pub fn solve(&self, problem: &LseProblem, w: f64) -> Result<PenaltySolution, Error> {
        self.solve_refined(problem, w, Refine::EstimateOnly)
            .map(|(solution, _)| solution)
    }

    /// [`PenaltySweep::solve`] followed by refinement with the same factor
    /// (the method of multipliers, see [`super::refine`]): with
    /// [`Refine::EstimateOnly`] the plain penalty solution and the estimate of its
    /// distance from the constrained solution; otherwise the refined one.
    /// The solution's `backward_error` and `forward_error_estimate` are
    /// those of the plain penalty solve (against the penalty system).
    pub fn solve_refined(
        &self,
        problem: &LseProblem,
        w: f64,
        mode: Refine,
    ) -> Result<(PenaltySolution, Refinement), Error> {
        let t = Instant::now();
        let mut prepared = self.factorize(w)?;
        let numeric_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (mut x, rhs) = prepared.solve_with_rhs(problem)?;
        let solve_s = t.elapsed().as_secs_f64();
        let backward_error = backward_error(prepared.lower.as_ref(), &x, &rhs);
        let forward_error_estimate = prepared.forward_error_estimate(&x, &rhs)?;
        let refinement = refine(&mut prepared, problem, &mut x, mode)?;
        if let Some(vertex) = first_non_finite(x.as_ref()) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        let max_constraint_residual = (0..problem.b().nrows())
            .map(|k| problem.hard_residual(k, &x))
            .fold(0.0, f64::max);
        let solution = PenaltySolution {
            least_squares_residual: problem.least_squares_residual(&x),
            x,
            max_constraint_residual,
            backward_error,
            forward_error_estimate,
            numeric_s,
            solve_s,
        };
        Ok((solution, refinement))
    }

    /// One point per weight, in the order given: the analysis of
    /// [`PenaltySweep::new`] is reused, so the cost is one numeric
    /// factorisation and one solve per weight. The weights are independent
    /// given the analysis, so they are dealt to rayon's threads (one weight
    /// per thread at a time; up to one factor per thread in memory).
    pub fn run(&self, problem: &LseProblem, weights: &[f64]) -> Vec<PenaltyPoint> {
        use rayon::prelude::*;
        weights
            .par_iter()
            .with_max_len(1)
            .map(|&weight| PenaltyPoint {
                weight,
                result: self.solve(problem, weight),
            })
            .collect()
    }
}

/// `max_c ‖N x_c − r_c‖∞ / (‖N‖∞ ‖x_c‖∞ + ‖r_c‖∞)`.
fn backward_error(
    lower: faer::sparse::SparseColMatRef<'_, usize, f64>,
    x: &Mat<f64>,
    rhs: &Mat<f64>,
) -> f64 {
    let mut nx = Mat::<f64>::zeros(x.nrows(), x.ncols());
    lower_sym_mul(lower, x.as_ref(), nx.as_mut());
    let norm = lower_sym_norm_inf(lower);
    let mut worst = 0.0f64;
    for c in 0..x.ncols() {
        let (mut r, mut xn, mut bn) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..x.nrows() {
            r = r.max((nx[(i, c)] - rhs[(i, c)]).abs());
            xn = xn.max(x[(i, c)].abs());
            bn = bn.max(rhs[(i, c)].abs());
        }
        let denom = norm * xn + bn;
        if denom > 0.0 {
            worst = worst.max(r / denom);
        }
    }
    worst
}

/// A factored penalty system.
struct PreparedPenalty {
    /// The effective weight `w s`.
    weight: f64,
    lower: SparseColMat<usize, f64>,
    factor: Box<dyn SpdFactor>,
    /// The method of multipliers' shifted targets `D̃_k` (`None`:
    /// `D̃_0 = D`, reset by every solve).
    shifted_targets: Option<Mat<f64>>,
    /// `D̃_{k+1}` of the last correction, committed by `accept_correction`.
    pending_targets: Option<Mat<f64>>,
}

impl PreparedPenalty {
    /// `(ws)²`.
    fn w2(&self) -> f64 {
        self.weight * self.weight
    }

    /// `X` and the right-hand side `AᵀC + w²BᵀD` it solves.
    fn solve_with_rhs(&mut self, problem: &LseProblem) -> Result<(Mat<f64>, Mat<f64>), Error> {
        let mut rhs = at_times(problem.a().as_ref(), problem.c().as_ref());
        add_bt_times(
            problem.b().as_ref(),
            problem.d().as_ref(),
            self.w2(),
            rhs.as_mut(),
        );
        let mut x = rhs.clone();
        self.factor.solve_in_place(x.as_mut())?;
        if let Some(vertex) = first_non_finite(x.as_ref()) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        Ok((x, rhs))
    }
}

impl PreparedPenalty {
    /// See [`PenaltySolution::forward_error_estimate`].
    fn forward_error_estimate(
        &mut self,
        x: &Mat<f64>,
        rhs: &Mat<f64>,
    ) -> Result<f64, NumericalError> {
        let lower = self.lower.as_ref();
        let mut nx = Mat::<f64>::zeros(x.nrows(), x.ncols());
        lower_sym_mul(lower, x.as_ref(), nx.as_mut());
        let abs_x = Mat::<f64>::from_fn(x.nrows(), x.ncols(), |i, c| x[(i, c)].abs());
        let mut abs_nx = Mat::<f64>::zeros(x.nrows(), x.ncols());
        lower_sym_abs_mul(lower, abs_x.as_ref(), abs_nx.as_mut());
        let gamma = (lower_sym_max_row_nnz(lower) + 1) as f64 * f64::EPSILON;
        let mut v = Mat::<f64>::from_fn(x.nrows(), x.ncols(), |i, c| {
            (rhs[(i, c)] - nx[(i, c)]).abs() + gamma * abs_nx[(i, c)]
        });
        self.factor.solve_in_place(v.as_mut())?;
        let mut worst = 0.0f64;
        for c in 0..x.ncols() {
            let (mut e, mut xn) = (0.0f64, 0.0f64);
            for i in 0..x.nrows() {
                e = e.max(v[(i, c)].abs());
                xn = xn.max(x[(i, c)].abs());
            }
            let ratio = if xn > 0.0 { e / xn } else { e };
            worst = worst.max(if ratio.is_nan() { f64::INFINITY } else { ratio });
        }
        Ok(worst)
    }
}

impl Prepared for PreparedPenalty {
    /// The classical penalty solution. Its accuracy is not checked here: the
    /// refine phase estimates its distance from the exact constrained
    /// solution (one multiplier step) and warns above the threshold.
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error> {
        self.shifted_targets = None;
        self.pending_targets = None;
        let (x, _) = self.solve_with_rhs(problem)?;
        Ok(x)
    }

    /// One step of the method of multipliers in residual form (docs/refinement.md §4):
    /// `D̃_{k+1} = D̃_k + (D − B X_k)`,
    /// `ΔX = K⁻¹ [Aᵀ(C − A X_k) + w² Bᵀ(D̃_{k+1} − B X_k)]`, same factor.
    /// The first part of the bracket also corrects the rounding drift of the
    /// penalty system's stationarity (the corrected semi-normal-equation
    /// step of the other formulations), so the iteration converges to the
    /// constrained solution to rounding.
    fn correction(
        &mut self,
        problem: &LseProblem,
        x: &Mat<f64>,
    ) -> Result<Option<Mat<f64>>, Error> {
        let (b, d) = (problem.b().as_ref(), problem.d());
        let violation = hard_residual(b, d.as_ref(), x.as_ref());
        let next = match &self.shifted_targets {
            Some(shifted) => shifted + &violation,
            None => d + &violation,
        };
        let mut rhs = at_residual(problem.a().as_ref(), problem.c().as_ref(), x.as_ref());
        let shifted_violation = hard_residual(b, next.as_ref(), x.as_ref());
        add_bt_times(b, shifted_violation.as_ref(), self.w2(), rhs.as_mut());
        self.factor.solve_in_place(rhs.as_mut())?;
        self.pending_targets = Some(next);
        Ok(Some(rhs))
    }

    fn accept_correction(&mut self) {
        if let Some(next) = self.pending_targets.take() {
            self.shifted_targets = Some(next);
        }
    }

    fn refactorizations(&self) -> usize {
        self.factor.refactorizations()
    }

    fn skipped(&self) -> &[usize] {
        &[]
    }

    fn exact(&self) -> bool {
        false
    }

    fn estimate_condition(&mut self) -> Result<ConditionEstimate, Error> {
        let lower = self.lower.as_ref();
        let factor = &mut self.factor;
        let mut matrix = LowerSymmetricOperator::new(lower);
        let mut inverse = InverseOperator::new(lower.ncols(), |rhs| {
            factor.solve_in_place(rhs)?;
            Ok(())
        });
        condition::estimate(&mut matrix, &mut inverse, "AᵀA + w²BᵀB")
    }

    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>> {
        Some(lower_to_full(self.lower.as_ref()))
    }
}
