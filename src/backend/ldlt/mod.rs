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
//! A back end does not judge the pivots: what a pivot should be (its sign,
//! how small is singular) depends on the matrix, so the factor hands them
//! out with the magnitude each was computed from ([`LdltFactor::pivots`])
//! and the caller decides.

use faer::MatMut;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use crate::backend::FactorStorage;
use crate::backend::spd::check_factor_size;
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

mod faer_ldlt;

pub use faer_ldlt::FaerLdlt;

/// An `LDLᵀ` back end, as a typed choice ([`LdltKind::backend`] makes
/// it); serialised in reports as its word.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum LdltKind {
    /// faer's choice between the two below, from the symbolic factor's
    /// density.
    #[default]
    FaerAuto,
    /// faer's simplicial (column by column) `LDLᵀ`.
    FaerSimplicial,
    /// faer's supernodal `LDLᵀ` (dense blocks of columns).
    FaerSupernodal,
    /// MUMPS's multifrontal `LDLᵀ` in the given order, on one rank or many
    /// (cargo feature `mumps`).
    Mumps,
}

impl LdltKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [LdltKind; 4] = [
        LdltKind::FaerAuto,
        LdltKind::FaerSimplicial,
        LdltKind::FaerSupernodal,
        LdltKind::Mumps,
    ];

    /// The word in reports.
    pub fn name(self) -> &'static str {
        match self {
            LdltKind::FaerAuto => "faer-ldlt-auto",
            LdltKind::FaerSimplicial => "faer-ldlt-simplicial",
            LdltKind::FaerSupernodal => "faer-ldlt-supernodal",
            LdltKind::Mumps => "mumps-ldlt",
        }
    }

    /// The `LDLᵀ` variant an SPD back-end choice selects (the CLI's and
    /// Python's `spd` for the KKT method): faer's automatic, simplicial or
    /// supernodal factorisation for the faer kinds; `None` for the others,
    /// which have no `LDLᵀ`.
    pub fn for_spd(spd: crate::backend::spd::SpdKind) -> Option<LdltKind> {
        use crate::backend::spd::SpdKind;
        match spd {
            SpdKind::FaerAuto => Some(LdltKind::FaerAuto),
            SpdKind::FaerSimplicial => Some(LdltKind::FaerSimplicial),
            SpdKind::FaerSupernodal => Some(LdltKind::FaerSupernodal),
            SpdKind::Mumps => Some(LdltKind::Mumps),
            SpdKind::Nalgebra | SpdKind::Cholmod => None,
        }
    }

    /// The back end, keeping its factor in core.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for `Mumps` in a build
    /// without the feature `mumps`.
    pub fn backend(self) -> Result<Box<dyn LdltBackend>, ProblemError> {
        self.backend_with(&FactorStorage::InCore)
    }

    /// The back end keeping its factor in `storage` (out of core: `Mumps`
    /// only).
    pub fn backend_with(
        self,
        storage: &FactorStorage,
    ) -> Result<Box<dyn LdltBackend>, ProblemError> {
        match self {
            #[cfg(feature = "mumps")]
            LdltKind::Mumps => Ok(Box::new(crate::backend::mumps::MumpsLdlt::new(
                storage.directory().map(std::path::Path::to_path_buf),
            )?)),
            #[cfg(not(feature = "mumps"))]
            LdltKind::Mumps => Err(ProblemError::InvalidArgument {
                message: crate::backend::spd::MUMPS_MISSING.into(),
            }),
            _ => {
                storage.refuse_out_of_core(self.name())?;
                Ok(Box::new(FaerLdlt::new(self)))
            }
        }
    }
}

impl crate::choice::Word for LdltKind {
    const WHAT: &'static str = "LDLT back end";
    fn all() -> &'static [Self] {
        &LdltKind::ALL
    }
    fn name(self) -> &'static str {
        LdltKind::name(self)
    }
}

crate::choice::word_traits!(LdltKind);

/// A sparse `LDLᵀ` family.
pub trait LdltBackend: Send + Sync {
    /// Which back end this is.
    fn kind(&self) -> LdltKind;

    /// Symbolic factorisation of the lower-triangle pattern `lower`
    /// (square, sorted rows, every diagonal entry stored) with the unknowns
    /// eliminated in `order` (`order[i]` is the unknown eliminated `i`-th;
    /// a permutation of `0..lower.ncols()`).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Box<dyn LdltSymbolic>, NumericalError>;
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait LdltSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed), without
    /// pivoting. A pivot that the back end itself finds unusable (an exact
    /// zero) does not fail the call: it is in
    /// [`LdltFactor::reported_failure`], so that the caller can first run
    /// its own, more telling, pivot test.
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
}

/// The pivots as a back end that judges them itself reports them
/// (MUMPS's null-pivot detection): the unknowns whose pivots it found null
/// (0-based, original order) and the number of negative pivots.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DetectedPivots {
    /// Unknowns with a null pivot.
    pub null: Vec<usize>,
    /// When `null` is not empty: the unknowns still null when the matrix is
    /// factored again with a threshold at the level of rounding (a pivot in
    /// `null` but not here was small but sound, as on sliver-heavy meshes).
    pub null_at_rounding: Vec<usize>,
    /// How many pivots were negative (the inertia's negative count).
    pub negative: usize,
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

/// A numeric factorisation `P K Pᵀ = L D Lᵀ`.
pub trait LdltFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `K X = B` in place for all columns of `rhs` together.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>);

    /// Number of stored entries of `L` (lower triangle, diagonal included,
    /// the diagonal holding `D`).
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices.
    fn bytes(&self) -> usize;

    /// Every pivot in elimination order; `lower` is the matrix factored
    /// (for `K_jj`).
    fn pivots(&self, lower: SparseColMatRef<'_, usize, f64>) -> Vec<Pivot>;

    /// The back end's own report of a failed pivot during the numeric
    /// factorisation (its error, as text), if any.
    fn reported_failure(&self) -> Option<&str>;

    /// `Some` for a back end that judges the pivots itself instead of
    /// handing them out ([`LdltFactor::pivots`] is then empty).
    fn detected_pivots(&self) -> Option<DetectedPivots> {
        None
    }

    /// What a MUMPS factor reports of its ranks; `None` for the others.
    fn mumps_facts(&self) -> Option<crate::backend::MumpsFacts> {
        None
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
            assert_eq!(backend.kind(), kind);
            let symbolic = backend.analyze(k.symbolic(), &[0, 1, 2]).unwrap();
            assert!(symbolic.factor_values() >= 6, "{kind}");
            let mut factor = symbolic.factorize(k.as_ref()).unwrap();
            assert_eq!(factor.dim(), 3);
            assert_eq!(factor.nnz(), 6, "{kind}");
            assert!(factor.reported_failure().is_none(), "{kind}");
            let pivots = factor.pivots(k.as_ref());
            let expected = [(0, 2.0, 2.0), (1, 1.5, 2.5), (2, -2.0 / 3.0, 2.0 / 3.0)];
            for (p, (unknown, value, magnitude)) in pivots.iter().zip(expected) {
                assert_eq!(p.unknown, unknown, "{kind}");
                assert!((p.value - value).abs() < 1e-15, "{kind}: {p:?}");
                assert!((p.magnitude - magnitude).abs() < 1e-15, "{kind}: {p:?}");
            }
            // Three columns (the workspace) and five (a buffer of their own).
            for k_cols in [3, 5] {
                let x_true = Mat::from_fn(3, k_cols, |i, c| (i + 2 * c) as f64 - 1.5);
                let mut x = Mat::from_fn(3, k_cols, |i, c| {
                    (0..3).map(|j| full[i][j] * x_true[(j, c)]).sum::<f64>()
                });
                factor.solve_in_place(x.as_mut());
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
        let first = factor.pivots(k.as_ref())[0];
        assert_eq!((first.unknown, first.value, first.magnitude), (2, 0.0, 0.0));
        assert!(factor.reported_failure().is_some());
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
        let last = factor.pivots(k.as_ref())[2];
        assert_eq!((last.unknown, last.value, last.magnitude), (2, 0.0, 2.0));
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
