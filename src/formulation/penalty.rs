//! Penalty weights — the paper's "only soft constraints" (its eq. 7 with the
//! hard rows appended): every hard row becomes a soft row of weight `w`, and
//! `X` solves the normal equations
//!
//! `(AᵀA + w² BᵀB) X = AᵀC + w² BᵀD`
//!
//! with the SPD back end. The hard rows then hold only approximately: their
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

use super::null_space::with_context;
use super::util::{
    add_bt_times, at_times, lower_sym_abs_mul, lower_sym_max_row_nnz, lower_sym_mul,
    lower_sym_norm_inf, lower_to_full, split_normal,
};
use super::{Formulation, Prepared};
use crate::backend::spd::{FaerLlt, SpdBackend, SpdFactor, SpdSymbolic, check_factor_size};
use crate::condition::{self, ConditionEstimate, InverseOperator, LowerSymmetricOperator};
use crate::error::{Error, NumericalError, ProblemError};
use crate::problem::LseProblem;
use crate::report::{Report, first_non_finite};

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

/// Rejects weights whose square is not a finite positive number.
fn check_weight(w: f64) -> Result<(), Error> {
    if w.is_nan() || w <= 0.0 || !(w * w).is_finite() || w * w == 0.0 {
        return Err(ProblemError::InvalidArgument {
            message: format!(
                "penalty weight {w:e} is invalid: it must be finite and > 0 with w² finite and nonzero (1e-154 < w < 1e154)"
            ),
        }
        .into());
    }
    Ok(())
}

/// Largest accepted [`PenaltySolution::forward_error_estimate`] for a
/// solution returned through [`Formulation`]: `1e-2`, i.e. fewer than about
/// two correct digits *estimated*. The estimate over-states the true error by
/// two to three orders of magnitude on the test problems (it replaces
/// `|N⁻¹|` by `N⁻¹` in LAPACK's bound), so a rejected solution has at most
/// four to five correct digits — visibly wrong geometry. The weight sweep
/// ([`PenaltySweep`]) reports the estimate instead of rejecting.
pub const PENALTY_FORWARD_ERROR_LIMIT: f64 = 1e-2;

/// The description of the penalty matrix used in error messages.
fn matrix_name(w: f64) -> String {
    format!("the penalty normal matrix AᵀA + w²BᵀB (w = {w:e})")
}

impl Formulation for Penalty {
    fn name(&self) -> String {
        "penalty".into()
    }

    fn precompute(
        &self,
        problem: &LseProblem,
        report: &mut Report,
    ) -> Result<Box<dyn Prepared>, Error> {
        check_weight(self.weight)?;
        report.method = self.name();
        report.spd_backend = Some(self.spd.name().into());
        report.penalty_weight = Some(self.weight);
        let sweep = PenaltySweep::new(problem, self.spd.as_ref())?;
        report.timings_s.normal_matrix = sweep.normal_matrix_s;
        report.timings_s.symbolic = sweep.symbolic_s;
        report.nnz.normal = Some(sweep.full_nnz());
        let t = Instant::now();
        let prepared = sweep.factorize(self.weight)?;
        report.timings_s.numeric = t.elapsed().as_secs_f64();
        report.nnz.factor = Some(prepared.factor.nnz());
        report.nnz.factor_bytes = Some(prepared.factor.bytes());
        if problem.b().nrows() > 0 {
            report.warnings.push(format!(
                "penalty method: the {} hard constraints are soft rows of weight {:e}; they hold only approximately (see max_constraint_residual)",
                problem.b().nrows(),
                self.weight
            ));
        }
        Ok(Box::new(prepared))
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
    pattern: SymbolicSparseColMat<usize>,
    ata: Vec<f64>,
    btb: Vec<f64>,
    symbolic: Box<dyn SpdSymbolic>,
    backend: &'static str,
    /// Seconds spent building the pattern and the values of `AᵀA`, `BᵀB`.
    pub normal_matrix_s: f64,
    /// Seconds spent in the (single) symbolic analysis.
    pub symbolic_s: f64,
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
    pub fn new(problem: &LseProblem, spd: &dyn SpdBackend) -> Result<PenaltySweep, Error> {
        let t = Instant::now();
        let (pattern, ata, btb) = split_normal(problem);
        let normal_matrix_s = t.elapsed().as_secs_f64();

        let t = Instant::now();
        let symbolic = spd.analyze(pattern.as_ref())?;
        let symbolic_s = t.elapsed().as_secs_f64();
        check_factor_size(symbolic.factor_nnz(), pattern.ncols(), "AᵀA + w²BᵀB")?;
        Ok(PenaltySweep {
            ata,
            btb,
            pattern,
            symbolic,
            backend: spd.name(),
            normal_matrix_s,
            symbolic_s,
        })
    }

    /// Entries of the full symmetric `AᵀA + w²BᵀB`.
    pub fn full_nnz(&self) -> usize {
        2 * self.pattern.row_idx().len() - self.pattern.ncols()
    }

    /// The SPD back end's name.
    pub fn backend(&self) -> &'static str {
        self.backend
    }

    /// `tril(AᵀA + w²BᵀB)` (values summed on the analysed pattern).
    pub fn normal_matrix(&self, w: f64) -> Result<SparseColMat<usize, f64>, Error> {
        check_weight(w)?;
        let w2 = w * w;
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
            weight: w,
            lower,
            factor,
            accuracy_checked: false,
        })
    }

    /// Factors for weight `w` and solves for the current `C`, `D` of
    /// `problem` (the problem this sweep was built from), with the accuracy
    /// of the result measured from `X`.
    pub fn solve(&self, problem: &LseProblem, w: f64) -> Result<PenaltySolution, Error> {
        let t = Instant::now();
        let mut prepared = self.factorize(w)?;
        let numeric_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (x, rhs) = prepared.solve_with_rhs(problem)?;
        let solve_s = t.elapsed().as_secs_f64();
        let backward_error = backward_error(prepared.lower.as_ref(), &x, &rhs);
        let forward_error_estimate = prepared.forward_error_estimate(&x, &rhs);
        let max_constraint_residual = (0..problem.b().nrows())
            .map(|k| problem.hard_residual(k, &x))
            .fold(0.0, f64::max);
        Ok(PenaltySolution {
            least_squares_residual: problem.least_squares_residual(&x),
            x,
            max_constraint_residual,
            backward_error,
            forward_error_estimate,
            numeric_s,
            solve_s,
        })
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
    weight: f64,
    lower: SparseColMat<usize, f64>,
    factor: Box<dyn SpdFactor>,
    /// Whether the first solve's forward error was checked (the check costs
    /// one more solve; the conditioning it measures is the matrix's, so once
    /// per factorisation is enough).
    accuracy_checked: bool,
}

impl PreparedPenalty {
    /// `X` and the right-hand side `AᵀC + w²BᵀD` it solves.
    fn solve_with_rhs(&mut self, problem: &LseProblem) -> Result<(Mat<f64>, Mat<f64>), Error> {
        let mut rhs = at_times(problem.a().as_ref(), problem.c().as_ref());
        let w2 = self.weight * self.weight;
        add_bt_times(problem.b().as_ref(), problem.d().as_ref(), w2, rhs.as_mut());
        let mut x = rhs.clone();
        self.factor.solve_in_place(x.as_mut());
        if let Some(vertex) = first_non_finite(&x) {
            return Err(NumericalError::NonFiniteSolution { vertex }.into());
        }
        Ok((x, rhs))
    }
}

impl PreparedPenalty {
    /// See [`PenaltySolution::forward_error_estimate`].
    fn forward_error_estimate(&mut self, x: &Mat<f64>, rhs: &Mat<f64>) -> f64 {
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
        self.factor.solve_in_place(v.as_mut());
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
        worst
    }
}

impl Prepared for PreparedPenalty {
    fn solve(&mut self, problem: &LseProblem) -> Result<Mat<f64>, Error> {
        let (x, rhs) = self.solve_with_rhs(problem)?;
        if !self.accuracy_checked {
            let estimate = self.forward_error_estimate(&x, &rhs);
            // NaN-safe: a NaN estimate is rejected.
            let accurate = estimate <= PENALTY_FORWARD_ERROR_LIMIT;
            if !accurate {
                return Err(NumericalError::LostAccuracy {
                    matrix: matrix_name(self.weight),
                    estimate,
                    tolerance: PENALTY_FORWARD_ERROR_LIMIT,
                }
                .into());
            }
            self.accuracy_checked = true;
        }
        Ok(x)
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
            factor.solve_in_place(rhs);
            Ok(())
        });
        condition::estimate(&mut matrix, &mut inverse, "AᵀA + w²BᵀB")
    }

    fn factored_matrix(&self) -> Option<SparseColMat<usize, f64>> {
        Some(lower_to_full(self.lower.as_ref()))
    }
}
