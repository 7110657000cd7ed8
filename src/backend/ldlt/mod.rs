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

pub use crate::backend::kinds::LdltKind;

mod faer_ldlt;
mod seam;

pub use faer_ldlt::FaerLdlt;
pub use seam::{LdltBackend, LdltFactor, LdltSymbolic, Pivot, PivotFault, PivotRule, first_fault};

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
