//! Iterative refinement of a solution with the factor it was computed with,
//! and the forward-error estimate every result carries.
//!
//! Every formulation factors a matrix of normal-equation type, whose
//! condition number is the square of the least-squares problem's: a solve
//! alone loses about `log10(ε κ(N))` digits. One refinement step computes the
//! residual of the **original** rows (`C − A X`, `D − B X`, never
//! `AᵀC − AᵀA X`), maps it through the same factor to a correction `ΔX` and
//! adds it (docs/refinement.md §1–§4):
//!
//! - null-space QR: `Δy = R1⁻ᵀ (D − B X)_kept` with the residual in twice
//!   the working precision (a kept row close to dependence amplifies the
//!   rounding of `y`, which a plain residual does not see), then
//!   `g = Q2ᵀ Aᵀ (C − A X')` at `X' = X + Q [Δy; 0]`, `Δz = H⁻¹ g`,
//!   `ΔX = Q [Δy; Δz]` (Björck's corrected semi-normal equations on the
//!   reduced problem; `Δy` is below an ulp unless a kept row is nearly
//!   dependent);
//! - elimination: the same with `Q2` the selection of the free columns;
//! - KKT: `K [Δx; Δμ] = [Aᵀ(C − A x) − s Bᵀ μ; s (D − B x)]` (the last
//!   residual in twice the working precision);
//! - penalty: the method of multipliers (Van Loan 1985; Björck 1996 §5.1.5):
//!   shifted targets `D_{k+1} = D_k + (D − B X_k)` and
//!   `ΔX = K⁻¹ [Aᵀ(C − A X_k) + w² Bᵀ(D_{k+1} − B X_k)]`, which converges to
//!   the exact constrained solution with the error shrinking by about
//!   `max_i 1/(1 + w² μ_i)` per step (`μ_i` the eigenvalues of
//!   `B (AᵀA)⁻¹ Bᵀ`).
//!
//! **Forward-error estimate.** The size of a correction,
//! `max_i ‖ΔX_i‖₂ / length scale` (the largest vertex move over the mesh's
//! bounding-box diagonal), estimates the error of the solution it corrects:
//! to first order `ΔX = X* − X` when the factor is accurate enough for the
//! iteration to contract, which is when refinement is useful at all. With
//! [`Refine::EstimateOnly`] one correction is computed and *not applied*: its size is
//! the estimate (the cost of one more solve). With refinement on, the
//! estimate is the size of the last correction computed, which is an upper
//! bound of the remaining error while the iteration contracts (it is the
//! error *before* that correction) and equals it once the corrections have
//! reached the rounding floor: with `e` the error before a correction `ΔX`
//! and `ρ` the contraction per step, `‖e − ΔX‖ ≤ ρ‖e‖` and
//! `‖ΔX‖ ≥ (1 − ρ)‖e‖`, so the error after it is at most `ρ/(1 − ρ)‖ΔX‖`,
//! at most `‖ΔX‖` for `ρ ≤ ½`. When refinement stops at its step limit
//! while the corrections still shrink by `ρ > ½` per step, the estimate is
//! the rest of that geometric series, `ρ/(1 − ρ) ‖ΔX‖`. The method of
//! multipliers can contract slowly (its rate is `max_i 1/(1 + w²μ_i)`), so
//! for penalty with [`Refine::EstimateOnly`] a second correction is computed from the
//! first applied to a copy, and the estimate is `‖ΔX₁‖ / (1 − ρ)` with
//! `ρ = ‖ΔX₂‖/‖ΔX₁‖` (when `ρ < 1`). Above [`FORWARD_ERROR_WARNING`] a
//! result is returned with a warning.

use faer::Mat;

use crate::error::Error;
use crate::problem::LseProblem;

use super::Prepared;
pub use crate::refinement_types::{
    AUTO_MAX_STEPS, CONVERGED_ULPS, FORWARD_ERROR_WARNING, FactorRounding, REMEASURE_EVERY, Refine,
    RefineStop, Refinement,
};

/// The penalty method's conflict test: a hard-constraint residual above
/// the conflict tolerance and more than this many times the size of the
/// last correction (for three steps running) cannot be the error of `X`
/// (the rows of `B` have norm of order one, so `‖B ΔX‖ ≲ ‖ΔX‖`).
const CONFLICT_STALL_RATIO: f64 = 1e3;

/// `max_i ‖M_i‖₂` over the rows of `m`.
pub(crate) fn max_row_norm(m: &Mat<f64>) -> f64 {
    let mut worst = 0.0f64;
    for i in 0..m.nrows() {
        let mut s = 0.0;
        for c in 0..m.ncols() {
            s += m[(i, c)] * m[(i, c)];
        }
        worst = worst.max(s);
    }
    worst.sqrt()
}

/// `max_k ‖b_k X − d_k‖₂` over all hard rows of `problem` (including rows a
/// formulation dropped as redundant), each the Euclidean norm over the
/// columns of `X` ([`LseProblem::hard_residual`]), in the problem's own units
/// (not divided by its length scale); `0` for a problem without hard rows.
pub fn max_hard_residual(problem: &LseProblem, x: &Mat<f64>) -> f64 {
    (0..problem.b().nrows())
        .map(|k| problem.hard_residual(k, x))
        .fold(0.0, f64::max)
}

/// Refines `x` in place with `system` (which produced it) as `mode` says,
/// and returns what happened.
///
/// A correction is applied only if it is finite and smaller than the one
/// before it (the first always, when finite), so refinement never returns a
/// solution that a step made worse by more than that step's own size.
pub fn refine(
    system: &mut dyn Prepared,
    problem: &LseProblem,
    x: &mut Mat<f64>,
    mode: Refine,
) -> Result<Refinement, Error> {
    refine_with_rounding(system, problem, x, mode, None)
}

/// [`refine`], remembering in `rounding` what this refinement measured
/// about the factor's rounding, and, for the exact formulations under
/// [`Refine::Auto`] or [`Refine::Until`] once a floor is known, stopping as
/// soon as the error left is predicted to be at that floor
/// ([`RefineStop::Predicted`], docs/refinement.md §6). `rounding` must
/// belong to `system`'s factor (reset it at every precompute).
pub(crate) fn refine_with_rounding(
    system: &mut dyn Prepared,
    problem: &LseProblem,
    x: &mut Mat<f64>,
    mode: Refine,
    rounding: Option<&mut FactorRounding>,
) -> Result<Refinement, Error> {
    let predictable = system.exact() && matches!(mode, Refine::Auto | Refine::Until(_));
    let known_floor = rounding
        .as_deref()
        .filter(|r| predictable && r.predicted_since_measured < REMEASURE_EVERY)
        .and_then(|r| r.floor.map(|floor| (r.contraction, floor)));
    let mut run = Run {
        scale: positive_or_one(problem.length_scale()),
        track_constraints: !system.exact() && problem.b().nrows() > 0,
        predictable,
        known_floor,
        rates: Vec::new(),
        x_size: 0.0,
        stalled: 0,
    };
    let mut out = Refinement {
        mode,
        ..Refinement::default()
    };
    if run.track_constraints {
        out.constraint_residuals
            .push(max_hard_residual(problem, x) / run.scale);
    }
    loop {
        crate::interrupt::check()?;
        let Some(dx) = system.correction(problem, x)? else {
            out.stop_reason = RefineStop::Exact;
            return Ok(out);
        };
        if let Some(stop) = run.step(system, problem, x, &dx, &mut out)? {
            out.stop_reason = stop;
            break;
        }
    }
    run.finish(&mut out, rounding);
    Ok(out)
}

/// The state of one refinement between its steps.
struct Run {
    /// The length scale the sizes are relative to (1 if not positive).
    scale: f64,
    /// Penalty with hard rows: follow the hard-constraint residual.
    track_constraints: bool,
    /// Exact formulation under `auto` or `until`: the floor can be measured
    /// and predicted.
    predictable: bool,
    /// The contraction and rounding floor measured earlier with this
    /// factor, when a stop on a prediction is allowed.
    known_floor: Option<(f64, f64)>,
    /// The contraction of each applied correction.
    rates: Vec<f64>,
    /// The solution's size relative to the length scale, at the last step.
    x_size: f64,
    /// Steps in a row whose residual showed a conflict.
    stalled: usize,
}

impl Run {
    /// Records the correction `dx` of `x` in `out` and applies it unless
    /// refinement stops before it; the reason to stop, if any.
    fn step(
        &mut self,
        system: &mut dyn Prepared,
        problem: &LseProblem,
        x: &mut Mat<f64>,
        dx: &Mat<f64>,
        out: &mut Refinement,
    ) -> Result<Option<RefineStop>, Error> {
        let size = max_row_norm(dx) / self.scale;
        let size = if size.is_nan() { f64::INFINITY } else { size };
        let previous = out.corrections.last().copied();
        self.x_size = max_row_norm(x) / self.scale;
        // This correction's contraction: the first's size over the
        // solution's, later ones' over the correction before.
        let rate = size / previous.unwrap_or(self.x_size);
        out.corrections.push(size);
        out.forward_error_estimate = size;
        if out.mode.is_estimate_only() {
            if self.track_constraints && size.is_finite() && size > 0.0 {
                // The method of multipliers can contract slowly: measure
                // its rate with a second correction from the first applied
                // to a copy (the next solve restarts the multipliers), and
                // count the corrections still to come.
                let trial = &*x + dx;
                system.accept_correction();
                if let Some(next) = system.correction(problem, &trial)? {
                    let rate = max_row_norm(&next) / self.scale / size;
                    out.forward_error_estimate = size * geometric_tail(rate);
                }
            }
            return Ok(Some(RefineStop::Off));
        }
        // A correction that does not shrink is rounding noise: every
        // iteration here contracts (the exact formulations' by `ε κ(N)`,
        // the method of multipliers' by `max_i 1/(1 + w²μ_i)`).
        if !size.is_finite() || previous.is_some_and(|p| size >= p) {
            return Ok(Some(RefineStop::Stagnated));
        }
        *x += dx;
        system.accept_correction();
        out.steps += 1;
        self.rates.push(rate);
        if self.track_constraints {
            let r = max_hard_residual(problem, x) / self.scale;
            out.constraint_residuals.push(r);
            self.stalled = if conflict_shows(r, size) {
                self.stalled + 1
            } else {
                0
            };
            if self.stalled >= 3 {
                return Ok(Some(RefineStop::ConflictingConstraints));
            }
        }
        Ok(self.stop_after(size, previous, rate, out))
    }

    /// Whether to stop after applying a correction of `size` (after one of
    /// `previous`, contracting by `rate`): converged, at the tolerance, at
    /// the measured or predicted floor, or at the step cap.
    fn stop_after(
        &self,
        size: f64,
        previous: Option<f64>,
        rate: f64,
        out: &mut Refinement,
    ) -> Option<RefineStop> {
        let floor = CONVERGED_ULPS * f64::EPSILON * self.x_size;
        if size <= floor {
            return Some(RefineStop::Converged);
        }
        if let Refine::Until(tolerance) = out.mode
            && size <= tolerance
        {
            return Some(RefineStop::Tolerance);
        }
        if self.predictable && at_measured_floor(size, previous, &self.rates, self.x_size) {
            return Some(RefineStop::Converged);
        }
        if let Some((contraction, floor_ratio)) = self.known_floor
            && let Some(left) = predicted_error(
                contraction.max(rate),
                size,
                floor_ratio * self.x_size,
                floor,
            )
        {
            out.forward_error_estimate = left;
            return Some(RefineStop::Predicted);
        }
        (out.steps >= out.mode.max_steps()).then_some(RefineStop::StepLimit)
    }

    /// After the last step: the estimate of the corrections still to come
    /// at the step limit, what `rounding` learns, and (penalty) the
    /// residual's bound on the error and the conflict verdict.
    fn finish(&self, out: &mut Refinement, rounding: Option<&mut FactorRounding>) {
        // Stopped while still contracting — at the step limit, or (the
        // method of multipliers, whose slowest mode can contract by nearly
        // 1 per step long before rounding matters) at a correction that did
        // not shrink: the corrections still to come, at the rate of the
        // last two applied.
        let slow = out.stop_reason == RefineStop::StepLimit;
        if slow && let [.., before, last] = out.corrections[..out.steps] {
            let tail = last * (geometric_tail(last / before) - 1.0);
            out.forward_error_estimate = out.forward_error_estimate.max(tail);
        }
        if let Some(r) = rounding
            && self.predictable
        {
            remember(r, out, &self.rates, self.x_size);
        }
        if self.track_constraints {
            // `‖B (X − X*)‖ = ‖B X − D‖` and the rows of `B` have norm of
            // order one: the residual bounds the error from below.
            let r = *out.constraint_residuals.last().unwrap_or(&0.0);
            let last = *out.corrections.last().unwrap_or(&0.0);
            out.forward_error_estimate = out.forward_error_estimate.max(r);
            let first = out.constraint_residuals[0];
            // A residual above the conflict tolerance that the multiplier
            // updates did not reduce (stopped by a correction that did not
            // shrink, or by the step limit) is a conflict too: for
            // consistent rows each update removes a fixed fraction of it.
            let flat = matches!(
                out.stop_reason,
                RefineStop::Stagnated | RefineStop::StepLimit
            ) && r > crate::report::CONFLICT_RELATIVE_TOLERANCE
                && r >= FLAT_RESIDUAL * first;
            if !out.mode.is_estimate_only() && (conflict_shows(r, last) || flat) {
                out.stop_reason = RefineStop::ConflictingConstraints;
            }
        }
    }
}

/// A correction counts as a measurement of the rounding floor when it is
/// more than this many times the error the correction before it was
/// predicted to leave: at least half of it is then rounding, not error.
const FLOOR_EVIDENCE: f64 = 2.0;

/// …and at most this many ulps of the solution's size: above, it is taken
/// for error whatever its ratio, because the contraction the corrections
/// before it measured can be an underestimate (the first correction's
/// size over the solution's is the error of one right-hand side: on the
/// watertight Bunny it says `6e-5` while the second correction contracts
/// by `2.4e-4`). The floors the real meshes' first refinements measure are
/// 1e-15 to 2e-13 of the diagonal (docs/refinement.md §8), within it; a
/// sliver mesh's higher floor keeps the stop that does not shrink.
const FLOOR_ULPS: f64 = 1024.0;

/// Whether the correction of `size` just applied, after one of size
/// `previous`, measured the rounding floor (docs/refinement.md §8): it is
/// within [`FLOOR_ULPS`] ulps of the solution (`x_size`) and more than
/// [`FLOOR_EVIDENCE`] times the error `ρ/(1 − ρ) · previous` the
/// correction before it was predicted to leave (`ρ` the largest
/// contraction of the corrections before it; `rates` ends with this
/// one's), so it is mostly rounding: the error left after it is at the
/// floor, and another correction could only measure the floor again.
fn at_measured_floor(size: f64, previous: Option<f64>, rates: &[f64], x_size: f64) -> bool {
    let (Some(previous), [before @ .., _]) = (previous, rates) else {
        return false;
    };
    let rho = before.iter().copied().fold(0.0, f64::max);
    let left = previous * rho / (1.0 - rho);
    rho < 1.0 && size <= FLOOR_ULPS * f64::EPSILON * x_size && size > FLOOR_EVIDENCE * left
}

/// The error left after applying a correction of `size` with the
/// contraction `rate`, `rate/(1 − rate) · size`, or the rounding `floor`
/// measured with the factor if larger; `None` when that prediction is above
/// both the measured floor and `ulps` ([`CONVERGED_ULPS`] ulps of the
/// solution: one more correction is needed) or the iteration does not
/// contract (docs/refinement.md §6).
fn predicted_error(rate: f64, size: f64, floor: f64, ulps: f64) -> Option<f64> {
    let left = size * rate / (1.0 - rate);
    (rate < 1.0 && left <= floor.max(ulps) && floor.is_finite()).then_some(left.max(floor))
}

/// Updates what `rounding` knows of the factor from the refinement `out`
/// (`rates` the contractions of its applied corrections, `x_size` the
/// solution's size relative to the length scale): a refinement that
/// stopped on a correction at the floor (converged or not shrinking)
/// measured the floor; a predicted stop counts towards the next
/// measurement.
fn remember(rounding: &mut FactorRounding, out: &Refinement, rates: &[f64], x_size: f64) {
    // A correction at the rounding floor is noise, not a contraction of the
    // one before it: only corrections above NOISE_MARGIN times the one that
    // ended a measured refinement (the floor) count.
    let noise = match out.stop_reason {
        RefineStop::Converged | RefineStop::Stagnated => out.corrections.last().copied(),
        _ => None,
    };
    let seen = rates
        .iter()
        .zip(&out.corrections)
        .filter(|&(_, &size)| noise.is_none_or(|n| size > NOISE_MARGIN * n))
        .map(|(&rate, _)| rate)
        .filter(|r| r.is_finite());
    rounding.contraction = seen.fold(rounding.contraction, f64::max);
    match out.stop_reason {
        RefineStop::Converged | RefineStop::Stagnated => {
            let last = out.corrections.last().copied().unwrap_or(0.0);
            let floor = last / x_size;
            if floor.is_finite() && x_size > 0.0 {
                rounding.floor = Some(floor);
                rounding.predicted_since_measured = 0;
            }
        }
        RefineStop::Predicted => rounding.predicted_since_measured += 1,
        _ => {}
    }
}

/// A correction counts towards the contraction a factor is known for only
/// when it is above this many times the rounding floor its refinement
/// ended on: the ratio of two corrections at the floor is the ratio of two
/// samples of noise (0.6 to 0.95 on the Bunny), not a contraction.
const NOISE_MARGIN: f64 = 4.0;

/// A hard-constraint residual still at this fraction of its size before
/// the multiplier updates when they stop has not been reduced by them
/// (see [`refine`]).
const FLAT_RESIDUAL: f64 = 0.9;

/// `1 / (1 − ρ)`, the sum of the corrections `1, ρ, ρ², …` of an iteration
/// contracting by `ρ` per step, for `0 ≤ ρ < 1`; 1 otherwise (a correction
/// that does not shrink is rounding noise, and then the first is the
/// estimate).
fn geometric_tail(rate: f64) -> f64 {
    if rate.is_finite() && (0.0..1.0).contains(&rate) {
        1.0 / (1.0 - rate)
    } else {
        1.0
    }
}

/// The penalty method's conflict test: conflicting hard rows leave a
/// residual `r` at the size of the conflict while the corrections of `X`
/// die out; for consistent rows `‖B ΔX‖` follows the residual down. So a
/// residual above the conflict tolerance and [`CONFLICT_STALL_RATIO`] times
/// the last correction is a conflict.
fn conflict_shows(residual: f64, correction: f64) -> bool {
    residual > crate::report::CONFLICT_RELATIVE_TOLERANCE
        && residual > CONFLICT_STALL_RATIO * correction
}

fn positive_or_one(s: f64) -> f64 {
    if s > 0.0 && s.is_finite() { s } else { 1.0 }
}
