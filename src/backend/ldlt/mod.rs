//! Sparse symmetric **indefinite** solvers: `P K Pᵀ = L D Lᵀ` with `L` unit
//! lower triangular and `D` diagonal, in an elimination order the caller
//! gives (static pivoting: no row or column is exchanged during the numeric
//! factorisation, so the order must be one in which every pivot exists, as
//! the KKT formulation's is).
//!
//! The phases are those of the SPD back ends ([`crate::backend::spd`]): a
//! back end analyses a pattern once ([`LdltBackend::analyze`]: the symbolic
//! factorisation in the given order), then factors any matrix with that
//! pattern ([`LdltSymbolic::factorize`]), and the factor solves in place
//! ([`LdltFactor::solve_in_place`]). Matrices are given as their **lower
//! triangle** in CSC form with sorted row indices, every diagonal entry
//! stored (an explicit zero where the matrix has none).
//!
//! **One pivot protocol.** What a pivot should be (its sign, how small is
//! singular) depends on the matrix, so the caller states it as a
//! [`PivotRule`] and the factor answers with the first pivot, in
//! elimination order, that breaks it ([`LdltFactor::pivot_fault`]): a
//! back end that computes its pivots hands out the pivot with the
//! magnitude it was computed from ([`PivotFault::Computed`], through
//! [`first_fault`]); one that only detects null pivots by its own test
//! names the unknown and the test ([`PivotFault::Null`]); a failure the
//! back end met but did not attribute to a pivot is
//! [`PivotFault::Reported`]. The KKT formulation turns the answer into its
//! error, whichever back end gave it.

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

pub use crate::backend::kinds::LdltKind;
use crate::backend::spd::check_factor_size;
use crate::backend::{BackendFacts, BackendName};
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;
use crate::resources::Threads;

mod faer_ldlt;

pub use faer_ldlt::FaerLdlt;

/// A sparse `LDLᵀ` family: the crate's own ([`LdltKind`]'s catalogue) or
/// one brought from outside (docs/backends.md,
/// `lse_deform::testing::conformance::ldlt`).
pub trait LdltBackend: Send + Sync {
    /// The back end's name in reports and `compare` rows.
    fn name(&self) -> BackendName;

    /// Symbolic factorisation of the lower-triangle pattern `lower`
    /// (square, sorted rows, every diagonal entry stored) with the unknowns
    /// eliminated in `order` (`order[i]` is the unknown eliminated `i`-th;
    /// a permutation of `0..lower.ncols()`).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError>;

    /// [`LdltBackend::analyze`] with the factorisations on `threads`
    /// (called only when a count is asked for). The default ignores the
    /// count: the report's `"threads"` is then what
    /// [`LdltSymbolic::plan_used`] says (`null` unless the back end says).
    fn analyze_on_threads(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
        threads: Threads,
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError> {
        let _ = threads;
        self.analyze(lower, order)
    }
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait LdltSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed), without
    /// pivoting. A pivot that the back end itself finds unusable (an exact
    /// zero) does not fail the call: it is reported by
    /// [`LdltFactor::pivot_fault`], so that the caller's rule names it.
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn LdltFactor>, NumericalError>;

    /// Number of `f64` values the numeric factor will store, known after
    /// analysis (what the memory budget is checked against).
    fn factor_values(&self) -> usize;

    /// Refuses a factorisation that would not fit in `budget`: by default
    /// [`check_factor_size`] on [`LdltSymbolic::factor_values`]; MUMPS
    /// checks its own estimate on every rank.
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        check_factor_size(self.factor_values(), dim, matrix, budget)
    }

    /// The threads this analysis's factorisations use (the ordering is
    /// always the caller's); `None` by default: not said.
    fn threads_used(&self) -> Option<usize> {
        None
    }
}

/// A pivot `d_i` of the factorisation, in elimination order, with the
/// magnitude it was computed from: `d_i = K_jj − Σ_{k<i} L_ik² d_k` for the
/// unknown `j` eliminated `i`-th, and
/// `magnitude = |K_jj| + Σ_{k<i} L_ik² |d_k|` (its rounding error is a
/// small multiple of `ε` times that).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pivot {
    /// The original unknown `j`.
    pub unknown: usize,
    /// `d_i`.
    pub value: f64,
    /// `|K_jj| + Σ_{k<i} L_ik² |d_k|`.
    pub magnitude: f64,
}

/// What the caller requires of the pivots `d_i` of a static-order
/// `LDLᵀ`: the unknowns `j < positive` must have `d > 0`, the others
/// `d < 0`, each with `|d| > tolerance · magnitude` (the magnitude it was
/// computed from, [`Pivot::magnitude`]). For the KKT matrix
/// `[AᵀA sBᵀ; sB 0]`, `positive = n` (the vertices) and the tolerance is
/// the KKT formulation's pivot tolerance `1000 ε` (docs/formulations.md
/// §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PivotRule {
    /// Unknowns below this index expect a positive pivot, the rest a
    /// negative one.
    pub positive: usize,
    /// The least `|d| / magnitude` of a pivot that keeps its digits.
    pub tolerance: f64,
}

impl PivotRule {
    /// Whether `pivot` keeps the rule (a non-finite value or ratio never
    /// does).
    pub fn holds(&self, pivot: &Pivot) -> bool {
        let ratio = pivot.value.abs() / pivot.magnitude;
        let right_sign = if pivot.unknown < self.positive {
            pivot.value > 0.0
        } else {
            pivot.value < 0.0
        };
        pivot.value.is_finite() && ratio.is_finite() && ratio > self.tolerance && right_sign
    }
}

/// The first pivot, in elimination order, that breaks a [`PivotRule`], as
/// the back end knows it.
#[derive(Clone, Debug, PartialEq)]
pub enum PivotFault {
    /// A computed pivot: its position in the elimination order (of `dim`
    /// pivots) and the pivot with its magnitude.
    Computed {
        /// 0-based position in the elimination order.
        position: usize,
        /// Number of pivots.
        dim: usize,
        /// The pivot.
        pivot: Pivot,
    },
    /// A pivot the back end found null by its own test, without handing
    /// out its value: the unknown (original order), and the test in words.
    /// A back end whose elimination may merge unknowns (so that the one it
    /// flags need not be the first of a dependent group in the given
    /// order) says so by flagging; the caller may then name the group's
    /// first member itself.
    Null {
        /// The unknown.
        unknown: usize,
        /// What the back end tested, for the message.
        test: String,
    },
    /// A failure the back end met during the numeric factorisation but did
    /// not attribute to a pivot that breaks the rule: its own words.
    Reported {
        /// The back end's message.
        message: String,
    },
}

/// The first of `pivots` (in elimination order) that breaks `rule`, as a
/// [`PivotFault::Computed`]; else, when the back end reported a `failure`
/// of its own, [`PivotFault::Reported`]. For back ends that compute their
/// pivots.
pub fn first_fault(pivots: &[Pivot], rule: PivotRule, failure: Option<&str>) -> Option<PivotFault> {
    let dim = pivots.len();
    match pivots.iter().position(|p| !rule.holds(p)) {
        Some(position) => Some(PivotFault::Computed {
            position,
            dim,
            pivot: pivots[position],
        }),
        None => failure.map(|message| PivotFault::Reported {
            message: message.to_string(),
        }),
    }
}

/// A numeric factorisation `P K Pᵀ = L D Lᵀ`.
pub trait LdltFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `K X = B` in place for all columns of `rhs` together.
    ///
    /// Errors: a typed [`NumericalError`] naming what failed; `rhs` is
    /// then unspecified. Never non-finite values as a signal.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) -> Result<(), NumericalError>;

    /// Number of stored entries of `L` (lower triangle, diagonal included,
    /// the diagonal holding `D`).
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices.
    fn bytes(&self) -> usize;

    /// The first pivot that breaks `rule` ([`PivotFault`]), `None` when
    /// every pivot keeps it; `lower` is the matrix factored (for `K_jj`).
    fn pivot_fault(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
        rule: PivotRule,
    ) -> Option<PivotFault>;

    /// What the back end reports of this factorisation beyond the generic
    /// record, as a section of the report; `None` by default.
    fn facts(&self) -> Option<BackendFacts> {
        None
    }

    /// How many times a solve had to factor the matrix again; `0` by
    /// default ([`crate::backend::spd::SpdFactor::refactorizations`]).
    fn refactorizations(&self) -> usize {
        0
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;
    use faer::sparse::{SparseColMat, Triplet};

    use super::*;

    /// The lower triangle of a symmetric matrix from its `(row ≥ col)`
    /// entries.
    fn lower(n: usize, entries: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
        let t: Vec<_> = entries
            .iter()
            .map(|&(i, j, v)| Triplet::new(i, j, v))
            .collect();
        SparseColMat::try_new_from_triplets(n, n, &t).unwrap()
    }

    /// `K = [2 1 1; 1 2 0; 1 0 0]` (a vertex block and one multiplier):
    /// `d = (2, 3/2, −2/3)`, the last computed from
    /// `0 + (1/2)²·2 + (1/3)²·3/2 = 2/3`.
    fn kkt_like() -> SparseColMat<usize, f64> {
        lower(
            3,
            &[
                (0, 0, 2.0),
                (1, 0, 1.0),
                (2, 0, 1.0),
                (1, 1, 2.0),
                (2, 2, 0.0),
            ],
        )
    }

    #[test]
    fn every_variant_factors_solves_and_hands_out_the_pivots() {
        let k = kkt_like();
        let full = [[2.0, 1.0, 1.0], [1.0, 2.0, 0.0], [1.0, 0.0, 0.0]];
        // MUMPS judges its pivots itself (tests/distributed.rs).
        let faer_kinds = [
            LdltKind::FaerAuto,
            LdltKind::FaerSimplicial,
            LdltKind::FaerSupernodal,
        ];
        for kind in faer_kinds {
            let backend = kind.backend().unwrap();
            assert_eq!(backend.name(), kind.name());
            let symbolic = backend.analyze(k.symbolic(), &[0, 1, 2]).unwrap();
            assert!(symbolic.factor_values() >= 6, "{kind}");
            let mut factor = symbolic.factorize(k.as_ref()).unwrap();
            assert_eq!(factor.dim(), 3);
            assert_eq!(factor.nnz(), 6, "{kind}");
            // The saddle point's signs hold; a rule expecting one sign more
            // or fewer meets the pivot that breaks it, with its magnitude.
            let rule = |positive| PivotRule {
                positive,
                tolerance: 1e-12,
            };
            assert_eq!(factor.pivot_fault(k.as_ref(), rule(2)), None, "{kind}");
            let expected = [(0, 2.0, 2.0), (1, 1.5, 2.5), (2, -2.0 / 3.0, 2.0 / 3.0)];
            for (positive, position) in [(0, 0), (3, 2)] {
                let Some(PivotFault::Computed {
                    position: at,
                    dim,
                    pivot,
                }) = factor.pivot_fault(k.as_ref(), rule(positive))
                else {
                    panic!("{kind}: no computed fault for positive = {positive}");
                };
                let (unknown, value, magnitude) = expected[position];
                assert_eq!((at, dim, pivot.unknown), (position, 3, unknown), "{kind}");
                assert!((pivot.value - value).abs() < 1e-15, "{kind}: {pivot:?}");
                assert!(
                    (pivot.magnitude - magnitude).abs() < 1e-15,
                    "{kind}: {pivot:?}"
                );
            }
            // Three columns (the workspace) and five (a buffer of their own).
            for k_cols in [3, 5] {
                let x_true = Mat::from_fn(3, k_cols, |i, c| (i + 2 * c) as f64 - 1.5);
                let mut x = Mat::from_fn(3, k_cols, |i, c| {
                    (0..3).map(|j| full[i][j] * x_true[(j, c)]).sum::<f64>()
                });
                factor.solve_in_place(x.as_mut()).unwrap();
                for c in 0..k_cols {
                    for i in 0..3 {
                        assert!((x[(i, c)] - x_true[(i, c)]).abs() < 1e-14, "{kind}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_order_is_the_callers() {
        // Eliminating the multiplier first meets its zero diagonal.
        let k = kkt_like();
        let symbolic = LdltKind::FaerSimplicial
            .backend()
            .unwrap()
            .analyze(k.symbolic(), &[2, 0, 1])
            .unwrap();
        let factor = symbolic.factorize(k.as_ref()).unwrap();
        let rule = PivotRule {
            positive: 2,
            tolerance: 1e-12,
        };
        let Some(PivotFault::Computed {
            position, pivot, ..
        }) = factor.pivot_fault(k.as_ref(), rule)
        else {
            panic!("the zero pivot is not reported");
        };
        assert_eq!(
            (position, pivot.unknown, pivot.value, pivot.magnitude),
            (0, 2, 0.0, 0.0)
        );
    }

    #[test]
    fn a_dependent_multiplier_has_a_zero_pivot() {
        // Two multipliers of the same row `x0 = …`: the second pivot is
        // 0 − 1·1 − 1·(−1) = 0, from a magnitude of 2.
        let k = lower(
            3,
            &[
                (0, 0, 1.0),
                (1, 0, 1.0),
                (2, 0, 1.0),
                (1, 1, 0.0),
                (2, 2, 0.0),
            ],
        );
        let symbolic = LdltKind::FaerAuto
            .backend()
            .unwrap()
            .analyze(k.symbolic(), &[0, 1, 2])
            .unwrap();
        let factor = symbolic.factorize(k.as_ref()).unwrap();
        let rule = PivotRule {
            positive: 1,
            tolerance: 1e-12,
        };
        let Some(PivotFault::Computed {
            position, pivot, ..
        }) = factor.pivot_fault(k.as_ref(), rule)
        else {
            panic!("the dependent multiplier is not reported");
        };
        assert_eq!(
            (position, pivot.unknown, pivot.value, pivot.magnitude),
            (2, 2, 0.0, 2.0)
        );
    }

    #[test]
    fn kinds_name_their_report_words_and_follow_the_spd_choice() {
        use crate::backend::spd::SpdKind;
        assert_eq!(
            LdltKind::for_spd(SpdKind::FaerSimplicial),
            Some(LdltKind::FaerSimplicial)
        );
        assert_eq!(LdltKind::for_spd(SpdKind::Nalgebra), None);
        assert_eq!(
            "faer-ldlt-supernodal".parse::<LdltKind>(),
            Ok(LdltKind::FaerSupernodal)
        );
        assert_eq!(LdltKind::default().to_string(), "faer-ldlt-auto");
    }
}

#[cfg(test)]
mod rule_tests {
    use super::*;

    /// The rule by hand: signs, the tolerance (strict), non-finite values.
    #[test]
    fn the_rule_checks_sign_size_and_finiteness() {
        let rule = PivotRule {
            positive: 1,
            tolerance: 0.25,
        };
        let p = |unknown, value, magnitude| Pivot {
            unknown,
            value,
            magnitude,
        };
        assert!(rule.holds(&p(0, 1.0, 2.0)));
        assert!(!rule.holds(&p(0, -1.0, 2.0)));
        assert!(rule.holds(&p(1, -1.0, 2.0)));
        assert!(!rule.holds(&p(1, 1.0, 2.0)));
        assert!(
            !rule.holds(&p(0, 0.5, 2.0)),
            "a ratio at the tolerance fails"
        );
        assert!(!rule.holds(&p(0, f64::NAN, 2.0)));
        assert!(!rule.holds(&p(0, 1.0, 0.0)));
        let pivots = [p(0, 1.0, 1.0), p(1, -1.0, 1.0)];
        assert_eq!(first_fault(&pivots, rule, None), None);
        assert_eq!(
            first_fault(&pivots, rule, Some("zero pivot")),
            Some(PivotFault::Reported {
                message: "zero pivot".into()
            })
        );
    }
}
