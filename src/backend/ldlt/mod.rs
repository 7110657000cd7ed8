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

use crate::error::NumericalError;

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
}

impl LdltKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [LdltKind; 3] = [
        LdltKind::FaerAuto,
        LdltKind::FaerSimplicial,
        LdltKind::FaerSupernodal,
    ];

    /// The word in reports.
    pub fn name(self) -> &'static str {
        match self {
            LdltKind::FaerAuto => "faer-ldlt-auto",
            LdltKind::FaerSimplicial => "faer-ldlt-simplicial",
            LdltKind::FaerSupernodal => "faer-ldlt-supernodal",
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
            SpdKind::Nalgebra | SpdKind::Cholmod => None,
        }
    }

    /// The back end.
    pub fn backend(self) -> Box<dyn LdltBackend> {
        Box::new(FaerLdlt::new(self))
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
}
