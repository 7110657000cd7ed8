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

use crate::error::{NumericalError, ProblemError};

#[cfg(feature = "suitesparse")]
mod cholmod;
mod faer_llt;
mod nalgebra;
mod tree_split;
mod triangular;

#[cfg(feature = "suitesparse")]
pub use cholmod::Cholmod;
pub use faer_llt::FaerLlt;
pub use nalgebra::NalgebraCsc;

/// The SPD back ends of this build, in the order they are listed to users
/// (what [`by_name`] accepts): `cholmod` only with the cargo feature
/// `suitesparse`.
#[cfg(feature = "suitesparse")]
pub const NAMES: &[&str] = &[
    "faer-supernodal",
    "faer-simplicial",
    "faer-auto",
    "nalgebra",
    "cholmod",
];
/// The SPD back ends of this build, in the order they are listed to users
/// (what [`by_name`] accepts): `cholmod` only with the cargo feature
/// `suitesparse`.
#[cfg(not(feature = "suitesparse"))]
pub const NAMES: &[&str] = &[
    "faer-supernodal",
    "faer-simplicial",
    "faer-auto",
    "nalgebra",
];

/// Back ends that exist with the cargo feature `suitesparse` only; in a
/// build without it [`by_name`] says how to get them.
pub const SUITESPARSE_NAMES: &[&str] = &["cholmod"];

/// The SPD back end called `name` (one of [`NAMES`]).
///
/// Errors: [`ProblemError::InvalidArgument`] for an unknown name (the
/// message lists [`NAMES`]) and for `cholmod` in a build without the
/// `suitesparse` feature (the message says how to enable it).
pub fn by_name(name: &str) -> Result<Arc<dyn SpdBackend>, ProblemError> {
    match name {
        "faer-supernodal" => Ok(Arc::new(FaerLlt::supernodal())),
        "faer-simplicial" => Ok(Arc::new(FaerLlt::simplicial())),
        "faer-auto" => Ok(Arc::new(FaerLlt::auto())),
        "nalgebra" => Ok(Arc::new(NalgebraCsc)),
        #[cfg(feature = "suitesparse")]
        "cholmod" => Ok(Arc::new(Cholmod)),
        #[cfg(not(feature = "suitesparse"))]
        "cholmod" => Err(ProblemError::InvalidArgument {
            message: "the SPD back end 'cholmod' (SuiteSparse CHOLMOD) is not in this build: rebuild with `--features suitesparse` (needs the system packages libsuitesparse-dev and libclang-dev)".into(),
        }),
        other => Err(ProblemError::InvalidArgument {
            message: format!(
                "unknown SPD back end '{other}' (expected one of: {})",
                NAMES.join(", ")
            ),
        }),
    }
}

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
/// would not fit in the memory budget ([`crate::limits`]): `matrix` names
/// the matrix for the message.
pub fn check_factor_size(factor_nnz: usize, dim: usize, matrix: &str) -> Result<(), ProblemError> {
    let bytes = (factor_nnz as u64).saturating_mul(crate::limits::FACTOR_BYTES_PER_ENTRY);
    crate::limits::check(bytes, || {
        format!("the Cholesky factor of {matrix} ({dim} unknowns, {factor_nnz} entries after fill-in) would need")
    })
    .map_err(|detail| ProblemError::TooLarge { detail })
}

/// A sparse SPD solver family.
pub trait SpdBackend: Send + Sync {
    /// Name used on the command line and in reports.
    fn name(&self) -> &'static str;

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
