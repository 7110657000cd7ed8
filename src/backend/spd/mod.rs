//! Sparse symmetric positive definite solvers.
//!
//! A back end analyses a sparsity pattern once ([`SpdBackend::analyze`]:
//! fill-reducing ordering and symbolic factorisation) and then factors any
//! matrix with that pattern numerically ([`SpdSymbolic::factorize`]) as
//! often as needed (a new penalty weight, new soft weights), without a new
//! analysis. Matrices are given as their **lower triangle** in CSC form with
//! sorted row indices, diagonal included.
//!
//! Numerical failure is a typed [`NumericalError`] naming the failing pivot
//! in the *original* (unpermuted) ordering: either a pivot that is not
//! positive, or a pivot that lost all its digits to cancellation
//! ([`BREAKDOWN_RATIO`]).

use std::sync::Arc;

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, MatRef};

use crate::backend::FactorStorage;
use crate::error::{NumericalError, ProblemError};
use crate::limits::MemoryBudget;

#[cfg(feature = "suitesparse")]
mod cholmod;
mod factor_size;
mod faer_llt;
mod nalgebra;
mod tree_split;
mod triangular;

#[cfg(feature = "suitesparse")]
pub use cholmod::Cholmod;
pub(crate) use factor_size::factor_size;
pub use faer_llt::FaerLlt;
pub use nalgebra::NalgebraCsc;

/// An SPD back end, as a typed choice ([`SpdKind::backend`] makes it;
/// `FromStr` reads the CLI's and Python's names, [`SpdKind::name`] gives
/// them back).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SpdKind {
    /// faer's supernodal Cholesky.
    FaerSupernodal,
    /// faer's simplicial (column by column) Cholesky.
    FaerSimplicial,
    /// faer's choice between the two, from the symbolic factor's density.
    FaerAuto,
    /// nalgebra-sparse's CSC Cholesky.
    Nalgebra,
    /// SuiteSparse CHOLMOD (cargo feature `suitesparse`).
    Cholmod,
    /// MUMPS's multifrontal Cholesky, on one rank or many (cargo feature
    /// `mumps`).
    Mumps,
}

impl SpdKind {
    /// Every kind, in the order they are listed to users.
    pub const ALL: [SpdKind; 6] = [
        SpdKind::FaerSupernodal,
        SpdKind::FaerSimplicial,
        SpdKind::FaerAuto,
        SpdKind::Nalgebra,
        SpdKind::Cholmod,
        SpdKind::Mumps,
    ];

    /// The name the CLI and Python use.
    pub fn name(self) -> &'static str {
        match self {
            SpdKind::FaerSupernodal => "faer-supernodal",
            SpdKind::FaerSimplicial => "faer-simplicial",
            SpdKind::FaerAuto => "faer-auto",
            SpdKind::Nalgebra => "nalgebra",
            SpdKind::Cholmod => "cholmod",
            SpdKind::Mumps => "mumps",
        }
    }

    /// Whether this build has the back end (`Cholmod` needs the cargo
    /// feature `suitesparse`, `Mumps` the feature `mumps`).
    pub fn in_this_build(self) -> bool {
        let missing = (self == SpdKind::Cholmod && !cfg!(feature = "suitesparse"))
            || (self == SpdKind::Mumps && !cfg!(feature = "mumps"));
        !missing
    }

    /// The kinds of this build, in [`SpdKind::ALL`]'s order.
    pub fn available() -> Vec<SpdKind> {
        SpdKind::ALL
            .into_iter()
            .filter(|k| k.in_this_build())
            .collect()
    }

    /// The back end.
    ///
    /// Errors: [`ProblemError::InvalidArgument`] for `Cholmod` in a build
    /// without the `suitesparse` feature (the message says how to enable
    /// it).
    pub fn backend(self) -> Result<Arc<dyn SpdBackend>, ProblemError> {
        self.backend_with(&FactorStorage::InCore)
    }

    /// The back end keeping its factor in `storage`.
    ///
    /// Errors: as [`SpdKind::backend`], and
    /// [`ProblemError::InvalidArgument`] for out-of-core storage with any
    /// back end but `Mumps`.
    pub fn backend_with(
        self,
        storage: &FactorStorage,
    ) -> Result<Arc<dyn SpdBackend>, ProblemError> {
        if self != SpdKind::Mumps {
            storage.refuse_out_of_core(self.name())?;
        }
        match self {
            SpdKind::FaerSupernodal => Ok(Arc::new(FaerLlt::supernodal())),
            SpdKind::FaerSimplicial => Ok(Arc::new(FaerLlt::simplicial())),
            SpdKind::FaerAuto => Ok(Arc::new(FaerLlt::auto())),
            SpdKind::Nalgebra => Ok(Arc::new(NalgebraCsc)),
            #[cfg(feature = "suitesparse")]
            SpdKind::Cholmod => Ok(Arc::new(Cholmod)),
            #[cfg(not(feature = "suitesparse"))]
            SpdKind::Cholmod => Err(ProblemError::InvalidArgument {
                message: "the SPD back end 'cholmod' (SuiteSparse CHOLMOD) is not in this build: rebuild with `--features suitesparse` (needs the system packages libsuitesparse-dev and libclang-dev)".into(),
            }),
            #[cfg(feature = "mumps")]
            SpdKind::Mumps => Ok(Arc::new(crate::backend::mumps::MumpsLlt::new(
                storage.directory().map(std::path::Path::to_path_buf),
            )?)),
            #[cfg(not(feature = "mumps"))]
            SpdKind::Mumps => Err(ProblemError::InvalidArgument {
                message: MUMPS_MISSING.into(),
            }),
        }
    }
}

/// Why `mumps` is refused by a build without it.
#[cfg(not(feature = "mumps"))]
pub(crate) const MUMPS_MISSING: &str = "the back end 'mumps' (MUMPS over MPI) is not in this build: rebuild with `--features mumps` (needs the system packages libmumps-ptscotch-dev, libmumps-headers-dev, libopenmpi-dev, openmpi-bin and libclang-dev)";

/// Threshold on `L_kk² / A_kk` below which a completed Cholesky
/// factorisation is declared broken down.
///
/// The computed pivot `L_kk² = A_kk − Σ_j L_kj²` carries a rounding error of a
/// small multiple of `ε·A_kk` (each `L_kj² ≤ A_kk` for an SPD matrix), so a
/// ratio below `1000 ε ≈ 2.2e-13` leaves at most about three significant
/// digits in the pivot. Since `L_kk² ≥ λ_min` and `A_kk ≤ λ_max`, such a ratio
/// also certifies `κ(A) > 4.5e12`: the solve would lose twelve or more of
/// sixteen digits. We stop there rather than return such a solution.
pub const BREAKDOWN_RATIO: f64 = 1000.0 * f64::EPSILON;

/// Refuses a factorisation whose factor, as the symbolic analysis sized it,
/// would not fit in the solve's memory `budget` ([`crate::limits`]):
/// `matrix` names the matrix for the message.
pub fn check_factor_size(
    factor_nnz: usize,
    dim: usize,
    matrix: &str,
    budget: MemoryBudget,
) -> Result<(), ProblemError> {
    let bytes = (factor_nnz as u64).saturating_mul(crate::limits::FACTOR_BYTES_PER_ENTRY);
    budget.check(bytes, || {
        format!("the Cholesky factor of {matrix} ({dim} unknowns, {factor_nnz} entries after fill-in) would need")
    })
    .map_err(|detail| ProblemError::TooLarge { detail })
}

impl crate::choice::Word for SpdKind {
    const WHAT: &'static str = "SPD back end";
    fn all() -> &'static [Self] {
        &SpdKind::ALL
    }
    fn name(self) -> &'static str {
        SpdKind::name(self)
    }
    fn listed() -> Vec<Self> {
        SpdKind::available()
    }
}

crate::choice::word_traits!(SpdKind);

/// A sparse SPD solver family.
pub trait SpdBackend: Send + Sync {
    /// Which back end this is.
    fn kind(&self) -> SpdKind;

    /// Name used on the command line and in reports.
    fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// Symbolic analysis (ordering + symbolic factorisation) of the lower
    /// triangle pattern `lower` (square, sorted rows, diagonal present).
    fn analyze(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Box<dyn SpdSymbolic>, NumericalError>;
}

/// The result of a symbolic analysis: factors any matrix with its pattern.
pub trait SpdSymbolic: Send + Sync {
    /// Numeric factorisation of `lower` (same pattern as analysed).
    fn factorize(
        &self,
        lower: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Box<dyn SpdFactor>, NumericalError>;

    /// Number of stored entries of the factor `L` (lower triangle, diagonal
    /// included), known after analysis.
    fn factor_nnz(&self) -> usize;

    /// Refuses a factorisation that would not fit in `budget`: by default
    /// [`check_factor_size`] on [`SpdSymbolic::factor_nnz`]; MUMPS checks
    /// its own estimate on every rank. `dim` and `matrix` are for the
    /// message.
    fn check_budget(
        &self,
        budget: MemoryBudget,
        dim: usize,
        matrix: &str,
    ) -> Result<(), ProblemError> {
        check_factor_size(self.factor_nnz(), dim, matrix, budget)
    }
}

/// A numeric factorisation `P A Pᵀ = L Lᵀ`.
pub trait SpdFactor: Send + Sync {
    /// Dimension of the factored matrix.
    fn dim(&self) -> usize;

    /// Solves `A X = B` in place for all columns of `rhs` together.
    fn solve_in_place(&mut self, rhs: MatMut<'_, f64>);

    /// Number of stored entries of `L`.
    fn nnz(&self) -> usize;

    /// Bytes of the factor's numerical values and indices (what a solve must
    /// read twice: the bandwidth floor of a solve).
    fn bytes(&self) -> usize;

    /// What a MUMPS factor reports of its ranks; `None` for the others.
    fn mumps_facts(&self) -> Option<crate::backend::MumpsFacts> {
        None
    }
}

/// Solves with a factor, returning the solution (convenience).
pub fn solve(factor: &mut dyn SpdFactor, rhs: MatRef<'_, f64>) -> faer::Mat<f64> {
    let mut x = rhs.to_owned();
    factor.solve_in_place(x.as_mut());
    x
}

/// The breakdown check shared by every back end: rejects a completed factor
/// `P A Pᵀ = L Lᵀ` whose pivot ratio `L_kk² / A_kk` is below
/// [`BREAKDOWN_RATIO`] or not finite, naming the worst such pivot.
///
/// `l_diag[k]` is `L_kk` in the permuted order, `fwd[k]` the original index
/// of permuted unknown `k`, `lower` the factored matrix (lower triangle,
/// original order). A missing diagonal entry counts as `A_kk = 0`, which
/// makes the ratio infinite or NaN; NaN is rejected.
pub(crate) fn check_breakdown(
    l_diag: &[f64],
    fwd: &[usize],
    lower: SparseColMatRef<'_, usize, f64>,
) -> Result<(), NumericalError> {
    let (col_ptr, row_idx, val) = (
        lower.symbolic().col_ptr(),
        lower.symbolic().row_idx(),
        lower.val(),
    );
    let a_diag = |j: usize| -> f64 {
        let range = col_ptr[j]..col_ptr[j + 1];
        row_idx[range.clone()]
            .iter()
            .position(|&i| i == j)
            .map(|p| val[range.start + p])
            .unwrap_or(0.0)
    };
    // Report the worst pivot, not the first below the threshold.
    let mut worst: Option<(usize, f64)> = None;
    for (k, &l) in l_diag.iter().enumerate() {
        let orig = fwd.get(k).copied().unwrap_or(k);
        let ratio = l * l / a_diag(orig);
        let healthy = ratio >= BREAKDOWN_RATIO; // false for NaN
        if !healthy && worst.is_none_or(|(_, r)| ratio < r || ratio.is_nan()) {
            worst = Some((orig, ratio));
        }
    }
    match worst {
        None => Ok(()),
        Some((unknown, ratio)) => Err(NumericalError::Breakdown {
            matrix: String::new(),
            unknown,
            vertex: None,
            ratio,
            threshold: BREAKDOWN_RATIO,
        }),
    }
}
