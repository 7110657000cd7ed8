//! What refinement is asked to do ([`Refine`]) and what it did
//! ([`Refinement`], [`RefineStop`]), with its thresholds: the vocabulary the
//! formulations, the report and the front doors share. The algorithm is
//! `formulation::iterative_refinement`; the mathematics is
//! docs/refinement.md §1–§5. (This module was `refinement` until 0.1;
//! `lse_deform::refinement` remains as its alias for one release.)

use serde::Serialize;

use crate::error::ParseWordError;

/// Whether and how far to refine a solution (the CLI's `--refine
/// estimate|off|auto|N`; [`Refine::Until`] is for callers with an accuracy
/// target, such as the response basis of the `handle` module).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Refine {
    /// No refinement, only the forward-error estimate: one correction is
    /// computed and not applied (two for penalty, module
    /// `formulation::iterative_refinement`). Its words are `estimate` and
    /// `off` (the name it had, kept); it is written `off`.
    EstimateOnly,
    /// Refine until a correction is below [`CONVERGED_ULPS`] ulps of the
    /// solution's size, measures the rounding floor (exact formulations:
    /// docs/refinement.md §8), stops shrinking, or [`AUTO_MAX_STEPS`]
    /// steps.
    #[default]
    Auto,
    /// Exactly this many steps unless a correction stops shrinking or
    /// reaches the rounding floor (then fewer). `Steps(0)` applies none:
    /// it is [`Refine::EstimateOnly`] (one correction computed for the
    /// estimate, stop reason [`RefineStop::Off`]).
    Steps(usize),
    /// As [`Refine::Auto`], and stop after applying a correction of at
    /// most this size (relative to the length scale, as the estimate).
    /// The estimate is then that correction's size: the error before it,
    /// and an upper bound of the error after it while the iteration
    /// contracts by at most ½ per step (module documentation).
    Until(f64),
}

impl Refine {
    /// Whether no correction is applied: [`Refine::EstimateOnly`], and
    /// [`Refine::Steps`]`(0)`, which is the same (zero steps; one
    /// correction computed for the estimate).
    pub(crate) fn is_estimate_only(self) -> bool {
        self.max_steps() == 0
    }

    /// The cap on steps.
    pub(crate) fn max_steps(self) -> usize {
        match self {
            Refine::EstimateOnly => 0,
            Refine::Auto | Refine::Until(_) => AUTO_MAX_STEPS,
            Refine::Steps(n) => n,
        }
    }
}

impl std::str::FromStr for Refine {
    type Err = ParseWordError;
    /// Parses `estimate` or its old word `off` ([`Refine::EstimateOnly`]),
    /// `auto` or a step count (the CLI's and Python's words).
    ///
    /// Errors: [`ParseWordError`] listing them.
    fn from_str(word: &str) -> Result<Refine, ParseWordError> {
        match word {
            "off" | "estimate" => Ok(Refine::EstimateOnly),
            "auto" => Ok(Refine::Auto),
            n => n
                .parse::<usize>()
                .map(Refine::Steps)
                .map_err(|_| ParseWordError {
                    what: "refinement",
                    word: word.to_string(),
                    expected: vec!["off", "estimate", "auto", "a number of steps"],
                }),
        }
    }
}

/// Serialised as its word (`off` for [`Refine::EstimateOnly`], as before
/// its rename, `auto`, a step count as a string, `until 1e-9`).
impl Serialize for Refine {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl std::fmt::Display for Refine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refine::EstimateOnly => write!(f, "off"),
            Refine::Auto => write!(f, "auto"),
            Refine::Steps(n) => write!(f, "{n}"),
            Refine::Until(tolerance) => write!(f, "until {tolerance:e}"),
        }
    }
}

/// The cap of [`Refine::Auto`]: 30 steps. The exact formulations converge in
/// 1–4 steps whenever `ε κ(N) < 1` (each step gains about
/// `−log10(ε κ(N))` digits); the method of multipliers contracts by
/// `1/(1 + w² μ_min)` per step, so a small penalty weight can need more, and
/// 30 steps of a rate of 1/3 gain 14 digits.
pub const AUTO_MAX_STEPS: usize = 30;

/// [`Refine::Auto`] stops once a correction is at most this many ulps of the
/// solution's size (`‖ΔX‖ ≤ 8 ε max_i ‖X_i‖`): below that a correction only
/// moves rounding noise.
pub const CONVERGED_ULPS: f64 = 8.0;

/// A result whose [`Refinement::forward_error_estimate`] exceeds `1e-8`
/// (relative to the length scale) is returned with a warning: the same bound
/// that classifies a skipped constraint as conflicting (the report's
/// `CONFLICT_RELATIVE_TOLERANCE`, docs/formulations.md §3); an error above it can
/// show in a rendering or in a comparison of methods.
pub const FORWARD_ERROR_WARNING: f64 = 1e-8;

/// Why refinement stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RefineStop {
    /// Refinement was off (one correction was computed for the estimate).
    #[default]
    Off,
    /// A correction fell below [`CONVERGED_ULPS`] ulps of the solution,
    /// or (exact formulations) measured the rounding floor: it was far
    /// above the error the correction before it was predicted to leave
    /// (docs/refinement.md §8). It was applied.
    Converged,
    /// A correction was at most the tolerance of [`Refine::Until`].
    Tolerance,
    /// A correction did not shrink: the rounding floor of this factor; it
    /// was not applied.
    Stagnated,
    /// Exact formulations, a factor refined before: the error left after
    /// the last correction is predicted to be at the rounding floor that an
    /// earlier refinement with the same factor measured
    /// ([`FactorRounding`], docs/refinement.md §6); no further correction
    /// was computed.
    Predicted,
    /// The step cap was reached.
    StepLimit,
    /// Penalty only: the hard-constraint residual `‖D − B X_k‖` stopped
    /// shrinking above the conflict tolerance while the shifted targets
    /// kept moving — conflicting hard constraints, which the method of
    /// multipliers cannot satisfy.
    ConflictingConstraints,
    /// Nothing to refine (every unknown fixed by the hard constraints).
    Exact,
}

/// What refinement did, for the report.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct Refinement {
    /// The mode asked for (serialised as `off`, `auto`, or the step count).
    pub mode: Refine,
    /// Corrections applied.
    pub steps: usize,
    /// `max_i ‖ΔX_i‖₂ / length scale` of every correction computed, in order
    /// (one more than `steps` when the last was not applied).
    pub corrections: Vec<f64>,
    /// Why it stopped.
    pub stop_reason: RefineStop,
    /// The estimated forward error of the returned solution, relative to
    /// the length scale (see the module documentation).
    pub forward_error_estimate: f64,
    /// Penalty only: `max_k ‖b_k X − d_k‖₂ / length scale` after each
    /// step (the first entry before any), the quantity the method of
    /// multipliers drives to zero.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub constraint_residuals: Vec<f64>,
}

/// What earlier refinements with one factor measured about it
/// (docs/refinement.md §6): the contraction `ρ` of a correction (the
/// relative error a solve with the factor leaves) and the rounding floor
/// below which corrections are noise, relative to the solution's size.
/// Both are properties of the factor, not of the right-hand side, so a
/// later solve with the same factor can stop once the error left is
/// predicted to be at that floor, without computing one more correction
/// only to see noise. A solver keeps one per factor and forgets it at
/// every precompute.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FactorRounding {
    /// The largest contraction per correction seen with this factor: the
    /// first correction's size over the solution's, and the ratio of each
    /// applied correction to the one before it.
    pub contraction: f64,
    /// The last measured floor: the size of the correction that ended a
    /// measured refinement (one that did not shrink, or one within
    /// [`CONVERGED_ULPS`] ulps) over the solution's size (both relative to
    /// the length scale); `None` until a refinement measured it.
    pub floor: Option<f64>,
    /// Refinements that stopped on a prediction since the floor was last
    /// measured (every [`REMEASURE_EVERY`]th refinement measures it again).
    pub predicted_since_measured: usize,
}

/// A solver that stops refinements on predictions measures the rounding
/// floor again on every this-many-th refinement with the same factor, so
/// that a floor measured on one right-hand side is not trusted forever.
pub const REMEASURE_EVERY: usize = 16;
